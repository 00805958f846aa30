//! Two-step synthesis (Section 6 of the paper): Step 1 chooses the gains L by minimising the
//! full-communication H2 bound subject to inter-agent stability LMIs; Step 2 chooses the
//! thresholds Δ by maximising tr Δ subject to a bounded-real LMI that spends the budget
//! J_max − c*. Analysis mode certifies the bound of given (L, Δ).
//!
//! Numerics follow the spec: Step 1 runs on noise scaled to unit centralised Kalman cost,
//! Step 2 on a balanced realisation, and every returned certificate is re-checked by eigenvalues.

use crate::error::EventEstError;
pub use crate::ipm::Solver;
use crate::linalg::{
    self, cholesky_lower, h2_squared, hinf_norm, kalman, max_eigenvalue, spectral_radius,
};
use crate::lmi::{Problem, Vars};
use crate::model::System;
use crate::sim::Design;
use nalgebra::DMatrix;

/// Strictness margin ε of the scaled problems (G(x) ⪰ ε I stands for G(x) ≻ 0).
const EPS: f64 = 1e-8;
/// Margin of the stability LMIs relative to the scale of P.
const STAB_MARGIN: f64 = 1e-8;

/// Inter-agent stability condition of Step 1.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stability {
    /// No stability constraint: returns the centralised Kalman filter (test oracle).
    None,
    /// Theorem 11: two Lyapunov matrices, 2^{N+1} LMIs.
    Thm11,
    /// Corollary 12: one common Lyapunov matrix, 2^N LMIs.
    Cor12,
    /// Corollary 13 in its H-free form: N+1 vertex LMIs.
    Cor13,
    /// Corollary 13 as stated, with the auxiliary 2n×2n variable H (for comparison only).
    Cor13WithH,
}

impl Stability {
    /// Parses "none", "thm11", "cor12", "cor13", "cor13h".
    pub fn parse(s: &str) -> Result<Self, EventEstError> {
        Ok(match s.to_ascii_lowercase().as_str() {
            "none" => Self::None,
            "thm11" => Self::Thm11,
            "cor12" => Self::Cor12,
            "cor13" => Self::Cor13,
            "cor13h" => Self::Cor13WithH,
            _ => {
                return Err(EventEstError::Name {
                    what: "stability condition",
                    given: s.to_string(),
                    reason: "unknown; known: none, thm11, cor12, cor13, cor13h",
                })
            }
        })
    }
}

/// Result of Step 1.
#[derive(Debug, Clone)]
pub struct Step1 {
    /// Gains L = P^{-1} U (n×p).
    pub l: DMatrix<f64>,
    /// Lyapunov certificate P (= P_1 for Thm 11), for the scaled noise.
    pub p: DMatrix<f64>,
    /// Second Lyapunov matrix P_2 of Thm 11.
    pub p2: Option<DMatrix<f64>>,
    /// Full-communication bound c* = sqrt(tr X) (physical noise scale).
    pub c_star: f64,
    /// True full-communication H2 cost of L (discrete Lyapunov equation).
    pub true_h2: f64,
    /// Centralised Kalman filter cost sqrt(tr Σ⁺).
    pub kalman_cost: f64,
    /// Clarabel's status.
    pub status: String,
    /// Solve time reported by Clarabel, seconds.
    pub solve_time: f64,
    /// Interior-point iterations.
    pub iterations: u32,
    /// Number of scalar decision variables.
    pub variables: usize,
    /// Number of inter-agent stability LMIs.
    pub stability_lmis: usize,
    /// Post-verification: largest eigenvalue of each stability inequality A_clᵀ P_k A_cl − P_l
    /// recomputed with the returned L (all negative).
    pub stability_margins: Vec<(String, f64)>,
}

pub(crate) fn subset_name(s: u64, n: usize) -> String {
    let members: Vec<String> = (0..n)
        .filter(|m| s >> m & 1 == 1)
        .map(|m| (m + 1).to_string())
        .collect();
    format!("{{{}}}", members.join(","))
}

/// Step 1 (5.39): minimise tr X over (P, [P_2], U, X) subject to the H2 LMIs and `stability`.
pub fn step1(sys: &System, stability: Stability) -> Result<Step1, EventEstError> {
    step1_using(sys, stability, Solver::Clarabel)
}

/// [`step1`] on a chosen SDP solver (use [`Solver::SchurIpm`] for Cor 13 with ≳ 8 agents).
pub fn step1_using(
    sys: &System,
    stability: Stability,
    solver: Solver,
) -> Result<Step1, EventEstError> {
    Ok(step1_with(sys, stability, None, solver)?.0)
}

