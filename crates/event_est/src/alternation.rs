//! General objective by alternation (spec 6.3): maximise Σ_i tr Δ_i subject to the certified
//! bound sqrt(N_s)‖G_1‖_∞ + ‖G_2‖_2 ≤ J_max, alternating a gain step (Δ fixed) and a threshold
//! step (L fixed, Step 2 on the exact H2 budget).
//!
//! The gain step of the thesis (Step 1 plus the bounded-real LMI, U = PL with one P shared by the
//! H2, bounded-real and stability LMIs) is conservative: at the two-step design of the platoon it
//! finds no gain with a lower certified bound. Here every condition keeps its own Lyapunov matrix
//! and the gain enters affinely: each LMI is written as [[P^{-1}, M(L)], [M(L)ᵀ, P]] ≻ 0 and
//! P^{-1} is replaced by its tangent 2P_k^{-1} − P_k^{-1} P P_k^{-1} ⪯ P^{-1} at the current
//! certificate P_k (convex–concave procedure). The SDP is an inner approximation that contains
//! the current design, so its optimum cannot increase the linearised (upper-bounding) objective;
//! every step is re-certified exactly (Lyapunov equation, frequency sweep, eigenvalues of the
//! stability inequalities) before it is accepted.
//!
//! Each LMI is normalised by the congruence P = R P̃ R with R = P_k^{1/2}, so that the current
//! point is P̃ = I whatever the scale of the slow error dynamics.
//!
//! The performance output is the estimation error (z = e): the thresholds enter the bound
//! through G_1 = (zI − Â)^{-1}LΔ. The spec's Δ-dependent example z = q (normalised innovation)
//! is not used: its bound falls monotonically as Δ is scaled up (G_1 is scale invariant, G_2
//! falls as 1/t), so maximising Σ tr Δ_i under it is unbounded or infeasible (test
//! `innovation_output_bound_is_monotone_in_the_threshold_scale`).

use crate::error::EventEstError;
use crate::linalg::{self, hinf_norm, kalman, max_eigenvalue, min_eigenvalue, spectral_radius};
use crate::lmi::{Problem, Vars};
use crate::model::System;
use crate::sim::Design;
use crate::synth::{
    analyse, certified_thresholds, delta_block, full_communication_cost, step1, subset_name, Bound,
    Solver, Stability,
};
use nalgebra::DMatrix;

/// Strictness margin of the gain-step LMIs (normalised units), unless the current point has
/// less slack, in which case half of its slack is used.
const EPS: f64 = 1e-9;
/// Interior margin of the certificates built at the current design, relative to the decay
/// margin 1 − ρ(Â)² of the error dynamics: the certificates satisfy their inequalities with
/// slack η P, i.e. for the dynamics slowed down by 1/sqrt(1 − η).
const ETA: f64 = 1e-3;
/// Name of the level-set constraint of the gain step (the current design lies on it).
const LEVEL_SET: &str = "gain step: level set of the bound";
/// A gain step must lower the exact bound by at least this relative amount to count.
const MIN_DECREASE: f64 = 1e-7;

/// One iterate of [`alternate`].
#[derive(Debug, Clone)]
pub struct Iterate {
    /// Gains and thresholds.
    pub design: Design,
    /// Σ_i tr Δ_i (the objective, maximised).
    pub trace_delta: f64,
    /// Certified bound of the design (analysis mode), ≤ J_max.
    pub bound: Bound,
    /// Exact bound of these gains with the previous iterate's thresholds (the gain step's
    /// objective; below the previous bound). `None` for iterate 0.
    pub gain_step_bound: Option<f64>,
    /// Step size θ of the accepted gain step L_k + θ(L' − L_k). `None` for iterate 0.
    pub step_size: Option<f64>,
    /// Common Lyapunov matrix of the stability inequalities for these gains (Cor 12: all
    /// patterns; Cor 13: the vertices); empty (0×0) for `Stability::None`.
    pub stability_certificate: DMatrix<f64>,
    /// Largest eigenvalue of A_clᵀPA_cl − P relative to |P| for each certified matrix (< 0).
    pub stability_margins: Margins,
}

