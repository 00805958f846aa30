//! Centralised periodic Kalman filter at a reduced rate 1/m (the comparison design of the
//! paper): re-sample the model at period m, design the steady-state filter, and average the
//! error power over all fast steps.

use crate::error::EventEstError;
use crate::linalg::kalman;
use crate::model::System;
use nalgebra::DMatrix;

/// Error power sqrt((1/m) Σ_{j<m} tr Σ_j) of the centralised filter that receives all
/// measurements every `m` steps: Σ_0 = Σ⁺ of the filter for (A^m, C, V_m, W), Σ_{j+1} = A Σ_j Aᵀ + V.
pub fn periodic_power(sys: &System, m: usize) -> Result<f64, EventEstError> {
    if m == 0 {
        return Err(EventEstError::Parameter {
            name: "period m",
            value: 0.0,
            reason: "the period must be at least one step",
        });
    }
    let n = sys.n();
    let v = sys.v();
    let mut a_m = DMatrix::identity(n, n);
    let mut v_m = DMatrix::zeros(n, n);
    for _ in 0..m {
        v_m = &sys.a * &v_m * sys.a.transpose() + &v;
        a_m = &sys.a * a_m;
    }
    let kf = kalman(&a_m, &sys.c, &v_m, &sys.w)?;
    let mut sigma = kf.posterior;
    let mut total = 0.0;
    for _ in 0..m {
        total += sigma.trace();
        sigma = &sys.a * &sigma * sys.a.transpose() + &v;
    }
    Ok((total / m as f64).sqrt())
}