/// Result of the relaxed Step 1.
#[derive(Debug, Clone)]
pub struct RelaxedStep1 {
    /// Gains, certificates and post-verification; the stability margins are those of
    /// A_clᵀP_kA_cl − P_l − λ̄ I (all negative).
    pub step1: Step1,
    /// Decay bound λ̄ ≥ 0 of A_clᵀP_kA_cl − P_l ≺ λ̄ I (0: the unrelaxed conditions hold).
    pub lambda_bar: f64,
}

/// Step 1 with the feasibility relaxation of App. E (spec 8.2): the stability inequalities
/// A_clᵀ P_k A_cl − P_l ≺ λ̄ I with the decay bound λ̄ ≥ 0 as a decision variable, minimising
/// tr X + `weight`·λ̄/|P|_scale (|P|_scale = norm of the Kalman error Gramian, the scale of P).
/// Always feasible when (A, C) is detectable; λ̄ > 0 calls for the estimator resets of
/// [`reset_schedule`].
pub fn step1_relaxed(
    sys: &System,
    stability: Stability,
    weight: f64,
) -> Result<RelaxedStep1, EventEstError> {
    if matches!(stability, Stability::None | Stability::Cor13WithH) {
        return Err(EventEstError::Name {
            what: "stability condition of the relaxed Step 1",
            given: format!("{stability:?}").to_ascii_lowercase(),
            reason: "nothing to relax, or the H form; use thm11, cor12 or cor13",
        });
    }
    let (step1, lambda_bar) = step1_with(sys, stability, Some(weight), Solver::Clarabel)?;
    Ok(RelaxedStep1 { step1, lambda_bar })
}

