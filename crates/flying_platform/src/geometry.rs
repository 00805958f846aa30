//! Nominal allocation geometry of the three actuation units (spec §3.2-3.3).
//!
//! Units sit at the corners of an equilateral triangle of side `2 l1`; unit `i` is turned by
//! `psi_i = 0°, 120°, 240°` about body z so that its local x axis (flap 1) points at the centre.
//! Inputs are ordered `(F1x F1y F1z F2x F2y F2z F3x F3y F3z)` in the units' local frames.

use nalgebra::{Matrix2, Matrix3, SMatrix, Vector3};

/// Number of thrust inputs (3 units x 3 local axes).
pub const N_INPUTS: usize = 9;
/// Input names in the order of the input vector (DESIGN.md).
pub const INPUT_NAMES: [&str; N_INPUTS] = [
    "F1x", "F1y", "F1z", "F2x", "F2y", "F2z", "F3x", "F3y", "F3z",
];

const S3_2: f64 = 0.866_025_403_784_438_6; // sqrt(3)/2

/// `J2 = [[0, 1], [-1, 0]]`.
pub fn j2() -> Matrix2<f64> {
    Matrix2::new(0.0, 1.0, -1.0, 0.0)
}

/// Nominal `T11` (2x9): local horizontal forces rotated into the body x/y axes.
pub fn t11_nominal() -> SMatrix<f64, 2, 9> {
    SMatrix::<f64, 2, 9>::from_row_slice(&[
        1.0, 0.0, 0.0, -0.5, -S3_2, 0.0, -0.5, S3_2, 0.0, //
        0.0, 1.0, 0.0, S3_2, -0.5, 0.0, -S3_2, -0.5, 0.0,
    ])
}

/// Nominal `V1` restricted to the vertical-thrust columns (2x3, columns F1z F2z F3z).
pub fn v1_nominal() -> SMatrix<f64, 2, 3> {
    SMatrix::<f64, 2, 3>::from_row_slice(&[0.0, -S3_2, S3_2, 1.0, -0.5, -0.5])
}

/// Circumradius `rho = 2 l1 / sqrt(3)` of the triangle of side `2 l1`.
pub fn circumradius(l1: f64) -> f64 {
    l1 / S3_2
}

/// Yaw angle `psi_i` (rad) of unit `i` (0-based) about body z.
pub fn unit_yaw(i: usize) -> f64 {
    (i % 3) as f64 * 2.0 * core::f64::consts::FRAC_PI_3
}

/// Rotation from unit `i`'s local frame to the body frame.
pub fn unit_rotation(i: usize) -> Matrix3<f64> {
    let (s, c) = unit_yaw(i).sin_cos();
    Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
}

/// Points where the unit forces act, in the body frame (z up, `l3` below the CoG).
pub fn unit_positions(l1: f64, l3: f64) -> [Vector3<f64>; 3] {
    let rho = circumradius(l1);
    [
        Vector3::new(-rho, 0.0, -l3),
        Vector3::new(rho / 2.0, -l1, -l3),
        Vector3::new(rho / 2.0, l1, -l3),
    ]
}
