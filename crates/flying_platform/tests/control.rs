//! Inner LQR (AT-09), outer loop poles (AT-10) and actuator limits.
#![allow(clippy::unwrap_used)]

use flying_platform::control::{
    ActuatorLimits, CascadedController, InnerLqr, Measurement, OuterGains, Setpoint, YawLaw,
};
use flying_platform::PlatformParams;
use nalgebra::{DMatrix, Matrix3, SVector, Vector3};
use proptest::prelude::*;

fn sorted_poles(m: &DMatrix<f64>) -> Vec<f64> {
    let mut p: Vec<f64> = m.complex_eigenvalues().iter().map(|z| z.re).collect();
    p.sort_by(|a, b| a.partial_cmp(b).unwrap());
    p
}

#[test]
fn inner_lqr_closed_form_equals_generic_care_and_reproduces_poles() {
    for (l3, expected) in [
        (0.079, [-50.12, -50.12, -29.09]),
        (0.17, [-88.54, -88.54, -29.09]),
    ] {
        let mut design = PlatformParams::nominal();
        design.l3 = l3;
        let (q, r) = InnerLqr::paper_weights();
        let lqr = InnerLqr::design(&design, &q, &r).unwrap();
        let b = DMatrix::from_fn(3, 9, |i, j| lqr.b[(i, j)]);
        let reference = rigid_body::lti::lqr(
            &DMatrix::zeros(3, 3),
            &b,
            &DMatrix::from_fn(3, 3, |i, j| q[(i, j)]),
            &DMatrix::from_diagonal(&nalgebra::DVector::from_column_slice(r.as_slice())),
        )
        .unwrap();
        let k = DMatrix::from_fn(9, 3, |i, j| lqr.k[(i, j)]);
        assert!(
            (&k - &reference.k).amax() < 1e-8 * k.amax(),
            "K differs from CARE"
        );
        let poles = sorted_poles(&DMatrix::from_fn(3, 3, |i, j| lqr.closed_loop()[(i, j)]));
        for (p, e) in poles.iter().zip(expected) {
            assert!((p - e).abs() < 0.05, "l3 = {l3}: poles {poles:?}");
        }
    }
}

/// Coefficients of a linear law obtained by probing it with unit perturbations.
fn probe(ctrl: &CascadedController, f: impl Fn(&mut Measurement, f64)) -> (Vector3<f64>, f64) {
    let mut m = Measurement::default();
    f(&mut m, 1.0);
    ctrl.outer(&m, &Setpoint::default())
}

#[test]
fn outer_loop_places_the_paper_poles_with_an_ideal_rate_loop() {
    for law in [YawLaw::Intended, YawLaw::AsPrinted] {
        let gains = OuterGains {
            yaw_law: law,
            ..OuterGains::default()
        };
        let ctrl =
            CascadedController::new(&PlatformParams::nominal(), gains, ActuatorLimits::default())
                .unwrap();
        let g0 = ctrl.g0;
        // x: state (x, vx, pitch); x' = vx, vx' = g0 pitch, pitch' = w_des,y.
        let kx = probe(&ctrl, |m, s| m.position[0] = s).0[1];
        let kv = probe(&ctrl, |m, s| m.velocity[0] = s).0[1];
        let kb = probe(&ctrl, |m, s| m.attitude[1] = s).0[1];
        let ax = DMatrix::from_row_slice(3, 3, &[0.0, 1.0, 0.0, 0.0, 0.0, g0, kx, kv, kb]);
        // y: state (y, vy, roll); vy' = -g0 roll, roll' = w_des,x.
        let ky = probe(&ctrl, |m, s| m.position[1] = s).0[0];
        let kvy = probe(&ctrl, |m, s| m.velocity[1] = s).0[0];
        let ka = probe(&ctrl, |m, s| m.attitude[0] = s).0[0];
        let ay = DMatrix::from_row_slice(3, 3, &[0.0, 1.0, 0.0, 0.0, 0.0, -g0, ky, kvy, ka]);
        for a in [ax, ay] {
            let p = sorted_poles(&a);
            for (got, want) in p.iter().zip([-3.0, -3.0, -1.0]) {
                assert!((got - want).abs() < 1e-4, "{p:?}");
            }
        }
        // z: z'' = (3/m) F_z.
        let fz_z = probe(&ctrl, |m, s| m.position[2] = s).1 * 3.0 / ctrl.mass;
        let fz_v = probe(&ctrl, |m, s| m.velocity[2] = s).1 * 3.0 / ctrl.mass;
        let pz = sorted_poles(&DMatrix::from_row_slice(2, 2, &[0.0, 1.0, fz_z, fz_v]));
        assert!(pz.iter().all(|p| (p + 2.0).abs() < 1e-4), "{pz:?}");
        let yaw_pole = probe(&ctrl, |m, s| m.attitude[2] = s).0[2];
        let want = if law == YawLaw::Intended {
            -2.0
        } else {
            -2.0 / 9.81
        };
        assert!((yaw_pole - want).abs() < 1e-12);
    }
}

