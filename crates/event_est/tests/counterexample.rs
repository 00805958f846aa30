//! The two-agent counterexample of App. F (spec 8.4, acceptance tests 1–3): with communicated
//! inputs agent 2 tracks a diverging state perfectly and never transmits; with reconstructed
//! inputs one transmission at k = 1 brings the state to zero at k = 2.
#![allow(clippy::unwrap_used)]

use event_est::linalg::{max_eigenvalue, spectral_radius};
use event_est::model::counterexample;
use event_est::runtime::InputMode;
use event_est::sim::{simulate, Design, SimConfig, SimLog};
use nalgebra::{DMatrix, DVector};

fn run(mode: InputMode, steps: usize) -> SimLog {
    let (sys, l) = counterexample().unwrap();
    let mut cfg = SimConfig::new(&sys, steps, None, 1);
    cfg.loss = 0.0;
    cfg.input_mode = mode;
    cfg.x0 = DVector::from_vec(vec![0.0, 2.0]);
    cfg.xhat0 = vec![
        DVector::from_vec(vec![0.0, 1.0]),
        DVector::from_vec(vec![0.0, 2.0]),
    ];
    cfg.record = true;
    simulate(&sys, &Design::scalar(l, &[1.0, 1.0]), &cfg)
        .unwrap()
        .log
        .unwrap()
}

fn close(a: &DVector<f64>, b: &[f64]) -> bool {
    let b = DVector::from_column_slice(b);
    (a - &b).norm() <= 1e-12 * b.norm().max(1.0)
}

#[test]
fn communicated_inputs_diverge_without_any_transmission() {
    let log = run(InputMode::Communicated, 20);
    assert!(close(&log.u[0], &[-2.0, 0.0]));
    for k in 1..=20 {
        let two_k = 2f64.powi(k as i32);
        assert!(
            log.fired[k].iter().all(|f| !f),
            "k = {k}: someone transmitted"
        );
        assert!(close(&log.x[k], &[0.0, two_k]), "x({k}) = {}", log.x[k]);
        assert!(close(&log.xhat[k][1], &[0.0, two_k]));
        assert!(close(&log.xhat[k][0], &[0.0, 0.0]));
        if k < 20 {
            assert!(close(&log.u[k], &[0.0, 0.0]), "u({k}) = {}", log.u[k]);
        }
    }
}

#[test]
fn reconstructed_inputs_reach_zero_from_k_2() {
    let log = run(InputMode::Reconstructed, 20);
    assert_eq!(
        log.fired[1],
        vec![false, true],
        "only agent 2 fires at k = 1"
    );
    assert!(close(&log.xhat[1][0], &[0.0, 2.0]) && close(&log.xhat[1][1], &[0.0, 2.0]));
    assert!(close(&log.u[0], &[-2.0, 0.0]));
    assert!(close(&log.u[1], &[-4.0, 0.0]), "u(1) = {}", log.u[1]);
    for k in 2..=20 {
        assert!(log.fired[k].iter().all(|f| !f));
        assert_eq!(log.x[k], DVector::zeros(2), "x({k})");
        assert_eq!(log.xhat[k][0], DVector::zeros(2));
        assert_eq!(log.xhat[k][1], DVector::zeros(2));
    }
}

#[test]
fn cor12_certificate_with_identity() {
    let (sys, l) = counterexample().unwrap();
    let af = sys.a_cl();
    assert!((spectral_radius(&af) - 0.6).abs() < 1e-12);
    let est = (DMatrix::identity(2, 2) - &l * &sys.c) * &sys.a;
    assert!(spectral_radius(&est) < 1e-12);
    let p = DMatrix::<f64>::identity(2, 2);
    let expected = [-0.64, -1.0, -0.64, -1.0]; // S = ∅, {1}, {2}, {1,2}
    for (subset, want) in expected.iter().enumerate() {
        let acl = (DMatrix::identity(2, 2) - sys.lc_subset(&l, subset as u64)) * &af;
        let m = max_eigenvalue(&(acl.transpose() * &p * &acl - &p));
        assert!((m - want).abs() < 1e-12, "S = {subset:b}: {m}");
    }
}

#[test]
fn reset_period_matches_the_recursion_and_vanishes_for_a_certified_design() {
    use event_est::synth::reset_schedule;
    let (sys, l) = counterexample().unwrap();
    // P = I certifies Cor 12 (λ̄ = −0.64): with small disturbances V̂ stays below V_max.
    let eye = DMatrix::<f64>::identity(2, 2);
    let certified = reset_schedule(&sys, &l, &eye, &eye, 1e-3, 1.0).unwrap();
    assert!((certified.lambda_bar + 0.64).abs() < 1e-12);
    assert_eq!(certified.k_reset, None);
    // Three times the gain over-corrects x_1 (A_cl({1}) = diag(−1.2, 0)): λ̄ = 0.44 > 0 with
    // P = I, so V̂ grows and resets are periodic.
    let triple = &l * 3.0;
    let relaxed = reset_schedule(&sys, &triple, &eye, &eye, 0.1, 4.0).unwrap();
    assert!((relaxed.lambda_bar - 0.44).abs() < 1e-12 && relaxed.a > 1.0);
    let k_reset = relaxed.k_reset.unwrap();
    // The closed form equals the first k at which V̂(k) = a V̂(k−1) + β reaches V_max.
    let (mut v, mut k) = (0.0, 0);
    while v < 4.0 {
        v = relaxed.a * v + relaxed.beta;
        k += 1;
    }
    assert_eq!(k, k_reset);
    assert!(reset_schedule(&sys, &triple, &eye, &(-&eye), 0.1, 4.0).is_err());
}

