//! Backstepping balance (spec §8.2): closed-loop identities, Lyapunov decrease, poles and tuning,
//! recovery, almost-global convergence, untouched yaw momentum, disturbance rejection.
#![allow(clippy::unwrap_used)]
mod common;

use common::*;
use cubli::model::{
    g_hat, inclination, reduced_derivative, signed_inclination, split_momentum, tilt_axis, upright,
    yaw_momentum,
};
use cubli::simulate::{simulate, RunConfig};
use cubli::{
    reduced_step, Backstepping, FullState, Gains, IntegralBackstepping, Params, Plant,
    ReducedState, TiltPolynomial,
};
use nalgebra::{Complex, Matrix3, Vector3};
use proptest::prelude::*;

fn gains() -> impl Strategy<Value = Gains> {
    (0.5..20.0f64, 0.5..20.0f64, 0.5..20.0f64, 0.1..5.0f64)
        .prop_map(|(a, b, c, d)| Gains::new(a, b, c, d).unwrap())
}

/// Closed-loop right-hand side under continuous backstepping.
fn closed(ctrl: &Backstepping, x: &ReducedState) -> ReducedState {
    reduced_derivative(ctrl.params(), x, &ctrl.control(x).unwrap())
}

fn shift(x: &ReducedState, f: &ReducedState, a: f64) -> ReducedState {
    ReducedState {
        g: x.g + f.g * a,
        p_h: x.p_h + f.p_h * a,
        p_w: x.p_w + f.p_w * a,
    }
}

