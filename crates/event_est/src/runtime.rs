//! The agent runtime: prediction with input reconstruction, the event trigger, the update with
//! received measurements, and the local control law.
//!
//! Everything here is `no_std` and allocation-free: the shared [`Network`] borrows column-major
//! matrices, and each [`Agent`] borrows one workspace slice of length
//! [`Agent::workspace_len`], so one step costs a handful of matrix-vector products and nothing else.
//!
//! ```
//! use event_est::runtime::{Agent, InputMode, LocalUpdate, Network, NetworkData};
//! // Scalar plant x+ = 0.9 x + u, one agent measuring x, gain L = 0.5, threshold 0.1, F = -0.5.
//! let data = NetworkData {
//!     n: 1, a: &[0.9], b: &[1.0], c: &[1.0], f: &[-0.5], l: &[0.5],
//!     delta_inv: &[10.0], outputs: &[0, 1], inputs: &[0, 1],
//! };
//! let mut a_cl = [0.0];
//! let net = Network::new(data, &mut a_cl).unwrap();
//! let mut ws = [0.0; 3];
//! let mut agent = Agent::new(&net, 0, &mut ws, InputMode::Reconstructed, LocalUpdate::OnlyOnEvent).unwrap();
//! agent.predict(None).unwrap();
//! let fired = agent.trigger(&[0.5]).unwrap(); // |0.5 - 0| >= 0.1
//! assert!(fired);
//! agent.update(&[0.5], core::iter::empty()).unwrap();
//! assert!((agent.estimate()[0] - 0.25).abs() < 1e-15);
//! ```

use crate::error::EventEstError;
use nalgebra::{DMatrixView, DVectorView, DVectorViewMut, Dyn};

/// How an agent predicts the effect of the plant input.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InputMode {
    /// From its own estimate, u = F x̂_i (no input communication; the method of the paper).
    Reconstructed,
    /// From the true previous input (legacy architecture that needs input communication).
    Communicated,
}

/// Whether an agent that did not transmit still uses its own measurement.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LocalUpdate {
    /// Own measurement only when it was transmitted (default of the paper).
    OnlyOnEvent,
    /// Own measurement at every step (continuous local update, App. C).
    Always,
}

/// Borrowed column-major description of the network, as handed to [`Network::new`].
#[derive(Debug, Clone, Copy)]
pub struct NetworkData<'a> {
    /// State dimension n.
    pub n: usize,
    /// A (n×n).
    pub a: &'a [f64],
    /// B (n×n_u).
    pub b: &'a [f64],
    /// C (p×n), rows grouped by agent.
    pub c: &'a [f64],
    /// F (n_u×n), rows grouped by agent.
    pub f: &'a [f64],
    /// L (n×p), columns grouped by agent.
    pub l: &'a [f64],
    /// Block-diagonal Δ^{-1} (p×p); only the diagonal blocks are read.
    pub delta_inv: &'a [f64],
    /// Output offsets per agent, length N+1, from 0 to p (agent i owns rows outputs[i]..outputs[i+1]).
    pub outputs: &'a [usize],
    /// Input offsets per agent, length N+1, from 0 to n_u.
    pub inputs: &'a [usize],
}

/// Shared, read-only network description every agent works with.
#[derive(Debug, Clone, Copy)]
pub struct Network<'a> {
    n: usize,
    p: usize,
    nu: usize,
    a: DMatrixView<'a, f64>,
    a_cl: DMatrixView<'a, f64>,
    b: DMatrixView<'a, f64>,
    c: DMatrixView<'a, f64>,
    f: DMatrixView<'a, f64>,
    l: DMatrixView<'a, f64>,
    delta_inv: DMatrixView<'a, f64>,
    outputs: &'a [usize],
    inputs: &'a [usize],
}

fn offsets_valid(name: &'static str, off: &[usize], total: usize) -> Result<(), EventEstError> {
    let sum = off.last().copied().unwrap_or(0);
    if off.first() != Some(&0) || off.windows(2).any(|w| w[1] < w[0]) || sum != total {
        return Err(EventEstError::BlockSizes {
            name,
            sum,
            expected: total,
        });
    }
    Ok(())
}

