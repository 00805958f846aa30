//! Model properties (spec §8.1): identities, conserved quantities, equilibria, linearization.
#![allow(clippy::unwrap_used)]
mod common;

use common::*;
use cubli::model::{
    energy, figure_axis_momentum, housing_energy, linearize, reduced_derivative,
    relative_equilibrium, split_momentum, upright, upright_instability_rate, yaw_momentum,
};
use cubli::{reduced_step, FullState, Params, Plant, ReducedState, WheelEffects};
use nalgebra::{Matrix2, Vector2, Vector3};
use proptest::prelude::*;

fn jp(v: &Vector3<f64>) -> Vector2<f64> {
    Matrix2::new(0.0, 1.0, -1.0, 0.0) * Vector2::new(v[0], v[1])
}

proptest! {
    /// (1.39): P(a × b) = −a3 J P b + b3 J P a, and the Lagrange identity (1.21).
    #[test]
    fn projection_and_lagrange_identities(a in vec3(5.0), b in vec3(5.0)) {
        let lhs = a.cross(&b);
        let rhs = -jp(&b) * a[2] + jp(&a) * b[2];
        prop_assert!((Vector2::new(lhs[0], lhs[1]) - rhs).amax() <= 1e-14 * (1.0 + a.norm() * b.norm()));
        let lag = a.cross(&b.cross(&a.cross(&b)));
        let r = -a.cross(&b) * a.dot(&b);
        prop_assert!((lag - r).amax() <= 1e-12 * (1.0 + a.norm().powi(2) * b.norm().powi(2)));
    }

    /// Yaw momentum p_hᵀg is conserved under gravity and internal torques only (arbitrary motor
    /// torques plus wheel friction and a torque-constant error, full model, RK4): its drift is
    /// the integrator's truncation error, so it falls about 16-fold when the step is halved (a
    /// torque that broke the conservation would not fall with the step), down to rounding. A
    /// fixed bound of 1e-9 failed for fast tumbling (1.1e-9 at 2e-4 s, 7.1e-11 at 1e-4 s).
    #[test]
    fn yaw_momentum_conserved_with_internal_torques(
        att in attitude(), ph in vec3(0.1), pw in vec3(0.1),
        amp in vec3(0.05), freq in vec3(6.0), visc in 0.0..1e-4f64, coul in 0.0..5e-3f64,
    ) {
        let p = Params::reference();
        let plant = Plant {
            effects: WheelEffects {
                torque_constant: Vector3::new(0.9, 1.1, 1.0),
                viscous: Vector3::repeat(visc),
                coulomb: Vector3::repeat(coul),
                coulomb_smoothing: 0.5,
            },
            ..Plant::ideal(p)
        };
        let yaw = |x: &FullState| x.p_h.dot(&x.gravity_body(&p));
        let scale = ph.norm().max(0.01) * p.gravity();
        // Largest relative drift over 1 s with step h.
        let drift = |h: f64| {
            let mut x = FullState { attitude: att, p_h: ph, p_w: pw };
            let y0 = yaw(&x);
            let mut worst: f64 = 0.0;
            for k in 0..(1.0 / h).round() as usize {
                let t = k as f64 * h;
                let torque = amp.component_mul(&freq.map(|f| (f * t).sin()));
                x = plant.step(&x, &torque, h);
                worst = worst.max((yaw(&x) - y0).abs());
            }
            worst / scale
        };
        let (coarse, fine) = (drift(2e-4), drift(1e-4));
        prop_assert!(coarse < 1e-7, "relative drift {coarse} at 2e-4 s");
        prop_assert!(
            fine < 1e-11 || fine < coarse / 10.0,
            "relative drift {coarse} at 2e-4 s, {fine} at 1e-4 s: not truncation error"
        );
    }

    /// Ḣ_h = −ω_hᵀ T (1.4) and ṗ_h⊥ = p_h⊥ × ω_h + m × g, by central differences.
    #[test]
    fn housing_energy_and_perp_momentum_rates(g in unit(), ph in vec3(0.1), pw in vec3(0.1), t in vec3(0.2)) {
        let p = Params::reference();
        let x = reduced(&p, g, ph, pw);
        let f = reduced_derivative(&p, &x, &t);
        let eps = 1e-6;
        let shift = |a: f64| ReducedState { g: x.g + f.g * a, p_h: x.p_h + f.p_h * a, p_w: x.p_w + f.p_w * a };
        let fd = (housing_energy(&p, &shift(eps)) - housing_energy(&p, &shift(-eps))) / (2.0 * eps);
        let w = x.omega_h(&p);
        let exact = -w.dot(&t);
        prop_assert!((fd - exact).abs() <= 1e-6 * (exact.abs() + 1e-3), "{fd} vs {exact}");
        let fdp = (split_momentum(&shift(eps)).0 - split_momentum(&shift(-eps)).0) / (2.0 * eps);
        let (pp, _) = split_momentum(&x);
        let rate = pp.cross(&w) + p.m().cross(&x.g);
        prop_assert!((fdp - rate).amax() <= 1e-6 * (rate.amax() + 1e-3));
    }

    /// Relative equilibria (1.7): the reduced right-hand side vanishes with T = 0.
    #[test]
    fn relative_equilibria_are_stationary(g in unit(), l1 in 0.1..5.0f64, sign in any::<bool>(), l2 in -1.0..1.0f64) {
        let p = Params::reference();
        let l1 = if sign { l1 } else { -l1 };
        let x = relative_equilibrium(&p, &g, l1, l2).unwrap();
        let f = reduced_derivative(&p, &x, &Vector3::zeros());
        let scale = 1.0 + x.p_h.norm() + x.p_w.norm();
        prop_assert!(f.g.amax() < 1e-12 * scale * p.gravity());
        prop_assert!(f.p_h.amax() < 1e-12 * scale * p.gravity());
    }
}

