//! Acceptance tests 1–5 of spec/pmpc.md §10 (basis), against independent references:
//! Gauss–Laguerre quadrature, complex-step differentiation, nalgebra's matrix exponential,
//! LU inverses and Kronecker products.
extern crate std;
use super::*;
use nalgebra::{Complex, DMatrix, DVector, SymmetricEigen};
use proptest::prelude::*;
use std::vec;
use std::vec::Vec;

/// Gauss–Laguerre nodes and weights (weight e^{-x} on [0, ∞)) by Golub–Welsch.
fn gauss_laguerre(n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut j = DMatrix::<f64>::zeros(n, n);
    for k in 0..n {
        j[(k, k)] = (2 * k + 1) as f64;
        if k + 1 < n {
            j[(k, k + 1)] = (k + 1) as f64;
            j[(k + 1, k)] = (k + 1) as f64;
        }
    }
    // Nodes from the Jacobi matrix, polished by Newton on L_n; weights from the classical
    // formula w = x / ((n+1) L_{n+1}(x))², which is accurate even for the tiny tail weights.
    let lag = |k: usize, x: f64| {
        let (mut prev, mut cur) = (0.0, 1.0);
        for i in 0..k {
            let next = ((2.0 * i as f64 + 1.0 - x) * cur - i as f64 * prev) / (i as f64 + 1.0);
            prev = cur;
            cur = next;
        }
        (cur, prev)
    };
    let eig = SymmetricEigen::new(j);
    let mut nodes: Vec<f64> = eig.eigenvalues.iter().copied().collect();
    for x in nodes.iter_mut() {
        for _ in 0..3 {
            let (ln, lm) = lag(n, *x);
            let d = n as f64 * (ln - lm) / *x;
            *x -= ln / d;
        }
    }
    let weights = nodes
        .iter()
        .map(|&x| x / ((n + 1) as f64 * lag(n + 1, x).0).powi(2))
        .collect();
    (nodes, weights)
}

fn basis(s: usize, nu: f64) -> Laguerre {
    Laguerre::new(s, nu).unwrap()
}

fn m_dense(b: &Laguerre) -> DMatrix<f64> {
    let s = b.dim();
    let mut m = vec![0.0; s * s];
    b.m_matrix(&mut m).unwrap();
    DMatrix::from_row_slice(s, s, &m)
}

fn e_dense(b: &Laguerre, h: f64) -> DMatrix<f64> {
    let s = b.dim();
    let mut e = vec![0.0; s * s];
    b.shift_matrix(h, &mut e).unwrap();
    DMatrix::from_row_slice(s, s, &e)
}

fn tau_vec(b: &Laguerre, t: f64) -> DVector<f64> {
    let mut v = vec![0.0; b.dim()];
    b.tau(t, &mut v);
    DVector::from_vec(v)
}

/// τ(t) for complex t by the same three-term recurrence, for complex-step derivatives.
fn tau_complex(s: usize, nu: f64, t: Complex<f64>) -> Vec<Complex<f64>> {
    let x = t * (2.0 * nu);
    let scale = (t * (-nu)).exp() * (2.0 * nu).sqrt();
    let (mut prev, mut cur) = (Complex::new(0.0, 0.0), Complex::new(1.0, 0.0));
    let mut out = Vec::with_capacity(s);
    for k in 0..s {
        out.push(scale * cur);
        let kf = k as f64;
        let next = ((-x + (2.0 * kf + 1.0)) * cur - prev * kf) / (kf + 1.0);
        prev = cur;
        cur = next;
    }
    out
}

fn gram_by_quadrature(b: &Laguerre) -> DMatrix<f64> {
    let s = b.dim();
    let (nodes, weights) = gauss_laguerre(s + 2);
    let mut g = DMatrix::<f64>::zeros(s, s);
    for (x, w) in nodes.iter().zip(weights.iter()) {
        // x = 2νt, dt = dx/(2ν); τ_iτ_j = 2ν L_i L_j e^{-x}
        let tau = tau_vec(b, x / (2.0 * b.nu()));
        g += &tau * tau.transpose() * (w * x.exp() / (2.0 * b.nu()));
    }
    g
}