/// Step 1, optionally relaxed (App. E): with `relax = Some(w)` the stability inequalities become
/// A_clᵀP_kA_cl − P_l ≺ λ̄ I with the decay bound λ̄ ≥ 0 a decision variable and the objective
/// tr X + w λ̄/|P|_scale (λ̄ measured relative to the scale of P). Returns the result and λ̄
/// (0 without relaxation).
fn step1_with(
    sys: &System,
    stability: Stability,
    relax: Option<f64>,
    solver: Solver,
) -> Result<(Step1, f64), EventEstError> {
    let (n, p, na) = (sys.n(), sys.p(), sys.agents());
    if na > 63 {
        return Err(EventEstError::Parameter {
            name: "agents",
            value: na as f64,
            reason: "communication patterns are bit sets of at most 63 agents",
        });
    }
    if matches!(stability, Stability::Thm11 | Stability::Cor12) && na > 16 {
        return Err(EventEstError::Parameter {
            name: "agents",
            value: na as f64,
            reason: "Thm 11 and Cor 12 need 2^N LMIs; use Cor 13 beyond 16 agents",
        });
    }
    let a = &sys.a;
    let c = &sys.c;
    let af = sys.a_cl();
    let kf = kalman(a, c, &sys.v(), &sys.w)?;
    let kalman_cost = kf.posterior.trace().sqrt();
    // Scale the noise to unit centralised cost (L is scale invariant).
    let s = 1.0 / kf.posterior.trace();
    let w_half = sys.w_sqrt()? * s.sqrt();
    let v_half = &sys.v_sqrt * s.sqrt();
    let nv = v_half.ncols();
    let off = sys.output_offsets();
    let identity = DMatrix::<f64>::identity(n, n);
    // The stability LMIs are active at the optimum: tighten them relative to the scale of P
    // (≈ the observability Gramian of the Kalman error dynamics, large for slow modes) so that
    // the Lyapunov decrease survives the solver tolerance when re-checked with the returned L.
    let a_kf = (&identity - &kf.gain * c) * a;
    let p_scale = linalg::dlyap(
        &a_kf.transpose(),
        &identity,
        "scale of P (Kalman error Gramian)",
    )?
    .norm();
    let stab_eps = STAB_MARGIN * p_scale;
    let mut vars = Vars::default();
    let pv = vars.sym(n);
    let p2v = (stability == Stability::Thm11).then(|| vars.sym(n));
    let uv = vars.full(n, p);
    let xv = vars.sym(p + nv);
    let hv = (stability == Stability::Cor13WithH).then(|| vars.sym(2 * n));
    let lambda_v = relax.map(|_| vars.scalar());
    let mut prob = Problem::new(vars);
    for i in 0..(p + nv) {
        prob.objective[xv.index(i, i)] = 1.0;
    }
    if let (Some(w), Some(lv)) = (relax, lambda_v) {
        if !(w.is_finite() && w > 0.0) {
            return Err(EventEstError::Parameter {
                name: "relaxation weight",
                value: w,
                reason: "must be positive",
            });
        }
        prob.objective[lv.index(0, 0)] = w / p_scale;
        prob.lmi("decay bound λ̄ ≥ 0", 1)
            .add_scalar_identity(lv, 0, 1, 1.0);
    }
    let ca = c * a;
    let caf = c * &af;
    // (H2-a): [[P, PA − UCA], [*, P − I]].
    {
        let l = prob.lmi("H2 Lyapunov inequality P − ÂᵀPÂ − I ≻ 0", 2 * n);
        l.add_sym(pv, 0, 1.0);
        l.add_sym_times(pv, a, 0, n, 1.0);
        l.add_full_times(uv, &ca, 0..p, 0, n, -1.0);
        l.add_sym(pv, n, 1.0);
        l.add_const(n, n, &(-&identity));
    }
    // (H2-b): [[P, [−U W^½, (P − UC) V^½]], [*, X]].
    {
        let l = prob.lmi("H2 cost X ≻ B̂ᵀPB̂", n + p + nv);
        l.add_sym(pv, 0, 1.0);
        l.add_full_times(uv, &w_half, 0..p, 0, n, -1.0);
        l.add_sym_times(pv, &v_half, 0, n + p, 1.0);
        l.add_full_times(uv, &(c * &v_half), 0..p, 0, n + p, -1.0);
        l.add_sym(xv, n, 1.0);
    }
    // Adds [[Pk, (P − Σ_{m∈S} w U_m C_m) A_F], [*, Pl]] with P multiplying the gains.
    let add_pattern = |prob: &mut Problem,
                       name: String,
                       subset: u64,
                       weight: f64,
                       pk: crate::lmi::VarId,
                       pl: crate::lmi::VarId| {
        let l = prob.lmi(name, 2 * n);
        l.add_sym(pk, 0, 1.0);
        l.add_sym_times(pk, &af, 0, n, 1.0);
        if pk == pv {
            for m in 0..na {
                if subset >> m & 1 == 1 {
                    l.add_full_times(uv, &caf, off[m]..off[m + 1], 0, n, -weight);
                }
            }
        }
        l.add_sym(pl, n, 1.0);
        if let Some(lv) = lambda_v {
            l.add_scalar_identity(lv, n, n, 1.0);
        }
        l.set_margin(stab_eps);
    };
    let measuring = sys.measuring_agents();
    let mut stability_lmis = 0;
    match stability {
        Stability::None => {}
        Stability::Cor12 => {
            for subset in 0..(1u64 << na) {
                add_pattern(
                    &mut prob,
                    format!("Cor 12 pattern {}", subset_name(subset, na)),
                    subset,
                    1.0,
                    pv,
                    pv,
                );
                stability_lmis += 1;
            }
        }
        Stability::Cor13 => {
            add_pattern(&mut prob, "Cor 13 vertex A+BF".into(), 0, 1.0, pv, pv);
            stability_lmis += 1;
            for m in 0..na {
                if sys.outputs[m] > 0 {
                    add_pattern(
                        &mut prob,
                        format!("Cor 13 vertex (I − N L_{} C_{})(A+BF)", m + 1, m + 1),
                        1 << m,
                        measuring as f64,
                        pv,
                        pv,
                    );
                    stability_lmis += 1;
                }
            }
        }
        Stability::Thm11 => {
            let p2 = declared(p2v, "P_2")?;
            for subset in 0..(1u64 << na) {
                let (pk, name) = if subset == 0 {
                    (p2, "P_2")
                } else {
                    (pv, "P_1")
                };
                for (pl, lname) in [(pv, "P_1"), (p2, "P_2")] {
                    add_pattern(
                        &mut prob,
                        format!(
                            "Thm 11 pattern {} with ({name}, {lname})",
                            subset_name(subset, na)
                        ),
                        subset,
                        1.0,
                        pk,
                        pl,
                    );
                    stability_lmis += 1;
                }
            }
        }
        Stability::Cor13WithH => {
            let h = declared(hv, "H")?;
            add_pattern(&mut prob, "Cor 13 M_0 ≻ 0".into(), 0, 1.0, pv, pv);
            // H − M_0 ⪰ 0.
            {
                let l = prob.lmi("Cor 13 H ⪰ M_0", 2 * n);
                l.add_sym(h, 0, 1.0);
                l.add_sym(pv, 0, -1.0);
                l.add_sym_times(pv, &af, 0, n, -1.0);
                l.add_sym(pv, n, -1.0);
            }
            for m in 0..na {
                // N M_m − (N − 1) H ≻ 0.
                let nn = na as f64;
                let l = prob.lmi(format!("Cor 13 M_{} − ((N−1)/N) H ≻ 0", m + 1), 2 * n);
                l.add_sym(pv, 0, nn);
                l.add_sym_times(pv, &af, 0, n, nn);
                l.add_full_times(uv, &caf, off[m]..off[m + 1], 0, n, -nn);
                l.add_sym(pv, n, nn);
                l.add_sym(h, 0, -(nn - 1.0));
            }
            stability_lmis += na + 2;
        }
    }
    let sol = prob.solve_with(solver, "Step 1 (gains)", EPS)?;
    let pm = pv.value(&sol.x);
    let um = uv.value(&sol.x);
    let chol = pm
        .clone()
        .cholesky()
        .ok_or(EventEstError::NotPositiveDefinite {
            name: "Step-1 certificate P",
        })?;
    let l = chol.solve(&um);
    let c_star = (xv.value(&sol.x).trace() / s).sqrt();
    let p2 = p2v.map(|v| v.value(&sol.x));
    let lambda_bar = lambda_v.map_or(0.0, |v| v.value(&sol.x)[(0, 0)].max(0.0));

    // Post-verification with the returned L.
    let a_hat = (&identity - &l * c) * a;
    let rho = spectral_radius(&a_hat);
    if rho >= 1.0 {
        return Err(EventEstError::Verification {
            condition: "ρ((I−LC)A) < 1".into(),
            margin: rho - 1.0,
        });
    }
    let mut margins = Vec::new();
    let mut check = |name: String,
                     acl: &DMatrix<f64>,
                     pk: &DMatrix<f64>,
                     pl: &DMatrix<f64>|
     -> Result<(), EventEstError> {
        let shifted = acl.transpose() * pk * acl - pl - &identity * lambda_bar;
        let m = max_eigenvalue(&shifted) / pl.norm().max(1e-300);
        if m.is_nan() || m >= 0.0 {
            return Err(EventEstError::Verification {
                condition: name,
                margin: m,
            });
        }
        margins.push((name, m));
        Ok(())
    };
    let acl_of = |subset: u64, weight: f64| (&identity - sys.lc_subset(&l, subset) * weight) * &af;
    match stability {
        Stability::None => {}
        Stability::Cor12 | Stability::Cor13WithH => {
            for subset in 0..(1u64 << na) {
                check(
                    format!("A_cl({})ᵀPA_cl − P ≺ 0", subset_name(subset, na)),
                    &acl_of(subset, 1.0),
                    &pm,
                    &pm,
                )?;
            }
        }
        Stability::Cor13 => {
            check("(A+BF)ᵀP(A+BF) − P ≺ 0".into(), &af, &pm, &pm)?;
            for m in 0..na {
                if sys.outputs[m] > 0 {
                    check(
                        format!("vertex m = {}: A_mᵀPA_m − P ≺ 0", m + 1),
                        &acl_of(1 << m, measuring as f64),
                        &pm,
                        &pm,
                    )?;
                }
            }
        }
        Stability::Thm11 => {
            let p2m = p2.clone().unwrap_or_else(|| pm.clone());
            for subset in 0..(1u64 << na) {
                let acl = acl_of(subset, 1.0);
                let pk = if subset == 0 { &p2m } else { &pm };
                check(
                    format!("A_cl({})ᵀP_kA_cl − P_1 ≺ 0", subset_name(subset, na)),
                    &acl,
                    pk,
                    &pm,
                )?;
                check(
                    format!("A_cl({})ᵀP_kA_cl − P_2 ≺ 0", subset_name(subset, na)),
                    &acl,
                    pk,
                    &p2m,
                )?;
            }
        }
    }
    let true_h2 = full_communication_cost(sys, &l)?;
    if true_h2 > c_star * (1.0 + 1e-4) {
        return Err(EventEstError::Verification {
            condition: "true H2 cost of L ≤ c*".into(),
            margin: true_h2 - c_star,
        });
    }
    let step = Step1 {
        l,
        p: pm,
        p2,
        c_star,
        true_h2,
        kalman_cost,
        status: sol.status,
        solve_time: sol.solve_time,
        iterations: sol.iterations,
        variables: prob.vars.len(),
        stability_lmis,
        stability_margins: margins,
    };
    Ok((step, lambda_bar))
}