/// Spec test 3 with h = 1e-4 over 5 s: drift below 1e-11.
#[test]
fn yaw_momentum_drift_fine_step() {
    let p = Params::reference();
    let plant = Plant::ideal(p);
    let mut x = FullState {
        attitude: nalgebra::UnitQuaternion::from_euler_angles(0.4, -0.3, 1.0),
        p_h: Vector3::new(0.1, -0.05, 0.08),
        p_w: Vector3::new(-0.02, 0.1, 0.05),
    };
    let yaw = |x: &FullState| x.p_h.dot(&x.gravity_body(&p)) / p.gravity();
    let y0 = yaw(&x);
    let h = 1e-4;
    let mut worst: f64 = 0.0;
    for k in 0..50_000 {
        let t = k as f64 * h;
        let torque = Vector3::new((3.0 * t).sin(), (5.0 * t).cos(), (7.0 * t).sin()) * 0.05;
        x = plant.step(&x, &torque, h);
        worst = worst.max((yaw(&x) - y0).abs());
    }
    assert!(worst < 1e-11, "drift {worst:e}");
}

/// Spec test 4: energy H and H_h conserved with T = 0, p_w constant.
#[test]
fn energy_conserved_without_torque() {
    let p = Params::reference();
    let mut x = reduced(
        &p,
        Vector3::new(0.3, -0.2, -0.9),
        Vector3::new(0.1, -0.1, 0.05),
        Vector3::new(0.05, 0.02, -0.1),
    );
    let (h0, hh0, pw0) = (energy(&p, &x), housing_energy(&p, &x), x.p_w);
    let mut worst: f64 = 0.0;
    for _ in 0..5000 {
        x = reduced_step(&p, &x, 1e-3, |_| Vector3::zeros());
        worst = worst
            .max((energy(&p, &x) - h0).abs())
            .max((housing_energy(&p, &x) - hh0).abs());
    }
    assert!(worst < 1e-7, "energy drift {worst:e}");
    assert_eq!(x.p_w, pw0);
}

