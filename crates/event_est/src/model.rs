//! Networked systems with agent blocks: validation and the examples of the paper
//! (vehicle platoon, two-agent counterexample).

use crate::error::EventEstError;
use crate::linalg::{lti_err, spectral_radius};
use nalgebra::DMatrix;
use rigid_body::lti;

/// Plant x+ = A x + B u + v, y = C x + w with N agents, static feedback u_i = F_i x̂_i, and the
/// noise covariances used for design.
#[derive(Debug, Clone)]
pub struct System {
    /// A (n×n).
    pub a: DMatrix<f64>,
    /// B (n×n_u), columns grouped by agent.
    pub b: DMatrix<f64>,
    /// C (p×n), rows grouped by agent.
    pub c: DMatrix<f64>,
    /// F (n_u×n) with A+BF Schur stable.
    pub f: DMatrix<f64>,
    /// Outputs per agent p_i (Σ = p).
    pub outputs: Vec<usize>,
    /// Inputs per agent q_i (Σ = n_u).
    pub inputs: Vec<usize>,
    /// Measurement noise covariance W (p×p, block diagonal by agent).
    pub w: DMatrix<f64>,
    /// Process noise factor V^{1/2} (n×n_v), V = V^{1/2} V^{1/2}ᵀ.
    pub v_sqrt: DMatrix<f64>,
}

fn shape(
    name: &'static str,
    m: &DMatrix<f64>,
    rows: usize,
    cols: usize,
) -> Result<(), EventEstError> {
    if m.nrows() != rows || m.ncols() != cols {
        return Err(EventEstError::Dimension {
            name,
            expected_rows: rows,
            expected_cols: cols,
            found_rows: m.nrows(),
            found_cols: m.ncols(),
        });
    }
    if m.iter().any(|v| !v.is_finite()) {
        return Err(EventEstError::NonFinite { name });
    }
    Ok(())
}

/// Offsets 0, b_0, b_0+b_1, ... of a block partition.
pub fn offsets(blocks: &[usize]) -> Vec<usize> {
    let mut off = Vec::with_capacity(blocks.len() + 1);
    off.push(0);
    for b in blocks {
        off.push(off.last().copied().unwrap_or(0) + b);
    }
    off
}

impl System {
    /// Validates shapes, block partitions, W ≻ 0 and ρ(A+BF) < 1.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        a: DMatrix<f64>,
        b: DMatrix<f64>,
        c: DMatrix<f64>,
        f: DMatrix<f64>,
        outputs: Vec<usize>,
        inputs: Vec<usize>,
        w: DMatrix<f64>,
        v_sqrt: DMatrix<f64>,
    ) -> Result<Self, EventEstError> {
        let n = a.nrows();
        shape("A", &a, n, n)?;
        if n == 0 {
            return Err(EventEstError::Dimension {
                name: "A",
                expected_rows: 1,
                expected_cols: 1,
                found_rows: 0,
                found_cols: 0,
            });
        }
        shape("B", &b, n, b.ncols())?;
        shape("C", &c, c.nrows(), n)?;
        let (nu, p) = (b.ncols(), c.nrows());
        shape("F", &f, nu, n)?;
        shape("W", &w, p, p)?;
        shape("V^1/2", &v_sqrt, n, v_sqrt.ncols())?;
        if outputs.len() != inputs.len() || outputs.is_empty() {
            return Err(EventEstError::BlockSizes {
                name: "number of agents in outputs and inputs",
                sum: inputs.len(),
                expected: outputs.len(),
            });
        }
        if outputs.iter().sum::<usize>() != p {
            return Err(EventEstError::BlockSizes {
                name: "outputs (rows of C)",
                sum: outputs.iter().sum(),
                expected: p,
            });
        }
        if inputs.iter().sum::<usize>() != nu {
            return Err(EventEstError::BlockSizes {
                name: "inputs (columns of B)",
                sum: inputs.iter().sum(),
                expected: nu,
            });
        }
        if (&w - w.transpose()).norm() > 1e-12 * w.norm().max(1.0) || w.clone().cholesky().is_none()
        {
            return Err(EventEstError::NotPositiveDefinite { name: "W" });
        }
        let sys = Self {
            a,
            b,
            c,
            f,
            outputs,
            inputs,
            w,
            v_sqrt,
        };
        let rho = spectral_radius(&sys.a_cl());
        if rho >= 1.0 {
            return Err(EventEstError::UnstableFeedback { rho });
        }
        Ok(sys)
    }

    /// A+BF.
    pub fn a_cl(&self) -> DMatrix<f64> {
        &self.a + &self.b * &self.f
    }

    /// State dimension n.
    pub fn n(&self) -> usize {
        self.a.nrows()
    }

    /// Total outputs p.
    pub fn p(&self) -> usize {
        self.c.nrows()
    }

    /// Number of agents N.
    pub fn agents(&self) -> usize {
        self.outputs.len()
    }

    /// Number of agents that measure something (N_s).
    pub fn measuring_agents(&self) -> usize {
        self.outputs.iter().filter(|&&p| p > 0).count()
    }

    /// Output offsets (length N+1).
    pub fn output_offsets(&self) -> Vec<usize> {
        offsets(&self.outputs)
    }

    /// Input offsets (length N+1).
    pub fn input_offsets(&self) -> Vec<usize> {
        offsets(&self.inputs)
    }

    /// Process noise covariance V = V^{1/2} V^{1/2}ᵀ.
    pub fn v(&self) -> DMatrix<f64> {
        &self.v_sqrt * self.v_sqrt.transpose()
    }

    /// W^{1/2} (lower Cholesky factor of W).
    pub fn w_sqrt(&self) -> Result<DMatrix<f64>, EventEstError> {
        crate::linalg::cholesky_lower(&self.w, "W")
    }

    /// Sum of L_m C_m over the agents in `subset` (bit m set ⇔ agent m in the set).
    pub fn lc_subset(&self, l: &DMatrix<f64>, subset: u64) -> DMatrix<f64> {
        let off = self.output_offsets();
        let n = self.n();
        let mut s = DMatrix::zeros(n, n);
        for (m, (&o, &pm)) in off.iter().zip(&self.outputs).enumerate() {
            if m < 64 && subset >> m & 1 == 1 {
                s += l.columns(o, pm) * self.c.rows(o, pm);
            }
        }
        s
    }
}

