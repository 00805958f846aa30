//! Constraint check on [0, ∞) by third-order Taylor bounds (spec/pmpc.md §7.5): a
//! certified "satisfied within ε" or a violation instant, in finitely many O(s²) steps.
//!
//! For the coefficient vector y of g(t_off + τ) = τ(τ)ᵀy the Lagrange remainder gives
//! `b_l(τ) ≤ g ≤ b_u(τ)` with `b_{u,l} = f0 + f1 τ + f2 τ²/2 ± R τ³/6`, `R = c_τ |(Mᵀ)³ y|`.
//! Either a bound proves a violation, or the constraint is certainly satisfied up to the
//! first crossing τ_s of the widened limits, and the origin moves there by the closed-form
//! shift. The tail certificate `c_τ |y| ≤ min(l_u, −l_l) + ε`, or the polynomial one (no lobe
//! beyond can cross a limit, see [`polynomial_tail`]), ends the search.

use super::fmath::{abs, sqrt};
use super::{Row, Settings, Side};
use crate::laguerre::Laguerre;

/// A violation found by the check: instant, side, and signed excess over the limit (> 0).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Violation {
    pub(super) t: f64,
    pub(super) side: Side,
    pub(super) excess: f64,
}

/// Scratch vectors (length s each) for one row check: the walked coefficients, the shift's
/// output, and the polynomial tail's sums.
pub(super) struct Scratch<'a> {
    pub(super) y: &'a mut [f64],
    pub(super) y2: &'a mut [f64],
    pub(super) s_k: &'a mut [f64],
}

/// Result of checking one row.
pub(super) enum RowCheck {
    Satisfied,
    Violated(Violation),
    StepLimit,
}

/// Relative accuracy of the certified step: a step at most this much shorter than the
/// bound allows costs as little in extra steps, and saves Newton iterations.
const ROOT_RTOL: f64 = 1e-4;

/// A point at or just below the smallest positive root of a3 τ³ + a2 τ² + a1 τ + a0 with
/// a0 < 0 < a3, with the polynomial negative on [0, result) (to rounding): the step the check
/// may certify. Newton from the quadratic model at the start of the bracket, then a probe just
/// below a converged iterate, so a step costs a handful of evaluations.
pub(super) fn first_positive_root(a3: f64, a2: f64, a1: f64, a0: f64) -> f64 {
    let p = |t: f64| ((a3 * t + a2) * t + a1) * t + a0;
    let dp = |t: f64| (3.0 * a3 * t + 2.0 * a2) * t + a1;
    // Split (0, ∞) at the positive critical points; p is monotone on each piece.
    let mut cuts = [f64::INFINITY; 2];
    let disc = a2 * a2 - 3.0 * a3 * a1;
    if disc >= 0.0 {
        let sq = sqrt(disc);
        let (r1, r2) = ((-a2 - sq) / (3.0 * a3), (-a2 + sq) / (3.0 * a3));
        let mut k = 0;
        for r in [r1, r2] {
            if r > 0.0 {
                cuts[k] = r;
                k += 1;
            }
        }
    }
    let bound = 1.0 + abs(a0).max(abs(a1)).max(abs(a2)) / a3;
    let mut lo = 0.0;
    let mut hi = bound;
    for c in cuts {
        if c < bound && p(c) >= 0.0 {
            hi = c;
            break;
        }
        if c < bound {
            lo = c;
        }
    }
    // p is increasing on [lo, hi] with p(lo) < 0 <= p(hi). Start at the root of the quadratic
    // Taylor model at lo (below p for τ > lo, so its root is at or beyond p's).
    let (v0, d0, c0) = (p(lo), dp(lo), 6.0 * a3 * lo + 2.0 * a2);
    let q = d0 * d0 - 2.0 * c0 * v0;
    let mut t = if q >= 0.0 {
        lo - 2.0 * v0 / (d0 + sqrt(q))
    } else {
        f64::NAN
    };
    if !(t > lo && t < hi) {
        t = 0.5 * (lo + hi);
    }
    for _ in 0..100 {
        let v = p(t);
        if v < 0.0 {
            lo = t;
        } else {
            hi = t;
        }
        if hi - lo <= ROOT_RTOL * hi {
            break;
        }
        let d = dp(t);
        let step = v / d;
        if v >= 0.0 && d > 0.0 && step <= 0.25 * ROOT_RTOL * t {
            // Converged from above: the probe below it closes the bracket from the other side.
            let probe = t - 2.0 * step - 0.25 * ROOT_RTOL * t;
            if probe > lo && p(probe) < 0.0 {
                lo = probe;
                break;
            }
        }
        let newton = t - step;
        t = if d > 0.0 && newton > lo && newton < hi {
            newton
        } else {
            0.5 * (lo + hi)
        };
    }
    if lo > 0.0 && hi - lo <= ROOT_RTOL * hi {
        lo
    } else {
        hi
    }
}

