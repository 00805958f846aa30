//! Projection onto M = { [w]x^2 + [h]x } against its defining properties, an independent
//! search over directions, and the derivative values stated in spec/tilt.md.
#![allow(clippy::unwrap_used)]

use common::config;
use nalgebra::{Matrix3, Vector3};
use proptest::prelude::*;
use rigid_body::so3::{exp, hat};
use rigid_body::{matrix_set, Error};

mod common;

fn vector(lim: f64) -> impl Strategy<Value = Vector3<f64>> {
    (-lim..lim, -lim..lim, -lim..lim).prop_map(|(x, y, z)| Vector3::new(x, y, z))
}

fn matrix(lim: f64) -> impl Strategy<Value = Matrix3<f64>> {
    prop::array::uniform9(-lim..lim).prop_map(|a| Matrix3::from_column_slice(&a))
}

fn member(w: &Vector3<f64>, h: &Vector3<f64>) -> Matrix3<f64> {
    hat(w) * hat(w) + hat(h)
}

/// Independent reference: the squared distance from `a` to M minimised over a Fibonacci grid
/// of directions `u` (skew part kept; for fixed `u` the best `|w|^2` is
/// `max(0, (u^T S u - tr S) / 2)`, a one-dimensional least-squares fit).
fn grid_distance_squared(a: &Matrix3<f64>, points: usize) -> f64 {
    let s = matrix_set::symm(a);
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..points)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / points as f64;
            let rho = (1.0 - z * z).sqrt();
            let phi = golden * i as f64;
            let u = Vector3::new(rho * phi.cos(), rho * phi.sin(), z);
            let basis = u * u.transpose() - Matrix3::identity();
            let t = ((u.transpose() * s * u)[0] - s.trace()) / 2.0;
            (s - basis * t.max(0.0)).norm_squared()
        })
        .fold(f64::INFINITY, f64::min)
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn member_projects_to_itself(w in vector(3.0), h in vector(3.0)) {
        let a = member(&w, &h);
        let p = matrix_set::project(&a).unwrap();
        prop_assert!((p.matrix - a).norm() < 1e-12 * a.norm().max(1.0));
        prop_assert!((p.h - h).norm() < 1e-15 * 10.0);
        let (pw, ww) = (hat(&p.w) * hat(&p.w), hat(&w) * hat(&w));
        prop_assert!((pw - ww).norm() < 1e-12 * a.norm().max(1.0));
        prop_assert!(p.distance_squared < 1e-22 * a.norm_squared().max(1.0));
    }

    #[test]
    fn projection_is_idempotent_and_in_m(a in matrix(3.0)) {
        let p = matrix_set::project(&a).unwrap();
        let pp = matrix_set::project(&p.matrix).unwrap();
        prop_assert!((pp.matrix - p.matrix).norm() < 1e-12 * a.norm().max(1.0));
        prop_assert!((member(&p.w, &p.h) - p.matrix).norm() < 1e-14 * a.norm().max(1.0));
        // Symmetric part of the result: eigenvalues (-s, -s, 0), s >= 0.
        let mut ev: Vec<f64> = matrix_set::symm(&p.matrix).symmetric_eigenvalues().iter().copied().collect();
        ev.sort_by(f64::total_cmp);
        prop_assert!((ev[0] - ev[1]).abs() < 1e-12 && ev[2].abs() < 1e-12 && ev[0] <= 1e-12);
    }

    #[test]
    fn projection_is_nearest(a in matrix(3.0), samples in prop::collection::vec((vector(3.0), vector(3.0)), 32)) {
        let p = matrix_set::project(&a).unwrap();
        let d2 = (a - p.matrix).norm_squared();
        prop_assert!((d2 - p.distance_squared).abs() < 1e-12 * a.norm_squared().max(1.0));
        // No sampled member is closer: random members, and members near the projection.
        for (w, h) in &samples {
            prop_assert!((a - member(w, h)).norm_squared() >= d2 - 1e-12);
            let near = member(&(p.w + w * 1e-3), &(p.h + h * 1e-3));
            prop_assert!((a - near).norm_squared() >= d2 - 1e-12);
        }
        // Independent search over directions agrees to grid resolution.
        let grid = grid_distance_squared(&a, 20_000);
        prop_assert!(d2 <= grid + 1e-12, "projection {d2} worse than grid {grid}");
        prop_assert!(grid - d2 < 5e-3 * a.norm_squared().max(1.0), "grid {grid} vs {d2}");
    }

    #[test]
    fn projection_is_rotation_equivariant(a in matrix(3.0), axis in vector(3.0)) {
        let t = exp(&axis);
        let t = t.matrix();
        let p = matrix_set::project(&a).unwrap().matrix;
        let q = matrix_set::project(&(t * a * t.transpose())).unwrap().matrix;
        prop_assert!((q - t * p * t.transpose()).norm() < 1e-11 * a.norm().max(1.0));
    }
}