/// Result of [`alternate`].
#[derive(Debug, Clone)]
pub struct Alternation {
    /// Iterate 0 is the two-step design (Step 1, then Step 2 on the exact H2 budget); every
    /// further entry follows one accepted gain step and one threshold step.
    pub iterates: Vec<Iterate>,
    /// Why the iteration ended.
    pub stop: String,
}

/// Named relative margins of the stability inequalities.
type Margins = Vec<(String, f64)>;

/// A communication pattern certified by a common quadratic Lyapunov function:
/// A_cl = (I − w Σ_{m∈S} L_m C_m)(A+BF).
#[derive(Debug, Clone)]
struct Pattern {
    name: String,
    subset: u64,
    weight: f64,
}

fn patterns(sys: &System, stability: Stability) -> Result<Vec<Pattern>, EventEstError> {
    let na = sys.agents();
    let pattern = |name: String, subset: u64, weight: f64| Pattern {
        name,
        subset,
        weight,
    };
    Ok(match stability {
        Stability::None => Vec::new(),
        Stability::Cor12 | Stability::Cor13WithH => {
            if na > 16 {
                return Err(EventEstError::Parameter {
                    name: "agents",
                    value: na as f64,
                    reason: "Cor 12 needs 2^N LMIs; use Cor 13 beyond 16 agents",
                });
            }
            (0..(1u64 << na))
                .map(|s| pattern(format!("Cor 12 pattern {}", subset_name(s, na)), s, 1.0))
                .collect()
        }
        Stability::Cor13 => {
            let ns = sys.measuring_agents() as f64;
            let mut v = vec![pattern("Cor 13 vertex A+BF".into(), 0, 1.0)];
            for m in (0..na).filter(|&m| sys.outputs[m] > 0) {
                v.push(pattern(format!("Cor 13 vertex m = {}", m + 1), 1 << m, ns));
            }
            v
        }
        Stability::Thm11 => {
            return Err(EventEstError::Name {
                what: "stability condition of the alternation",
                given: "thm11".into(),
                reason: "the alternation certifies gains with a common P; use none, cor12 or cor13",
            })
        }
    })
}

fn closed_loop(sys: &System, l: &DMatrix<f64>, pat: &Pattern) -> DMatrix<f64> {
    let n = sys.n();
    (DMatrix::identity(n, n) - sys.lc_subset(l, pat.subset) * pat.weight) * sys.a_cl()
}

/// Largest eigenvalue of A_clᵀPA_cl − P relative to |P| for every pattern, or the first
/// pattern that fails.
fn stability_margins(
    sys: &System,
    l: &DMatrix<f64>,
    pats: &[Pattern],
    p: &DMatrix<f64>,
) -> Result<Margins, EventEstError> {
    let scale = p.norm().max(f64::MIN_POSITIVE);
    pats.iter()
        .map(|pat| {
            let m = closed_loop(sys, l, pat);
            let margin = max_eigenvalue(&(m.transpose() * p * &m - p)) / scale;
            if margin.is_nan() || margin >= 0.0 {
                Err(EventEstError::Verification {
                    condition: pat.name.clone(),
                    margin,
                })
            } else {
                Ok((pat.name.clone(), margin))
            }
        })
        .collect()
}

