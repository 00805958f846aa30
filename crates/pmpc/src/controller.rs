//! The online controller: solve the semi-infinite QP at every sample, warm-started from the
//! previous working set with its instants predicted for the new sample, with the shifted
//! previous plan as fallback (which keeps recursive feasibility and the Lyapunov decrease when
//! the solver stops early).

use crate::constraints::Constraints;
use crate::error::{Error, Result};
use crate::problem::Problem;
use nalgebra::DMatrix;
use rigid_body::laguerre::Laguerre;
use rigid_body::siqp::{self, Active, Settings, Stats, Status, WorkspaceStorage};

/// Where the applied plan came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Source {
    /// The solver converged.
    Optimal,
    /// The solver stopped with this status; the previous plan, shifted by T_d, is applied.
    Fallback(Status),
}

/// Work one step may do, known before running (from the budget and the settings).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WorkBound {
    /// Outer iterations: one Taylor-bound check of every constrained row, then one dual step
    /// per violated row.
    pub iterations: usize,
    /// Taylor steps over all checks: iterations × constrained rows × `max_check_steps`.
    pub taylor_steps: usize,
    /// Instants added: at most one per violated row and iteration (iterations × rows).
    pub adds: usize,
    /// Instants dropped. Each re-factorisation of the working set (one at the start, then
    /// at most 1 + `polish_steps` per addition) and each dual step drops at most the working
    /// set's capacity c: c · (1 + adds · (2 + `polish_steps`)).
    pub drops: usize,
    /// Accepted Newton moves of the working set (at most one per dual step).
    pub moves: usize,
}

/// Diagnostics of the last step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepInfo {
    /// Origin of the applied plan.
    pub source: Source,
    /// Solver counters.
    pub stats: Stats,
    /// Open-loop cost ½zᵀHz of the applied plan (the MPC Lyapunov function).
    pub cost: f64,
    /// Size of the final working set.
    pub active: usize,
}

/// The warm start of the next step from this step's final working set `last`, the final set
/// `before` of the step before, and the set `seeded` this step started from, into `out`. An
/// instant the solver placed this step (added or moved: not in `seeded` at the same instant)
/// with a partner in `before` (same row and side, both after 0, the nearest, within `reach`
/// seconds) continues its drift, t + (t − t_before); any other one is shifted by the sampling
/// time, t − h; both are clamped at 0. The parametrized plan is not shift invariant: on the
/// quadruple integrator the touch points of |u| ≤ 0.5 near 0.2 s and 1.1 s drift by −0.0014
/// and −0.007 s per 0.02 s step and those of x_1 ≥ 0 near 6 s and 13 s by −0.027 and
/// −0.08 s, nearly constant over many steps, and a shifted instant off the new extremum
/// costs exchange iterations. An instant that was only seeded and not moved satisfied the
/// check where it was, so it is shifted as the clock says (extrapolating a drift it did not
/// make would walk it away). An instant that falls before 0 moves to 0 rather than being
/// dropped: a row held at the start of the plan (a saturated input) is held at the start of
/// the next one, and without it the rest of the set is not dual feasible, so the seed would
/// drop it all and the step start cold. The prediction only seeds the solve, which still
/// ends on a check of every row.
fn predict_instants(
    last: &[Active],
    before: &[Active],
    seeded: &[Active],
    h: f64,
    reach: f64,
    out: &mut Vec<Active>,
) {
    out.clear();
    for a in last {
        let same = |b: &&Active| b.row == a.row && b.side == a.side;
        let placed = !seeded.iter().filter(same).any(|b| b.t == a.t);
        let partner = before
            .iter()
            .filter(same)
            .filter(|b| b.t > 0.0)
            .map(|b| b.t)
            .min_by(|x, y| (x - a.t).abs().total_cmp(&(y - a.t).abs()));
        let t = match partner {
            Some(tb) if placed && a.t > 0.0 && (a.t - tb).abs() < reach => a.t + (a.t - tb),
            _ => a.t - h,
        };
        out.push(Active {
            t: if t.is_finite() { t.max(0.0) } else { 0.0 },
            ..*a
        });
    }
}

