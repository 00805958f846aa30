//! Solver tests (spec/pmpc.md §10 items 13–16) against independent references: a dense-scan
//! extremum oracle, direct Cholesky factorisations and the KKT conditions.
extern crate std;
use super::check::{check_row, first_positive_root, polynomial_tail, RowCheck, Scratch, Violation};
use super::*;
use nalgebra::DMatrix;
use proptest::prelude::*;
use std::vec;
use std::vec::Vec;

/// Seeded SplitMix64 stream (rigid_body has no `rand` dependency).
struct TestRng(u64);

impl TestRng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
}

fn uniform(rng: &mut TestRng, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo) * ((rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64)
}

fn rng(seed: u64) -> TestRng {
    TestRng(seed)
}

fn g_at(b: &Laguerre, w: &[f64], t: f64) -> f64 {
    let mut tau = vec![0.0; b.dim()];
    b.tau(t, &mut tau);
    tau.iter().zip(w).map(|(p, q)| p * q).sum()
}

/// One row check with scratch from `buf` (length ≥ 3 s): result and Taylor steps.
fn check(
    b: &Laguerre,
    row: Row,
    w: &[f64],
    settings: &Settings,
    scan: bool,
    buf: &mut [f64],
) -> (RowCheck, usize) {
    let s = b.dim();
    let (y, rest) = buf.split_at_mut(s);
    let (y2, rest) = rest.split_at_mut(s);
    let s_k = &mut rest[..s];
    let mut sc = Scratch { y, y2, s_k };
    let mut steps = 0;
    let res = check_row(b, row, w, settings, scan, &mut sc, &mut steps);
    (res, steps)
}

/// Exact oracle: (max g − upper, lower − min g) over [0, ∞) from `laguerre::extrema`.
fn oracle(b: &Laguerre, w: &[f64], row: Row) -> (f64, f64) {
    let ext = crate::laguerre::extrema(b, w);
    let gmax = ext.iter().map(|e| e.1).fold(f64::NEG_INFINITY, f64::max);
    let gmin = ext.iter().map(|e| e.1).fold(f64::INFINITY, f64::min);
    (gmax - row.upper, row.lower - gmin)
}

#[test]
fn taylor_check_agrees_with_exact_oracle_on_10k_vectors() {
    let mut r = rng(7);
    let mut max_steps = 0;
    let (mut scanned, mut near_top, mut first_near_top) = (0, 0, 0);
    for case in 0..10_000 {
        let s = 4 + (r.next_u64() % 13) as usize;
        let b = Laguerre::new(s, uniform(&mut r, 0.3, 2.0)).unwrap();
        let mut w: Vec<f64> = (0..s).map(|_| uniform(&mut r, -1.0, 1.0)).collect();
        let scale = b.sup_norm() * w.iter().map(|x| x * x).sum::<f64>().sqrt();
        w.iter_mut().for_each(|x| *x /= scale);
        let row = match case % 3 {
            0 => Row {
                lower: -uniform(&mut r, 0.02, 0.8),
                upper: uniform(&mut r, 0.02, 0.8),
            },
            1 => Row {
                lower: f64::NEG_INFINITY,
                upper: uniform(&mut r, 0.0, 0.8),
            },
            _ => Row {
                lower: 0.0,
                upper: f64::INFINITY,
            },
        };
        let eps = [1e-3, 1e-6, 1e-8][case % 5 % 3];
        let settings = Settings {
            tolerance: eps,
            ..Settings::default()
        };
        let mut buf = vec![0.0; 3 * s];
        let (first, f_steps) = check(&b, row, &w, &settings, false, &mut buf);
        let (worst, w_steps) = check(&b, row, &w, &settings, true, &mut buf);
        max_steps = max_steps.max(f_steps).max(w_steps);
        let (vu, vl) = oracle(&b, &w, row);
        let excess = |v: &Violation| {
            let g = g_at(&b, &w, v.t);
            match v.side {
                Side::Upper => g - row.upper,
                Side::Lower => row.lower - g,
            }
        };
        match (first, worst) {
            (RowCheck::Satisfied, RowCheck::Satisfied) => assert!(
                vu <= eps + 1e-12 && vl <= eps + 1e-12,
                "case {case}: SATISFIED but violation {vu} / {vl} > eps {eps}"
            ),
            (RowCheck::Violated(f), RowCheck::Violated(v)) => {
                for x in [&f, &v] {
                    assert!(x.t >= 0.0);
                    assert!(
                        excess(x) > eps / 2.0 - 1e-12,
                        "case {case}: excess {}",
                        excess(x)
                    );
                    // The reported excess is proven: the value there or a Taylor lower bound.
                    assert!(
                        x.excess <= excess(x) + 1e-12,
                        "case {case}: reported excess {} > {}",
                        x.excess,
                        excess(x)
                    );
                }
                // The scan reports the worst instant it met, and it meets the first one.
                assert!(
                    v.excess >= f.excess,
                    "case {case}: scan {} < first {}",
                    v.excess,
                    f.excess
                );
                let top = vu.max(vl);
                scanned += 1;
                near_top += usize::from(v.excess >= 0.5 * top);
                first_near_top += usize::from(f.excess >= 0.5 * top);
            }
            _ => panic!("case {case}: the two checks disagree on whether the row is violated"),
        }
    }
    // The scan's instant is a sample on the violated stretch, not its extremum (the solver
    // refines it). Measured on these cases: 5763 of 5764 scans within half of the worst
    // excess, against 3713 for the first violation.
    assert!(
        near_top as f64 >= 0.99 * scanned as f64,
        "scan within half of the worst excess in {near_top} of {scanned}"
    );
    assert!(near_top > first_near_top, "{near_top} vs {first_near_top}");
    assert!(max_steps < 10_000);
}

