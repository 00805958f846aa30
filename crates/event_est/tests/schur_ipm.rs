//! The Schur-complement interior-point method against Clarabel on the same LMI problems: the
//! Cor 13 platoon designs of 3, 4 and 6 vehicles (Step 1 and Step 2), closed-form SDPs, and
//! errors for infeasible and empty problems.
#![allow(clippy::unwrap_used)]

use event_est::lmi::{Problem, Vars};
use event_est::model::platoon;
use event_est::synth::{step1_using, step2_unit_using, Solver, Stability};
use event_est::EventEstError;
use nalgebra::DMatrix;
use proptest::prelude::*;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// Step 1 objective tr X = c*²·s: both solvers return post-verified gains; where Clarabel
/// reports `Solved` (3 vehicles) the optima agree to 1e-6, where it stops at `AlmostSolved`
/// (≥ 4 vehicles) the Schur method's c* is never larger than Clarabel's, and within 5e-4 of
/// the spec's independent CVXPY + Clarabel reproduction (table 7.5, 4 digits, itself stopped
/// at `AlmostSolved`). Where in-process Clarabel stops depends on the machine: on one with
/// AVX-512 it stopped at c* = 0.029174 for 6 vehicles, 1.1e-3 above the table's 0.02914,
/// where the Schur method's 0.029148 is 2.9e-4 from it.
#[test]
fn cor13_step1_matches_clarabel_for_3_4_6_vehicles() {
    let table = |m: usize| match m {
        4 => 0.01535,
        _ => 0.02914,
    };
    for m in [3usize, 4, 6] {
        let (sys, _) = platoon(m).unwrap();
        let ipm = step1_using(&sys, Stability::Cor13, Solver::SchurIpm).unwrap();
        let cla = step1_using(&sys, Stability::Cor13, Solver::Clarabel).unwrap();
        let objective = rel(ipm.c_star.powi(2), cla.c_star.powi(2));
        println!(
            "M = {m}: c* Schur {:.10} ({}, {} it), Clarabel {:.10} ({}, {} it), rel {objective:.1e}",
            ipm.c_star, ipm.status, ipm.iterations, cla.c_star, cla.status, cla.iterations
        );
        assert_eq!(ipm.stability_margins.len(), m + 1);
        assert!(ipm.stability_margins.iter().all(|(_, v)| *v < 0.0));
        assert!(ipm.true_h2 <= ipm.c_star * (1.0 + 1e-4));
        if cla.status == "Solved" {
            assert!(
                objective < 1e-6,
                "M = {m}: relative objective gap {objective:e}"
            );
        } else {
            assert!(ipm.c_star <= cla.c_star * (1.0 + 1e-7), "M = {m}");
            let spec = rel(ipm.c_star, table(m));
            assert!(
                spec < 5e-4,
                "M = {m}: c* {} is {spec:e} from the table",
                ipm.c_star
            );
        }
        // Gains of the two solvers agree to the accuracy of the objective.
        let dl = (&ipm.l - &cla.l).amax() / cla.l.amax();
        assert!(dl < 0.05, "M = {m}: gains differ by {dl:e}");
    }
}

/// Beyond Clarabel's practical range: 8 vehicles against the spec's independent CVXPY + Clarabel
/// reproduction (table 7.5: c* = 0.04353, true H2 = 0.01829, 4 digits).
#[test]
fn cor13_step1_for_8_vehicles_matches_the_spec_table() {
    let (sys, _) = platoon(8).unwrap();
    let s1 = step1_using(&sys, Stability::Cor13, Solver::SchurIpm).unwrap();
    println!("M = 8: c* {:.6}, true H2 {:.6}", s1.c_star, s1.true_h2);
    assert!(rel(s1.c_star, 0.04353) < 2e-4, "c* = {}", s1.c_star);
    assert!(rel(s1.true_h2, 0.01829) < 5e-4, "H2 = {}", s1.true_h2);
    assert_eq!(s1.stability_margins.len(), 9);
}