/// Analysis SDP: the common Lyapunov matrix 0 ⪯ P ⪯ I that maximises the smallest eigenvalue
/// of every [[P, P A_cl], [*, P]] (a well-centred certificate), re-checked by eigenvalues.
fn stability_certificate(
    sys: &System,
    l: &DMatrix<f64>,
    pats: &[Pattern],
) -> Result<(DMatrix<f64>, Margins), EventEstError> {
    if pats.is_empty() {
        return Ok((DMatrix::zeros(0, 0), Vec::new()));
    }
    let n = sys.n();
    let mut vars = Vars::default();
    let pv = vars.sym(n);
    let t = vars.scalar();
    let mut prob = Problem::new(vars);
    prob.objective[t.index(0, 0)] = -1.0;
    {
        let lm = prob.lmi("P ⪯ I", n);
        lm.add_sym(pv, 0, -1.0);
        lm.add_const(0, 0, &DMatrix::identity(n, n));
    }
    for pat in pats {
        let lm = prob.lmi(pat.name.clone(), 2 * n);
        lm.add_sym(pv, 0, 1.0);
        lm.add_sym_times(pv, &closed_loop(sys, l, pat), 0, n, 1.0);
        lm.add_sym(pv, n, 1.0);
        lm.add_scalar_identity(t, 0, 2 * n, -1.0);
    }
    let sol = prob.solve("stability certificate of the alternated gains", 0.0)?;
    let p = pv.value(&sol.x);
    let margins = stability_margins(sys, l, pats, &p)?;
    Ok((p, margins))
}

/// Symmetric square root R = P^{1/2} and its inverse.
fn sqrt_and_inverse(
    p: &DMatrix<f64>,
    name: &'static str,
) -> Result<(DMatrix<f64>, DMatrix<f64>), EventEstError> {
    let eig = p.clone().symmetric_eigen();
    if eig.eigenvalues.iter().any(|&v| v.is_nan() || v <= 0.0) {
        return Err(EventEstError::NotPositiveDefinite { name });
    }
    let v = &eig.eigenvectors;
    let root = DMatrix::from_diagonal(&eig.eigenvalues.map(f64::sqrt));
    let inv_root = DMatrix::from_diagonal(&eig.eigenvalues.map(|x| 1.0 / x.sqrt()));
    Ok((v * root * v.transpose(), v * inv_root * v.transpose()))
}

/// Noise-scaled data of one synthesis (L is invariant to the scale s = 1/tr Σ_post of the
/// centralised Kalman filter, which brings the H2 cost to order one).
struct Scaled<'a> {
    sys: &'a System,
    w_half: DMatrix<f64>,
    v_half: DMatrix<f64>,
    s: f64,
    pats: Vec<Pattern>,
}

/// Certificates of the current design (scaled units) for the normalisation of the gain step.
struct Certificates {
    /// P_a − ÂᵀP_aÂ − I ≻ 0.
    p_h2: DMatrix<f64>,
    /// X ≻ B̂ᵀP_aB̂ (tr X bounds the scaled ‖G_2‖²_2).
    x: DMatrix<f64>,
    /// Bounded-real certificate of ‖(zI − Â)^{-1} L Δ‖²_∞ < γ.
    p_brl: DMatrix<f64>,
    gamma: f64,
    /// Common Lyapunov matrix of the stability patterns (0×0 without patterns).
    p_stab: DMatrix<f64>,
}

fn b_hat(sc: &Scaled<'_>, l: &DMatrix<f64>) -> DMatrix<f64> {
    let n = sc.sys.n();
    let left = -(l * &sc.w_half);
    let right = (DMatrix::identity(n, n) - l * &sc.sys.c) * &sc.v_half;
    let mut b = DMatrix::zeros(n, left.ncols() + right.ncols());
    b.columns_mut(0, left.ncols()).copy_from(&left);
    b.columns_mut(left.ncols(), right.ncols()).copy_from(&right);
    b
}

fn sym(m: DMatrix<f64>) -> DMatrix<f64> {
    (&m + m.transpose()) * 0.5
}