/// A decision variable declared only for some stability conditions.
fn declared(
    var: Option<crate::lmi::VarId>,
    name: &'static str,
) -> Result<crate::lmi::VarId, EventEstError> {
    var.ok_or(EventEstError::Parameter {
        name,
        value: f64::NAN,
        reason: "missing",
    })
}

/// B̂_2 = [−L W^½, (I − LC) V^½].
fn b_hat(sys: &System, l: &DMatrix<f64>) -> Result<DMatrix<f64>, EventEstError> {
    let n = sys.n();
    let w_half = sys.w_sqrt()?;
    let left = -(l * w_half);
    let right = (DMatrix::identity(n, n) - l * &sys.c) * &sys.v_sqrt;
    let mut b = DMatrix::zeros(n, left.ncols() + right.ncols());
    b.columns_mut(0, left.ncols()).copy_from(&left);
    b.columns_mut(left.ncols(), right.ncols()).copy_from(&right);
    Ok(b)
}

/// True full-communication cost ‖G_2‖_2 of the gains L (Kalman objective, z = e).
pub fn full_communication_cost(sys: &System, l: &DMatrix<f64>) -> Result<f64, EventEstError> {
    check_gain(sys, l)?;
    let n = sys.n();
    let a_hat = (DMatrix::identity(n, n) - l * &sys.c) * &sys.a;
    Ok(h2_squared(&a_hat, &b_hat(sys, l)?)?.sqrt())
}

