//! Newton moves of the active instants (local reduction of the semi-infinite QP).
//!
//! At a solution every active instant t_j > 0 is a local extremum of its constraint function:
//! besides `v_jᵀw = β_j` also `v_j'ᵀw = 0` (v_j' = σ_j e_k ⊗ Mτ(t_j)). The dual step alone only
//! reaches this by exchanges, adding the refined extremum and dropping the instant next to it,
//! which converges linearly: on the quadruple integrator a pair of nearly coincident instants
//! zig-zags for 10-20 full constraint checks each time a new instant enters. Here Newton's
//! method on the joint system in (λ, t) moves the instants instead; λ and w are then recomputed
//! exactly for the moved instants, and a move is kept only if it raises the cost (the dual
//! method's monotonicity), so the semi-infinite check that ends every solve is unchanged.

use super::fmath::abs;
use super::{seed, Problem, Settings, Stats, Workspace};

/// Cost increase ½ Σ λ_j (v_jᵀw0 − β_j) of the current working set (equalities hold on it).
fn dual_cost(problem: &Problem<'_>, ws: &Workspace<'_>) -> f64 {
    (0..ws.n_active)
        .map(|j| ws.lambda[j] * (ws.v_dot(j, ws.w0) - problem.beta(&ws.active[j])))
        .sum::<f64>()
        * 0.5
}

/// σ_j (block k_j of x) · `dir`, for a direction `dir` of length s.
fn dot_row(ws: &Workspace<'_>, j: usize, dir: &[f64], x: &[f64]) -> f64 {
    let a = ws.active[j];
    let blk = &x[a.row * ws.s..(a.row + 1) * ws.s];
    a.side.sign() * dir.iter().zip(blk).map(|(p, q)| p * q).sum::<f64>()
}

/// Solve the dense `n×n` system `jac · x = rhs` (row-major, stride `n`) in place by Gaussian
/// elimination with partial pivoting; false if it is singular to working precision.
fn solve_dense(jac: &mut [f64], rhs: &mut [f64], n: usize) -> bool {
    let scale = jac[..n * n].iter().fold(0.0f64, |m, v| m.max(abs(*v)));
    if scale == 0.0 {
        return false;
    }
    for c in 0..n {
        let piv = (c..n)
            .max_by(|&a, &b| abs(jac[a * n + c]).total_cmp(&abs(jac[b * n + c])))
            .unwrap_or(c);
        if abs(jac[piv * n + c]) <= 1e-13 * scale {
            return false;
        }
        if piv != c {
            for k in 0..n {
                jac.swap(c * n + k, piv * n + k);
            }
            rhs.swap(c, piv);
        }
        for r in c + 1..n {
            let f = jac[r * n + c] / jac[c * n + c];
            if f != 0.0 {
                for k in c..n {
                    jac[r * n + k] -= f * jac[c * n + k];
                }
                rhs[r] -= f * rhs[c];
            }
        }
    }
    for c in (0..n).rev() {
        let acc = rhs[c] - (c + 1..n).map(|k| jac[c * n + k] * rhs[k]).sum::<f64>();
        rhs[c] = acc / jac[c * n + c];
    }
    true
}

/// Merge the closest pair of instants of one row and side that lie within 0.05/ν of each
/// other into one at their midpoint (a pair that brackets one extremum is what the exchange
/// zig-zags on); true if a pair was merged.
fn merge_closest_pair(problem: &Problem<'_>, ws: &mut Workspace<'_>) -> bool {
    let p = ws.n_active;
    let mut best: Option<(usize, usize, f64)> = None;
    for i in 0..p {
        for j in i + 1..p {
            let (a, b) = (ws.active[i], ws.active[j]);
            let gap = abs(a.t - b.t);
            if a.row == b.row
                && a.side == b.side
                && gap < 0.05 / problem.basis.nu()
                && best.is_none_or(|(_, _, g)| gap < g)
            {
                best = Some((i, j, gap));
            }
        }
    }
    let Some((i, j, _)) = best else {
        return false;
    };
    ws.active[i].t = 0.5 * (ws.active[i].t + ws.active[j].t);
    ws.active.copy_within(j + 1..p, j);
    ws.n_active = p - 1;
    true
}

/// Newton moves of the working set's instants (see module doc), after merging a bracketing
/// pair; the whole move is undone unless it raises the cost.
pub(super) fn polish(
    problem: &Problem<'_>,
    settings: &Settings,
    ws: &mut Workspace<'_>,
    stats: &mut Stats,
) {
    if settings.polish_steps == 0 || ws.n_active == 0 {
        return;
    }
    let before = dual_cost(problem, ws);
    let p0 = ws.n_active;
    ws.save();
    let mut changed = merge_closest_pair(problem, ws);
    if changed {
        seed(problem, settings, ws, stats);
    }
    let floor = before - 1e-12 * (1.0 + abs(before));
    for _ in 0..settings.polish_steps {
        if !newton_step(problem, settings, ws, stats) {
            break;
        }
        changed = true;
        // A step that lowered the cost is undone below: stop moving.
        if dual_cost(problem, ws) < floor {
            break;
        }
    }
    if !changed {
        return;
    }
    if dual_cost(problem, ws) >= floor {
        stats.moves += 1;
    } else {
        ws.restore(p0);
    }
}