/// Bounded-real certificate by policy iteration on the worst-case disturbance w = K e:
/// P solves P = (Â + BK)ᵀP(Â + BK) + Q − γKᵀK with K = (γI − BᵀPB)^{-1}BᵀPÂ, which increases
/// monotonically to the stabilising Riccati solution when γ > ‖Q^{1/2}(zI − Â)^{-1}B‖²_∞.
fn brl_certificate(
    a_hat: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    gamma: f64,
) -> Result<DMatrix<f64>, EventEstError> {
    let mut p = linalg::dlyap(&a_hat.transpose(), q, "bounded-real certificate")?;
    let not_bounded = || EventEstError::Verification {
        condition: "bounded-real certificate: γ > ‖(zI − Â)^{-1}LΔ‖²_∞".into(),
        margin: gamma,
    };
    for _ in 0..100 {
        let s = DMatrix::identity(b.ncols(), b.ncols()) * gamma - b.transpose() * &p * b;
        let chol = s.cholesky().ok_or_else(not_bounded)?;
        let k = chol.solve(&(b.transpose() * &p * a_hat));
        let acl = a_hat + b * &k;
        if spectral_radius(&acl) >= 1.0 {
            return Err(not_bounded());
        }
        let next = sym(linalg::dlyap(
            &acl.transpose(),
            &sym(q - k.transpose() * &k * gamma),
            "bounded-real certificate",
        )?);
        let change = (&next - &p).norm();
        p = next;
        if change <= 1e-13 * p.norm() {
            break;
        }
    }
    Ok(p)
}