fn check_gain(sys: &System, l: &DMatrix<f64>) -> Result<(), EventEstError> {
    if l.nrows() != sys.n() || l.ncols() != sys.p() {
        return Err(EventEstError::Dimension {
            name: "L",
            expected_rows: sys.n(),
            expected_cols: sys.p(),
            found_rows: l.nrows(),
            found_cols: l.ncols(),
        });
    }
    if l.iter().any(|v| !v.is_finite()) {
        return Err(EventEstError::NonFinite { name: "L" });
    }
    Ok(())
}

/// Thresholds for unit γ, from which every J_max follows by the exact scaling law
/// Δ*(J_max) = sqrt(γ(J_max)) · Δ̃*.
#[derive(Debug, Clone)]
pub struct UnitThresholds {
    /// Δ̃_i per agent (solution of Step 2 with γ = 1).
    pub delta: Vec<DMatrix<f64>>,
    /// ‖(zI − Â)^{-1} L‖_∞ used for balancing.
    pub hinf_scale: f64,
    /// Clarabel's status.
    pub status: String,
    /// Solve time reported by Clarabel, seconds.
    pub solve_time: f64,
}

/// Step 2 (5.40) with γ = 1 on the balanced realisation: maximise tr Δ subject to
/// ‖(zI − Â)^{-1} L Δ‖_∞ < 1 (Kalman objective). `gamma_factor` scales the balancing level
/// γ_s = gamma_factor · h² (1 is the default; results must not depend on it).
pub fn step2_unit(
    sys: &System,
    l: &DMatrix<f64>,
    gamma_factor: f64,
) -> Result<UnitThresholds, EventEstError> {
    step2_unit_using(sys, l, gamma_factor, Solver::Clarabel)
}

