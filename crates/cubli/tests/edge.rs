//! Face → edge jump (the planar Cubli): geometry and closed forms, the planar backstepping law,
//! its poles, learning of the edge wheel speed on nominal and mismatched plants, and learning
//! with a random brake efficiency per trial. Counts are printed.
#![allow(clippy::unwrap_used)]
mod common;

use common::deg;
use cubli::edge::{EdgeJump, EdgeJumpModel};
use cubli::jump::{face_attitude, pre_brake_state, ErrorModel, ImpactModel, Learner};
use cubli::model::inclination;
use cubli::{
    jump_trial, CubliError, Gains, JumpConfig, JumpControllers, JumpOutcome, Limits, Params, Plant,
    ReducedState, TiltPolynomial,
};
use nalgebra::{Complex, Matrix3, SVector, Vector3};
use proptest::prelude::*;
use rand::{Rng, SeedableRng};

/// Independent numbers of the edge e1 of the reference set: I_e = Θ0₁₁, |m⊥||g| from the
/// components of m normal to e1, φ0 = 45°.
fn reference_edge() -> (f64, f64, f64, f64) {
    let p = Params::reference();
    let ie = p.theta0()[(0, 0)];
    let mgl = (p.m()[1].powi(2) + p.m()[2].powi(2)).sqrt() * p.gravity();
    (ie, mgl, std::f64::consts::FRAC_PI_4, p.theta_w()[0])
}

/// Speed needed with the `Lock` brake and efficiency κ on the edge wheel (energy and momentum
/// balance of the planar pendulum): Θw κ θ = (I_e + Θw) √(2 |m⊥||g| (1 − cos φ0) / I_e).
fn lock_speed(ie: f64, mgl: f64, phi0: f64, tw: f64, kappa: f64) -> f64 {
    (ie + tw) / (tw * kappa) * (2.0 * mgl * (1.0 - phi0.cos()) / ie).sqrt()
}

/// The mismatched "true plant" of the corner tests (spec test 33) on edge e1: 5 % heavier
/// housing, shifted centre of mass, lossy brake (κ = 0.90 on wheel 1), 0.2 N m motors.
fn mismatched() -> (Plant, ImpactModel) {
    let p = Params::reference();
    let m = p.m() * 0.97 + Vector3::new(0.002, -0.002, 0.0);
    let full = Plant {
        limits: Limits::cubli(),
        ..Plant::ideal(p.with_mismatch(1.05, m).unwrap())
    };
    let edge = EdgeJump::new(&full.params, 0).unwrap();
    (
        edge.plant(&full).unwrap(),
        ImpactModel::Lossy {
            kappa: Vector3::new(0.90, 0.88, 0.92),
        },
    )
}

fn trial(plant: &Plant, brake: ImpactModel, theta: f64, balance: bool) -> JumpOutcome {
    let edge = EdgeJump::new(&Params::reference(), 0).unwrap();
    let balancer = edge.balancer(Gains::paper());
    let cfg = JumpConfig {
        brake,
        ..JumpConfig::default()
    };
    let controllers = JumpControllers {
        guide: None,
        balance: balance.then_some(&balancer),
    };
    jump_trial(
        plant,
        face_attitude(),
        &Vector3::new(theta, 0.0, 0.0),
        controllers,
        &cfg,
    )
    .unwrap()
}

/// Runs `n` learning trials (free flight, edge balancer after the hand-over); the brake of trial
/// i is `brake(i)`. Returns (θ_i, outcome_i).
fn learn(
    plant: &Plant,
    mut brake: impl FnMut(usize) -> ImpactModel,
    start: f64,
    n: usize,
) -> Vec<(f64, JumpOutcome)> {
    let model = EdgeJumpModel::new(&EdgeJump::new(&Params::reference(), 0).unwrap()).unwrap();
    let learner = Learner::new(&model, 0.8).unwrap();
    let mut theta = SVector::<f64, 1>::new(start);
    (0..n)
        .map(|i| {
            let out = trial(plant, brake(i), theta[0], true);
            let here = theta[0];
            theta = learner.update(&theta, &model.measured(&out.corrected));
            (here, out)
        })
        .collect()
}