proptest! {
    /// Spec test 10 (1.13): ż = −γ z − δ Θ0 (m × g) along the closed loop.
    #[test]
    fn z_dynamics_identity(k in gains(), g in unit(), ph in vec3(0.1), pw in vec3(0.1)) {
        let p = Params::reference();
        let c = Backstepping::new(p, k);
        let x = reduced(&p, g, ph, pw);
        let f = closed(&c, &x);
        let eps = 1e-6;
        let fd = (c.z(&shift(&x, &f, eps)) - c.z(&shift(&x, &f, -eps))) / (2.0 * eps);
        let exact = -c.z(&x) * k.gamma - p.theta0() * p.m().cross(&x.g) * k.delta;
        prop_assert!((fd - exact).amax() <= 1e-6 * (exact.amax() + 1e-4), "{fd} vs {exact}");
    }

    /// Spec test 11: V̇ = −β|g × m|² − (γ/δ)|Θ0⁻¹ z|² ≤ 0.
    #[test]
    fn lyapunov_derivative(k in gains(), g in unit(), ph in vec3(0.1), pw in vec3(0.1)) {
        let p = Params::reference();
        let c = Backstepping::new(p, k);
        let x = reduced(&p, g, ph, pw);
        let f = closed(&c, &x);
        let eps = 1e-6;
        let fd = (c.lyapunov(&shift(&x, &f, eps)) - c.lyapunov(&shift(&x, &f, -eps))) / (2.0 * eps);
        let exact = -k.beta * x.g.cross(p.m()).norm_squared()
            - k.gamma / k.delta * (p.theta0_inv() * c.z(&x)).norm_squared();
        prop_assert!(exact <= 0.0);
        prop_assert!((fd - exact).abs() <= 1e-6 * (exact.abs() + 1e-4), "{fd} vs {exact}");
    }

    /// Spec test 12: the matrix form (1.10) with K1..K4 equals the implemented expanded form.
    #[test]
    fn matrix_form_agrees(k in gains(), g in unit(), ph in vec3(0.1), pw in vec3(0.1)) {
        let p = Params::reference();
        let c = Backstepping::new(p, k);
        let x = reduced(&p, g, ph, pw);
        let (pp, _) = split_momentum(&x);
        let i = Matrix3::identity();
        let k1 = i + p.theta0() * (k.alpha + k.beta * k.gamma + k.delta);
        let k2 = p.theta0() * (pp.cross_matrix() * k.alpha + p.m().cross_matrix() * x.g.cross_matrix() * k.beta)
            + x.p_h.cross_matrix();
        let k3 = (i + p.theta0() * (i - x.g * x.g.transpose() / x.g.norm_squared()) * k.alpha) * k.gamma;
        let t = k1 * p.m().cross(&x.g) + k2 * x.omega_h(&p) + k3 * x.p_h - x.p_w * k.gamma;
        let u = c.control(&x).unwrap();
        prop_assert!((t - u).amax() <= 1e-12 * (1.0 + t.amax()));
    }

    /// Spec test 13: the closed-loop ω̇_h does not depend on Θ0 for given (g, ω_h, p_h⊥).
    #[test]
    fn closed_loop_rate_independent_of_inertia(g in unit(), wh in vec3(2.0), pperp in vec3(0.1), pg in -0.1..0.1f64, ww in vec3(50.0)) {
        let p1 = Params::reference();
        let t0 = Matrix3::new(0.03, 0.002, -0.001, 0.002, 0.025, 0.003, -0.001, 0.003, 0.02);
        let p2 = Params::new(t0, *p1.theta_w(), *p1.m(), 9.81).unwrap();
        let gd = g * 9.81;
        let ph = pperp - g * g.dot(&pperp) + g * pg;
        let rate = |p: &Params| {
            // p_w from ω_h: p_w = p_h − Θ0 ω_h; ww only changes the split between wheels and housing.
            let pw = ph - p.theta0() * wh;
            let x = ReducedState { g: gd, p_h: ph, p_w: pw };
            let c = Backstepping::new(*p, Gains::paper());
            let f = closed(&c, &x);
            let _ = ww;
            p.theta0_inv() * (f.p_h - f.p_w)
        };
        let (a, b) = (rate(&p1), rate(&p2));
        prop_assert!((a - b).amax() <= 1e-10 * (1.0 + a.amax()));
    }

    /// Forward tuning map: Routh–Hurwitz holds for every positive gain set (spec test 16).
    #[test]
    fn positive_gains_are_hurwitz(k in gains(), mg in 0.5..3.0f64) {
        let t = TiltPolynomial::from_gains(&k, mg);
        prop_assert!(t.a > 0.0 && t.b > 0.0 && t.c > 0.0 && t.a * t.b > t.c);
        prop_assert!(t.poles().iter().all(|s| s.re < 0.0));
    }

    /// Issue acceptance: from any tilt in the almost-global region (g uniform on S², random
    /// momenta), continuous backstepping brings g upright within 15 s (spec test 19), and the
    /// yaw momentum p_hᵍ is untouched by the control (1e-7).
    #[test]
    fn almost_global_convergence_keeps_yaw_momentum(g in unit(), ph in vec3(0.2), pw in vec3(0.2)) {
        let p = Params::reference();
        let c = Backstepping::new(p, Gains::paper());
        let mut x = reduced(&p, g, ph, pw);
        prop_assume!(inclination(&p, &x.g) < 179f64.to_radians());
        let yaw0 = yaw_momentum(&x);
        let mut worst_yaw: f64 = 0.0;
        for _ in 0..30_000 {
            x = reduced_step(&p, &x, 5e-4, |s| c.control(s).unwrap());
            worst_yaw = worst_yaw.max((yaw_momentum(&x) - yaw0).abs());
        }
        let (pp, pg) = split_momentum(&x);
        prop_assert!(inclination(&p, &x.g) < 0.1f64.to_radians(), "phi {}", inclination(&p, &x.g).to_degrees());
        prop_assert!(x.omega_h(&p).norm() < 1e-3);
        prop_assert!(pp.norm() < 1e-4);
        prop_assert!(worst_yaw < 1e-7, "yaw drift {worst_yaw:e}");
        prop_assert!((x.p_w - g_hat(&x) * pg).norm() < 1e-4);
    }
}

/// Spec test 14 (Proposition 1): released at rest, ω_h and p_h stay parallel to m × g.
#[test]
fn planar_motion_from_rest() {
    let p = Params::reference();
    let c = Backstepping::new(p, Gains::paper());
    for phi0 in [10.0, 30.0, 60.0, 120.0] {
        let att = tilted(&p, deg(phi0));
        let mut x = FullState {
            attitude: att,
            p_h: Vector3::zeros(),
            p_w: Vector3::zeros(),
        }
        .reduced(&p);
        let mut worst: f64 = 0.0;
        for _ in 0..3000 {
            x = reduced_step(&p, &x, 1e-3, |s| c.control(s).unwrap());
            let e = p.m().cross(&x.g).normalize();
            worst = worst
                .max(e.cross(&x.omega_h(&p)).norm())
                .max(e.cross(&x.p_h).norm());
        }
        assert!(worst < 1e-10, "phi0 {phi0}: {worst:e}");
    }
}