#[test]
fn gram_is_identity_for_listed_sizes_and_rates() {
    for s in 1..=20 {
        for nu in [0.1, 0.7, 5.0] {
            let g = gram_by_quadrature(&basis(s, nu));
            let err = (g - DMatrix::<f64>::identity(s, s)).amax();
            assert!(err < 1e-12, "s={s} nu={nu} err={err}");
        }
    }
}

#[test]
fn lyapunov_identity_is_exact() {
    for s in [1, 4, 12, 20] {
        let b = basis(s, 0.7);
        let m = m_dense(&b);
        let t0 = tau_vec(&b, 0.0);
        let res = &m + m.transpose() + &t0 * t0.transpose();
        assert_eq!(res.amax(), 0.0, "s={s}");
    }
}

#[test]
fn spec_shift_example_s4() {
    let e = e_dense(&basis(4, 0.7), 0.02);
    let expect = [0.986098, -0.027611, -0.027224, -0.026841];
    for (d, v) in expect.iter().enumerate() {
        assert!((e[(d, 0)] - v).abs() < 1e-6, "d={d}: {}", e[(d, 0)]);
        assert!((e[(3, 3 - d)] - v).abs() < 1e-6);
    }
    assert_eq!(e[(0, 1)], 0.0);
}

#[test]
fn spec_reference_tau_at_one() {
    let expect = [
        0.587568, -0.235027, -0.481805, -0.421482, -0.228721, -0.010470, 0.173849, 0.297067,
        0.352895, 0.347626, 0.294216, 0.208216,
    ];
    let tau = tau_vec(&basis(12, 0.7), 1.0);
    for (a, e) in tau.iter().zip(expect.iter()) {
        assert!((a - e).abs() < 1e-6, "{a} vs {e}");
    }
}

#[test]
fn sup_norm_and_integral_match_closed_forms() {
    let b = basis(12, 0.7);
    assert!((b.sup_norm() - 4.0987803).abs() < 1e-7);
    assert!((tau_vec(&b, 0.0).norm() - b.sup_norm()).abs() < 1e-13);
    let mut bar = vec![0.0; 12];
    b.integral(&mut bar);
    let m = m_dense(&b);
    let reference = -m.lu().solve(&tau_vec(&b, 0.0)).unwrap();
    for (a, r) in bar.iter().zip(reference.iter()) {
        assert!((a - r).abs() < 1e-13);
    }
    assert!((bar[1] + 1.6903085).abs() < 1e-7);
}

#[test]
fn bad_parameters_are_named() {
    assert!(matches!(
        Laguerre::new(0, 1.0),
        Err(Error::InvalidParameter { name: "s", .. })
    ));
    assert!(matches!(
        Laguerre::new(3, f64::NAN),
        Err(Error::InvalidParameter { name: "nu", .. })
    ));
    assert!(matches!(
        Laguerre::new(3, -1.0),
        Err(Error::InvalidParameter { name: "nu", .. })
    ));
    let b = basis(3, 1.0);
    let mut out = [0.0; 4];
    assert_eq!(
        b.m_matrix(&mut out),
        Err(Error::DimensionMismatch {
            name: "out",
            rows: 4,
            cols: 1,
            expected_rows: 9,
            expected_cols: 1
        })
    );
}

