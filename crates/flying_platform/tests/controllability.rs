//! Gramian closed form vs numerics (AT-06, AT-07) and the optimal lever arm (AT-08).
#![allow(clippy::unwrap_used)]

use flying_platform::controllability::{
    gramian_det_closed_form, reachability_gramian, thrust_vectoring_system, LeverArmTradeoff,
};
use flying_platform::PlatformParams;
use nalgebra::DMatrix;
use proptest::prelude::*;

fn params(m: f64, i1: f64, l3: f64) -> PlatformParams {
    let mut p = PlatformParams::nominal();
    p.mass = m;
    p.i1 = i1;
    p.l3 = l3;
    p
}

/// Composite Simpson quadrature of `e^{-At} B B^T e^{-A^T t}` (independent of Van Loan).
fn gramian_by_quadrature(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    horizon: f64,
    n: usize,
) -> DMatrix<f64> {
    let h = horizon / n as f64;
    let integrand = |t: f64| {
        let e = (-a * t).exp();
        &e * b * b.transpose() * e.transpose()
    };
    let mut w = integrand(0.0) + integrand(horizon);
    for i in 1..n {
        w += integrand(i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
    }
    w * (h / 3.0)
}

#[test]
fn gramian_determinant_matches_closed_form_and_test_vectors() {
    for (m, i1, l3, horizon, expected) in [
        (8.0, 0.07, 0.17, 1.0, 3807.033),
        (8.0, 0.07, 0.079, 2.0, 101219.6),
        (3.0, 0.2, 0.1, 1.5, 0.0326331),
    ] {
        let closed = gramian_det_closed_form(9.81, horizon, l3, i1);
        assert!(
            (closed - expected).abs() < 2e-6 * expected,
            "{closed} vs {expected}"
        );
        let (a, b) = thrust_vectoring_system(&params(m, i1, l3)).unwrap();
        let w = reachability_gramian(&a, &b, horizon).unwrap();
        let det = w.determinant();
        assert!(
            (det - closed).abs() < 1e-6 * closed,
            "numeric {det} vs closed {closed}"
        );
        let quad = gramian_by_quadrature(&a, &b, horizon, 400);
        assert!((&quad - &w).amax() < 1e-9 * w.amax());
    }
}

#[test]
fn integral_of_m_has_determinant_g0_squared_t9_over_8640() {
    // M(t) = [[z², -z t, z], [-z t, t², -t], [z, -t, 1]], z = c - g0 t²/2, for any c.
    for (c, horizon) in [(0.5, 1.0), (3.0, 2.0), (-1.0, 0.7)] {
        let g0 = 9.81;
        let n = 2000;
        let h = horizon / n as f64;
        let m = |t: f64| {
            let z = c - g0 * t * t / 2.0;
            DMatrix::from_row_slice(3, 3, &[z * z, -z * t, z, -z * t, t * t, -t, z, -t, 1.0])
        };
        let mut s = m(0.0) + m(horizon);
        for i in 1..n {
            s += m(i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
        }
        let det = (s * (h / 3.0)).determinant();
        let expected = g0 * g0 * horizon.powi(9) / 8640.0;
        assert!(
            (det - expected).abs() < 1e-9 * expected.max(1e-3) + 1e-9,
            "{det} vs {expected}"
        );
    }
}

#[test]
fn optimal_lever_arm_is_1_68_l1_with_inertia_0_076() {
    let trade = LeverArmTradeoff::paper();
    let l3 = trade.optimal_l3().unwrap();
    assert!((l3 - 0.16777).abs() < 1e-5, "{l3}");
    assert!((l3 / trade.l1 - 1.6777).abs() < 1e-4);
    assert!((trade.inertia(l3) - 0.076).abs() < 1e-12);
    // Golden-section search on the merit l3 / I1(l3), an independent 1-D maximisation.
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    let phi = (5f64.sqrt() - 1.0) / 2.0;
    for _ in 0..200 {
        let (x1, x2) = (hi - phi * (hi - lo), lo + phi * (hi - lo));
        if trade.merit(x1) < trade.merit(x2) {
            lo = x1
        } else {
            hi = x2
        }
    }
    assert!((lo - l3).abs() < 1e-4);
    // With three units' worth of vertical inertia the optimum moves to about 1.37 l1.
    let three = LeverArmTradeoff {
        vertical_factor: 3.0,
        ..trade
    };
    assert!((three.optimal_l3().unwrap() / trade.l1 - 1.37).abs() < 0.005);
    assert!(LeverArmTradeoff {
        delta: 0.0,
        ..trade
    }
    .optimal_l3()
    .is_err());
}

proptest! {
    /// det Wc(T) does not depend on the mass and follows the closed form for any l3, I1, T.
    #[test]
    fn gramian_closed_form_holds(m in 1.0..20.0f64, i1 in 0.02..0.5f64, l3 in -0.3..0.3f64, horizon in 0.5..2.0f64) {
        prop_assume!(l3.abs() > 0.02);
        let (a, b) = thrust_vectoring_system(&params(m, i1, l3)).unwrap();
        let det = reachability_gramian(&a, &b, horizon).unwrap().determinant();
        let closed = gramian_det_closed_form(9.81, horizon, l3, i1);
        prop_assert!((det - closed).abs() < 1e-6 * closed, "{} vs {}", det, closed);
    }

    /// The closed-form optimum is a maximum of l3 / I1 for any admissible numbers.
    #[test]
    fn optimum_beats_neighbours(i0 in 0.0..0.1f64, mt in 0.2..3.0f64, l1 in 0.05..0.3f64, delta in 0.3..1.5f64) {
        let t = LeverArmTradeoff { i0, unit_mass: mt, l1, delta, vertical_factor: 2.0 };
        let l3 = t.optimal_l3().unwrap();
        prop_assert!(t.merit(l3) >= t.merit(l3 * 1.01) && t.merit(l3) >= t.merit(l3 * 0.99));
    }
}