/// Spec test 15: the 3-D closed loop released at rest follows the scalar ODE (1.29).
#[test]
fn planar_inclination_ode_matches() {
    let p = Params::reference();
    let k = Gains::paper();
    let c = Backstepping::new(p, k);
    let mg = p.mg();
    let s = k.alpha + k.beta * k.gamma + k.delta;
    let ode = |v: [f64; 3]| {
        let [phi, d, dd] = v;
        let ddd = -(k.beta * mg * phi.cos() + k.gamma) * dd - s * mg * d * phi.cos()
            + k.beta * mg * d * d * phi.sin()
            - k.gamma * k.alpha * mg * phi.sin();
        [d, dd, ddd]
    };
    let rk4 = |v: [f64; 3], h: f64| {
        let add =
            |a: [f64; 3], b: [f64; 3], t: f64| [a[0] + t * b[0], a[1] + t * b[1], a[2] + t * b[2]];
        let k1 = ode(v);
        let k2 = ode(add(v, k1, h / 2.0));
        let k3 = ode(add(v, k2, h / 2.0));
        let k4 = ode(add(v, k3, h));
        [0, 1, 2].map(|i| v[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]))
    };
    for phi0 in [10.0, 30.0, 60.0, 120.0, 175.0] {
        let phi0 = deg(phi0);
        let mut x = FullState {
            attitude: tilted(&p, phi0),
            p_h: Vector3::zeros(),
            p_w: Vector3::zeros(),
        }
        .reduced(&p);
        let e0 = tilt_axis(&p, &x.g).unwrap();
        let mut v = [phi0, 0.0, -s * mg * phi0.sin()];
        let mut worst: f64 = 0.0;
        for _ in 0..50_000 {
            x = reduced_step(&p, &x, 1e-4, |st| c.control(st).unwrap());
            v = rk4(v, 1e-4);
            worst = worst.max((signed_inclination(&p, &x.g, &e0) - v[0]).abs());
        }
        assert!(worst < 1e-8, "phi0 {}: {worst:e}", phi0.to_degrees());
    }
}

/// Spec test 16: poles of the paper's gains and the tuning round trips.
#[test]
fn poles_and_tuning_method() {
    let t = TiltPolynomial::from_gains(&Gains::paper(), 1.8639);
    let poles = t.poles();
    let expected = [-0.855, -12.000, -32.70];
    for (s, (e, tol)) in poles.iter().zip(expected.iter().zip([0.005, 0.001, 0.01])) {
        assert!((s.re - e).abs() < tol && s.im.abs() < 1e-9, "{s} vs {e}");
    }
    assert!((1.0 / Gains::paper().gamma - 0.0833).abs() < 1e-4);

    let real =
        TiltPolynomial::from_poles(&[-30.0, -10.0, -1.0].map(|r| Complex::new(r, 0.0))).unwrap();
    assert_eq!((real.a, real.b, real.c), (41.0, 340.0, 300.0));
    let iv = real.admissible_gamma();
    assert_eq!(iv.as_slice().len(), 2);
    for ((lo, hi), (elo, ehi)) in iv.as_slice().iter().zip([(1.0, 10.0), (30.0, 41.0)]) {
        assert!(
            (lo - elo).abs() < 1e-9 && (hi - ehi).abs() < 1e-9,
            "({lo},{hi})"
        );
    }
    let k5 = real.gains(5.0, 1.0).unwrap();
    assert!(
        (k5.alpha - 60.0).abs() < 1e-12
            && (k5.beta - 36.0).abs() < 1e-12
            && (k5.delta - 100.0).abs() < 1e-12
    );
    let k35 = real.gains(35.0, 1.0).unwrap();
    assert!(
        (k35.alpha - 8.5714).abs() < 1e-4
            && (k35.beta - 6.0).abs() < 1e-12
            && (k35.delta - 121.43).abs() < 1e-2
    );
    assert!(
        matches!(real.gains(20.0, 1.0), Err(cubli::CubliError::InadmissibleGamma { h, .. }) if (h + 1900.0).abs() < 1e-9)
    );
    // The round trip reproduces the poles.
    let back = TiltPolynomial::from_gains(&k35, 1.0);
    assert!(
        (back.a - 41.0).abs() < 1e-9
            && (back.b - 340.0).abs() < 1e-9
            && (back.c - 300.0).abs() < 1e-9
    );

    let complex = TiltPolynomial::from_poles(&[
        Complex::new(-5.0, 5.0),
        Complex::new(-5.0, -5.0),
        Complex::new(-20.0, 0.0),
    ])
    .unwrap();
    assert!(
        (complex.a - 30.0).abs() < 1e-12
            && (complex.b - 250.0).abs() < 1e-12
            && (complex.c - 1000.0).abs() < 1e-12
    );
    let iv = complex.admissible_gamma();
    assert_eq!(iv.as_slice().len(), 1);
    assert!((iv.as_slice()[0].0 - 20.0).abs() < 1e-9 && (iv.as_slice()[0].1 - 30.0).abs() < 1e-12);

    assert!(TiltPolynomial::from_poles(&[
        Complex::new(1.0, 0.0),
        Complex::new(-1.0, 0.0),
        Complex::new(-2.0, 0.0)
    ])
    .is_err());
    assert!(TiltPolynomial::from_poles(&[
        Complex::new(-1.0, 1.0),
        Complex::new(-1.0, 0.5),
        Complex::new(-2.0, 0.0)
    ])
    .is_err());
    assert!(Gains::new(1.0, -1.0, 1.0, 1.0).is_err());
}