impl Scaled<'_> {
    /// Certificates of (L, Δ_s) with relative interior margin η.
    fn certificates(
        &self,
        l: &DMatrix<f64>,
        delta_s: &DMatrix<f64>,
        p_stab: DMatrix<f64>,
    ) -> Result<Certificates, EventEstError> {
        let n = self.sys.n();
        let identity = DMatrix::<f64>::identity(n, n);
        let a_hat = (&identity - l * &self.sys.c) * &self.sys.a;
        // Slowed-down dynamics Â/sqrt(1 − η): certificates with slack η P.
        let rho = spectral_radius(&a_hat);
        let eta = ETA * (1.0 - rho * rho).max(0.0);
        let slow = (1.0 - eta).sqrt();
        let q = &identity / (1.0 - eta);
        let p_h2 = sym(linalg::dlyap(
            &(a_hat.transpose() / slow),
            &q,
            "H2 certificate (1 − η)P = ÂᵀPÂ + I",
        )?);
        let bh = b_hat(self, l);
        let x0 = sym(bh.transpose() * &p_h2 * &bh);
        let m = x0.nrows();
        let x = &x0 + DMatrix::identity(m, m) * (ETA * x0.trace() / m as f64);
        let b = l * delta_s;
        let g = hinf_norm(&(&a_hat / slow), &(&b / slow), &q.map(f64::sqrt));
        let mut last = None;
        for attempt in 0..6 {
            let gamma = g * g * (1.0 + 4.0 * ETA) * (1.0 + 10.0 * ETA).powi(attempt);
            match brl_certificate(&(&a_hat / slow), &(&b / slow), &q, gamma) {
                Ok(p_brl) => {
                    return Ok(Certificates {
                        p_h2,
                        x,
                        p_brl,
                        gamma,
                        p_stab,
                    })
                }
                Err(e) => last = Some(e),
            }
        }
        Err(last.unwrap_or(EventEstError::Verification {
            condition: "bounded-real certificate".into(),
            margin: g,
        }))
    }

    /// One gain step at fixed Δ_s: an interior point of the inner approximation intersected with
    /// the level set of the tangent of sqrt(tr X) + sqrt(N_s γ), with L = L_k + D; returns the
    /// new gain and its stability certificate.
    fn gain_step(
        &self,
        l: &DMatrix<f64>,
        delta_s: &DMatrix<f64>,
        cert: &Certificates,
    ) -> Result<(DMatrix<f64>, DMatrix<f64>), EventEstError> {
        let sys = self.sys;
        let (n, p) = (sys.n(), sys.p());
        let identity = DMatrix::<f64>::identity(n, n);
        let nv = self.v_half.ncols();
        let (ra, ra_inv) = sqrt_and_inverse(&cert.p_h2, "H2 certificate")?;
        let (rb, rb_inv) = sqrt_and_inverse(&cert.p_brl, "bounded-real certificate")?;
        let ca = &sys.c * &sys.a;
        let a_hat = (&identity - l * &sys.c) * &sys.a;
        let delta_n = delta_s / cert.gamma.sqrt();
        let mut vars = Vars::default();
        let dv = vars.full(n, p);
        let pa = vars.sym(n);
        let xv = vars.sym(p + nv);
        let pb = vars.sym(n);
        let gv = vars.scalar();
        let ps = (!self.pats.is_empty()).then(|| vars.sym(n));
        let mut prob = Problem::new(vars);
        let ns = (sys.measuring_agents().max(1) as f64).sqrt();
        let two = &identity * 2.0;
        // [[P^{-1}, Â], [*, P − I]] ≻ 0  ⇔  P − ÂᵀPÂ − I ≻ 0.
        {
            let lm = prob.lmi("gain step: H2 Lyapunov inequality (tangent)", 2 * n);
            lm.add_const(0, 0, &two);
            lm.add_sym(pa, 0, -1.0);
            lm.add_const(0, n, &(&ra * &a_hat * &ra_inv));
            lm.add_full_product(Some(&ra), dv, &(&ca * &ra_inv), 0..p, (0, n), -1.0);
            lm.add_sym(pa, n, 1.0);
            lm.add_const(n, n, &-(&ra_inv * &ra_inv));
        }
        // [[P^{-1}, B̂], [*, X]] ≻ 0  ⇔  X ≻ B̂ᵀPB̂,  B̂ = [−L W^½, (I − LC) V^½].
        {
            let lm = prob.lmi("gain step: H2 cost (tangent)", n + p + nv);
            lm.add_const(0, 0, &two);
            lm.add_sym(pa, 0, -1.0);
            lm.add_const(0, n, &(&ra * b_hat(self, l)));
            lm.add_full_product(Some(&ra), dv, &self.w_half, 0..p, (0, n), -1.0);
            lm.add_full_product(
                Some(&ra),
                dv,
                &(&sys.c * &self.v_half),
                0..p,
                (0, n + p),
                -1.0,
            );
            lm.add_sym(xv, n, 1.0);
        }
        // [[P^{-1}, Â, LΔ/√γ_k, 0], [*, P, 0, I], [*, *, γ̃I, 0], [*, *, *, I]] ≻ 0
        // ⇔ ‖(zI − Â)^{-1} L Δ‖²_∞ < γ_k γ̃.
        {
            let lm = prob.lmi("gain step: bounded-real lemma (tangent)", 3 * n + p);
            lm.add_const(0, 0, &two);
            lm.add_sym(pb, 0, -1.0);
            lm.add_const(0, n, &(&rb * &a_hat * &rb_inv));
            lm.add_full_product(Some(&rb), dv, &(&ca * &rb_inv), 0..p, (0, n), -1.0);
            lm.add_const(0, 2 * n, &(&rb * l * &delta_n));
            lm.add_full_product(Some(&rb), dv, &delta_n, 0..p, (0, 2 * n), 1.0);
            lm.add_sym(pb, n, 1.0);
            lm.add_const(n, 2 * n + p, &rb_inv);
            lm.add_scalar_identity(gv, 2 * n, p, 1.0);
            lm.add_const(2 * n + p, 2 * n + p, &identity);
        }
        let stab = match ps {
            Some(psv) => {
                let (rs, rs_inv) = sqrt_and_inverse(&cert.p_stab, "stability certificate")?;
                let c_af = &sys.c * sys.a_cl() * &rs_inv;
                let off = sys.output_offsets();
                for pat in &self.pats {
                    // [[P^{-1}, A_cl], [*, P]] ≻ 0  ⇔  A_clᵀPA_cl − P ≺ 0.
                    let lm = prob.lmi(format!("gain step: {} (tangent)", pat.name), 2 * n);
                    lm.add_const(0, 0, &two);
                    lm.add_sym(psv, 0, -1.0);
                    lm.add_const(0, n, &(&rs * closed_loop(sys, l, pat) * &rs_inv));
                    for m in (0..sys.agents()).filter(|m| pat.subset >> m & 1 == 1) {
                        let w = -pat.weight;
                        lm.add_full_product(Some(&rs), dv, &c_af, off[m]..off[m + 1], (0, n), w);
                    }
                    lm.add_sym(psv, n, 1.0);
                }
                Some((psv, rs))
            }
            None => None,
        };
        // Level set {tangent of sqrt(tr X) + sqrt(N_s γ) ≤ its current value}. The objective is
        // zero, so the solver returns an interior point of the level set (method of centres),
        // whose tangent value, and hence exact bound, is lower. (Minimising the tangent instead
        // drives the solver onto near-degenerate faces of the slow error dynamics.)
        {
            let (wx, wg) = (0.5 / cert.x.trace().sqrt(), 0.5 * ns * cert.gamma.sqrt());
            let level = wx * cert.x.trace() + wg;
            let lm = prob.lmi(LEVEL_SET, 1);
            lm.add_const(0, 0, &DMatrix::from_element(1, 1, level));
            for i in 0..(p + nv) {
                lm.add_entry(xv.index(i, i), 0, 0, -wx);
            }
            lm.add_scalar_identity(gv, 0, 1, -wg);
        }
        // The current design (D = 0, P̃ = I) is strictly feasible: keep it so, with half its
        // slack where that is below the default margin.
        let mut x0 = vec![0.0; prob.vars.len()];
        for i in 0..n {
            x0[pa.index(i, i)] = 1.0;
            x0[pb.index(i, i)] = 1.0;
            if let Some((psv, _)) = &stab {
                x0[psv.index(i, i)] = 1.0;
            }
        }
        for j in 0..(p + nv) {
            for i in 0..=j {
                x0[xv.index(i, j)] = cert.x[(i, j)];
            }
        }
        x0[gv.index(0, 0)] = 1.0;
        for lm in &mut prob.lmis {
            let slack = min_eigenvalue(&lm.evaluate(&x0));
            // The level set passes through the current design.
            if lm.name == LEVEL_SET {
                continue;
            }
            if slack.is_nan() || slack <= 0.0 {
                return Err(EventEstError::Verification {
                    condition: format!("current design strictly feasible in {}", lm.name),
                    margin: slack,
                });
            }
            lm.set_margin(EPS.min(0.5 * slack));
        }
        let sol = prob.solve("gain step of the alternation", EPS)?;
        let l_new = l + dv.value(&sol.x);
        let p_stab = match stab {
            Some((psv, rs)) => &rs * psv.value(&sol.x) * &rs,
            None => DMatrix::zeros(0, 0),
        };
        Ok((l_new, p_stab))
    }
}