/// Acceptance test 23, simulation half: a relaxed design (P = I certifies only λ̄ ≈ 0.30 > 0
/// because L_1 = 2.9 over-corrects x_1, A_cl({1}) = diag(−1.14, 0)) under injected disturbances
/// |δ_i| ≤ r (so |d_ji| ≤ D = 2r) keeps |ε_ji| ≤ sqrt(V_max/σ_lo) at every step when all
/// estimates are reset every k_reset steps; without resets the same run leaves that level.
#[test]
fn periodic_resets_keep_the_inter_agent_error_within_the_reset_level() {
    use event_est::synth::reset_schedule;
    let (sys, _) = counterexample().unwrap();
    let l = DMatrix::from_diagonal(&DVector::from_vec(vec![2.9, 1.0]));
    // Full communication stays stable: ρ((I − LC)A) = 0.95.
    assert!(spectral_radius(&((DMatrix::identity(2, 2) - &l * &sys.c) * &sys.a)) < 1.0);
    let eye = DMatrix::<f64>::identity(2, 2);
    let (r, v_max) = (0.05, 1.0);
    let schedule = reset_schedule(&sys, &l, &eye, &eye, 2.0 * r, v_max).unwrap();
    assert!((schedule.lambda_bar - (1.14f64.powi(2) - 1.0)).abs() < 1e-12);
    let k_reset = schedule.k_reset.unwrap();
    let level = (v_max / schedule.sigma_lo).sqrt();
    // Small thresholds: both agents transmit almost always, the growing pattern {1,2} dominates.
    let design = Design::scalar(l, &[1e-3, 1e-3]);
    for seed in 0..4 {
        let mut cfg = SimConfig::new(&sys, 400, None, 23 + seed);
        cfg.loss = 0.0;
        cfg.x0 = DVector::from_vec(vec![0.0, 2.0]);
        cfg.estimate_disturbance = Some(r);
        cfg.reset_period = Some(k_reset);
        let with = simulate(&sys, &design, &cfg).unwrap();
        assert!(
            with.max_inter_agent <= level,
            "seed {seed}: max |ε| = {} > {level} with resets every {k_reset} steps",
            with.max_inter_agent
        );
        cfg.reset_period = None;
        let without = simulate(&sys, &design, &cfg).unwrap();
        assert!(
            without.max_inter_agent > level,
            "seed {seed}: without resets max |ε| = {} stayed below {level}",
            without.max_inter_agent
        );
    }
    let mut bad = SimConfig::new(&sys, 10, None, 0);
    bad.estimate_disturbance = Some(-1.0);
    assert!(simulate(&sys, &design, &bad).is_err());
}

/// ISS bound (5.22) of Thm 11 with the constants of the proof (σ_hi in the contractive case):
/// for random communication patterns and random bounded d, |ε(k)| never exceeds
/// a^{k/2} sqrt(σ_hi/σ_lo)|ε(0)| + sqrt(b/σ_lo) Σ_l a^{l/2} |d(k−l)| (acceptance test 24).
fn iss_bound_holds(seed: u64, p1: &DMatrix<f64>, p2: &DMatrix<f64>) {
    use rand::{rngs::StdRng, Rng, SeedableRng};
    let (sys, l) = counterexample().unwrap();
    let af = sys.a_cl();
    let acl = |s: u64| (DMatrix::identity(2, 2) - sys.lc_subset(&l, s)) * &af;
    let mut lambda_bar = f64::NEG_INFINITY;
    let mut b = 0.0f64;
    for s in 0..4u64 {
        let pk = if s == 0 { p2 } else { p1 };
        for pl in [p1, p2] {
            lambda_bar = lambda_bar.max(max_eigenvalue(&(acl(s).transpose() * pk * acl(s) - pl)));
        }
    }
    assert!(lambda_bar < 0.0);
    let alpha = -lambda_bar / 2.0;
    for s in 0..4u64 {
        for pm in [p1, p2] {
            let g = (pm * acl(s)).norm();
            b = b.max(g * g / alpha + pm.norm());
        }
    }
    let ev = |p: &DMatrix<f64>| p.symmetric_eigenvalues();
    let sigma_lo = ev(p1).min().min(ev(p2).min());
    let sigma_hi = ev(p1).max().max(ev(p2).max());
    let a = 1.0 + (lambda_bar + alpha) / sigma_hi;
    let mut rng = StdRng::seed_from_u64(seed);
    let mut eps = DVector::from_vec(vec![
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
    ]);
    let eps0 = eps.norm();
    let mut d_norms = Vec::new();
    for k in 1..=200 {
        let pattern = rng.random_range(0..4u64);
        let d = DVector::from_vec(vec![
            rng.random_range(-0.1..0.1),
            rng.random_range(-0.1..0.1),
        ]);
        d_norms.push(d.norm());
        eps = acl(pattern) * eps + d;
        let forced: f64 = (0..k)
            .map(|l| a.powf(l as f64 / 2.0) * d_norms[k - 1 - l])
            .sum();
        let bound = a.powf(k as f64 / 2.0) * (sigma_hi / sigma_lo).sqrt() * eps0
            + (b / sigma_lo).sqrt() * forced;
        assert!(
            eps.norm() <= bound * (1.0 + 1e-12),
            "k = {k}: {} > {bound}",
            eps.norm()
        );
    }
}

proptest::proptest! {
    #[test]
    fn iss_bound_of_theorem_11(seed in 0u64..1_000_000, scale in 1.0f64..3.0) {
        // P_1 = I and P_2 = diag(1, scale) both certify the counterexample's patterns.
        let p2 = DMatrix::from_diagonal(&DVector::from_vec(vec![1.0, scale]));
        iss_bound_holds(seed, &DMatrix::identity(2, 2), &p2);
    }
}