/// Uniform noise half-widths used by the simulator (variance a²/3 per component).
#[derive(Debug, Clone, PartialEq)]
pub struct UniformNoise {
    /// Half-width per output (length p).
    pub output: Vec<f64>,
    /// Half-width of the actuator noise per input (length n_u).
    pub input: Vec<f64>,
}

/// Vehicle platoon of `m` unit masses (Section 10.1): state (p_1, d_1, ..., p_{m−1}, d_{m−1}, p_m),
/// vehicle 1 measures its velocity, vehicle i ≥ 2 the distance to the vehicle ahead,
/// Ts = 20 ms, discrete LQR with Q = I, R = 100 I, W_i = 0.1²/3, V = (0.01²/3) B Bᵀ.
pub fn platoon(m: usize) -> Result<(System, UniformNoise), EventEstError> {
    if m < 2 {
        return Err(EventEstError::Parameter {
            name: "vehicles",
            value: m as f64,
            reason: "a platoon needs at least 2 vehicles",
        });
    }
    let ts = 0.02;
    let n = 2 * m - 1;
    let vel = |i: usize| 2 * i; // p_{i+1}, 0-based vehicle i
    let dist = |i: usize| 2 * i + 1; // d_{i+1}
    let mut ac = DMatrix::zeros(n, n);
    let mut bc = DMatrix::zeros(n, m);
    for i in 0..m {
        bc[(vel(i), i)] = 1.0;
        if i + 1 < m {
            ac[(dist(i), vel(i))] = 1.0;
            ac[(dist(i), vel(i + 1))] = -1.0;
        }
    }
    // A_c² = 0, so the zero-order hold is exact with two terms.
    let a = DMatrix::identity(n, n) + &ac * ts;
    let b = &bc * ts + &ac * &bc * (ts * ts / 2.0);
    let mut c = DMatrix::zeros(m, n);
    c[(0, vel(0))] = 1.0;
    for i in 1..m {
        c[(i, dist(i - 1))] = 1.0;
    }
    let lqr = lti::dlqr(
        &a,
        &b,
        &DMatrix::identity(n, n),
        &(DMatrix::identity(m, m) * 100.0),
    )
    .map_err(lti_err("platoon LQR"))?;
    let f = -lqr.k;
    let w = DMatrix::identity(m, m) * (0.1f64 * 0.1 / 3.0);
    let v_sqrt = &b * (0.01 / 3f64.sqrt());
    let sys = System::new(a, b, c, f, vec![1; m], vec![1; m], w, v_sqrt)?;
    Ok((
        sys,
        UniformNoise {
            output: vec![0.1; m],
            input: vec![0.01; m],
        },
    ))
}

/// The two-agent counterexample of App. F: A = diag(0.5, 2), B = [[0,1],[1,0]], C = I,
/// F = [[0,−2],[0.1,0]]; its gains are L = I (returned alongside).
pub fn counterexample() -> Result<(System, DMatrix<f64>), EventEstError> {
    let a = DMatrix::from_row_slice(2, 2, &[0.5, 0.0, 0.0, 2.0]);
    let b = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, 1.0, 0.0]);
    let c = DMatrix::identity(2, 2);
    let f = DMatrix::from_row_slice(2, 2, &[0.0, -2.0, 0.1, 0.0]);
    let sys = System::new(
        a,
        b,
        c,
        f,
        vec![1, 1],
        vec![1, 1],
        DMatrix::identity(2, 2),
        DMatrix::identity(2, 2),
    )?;
    Ok((sys, DMatrix::identity(2, 2)))
}
