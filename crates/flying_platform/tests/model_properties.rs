//! Allocation geometry, trim, effect bookkeeping and FRF invariants (spec AT-01, AT-03, AT-05).
#![allow(clippy::unwrap_used)]

use flying_platform::geometry::{t11_nominal, unit_positions, unit_rotation};
use flying_platform::{Effect, EffectSet, Error, Model, PlatformParams};
use nalgebra::{Matrix2, SVector, Vector3};
use proptest::prelude::*;

fn input(v: &[f64]) -> SVector<f64, 9> {
    SVector::<f64, 9>::from_column_slice(v)
}

#[test]
fn nominal_t11_rows_are_orthogonal_with_norm_sqrt3() {
    let t = t11_nominal();
    assert!((t * t.transpose() - Matrix2::identity() * 3.0).amax() < 1e-14);
}

#[test]
fn hover_trim_cancels_weight_and_fan_torques() {
    for m_torque in [0.0, 0.05, 0.15] {
        let mut p = PlatformParams::nominal();
        p.hover_torque = m_torque;
        p.input = flying_platform::InputMatrix::nominal(p.mass, p.l1, p.i3);
        let u = p.hover_input();
        let f = p.total_force(&u);
        let t = p.total_torque(&u);
        assert!((f - Vector3::new(0.0, 0.0, p.mass * p.g0)).amax() < 1e-12);
        // T2 u_bar = (0, 0, 3M): the flap-2 forces cancel the three reaction torques -e_z M.
        assert!((t - Vector3::new(0.0, 0.0, 3.0 * m_torque)).amax() < 1e-12);
    }
}

#[test]
fn effect_names_round_trip_and_unknown_names_are_named_errors() {
    for e in Effect::ALL {
        assert_eq!(Effect::from_name(e.name()).unwrap(), e);
    }
    let names: Vec<_> = Effect::ALL.iter().map(|e| e.name()).collect();
    assert_eq!(
        names,
        [
            "momentum_drag",
            "fan_gyroscopic",
            "actuator_lag",
            "input_delay"
        ]
    );
    match EffectSet::parse("momentum_drag,wind") {
        Err(Error::UnknownEffect(n)) => assert_eq!(n, "wind"),
        other => panic!("expected UnknownEffect, got {other:?}"),
    }
}

#[test]
fn parameter_vector_follows_enabled_effects_and_checks_bounds() {
    let mut m = Model::new(
        PlatformParams::default(),
        EffectSet::parse("input_delay,fan_gyroscopic").unwrap(),
    );
    assert_eq!(m.param_names(), ["c_omega_t0", "td"]);
    assert_eq!(m.parameter_vector(), [0.018, 0.045]);
    m.set_parameter_vector(&[0.01, 0.02]).unwrap();
    assert_eq!(m.parameter("td").unwrap(), 0.02);
    assert!(matches!(
        m.set_parameter_vector(&[0.01]),
        Err(Error::Length { .. })
    ));
    match m.set_parameter_vector(&[0.01, 0.5]) {
        Err(Error::OutOfBounds { name, .. }) => assert_eq!(name, "td"),
        other => panic!("expected OutOfBounds, got {other:?}"),
    }
    // A failed set leaves the vector unchanged.
    assert_eq!(m.parameter_vector(), [0.01, 0.02]);
    assert!(matches!(
        m.parameter("c_alpha1"),
        Err(Error::UnknownParameter(_))
    ));
    assert!(m.set_parameter("td", f64::NAN).is_err());
}

#[test]
fn low_complexity_model_has_all_poles_at_zero() {
    let ss = Model::low_complexity().state_space().unwrap();
    assert_eq!(ss.a.nrows(), 9);
    assert!(ss.poles().unwrap().iter().all(|p| p.norm() < 1e-9));
    assert_eq!(ss.delay, 0.0);
}

/// AT-05: zeros of v_x / F1x are +-sqrt(g0 m l3 / I1) for the nominal structure.
#[test]
fn nonminimum_phase_zero_of_lateral_force_to_velocity() {
    for (l3, z) in [(0.079, 9.411), (0.17, 13.806)] {
        let mut m = Model::new(PlatformParams::nominal(), EffectSet::none());
        m.params.l3 = l3;
        let ss = m.state_space().unwrap();
        // G(s) = (s^2 - z^2) / (m s^3): at s = j w the ratio of G to 1/(m s) is 1 + z^2/w^2.
        let w = 3.0;
        let g = ss.frequency_response_at(w).unwrap()[(0, 0)];
        let ratio = g * nalgebra::Complex::new(0.0, w) * m.params.mass;
        assert!((ratio.re - (1.0 + z * z / (w * w))).abs() < 2e-3, "{ratio}");
        assert!(ratio.im.abs() < 1e-12);
    }
}

