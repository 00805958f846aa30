//! User-supplied model with matrix thresholds (acceptance test 26). The thesis does not print
//! the two-arm pendulum's matrices, so this is a STAND-IN model with the paper's structure
//! (6 states, agent 1 measures (ϕ1, ϕ̇1, θ̇), agent 2 measures (ϕ2, ϕ̇2), 10 ms, the paper's
//! noise levels, 10 % loss); its numbers are not comparable with the paper's.
#![allow(clippy::unwrap_used)]

use event_est::model::{System, UniformNoise};
use event_est::sim::{simulate, SimConfig};
use event_est::synth::{g1_norm, step1, synthesize, Stability};
use nalgebra::{DMatrix, DVector};
use rigid_body::lti;

fn stand_in_pendulum() -> (System, UniformNoise) {
    // x = (θ, θ̇, ϕ1, ϕ̇1, ϕ2, ϕ̇2); arms follow rate commands with a 0.1 s lag and push the
    // pendulum back through their reaction: θ̈ = 30 θ − 0.5 (ϕ̈1 + ϕ̈2), ϕ̈i = 10 (ui − ϕ̇i).
    let mut ac = DMatrix::zeros(6, 6);
    let mut bc = DMatrix::zeros(6, 2);
    ac[(0, 1)] = 1.0;
    ac[(1, 0)] = 30.0;
    for i in 0..2 {
        let (p, v) = (2 + 2 * i, 3 + 2 * i);
        ac[(p, v)] = 1.0;
        ac[(v, v)] = -10.0;
        bc[(v, i)] = 10.0;
        ac[(1, v)] = 5.0; // −0.5 · (−10 ϕ̇i)
        bc[(1, i)] = -5.0; // −0.5 · 10 ui
    }
    let (a, b) = lti::c2d_zoh(&ac, &bc, 0.01).unwrap();
    let k = lti::dlqr(
        &a,
        &b,
        &DMatrix::identity(6, 6),
        &(DMatrix::identity(2, 2) * 10.0),
    )
    .unwrap()
    .k;
    let mut c = DMatrix::zeros(5, 6);
    for (row, col) in [(0, 2), (1, 3), (2, 1), (3, 4), (4, 5)] {
        c[(row, col)] = 1.0;
    }
    let deg = std::f64::consts::PI / 180.0;
    let sigma = [0.05 * deg, 0.1 * deg, 0.24 * deg, 0.05 * deg, 0.1 * deg];
    let w = DMatrix::from_diagonal(&DVector::from_iterator(5, sigma.iter().map(|s| s * s)));
    let v_sqrt = &b * (1.73 * deg);
    let sys = System::new(a, b, c, -k, vec![3, 2], vec![1, 1], w, v_sqrt).unwrap();
    let noise = UniformNoise {
        output: sigma.iter().map(|s| s * 3f64.sqrt()).collect(),
        input: vec![1.73 * deg * 3f64.sqrt(); 2],
    };
    (sys, noise)
}

#[test]
fn stand_in_pendulum_runs_through_both_steps_with_matrix_thresholds() {
    let (sys, noise) = stand_in_pendulum();
    let thm11 = step1(&sys, Stability::Thm11).unwrap();
    let cor12 = step1(&sys, Stability::Cor12).unwrap();
    assert!(thm11.c_star <= cor12.c_star * (1.0 + 1e-3));
    let syn = synthesize(&sys, Stability::Cor12, 5.0 * cor12.c_star).unwrap();
    let (d1, d2) = (&syn.design.delta[0], &syn.design.delta[1]);
    assert_eq!((d1.nrows(), d2.nrows()), (3, 2));
    // Full symmetric positive definite blocks, coupling the agent's different sensors.
    assert!(d1.clone().cholesky().is_some() && d2.clone().cholesky().is_some());
    assert!((d1 - d1.transpose()).amax() < 1e-12);
    let gamma = event_est::synth::budget_gamma(&sys, syn.step1.c_star, syn.j_max).unwrap();
    assert!(g1_norm(&sys, &syn.design).unwrap() <= gamma.sqrt() * (1.0 + 1e-3));
    assert!(syn.bound.bound <= syn.j_max * (1.0 + 1e-3));

    let mut cfg = SimConfig::new(&sys, 15_000, Some(noise), 4); // 150 s
    cfg.x0[0] = 0.02;
    cfg.window_start = 5_000;
    let r = simulate(&sys, &syn.design, &cfg).unwrap();
    println!(
        "c* {:.3e}, rates {:?}, ‖e‖_P {:.3e}",
        syn.step1.c_star, r.rates, r.error_power
    );
    assert!(r.max_state < 1.0, "diverged: {}", r.max_state);
    assert!(r.total_rate < 1.0 && r.total_rate > 0.0);
    assert!(r.error_power < syn.j_max);
}