fn view<'a>(
    name: &'static str,
    data: &'a [f64],
    rows: usize,
    cols: usize,
) -> Result<DMatrixView<'a, f64>, EventEstError> {
    if data.len() != rows * cols {
        return Err(EventEstError::Dimension {
            name,
            expected_rows: rows,
            expected_cols: cols,
            found_rows: data.len(),
            found_cols: 1,
        });
    }
    if data.iter().any(|v| !v.is_finite()) {
        return Err(EventEstError::NonFinite { name });
    }
    Ok(DMatrixView::from_slice_generic(data, Dyn(rows), Dyn(cols)))
}

impl<'a> Network<'a> {
    /// Checks the dimensions and computes A+BF into `a_cl_storage` (n·n entries).
    ///
    /// The number of agents is `outputs.len() - 1` (must equal `inputs.len() - 1`).
    pub fn new(data: NetworkData<'a>, a_cl_storage: &'a mut [f64]) -> Result<Self, EventEstError> {
        let n = data.n;
        if data.outputs.len() < 2 || data.outputs.len() != data.inputs.len() {
            return Err(EventEstError::BlockSizes {
                name: "inputs/outputs offsets (need N+1 entries each)",
                sum: data.inputs.len(),
                expected: data.outputs.len(),
            });
        }
        let p = data.outputs.last().copied().unwrap_or(0);
        let nu = data.inputs.last().copied().unwrap_or(0);
        offsets_valid("outputs", data.outputs, p)?;
        offsets_valid("inputs", data.inputs, nu)?;
        let a = view("A", data.a, n, n)?;
        let b = view("B", data.b, n, nu)?;
        let c = view("C", data.c, p, n)?;
        let f = view("F", data.f, nu, n)?;
        let l = view("L", data.l, n, p)?;
        let delta_inv = view("Delta^-1", data.delta_inv, p, p)?;
        if a_cl_storage.len() != n * n {
            return Err(EventEstError::Dimension {
                name: "A+BF storage",
                expected_rows: n,
                expected_cols: n,
                found_rows: a_cl_storage.len(),
                found_cols: 1,
            });
        }
        {
            let mut acl =
                nalgebra::DMatrixViewMut::from_slice_generic(&mut a_cl_storage[..], Dyn(n), Dyn(n));
            acl.copy_from(&a);
            // A + B F, column by column without temporaries.
            for j in 0..n {
                for r in 0..nu {
                    let frj = f[(r, j)];
                    if frj != 0.0 {
                        for i in 0..n {
                            acl[(i, j)] += b[(i, r)] * frj;
                        }
                    }
                }
            }
        }
        let a_cl = DMatrixView::from_slice_generic(&a_cl_storage[..], Dyn(n), Dyn(n));
        Ok(Self {
            n,
            p,
            nu,
            a,
            a_cl,
            b,
            c,
            f,
            l,
            delta_inv,
            outputs: data.outputs,
            inputs: data.inputs,
        })
    }

    /// Number of agents N.
    pub fn agents(&self) -> usize {
        self.outputs.len() - 1
    }

    /// State dimension n.
    pub fn states(&self) -> usize {
        self.n
    }

    /// Total number of outputs p.
    pub fn outputs(&self) -> usize {
        self.p
    }

    /// Total number of inputs n_u.
    pub fn inputs(&self) -> usize {
        self.nu
    }

    /// Output rows of agent i.
    pub fn output_range(&self, i: usize) -> core::ops::Range<usize> {
        self.outputs[i]..self.outputs[i + 1]
    }

    /// Input rows of agent i.
    pub fn input_range(&self, i: usize) -> core::ops::Range<usize> {
        self.inputs[i]..self.inputs[i + 1]
    }

    fn check_agent(&self, i: usize) -> Result<(), EventEstError> {
        if i >= self.agents() {
            return Err(EventEstError::AgentIndex {
                index: i,
                agents: self.agents(),
            });
        }
        Ok(())
    }
}

fn check_len(name: &'static str, v: &[f64], len: usize) -> Result<(), EventEstError> {
    if v.len() != len {
        return Err(EventEstError::Dimension {
            name,
            expected_rows: len,
            expected_cols: 1,
            found_rows: v.len(),
            found_cols: 1,
        });
    }
    Ok(())
}