/// Parametrized infinite-horizon MPC (spec/pmpc.md §5).
///
/// ```
/// use nalgebra::DMatrix;
/// use pmpc::{Constraints, Pmpc};
/// use rigid_body::laguerre::Laguerre;
/// // Double integrator, |u| <= 1.
/// let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, 0.0, 0.0]);
/// let b = DMatrix::from_row_slice(2, 1, &[0.0, 1.0]);
/// let c = Constraints::boxes(&[(f64::NEG_INFINITY, f64::INFINITY); 2], &[(-1.0, 1.0)]);
/// let basis = Laguerre::new(8, 1.0).unwrap();
/// let mut mpc = Pmpc::new(&a, &b, &DMatrix::identity(2, 2), &DMatrix::identity(1, 1), &c, basis, 0.05).unwrap();
/// let u = mpc.step(&[1.0, 0.0]).unwrap();
/// assert!(u[0].abs() <= 1.0 + 1e-6);
/// ```
#[derive(Debug, Clone)]
pub struct Pmpc {
    problem: Problem,
    td: f64,
    settings: Settings,
    warm_start: bool,
    budget: Option<usize>,
    storage: WorkspaceStorage,
    warm: Vec<Active>,
    before: Vec<Active>,
    seeded: Vec<Active>,
    next: Vec<Active>,
    has_plan: bool,
    z: Vec<f64>,
    z_shifted: Vec<f64>,
    w0: Vec<f64>,
    mu: Vec<f64>,
    /// Scratch of length n + dof for the plan's coefficients.
    scratch: Vec<f64>,
    tau: Vec<f64>,
    u: Vec<f64>,
    info: StepInfo,
}

impl Pmpc {
    /// Offline set-up for `ẋ = Ax + Bu`, cost ½∫(xᵀQx + uᵀRu)dt, stage constraints for all
    /// t ≥ 0, Laguerre basis (s functions, decay ν) and sampling time `td`.
    pub fn new(
        a: &DMatrix<f64>,
        b: &DMatrix<f64>,
        q: &DMatrix<f64>,
        r: &DMatrix<f64>,
        constraints: &Constraints,
        basis: Laguerre,
        td: f64,
    ) -> Result<Self> {
        if !td.is_finite() || td <= 0.0 {
            return Err(Error::InvalidParameter {
                name: "Td",
                value: td,
                requirement: "the sampling time must be finite and > 0",
            });
        }
        let problem = Problem::new(a, b, q, r, constraints, basis)?;
        let storage = WorkspaceStorage::new(&problem.siqp()?);
        let nvar = problem.num_variables();
        let l = problem.rows().len() * basis.dim();
        let cap = problem.dof().max(1);
        Ok(Self {
            td,
            settings: Settings::default(),
            warm_start: true,
            budget: None,
            storage,
            warm: Vec::with_capacity(cap),
            before: Vec::with_capacity(cap),
            seeded: Vec::with_capacity(cap),
            next: Vec::with_capacity(cap),
            has_plan: false,
            z: vec![0.0; nvar],
            z_shifted: vec![0.0; nvar],
            w0: vec![0.0; l],
            mu: vec![0.0; l],
            scratch: vec![0.0; problem.n() + problem.dof()],
            tau: vec![0.0; basis.dim()],
            u: vec![0.0; problem.m()],
            info: StepInfo {
                source: Source::Optimal,
                stats: Stats::default(),
                cost: 0.0,
                active: 0,
            },
            problem,
        })
    }

    /// Replace the solver settings (tolerance ε, iteration budget, ...).
    pub fn with_settings(mut self, settings: Settings) -> Self {
        self.settings = settings;
        self
    }

    /// Per-step budget of outer iterations once a plan exists: a step that needs more applies
    /// the shifted previous plan (feasible, with the Lyapunov decrease) and carries its working
    /// set to the next step. The first step (no plan yet) uses `settings.max_iter`.
    pub fn with_budget(mut self, budget: usize) -> Self {
        self.budget = Some(budget);
        self
    }

    /// The per-step iteration budget, if any.
    pub fn budget(&self) -> Option<usize> {
        self.budget
    }