/// Spec test 17: pure yaw is braked with time constant 1/γ; the momentum ends in the wheels.
#[test]
fn yaw_braking() {
    let p = Params::reference();
    let c = Backstepping::new(p, Gains::paper());
    let w0 = p.m_hat();
    let mut x = ReducedState {
        g: -p.m_hat() * 9.81,
        p_h: p.theta0() * w0,
        p_w: Vector3::zeros(),
    };
    let h = 1e-3;
    for k in 1..=1000 {
        x = reduced_step(&p, &x, h, |s| c.control(s).unwrap());
        let t = k as f64 * h;
        assert!(
            (x.omega_h(&p).norm() - (-12.0 * t).exp()).abs() < 1e-6,
            "t {t}"
        );
    }
    let (_, pg) = split_momentum(&x);
    assert!((x.p_w - g_hat(&x) * pg).norm() < 1e-6 && (x.p_h - x.p_w).norm() < 1e-6);
}

/// Spec test 18: recovery from 10° at rest (continuous), and from large tilts with 20 ms ZOH.
#[test]
fn tilt_recovery() {
    let p = Params::reference();
    let c = Backstepping::new(p, Gains::paper());
    let mut x = FullState {
        attitude: tilted(&p, deg(10.0)),
        p_h: Vector3::zeros(),
        p_w: Vector3::zeros(),
    }
    .reduced(&p);
    let e0 = tilt_axis(&p, &x.g).unwrap();
    let h = 1e-3;
    let (mut undershoot, mut t_under, mut settle) = (0.0f64, 0.0, 0.0);
    for k in 1..=5000 {
        x = reduced_step(&p, &x, h, |s| c.control(s).unwrap());
        let t = k as f64 * h;
        let phi = signed_inclination(&p, &x.g, &e0).to_degrees();
        if (t - 0.2).abs() < 1e-9 {
            assert!(phi.abs() < 1.0, "phi(0.2) = {phi}");
        }
        if phi < undershoot {
            undershoot = phi;
            t_under = t;
        }
        if phi.abs() >= 0.2 {
            settle = t;
        }
    }
    println!("10 deg recovery: undershoot {undershoot:.3} deg at {t_under:.3} s, within 2 % after {settle:.3} s");
    assert!((undershoot + 0.66).abs() < 0.03 && (t_under - 0.49).abs() < 0.03);
    assert!(settle <= 2.1);

    for phi0 in [10.0, 30.0, 90.0, 150.0] {
        let x0 = FullState {
            attitude: tilted(&p, deg(phi0)),
            p_h: Vector3::zeros(),
            p_w: Vector3::zeros(),
        };
        let cfg = RunConfig {
            duration: 15.02,
            ..RunConfig::default()
        };
        let run = simulate(
            &Plant::ideal(p),
            &x0,
            &mut c.clone(),
            &cfg,
            &mut cubli::simulate::quiet,
        )
        .unwrap();
        let last = *run.inclination.last().unwrap();
        assert!(
            last.to_degrees() < 1e-3,
            "phi0 {phi0}: {}",
            last.to_degrees()
        );
    }
}

