//! SO(3) maps against independent constructions, closed forms and finite differences.
#![allow(clippy::unwrap_used)]

use common::config;
use nalgebra::{Matrix3, Rotation3, Unit, Vector3};
use proptest::prelude::*;
use rigid_body::{so3, Error};
use std::f64::consts::{FRAC_PI_2, PI};

mod common;

fn unit_vector() -> impl Strategy<Value = Vector3<f64>> {
    (-1.0..1.0, -1.0..1.0, -1.0..1.0)
        .prop_filter("not too short", |(x, y, z)| x * x + y * y + z * z > 1e-2)
        .prop_map(|(x, y, z)| Vector3::new(x, y, z).normalize())
}

/// Rotation vectors with angles spread over (0, pi), near 0 and near pi.
fn rotation_vector() -> impl Strategy<Value = Vector3<f64>> {
    let angle = prop_oneof![
        0.0..PI - 1e-6,
        (-12.0f64..-2.0).prop_map(|e| 10f64.powf(e)),
        (-12.0f64..-2.0).prop_map(|e| PI - 10f64.powf(e)),
    ];
    (unit_vector(), angle).prop_map(|(n, a)| n * a)
}

fn rx(a: f64) -> Matrix3<f64> {
    Matrix3::new(1.0, 0.0, 0.0, 0.0, a.cos(), -a.sin(), 0.0, a.sin(), a.cos())
}
fn ry(a: f64) -> Matrix3<f64> {
    Matrix3::new(a.cos(), 0.0, a.sin(), 0.0, 1.0, 0.0, -a.sin(), 0.0, a.cos())
}
fn rz(a: f64) -> Matrix3<f64> {
    Matrix3::new(a.cos(), -a.sin(), 0.0, a.sin(), a.cos(), 0.0, 0.0, 0.0, 1.0)
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn hat_is_cross_product_and_vee_inverts_it(w in unit_vector(), v in unit_vector(), s in -5.0..5.0) {
        let w = w * s;
        prop_assert!((so3::hat(&w) * v - w.cross(&v)).norm() < 1e-15);
        prop_assert_eq!(so3::vee(&so3::hat(&w)), w);
    }

    #[test]
    fn exp_is_a_rotation_and_matches_axis_angle(w in rotation_vector()) {
        let r = so3::exp(&w);
        let m = r.matrix();
        prop_assert!((m.transpose() * m - Matrix3::identity()).norm() < 1e-15 * 10.0);
        prop_assert!((m.determinant() - 1.0).abs() < 1e-14);
        // Independent construction: nalgebra's axis-angle (quaternion-free Rodrigues).
        let reference = Rotation3::from_axis_angle(&Unit::new_normalize(w), w.norm());
        prop_assert!((m - reference.matrix()).norm() < 1e-14);
    }

    #[test]
    fn log_inverts_exp(w in rotation_vector()) {
        let back = so3::log(&so3::exp(&w));
        prop_assert!((back - w).norm() < 1e-12, "angle {} error {}", w.norm(), (back - w).norm());
    }

    #[test]
    fn exp_inverts_log(w in rotation_vector(), v in rotation_vector()) {
        // A generic rotation (product of two), then back through log.
        let r = so3::compose(&so3::exp(&w), &so3::exp(&v));
        let again = so3::exp(&so3::log(&r));
        prop_assert!((again.matrix() - r.matrix()).norm() < 1e-12);
        prop_assert!(so3::log(&r).norm() <= PI + 1e-15);
    }

    #[test]
    fn euler_round_trip_away_from_gimbal_lock(
        roll in -PI + 1e-9..PI,
        pitch in -FRAC_PI_2 + 1e-3..FRAC_PI_2 - 1e-3,
        yaw in -PI + 1e-9..PI,
    ) {
        let r = so3::from_euler_zyx(roll, pitch, yaw);
        prop_assert!((r.matrix() - rz(yaw) * ry(pitch) * rx(roll)).norm() < 1e-14);
        let (r2, p2, y2) = so3::euler_zyx(&r);
        prop_assert!((r2 - roll).abs() < 1e-11, "roll {roll} -> {r2}");
        prop_assert!((p2 - pitch).abs() < 1e-12);
        prop_assert!((y2 - yaw).abs() < 1e-11, "yaw {yaw} -> {y2}");
    }

    #[test]
    fn euler_at_gimbal_lock_reproduces_the_rotation(
        roll in -PI..PI, yaw in -PI..PI, sign in prop::bool::ANY, offset in 0.0f64..1e-11,
    ) {
        let pitch = if sign { FRAC_PI_2 - offset } else { -FRAC_PI_2 + offset };
        let r = so3::from_euler_zyx(roll, pitch, yaw);
        let (r2, p2, y2) = so3::euler_zyx(&r);
        let back = so3::from_euler_zyx(r2, p2, y2);
        prop_assert!((back.matrix() - r.matrix()).norm() < 1e-10);
        prop_assert!(r2.is_finite() && p2.is_finite() && y2.is_finite());
    }

    #[test]
    fn jacobian_identities(w in rotation_vector()) {
        let r = so3::exp(&w);
        let jr = so3::right_jacobian(&w);
        let jl = so3::left_jacobian(&w);
        prop_assert!((jl - r.matrix() * jr).norm() < 1e-14 * 10.0);
        prop_assert!((jr * so3::right_jacobian_inverse(&w) - Matrix3::identity()).norm() < 1e-11);
        prop_assert!((jl * so3::left_jacobian_inverse(&w) - Matrix3::identity()).norm() < 1e-11);
    }

    #[test]
    fn right_jacobian_matches_finite_differences(n in unit_vector(), angle in 0.0..3.0) {
        let w = n * angle;
        let r_inv = so3::exp(&w).inverse();
        let eps = 1e-6;
        let jr = so3::right_jacobian(&w);
        let jl = so3::left_jacobian(&w);
        for i in 0..3 {
            let d = Vector3::ith(i, eps);
            // Right perturbation: exp(w)^-1 exp(w + d) ≈ exp(J_r d).
            let fd_r = (so3::log(&(r_inv * so3::exp(&(w + d))))
                - so3::log(&(r_inv * so3::exp(&(w - d))))) / (2.0 * eps);
            prop_assert!((fd_r - jr.column(i)).norm() < 1e-8);
            // Left perturbation: exp(w + d) exp(w)^-1 ≈ exp(J_l d).
            let fd_l = (so3::log(&(so3::exp(&(w + d)) * r_inv))
                - so3::log(&(so3::exp(&(w - d)) * r_inv))) / (2.0 * eps);
            prop_assert!((fd_l - jl.column(i)).norm() < 1e-8);
        }
    }
}