/// Random feasible problem: Φ = F Fᵀ of rank r and w0 = Φ c, so w = 0 is reachable and every
/// row (limits straddle 0) is satisfiable.
fn random_problem(r: &mut TestRng) -> (Laguerre, Vec<Row>, Vec<f64>, Vec<f64>, usize) {
    let s = 4 + (r.next_u64() % 8) as usize;
    let nc = 1 + (r.next_u64() % 2) as usize;
    let d = nc * s;
    // Rank = degrees of freedom; MPC problems have m·s − n of them (8 in the example).
    let rank = 2 + (r.next_u64() % (d.min(9) as u64 - 1)) as usize;
    let f = DMatrix::from_fn(d, rank, |_, _| uniform(r, -1.0, 1.0));
    let phi = &f * f.transpose();
    let c = nalgebra::DVector::from_fn(d, |_, _| uniform(r, -3.0, 3.0));
    let w0 = &phi * c;
    let rows = (0..nc)
        .map(|k| match k {
            0 => Row {
                lower: -uniform(r, 0.1, 1.0),
                upper: uniform(r, 0.1, 1.0),
            },
            _ => Row {
                lower: 0.0,
                upper: f64::INFINITY,
            },
        })
        .collect();
    let phi_rows: Vec<f64> = phi.transpose().iter().copied().collect();
    let nu = uniform(r, 0.3, 2.0);
    (
        Laguerre::new(s, nu).unwrap(),
        rows,
        phi_rows,
        w0.iter().copied().collect(),
        rank,
    )
}

#[test]
fn kkt_holds_at_termination_on_random_problems() {
    let mut r = rng(11);
    let mut worst_gap: f64 = 0.0;
    for case in 0..200 {
        let (b, rows, phi, w0, rank) = random_problem(&mut r);
        let p = Problem::new(b, &rows, &phi, rank).unwrap();
        let mut st = WorkspaceStorage::new(&p);
        let mut ws = st.workspace(&p).unwrap();
        let d = p.dim();
        let s = b.dim();
        let mut tau = vec![0.0; s];
        let mut mu = vec![0.0; d];
        let mut costs = vec![];
        // Always scanning, the default, and never scanning.
        for scan_after in [0, Settings::default().scan_after_cold, usize::MAX] {
            let settings = Settings {
                tolerance: 1e-8,
                max_iter: 100_000,
                scan_after_cold: scan_after,
                ..Settings::default()
            };
            let out = solve(&p, &settings, &w0, false, &mut ws).unwrap();
            let at = std::format!("case {case}, scan after {scan_after}");
            assert_eq!(out.status, Status::Optimal, "{at}");
            // Stationarity in coefficient space: w = w0 − Φ μ.
            out.multiplier_coefficients(&p, &mut tau, &mut mu);
            for i in 0..d {
                let phimu: f64 = (0..d).map(|j| phi[i * d + j] * mu[j]).sum();
                assert!((out.w[i] - (w0[i] - phimu)).abs() < 1e-9, "{at}");
            }
            for (a, &lam) in out.active.iter().zip(out.lambda) {
                assert!(lam >= 0.0);
                let g = g_at(&b, &out.w[a.row * s..(a.row + 1) * s], a.t);
                let beta = match a.side {
                    Side::Upper => rows[a.row].upper,
                    Side::Lower => rows[a.row].lower,
                };
                assert!(
                    (g - beta).abs() < 1e-9,
                    "{at}: active residual {}",
                    g - beta
                );
            }
            for (k, row) in rows.iter().enumerate() {
                let (vu, vl) = oracle(&b, &out.w[k * s..(k + 1) * s], *row);
                assert!(vu <= 1e-8 + 1e-12 && vl <= 1e-8 + 1e-12, "{at}");
            }
            let inc = out.cost_increase(&p, &mut tau);
            let direct: f64 = 0.5
                * mu.iter()
                    .zip(w0.iter().zip(out.w))
                    .map(|(m, (a, c))| m * (a - c))
                    .sum::<f64>();
            assert!((inc - direct).abs() <= 1e-12 * (1.0 + inc.abs()), "{at}");
            costs.push(inc);
        }
        // Each cost lies between the ε-relaxed and the exact optimum, which differ most where
        // a zero bound (the row x ≥ 0) lends its ε of slack far out in time.
        let (lo, hi) = costs
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &c| {
                (l.min(c), h.max(c))
            });
        worst_gap = worst_gap.max((hi - lo) / (1.0 + hi.abs()));
    }
    // Measured: 5.1e-4 over these 200 problems.
    assert!(worst_gap <= 1e-3, "relative cost gap {worst_gap:e}");
}

