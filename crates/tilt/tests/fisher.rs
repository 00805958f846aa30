//! Acceptance tests F1-F6 of spec/tilt.md section 11 (Fisher information, Cramer-Rao bound,
//! D-optimal placement).
#![allow(clippy::unwrap_used)]

mod common;

use common::*;
use nalgebra::{Matrix3, Matrix3x2, SMatrix, Vector2, Vector3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rigid_body::so3;
use tilt::simulation::gaussian_vector;
use tilt::{
    d_criterion, d_criterion_bound, expected_omega_block, fisher_information, jacobian,
    omega_matrix, optimality_residuals, platonic_layout, tangent_basis, Layout, Matrix8, TiltError,
    G0, MAX_SENSORS,
};

/// Residual `m - Omega(omega, omega_dot) p + exp([Pi n]x) g_bar` with `m` chosen so that it
/// vanishes at the reference point.
fn residual(
    x: &SMatrix<f64, 8, 1>,
    p: &Vector3<f64>,
    g_bar: &Vector3<f64>,
    basis: &Matrix3x2<f64>,
) -> Vector3<f64> {
    let omega = Vector3::new(x[0], x[1], x[2]);
    let omega_dot = Vector3::new(x[3], x[4], x[5]);
    let n = basis * Vector2::new(x[6], x[7]);
    -omega_matrix(&omega, &omega_dot) * p + so3::exp(&n) * g_bar
}

#[test]
fn f1_jacobian_matches_finite_differences() {
    let mut rng = StdRng::seed_from_u64(1);
    for _ in 0..200 {
        let (p, w, h, g) = (
            gaussian_vector(&mut rng),
            gaussian_vector(&mut rng),
            gaussian_vector(&mut rng),
            random_gravity(&mut rng),
        );
        let basis = tangent_basis(&g).unwrap();
        let j = jacobian(&p, &w, &g, &basis);
        let mut x = SMatrix::<f64, 8, 1>::zeros();
        x.fixed_rows_mut::<3>(0).copy_from(&w);
        x.fixed_rows_mut::<3>(3).copy_from(&h);
        let step = 1e-6;
        for k in 0..8 {
            let mut dx = SMatrix::<f64, 8, 1>::zeros();
            dx[k] = step;
            let fd = (residual(&(x + dx), &p, &g, &basis) - residual(&(x - dx), &p, &g, &basis))
                / (2.0 * step);
            let col = j.column(k);
            assert!(
                (fd - col).norm() <= 1e-6 * col.norm().max(1.0),
                "column {k}: {fd} vs {col}"
            );
        }
    }
}

#[test]
fn tangent_basis_is_orthonormal_and_canonical_for_z_down() {
    let basis = tangent_basis(&down()).unwrap();
    assert_eq!(basis, Matrix3x2::new(1.0, 0.0, 0.0, 1.0, 0.0, 0.0));
    let mut rng = StdRng::seed_from_u64(2);
    for _ in 0..100 {
        let g = random_gravity(&mut rng);
        let b = tangent_basis(&g).unwrap();
        assert!((b.transpose() * b - nalgebra::Matrix2::identity()).norm() < 1e-12);
        assert!((b.transpose() * g).norm() < 1e-12);
    }
    assert!(matches!(
        tangent_basis(&Vector3::zeros()),
        Err(TiltError::InvalidState(_))
    ));
}

/// The paper's Jacobian (2.54): `(2[omega]x[p]x, [p]x, -[g]x Pi)`.
fn paper_information(layout: &Layout, w: &Vector3<f64>, g: &Vector3<f64>) -> Matrix8 {
    let basis = tangent_basis(g).unwrap();
    let mut info = Matrix8::zeros();
    for p in layout.positions() {
        let mut j = SMatrix::<f64, 3, 8>::zeros();
        j.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(w.cross_matrix() * p.cross_matrix() * 2.0));
        j.fixed_view_mut::<3, 3>(0, 3).copy_from(&p.cross_matrix());
        j.fixed_view_mut::<3, 2>(0, 6)
            .copy_from(&(-g.cross_matrix() * basis));
        info += j.transpose() * j;
    }
    info
}