/// Step 1/Step 2 alternation (Section 6.3): maximise Σ tr Δ_i subject to the certified bound
/// sqrt(N_s)‖G_1‖_∞ + ‖G_2‖_2 ≤ J_max, alternating
/// (i) gains with Δ fixed: the convex–concave SDP of the module documentation, which lowers the
///     exact bound at the current Δ; the step L_k + θ(L' − L_k) is accepted for the largest
///     θ ∈ {1, 1/2, …, 1/64} whose interpolated stability certificate passes the eigenvalue test
///     and whose exact bound is lower by at least 1e−7 relative;
/// (ii) thresholds with L fixed: Step 2 on the budget J_max − ‖G_2(L)‖_2. The previous Δ is
///     feasible there (its bound dropped in (i)), so Σ tr Δ_i increases.
///
/// Iterate 0 is Step 1 + Step 2 (exact H2 budget). Stops after `max_iter` accepted iterations,
/// when the relative change of Δ is below 1e−4, or when no gain step lowers the bound.
///
/// ```no_run
/// use event_est::alternation::alternate;
/// use event_est::model::platoon;
/// use event_est::synth::Stability;
/// let sys = platoon(3)?.0;
/// let alt = alternate(&sys, Stability::Cor12, 0.38, 20)?;
/// let (first, last) = (&alt.iterates[0], &alt.iterates[alt.iterates.len() - 1]);
/// assert!(last.trace_delta > first.trace_delta && last.bound.bound <= 0.38 * (1.0 + 1e-3));
/// # Ok::<(), event_est::EventEstError>(())
/// ```
pub fn alternate(
    sys: &System,
    stability: Stability,
    j_max: f64,
    max_iter: usize,
) -> Result<Alternation, EventEstError> {
    let pats = patterns(sys, stability)?;
    let kf = kalman(&sys.a, &sys.c, &sys.v(), &sys.w)?;
    let s = 1.0 / kf.posterior.trace();
    let scaled = Scaled {
        sys,
        w_half: sys.w_sqrt()? * s.sqrt(),
        v_half: &sys.v_sqrt * s.sqrt(),
        s,
        pats,
    };
    let start = step1(sys, stability)?;
    let mut iterates = vec![threshold_iterate(&scaled, start.l, j_max, None, None)?];
    let mut stop = format!("max_iter = {max_iter} reached");
    for _ in 0..max_iter {
        let current = &iterates[iterates.len() - 1];
        let delta_s = delta_block(sys, &current.design.delta) * scaled.s.sqrt();
        let l0 = &current.design.l;
        let step = scaled
            .certificates(l0, &delta_s, current.stability_certificate.clone())
            .and_then(|cert| {
                let result = scaled.gain_step(l0, &delta_s, &cert);
                Ok((result?, cert))
            });
        let ((target, p_target), cert) = match step {
            Ok(v) => v,
            Err(e) => {
                stop = format!("gain step failed: {e}");
                break;
            }
        };
        let accepted = (0..7).find_map(|j| {
            let theta = 0.5f64.powi(j);
            let l = l0 + (&target - l0) * theta;
            let p = &cert.p_stab * (1.0 - theta) + &p_target * theta;
            stability_margins(sys, &l, &scaled.pats, &p).ok()?;
            let design = Design {
                l: l.clone(),
                delta: current.design.delta.clone(),
            };
            let b = analyse(sys, &design).ok()?;
            (b.bound < current.bound.bound * (1.0 - MIN_DECREASE)).then_some((l, b.bound, theta))
        });
        let Some((l, gain_bound, theta)) = accepted else {
            stop = "no gain step lowers the certified bound at the current Δ".into();
            break;
        };
        let next = threshold_iterate(&scaled, l, j_max, Some(gain_bound), Some(theta))?;
        let change = next
            .design
            .delta
            .iter()
            .zip(&current.design.delta)
            .map(|(a, b)| (a - b).norm())
            .sum::<f64>()
            / current.design.delta.iter().map(|d| d.norm()).sum::<f64>();
        iterates.push(next);
        if change < 1e-4 {
            stop = format!("relative change of Δ {change:.2e} < 1e-4");
            break;
        }
    }
    Ok(Alternation { iterates, stop })
}