/// [`step2_unit`] on a chosen SDP solver.
pub fn step2_unit_using(
    sys: &System,
    l: &DMatrix<f64>,
    gamma_factor: f64,
    solver: Solver,
) -> Result<UnitThresholds, EventEstError> {
    check_gain(sys, l)?;
    if !(gamma_factor.is_finite() && gamma_factor > 0.0) {
        return Err(EventEstError::Parameter {
            name: "gamma_factor",
            value: gamma_factor,
            reason: "must be positive",
        });
    }
    let (n, p) = (sys.n(), sys.p());
    let identity = DMatrix::<f64>::identity(n, n);
    let a_hat = (&identity - l * &sys.c) * &sys.a;
    let rho = spectral_radius(&a_hat);
    if rho >= 1.0 {
        return Err(EventEstError::Verification {
            condition: "ρ((I−LC)A) < 1 before Step 2".into(),
            margin: rho - 1.0,
        });
    }
    // (a) balance: G_c = Â G_c Âᵀ + L Lᵀ, T = chol(G_c).
    let gc = linalg::dlyap(&a_hat, &(l * l.transpose()), "Step-2 balancing Gramian")?;
    let t = cholesky_lower(&gc, "balancing Gramian G_c (is every state reached by L?)")?;
    let t_inv = t.clone().try_inverse().ok_or(EventEstError::Singular {
        name: "balancing factor T",
    })?;
    let a_t = &t_inv * &a_hat * &t;
    let l_t = &t_inv * l;
    let c_t = t.clone(); // Ĉ T with Ĉ = I
                         // (b) H∞ level of the channel from the event noise to the error.
    let h = hinf_norm(&a_hat, l, &identity);
    let gamma_s = gamma_factor * h * h;
    let off = sys.output_offsets();
    let mut vars = Vars::default();
    let qv = vars.sym(n);
    let deltas: Vec<_> = sys.outputs.iter().map(|&pi| vars.sym(pi)).collect();
    let mut prob = Problem::new(vars);
    for (i, d) in deltas.iter().enumerate() {
        for k in 0..sys.outputs[i] {
            prob.objective[d.index(k, k)] = -1.0;
        }
    }
    let nz = c_t.nrows();
    {
        // [[Q, ÃQ, L̃Δ, 0], [*, Q, 0, QĈ'ᵀ], [*, *, I, 0], [*, *, *, γ_s I]].
        let lm = prob.lmi("bounded-real lemma ‖G_1‖_∞ < sqrt(γ)", 2 * n + p + nz);
        lm.add_sym(qv, 0, 1.0);
        lm.add_times_sym(&a_t, qv, 0, n, 1.0);
        for (i, d) in deltas.iter().enumerate() {
            lm.add_times_sym(
                &l_t.columns(off[i], sys.outputs[i]).into_owned(),
                *d,
                0,
                2 * n + off[i],
                1.0,
            );
        }
        lm.add_sym(qv, n, 1.0);
        lm.add_sym_times(qv, &c_t.transpose(), n, 2 * n + p, 1.0);
        lm.add_const(2 * n, 2 * n, &DMatrix::identity(p, p));
        lm.add_const(2 * n + p, 2 * n + p, &(DMatrix::identity(nz, nz) * gamma_s));
    }
    // Balanced thresholds Δ_s are of order sqrt(γ_s); bounds are set relative to it.
    let delta_min = 1e-9 * gamma_s.sqrt();
    for (i, d) in deltas.iter().enumerate() {
        let pi = sys.outputs[i];
        if pi == 0 {
            continue;
        }
        let lm = prob.lmi(format!("Δ_{} ⪰ δ_min I", i + 1), pi);
        lm.add_sym(*d, 0, 1.0);
        lm.add_const(0, 0, &(DMatrix::identity(pi, pi) * -delta_min));
        // tr Δ_i is unbounded along ker L_i: cap Δ_i when L_i has no full column rank.
        let li = l.columns(off[i], pi).into_owned();
        let sv = li.singular_values();
        let smax = sv.iter().copied().fold(0.0, f64::max);
        if sv.iter().any(|&v| v <= 1e-10 * smax.max(1e-300)) {
            let cap = 1e3 * gamma_s.sqrt();
            let lm = prob.lmi(
                format!("Δ_{} ⪯ Δ_max I (L_{} rank deficient)", i + 1, i + 1),
                pi,
            );
            lm.add_sym(*d, 0, -1.0);
            lm.add_const(0, 0, &(DMatrix::identity(pi, pi) * cap));
        }
    }
    let sol = prob.solve_with(solver, "Step 2 (thresholds)", EPS * gamma_s.sqrt())?;
    let scale = 1.0 / gamma_s.sqrt();
    let delta: Vec<DMatrix<f64>> = deltas.iter().map(|d| d.value(&sol.x) * scale).collect();
    // Post-verification: ‖(zI−Â)^{-1} L Δ̃‖_∞ ≤ 1 (1 + 1e−3) and Δ̃_i ≻ 0.
    let design = Design {
        l: l.clone(),
        delta: delta.clone(),
    };
    let g1 = g1_norm(sys, &design)?;
    if g1 > 1.0 + 1e-3 {
        return Err(EventEstError::Verification {
            condition: "‖G_1‖_∞ ≤ sqrt(γ) for the unit-γ thresholds".into(),
            margin: g1 - 1.0,
        });
    }
    Ok(UnitThresholds {
        delta,
        hinf_scale: h,
        status: sol.status,
        solve_time: sol.solve_time,
    })
}

/// ‖G_1‖_∞ = ‖(zI − Â)^{-1} L Δ‖_∞ (checks every Δ_i ≻ 0 first).
pub fn g1_norm(sys: &System, design: &Design) -> Result<f64, EventEstError> {
    check_gain(sys, &design.l)?;
    design.delta_inverse(sys)?;
    let n = sys.n();
    let delta = delta_block(sys, &design.delta);
    let identity = DMatrix::<f64>::identity(n, n);
    let a_hat = (&identity - &design.l * &sys.c) * &sys.a;
    Ok(hinf_norm(&a_hat, &(&design.l * delta), &identity))
}

/// Block-diagonal p×p matrix diag(Δ_1, …, Δ_N) (blocks already checked by the caller).
pub(crate) fn delta_block(sys: &System, delta: &[DMatrix<f64>]) -> DMatrix<f64> {
    let p = sys.p();
    let off = sys.output_offsets();
    let mut block = DMatrix::zeros(p, p);
    for (i, d) in delta.iter().enumerate() {
        block
            .view_mut((off[i], off[i]), (sys.outputs[i], sys.outputs[i]))
            .copy_from(d);
    }
    block
}

/// γ = (1 − 1e−6)(J_max − c*)²/N_s, or an error if J_max ≤ c*.
pub fn budget_gamma(sys: &System, c_star: f64, j_max: f64) -> Result<f64, EventEstError> {
    if !(j_max.is_finite() && j_max > c_star) {
        return Err(EventEstError::Budget { j_max, c_star });
    }
    Ok((1.0 - 1e-6) * (j_max - c_star).powi(2) / sys.measuring_agents().max(1) as f64)
}