fn f4_state() -> (Vector3<f64>, Vector3<f64>) {
    (Vector3::new(1.0, -0.5, 0.8), Vector3::new(2.0, 1.0, -1.0))
}

#[test]
fn f2_paper_jacobian_differs_only_in_the_omega_dot_block() {
    let layout = simulation_layout();
    let (w, h) = f4_state();
    let exact = fisher_information(&layout, &w, &h, &down(), 1.0).unwrap();
    let paper = paper_information(&layout, &w, &down());
    let (de, dp) = (exact.matrix().determinant(), paper.determinant());
    assert!((de - dp).abs() <= 1e-8 * de.abs(), "{de} vs {dp}");
    let (ce, cp) = (
        exact.crb().unwrap().covariance,
        paper.try_inverse().unwrap(),
    );
    let block = |m: &Matrix8, k: usize, n: usize| m.view((k, k), (n, n)).into_owned();
    assert!((block(&ce, 0, 3) - block(&cp, 0, 3)).norm() < 1e-9 * block(&ce, 0, 3).norm());
    assert!((block(&ce, 6, 2) - block(&cp, 6, 2)).norm() < 1e-9 * block(&ce, 6, 2).norm());
    assert!(
        (block(&ce, 3, 3).trace() - 2.2419).abs() < 1e-3,
        "{}",
        block(&ce, 3, 3).trace()
    );
    assert!(
        (block(&cp, 3, 3).trace() - 3.722).abs() < 1e-3,
        "{}",
        block(&cp, 3, 3).trace()
    );
}

#[test]
fn f3_rank_of_the_fisher_information() {
    let sim = simulation_layout();
    let (w, h) = f4_state();
    assert_eq!(
        fisher_information(&sim, &w, &h, &down(), 1.0)
            .unwrap()
            .rank(),
        8
    );
    let at_rest = fisher_information(&sim, &Vector3::zeros(), &h, &down(), 1.0).unwrap();
    assert!(at_rest.rank() <= 5);
    assert_eq!(
        at_rest.crb().unwrap_err(),
        TiltError::SingularFisher {
            rank: at_rest.rank()
        }
    );
    let three = Layout::new(&three_positions()).unwrap();
    assert_eq!(
        fisher_information(&three, &w, &h, &down(), 1.0)
            .unwrap()
            .rank(),
        8
    );
    let mut rng = StdRng::seed_from_u64(3);
    for _ in 0..20 {
        let g = random_gravity(&mut rng);
        let along = Vector3::new(1.0, 1.0, 1.0) * rng.random_range(0.1..3.0);
        let f = fisher_information(&three, &along, &gaussian_vector(&mut rng), &g, 1.0).unwrap();
        let s = f.jacobian_singular_values();
        assert_eq!(f.rank(), 7, "{s}");
        assert!(s[7] < 1e-9 * s[0]);
        assert!(f.crb().is_err());
    }
}

#[test]
fn f3_layouts_without_full_span_or_with_two_sensors_are_rejected() {
    // Rank < 8 at every state: the layout itself is refused.
    let planar = [
        Vector3::new(1.0, 0.0, 0.0),
        Vector3::new(0.0, 1.0, 0.0),
        Vector3::new(1.0, 1.0, 0.0),
    ];
    assert!(matches!(
        Layout::new(&planar),
        Err(TiltError::PositionsDoNotSpan { rank: 2 })
    ));
    let two = [Vector3::new(1.0, 0.0, 0.0), Vector3::new(0.0, 1.0, 1.0)];
    assert_eq!(
        Layout::new(&two).unwrap_err(),
        TiltError::TooFewSensors { got: 2 }
    );
    // The stacked Jacobian of the planar layout (through the pivot) is singular when omega
    // lies in the plane or along its normal, but not for generic omega (the paper's
    // Proposition 2 claims singularity for every state; spec section 6.3 repeats it).
    let basis = tangent_basis(&down()).unwrap();
    let stacked_singular_values = |positions: &[Vector3<f64>], w: Vector3<f64>| {
        let mut stacked = nalgebra::DMatrix::zeros(3 * positions.len(), 8);
        for (i, p) in positions.iter().enumerate() {
            stacked
                .view_mut((3 * i, 0), (3, 8))
                .copy_from(&jacobian(p, &w, &down(), &basis));
        }
        let sv = stacked.singular_values();
        (sv.len(), sv.min() / sv.max())
    };
    for w in [
        Vector3::new(0.0, 0.0, 1.0),
        Vector3::new(1.0, 0.0, 0.0),
        Vector3::new(1.0, 1.0, 0.0),
    ] {
        assert!(stacked_singular_values(&planar, w).1 < 1e-12);
    }
    for w in [Vector3::new(1.0, -0.5, 0.8), Vector3::new(1.0, 1.0, 1.0)] {
        assert!(stacked_singular_values(&planar, w).1 > 1e-2);
    }
    // Two sensors give 6 equations for 8 unknowns.
    assert_eq!(
        stacked_singular_values(&two, Vector3::new(1.0, -0.5, 0.8)).0,
        6
    );
}

