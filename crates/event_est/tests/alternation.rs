//! Step 1/Step 2 alternation (spec 6.3) on the 3-vehicle platoon: every accepted gain step lowers
//! the certified bound at fixed thresholds, every threshold step enlarges Σ tr Δ_i at the same
//! J_max, and the result beats Step 1 + Step 2. Each iterate is re-checked against references
//! written here independently of the crate: the H2 cost by summing the impulse response, the
//! H∞ norm on a dense uniform frequency grid, the stability inequalities by eigenvalues, and the
//! error power of a networked simulation.
#![allow(clippy::unwrap_used)]

use event_est::alternation::{alternate, Alternation};
use event_est::model::{platoon, System};
use event_est::sim::{simulate, Design, SimConfig};
use event_est::synth::{complete_with, step1, BudgetBase, Stability};
use nalgebra::{Complex, DMatrix};
use std::sync::OnceLock;

const J_MAX: f64 = 0.38;

fn platoon_run() -> &'static (System, Alternation) {
    static RUN: OnceLock<(System, Alternation)> = OnceLock::new();
    RUN.get_or_init(|| {
        let sys = platoon(3).unwrap().0;
        let alt = alternate(&sys, Stability::Cor12, J_MAX, 20).unwrap();
        (sys, alt)
    })
}

fn a_hat(sys: &System, l: &DMatrix<f64>) -> DMatrix<f64> {
    (DMatrix::identity(sys.n(), sys.n()) - l * &sys.c) * &sys.a
}

/// ‖G_2‖²_2 = Σ_k ‖Â^k B̂‖²_F, summed until the terms are negligible.
fn h2_by_impulse_response(sys: &System, l: &DMatrix<f64>) -> f64 {
    let n = sys.n();
    let w_half = sys.w.map(f64::sqrt); // W is diagonal for the platoon
    let mut b = DMatrix::zeros(n, sys.p() + sys.v_sqrt.ncols());
    b.columns_mut(0, sys.p()).copy_from(&-(l * w_half));
    b.columns_mut(sys.p(), sys.v_sqrt.ncols())
        .copy_from(&((DMatrix::identity(n, n) - l * &sys.c) * &sys.v_sqrt));
    let a = a_hat(sys, l);
    let (mut sum, mut term) = (0.0, b);
    for _ in 0..200_000 {
        let t = term.norm_squared();
        sum += t;
        if t < 1e-18 * sum {
            break;
        }
        term = &a * term;
    }
    sum
}

/// max over a uniform grid of 20 001 frequencies in [0, π] of σ_max((e^{jω}I − Â)^{-1} L Δ).
fn hinf_on_grid(sys: &System, design: &Design) -> f64 {
    let n = sys.n();
    let a = a_hat(sys, &design.l);
    let delta = DMatrix::from_diagonal(&nalgebra::DVector::from_iterator(
        sys.p(),
        design.delta.iter().map(|d| d[(0, 0)]),
    ));
    let b = (&design.l * delta).map(|v| Complex::new(v, 0.0));
    (0..=20_000)
        .map(|k| {
            let w = std::f64::consts::PI * k as f64 / 20_000.0;
            let z = Complex::new(w.cos(), w.sin());
            let m = DMatrix::from_fn(n, n, |i, j| {
                let d = if i == j { z } else { Complex::new(0.0, 0.0) };
                d - Complex::new(a[(i, j)], 0.0)
            });
            let g = m.lu().solve(&b).unwrap();
            g.singular_values().max()
        })
        .fold(0.0, f64::max)
}

#[test]
fn starts_at_the_two_step_design_and_enlarges_the_thresholds() {
    let (sys, alt) = platoon_run();
    let two_step = complete_with(
        sys,
        step1(sys, Stability::Cor12).unwrap(),
        J_MAX,
        BudgetBase::ExactH2,
    )
    .unwrap();
    let first = &alt.iterates[0];
    for (a, b) in first.design.delta.iter().zip(&two_step.design.delta) {
        assert!((a - b).norm() <= 1e-4 * b.norm(), "{a} vs {b}");
    }
    // Measured: 8 accepted iterations, Σ tr Δ 0.3510 → 0.4186 (+19 %).
    assert!(alt.iterates.len() >= 4, "stop: {}", alt.stop);
    let last = &alt.iterates[alt.iterates.len() - 1];
    assert!(
        last.trace_delta >= 1.1 * first.trace_delta,
        "Σ tr Δ {} → {} ({})",
        first.trace_delta,
        last.trace_delta,
        alt.stop
    );
}