    /// Worst-case work of a step after the first, if a budget is set: a step that would
    /// exceed it stops there and applies the shifted previous plan instead.
    pub fn work_bound(&self) -> Option<WorkBound> {
        let iterations = self.budget?.min(self.settings.max_iter);
        let rows = self
            .problem
            .rows()
            .iter()
            .filter(|r| r.lower.is_finite() || r.upper.is_finite())
            .count();
        let adds = iterations * rows;
        let capacity = self.problem.dof().max(1);
        Some(WorkBound {
            iterations,
            taylor_steps: iterations * rows * self.settings.max_check_steps,
            adds,
            drops: capacity * (1 + adds * (2 + self.settings.polish_steps)),
            moves: adds,
        })
    }

    /// Enable or disable warm starting from the previous working set (see `predict_instants`).
    pub fn with_warm_start(mut self, warm: bool) -> Self {
        self.warm_start = warm;
        self
    }

    /// Solver settings.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// The offline problem data.
    pub fn problem(&self) -> &Problem {
        &self.problem
    }

    /// Sampling time T_d.
    pub fn sampling_time(&self) -> f64 {
        self.td
    }

    /// Forget the previous plan and working set.
    pub fn reset(&mut self) {
        self.has_plan = false;
        self.warm.clear();
        self.before.clear();
        self.seeded.clear();
        self.next.clear();
    }

    /// Solve for the measured state `x` and return the input ũ(0) to apply now. The whole
    /// input trajectory of the plan is available through [`Pmpc::input_at`]. Allocation-free.
    pub fn step(&mut self, x: &[f64]) -> Result<&[f64]> {
        crate::check_vector("x", x, self.problem.n())?;
        self.problem.unconstrained_coefficients(x, &mut self.w0);
        let sp = self.problem.siqp()?;
        let mut ws = self.storage.workspace(&sp)?;
        let warm = self.warm_start && self.has_plan;
        if warm {
            let reach = 0.25 / sp.basis().nu();
            predict_instants(
                &self.warm,
                &self.before,
                &self.seeded,
                self.td,
                reach,
                &mut self.next,
            );
            ws.set_active(&self.next);
        } else {
            self.next.clear();
        }
        let mut settings = self.settings;
        if let (Some(b), true) = (self.budget, self.has_plan) {
            settings.max_iter = settings.max_iter.min(b);
        }
        let out = siqp::solve(&sp, &settings, &self.w0, warm, &mut ws)?;
        let stats = out.stats;
        let status = out.status;
        // The working set reached seeds the next step (its instants predicted from this set and
        // the one before), also when this step stopped early: its work is not lost.
        std::mem::swap(&mut self.warm, &mut self.before);
        self.warm.clear();
        self.warm.extend_from_slice(out.active);
        std::mem::swap(&mut self.seeded, &mut self.next);
        let source = if status == Status::Optimal {
            out.multiplier_coefficients(&sp, &mut self.tau, &mut self.mu);
            let active = out.active.len();
            self.problem
                .coefficients(x, &self.mu, &mut self.scratch, &mut self.z);
            self.info.active = active;
            Source::Optimal
        } else if self.has_plan {
            // The shifted previous plan is applied (feasible, with the Lyapunov decrease); it
            // is shifted here, when it is needed, not after every step.
            self.problem.shift(&self.z, self.td, &mut self.z_shifted);
            std::mem::swap(&mut self.z, &mut self.z_shifted);
            Source::Fallback(status)
        } else if status == Status::Infeasible {
            return Err(Error::Infeasible { x: x.to_vec() });
        } else {
            return Err(Error::NotConverged(match status {
                Status::IterationLimit => "iteration limit",
                _ => "constraint-check step limit",
            }));
        };
        self.has_plan = true;
        self.problem
            .input_at(&self.z, 0.0, &mut self.tau, &mut self.u);
        self.info = StepInfo {
            source,
            stats,
            cost: self.problem.cost(&self.z),
            active: self.info.active,
        };
        Ok(&self.u)
    }

    /// Diagnostics of the last step.
    pub fn last_step(&self) -> StepInfo {
        self.info
    }

    /// Coefficients z = (η_x, η_u) of the current plan.
    pub fn plan(&self) -> &[f64] {
        &self.z
    }

    /// Planned input ũ(t), t ≥ 0 seconds after the last step, into `out` (length m).
    pub fn input_at(&self, t: f64, out: &mut [f64]) -> Result<()> {
        self.check_time(t, out.len(), self.problem.m())?;
        let mut tau = vec![0.0; self.problem.basis().dim()];
        self.problem.input_at(&self.z, t, &mut tau, out);
        Ok(())
    }