#[test]
fn f4_cramer_rao_traces_per_unit_noise() {
    let (w, h) = f4_state();
    let crb = fisher_information(&simulation_layout(), &w, &h, &down(), 1.0)
        .unwrap()
        .crb()
        .unwrap();
    assert!(
        (crb.omega.trace() - 0.8420).abs() < 1e-4,
        "{}",
        crb.omega.trace()
    );
    assert!(
        (crb.omega_dot.trace() - 2.2419).abs() < 1e-4,
        "{}",
        crb.omega_dot.trace()
    );
    assert!(
        (crb.tilt.trace() - 1.2704).abs() < 1e-4,
        "{}",
        crb.tilt.trace()
    );
    let n_block = crb.covariance.fixed_view::<2, 2>(6, 6).trace();
    assert!((n_block - 0.013201).abs() < 1e-6, "{n_block}");
    // Scaling: the bound is proportional to sigma^2.
    let scaled = fisher_information(&simulation_layout(), &w, &h, &down(), 7.7e-3)
        .unwrap()
        .crb()
        .unwrap();
    assert!((scaled.tilt.trace() / crb.tilt.trace() - 7.7e-3f64.powi(2)).abs() < 1e-15);
}

#[test]
fn f5_expected_omega_block() {
    let mut rng = StdRng::seed_from_u64(5);
    let layout = simulation_layout();
    let sigma_omega = 1.3;
    let mut mean = Matrix8::zeros();
    let samples = 20_000;
    for _ in 0..samples {
        let w = gaussian_vector(&mut rng) * sigma_omega;
        mean += fisher_information(&layout, &w, &Vector3::zeros(), &down(), 1.0)
            .unwrap()
            .matrix();
    }
    mean /= samples as f64;
    let expected = expected_omega_block(&layout, sigma_omega);
    let scale = (0..3).map(|k| expected[(k, k)]).fold(0.0, f64::max);
    let block = mean.fixed_view::<3, 3>(0, 0);
    assert!(
        (block - expected).amax() < 0.03 * scale,
        "{block} vs {expected}"
    );
    assert!(mean.fixed_view::<3, 5>(0, 3).amax() < 0.03 * scale);
    // The paper's 8 sigma^2 Theta is off on the diagonal by about a third.
    let paper = layout.theta() * (8.0 * sigma_omega * sigma_omega);
    assert!((paper[(0, 0)] / expected[(0, 0)] - 1.0).abs() > 0.25);
}