/// Step 2 (unit γ) on the same gains: the thresholds of both solvers agree.
#[test]
fn step2_thresholds_match_clarabel() {
    for m in [3usize, 4, 6] {
        let (sys, _) = platoon(m).unwrap();
        let s1 = step1_using(&sys, Stability::Cor13, Solver::Clarabel).unwrap();
        let ipm = step2_unit_using(&sys, &s1.l, 1.0, Solver::SchurIpm).unwrap();
        let cla = step2_unit_using(&sys, &s1.l, 1.0, Solver::Clarabel).unwrap();
        let ti: f64 = ipm.delta.iter().map(|d| d.trace()).sum();
        let tc: f64 = cla.delta.iter().map(|d| d.trace()).sum();
        println!("M = {m}: tr Δ̃ Schur {ti:.8}, Clarabel {tc:.8}");
        assert!(rel(ti, tc) < 1e-5, "M = {m}: {ti} vs {tc}");
        for (a, b) in ipm.delta.iter().zip(&cla.delta) {
            assert!(rel(a[(0, 0)], b[(0, 0)]) < 1e-3);
        }
    }
}

/// min t s.t. t I − S ⪰ 0 has the optimum λ_max(S).
fn lambda_max_problem(s: &DMatrix<f64>) -> (Problem, usize) {
    let d = s.nrows();
    let mut vars = Vars::default();
    let t = vars.scalar();
    let mut prob = Problem::new(vars);
    let l = prob.lmi("t I − S ⪰ 0", d);
    l.add_scalar_identity(t, 0, d, 1.0);
    l.add_const(0, 0, &(-s));
    prob.objective[t.index(0, 0)] = 1.0;
    (prob, t.index(0, 0))
}

proptest! {
    /// Largest eigenvalue of a random symmetric matrix as an SDP.
    #[test]
    fn largest_eigenvalue_as_sdp(v in proptest::collection::vec(-5.0f64..5.0, 36), d in 2usize..7) {
        let m = DMatrix::from_column_slice(6, 6, &v).view((0, 0), (d, d)).into_owned();
        let s = (&m + m.transpose()) * 0.5;
        let (prob, t) = lambda_max_problem(&s);
        let sol = prob.solve_with(Solver::SchurIpm, "λ_max", 0.0).unwrap();
        let exact = s.symmetric_eigenvalues().max();
        prop_assert!((sol.x[t] - exact).abs() < 1e-6 * (1.0 + exact.abs()), "{} vs {exact}", sol.x[t]);
    }

    /// Several blocks on one symmetric variable: min tr P s.t. P ⪰ S_k (k = 1..3) for S_k with
    /// a common eigenbasis Q has the optimum Σ_i max_k λ_{k,i} (P = Q diag(max_k λ_k) Qᵀ is
    /// feasible, and tr P = Σ_i q_iᵀPq_i ≥ Σ_i max_k q_iᵀS_kq_i for every feasible P).
    #[test]
    fn common_upper_bound_has_the_closed_form(
        v in proptest::collection::vec(-1.0f64..1.0, 16),
        lam in proptest::collection::vec(-3.0f64..3.0, 12),
    ) {
        let d = 4;
        let q = DMatrix::from_column_slice(d, d, &v).qr().q();
        prop_assume!((q.transpose() * &q - DMatrix::<f64>::identity(d, d)).amax() < 1e-10);
        let mut vars = Vars::default();
        let p = vars.sym(d);
        let mut prob = Problem::new(vars);
        for k in 0..3 {
            let diag = DMatrix::from_diagonal(&nalgebra::DVector::from_column_slice(&lam[d * k..d * (k + 1)]));
            let s = &q * diag * q.transpose();
            let l = prob.lmi(format!("P ⪰ S_{k}"), d);
            l.add_sym(p, 0, 1.0);
            l.add_const(0, 0, &(-s));
        }
        for i in 0..d {
            prob.objective[p.index(i, i)] = 1.0;
        }
        let sol = prob.solve_with(Solver::SchurIpm, "upper bound", 0.0).unwrap();
        let exact: f64 = (0..d)
            .map(|i| (0..3).map(|k| lam[d * k + i]).fold(f64::NEG_INFINITY, f64::max))
            .sum();
        let value = p.value(&sol.x).trace();
        prop_assert!((value - exact).abs() < 1e-6 * (1.0 + exact.abs()), "{value} vs {exact}");
    }
}

