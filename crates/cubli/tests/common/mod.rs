//! Shared strategies and helpers for the integration tests.
#![allow(dead_code)]
use cubli::{FullState, Params, ReducedState};
use nalgebra::{UnitQuaternion, Vector3};
use proptest::prelude::*;

pub fn vec3(scale: f64) -> impl Strategy<Value = Vector3<f64>> {
    (-scale..scale, -scale..scale, -scale..scale).prop_map(|(a, b, c)| Vector3::new(a, b, c))
}

/// Uniform unit vector (rejecting the tiny ball around zero).
pub fn unit() -> impl Strategy<Value = Vector3<f64>> {
    vec3(1.0)
        .prop_filter("away from zero", |v| v.norm() > 0.1)
        .prop_map(|v| v.normalize())
}

pub fn attitude() -> impl Strategy<Value = UnitQuaternion<f64>> {
    vec3(std::f64::consts::PI).prop_map(UnitQuaternion::from_scaled_axis)
}

pub fn reduced(
    p: &Params,
    g_dir: Vector3<f64>,
    p_h: Vector3<f64>,
    p_w: Vector3<f64>,
) -> ReducedState {
    ReducedState {
        g: g_dir.normalize() * p.gravity(),
        p_h,
        p_w,
    }
}

pub fn full_from_reduced_gravity(
    attitude: UnitQuaternion<f64>,
    p_h: Vector3<f64>,
    p_w: Vector3<f64>,
) -> FullState {
    FullState { attitude, p_h, p_w }
}

/// Attitude that lies at inclination `phi` from upright, tilting about body axis (1,-1,0)/√2.
pub fn tilted(p: &Params, phi: f64) -> UnitQuaternion<f64> {
    // Upright: R m̂ = e3. Start from the rotation taking m̂ to e3, then tilt about inertial e_x'.
    let up = UnitQuaternion::rotation_between(&p.m_hat(), &Vector3::z()).unwrap();
    let axis = up * Vector3::new(1.0, -1.0, 0.0).normalize();
    UnitQuaternion::from_scaled_axis(axis * phi) * up
}

pub fn deg(x: f64) -> f64 {
    x.to_radians()
}