#[test]
fn geometry_and_model_root_match_the_closed_form() {
    let (ie, mgl, phi0, tw) = reference_edge();
    let edge = EdgeJump::new(&Params::reference(), 0).unwrap();
    assert!((edge.inertia() - ie).abs() < 1e-15);
    assert!((edge.mg() - mgl).abs() < 1e-12);
    assert!((edge.resting_inclination() - phi0).abs() < 1e-12);
    let model = EdgeJumpModel::new(&edge).unwrap();
    let closed = (2.0 * ie * mgl * (1.0 - phi0.cos())).sqrt() / tw;
    let bar = model.nominal_wheel_speed();
    println!("edge e1: I_e {ie} kg m2, |m_perp||g| {mgl:.4} N m, nominal speed {bar:.2} rad/s, Lock brake {:.2} rad/s", lock_speed(ie, mgl, phi0, tw, 1.0));
    assert!((bar - closed).abs() < 1e-9 * closed, "{bar} vs {closed}");
    assert!(model.predict(&model.root())[0].abs() < 1e-12);
    // Jacobian of the energy error: Θw² θ / I_e.
    assert!((model.jacobian(&model.root())[0] - tw * tw * bar / ie).abs() < 1e-12);
    assert_eq!(
        EdgeJump::new(&Params::reference(), 2),
        Err(CubliError::EdgeAxis { axis: 2 })
    );
}

/// With the ideal brake at the model root the cube rolls up the ideal planar trajectory
/// tan(φ/4) = tan(φ0/4) e^{−ct}, c = √(|m⊥||g|/I_e), and never leaves the plane.
#[test]
fn ideal_edge_jump_follows_the_closed_form() {
    let (ie, mgl, phi0, _) = reference_edge();
    let edge = EdgeJump::new(&Params::reference(), 0).unwrap();
    let p = *edge.params();
    let theta = Vector3::new(
        EdgeJumpModel::new(&edge).unwrap().nominal_wheel_speed(),
        0.0,
        0.0,
    );
    let plant = Plant::ideal(p);
    let mut x = ImpactModel::Ideal.apply(&p, &pre_brake_state(&p, face_attitude(), &theta));
    let c = (mgl / ie).sqrt();
    let mut worst: f64 = 0.0;
    for k in 1..=10_000 {
        x = plant.step(&x, &Vector3::zeros(), 1e-4);
        let t = k as f64 * 1e-4;
        let exact = 4.0 * ((phi0 / 4.0).tan() * (-c * t).exp()).atan();
        worst = worst.max((inclination(&p, &x.gravity_body(&p)) - exact).abs());
        let w = x.omega_h(&p);
        assert!(w[1] == 0.0 && w[2] == 0.0 && x.gravity_body(&p)[0].abs() < 1e-12);
    }
    assert!(worst < 1e-8, "{worst:e}");
    // The hinged 3-D cube has the same momentum about the edge.
    let hinged = edge.hinged_state(&x);
    assert!((hinged.p_h[0] - x.p_h[0]).abs() < 1e-15);
    assert!((hinged.omega_h(edge.full_params()) - x.omega_h(&p)).amax() < 1e-12);
}

proptest! {
    /// The edge balancer is the scalar backstepping law
    /// T = (1 + (α+βγ+δ) I_e) τ − β I_e (m⊥·g) ω + γ (1 + α I_e) p − γ p_w, τ = (m⊥ × g)·e,
    /// on the edge wheel only, also from a measurement that has left the plane.
    #[test]
    fn edge_balancer_is_the_planar_backstepping_law(
        phi in -3.0f64..3.0, p in -0.3f64..0.3, pw in -0.3f64..0.3,
        off in -0.05f64..0.05, q in -0.1f64..0.1,
    ) {
        let (ie, _, _, _) = reference_edge();
        let edge = EdgeJump::new(&Params::reference(), 0).unwrap();
        let k = Gains::paper();
        let ctrl = edge.balancer(k);
        let mp = edge.params().m();
        let up = -mp.normalize();
        let side = Vector3::x().cross(&up);
        let g = (up * phi.cos() + side * phi.sin()) * 9.81;
        let tau = mp.cross(&g)[0];
        let w = (p - pw) / ie;
        let expected = (1.0 + (k.alpha + k.beta * k.gamma + k.delta) * ie) * tau
            - k.beta * ie * mp.dot(&g) * w
            + k.gamma * (1.0 + k.alpha * ie) * p
            - k.gamma * pw;
        let planar = ReducedState { g, p_h: Vector3::new(p, 0.0, 0.0), p_w: Vector3::new(pw, 0.0, 0.0) };
        let t = ctrl.control(&planar).unwrap();
        prop_assert!((t[0] - expected).abs() < 1e-10 * (1.0 + expected.abs()));
        prop_assert!(t[1] == 0.0 && t[2] == 0.0);
        // Off-plane components of a measurement are projected away.
        let tilted = (g + Vector3::new(off, 0.0, 0.0)).normalize() * 9.81;
        let noisy = ReducedState { g: tilted, p_h: Vector3::new(p, q, -q), p_w: Vector3::new(pw, q, q) };
        let tn = ctrl.control(&noisy).unwrap();
        prop_assert!((tn[0] - t[0]).abs() < 1e-9 * (1.0 + t[0].abs()) && tn[1] == 0.0 && tn[2] == 0.0);
    }
}