/// Thresholds for J_max from the unit-γ solution: Δ = sqrt(γ) Δ̃.
pub fn thresholds(
    sys: &System,
    unit: &UnitThresholds,
    c_star: f64,
    j_max: f64,
) -> Result<Vec<DMatrix<f64>>, EventEstError> {
    let g = budget_gamma(sys, c_star, j_max)?;
    Ok(unit.delta.iter().map(|d| d * g.sqrt()).collect())
}

/// Certified bound of a design (analysis mode): J_bound = sqrt(N_s)‖G_1‖_∞ + ‖G_2‖_2.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bound {
    /// ‖G_1‖_∞ from the event-triggering nonlinearity.
    pub g1_hinf: f64,
    /// ‖G_2‖_2, the full-communication cost.
    pub g2_h2: f64,
    /// sqrt(N_s) ‖G_1‖_∞ + ‖G_2‖_2 (bounds ‖e‖_P with identical initial estimates, no drops).
    pub bound: f64,
}

/// Analysis mode: the exact terms of (5.38) for given (L, Δ).
pub fn analyse(sys: &System, design: &Design) -> Result<Bound, EventEstError> {
    let g1 = g1_norm(sys, design)?;
    let g2 = full_communication_cost(sys, &design.l)?;
    Ok(Bound {
        g1_hinf: g1,
        g2_h2: g2,
        bound: (sys.measuring_agents() as f64).sqrt() * g1 + g2,
    })
}

/// A complete design for one J_max.
#[derive(Debug, Clone)]
pub struct Synthesis {
    /// Step-1 result.
    pub step1: Step1,
    /// Unit-γ thresholds.
    pub unit: UnitThresholds,
    /// Gains and thresholds for `j_max`.
    pub design: Design,
    /// Requested bound.
    pub j_max: f64,
    /// Certified bound of the design (analysis mode), ≤ J_max.
    pub bound: Bound,
}

/// Step 1, Step 2 and analysis for one J_max.
pub fn synthesize(
    sys: &System,
    stability: Stability,
    j_max: f64,
) -> Result<Synthesis, EventEstError> {
    let step1 = step1(sys, stability)?;
    complete(sys, step1, j_max)
}

/// What Step 2 subtracts from J_max to get its budget.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BudgetBase {
    /// The Step-1 bound c* (the thesis).
    Step1Bound,
    /// The exact full-communication H2 cost of L (≤ c*; larger thresholds, same guarantee,
    /// because the P of Thm 16 need not equal the Step-1 P).
    ExactH2,
}

/// Step 2 and analysis on a given Step-1 result (e.g. to pick J_max as a multiple of c*).
pub fn complete(sys: &System, step1: Step1, j_max: f64) -> Result<Synthesis, EventEstError> {
    complete_with(sys, step1, j_max, BudgetBase::Step1Bound)
}

/// [`complete`] with a choice of budget.
pub fn complete_with(
    sys: &System,
    step1: Step1,
    j_max: f64,
    base: BudgetBase,
) -> Result<Synthesis, EventEstError> {
    complete_using(sys, step1, j_max, base, Solver::Clarabel)
}

/// [`complete_with`] with Step 2 on a chosen SDP solver.
pub fn complete_using(
    sys: &System,
    step1: Step1,
    j_max: f64,
    base: BudgetBase,
    solver: Solver,
) -> Result<Synthesis, EventEstError> {
    let spent = match base {
        BudgetBase::Step1Bound => step1.c_star,
        BudgetBase::ExactH2 => step1.true_h2,
    };
    let (unit, design, bound) = certified_thresholds(sys, step1.l.clone(), spent, j_max, solver)?;
    Ok(Synthesis {
        step1,
        unit,
        design,
        j_max,
        bound,
    })
}

/// Step 2 for gains `l` on the budget J_max − `spent`, and the certified bound of the design
/// (an error if it exceeds J_max by more than the solver tolerance 1e−3).
pub(crate) fn certified_thresholds(
    sys: &System,
    l: DMatrix<f64>,
    spent: f64,
    j_max: f64,
    solver: Solver,
) -> Result<(UnitThresholds, Design, Bound), EventEstError> {
    budget_gamma(sys, spent, j_max)?;
    let unit = step2_unit_using(sys, &l, 1.0, solver)?;
    let delta = thresholds(sys, &unit, spent, j_max)?;
    let design = Design { l, delta };
    let bound = analyse(sys, &design)?;
    if bound.bound > j_max * (1.0 + 1e-3) {
        return Err(EventEstError::Verification {
            condition: "certified bound ≤ J_max".into(),
            margin: bound.bound - j_max,
        });
    }
    Ok((unit, design, bound))
}