/// Spec test 20: the hanging rest set is an equilibrium with T = 0; a small tilt leaves it.
#[test]
fn hanging_rest_set() {
    let p = Params::reference();
    let c = Backstepping::new(p, Gains::paper());
    let pw = p.m_hat() * 0.03;
    let hang = ReducedState {
        g: p.m_hat() * 9.81,
        p_h: pw,
        p_w: pw,
    };
    assert!(c.control(&hang).unwrap().amax() < 1e-15);
    let mut x = FullState {
        attitude: tilted(&p, std::f64::consts::PI - 1e-3),
        p_h: Vector3::zeros(),
        p_w: Vector3::zeros(),
    }
    .reduced(&p);
    let mut reached = None;
    for k in 1..=8000 {
        x = reduced_step(&p, &x, 1e-3, |s| c.control(s).unwrap());
        let phi = inclination(&p, &x.g);
        if phi >= 0.1f64.to_radians() {
            reached = None;
        } else if reached.is_none() {
            reached = Some(k as f64 * 1e-3);
        }
    }
    let t = reached.unwrap();
    println!("from 1e-3 rad off hanging: below 0.1 deg for good after {t:.2} s");
    assert!((t - 4.8).abs() < 0.3);
}

/// Spec test 21 (Figs. 1.6 and 1.7): 0.17 N m on wheel 1 for 60 ms, 20 ms ZOH.
#[test]
fn disturbance_rejection() {
    let p = Params::reference();
    let mut c = Backstepping::new(p, Gains::paper());
    let x0 = FullState::from_velocities(&p, tilted(&p, 0.0), &Vector3::zeros(), &Vector3::zeros());
    let cfg = RunConfig {
        duration: 5.01,
        tick: 0.01,
        control_every: 2,
        plant_substeps: 10,
        ..RunConfig::default()
    };
    let mut push = |_k: usize, t: f64| {
        let d = if t < 0.06 - 1e-9 {
            Vector3::new(0.17, 0.0, 0.0)
        } else {
            Vector3::zeros()
        };
        (Vector3::zeros(), d)
    };
    let run = simulate(&Plant::ideal(p), &x0, &mut c, &cfg, &mut push).unwrap();
    let phi: Vec<f64> = run.inclination.iter().map(|v| v.to_degrees()).collect();
    let peak = phi.iter().cloned().fold(0.0, f64::max);
    let settle_5 = run
        .t
        .iter()
        .zip(&phi)
        .filter(|(_, v)| **v > 0.05 * peak)
        .map(|(t, _)| *t)
        .fold(0.0, f64::max);
    let below_rms = run
        .t
        .iter()
        .zip(&phi)
        .filter(|(_, v)| **v > 0.025)
        .map(|(t, _)| *t)
        .fold(0.0, f64::max);
    let wheels = run.omega_w.last().unwrap().norm();
    println!("disturbance: peak {peak:.3} deg, within 5 % of peak after {settle_5:.2} s, below 0.025 deg after {below_rms:.2} s, |w_w(5 s)| = {wheels:.3} rad/s");
    assert!(peak < 0.5);
    assert!(below_rms < 1.8);
    assert!(settle_5 <= 1.8);
    assert!(wheels < 0.2);
}