#[test]
fn cost_is_non_decreasing_over_iterations() {
    let mut r = rng(13);
    for _ in 0..50 {
        let (b, rows, phi, w0, rank) = random_problem(&mut r);
        let p = Problem::new(b, &rows, &phi, rank).unwrap();
        let mut st = WorkspaceStorage::new(&p);
        let mut tau = vec![0.0; b.dim()];
        let mut last = 0.0;
        for k in 1..40 {
            let mut ws = st.workspace(&p).unwrap();
            let settings = Settings {
                max_iter: k,
                ..Settings::default()
            };
            let out = solve(&p, &settings, &w0, false, &mut ws).unwrap();
            let c = out.cost_increase(&p, &mut tau);
            assert!(c >= last - 1e-12 * (1.0 + c.abs()), "{c} < {last}");
            last = c;
            if out.status == Status::Optimal {
                break;
            }
        }
    }
}

#[test]
fn warm_start_from_final_set_needs_one_check() {
    let mut r = rng(17);
    for case in 0..50 {
        let (b, rows, phi, w0, rank) = random_problem(&mut r);
        let p = Problem::new(b, &rows, &phi, rank).unwrap();
        let mut st = WorkspaceStorage::new(&p);
        let mut ws = st.workspace(&p).unwrap();
        let settings = Settings {
            max_iter: 100_000,
            ..Settings::default()
        };
        let out = solve(&p, &settings, &w0, false, &mut ws).unwrap();
        assert!(out.status.is_optimal());
        let cold: Vec<f64> = out.w.to_vec();
        let warm = solve(&p, &settings, &w0, true, &mut ws).unwrap();
        assert!(warm.status.is_optimal());
        assert_eq!(warm.stats.iterations, 1, "case {case}");
        for (a, c) in warm.w.iter().zip(&cold) {
            assert!((a - c).abs() < 1e-9);
        }
    }
}

#[test]
fn infeasible_and_bad_input_are_reported() {
    let b = Laguerre::new(3, 1.0).unwrap();
    let rows = [Row {
        lower: 0.0,
        upper: f64::INFINITY,
    }];
    // Φ = 0: nothing can move, and g(0) < 0 is fixed.
    let phi = [0.0; 9];
    let p = Problem::new(b, &rows, &phi, 1).unwrap();
    let mut st = WorkspaceStorage::new(&p);
    let mut ws = st.workspace(&p).unwrap();
    let out = solve(&p, &Settings::default(), &[-1.0, 0.0, 0.0], false, &mut ws).unwrap();
    assert_eq!(out.status, Status::Infeasible);
    assert!(matches!(
        solve(
            &p,
            &Settings::default(),
            &[f64::NAN, 0.0, 0.0],
            false,
            &mut ws
        ),
        Err(Error::NonFinite { name: "w0" })
    ));
    assert!(matches!(
        solve(&p, &Settings::default(), &[0.0; 2], false, &mut ws),
        Err(Error::DimensionMismatch { name: "w0", .. })
    ));
    let bad = [Row {
        lower: 0.5,
        upper: 1.0,
    }];
    assert!(matches!(
        Problem::new(b, &bad, &phi, 1),
        Err(Error::InvalidParameter {
            name: "row lower limit",
            ..
        })
    ));
    let nan_phi = [f64::NAN; 9];
    assert!(matches!(
        Problem::new(b, &rows, &nan_phi, 1),
        Err(Error::NonFinite { name: "phi" })
    ));
}