/// Spec test 6: p_hᵐ conserved with T = 0, p_w = 0 under Assumption 4.1; not conserved with p_w ≠ 0.
#[test]
fn figure_axis_momentum_needs_symmetry_and_stopped_wheels() {
    let p = Params::reference();
    let run = |pw: Vector3<f64>| {
        let mut x = reduced(
            &p,
            Vector3::new(0.1, 0.4, -0.9),
            Vector3::new(0.05, -0.1, 0.02),
            pw,
        );
        let m0 = figure_axis_momentum(&p, &x);
        let mut worst: f64 = 0.0;
        for _ in 0..20_000 {
            x = reduced_step(&p, &x, 1e-4, |_| Vector3::zeros());
            worst = worst.max((figure_axis_momentum(&p, &x) - m0).abs());
        }
        worst
    };
    assert!(run(Vector3::zeros()) < 1e-9);
    assert!(run(Vector3::new(0.05, -0.02, 0.0)) > 1e-4);
}

/// Spec test 8: full and reduced models agree; the quaternion stays a rotation, |g| stays 9.81.
#[test]
fn full_and_reduced_models_agree() {
    let p = Params::reference();
    let plant = Plant::ideal(p);
    let mut xf = FullState {
        attitude: nalgebra::UnitQuaternion::from_euler_angles(0.7, 0.2, -0.4),
        p_h: Vector3::new(0.08, -0.03, 0.1),
        p_w: Vector3::new(0.01, 0.04, -0.02),
    };
    let mut xr = xf.reduced(&p);
    for _ in 0..20_000 {
        xf = plant.step(&xf, &Vector3::new(0.01, -0.02, 0.005), 1e-4);
        xr = reduced_step(&p, &xr, 1e-4, |_| Vector3::new(0.01, -0.02, 0.005));
    }
    let r = xf.attitude.to_rotation_matrix().into_inner();
    assert!((r.transpose() * r - nalgebra::Matrix3::identity()).amax() < 1e-8);
    assert!((xf.gravity_body(&p) - xr.g).amax() < 1e-9);
    assert!((xr.g.norm() - 9.81).abs() < 1e-8);
    assert!((xf.p_h - xr.p_h).amax() < 1e-9);
}

/// Spec test 9: upright is unstable with rate √(|m||g|/I1) = 7.856 s⁻¹; hanging is marginal.
#[test]
fn upright_unstable_hanging_marginal() {
    let p = Params::reference();
    let rate = upright_instability_rate(&p);
    assert!((rate - 7.856).abs() < 1e-3, "rate {rate}");
    let up = upright(&p, Vector3::zeros());
    let eig = linearize(&p, &up).0.complex_eigenvalues();
    let max_re = eig.iter().map(|e| e.re).fold(f64::MIN, f64::max);
    assert!((max_re - rate).abs() < 1e-9, "{max_re}");
    let hanging = ReducedState { g: -up.g, ..up };
    let eig = linearize(&p, &hanging).0.complex_eigenvalues();
    assert!(eig.iter().all(|e| e.re.abs() < 1e-9));
    assert!(eig.iter().any(|e| (e.im.abs() - rate).abs() < 1e-9));
}

/// Spec test 7, second part: upright and hanging at rest with equal p_h = p_w along g are equilibria,
/// and the yaw momentum of an upright state equals its wheel momentum along ĝ.
#[test]
fn upright_and_hanging_rest_are_equilibria() {
    let p = Params::reference();
    let up = upright(&p, -p.m_hat() * 0.07);
    let f = reduced_derivative(&p, &up, &Vector3::zeros());
    assert!(f.g.amax() < 1e-15 && f.p_h.amax() < 1e-15);
    assert!((yaw_momentum(&up) - 0.07).abs() < 1e-15);
    let hanging = ReducedState { g: -up.g, ..up };
    let f = reduced_derivative(&p, &hanging, &Vector3::zeros());
    assert!(f.g.amax() < 1e-15 && f.p_h.amax() < 1e-15);
}