/// Tail certificate from the polynomial factor: `τ(σ)ᵀy = e^{−x/2} P(x)` with x = 2νσ and
/// `P(x) = sqrt(2ν) Σ_i y_i L_i(x) = Σ_k c_k x^k`, `c_k = sqrt(2ν) (−1)^k S_k / k!`,
/// `S_k = Σ_i C(i, k) y_i`. As `e^{x/2} ≥ Σ_{k<s} (x/2)^k / k!`, the function stays within
/// the widened limits on [0, ∞) if `sqrt(2ν)(−1)^k S_k ≥ (lower − ε)/2^k` and
/// `≤ (upper + ε)/2^k` for every k. This ends the walk once no lobe beyond can cross a limit,
/// where the norm certificate would walk on until the whole function is below ε (the lower
/// limit 0 of a state makes that tail ε). `s_k` is scratch of length s; O(s²) additions.
pub(super) fn polynomial_tail(
    basis: &Laguerre,
    row: Row,
    eps: f64,
    y: &[f64],
    s_k: &mut [f64],
) -> bool {
    let s = basis.dim();
    // Σ_i y_i (1 + z)^i by Horner in (1 + z): coefficient k of z is S_k.
    s_k[..s].fill(0.0);
    for (i, &yi) in y[..s].iter().enumerate().rev() {
        // Multiply by (1 + z) (degree s − 2 − i so far), then add y_i.
        for k in (1..s - i).rev() {
            s_k[k] += s_k[k - 1];
        }
        s_k[0] += yi;
    }
    let c0 = basis.tau0_entry();
    let (lo, up) = (row.lower - eps, row.upper + eps);
    let mut scale = 1.0;
    for (k, &sk) in s_k[..s].iter().enumerate() {
        let c = if k % 2 == 0 { c0 * sk } else { -c0 * sk };
        if c < lo * scale || c > up * scale {
            return false;
        }
        scale *= 0.5;
    }
    true
}

/// Records a violation found by the check: without `scan` it ends the row's check at once
/// (`Some`), with `scan` it replaces `worst` if larger and the walk goes on (`None`).
fn record(scan: bool, worst: &mut Option<Violation>, v: Violation) -> Option<RowCheck> {
    if !scan {
        return Some(RowCheck::Violated(v));
    }
    if worst.is_none_or(|b| v.excess > b.excess) {
        *worst = Some(v);
    }
    None
}