#[test]
fn infeasible_problem_names_the_conflicting_condition() {
    // [[t, 1], [1, −t]] ⪰ 0 needs t ≥ 0, −t ≥ 0 and −t² − 1 ≥ 0: no t satisfies it. A second,
    // satisfiable LMI s ⪰ 0 is not part of the conflict.
    let mut vars = Vars::default();
    let t = vars.scalar();
    let u = vars.scalar();
    let mut prob = Problem::new(vars);
    let l = prob.lmi("[[t, 1], [1, −t]] ⪰ 0", 2);
    l.add_scalar_identity(t, 0, 1, 1.0);
    l.add_scalar_identity(t, 1, 1, -1.0);
    l.add_const(0, 1, &DMatrix::from_element(1, 1, 1.0));
    let l = prob.lmi("s ⪰ 0", 1);
    l.add_scalar_identity(u, 0, 1, 1.0);
    let err = prob
        .solve_with(Solver::SchurIpm, "conflict", 0.0)
        .unwrap_err();
    let EventEstError::Infeasible { condition, .. } = &err else {
        panic!("expected Infeasible, got {err}");
    };
    assert!(condition.contains("[[t, 1], [1, −t]]"), "{condition}");
    assert!(!condition.contains("s ⪰ 0"), "{condition}");
}

#[test]
fn solver_names_parse_and_unknown_names_are_errors() {
    assert_eq!(Solver::parse("schur").unwrap(), Solver::SchurIpm);
    assert_eq!(Solver::parse("Clarabel").unwrap(), Solver::Clarabel);
    let err = Solver::parse("sdpt3").unwrap_err();
    assert!(err.to_string().contains("solver"), "{err}");
}

#[test]
fn empty_problem_is_named() {
    let prob = Problem::new(Vars::default());
    let err = prob.solve_with(Solver::SchurIpm, "empty", 0.0).unwrap_err();
    assert!(err.to_string().contains("empty"), "{err}");
}

/// A random well-posed SDP with a dense objective: bounded by ‖x‖ ≤ 1 (as an LMI), the
/// optimum of min qᵀx is −|q| at x = −q/|q|.
#[test]
fn ball_constrained_linear_objective() {
    let mut rng = StdRng::seed_from_u64(11);
    for dim in [2usize, 5, 12] {
        let q: Vec<f64> = (0..dim).map(|_| rng.random_range(-2.0..2.0)).collect();
        let mut vars = Vars::default();
        let x = vars.full(dim, 1);
        let mut prob = Problem::new(vars);
        // [[1, xᵀ], [x, I]] ⪰ 0 ⇔ |x| ≤ 1.
        let l = prob.lmi("|x| ≤ 1", dim + 1);
        l.add_const(0, 0, &DMatrix::from_element(1, 1, 1.0));
        // x enters the lower-left block (stored as its transpose above the diagonal).
        l.add_full_times(x, &DMatrix::identity(1, 1), 0..1, 1, 0, 1.0);
        l.add_const(1, 1, &DMatrix::identity(dim, dim));
        prob.objective.copy_from_slice(&q);
        let sol = prob.solve_with(Solver::SchurIpm, "ball", 0.0).unwrap();
        let norm = q.iter().map(|v| v * v).sum::<f64>().sqrt();
        let value: f64 = q.iter().zip(&sol.x).map(|(a, b)| a * b).sum();
        assert!(
            (value + norm).abs() < 1e-7 * norm,
            "dim {dim}: {value} vs {}",
            -norm
        );
    }
}