#[test]
fn flap_limits_scale_with_thrust() {
    let lim = ActuatorLimits::default();
    let u =
        SVector::<f64, 9>::from_column_slice(&[10.0, -10.0, 26.4, -1.0, 0.5, 13.2, 0.0, 0.0, 80.0]);
    let (s, saturated) = lim.saturate(&u);
    assert!(saturated);
    assert!((s[0] - 3.0).abs() < 1e-12 && (s[1] + 1.5).abs() < 1e-12); // ±18° at 26.4 N
    assert!((s[3] + 1.0).abs() < 1e-12 && (s[4] - 0.5).abs() < 1e-12); // inside at 13.2 N (±1.5, ±0.75)
    assert_eq!(s[8], 46.9);
    let angles = lim.flap_angles_deg(&s);
    assert!((angles[0][0] - 18.0).abs() < 1e-12 && (angles[0][1] + 18.0).abs() < 1e-12);
}

proptest! {
    /// Saturated commands never exceed ±18° flap deflection or the thrust range, and
    /// commands inside the limits pass unchanged.
    #[test]
    fn saturation_respects_limits(u in proptest::collection::vec(-60.0..60.0f64, 9)) {
        let lim = ActuatorLimits::default();
        let u = SVector::<f64, 9>::from_column_slice(&u);
        let (s, _) = lim.saturate(&u);
        for unit in 0..3 {
            prop_assert!(s[3 * unit + 2] >= lim.thrust_min && s[3 * unit + 2] <= lim.thrust_max);
        }
        for a in lim.flap_angles_deg(&s).iter().flatten() {
            prop_assert!(a.abs() <= 18.0 + 1e-9);
        }
        let (again, sat) = lim.saturate(&s);
        prop_assert!(!sat);
        prop_assert_eq!(again, s);
    }

    /// The closed-form LQR solves the Riccati equation `Q - P S P = 0` for any SPD weight.
    #[test]
    fn lqr_solves_riccati(q1 in 1.0..1000.0f64, q2 in 1.0..1000.0f64, q3 in 1.0..1000.0f64, off in -0.5..0.5f64) {
        let q = Matrix3::new(q1, off * (q1 * q2).sqrt(), 0.0, off * (q1 * q2).sqrt(), q2, 0.0, 0.0, 0.0, q3);
        let (_, r) = InnerLqr::paper_weights();
        let lqr = InnerLqr::design(&PlatformParams::nominal(), &q, &r).unwrap();
        let r_inv = nalgebra::SMatrix::<f64, 9, 9>::from_diagonal(&r.map(|v| 1.0 / v));
        let residual = q - lqr.p * lqr.b * r_inv * lqr.b.transpose() * lqr.p;
        prop_assert!(residual.amax() < 1e-8 * q.amax());
    }
}