/// The polynomial tail certificate holds for functions that stay non-negative by their
/// polynomial factor (τ₁, τ₁ − τ₂) and fails for ones that go below the limit (τ₂, a dip).
#[test]
fn polynomial_tail_certifies_a_positive_function_and_refuses_a_dip() {
    let b = Laguerre::new(6, 0.7).unwrap();
    let row = Row {
        lower: 0.0,
        upper: f64::INFINITY,
    };
    let mut sk = vec![0.0; 6];
    // τ₁ alone: P = sqrt(2ν) > 0, so g > 0 on [0, ∞).
    assert!(polynomial_tail(
        &b,
        row,
        1e-6,
        &[1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        &mut sk
    ));
    // τ₁ − τ₂: P(x) = sqrt(2ν)(1 − (1 − x)) = sqrt(2ν) x ≥ 0 on [0, ∞) (touches 0 at t = 0).
    assert!(polynomial_tail(
        &b,
        row,
        1e-6,
        &[1.0, -1.0, 0.0, 0.0, 0.0, 0.0],
        &mut sk
    ));
    // τ₂: P(x) = sqrt(2ν)(1 − x) < 0 beyond x = 1.
    assert!(!polynomial_tail(
        &b,
        row,
        1e-6,
        &[0.0, 1.0, 0.0, 0.0, 0.0, 0.0],
        &mut sk
    ));
    // A dip to −1e-3 below 0 cannot be certified at ε = 1e-6.
    let dip = [1e-3, 0.0, -2e-3, 0.0, 0.0, 0.0];
    assert!(crate::laguerre::extrema(&b, &dip)
        .iter()
        .any(|e| e.1 < -1e-6));
    assert!(!polynomial_tail(&b, row, 1e-6, &dip, &mut sk));
}

proptest! {
    /// The shifted working set keeps every instant, row and side; an instant that falls
    /// before 0 is clamped to 0 (not dropped).
    #[test]
    fn shift_keeps_every_instant_clamped_at_zero(
        ts in proptest::collection::vec(0.0f64..2.0, 1..6),
        h in 0.0f64..1.0,
    ) {
        let (b, rows, phi, _, rank) = random_problem(&mut rng(3));
        let p = Problem::new(b, &rows, &phi, rank.max(ts.len())).unwrap();
        let mut st = WorkspaceStorage::new(&p);
        let mut ws = st.workspace(&p).unwrap();
        let list: Vec<Active> = ts
            .iter()
            .enumerate()
            .map(|(i, &t)| Active { t, row: i % rows.len(), side: Side::Lower })
            .collect();
        ws.set_active(&list);
        ws.shift_active(h);
        prop_assert_eq!(ws.active().len(), list.len());
        for (a, s) in list.iter().zip(ws.active()) {
            prop_assert_eq!((a.row, a.side), (s.row, s.side));
            prop_assert_eq!(s.t, (a.t - h).max(0.0));
        }
    }

    /// Whenever the polynomial certificate holds, the function stays within the widened
    /// limits on [0, ∞) (exact extrema oracle).
    #[test]
    fn polynomial_tail_certificate_is_sound(
        s in 1usize..16,
        nu in 0.3f64..2.0,
        coeffs in proptest::collection::vec(-1.0f64..1.0, 16),
        decay in 0.0f64..3.0,
        kind in 0usize..3,
        limit in 0.0f64..0.5,
        eps_exp in 3i32..9,
    ) {
        let b = Laguerre::new(s, nu).unwrap();
        // Decaying coefficients make certifiable tails common; some cases still dip.
        let y: Vec<f64> = (0..s).map(|i| coeffs[i] * (-decay * i as f64).exp()).collect();
        let row = match kind {
            0 => Row { lower: 0.0, upper: f64::INFINITY },
            1 => Row { lower: f64::NEG_INFINITY, upper: limit },
            _ => Row { lower: -limit, upper: limit },
        };
        let eps = 10f64.powi(-eps_exp);
        let mut sk = vec![0.0; s];
        if polynomial_tail(&b, row, eps, &y, &mut sk) {
            let (vu, vl) = oracle(&b, &y, row);
            prop_assert!(vu <= eps + 1e-12 && vl <= eps + 1e-12,
                "certified but excess {vu} / {vl} > eps {eps}");
        }
    }

    /// The scanning check agrees with the first-violation check on whether a row is violated and
    /// reports a proven excess at least as large (how close it comes to the exact worst one is
    /// a rate, measured in `taylor_check_agrees_with_exact_oracle_on_10k_vectors`).
    #[test]
    fn scanning_check_reports_the_worst_violation(
        s in 2usize..16,
        nu in 0.3f64..2.0,
        coeffs in proptest::collection::vec(-1.0f64..1.0, 16),
        kind in 0usize..3,
        limit in 0.02f64..0.8,
        eps_exp in 3i32..9,
    ) {
        let b = Laguerre::new(s, nu).unwrap();
        let scale = b.sup_norm() * coeffs[..s].iter().map(|x| x * x).sum::<f64>().sqrt();
        let w: Vec<f64> = coeffs[..s].iter().map(|x| x / scale.max(1e-12)).collect();
        let row = match kind {
            0 => Row { lower: 0.0, upper: f64::INFINITY },
            1 => Row { lower: f64::NEG_INFINITY, upper: limit },
            _ => Row { lower: -limit, upper: limit },
        };
        let settings = Settings { tolerance: 10f64.powi(-eps_exp), ..Settings::default() };
        let mut buf = vec![0.0; 3 * s];
        let (first, _) = check(&b, row, &w, &settings, false, &mut buf);
        let (worst, _) = check(&b, row, &w, &settings, true, &mut buf);
        let (vu, vl) = oracle(&b, &w, row);
        match (first, worst) {
            (RowCheck::Satisfied, RowCheck::Satisfied) => {
                prop_assert!(vu.max(vl) <= settings.tolerance + 1e-12);
            }
            (RowCheck::Violated(f), RowCheck::Violated(v)) => {
                let g = g_at(&b, &w, v.t);
                let real = match v.side { Side::Upper => g - row.upper, Side::Lower => row.lower - g };
                prop_assert!(v.excess >= f.excess);
                prop_assert!(v.excess <= real + 1e-12);
            }
            (RowCheck::StepLimit, _) | (_, RowCheck::StepLimit) => prop_assert!(false, "step limit"),
            _ => prop_assert!(false, "the checks disagree on whether the row is violated"),
        }
    }

    #[test]
    fn cubic_root_is_the_first_sign_change(a3 in 1e-3f64..10.0, a2 in -10.0f64..10.0,
                                            a1 in -10.0f64..10.0, a0 in -10.0f64..-1e-6) {
        let p = |t: f64| ((a3 * t + a2) * t + a1) * t + a0;
        let root = first_positive_root(a3, a2, a1, a0);
        prop_assert!(root > 0.0);
        let scale = a3 * root.powi(3) + a2.abs() * root * root + a1.abs() * root + a0.abs();
        // The first sign change lies within the root finder's relative accuracy beyond it ...
        prop_assert!(p(root * (1.0 + 2e-4)) >= -1e-12 * scale);
        // ... and the polynomial is negative up to it (what the check may certify).
        for i in 1..=2000 {
            let t = root * (i as f64) / 2000.0;
            prop_assert!(p(t) < 1e-14 * scale);
        }
    }

    #[test]
    fn factor_updates_match_direct_cholesky(
        n in 1usize..8,
        remove_at in 0usize..8,
        entries in proptest::collection::vec(-1.0f64..1.0, 64),
    ) {
        let f = DMatrix::from_fn(n, n + 2, |i, j| entries[(i * 8 + j) % 64] + if i == j { 2.0 } else { 0.0 });
        let k = &f * f.transpose();
        let mut buf = vec![0.0; 64];
        let mut fac = factor::Factor { l: &mut buf, cap: 8 };
        for p in 0..n {
            let mut row: Vec<f64> = (0..p).map(|j| k[(p, j)]).collect();
            fac.forward(p, &mut row);
            let schur = k[(p, p)] - row.iter().map(|x| x * x).sum::<f64>();
            fac.append(p, &row, schur);
        }
        let j = remove_at % n;
        fac.remove(n, j);
        let keep: Vec<usize> = (0..n).filter(|&i| i != j).collect();
        let l = DMatrix::from_fn(n - 1, n - 1, |a, b| if b <= a { buf[a * 8 + b] } else { 0.0 });
        let rebuilt = &l * l.transpose();
        for (a, &ia) in keep.iter().enumerate() {
            for (b, &ib) in keep.iter().enumerate() {
                prop_assert!((rebuilt[(a, b)] - k[(ia, ib)]).abs() < 1e-10 * (1.0 + k.amax()));
            }
            prop_assert!(l[(a, a)] > 0.0);
        }
    }
}