proptest! {
    /// The plane model with a torque on the edge wheel is the hinge ODE
    /// φ̇ = −(p − p_w)/I_e, ṗ = −|m⊥||g| sin φ, ṗ_w = T (φ signed about e1 in this test's
    /// parametrization), integrated here independently as scalars; the state never leaves the
    /// plane.
    #[test]
    fn plane_model_is_the_hinge_ode(
        psi in -1.0f64..1.0, p0 in -0.1f64..0.1, pw0 in -0.1f64..0.1, torque in -0.3f64..0.3,
    ) {
        let (ie, mgl, _, _) = reference_edge();
        let edge = EdgeJump::new(&Params::reference(), 0).unwrap();
        let p = *edge.params();
        let up = -p.m().normalize();
        let side = Vector3::x().cross(&up);
        let attitude = nalgebra::UnitQuaternion::from_axis_angle(&Vector3::x_axis(), psi);
        let mut x = cubli::FullState {
            attitude,
            p_h: Vector3::new(p0, 0.0, 0.0),
            p_w: Vector3::new(pw0, 0.0, 0.0),
        };
        let angle = |x: &cubli::FullState| {
            let g = x.gravity_body(&p);
            g.dot(&side).atan2(g.dot(&up))
        };
        let f = |s: &Vector3<f64>| Vector3::new(-(s[1] - s[2]) / ie, -mgl * s[0].sin(), torque);
        let mut s = Vector3::new(angle(&x), p0, pw0);
        let plant = Plant::ideal(p);
        let t = Vector3::new(torque, 0.0, 0.0);
        let h = 1e-3;
        for _ in 0..300 {
            x = plant.step(&x, &t, h);
            let k1 = f(&s);
            let k2 = f(&(s + k1 * (h / 2.0)));
            let k3 = f(&(s + k2 * (h / 2.0)));
            let k4 = f(&(s + k3 * h));
            s += (k1 + (k2 + k3) * 2.0 + k4) * (h / 6.0);
        }
        // The free cube may swing through hanging: compare the angles modulo 2π.
        let pi = std::f64::consts::PI;
        let d = (angle(&x) - s[0] + pi).rem_euclid(2.0 * pi) - pi;
        prop_assert!(d.abs() < 1e-8, "{} vs {}", angle(&x), s[0]);
        prop_assert!((x.p_h[0] - s[1]).abs() < 1e-9 && (x.p_w[0] - s[2]).abs() < 1e-12);
        prop_assert!(x.p_h[1] == 0.0 && x.p_h[2] == 0.0 && x.p_w[1] == 0.0 && x.p_w[2] == 0.0);
    }
}

/// The linearized planar closed loop (φ, p, p_w) has the poles of the paper's tilt polynomial
/// (1.31) with |m||g| replaced by |m⊥||g| (the law is inertia independent, spec test 13).
#[test]
fn edge_balancer_poles_follow_the_tilt_polynomial() {
    let (ie, mgl, _, _) = reference_edge();
    let edge = EdgeJump::new(&Params::reference(), 0).unwrap();
    let ctrl = edge.balancer(Gains::paper());
    let mp = *edge.params().m();
    let up = -mp.normalize();
    let side = Vector3::x().cross(&up);
    let f = |s: &Vector3<f64>| {
        let g = (up * s[0].cos() + side * s[0].sin()) * 9.81;
        let x = ReducedState {
            g,
            p_h: Vector3::new(s[1], 0.0, 0.0),
            p_w: Vector3::new(s[2], 0.0, 0.0),
        };
        let t = ctrl.control(&x).unwrap()[0];
        // ġ = −ω e × g gives φ̇ = −ω for this parametrization, and τ = −|m⊥||g| sin φ.
        Vector3::new(-(s[1] - s[2]) / ie, -mgl * s[0].sin(), t)
    };
    let h = 1e-6;
    let a = Matrix3::from_fn(|i, j| {
        let e = Vector3::ith(j, h);
        (f(&e) - f(&-e))[i] / (2.0 * h)
    });
    let mut got: Vec<Complex<f64>> = a.complex_eigenvalues().iter().copied().collect();
    got.sort_by(|x, y| y.re.total_cmp(&x.re));
    let want = TiltPolynomial::from_gains(&Gains::paper(), mgl).poles();
    println!("edge balancer poles {got:.3?}");
    for (g, w) in got.iter().zip(want.iter()) {
        assert!((g - w).norm() < 1e-4 * w.norm(), "{g} vs {w}");
        assert!(g.re < 0.0);
    }
}