/// Periodic estimator resets of App. E for a certificate (P_1, P_2) that may only satisfy the
/// relaxed inequalities A_clᵀ P_k A_cl − P_l ≺ λ̄ I.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResetSchedule {
    /// λ̄: the largest eigenvalue of A_cl(S)ᵀ P_k A_cl(S) − P_l over all patterns and pairs.
    pub lambda_bar: f64,
    /// σ_lo = min(λ_min(P_1), λ_min(P_2)).
    pub sigma_lo: f64,
    /// The free constant α > 0 that maximises the reset period.
    pub alpha: f64,
    /// Growth factor a = 1 + (λ̄ + α)/σ_lo of V̂(k) = a V̂(k−1) + β.
    pub a: f64,
    /// β = (γ̄²/α + δ̄) D².
    pub beta: f64,
    /// First k with V̂(k) ≥ V_max (resets every k_reset steps keep σ_lo|ε|² ≤ V_max);
    /// `None` if V̂ never reaches V_max (no resets needed).
    pub k_reset: Option<usize>,
}

/// Reset period for gains `l`, certificate (P_1, P_2), disturbance bound D ≥ |d_ji| and level
/// V_max, with α chosen on a logarithmic grid to maximise k_reset.
pub fn reset_schedule(
    sys: &System,
    l: &DMatrix<f64>,
    p1: &DMatrix<f64>,
    p2: &DMatrix<f64>,
    d_bound: f64,
    v_max: f64,
) -> Result<ResetSchedule, EventEstError> {
    check_gain(sys, l)?;
    let (n, na) = (sys.n(), sys.agents());
    if na > 16 {
        return Err(EventEstError::Parameter {
            name: "agents",
            value: na as f64,
            reason: "the reset schedule enumerates 2^N patterns; at most 16 agents",
        });
    }
    for (name, p) in [("P_1", p1), ("P_2", p2)] {
        if p.nrows() != n || p.ncols() != n {
            return Err(EventEstError::Dimension {
                name,
                expected_rows: n,
                expected_cols: n,
                found_rows: p.nrows(),
                found_cols: p.ncols(),
            });
        }
    }
    for (name, v) in [("D", d_bound), ("V_max", v_max)] {
        if !(v.is_finite() && v > 0.0) {
            return Err(EventEstError::Parameter {
                name,
                value: v,
                reason: "must be positive",
            });
        }
    }
    let sigma_lo = linalg::min_eigenvalue(p1).min(linalg::min_eigenvalue(p2));
    if sigma_lo <= 0.0 {
        return Err(EventEstError::NotPositiveDefinite { name: "P_1 or P_2" });
    }
    let af = sys.a_cl();
    let identity = DMatrix::<f64>::identity(n, n);
    let (mut lambda_bar, mut gamma_bar) = (f64::NEG_INFINITY, 0.0f64);
    for subset in 0..(1u64 << na) {
        let acl = (&identity - sys.lc_subset(l, subset)) * &af;
        let pk = if subset == 0 { p2 } else { p1 };
        for pl in [p1, p2] {
            lambda_bar = lambda_bar.max(max_eigenvalue(&(acl.transpose() * pk * &acl - pl)));
        }
        for pm in [p1, p2] {
            gamma_bar = gamma_bar.max((pm * &acl).singular_values().max());
        }
    }
    let delta_bar = p1.singular_values().max().max(p2.singular_values().max());
    let schedule = |alpha: f64| {
        let a = 1.0 + (lambda_bar + alpha) / sigma_lo;
        let beta = (gamma_bar * gamma_bar / alpha + delta_bar) * d_bound * d_bound;
        let k_reset = if a < 1.0 && beta / (1.0 - a) < v_max {
            None
        } else if (a - 1.0).abs() < 1e-15 {
            Some((v_max / beta).ceil().max(1.0) as usize)
        } else {
            // β(a^k − 1)/(a − 1) ≥ V_max  ⇔  k ≥ ln(1 + V_max (a − 1)/β) / ln a.
            let k = (1.0 + v_max * (a - 1.0) / beta).ln() / a.ln();
            Some(k.ceil().max(1.0) as usize)
        };
        ResetSchedule {
            lambda_bar,
            sigma_lo,
            alpha,
            a,
            beta,
            k_reset,
        }
    };
    let mut best = schedule(sigma_lo * 1e-6);
    for i in 0..=120 {
        let alpha = sigma_lo * 10f64.powf(-6.0 + 8.0 * i as f64 / 120.0);
        if lambda_bar + alpha <= -sigma_lo {
            continue; // a must stay non-negative
        }
        let s = schedule(alpha);
        let better = match (s.k_reset, best.k_reset) {
            (None, Some(_)) => true,
            (Some(k), Some(b)) => k > b,
            _ => false,
        };
        if better {
            best = s;
        }
    }
    Ok(best)
}
