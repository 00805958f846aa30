//! Layouts and random draws shared by the integration tests.
#![allow(dead_code, clippy::unwrap_used)]

use nalgebra::{Matrix3, Vector3};
use rand::rngs::StdRng;
use rand::Rng;
use rigid_body::so3;
use tilt::simulation::gaussian_vector;
use tilt::{Layout, G0};

/// The 4-sensor layout of the paper's simulation (spec section 8.1).
pub fn simulation_positions() -> [Vector3<f64>; 4] {
    [
        Vector3::new(1.0, 0.0, 0.0),
        Vector3::new(0.0, 1.0, 0.0),
        Vector3::new(0.0, 0.0, 1.0),
        Vector3::new(0.2, 0.2, 0.2) / 3f64.sqrt(),
    ]
}

pub fn simulation_layout() -> Layout {
    Layout::new(&simulation_positions()).unwrap()
}

/// Three sensors 0.05 m along the axes (spec section 8.5).
pub fn three_positions() -> [Vector3<f64>; 3] {
    [
        Vector3::new(0.05, 0.0, 0.0),
        Vector3::new(0.0, 0.05, 0.0),
        Vector3::new(0.0, 0.0, 0.05),
    ]
}

/// The experimental layout (spec section 9).
pub fn experiment_layout() -> Layout {
    Layout::new(&[
        Vector3::new(0.122, 0.013, 0.145),
        Vector3::new(0.145, 0.122, 0.013),
        Vector3::new(0.028, 0.013, 0.005),
        Vector3::new(0.005, 0.122, 0.013),
    ])
    .unwrap()
}

pub fn down() -> Vector3<f64> {
    Vector3::new(0.0, 0.0, -G0)
}

/// A uniformly random point of the sphere of radius g0.
pub fn random_gravity(rng: &mut StdRng) -> Vector3<f64> {
    gaussian_vector(rng).normalize() * G0
}

/// A random rotation matrix.
pub fn random_rotation(rng: &mut StdRng) -> Matrix3<f64> {
    let axis = gaussian_vector(rng).normalize() * rng.random_range(0.0..std::f64::consts::PI);
    so3::exp(&axis).into_inner()
}

/// `true` when `a` lies in M: `symm(a)` has eigenvalues `(-s, -s, 0)`, `s >= 0`.
pub fn in_m(a: &Matrix3<f64>, tol: f64) -> bool {
    let s = (a + a.transpose()) * 0.5;
    let mut e: Vec<f64> = s.symmetric_eigenvalues().iter().copied().collect();
    e.sort_by(f64::total_cmp);
    let scale = e[0].abs().max(1.0);
    (e[0] - e[1]).abs() <= tol * scale && e[2].abs() <= tol * scale && e[0] <= tol * scale
}