/// On the nominal plant the learner converges to the closed-form speeds: θ̄ with the ideal brake,
/// (I_e + Θw)/I_e θ̄ with the Lock brake.
#[test]
fn nominal_learning_converges_to_the_closed_form() {
    let (ie, mgl, phi0, tw) = reference_edge();
    let edge = EdgeJump::new(&Params::reference(), 0).unwrap();
    let plant = Plant::ideal(*edge.params());
    let bar = EdgeJumpModel::new(&edge).unwrap().nominal_wheel_speed();
    for (brake, closed) in [
        (ImpactModel::Ideal, bar),
        (ImpactModel::Lock, lock_speed(ie, mgl, phi0, tw, 1.0)),
    ] {
        let run = learn(&plant, |_| brake, 0.8 * bar, 12);
        let last = run[11].0;
        println!(
            "nominal plant, {brake:?}: learned {last:.3} rad/s, closed form {closed:.3} rad/s"
        );
        assert!((last - closed).abs() < 0.05, "{last} vs {closed}");
        assert!(run[11].1.success);
    }
}

/// Issue acceptance for the edge jump: from 20 % too slow and 20 % too fast, learning on the
/// mismatched plant reaches a successful jump (hand-over and balanced within 0.5°) within the
/// paper's "about 5 trials", keeps succeeding, and converges to the plant's closed-form speed.
#[test]
fn edge_learning_from_twenty_percent_error_succeeds() {
    let (plant, brake) = mismatched();
    let truth = EdgeJump::new(&plant.params, 0).unwrap();
    let star = lock_speed(
        truth.inertia(),
        truth.mg(),
        truth.resting_inclination(),
        plant.params.theta_w()[0],
        0.90,
    );
    let bar = EdgeJumpModel::new(&EdgeJump::new(&Params::reference(), 0).unwrap())
        .unwrap()
        .nominal_wheel_speed();
    for scale in [0.8, 1.2] {
        let run = learn(&plant, |_| brake, scale * bar, 10);
        let ok: Vec<bool> = run.iter().map(|(_, o)| o.success).collect();
        let first = ok.iter().position(|s| *s).unwrap();
        let speeds: Vec<f64> = run.iter().map(|(t, _)| *t).collect();
        println!(
            "edge, start {scale} x nominal ({:.1} rad/s): first success at trial {} ({ok:?}), speeds {speeds:.2?}, plant closed form {star:.2}",
            scale * bar,
            first + 1
        );
        assert!(first < 5 && ok[first..].iter().all(|s| *s));
        assert!((speeds[9] - star).abs() < 0.1, "{} vs {star}", speeds[9]);
        assert!(run[9].1.final_inclination < deg(0.5));
        if scale < 1.0 {
            assert!(!ok[0], "the 20 % too slow jump must fail before learning");
        }
    }
}

/// Spec §5.1 option: a random brake efficiency per trial (κ of every wheel scaled by
/// U(1 − s, 1 + s), seeded). Learning still converges: after a few trials the speeds stay inside
/// the band the closed form gives for the extreme efficiencies. What it cannot remove is the
/// trial-to-trial scatter itself, so the success rate is compared with an oracle that always
/// uses the plant's exact speed for the mean efficiency under the same random brakes.
#[test]
fn edge_learning_with_random_brake_efficiency() {
    let (plant, brake) = mismatched();
    let truth = EdgeJump::new(&plant.params, 0).unwrap();
    let speed = |kappa: f64| {
        lock_speed(
            truth.inertia(),
            truth.mg(),
            truth.resting_inclination(),
            plant.params.theta_w()[0],
            kappa,
        )
    };
    let bar = EdgeJumpModel::new(&EdgeJump::new(&Params::reference(), 0).unwrap())
        .unwrap()
        .nominal_wheel_speed();
    let n = 25;
    for (spread, min_rate) in [(0.01, 0.95), (0.03, 0.5)] {
        let mut rng = rand::rngs::StdRng::seed_from_u64(51);
        let brakes: Vec<ImpactModel> = (0..n)
            .map(|_| {
                let f = Vector3::from_fn(|_, _| rng.random_range(1.0 - spread..1.0 + spread));
                brake.scaled(&f).unwrap()
            })
            .collect();
        let run = learn(&plant, |i| brakes[i], 0.8 * bar, n);
        let ok: Vec<bool> = run.iter().map(|(_, o)| o.success).collect();
        let first = ok.iter().position(|s| *s).unwrap();
        let settled = 8;
        let rate = |v: &[bool]| v.iter().filter(|s| **s).count() as f64 / v.len() as f64;
        let oracle: Vec<bool> = brakes[settled..]
            .iter()
            .map(|b| trial(&plant, *b, speed(0.90), true).success)
            .collect();
        let (lo, hi) = (speed(0.90 * (1.0 + spread)), speed(0.90 * (1.0 - spread)));
        let speeds: Vec<f64> = run.iter().map(|(t, _)| *t).collect();
        println!(
            "random brake efficiency +-{spread}: first success at trial {}, success rate from trial {} on {:.2} (oracle at the mean-efficiency speed {:.2}), speeds {speeds:.1?} (band {lo:.1}..{hi:.1})",
            first + 1,
            settled + 1,
            rate(&ok[settled..]),
            rate(&oracle)
        );
        assert!(first < 5, "first success after trial 5");
        assert!(rate(&ok[settled..]) >= min_rate, "{ok:?}");
        assert!(rate(&ok[settled..]) >= rate(&oracle) - 0.25);
        for t in &speeds[settled..] {
            assert!(*t > lo - 1.0 && *t < hi + 1.0, "{t} outside {lo}..{hi}");
        }
    }
}