#[test]
fn kronecker_matrices_match_nalgebra_kronecker() {
    let (n, m, s) = (3, 2, 5);
    let b = basis(s, 0.9);
    let a: Vec<f64> = (0..n * n).map(|i| (i as f64 * 0.37).sin()).collect();
    let bm: Vec<f64> = (0..n * m).map(|i| (i as f64 * 0.71).cos()).collect();
    let ad = DMatrix::from_row_slice(n, n, &a);
    let bd = DMatrix::from_row_slice(n, m, &bm);
    let mm = m_dense(&b);
    let is = DMatrix::<f64>::identity(s, s);
    let in_ = DMatrix::<f64>::identity(n, n);
    let t0 = tau_vec(&b, 0.0).transpose();

    let cols = (n + m) * s;
    let mut aeq = vec![0.0; (n * s + n) * cols];
    b.equality_matrix(n, m, &a, &bm, &mut aeq).unwrap();
    let aeq = DMatrix::from_row_slice(n * s + n, cols, &aeq);
    let mut expect = DMatrix::<f64>::zeros(n * s + n, cols);
    expect
        .view_mut((0, 0), (n * s, n * s))
        .copy_from(&(in_.kronecker(&mm.transpose()) - ad.kronecker(&is)));
    expect
        .view_mut((0, n * s), (n * s, m * s))
        .copy_from(&(-bd.kronecker(&is)));
    expect
        .view_mut((n * s, 0), (n, n * s))
        .copy_from(&in_.kronecker(&t0));
    assert!((aeq - expect).amax() < 1e-15);

    let mut weak = vec![0.0; n * s * cols];
    b.weak_dynamics_matrix(n, m, &a, &bm, &mut weak).unwrap();
    let weak = DMatrix::from_row_slice(n * s, cols, &weak);
    let mut expect = DMatrix::<f64>::zeros(n * s, cols);
    expect
        .view_mut((0, 0), (n * s, n * s))
        .copy_from(&(in_.kronecker(&mm) + ad.kronecker(&is)));
    expect
        .view_mut((0, n * s), (n * s, m * s))
        .copy_from(&bd.kronecker(&is));
    assert!((weak - expect).amax() < 1e-15);

    let cx = [1.0, 0.0, -2.0, 0.5, 0.25, 0.0];
    let cu = [0.0, 1.0, 3.0, 0.0];
    let mut cz = vec![0.0; 2 * s * cols];
    b.stage_matrix(n, m, &cx, &cu, &mut cz).unwrap();
    let cz = DMatrix::from_row_slice(2 * s, cols, &cz);
    let mut expect = DMatrix::<f64>::zeros(2 * s, cols);
    expect
        .view_mut((0, 0), (2 * s, n * s))
        .copy_from(&DMatrix::from_row_slice(2, n, &cx).kronecker(&is));
    expect
        .view_mut((0, n * s), (2 * s, m * s))
        .copy_from(&DMatrix::from_row_slice(2, m, &cu).kronecker(&is));
    assert!((cz - expect).amax() < 1e-15);
}