/// The event trigger (5.4): fires iff |Δ_i^{-1} r| ≥ 1, with `delta_inv` the p_i×p_i block.
/// Compares the squared norm with 1 (no square root). Agents without outputs never fire.
pub fn trigger_fires(delta_inv: DMatrixView<'_, f64>, r: &[f64]) -> bool {
    let mut norm2 = 0.0;
    for row in 0..r.len() {
        let mut q = 0.0;
        for (col, rc) in r.iter().enumerate() {
            q += delta_inv[(row, col)] * rc;
        }
        norm2 += q * q;
    }
    !r.is_empty() && norm2 >= 1.0
}

/// One agent's estimator, trigger and controller, on a borrowed workspace.
#[derive(Debug)]
pub struct Agent<'a> {
    id: usize,
    net: &'a Network<'a>,
    xhat: &'a mut [f64],
    xpred: &'a mut [f64],
    resid: &'a mut [f64],
    mode: InputMode,
    local: LocalUpdate,
    fired: bool,
}

impl<'a> Agent<'a> {
    /// Workspace length agent `id` needs: 2n + p_i.
    pub fn workspace_len(net: &Network<'_>, id: usize) -> usize {
        let p_i = if id < net.agents() {
            net.output_range(id).len()
        } else {
            0
        };
        2 * net.n + p_i
    }

    /// Agent `id` with estimate 0, borrowing `workspace` (length [`Agent::workspace_len`]).
    pub fn new(
        net: &'a Network<'a>,
        id: usize,
        workspace: &'a mut [f64],
        mode: InputMode,
        local: LocalUpdate,
    ) -> Result<Self, EventEstError> {
        net.check_agent(id)?;
        check_len("agent workspace", workspace, Self::workspace_len(net, id))?;
        workspace.fill(0.0);
        let (xhat, rest) = workspace.split_at_mut(net.n);
        let (xpred, resid) = rest.split_at_mut(net.n);
        Ok(Self {
            id,
            net,
            xhat,
            xpred,
            resid,
            mode,
            local,
            fired: false,
        })
    }

    /// This agent's index.
    pub fn id(&self) -> usize {
        self.id
    }

    /// Current estimate x̂_i(k).
    pub fn estimate(&self) -> &[f64] {
        self.xhat
    }

    /// Current prediction x̂_i(k|k−1).
    pub fn prediction(&self) -> &[f64] {
        self.xpred
    }

    /// Whether the last call to [`Agent::trigger`] fired.
    pub fn fired(&self) -> bool {
        self.fired
    }

    /// Sets the estimate (initialisation or an estimator reset).
    pub fn reset(&mut self, x: &[f64]) -> Result<(), EventEstError> {
        check_len("reset estimate", x, self.net.n)?;
        self.xhat.copy_from_slice(x);
        Ok(())
    }

    /// Prediction x̂_i(k|k−1): (A+BF) x̂_i, or A x̂_i + B u(k−1) in the communicated-input mode.
    pub fn predict(&mut self, u_prev: Option<&[f64]>) -> Result<(), EventEstError> {
        let n = self.net.n;
        let xhat = DVectorView::from_slice_generic(&self.xhat[..], Dyn(n), nalgebra::U1);
        let mut xpred =
            DVectorViewMut::from_slice_generic(&mut self.xpred[..], Dyn(n), nalgebra::U1);
        match self.mode {
            InputMode::Reconstructed => xpred.gemv(1.0, &self.net.a_cl, &xhat, 0.0),
            InputMode::Communicated => {
                let u = u_prev.ok_or(EventEstError::MissingInput)?;
                check_len("u(k-1)", u, self.net.nu)?;
                let u = DVectorView::from_slice_generic(u, Dyn(self.net.nu), nalgebra::U1);
                xpred.gemv(1.0, &self.net.a, &xhat, 0.0);
                xpred.gemv(1.0, &self.net.b, &u, 1.0);
            }
        }
        Ok(())
    }