#[test]
fn exact_angles_and_small_angle_accuracy() {
    // Half turn about x: log must return +-pi e_x.
    let r = so3::exp(&Vector3::new(PI, 0.0, 0.0));
    let w = so3::log(&r);
    assert!((w.x.abs() - PI).abs() < 1e-15 && w.y == 0.0 && w.z == 0.0);
    // Tiny rotation: first-order exactness, no cancellation.
    let w = Vector3::new(1e-14, -2e-14, 3e-14);
    assert!((so3::log(&so3::exp(&w)) - w).norm() < 1e-28);
    assert_eq!(so3::log(&Rotation3::identity()), Vector3::zeros());
    // Jacobians at zero are the identity, and continuous across the series threshold.
    assert_eq!(so3::right_jacobian(&Vector3::zeros()), Matrix3::identity());
    let n = Vector3::new(0.6, 0.0, 0.8);
    for f in [so3::right_jacobian, so3::right_jacobian_inverse] {
        let below = f(&(n * (1e-2 * (1.0 - 1e-14))));
        let above = f(&(n * (1e-2 * (1.0 + 1e-14))));
        assert!((below - above).norm() < 1e-14);
    }
}

#[test]
fn rotation_check_names_the_problem() {
    let m = Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, -1.0);
    let err = so3::rotation("R", &m).unwrap_err();
    assert!(matches!(err, Error::NotRotation { name: "R", .. }));
    assert!(err.to_string().starts_with("R is not a rotation matrix"));
    let err = so3::rotation("R", &(Matrix3::identity() * 1.1)).unwrap_err();
    assert!(matches!(err, Error::NotRotation { .. }));
    let err = so3::rotation("R", &Matrix3::from_element(f64::NAN)).unwrap_err();
    assert_eq!(err, Error::NonFinite { name: "R" });
    let r = so3::rotation("R", so3::exp(&Vector3::new(0.3, 0.2, 0.1)).matrix()).unwrap();
    assert!((so3::log(&r) - Vector3::new(0.3, 0.2, 0.1)).norm() < 1e-15);
}

#[test]
fn exp_of_a_rotation_vector_too_large_to_square_is_still_a_rotation() {
    // 1e300 squared overflows; the rotation by 1e300 rad about x is still defined (the angle
    // reduced mod 2 pi by the sine and cosine themselves), and the closed form is the reference.
    for angle in [1e300, -3e200, 1e155, 12.5] {
        let r = so3::exp(&Vector3::new(angle, 0.0, 0.0));
        let diff = (r.matrix() - rx(angle)).amax();
        assert!(diff < 1e-15, "angle {angle}: {diff}");
        let off_axis = so3::exp(&Vector3::new(0.0, 0.6 * angle, 0.8 * angle));
        let m = off_axis.matrix();
        assert!(m.iter().all(|v| v.is_finite()), "angle {angle}: {m}");
        assert!((m.transpose() * m - Matrix3::identity()).amax() < 1e-14);
        assert!((m * Vector3::new(0.0, 0.6, 0.8) - Vector3::new(0.0, 0.6, 0.8)).amax() < 1e-14);
    }
}