/// Check `row.lower − ε ≤ τ(t)ᵀ w ≤ row.upper + ε` on [0, horizon) (∞ if `None`).
///
/// Without `scan` the check stops at the first violation, which is cheapest when one addition
/// ends the solve. With `scan` it walks on through each violated stretch (stepping while the
/// Taylor bound proves the excess, down to the limit itself, so the steps cannot shrink to
/// nothing at the way out) and reports the most violated instant of the whole row: the
/// exchange then jumps to the worst lobe instead of walking one lobe per check along a
/// nearly saturated arc.
pub(super) fn check_row(
    basis: &Laguerre,
    row: Row,
    w: &[f64],
    settings: &Settings,
    scan: bool,
    sc: &mut Scratch<'_>,
    steps: &mut usize,
) -> RowCheck {
    let (eps, horizon, max_steps) = (
        settings.tolerance,
        settings.horizon,
        settings.max_check_steps,
    );
    let s = basis.dim();
    let c0 = basis.tau0_entry();
    let ctau = basis.sup_norm();
    let (lo, up) = (row.lower, row.upper);
    let tail = up.min(-lo) + eps;
    sc.y[..s].copy_from_slice(&w[..s]);
    let mut t_off = 0.0;
    let mut local = 0;
    let mut worst: Option<Violation> = None;
    let done = |worst: Option<Violation>| worst.map_or(RowCheck::Satisfied, RowCheck::Violated);
    loop {
        if local >= max_steps {
            return RowCheck::StepLimit;
        }
        local += 1;
        *steps += 1;
        let y = &*sc.y;
        let taylor = basis.taylor_data(y);
        let [f0, f1, f2] = taylor.sums.map(|v| c0 * v);
        let here = if f0 > up + 0.5 * eps {
            Some(Violation {
                t: t_off,
                side: Side::Upper,
                excess: f0 - up,
            })
        } else if f0 < lo - 0.5 * eps {
            Some(Violation {
                t: t_off,
                side: Side::Lower,
                excess: lo - f0,
            })
        } else {
            None
        };
        if let Some(v) = here {
            if let Some(found) = record(scan, &mut worst, v) {
                return found;
            }
        } else if ctau * taylor.norm <= tail || polynomial_tail(basis, row, eps, y, sc.s_k) {
            return done(worst);
        }
        let r = ctau * taylor.norm3;
        if r <= 0.0 {
            // g is a quadratic in τ with zero third derivative bound: only for y = 0.
            return done(worst);
        }
        let bl = |t: f64| f0 + f1 * t + 0.5 * f2 * t * t - r * t * t * t / 6.0;
        let bu = |t: f64| f0 + f1 * t + 0.5 * f2 * t * t + r * t * t * t / 6.0;
        let ts = match here {
            // Inside a violated stretch: step to where the bound no longer proves g beyond
            // the limit itself (0.5 ε inside the threshold that flagged it).
            Some(v) if v.side == Side::Upper => {
                first_positive_root(r / 6.0, -0.5 * f2, -f1, up - f0)
            }
            Some(_) => first_positive_root(r / 6.0, 0.5 * f2, f1, f0 - lo),
            None => {
                if up.is_finite() && f1 >= 0.0 {
                    let tu = (f2 + sqrt(f2 * f2 + 2.0 * r * f1)) / r;
                    let v = bl(tu);
                    if v > up + 0.5 * eps {
                        let v = Violation {
                            t: t_off + tu,
                            side: Side::Upper,
                            excess: v - up,
                        };
                        if let Some(found) = record(scan, &mut worst, v) {
                            return found;
                        }
                    }
                }
                if lo.is_finite() && f1 < 0.0 {
                    let tl = (-f2 + sqrt(f2 * f2 - 2.0 * r * f1)) / r;
                    let v = bu(tl);
                    if v < lo - 0.5 * eps {
                        let v = Violation {
                            t: t_off + tl,
                            side: Side::Lower,
                            excess: lo - v,
                        };
                        if let Some(found) = record(scan, &mut worst, v) {
                            return found;
                        }
                    }
                }
                let mut ts = f64::INFINITY;
                if up.is_finite() {
                    ts = ts.min(first_positive_root(r / 6.0, 0.5 * f2, f1, f0 - up - eps));
                }
                if lo.is_finite() {
                    ts = ts.min(first_positive_root(r / 6.0, -0.5 * f2, -f1, lo - eps - f0));
                }
                ts
            }
        };
        if !ts.is_finite() {
            return done(worst);
        }
        if let Some(tc) = horizon {
            if t_off + ts >= tc {
                return done(worst);
            }
        }
        basis.shift(ts, sc.y, sc.y2);
        core::mem::swap(&mut sc.y, &mut sc.y2);
        t_off += ts;
    }
}