/// A free (unbalanced) trial still measures at the top point, and the error is the housing
/// energy there: too slow stops short of upright with H_h < 0.
#[test]
fn free_edge_trial_measures_the_energy_at_the_top_point() {
    let edge = EdgeJump::new(&Params::reference(), 0).unwrap();
    let plant = Plant::ideal(*edge.params());
    let bar = EdgeJumpModel::new(&edge).unwrap().nominal_wheel_speed();
    let (ie, mgl, phi0, tw) = reference_edge();
    let out = trial(&plant, ImpactModel::Ideal, 0.9 * bar, false);
    let expected = 0.5 * (tw * 0.9 * bar).powi(2) / ie - mgl * (1.0 - phi0.cos());
    assert!(out.error[2] < 0.0 && !out.success);
    assert!(
        (out.error[2] - expected).abs() < 1e-6,
        "{} vs {expected}",
        out.error[2]
    );
    // At the top point the energy is all potential: H_h = −|m⊥||g|(1 − cos φ_top).
    let top = -mgl * (1.0 - out.top_inclination.cos());
    assert!((out.error[2] - top).abs() < 1e-3 * expected.abs());
}

/// A centre-of-mass error leaves the edge wheel spinning in steady state (as for the corner,
/// spec §3.3): with ω = 0 and T = 0 the law gives γαI_e p = −(1 + (α+βγ+δ)I_e) τ_model, where
/// τ_model is the gravity torque the model computes at the true upright.
#[test]
fn centre_of_mass_error_leaves_the_predicted_wheel_speed() {
    use cubli::simulate::{quiet, simulate, RunConfig};
    let (plant, _) = mismatched();
    let model = EdgeJump::new(&Params::reference(), 0).unwrap();
    let mut ctrl = model.balancer(Gains::paper());
    let m_true = *plant.params.m();
    let m_model = *model.params().m();
    // At rest, 1° off the true upright (centre of mass straight above the edge).
    let up_true = m_true.normalize();
    let attitude = nalgebra::UnitQuaternion::rotation_between(&up_true, &Vector3::z()).unwrap();
    let x0 = cubli::FullState::from_velocities(
        &plant.params,
        attitude * nalgebra::UnitQuaternion::from_axis_angle(&Vector3::x_axis(), deg(1.0)),
        &Vector3::zeros(),
        &Vector3::zeros(),
    );
    let cfg = RunConfig {
        duration: 20.0,
        ..RunConfig::default()
    };
    let run = simulate(&plant, &x0, &mut ctrl, &cfg, &mut quiet).unwrap();
    let k = Gains::paper();
    let ie = model.inertia();
    let g_true = up_true * -9.81;
    let tau = m_model.cross(&g_true)[0];
    let p = -(1.0 + (k.alpha + k.beta * k.gamma + k.delta) * ie) * tau / (k.gamma * k.alpha * ie);
    let expected = p / plant.params.theta_w()[0];
    let got = run.omega_w.last().unwrap()[0];
    println!("edge, centre-of-mass error: wheel speed {got:.2} rad/s, predicted {expected:.2}");
    assert!(*run.inclination.last().unwrap() < deg(0.01));
    assert!(expected.abs() > 10.0);
    assert!(
        (got - expected).abs() < 1e-3 * expected.abs(),
        "{got} vs {expected}"
    );
}