proptest! {
    /// AT-01: the nominal allocation equals the sum of r_i x (R_i F_i) over the units.
    #[test]
    fn allocation_matches_geometry(u in proptest::collection::vec(-30.0..30.0f64, 9), l3 in -0.3..0.3f64) {
        let mut p = PlatformParams::nominal();
        p.l3 = l3;
        let u = input(&u);
        let pos = unit_positions(p.l1, p.l3);
        let mut force = Vector3::zeros();
        let mut torque = Vector3::zeros();
        for i in 0..3 {
            let f = unit_rotation(i) * Vector3::new(u[3 * i], u[3 * i + 1], u[3 * i + 2]);
            force += f;
            torque += pos[i].cross(&f);
        }
        prop_assert!((p.total_force(&u) - force).amax() < 1e-10);
        prop_assert!((p.total_torque(&u) - torque).amax() < 1e-10);
    }

    /// The lag as nine extra states gives the same FRF as the factor 1/(1 + j w tau).
    #[test]
    fn lag_states_match_lag_factor(tau in 0.002..0.3f64, w in 0.1..60.0f64, td in 0.0..0.1f64) {
        let mut m = Model::augmented();
        m.effects.enable(Effect::ActuatorLag);
        m.set_parameter("tau", tau).unwrap();
        m.set_parameter("td", td).unwrap();
        let ss = m.state_space().unwrap();
        prop_assert_eq!(ss.a.nrows(), 18);
        let g_states = ss.frequency_response_at(w).unwrap();
        let g_factor = &m.frequency_response(&[w]).unwrap()[0];
        prop_assert!((g_states - g_factor).camax() < 1e-9 * (1.0 + g_factor.camax()));
    }

    /// The delay only rotates the phase: |G| is unchanged and the phase shift is w Td.
    #[test]
    fn delay_is_a_pure_phase_shift(td in 0.0..0.2f64, w in 0.1..30.0f64) {
        let mut m = Model::augmented();
        let g0 = m.frequency_response(&[w]).unwrap()[0].clone();
        m.set_parameter("td", td).unwrap();
        let g1 = &m.frequency_response(&[w]).unwrap()[0];
        let expected = g0.map(|g| g * nalgebra::Complex::new(0.0, -w * (td - 0.045)).exp());
        prop_assert!((g1 - expected).camax() < 1e-12);
    }

    /// Setting the flat vector and reading it back is the identity for in-bound values.
    #[test]
    fn parameter_vector_round_trip(c1 in 0.0..50.0f64, c2 in 0.0..50.0f64, l in -1.0..1.0f64, h in -0.2..0.2f64) {
        let mut m = Model::augmented();
        let theta = vec![c1, c2, l, -l, l / 2.0, c1 / 10.0, h, 0.03];
        m.set_parameter_vector(&theta).unwrap();
        prop_assert_eq!(m.parameter_vector(), theta);
    }
}

proptest! {
    /// Point-model drag: summing `-C_alpha (v + w x r_P)` and its moments over three points at
    /// radius rho and height h (120° apart) gives the same hover rows as the
    /// phenomenological totals with the point-model parameters.
    #[test]
    fn point_model_drag_equals_sum_over_three_points(
        c1 in 0.5..5.0f64, c2 in 0.5..5.0f64, h in -0.3..0.3f64, rho in 0.05..0.2f64,
        x in proptest::collection::vec(-1.0..1.0f64, 6),
    ) {
        let drag = flying_platform::MomentumDrag::point_model(c1, c2, h, rho).unwrap();
        let mut with = Model::new(PlatformParams::default(), EffectSet::none());
        with.effects.enable_with(Effect::MomentumDrag, &drag.to_vector()).unwrap();
        let without = Model::new(PlatformParams::default(), EffectSet::none());
        let a_drag = with.hover_matrices().unwrap().0 - without.hover_matrices().unwrap().0;
        let v = Vector3::new(x[0], x[1], x[2]);
        let w = Vector3::new(x[3], x[4], x[5]);
        let c = Vector3::new(c1, c1, c2);
        let (mut f, mut m) = (Vector3::zeros(), Vector3::zeros());
        for i in 0..3 {
            let psi = 2.0 * std::f64::consts::PI * i as f64 / 3.0 + 0.4;
            let r = Vector3::new(rho * psi.cos(), rho * psi.sin(), h);
            let fi = -c.component_mul(&(v + w.cross(&r)));
            f += fi;
            m += r.cross(&fi);
        }
        let p = &with.params;
        let state = nalgebra::DVector::from_column_slice(&[v[0], v[1], v[2], 0.0, 0.0, 0.0, w[0], w[1], w[2]]);
        let dx = &a_drag * state;
        let expected = [f[0] / p.mass, f[1] / p.mass, f[2] / p.mass, 0.0, 0.0, 0.0, m[0] / p.i1, m[1] / p.i1, m[2] / p.i3];
        for (i, e) in expected.iter().enumerate() {
            prop_assert!((dx[i] - e).abs() < 1e-10, "row {}: {} vs {}", i, dx[i], e);
        }
    }
}