proptest! {
    #[test]
    fn gram_is_identity(s in 1usize..=20, nu in 0.05f64..10.0) {
        let g = gram_by_quadrature(&basis(s, nu));
        prop_assert!((g - DMatrix::<f64>::identity(s, s)).amax() < 1e-12);
    }

    #[test]
    fn derivative_is_generator_times_tau(s in 1usize..=16, nu in 0.1f64..3.0, t in 0.0f64..50.0) {
        let b = basis(s, nu);
        let h = 1e-20;
        let d: Vec<f64> = tau_complex(s, nu, Complex::new(t, h)).iter().map(|c| c.im / h).collect();
        let md = m_dense(&b) * tau_vec(&b, t);
        let scale = md.norm().max(tau_vec(&b, t).norm()).max(f64::MIN_POSITIVE);
        for (a, r) in md.iter().zip(d.iter()) {
            prop_assert!((a - r).abs() <= 1e-10 * scale, "{} vs {}", a, r);
        }
    }

    #[test]
    fn shift_moves_tau_forward(s in 1usize..=16, nu in 0.1f64..3.0, t in 0.0f64..30.0, h in 0.0f64..10.0) {
        let b = basis(s, nu);
        let shifted = e_dense(&b, h) * tau_vec(&b, t);
        prop_assert!((shifted - tau_vec(&b, t + h)).amax() < 1e-13 * b.sup_norm());
    }

    #[test]
    fn shift_is_a_semigroup(s in 1usize..=16, nu in 0.1f64..3.0, h1 in 0.0f64..5.0, h2 in 0.0f64..5.0) {
        let b = basis(s, nu);
        let lhs = e_dense(&b, h1 + h2);
        let rhs = e_dense(&b, h1) * e_dense(&b, h2);
        prop_assert!((lhs - rhs).amax() < 1e-13);
        prop_assert_eq!(e_dense(&b, 0.0), DMatrix::<f64>::identity(s, s));
    }

    #[test]
    fn shift_equals_general_matrix_exponential(s in 1usize..=16, nu in 0.1f64..3.0, h in 0.0f64..5.0) {
        let b = basis(s, nu);
        let mh = m_dense(&b) * h;
        let reference = crate::lti::expm(&mh).unwrap();
        prop_assert!((e_dense(&b, h) - reference).amax() < 1e-13);
        prop_assert!((e_dense(&b, h) - mh.exp()).amax() < 1e-13);
    }

    #[test]
    fn vector_shift_matches_shift_matrix(s in 1usize..=16, nu in 0.1f64..3.0, h in 0.0f64..10.0,
                                         y in proptest::collection::vec(-1.0f64..1.0, 16)) {
        let b = basis(s, nu);
        let mut out = vec![0.0; s];
        b.shift(h, &y[..s], &mut out);
        let reference = e_dense(&b, h).transpose() * DVector::from_column_slice(&y[..s]);
        let mut mt = vec![0.0; s];
        b.mt_apply(&y[..s], &mut mt);
        let mt_ref = m_dense(&b).transpose() * DVector::from_column_slice(&y[..s]);
        let mut my = vec![0.0; s];
        b.m_apply(&y[..s], &mut my);
        let m_ref = m_dense(&b) * DVector::from_column_slice(&y[..s]);
        for i in 0..s {
            prop_assert!((out[i] - reference[i]).abs() < 1e-14);
            prop_assert!((mt[i] - mt_ref[i]).abs() < 1e-12);
            prop_assert!((my[i] - m_ref[i]).abs() < 1e-12);
        }
    }

    #[test]
    fn taylor_data_matches_dense_powers_of_m_transpose(s in 1usize..=16, nu in 0.1f64..3.0,
                                                       y in proptest::collection::vec(-1.0f64..1.0, 16)) {
        let b = basis(s, nu);
        let yv = DVector::from_column_slice(&y[..s]);
        let mt = m_dense(&b).transpose();
        let (d1, d2) = (&mt * &yv, &mt * &mt * &yv);
        let d3 = &mt * &d2;
        let data = b.taylor_data(&y[..s]);
        // Entries of (Mᵀ)^k y grow like (2ν s)^k: compare relative to that scale.
        let scale = |k: i32| (2.0 * nu * s as f64).powi(k).max(1.0) * s as f64;
        prop_assert!((data.sums[0] - yv.sum()).abs() < 1e-14 * scale(0));
        prop_assert!((data.sums[1] - d1.sum()).abs() < 1e-13 * scale(1));
        prop_assert!((data.sums[2] - d2.sum()).abs() < 1e-13 * scale(2));
        prop_assert!((data.norm - yv.norm()).abs() < 1e-14 * scale(0));
        prop_assert!((data.norm3 - d3.norm()).abs() < 1e-13 * scale(3));
    }

    #[test]
    fn norm_of_tau_is_non_increasing(s in 1usize..=20, nu in 0.1f64..3.0, t in 0.0f64..40.0, dt in 0.0f64..2.0) {
        let b = basis(s, nu);
        let (a, c) = (tau_vec(&b, t).norm(), tau_vec(&b, t + dt).norm());
        prop_assert!(c <= a * (1.0 + 1e-13) + 1e-300);
        prop_assert!(a <= b.sup_norm() * (1.0 + 1e-13));
    }
}