#[test]
fn f6_d_criterion_of_platonic_and_random_layouts() {
    let mut buffer = [Vector3::zeros(); MAX_SENSORS];
    for (l, value) in [(4, 2.0512e10), (6, 7.8855e11), (8, 1.0502e13)] {
        let layout = Layout::new(platonic_layout(l, &mut buffer).unwrap()).unwrap();
        let bound = d_criterion_bound(l, G0);
        assert!((bound / value - 1.0).abs() < 1e-4, "{bound} vs {value}");
        let d = d_criterion(&layout, &down());
        assert!((d / bound - 1.0).abs() < 1e-9, "L = {l}: {d} vs {bound}");
        assert!(optimality_residuals(&layout).iter().all(|&r| r < 1e-12));
    }
    for l in [12, 20] {
        let layout = Layout::new(platonic_layout(l, &mut buffer).unwrap()).unwrap();
        let mut rng = StdRng::seed_from_u64(l as u64);
        // With the centroid at the pivot the criterion does not depend on the orientation.
        let d = d_criterion(&layout, &random_gravity(&mut rng));
        assert!((d / d_criterion_bound(l, G0) - 1.0).abs() < 1e-9);
    }
    assert!(platonic_layout(5, &mut buffer).is_err());

    let mut rng = StdRng::seed_from_u64(6);
    let bound = d_criterion_bound(4, G0);
    let mut max_ratio = 0.0f64;
    for _ in 0..20_000 {
        let positions: Vec<_> = (0..4)
            .map(|_| gaussian_vector(&mut rng).normalize() * rng.random_range(0.0f64..1.0).cbrt())
            .collect();
        if let Ok(layout) = Layout::new(&positions) {
            max_ratio = max_ratio.max(d_criterion(&layout, &down()) / bound);
        }
    }
    assert!(max_ratio < 1.0 && max_ratio > 0.3, "max ratio {max_ratio}");

    let sim = simulation_layout();
    assert!(
        (d_criterion(&sim, &down()) / 1.8170e9 - 1.0).abs() < 1e-4,
        "{}",
        d_criterion(&sim, &down())
    );
    // Orientation dependence for p != 0 (spec erratum on (2.64)).
    let other = d_criterion(&sim, &(-Vector3::new(1.0, 1.0, 1.0).normalize() * G0));
    assert!((other / 1.163e9 - 1.0).abs() < 1e-3, "{other}");
}

#[test]
fn theta_is_the_inertia_of_unit_masses() {
    let layout = simulation_layout();
    let direct: Matrix3<f64> = layout
        .positions()
        .iter()
        .map(|p| -p.cross_matrix() * p.cross_matrix())
        .sum();
    assert!((layout.theta() - direct).norm() < 1e-12);
}

#[test]
fn optimal_placement_reaches_the_bound() {
    let mut buffer = [Vector3::zeros(); MAX_SENSORS];
    for l in (4..=20).filter(|&l| l != 5) {
        let (positions, ratio) = tilt::optimal_placement(l, &mut buffer).unwrap();
        let layout = Layout::new(positions).unwrap();
        // The reported ratio is the criterion of the returned layout.
        assert!((d_criterion(&layout, &down()) / d_criterion_bound(l, G0) - ratio).abs() < 1e-12);
        assert!(ratio > 1.0 - 1e-6, "L = {l}: ratio {ratio}");
        assert!(
            optimality_residuals(&layout).iter().all(|&r| r < 1e-6),
            "L = {l}"
        );
    }
    assert!(matches!(
        tilt::optimal_placement(3, &mut buffer),
        Err(TiltError::InvalidOption { .. })
    ));
}

#[test]
fn five_sensors_cannot_reach_the_bound() {
    // (2.65) needs a rank-1 projector u u^T on the complement of 1 with u_i^2 = 1/5 and
    // sum u_i = 0: impossible with an odd number of entries +-1/sqrt(5). The ascent's result
    // must still beat every random layout on the sphere.
    let mut buffer = [Vector3::zeros(); MAX_SENSORS];
    let (positions, ratio) = tilt::optimal_placement(5, &mut buffer).unwrap();
    assert!(positions.iter().all(|p| (p.norm() - 1.0).abs() < 1e-12));
    assert!(ratio > 0.98 && ratio < 1.0, "{ratio}");
    let mut rng = StdRng::seed_from_u64(55);
    let bound = d_criterion_bound(5, G0);
    for _ in 0..20_000 {
        let random: Vec<_> = (0..5)
            .map(|_| gaussian_vector(&mut rng).normalize())
            .collect();
        if let Ok(layout) = Layout::new(&random) {
            assert!(d_criterion(&layout, &down()) / bound <= ratio);
        }
    }
}