/// Step 2 on the exact H2 budget J_max − ‖G_2(L)‖_2 for gains `l`, its certified bound and a
/// centred stability certificate.
fn threshold_iterate(
    sc: &Scaled<'_>,
    l: DMatrix<f64>,
    j_max: f64,
    gain_step_bound: Option<f64>,
    step_size: Option<f64>,
) -> Result<Iterate, EventEstError> {
    let sys = sc.sys;
    let (stability_certificate, stability_margins) = stability_certificate(sys, &l, &sc.pats)?;
    let h2 = full_communication_cost(sys, &l)?;
    let (_, design, bound) = certified_thresholds(sys, l, h2, j_max, Solver::Clarabel)?;
    Ok(Iterate {
        trace_delta: design.delta.iter().map(|d| d.trace()).sum(),
        design,
        bound,
        gain_step_bound,
        step_size,
        stability_certificate,
        stability_margins,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn spd(v: &[f64], n: usize, shift: f64) -> DMatrix<f64> {
        let m = DMatrix::from_column_slice(n, n, &v[..n * n]);
        &m * m.transpose() + DMatrix::identity(n, n) * shift
    }

    proptest! {
        /// The tangent 2P_k^{-1} − P_k^{-1} P P_k^{-1} never exceeds P^{-1} (the inner
        /// approximation is conservative) and touches it at P = P_k.
        #[test]
        fn tangent_of_the_inverse_is_a_lower_bound(
            v in proptest::collection::vec(-2.0f64..2.0, 32), shift in 0.05f64..2.0,
        ) {
            let n = 4;
            let p = spd(&v, n, shift);
            let pk = spd(&v[16..], n, shift);
            let pk_inv = pk.clone().try_inverse().unwrap();
            let tangent = &pk_inv * 2.0 - &pk_inv * &p * &pk_inv;
            let gap = p.clone().try_inverse().unwrap() - tangent;
            prop_assert!(min_eigenvalue(&sym(gap)) >= -1e-9 * pk_inv.norm().powi(2) * p.norm());
            let at = &pk_inv * 2.0 - &pk_inv * &pk * &pk_inv;
            prop_assert!((at - &pk_inv).norm() <= 1e-9 * pk_inv.norm());
        }

        /// R = P^{1/2}: R R = P and R R^{-1} = I.
        #[test]
        fn symmetric_square_root(v in proptest::collection::vec(-2.0f64..2.0, 16), shift in 0.01f64..1.0) {
            let p = spd(&v, 4, shift);
            let (r, r_inv) = sqrt_and_inverse(&p, "P").unwrap();
            prop_assert!((&r * &r - &p).norm() <= 1e-9 * p.norm());
            prop_assert!((&r * &r_inv - DMatrix::identity(4, 4)).norm() <= 1e-8);
        }

        /// The policy-iteration certificate satisfies the bounded-real inequality
        /// P − ÂᵀPÂ − Q − ÂᵀPB(γI − BᵀPB)^{-1}BᵀPÂ ⪰ 0 with γI − BᵀPB ≻ 0, for γ above ‖G‖²_∞.
        #[test]
        fn bounded_real_certificate_holds(
            v in proptest::collection::vec(-1.0f64..1.0, 15), rho in 0.2f64..0.95,
        ) {
            let a0 = DMatrix::from_column_slice(3, 3, &v[..9]);
            let r0 = spectral_radius(&a0);
            prop_assume!(r0 > 1e-3);
            let a = a0 * (rho / r0);
            let b = DMatrix::from_column_slice(3, 2, &v[9..15]);
            let q = DMatrix::identity(3, 3);
            let g = hinf_norm(&a, &b, &q);
            let gamma = 1.05 * g * g + 1e-6;
            let p = brl_certificate(&a, &b, &q, gamma).unwrap();
            let s = DMatrix::identity(2, 2) * gamma - b.transpose() * &p * &b;
            prop_assert!(min_eigenvalue(&sym(s.clone())) > 0.0);
            let pb = &p * &b;
            let riccati = &p - a.transpose() * &p * &a - &q
                - a.transpose() * &pb * s.try_inverse().unwrap() * pb.transpose() * &a;
            prop_assert!(min_eigenvalue(&sym(riccati)) >= -1e-8 * p.norm());
        }
    }
}