/// One Newton step on (λ, t); false if converged or singular (nothing changed).
fn newton_step(
    problem: &Problem<'_>,
    settings: &Settings,
    ws: &mut Workspace<'_>,
    stats: &mut Stats,
) -> bool {
    let (d, s) = (ws.dim, ws.s);
    let basis = problem.basis;
    {
        let p = ws.n_active;
        // Instants at t = 0 stay put (their extremum may be the boundary); g2 < 0 marks a mover.
        let mut worst = 0.0f64;
        for j in 0..p {
            let a = ws.active[j];
            ws.f2[j] = 0.0;
            ws.g2[j] = 0.0;
            if a.t <= 0.0 {
                continue;
            }
            basis.m_apply(
                &ws.taus[j * s..(j + 1) * s],
                &mut ws.dtau[j * s..(j + 1) * s],
            );
            let wk = &ws.w[a.row * s..(a.row + 1) * s];
            basis.mt_apply(wk, ws.d1);
            let dj = &ws.dtau[j * s..(j + 1) * s];
            let f2 = a.side.sign() * dj.iter().zip(wk).map(|(x, y)| x * y).sum::<f64>();
            let g2 = a.side.sign() * dj.iter().zip(ws.d1.iter()).map(|(x, y)| x * y).sum::<f64>();
            // Only a strict local extremum within reach moves; the predicted excess of the
            // extremum over the limit is f2²/(2|g2|).
            if g2 >= 0.0 || abs(f2) > 0.25 / basis.nu() * -g2 {
                continue;
            }
            worst = worst.max(f2 * f2 / (-2.0 * g2));
            ws.f2[j] = f2;
            ws.g2[j] = g2;
        }
        if p == 0 || worst <= 1e-3 * settings.tolerance {
            return false;
        }
        for j in (0..p).filter(|&j| ws.g2[j] < 0.0) {
            let a = ws.active[j];
            problem.phi_v(
                a.row,
                a.side.sign(),
                &ws.dtau[j * s..(j + 1) * s],
                &mut ws.up[j * d..(j + 1) * d],
            );
        }
        // Unknowns (δλ, δt), equations F1_i = v_iᵀw − β_i and F2_i = v_i'ᵀw (or δt_i = 0).
        let n = 2 * p;
        ws.jac[..n * n].fill(0.0);
        for i in 0..p {
            let fixed_i = ws.g2[i] >= 0.0;
            for j in 0..p {
                let uj = &ws.u[j * d..(j + 1) * d];
                ws.jac[i * n + j] = -ws.v_dot(i, uj);
                if !fixed_i {
                    let dir = &ws.dtau[i * s..(i + 1) * s];
                    ws.jac[(p + i) * n + j] = -dot_row(ws, i, dir, uj);
                }
                if ws.g2[j] >= 0.0 {
                    continue;
                }
                let upj = &ws.up[j * d..(j + 1) * d];
                let lam = ws.lambda[j];
                ws.jac[i * n + p + j] = -lam * ws.v_dot(i, upj);
                if !fixed_i {
                    let dir = &ws.dtau[i * s..(i + 1) * s];
                    ws.jac[(p + i) * n + p + j] = -lam * dot_row(ws, i, dir, upj);
                }
            }
            ws.jac[i * n + p + i] += ws.f2[i];
            if fixed_i {
                ws.jac[(p + i) * n + p + i] = 1.0;
            } else {
                ws.jac[(p + i) * n + p + i] += ws.g2[i];
            }
            ws.rhs[i] = -(ws.v_dot(i, ws.w) - problem.beta(&ws.active[i]));
            ws.rhs[p + i] = -ws.f2[i];
        }
        if !solve_dense(ws.jac, ws.rhs, n) {
            return false;
        }
        // Keep the move local: at most a quarter of the basis time scale 1/ν per instant.
        let cap = 0.25 / basis.nu();
        let big = (0..p).fold(0.0f64, |m, j| m.max(abs(ws.rhs[p + j])));
        let damp = if big > cap { cap / big } else { 1.0 };
        for j in 0..p {
            let t = ws.active[j].t + damp * ws.rhs[p + j];
            ws.active[j].t = if t.is_finite() { t.max(0.0) } else { 0.0 };
        }
        seed(problem, settings, ws, stats);
        true
    }
}