#[test]
fn every_accepted_step_improves_its_certified_objective() {
    let (_, alt) = platoon_run();
    for (k, w) in alt.iterates.windows(2).enumerate() {
        let gain_bound = w[1].gain_step_bound.unwrap();
        // Gain step: the exact bound at the previous thresholds went down.
        assert!(
            gain_bound < w[0].bound.bound,
            "iteration {}: {} ≥ {}",
            k + 1,
            gain_bound,
            w[0].bound.bound
        );
        // Threshold step: Σ tr Δ_i went up at the same J_max.
        assert!(
            w[1].trace_delta > w[0].trace_delta,
            "iteration {}: Σ tr Δ {} → {}",
            k + 1,
            w[0].trace_delta,
            w[1].trace_delta
        );
        assert!(w[1].step_size.unwrap() > 0.0);
    }
}

#[test]
fn every_iterate_is_certified_by_independent_recomputation() {
    let (sys, alt) = platoon_run();
    let ns = (sys.measuring_agents() as f64).sqrt();
    for (k, it) in alt.iterates.iter().enumerate() {
        let h2 = h2_by_impulse_response(sys, &it.design.l).sqrt();
        assert!(
            (h2 - it.bound.g2_h2).abs() <= 1e-6 * h2,
            "iterate {k}: H2 {h2} vs {}",
            it.bound.g2_h2
        );
        let g1 = hinf_on_grid(sys, &it.design);
        // Two sweeps of the same norm: the crate's (log grid refined around its best point)
        // and this uniform one agree to 1e-5 (measured: ≤ 5e-6, the uniform grid finds a
        // slightly higher peak for some iterates; the bound keeps its 1e-3 tolerance).
        assert!(
            (g1 - it.bound.g1_hinf).abs() <= 1e-5 * g1,
            "iterate {k}: H∞ {g1} vs {}",
            it.bound.g1_hinf
        );
        assert!(ns * g1 + h2 <= J_MAX * (1.0 + 1e-3), "iterate {k}");
        // Cor 12: one P with A_cl(S)ᵀPA_cl(S) − P ≺ 0 for all 8 patterns.
        let p = &it.stability_certificate;
        assert!(p.clone().cholesky().is_some());
        let af = sys.a_cl();
        for s in 0..8u64 {
            let mut lc = DMatrix::zeros(sys.n(), sys.n());
            for m in (0..3).filter(|m| s >> m & 1 == 1) {
                lc += it.design.l.column(m) * sys.c.row(m);
            }
            let acl = (DMatrix::identity(sys.n(), sys.n()) - lc) * &af;
            let lyap = acl.transpose() * p * &acl - p;
            let max = lyap.symmetric_eigen().eigenvalues.max();
            assert!(max < 0.0, "iterate {k}, pattern {s}: {max}");
        }
    }
}

#[test]
fn alternated_design_keeps_the_bound_and_communicates_less_in_simulation() {
    let (sys, alt) = platoon_run();
    let noise = platoon(3).unwrap().1;
    let run = |design: &Design| {
        let mut cfg = SimConfig::new(sys, 50_000, Some(noise.clone()), 11);
        cfg.loss = 0.0;
        simulate(sys, design, &cfg).unwrap()
    };
    let first = run(&alt.iterates[0].design);
    let last = run(&alt.iterates[alt.iterates.len() - 1].design);
    assert!(last.error_power < J_MAX, "{}", last.error_power);
    assert!(
        last.total_rate < first.total_rate,
        "rate {} vs two-step {}",
        last.total_rate,
        first.total_rate
    );
}

