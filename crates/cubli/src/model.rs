//! Equations of motion in generalized momenta (spec §2): reduced and full models, conserved
//! quantities, inclination, the split of p_h into controllable and yaw parts, equilibria.
use nalgebra::{ComplexField, Quaternion, RealField, SMatrix, Vector3};

use crate::{CubliError, FullState, Params, ReducedState};

/// Right-hand side of the reduced model (1.5): returns (ġ, ṗ_h, ṗ_w) packed as a `ReducedState`.
///
/// ṗ_h = −ω_h × p_h + m × g, ṗ_w = T, ġ = −ω_h × g. `torque` is the torque the motors apply.
pub fn reduced_derivative(
    params: &Params,
    x: &ReducedState,
    torque: &Vector3<f64>,
) -> ReducedState {
    let w = x.omega_h(params);
    ReducedState {
        g: -w.cross(&x.g),
        p_h: -w.cross(&x.p_h) + params.m().cross(&x.g),
        p_w: *torque,
    }
}

/// Time derivative of the full state (1.1): (q̇, ṗ_h, ṗ_w) with q̇ = ½ q ⊗ (0, ω_h) for R = R(q).
pub fn full_derivative(
    params: &Params,
    x: &FullState,
    torque: &Vector3<f64>,
) -> (Quaternion<f64>, Vector3<f64>, Vector3<f64>) {
    let w = x.omega_h(params);
    let g = x.gravity_body(params);
    let q_dot = x.attitude.quaternion() * Quaternion::from_imag(w) * 0.5;
    (q_dot, -w.cross(&x.p_h) + params.m().cross(&g), *torque)
}

/// Unit gravity direction ĝ = g/|g|.
pub fn g_hat(x: &ReducedState) -> Vector3<f64> {
    x.g / x.g.norm()
}

/// Yaw momentum p_hᵍ = p_hᵀ ĝ: conserved for any torque (1.2); only friction at the pivot changes it.
pub fn yaw_momentum(x: &ReducedState) -> f64 {
    x.p_h.dot(&g_hat(x))
}

/// Split (1.8): p_h = p_h⊥ + p_hᵍ ĝ. Returns (p_h⊥, p_hᵍ); only p_h⊥ is controllable.
pub fn split_momentum(x: &ReducedState) -> (Vector3<f64>, f64) {
    let gh = g_hat(x);
    let pg = x.p_h.dot(&gh);
    (x.p_h - gh * pg, pg)
}

/// Total energy (1.3), zero upright at rest with wheels stopped; conserved when T = 0.
pub fn energy(params: &Params, x: &ReducedState) -> f64 {
    let w = x.omega_h(params);
    let abs = x.p_w.component_div(params.theta_w());
    0.5 * w.dot(&(params.theta0() * w)) + 0.5 * abs.dot(&x.p_w) - params.m().dot(&x.g) - params.mg()
}

/// Housing energy (1.4); Ḣ_h = −ω_hᵀ T.
pub fn housing_energy(params: &Params, x: &ReducedState) -> f64 {
    let w = x.omega_h(params);
    0.5 * w.dot(&(params.theta0() * w)) - params.m().dot(&x.g) - params.mg()
}

/// Momentum about the figure axis p_hᵐ = p_hᵀ m̂ (1.54).
pub fn figure_axis_momentum(params: &Params, x: &ReducedState) -> f64 {
    x.p_h.dot(&params.m_hat())
}

/// Inclination φ = arccos(−mᵀg / (|m||g|)) ∈ [0, π]; 0 is upright (1.26). Computed with atan2
/// so that it stays accurate near 0 and π.
pub fn inclination(params: &Params, g: &Vector3<f64>) -> f64 {
    let m = params.m();
    RealField::atan2(m.cross(g).norm(), -m.dot(g))
}

/// Tilt axis e_φ = (m × g)/|m × g| (1.25); undefined upright and hanging.
pub fn tilt_axis(params: &Params, g: &Vector3<f64>) -> Result<Vector3<f64>, CubliError> {
    let c = params.m().cross(g);
    let n = c.norm();
    if n <= 1e-12 * params.mg() {
        return Err(CubliError::TiltAxisUndefined);
    }
    Ok(c / n)
}

/// Signed inclination atan2((m × g)ᵀ e0, −mᵀg) about a fixed axis `e0` (spec §2.5), for planar
/// motions that pass through upright.
pub fn signed_inclination(params: &Params, g: &Vector3<f64>, e0: &Vector3<f64>) -> f64 {
    let m = params.m();
    RealField::atan2(m.cross(g).dot(e0), -m.dot(g))
}

/// Relative equilibrium (1.6)–(1.7): a steady spin λ1 about the vertical with
/// λ1 p̄_h + m = λ2 ḡ. `g_bar` is scaled to |g|; λ1 must be non-zero.
pub fn relative_equilibrium(
    params: &Params,
    g_bar: &Vector3<f64>,
    lambda1: f64,
    lambda2: f64,
) -> Result<ReducedState, CubliError> {
    if lambda1 == 0.0 || !lambda1.is_finite() {
        return Err(CubliError::NonPositive {
            field: "|lambda1|",
            value: lambda1,
        });
    }
    let g = g_bar * (params.gravity() / g_bar.norm());
    let p_h = (g * lambda2 - params.m()) / lambda1;
    let omega = g * lambda1;
    Ok(ReducedState {
        g,
        p_h,
        p_w: p_h - params.theta0() * omega,
    })
}

/// Upright rest state with wheel momentum `p_w` (must be parallel to gravity for T = 0 to hold it).
pub fn upright(params: &Params, p_w: Vector3<f64>) -> ReducedState {
    ReducedState {
        g: -params.m_hat() * params.gravity(),
        p_h: p_w,
        p_w,
    }
}

/// Jacobian (A, B) of the reduced model at (x, T), in the order (g, p_h, p_w); used to check the
/// instability of upright and the marginal stability of hanging (spec §2.6).
pub fn linearize(params: &Params, x: &ReducedState) -> (SMatrix<f64, 9, 9>, SMatrix<f64, 9, 3>) {
    let inv = params.theta0_inv();
    let w = x.omega_h(params);
    let gx = x.g.cross_matrix();
    let phx = x.p_h.cross_matrix();
    let mut a = SMatrix::<f64, 9, 9>::zeros();
    a.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(-w.cross_matrix()));
    a.fixed_view_mut::<3, 3>(0, 3).copy_from(&(gx * inv));
    a.fixed_view_mut::<3, 3>(0, 6).copy_from(&(-gx * inv));
    a.fixed_view_mut::<3, 3>(3, 0)
        .copy_from(&params.m().cross_matrix());
    a.fixed_view_mut::<3, 3>(3, 3)
        .copy_from(&(-w.cross_matrix() + phx * inv));
    a.fixed_view_mut::<3, 3>(3, 6).copy_from(&(-phx * inv));
    let mut b = SMatrix::<f64, 9, 3>::zeros();
    b.fixed_view_mut::<3, 3>(6, 0)
        .copy_from(&nalgebra::Matrix3::identity());
    (a, b)
}

/// Open-loop tilt eigenvalue √(|m||g|/I1) at upright with p_w = 0 (Assumption 4.1, spec §2.6).
pub fn upright_instability_rate(params: &Params) -> f64 {
    let e = params.m_hat().cross(&Vector3::new(1.0, 0.0, 0.0));
    let e = if e.norm() < 1e-6 {
        params.m_hat().cross(&Vector3::new(0.0, 1.0, 0.0))
    } else {
        e
    };
    ComplexField::sqrt(params.mg() / params.tilt_inertia(&e))
}