    /// Predicted state x̃(t), t ≥ 0 seconds after the last step, into `out` (length n).
    pub fn state_at(&self, t: f64, out: &mut [f64]) -> Result<()> {
        self.check_time(t, out.len(), self.problem.n())?;
        let mut tau = vec![0.0; self.problem.basis().dim()];
        self.problem.state_at(&self.z, t, &mut tau, out);
        Ok(())
    }

    /// The plan starts at the last step: earlier times are not part of it.
    fn check_time(&self, t: f64, len: usize, expected: usize) -> Result<()> {
        if !t.is_finite() || t < 0.0 {
            return Err(Error::InvalidParameter {
                name: "t",
                value: t,
                requirement: "the time since the last step must be finite and >= 0",
            });
        }
        if len != expected {
            return Err(Error::Shape {
                name: "out",
                rows: len,
                cols: 1,
                expected_rows: expected,
                expected_cols: 1,
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::predict_instants;
    use proptest::prelude::*;
    use rigid_body::siqp::{Active, Side};

    fn instant(t: f64, row: usize, upper: bool) -> Active {
        Active {
            t,
            row,
            side: if upper { Side::Upper } else { Side::Lower },
        }
    }

    fn set() -> impl Strategy<Value = Vec<Active>> {
        proptest::collection::vec(
            (
                prop_oneof![Just(0.0), 0.0f64..40.0],
                0usize..3,
                any::<bool>(),
            )
                .prop_map(|(t, r, u)| instant(t, r, u)),
            0..8,
        )
    }

    proptest! {
        /// Every predicted instant keeps its row and side, lies at t >= 0, and is either the
        /// clamped shift or the clamped drift continuation of a partner within reach.
        #[test]
        fn prediction_is_a_shift_or_a_drift_within_reach(
            last in set(), before in set(), seeded in set(), h in 1e-3f64..0.1, reach in 0.0f64..1.0,
        ) {
            let mut out = Vec::new();
            predict_instants(&last, &before, &seeded, h, reach, &mut out);
            prop_assert_eq!(out.len(), last.len());
            for (a, p) in last.iter().zip(&out) {
                prop_assert_eq!((a.row, a.side), (p.row, p.side));
                prop_assert!(p.t.is_finite() && p.t >= 0.0);
                let shifted = (a.t - h).max(0.0);
                let drift = before.iter().any(|b| {
                    b.row == a.row && b.side == a.side && b.t > 0.0 && (a.t - b.t).abs() < reach
                        && (p.t - (a.t + (a.t - b.t)).max(0.0)).abs() <= 1e-12
                });
                prop_assert!(p.t == shifted || drift, "{a:?} -> {p:?}");
            }
        }

        /// Without a step before, or for instants the solver did not move (seeded where they
        /// ended), the prediction is the shift by the sampling time, clamped at 0.
        #[test]
        fn unmoved_or_unpartnered_instants_are_shifted(
            last in set(), before in set(), h in 1e-3f64..0.1,
        ) {
            let mut out = Vec::new();
            predict_instants(&last, &[], &[], h, 1.0, &mut out);
            for (a, p) in last.iter().zip(&out) {
                prop_assert_eq!(p.t, (a.t - h).max(0.0));
            }
            predict_instants(&last, &before, &last, h, 1.0, &mut out);
            for (a, p) in last.iter().zip(&out) {
                prop_assert_eq!(p.t, (a.t - h).max(0.0));
            }
        }

        /// An instant the solver moved continues a constant drift exactly (its partner the
        /// nearest one of its row and side in the set before).
        #[test]
        fn moved_instant_continues_its_drift(
            t in 1.0f64..30.0, d in -0.2f64..0.2, h in 1e-3f64..0.1, row in 0usize..3,
        ) {
            let before = [instant(t - d, row, false), instant(t + 5.0, row, false)];
            let last = [instant(t, row, false)];
            let seeded = [instant(t + 1e-3, row, false)];
            let mut out = Vec::new();
            predict_instants(&last, &before, &seeded, h, 0.25, &mut out);
            prop_assert!((out[0].t - (t + d)).abs() <= 1e-12);
        }
    }
}