    /// Innovation of output block `j` against this agent's prediction, into `out`.
    fn innovation(&self, j: usize, y_j: &[f64], out: &mut [f64]) {
        let rows = self.net.output_range(j);
        for (k, r) in rows.enumerate() {
            let mut cx = 0.0;
            for col in 0..self.net.n {
                cx += self.net.c[(r, col)] * self.xpred[col];
            }
            out[k] = y_j[k] - cx;
        }
    }

    /// Event trigger on the own measurement y_i(k); returns whether the agent transmits.
    pub fn trigger(&mut self, y_own: &[f64]) -> Result<bool, EventEstError> {
        let rows = self.net.output_range(self.id);
        check_len("own measurement y_i", y_own, rows.len())?;
        let mut r = core::mem::take(&mut self.resid);
        self.innovation(self.id, y_own, r);
        let d = self
            .net
            .delta_inv
            .view((rows.start, rows.start), (rows.len(), rows.len()));
        self.fired = trigger_fires(d, r);
        self.resid = core::mem::take(&mut r);
        Ok(self.fired)
    }

    /// Adds L_j (y_j − C_j x̂_i(k|k−1)) to the estimate.
    fn add_correction(&mut self, j: usize, y_j: &[f64]) {
        let rows = self.net.output_range(j);
        for r in rows.clone() {
            let mut cx = 0.0;
            for col in 0..self.net.n {
                cx += self.net.c[(r, col)] * self.xpred[col];
            }
            let innov = y_j[r - rows.start] - cx;
            for i in 0..self.net.n {
                self.xhat[i] += self.net.l[(i, r)] * innov;
            }
        }
    }