#[test]
fn closed_forms_from_the_spec() {
    // Midpoint of [e1]x^2 and [e2]x^2 is -diag(1, 1, 2)/2, not in M: eigenvalues (-1, -1/2, -1/2),
    // distance^2 = (λ1 - λ2)^2 / 2 + λ3^2 = 0.375 (a tie λ2 = λ3: any top eigenvector works).
    let mid = Matrix3::from_diagonal(&Vector3::new(-0.5, -0.5, -1.0));
    let p = matrix_set::project(&mid).unwrap();
    assert!((p.distance_squared - 0.375).abs() < 1e-15);
    assert!(((mid - p.matrix).norm_squared() - 0.375).abs() < 1e-14);
    // Positive semidefinite symmetric part: the projection keeps only the skew part.
    let a = Matrix3::new(1.0, 2.0, 0.0, 0.0, 2.0, -1.0, 0.5, 0.0, 3.0);
    let p = matrix_set::project(&a).unwrap();
    assert_eq!(p.w, Vector3::zeros());
    assert!((p.matrix - matrix_set::skew(&a)).norm() < 1e-15);
    let err = matrix_set::project(&Matrix3::from_element(f64::NAN)).unwrap_err();
    assert_eq!(err, Error::NonFinite { name: "A" });
}

/// Central difference of the projection in direction `d`.
fn derivative(a: &Matrix3<f64>, d: &Matrix3<f64>) -> Matrix3<f64> {
    let eps = 1e-6;
    let plus = matrix_set::project(&(a + d * eps)).unwrap().matrix;
    let minus = matrix_set::project(&(a - d * eps)).unwrap().matrix;
    (plus - minus) / (2.0 * eps)
}

fn unit(i: usize, j: usize) -> Matrix3<f64> {
    let mut e = Matrix3::zeros();
    e[(i, j)] = 1.0;
    e
}

#[test]
fn derivative_at_a_diagonal_point_matches_spec_erratum() {
    // spec/tilt.md 4.4 at λ = (-3, -1, 2): c13 = 0.2, c23 = 1/3 (with the minus sign).
    let a = Matrix3::from_diagonal(&Vector3::new(-3.0, -1.0, 2.0));
    let (c13, c23) = (0.2, 1.0 / 3.0);
    let sym = |i, j| unit(i, j) + unit(j, i);
    let asym = |i, j| (unit(i, j) - unit(j, i)) * 0.5;
    let cases = [
        (
            unit(0, 0),
            Matrix3::from_diagonal(&Vector3::new(0.5, 0.5, 0.0)),
        ),
        (unit(2, 2), Matrix3::zeros()),
        (unit(0, 1), asym(0, 1)),
        (unit(0, 2), sym(0, 2) * c13 + asym(0, 2)),
        (unit(2, 0), sym(0, 2) * c13 + asym(2, 0)),
        (unit(1, 2), sym(1, 2) * c23 + asym(1, 2)),
    ];
    for (direction, want) in cases {
        assert!(
            (derivative(&a, &direction) - want).norm() < 1e-8,
            "{direction}"
        );
    }
    // Corrected Lipschitz gain at diag(-5, -4, 1) along (E23 + E32)/sqrt 2: 0.9 (paper's formula: 0.636).
    let a = Matrix3::from_diagonal(&Vector3::new(-5.0, -4.0, 1.0));
    let d = (unit(1, 2) + unit(2, 1)) / 2f64.sqrt();
    assert!((derivative(&a, &d).norm() - 0.9).abs() < 1e-8);
}