#[test]
fn cor13_vertices_also_admit_certified_gain_steps() {
    // Measured: 7 iterations, Σ tr Δ 0.3477 → 0.4150; every iterate's Lyapunov matrix
    // certifies the N + 1 vertices (A+BF and (I − N L_m C_m)(A+BF)).
    let sys = platoon(3).unwrap().0;
    let alt = alternate(&sys, Stability::Cor13, J_MAX, 20).unwrap();
    let (first, last) = (&alt.iterates[0], &alt.iterates[alt.iterates.len() - 1]);
    assert!(last.trace_delta >= 1.1 * first.trace_delta, "{}", alt.stop);
    for it in &alt.iterates {
        assert_eq!(it.stability_margins.len(), 4);
        assert!(it.stability_margins.iter().all(|(_, m)| *m < 0.0));
        assert!(it.bound.bound <= J_MAX * (1.0 + 1e-3));
    }
}

#[test]
fn alternation_rejects_two_matrix_certificates() {
    let sys = platoon(3).unwrap().0;
    assert!(alternate(&sys, Stability::Thm11, 0.38, 2).is_err());
}

/// The spec's Δ-dependent example output z = q = Δ^{-1}(y − C x̂⁻) (Ĉ = Δ^{-1}CA, D̂ = Δ^{-1}[W^½,
/// CV^½]) makes "max Σ tr Δ_i s.t. √N_s‖G₁‖∞ + ‖G₂‖₂ ≤ J_max" ill-posed: G₁ = Δ^{-1}CA(zI − Â)^{-1}LΔ
/// does not change under Δ → tΔ while ‖G₂‖₂ falls as 1/t, so the bound decreases towards
/// √N_s‖G₁‖∞ for growing t: unbounded thresholds when J_max exceeds that limit, no feasible Δ
/// of this shape otherwise. Hence the alternation is implemented for the estimation error z = e.
#[test]
fn innovation_output_bound_is_monotone_in_the_threshold_scale() {
    use event_est::linalg::{dlyap, hinf_norm};
    let (sys, alt) = platoon_run();
    let design = &alt.iterates[0].design;
    let l = &design.l;
    let a = a_hat(sys, l);
    let ca = &sys.c * &sys.a;
    let w_half = sys.w.map(f64::sqrt);
    let mut b = DMatrix::zeros(sys.n(), sys.p() + sys.v_sqrt.ncols());
    b.columns_mut(0, sys.p()).copy_from(&-(l * &w_half));
    b.columns_mut(sys.p(), sys.v_sqrt.ncols())
        .copy_from(&((DMatrix::identity(sys.n(), sys.n()) - l * &sys.c) * &sys.v_sqrt));
    let mut d = DMatrix::zeros(sys.p(), b.ncols());
    d.columns_mut(0, sys.p()).copy_from(&w_half);
    d.columns_mut(sys.p(), sys.v_sqrt.ncols())
        .copy_from(&(&sys.c * &sys.v_sqrt));
    let sigma = dlyap(&a, &(&b * b.transpose()), "test").unwrap();
    let bound = |t: f64| {
        let delta = DMatrix::from_diagonal(&nalgebra::DVector::from_iterator(
            sys.p(),
            design.delta.iter().map(|x| t * x[(0, 0)]),
        ));
        let inv = delta.clone().try_inverse().unwrap();
        let c_hat = &inv * &ca;
        let g1 = hinf_norm(&a, &(l * &delta), &c_hat);
        let h2 =
            ((&c_hat * &sigma * c_hat.transpose()).trace() + (&inv * &d).norm_squared()).sqrt();
        (g1, h2, (sys.measuring_agents() as f64).sqrt() * g1 + h2)
    };
    let (g1, h2, j1) = bound(1.0);
    let mut last = j1;
    for t in [2.0, 4.0, 8.0, 16.0] {
        let (g1t, h2t, jt) = bound(t);
        assert!((g1t - g1).abs() <= 1e-9 * g1, "t = {t}: {g1t} vs {g1}");
        assert!(
            (h2t * t - h2).abs() <= 1e-9 * h2,
            "t = {t}: {h2t} vs {h2}/t"
        );
        assert!(jt < last, "t = {t}: {jt} ≥ {last}");
        assert!(jt > (sys.measuring_agents() as f64).sqrt() * g1);
        last = jt;
    }
}