    /// Measurement update: x̂_i = x̂_i(k|k−1) + Σ_{received j} L_j (y_j − C_j x̂_i(k|k−1)),
    /// plus the own term if this agent fired (or always with [`LocalUpdate::Always`]).
    /// `received` holds the other agents' delivered measurements (sender, y_j).
    pub fn update<'m, I>(&mut self, y_own: &[f64], received: I) -> Result<(), EventEstError>
    where
        I: IntoIterator<Item = (usize, &'m [f64])>,
    {
        check_len(
            "own measurement y_i",
            y_own,
            self.net.output_range(self.id).len(),
        )?;
        self.xhat.copy_from_slice(self.xpred);
        for (j, y_j) in received {
            self.net.check_agent(j)?;
            check_len(
                "received measurement y_j",
                y_j,
                self.net.output_range(j).len(),
            )?;
            if j != self.id {
                self.add_correction(j, y_j);
            }
        }
        if self.fired || self.local == LocalUpdate::Always {
            self.add_correction(self.id, y_own);
        }
        Ok(())
    }

    /// Local control u_i(k) = F_i x̂_i(k), written into `u_i` (length q_i).
    pub fn control(&self, u_i: &mut [f64]) -> Result<(), EventEstError> {
        let rows = self.net.input_range(self.id);
        check_len("u_i", u_i, rows.len())?;
        for (k, r) in rows.enumerate() {
            let mut s = 0.0;
            for col in 0..self.net.n {
                s += self.net.f[(r, col)] * self.xhat[col];
            }
            u_i[k] = s;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn scalar_net<'a>(delta_inv: &'a [f64], a_cl: &'a mut [f64]) -> Network<'a> {
        let data = NetworkData {
            n: 1,
            a: &[0.9],
            b: &[1.0],
            c: &[1.0],
            f: &[-0.5],
            l: &[0.5],
            delta_inv,
            outputs: &[0, 1],
            inputs: &[0, 1],
        };
        Network::new(data, a_cl).unwrap()
    }

    #[test]
    fn trigger_fires_at_equality() {
        let d = [0.5];
        let view = DMatrixView::from_slice_generic(&d[..], Dyn(1), Dyn(1));
        assert!(trigger_fires(view, &[2.0])); // |0.5 · 2| = 1
        assert!(!trigger_fires(view, &[1.999_999]));
        assert!(trigger_fires(view, &[-2.0]));
    }

    #[test]
    fn agents_without_outputs_never_fire() {
        let d: [f64; 0] = [];
        let view = DMatrixView::from_slice_generic(&d[..], Dyn(0), Dyn(0));
        assert!(!trigger_fires(view, &[]));
    }

    #[test]
    fn dimension_errors_name_the_input() {
        let mut a_cl = [0.0];
        let data = NetworkData {
            n: 1,
            a: &[0.9, 0.0],
            b: &[1.0],
            c: &[1.0],
            f: &[-0.5],
            l: &[0.5],
            delta_inv: &[1.0],
            outputs: &[0, 1],
            inputs: &[0, 1],
        };
        let err = Network::new(data, &mut a_cl).unwrap_err();
        assert!(
            matches!(err, EventEstError::Dimension { name: "A", .. }),
            "{err}"
        );
        let mut a_cl = [0.0];
        let net = scalar_net(&[1.0], &mut a_cl);
        let mut ws = [0.0; 3];
        let mut agent = Agent::new(
            &net,
            0,
            &mut ws,
            InputMode::Communicated,
            LocalUpdate::OnlyOnEvent,
        )
        .unwrap();
        assert_eq!(agent.predict(None), Err(EventEstError::MissingInput));
        assert!(matches!(
            agent.trigger(&[1.0, 2.0]),
            Err(EventEstError::Dimension { .. })
        ));
        let mut ws = [0.0; 3];
        assert!(matches!(
            Agent::new(
                &net,
                3,
                &mut ws,
                InputMode::Reconstructed,
                LocalUpdate::OnlyOnEvent
            ),
            Err(EventEstError::AgentIndex {
                index: 3,
                agents: 1
            })
        ));
    }

    proptest! {
        /// Matrix thresholds fire on the Euclidean norm of Δ^{-1} r.
        #[test]
        fn matrix_trigger_is_the_euclidean_norm(
            m in proptest::collection::vec(-2.0f64..2.0, 4),
            r in proptest::collection::vec(-2.0f64..2.0, 2),
        ) {
            let q = [m[0] * r[0] + m[2] * r[1], m[1] * r[0] + m[3] * r[1]];
            let norm = (q[0] * q[0] + q[1] * q[1]).sqrt();
            prop_assume!((norm - 1.0).abs() > 1e-9);
            let view = DMatrixView::from_slice_generic(&m[..], Dyn(2), Dyn(2));
            prop_assert_eq!(trigger_fires(view, &r), norm >= 1.0);
        }

        /// For scalar thresholds the trigger is |r| ≥ Δ.
        #[test]
        fn scalar_trigger_is_abs_above_threshold(delta in 1e-3f64..10.0, r in -20.0f64..20.0) {
            prop_assume!((r.abs() - delta).abs() > 1e-9 * delta);
            let d = [1.0 / delta];
            let view = DMatrixView::from_slice_generic(&d[..], Dyn(1), Dyn(1));
            prop_assert_eq!(trigger_fires(view, &[r]), r.abs() >= delta);
        }

        /// One agent step equals the estimator equations written out for a scalar plant.
        #[test]
        fn scalar_step_matches_the_equations(x0 in -5.0f64..5.0, y in -5.0f64..5.0, delta in 0.01f64..3.0) {
            let d = [1.0 / delta];
            let mut a_cl = [0.0];
            let net = scalar_net(&d, &mut a_cl);
            let mut ws = [0.0; 3];
            let mut agent = Agent::new(&net, 0, &mut ws, InputMode::Reconstructed, LocalUpdate::OnlyOnEvent).unwrap();
            agent.reset(&[x0]).unwrap();
            agent.predict(None).unwrap();
            let pred = (0.9 - 0.5) * x0;
            prop_assert!((agent.prediction()[0] - pred).abs() < 1e-12);
            let fired = agent.trigger(&[y]).unwrap();
            prop_assert_eq!(fired, (y - pred).abs() >= delta);
            agent.update(&[y], core::iter::empty()).unwrap();
            let want = if fired { pred + 0.5 * (y - pred) } else { pred };
            prop_assert!((agent.estimate()[0] - want).abs() < 1e-12);
            let mut u = [0.0];
            agent.control(&mut u).unwrap();
            prop_assert!((u[0] + 0.5 * want).abs() < 1e-12);
        }
    }
}