/// Spec test 22: the integral extension removes a torque bias (V_I non-increasing); ν = 0 does not.
#[test]
fn integral_extension_removes_torque_bias() {
    let p = Params::reference();
    let bias = Vector3::new(0.01, -0.005, 0.0);
    let x0 = FullState::from_velocities(&p, tilted(&p, 0.0), &Vector3::zeros(), &Vector3::zeros());
    let cfg = RunConfig {
        duration: 60.0,
        ..RunConfig::default()
    };
    let final_speed = |nu: f64| {
        let mut c = IntegralBackstepping::new(Backstepping::new(p, Gains::paper()), nu).unwrap();
        let run = simulate(
            &Plant::ideal(p),
            &x0,
            &mut c,
            &cfg,
            &mut |_k: usize, _t: f64| (Vector3::zeros(), bias),
        )
        .unwrap();
        run.omega_w.last().unwrap().norm()
    };
    let (with, without) = (final_speed(5.0), final_speed(0.0));
    println!(
        "torque bias: |w_w(60 s)| = {with:.2e} rad/s with nu = 5, {without:.2} rad/s with nu = 0"
    );
    assert!(with < 0.01);
    assert!((without - 6.7).abs() < 0.3);

    // V_I is non-increasing along the continuous closed loop without bias.
    let mut c = IntegralBackstepping::new(
        Backstepping::new(p, Gains::new(15.0, 18.0, 12.0, 0.5).unwrap()),
        5.0,
    )
    .unwrap();
    let mut x = FullState {
        attitude: tilted(&p, deg(20.0)),
        p_h: Vector3::zeros(),
        p_w: Vector3::new(0.01, 0.0, 0.0),
    }
    .reduced(&p);
    let mut v = c.lyapunov(&x);
    for _ in 0..3000 {
        let u = c.control(&x).unwrap();
        let x1 = reduced_step(&p, &x, 1e-4, |s| u + (c.control(s).unwrap() - u));
        c.advance(&x, 1e-4);
        x = x1;
        let v1 = c.lyapunov(&x);
        assert!(v1 <= v + 1e-6 * v.abs().max(1e-9), "{v1} > {v}");
        v = v1;
    }
    let _ = upright(&p, Vector3::zeros());
}

/// Spec test 22, last part: the integral extension does not remove the wheel spin caused by a
/// wrong centre of mass (true m shifted by (4, −3, 0) g m).
#[test]
fn integral_extension_keeps_centre_of_mass_error() {
    let model = Params::reference();
    let truth = model
        .with_mismatch(1.0, model.m() + Vector3::new(0.004, -0.003, 0.0))
        .unwrap();
    let up = nalgebra::UnitQuaternion::rotation_between(&truth.m_hat(), &Vector3::z()).unwrap();
    let x0 = FullState::from_velocities(&truth, up, &Vector3::zeros(), &Vector3::zeros());
    let cfg = RunConfig {
        duration: 60.0,
        ..RunConfig::default()
    };
    let speed = |nu: f64| {
        let mut c =
            IntegralBackstepping::new(Backstepping::new(model, Gains::paper()), nu).unwrap();
        let run = simulate(
            &Plant::ideal(truth),
            &x0,
            &mut c,
            &cfg,
            &mut cubli::simulate::quiet,
        )
        .unwrap();
        run.omega_w.last().unwrap().norm()
    };
    let (s0, s1, s5) = (speed(0.0), speed(1.0), speed(5.0));
    println!("centre-of-mass error: steady wheel speed {s0:.1} (nu 0), {s1:.1} (nu 1), {s5:.1} (nu 5) rad/s");
    assert!((s0 - 240.0).abs() < 15.0);
    assert!((s1 - 195.0).abs() < 15.0 && (s5 - 195.0).abs() < 15.0);
}

proptest! {
    /// Spec test 36: rotating the attitude about the vertical leaves the torque unchanged, and the
    /// closed loop's inclination history too.
    #[test]
    fn yaw_rotation_invariance(att in attitude(), yaw in -3.1..3.1f64, ph in vec3(0.1), pw in vec3(0.1)) {
        let p = Params::reference();
        let c = Backstepping::new(p, Gains::paper());
        let rot = nalgebra::UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw);
        let a = FullState { attitude: att, p_h: ph, p_w: pw };
        let b = FullState { attitude: rot * att, ..a };
        let (ta, tb) = (c.control(&a.reduced(&p)).unwrap(), c.control(&b.reduced(&p)).unwrap());
        prop_assert!((ta - tb).amax() <= 1e-12 * (1.0 + ta.amax()));
    }
}
