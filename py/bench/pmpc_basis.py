"""Does another basis bring the parametrized MPC at s = 12 within 1 % of the discrete MPC at
N = 100 on the quadruple-integrator benchmark (spec/pmpc.md §8.4, x0 = 0.3*1, 1000 steps)?

The spec admits any orthonormal basis with a Hurwitz generator (§3.1, A1/A2). This script
closes the loop with three families of s functions, independently of stabilis.pmpc:
  * lag:S:NU        Laguerre functions (the crate's basis);
  * lqr:S:NU        the four closed-loop modes of the unconstrained LQR (so the unconstrained
                    optimum lies in the span exactly) and S - 4 Laguerre functions at NU;
  * mix:S:NU1,NU2   S/2 Laguerre functions at each of two rates;
  * kau:S:A,W       S Kautz functions of one pole pair -A +- jW (t^k e^{-A t} cos / sin(W t),
                    k < S/2), a cascade of second-order all-pass sections;
  * pre:S:NU        u = -K x + tau(t)' eta with the unconstrained LQR's K and S Laguerre
                    functions: the plan starts from the LQR's, and all S coefficients are free
                    (the other kinds leave S - 4 free after x(0) = x0), so pre:S has the free
                    coefficients of lag:S+4 (its inputs span the four modes and S functions).
A generator M' with start vector b becomes orthonormal through the Cholesky factor L of its
Gram matrix (M' G + G M'^T = -b b^T): M = L^-1 M' L, tau(0) = L^-1 b. The state trajectory
x(t) = Xi tau(t) solves Xi M - A Xi = B eta^T (A and M share no eigenvalue), so the plan's cost
is (|Xi|_Q^2 + |eta|^2) / 2 by orthonormality, and x(0) = Xi tau(0) = x0 are the n equalities.
The constraints |u| <= 0.5 and x_1 >= 0 are imposed on a grid (10 ms to 4 s, 0.1 s to 20 s)
instead of certified in continuous time, and each QP is solved by DAQP from scratch. J_cl is
the sampled cost of §8.4. For pre, the state [x; theta] with theta(t) = e^{M't} eta runs
freely (u = [-K, tau(0)'] [x; theta]), so the cost is a Lyapunov form in (x0, eta) and the
constraint rows are e^{F t}; rows are normalised and near-zero rows dropped (DAQP otherwise
reports spurious infeasibility near the origin). With lag:12:1.8 this gives 12.440 against stabilis.pmpc's 12.439
(`pmpc_peers.py --scan-nu 1.8 --s 12`), and lag:10:1.3 12.465 against 12.462.

    .venv/bin/python py/bench/pmpc_basis.py lag:12:1.8 lqr:12:1.3 mix:12:1.0,3.0 pre:8:1.8
"""
import argparse
from ctypes import c_int

import daqp
import numpy as np
import scipy.linalg as sl

N_STATES, TD, STEPS, U_MAX = 4, 0.02, 1000, 0.5
A = np.diag(np.ones(N_STATES - 1), 1)
B = np.eye(N_STATES)[:, [N_STATES - 1]]
GRID = np.concatenate([np.arange(0.0, 4.0, 0.01), np.arange(4.0, 20.0, 0.1)])


def laguerre(s: int, nu: float) -> tuple[np.ndarray, np.ndarray]:
    """Generator and tau(0) of s Laguerre functions (spec §3.3)."""
    return -nu * np.eye(s) - 2 * nu * np.tril(np.ones((s, s)), -1), np.sqrt(2 * nu) * np.ones(s)


def orthonormal(m: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The orthonormal basis spanning e^{m t} b."""
    chol = np.linalg.cholesky(sl.solve_continuous_lyapunov(m, -np.outer(b, b)))
    inv = np.linalg.inv(chol)
    return inv @ m @ chol, inv @ b


def lqr_gain() -> np.ndarray:
    return B.T @ sl.solve_continuous_are(A, B, np.eye(N_STATES), np.eye(1))


def lqr_modes(s: int, nu: float) -> tuple[np.ndarray, np.ndarray]:
    """The unconstrained LQR's closed-loop modes (real 2x2 blocks for complex pairs) and s - 4
    Laguerre functions."""
    k = lqr_gain()
    blocks, start = [], []
    for e in np.linalg.eigvals(A - B @ k):
        if e.imag > 1e-9:
            blocks.append(np.array([[e.real, e.imag], [-e.imag, e.real]]))
            start += [1.0, 1.0]
        elif abs(e.imag) <= 1e-9:
            blocks.append(np.array([[e.real]]))
            start.append(1.0)
    m, b = laguerre(s - N_STATES, nu)
    return orthonormal(sl.block_diag(*blocks, m), np.concatenate([start, b]))


def two_rates(s: int, rates: list[float]) -> tuple[np.ndarray, np.ndarray]:
    parts = [laguerre(s // len(rates), nu) for nu in rates]
    return orthonormal(sl.block_diag(*(m for m, _ in parts)), np.concatenate([b for _, b in parts]))


def kautz(s: int, decay: float, frequency: float) -> tuple[np.ndarray, np.ndarray]:
    """s Kautz functions of one pole pair -decay +- j frequency: a cascade of s/2 second-order
    all-pass sections (s^2 - p s + q) / (s^2 + p s + q), each in input-normal form, so the
    chain is orthonormal and well conditioned."""
    p, q = 2 * decay, decay**2 + frequency**2
    a = np.array([[0.0, 1.0], [-q, -p]])
    b = np.array([[0.0], [1.0]])
    c = np.array([[0.0, -2 * p]])
    chol = np.linalg.cholesky(sl.solve_continuous_lyapunov(a, -b @ b.T))
    inv = np.linalg.inv(chol)
    a, b, c = inv @ a @ chol, inv @ b, c @ chol
    k = s // 2
    m, start = np.zeros((s, s)), np.zeros(s)
    for i in range(k):
        m[2 * i:2 * i + 2, 2 * i:2 * i + 2] = a
        for j in range(i):
            m[2 * i:2 * i + 2, 2 * j:2 * j + 2] = b @ c  # section i hears u + sum of c x_j
        start[2 * i:2 * i + 2] = b[:, 0]
    return orthonormal(m, start)


def closed_loop(m: np.ndarray, tau0: np.ndarray, x0: np.ndarray) -> str:
    """J_cl of the loop that re-plans every TD and applies u(t) = tau(t)' eta in between, or
    the step where the QP had no solution (a basis too fast for the input bound)."""
    s, n = len(tau0), N_STATES
    # vec(Xi) = S eta, column-major vec, from Xi M - A Xi = B eta'.
    sylvester = np.kron(m.T, np.eye(n)) - np.kron(np.eye(s), A)
    plan = np.linalg.solve(sylvester, np.kron(np.eye(s), B))
    hessian = plan.T @ plan + np.eye(s)
    taus = np.array([sl.expm(m * t) @ tau0 for t in GRID])
    start = np.kron(tau0[None, :], np.eye(n)) @ plan
    x1 = np.array([np.kron(t[None, :], np.eye(n))[0] @ plan for t in taus])
    rows = np.vstack([start, taus, x1])
    sense = np.zeros(len(rows), dtype=c_int)
    sense[:n] = 5  # equality rows
    lower = np.concatenate([np.zeros(n), -U_MAX * np.ones(len(GRID)), np.zeros(len(GRID))])
    upper = np.concatenate([np.zeros(n), U_MAX * np.ones(len(GRID)), 1e30 * np.ones(len(GRID))])
    shift = sl.expm(m * TD) @ tau0
    x, cost = x0.copy(), 0.0
    for k in range(STEPS + 1):
        lower[:n] = upper[:n] = x
        eta, _, flag, _ = daqp.solve(hessian, np.zeros(s), rows, upper, lower, sense)
        if flag < 0:
            return f"no plan at step {k} (DAQP exit flag {flag})"
        if k >= 1:
            cost += 0.5 * (x @ x + (tau0 @ eta) ** 2) * TD
        x = (plan @ eta).reshape(s, n).T @ shift
    return f"{cost:.4f}"


def prestabilized_loop(s: int, nu: float, x0: np.ndarray) -> str:
    """J_cl of the loop that applies u(t) = -K x(t) + tau(t)' eta between re-plans."""
    n = N_STATES
    m, tau0 = laguerre(s, nu)
    k = lqr_gain()
    flow = np.block([[A - B @ k, B @ tau0[None, :]], [np.zeros((s, n)), m.T]])
    output = np.hstack([-k, tau0[None, :]])
    weights = np.vstack([np.hstack([np.eye(n), np.zeros((n, s))]), output])
    cost_form = sl.solve_continuous_lyapunov(flow.T, -weights.T @ weights)
    hessian = np.ascontiguousarray(cost_form[n:, n:])
    cross = np.ascontiguousarray(cost_form[n:, :n])
    maps = [sl.expm(flow * t) for t in GRID]
    rows = np.vstack([np.array([(output @ e)[0] for e in maps]), np.array([e[0] for e in maps])])
    norms = np.linalg.norm(rows[:, n:], axis=1)
    keep = norms > 1e-9
    limits = np.concatenate([U_MAX * np.ones(len(GRID)), np.zeros(len(GRID))])[keep] / norms[keep]
    rows = rows[keep] / norms[keep, None]
    inputs = int(keep[: len(GRID)].sum())
    on_eta, on_x = np.ascontiguousarray(rows[:, n:]), rows[:, :n]
    shift = sl.expm(flow * TD)
    x, cost = x0.copy(), 0.0
    for step in range(STEPS + 1):
        upper = np.where(np.arange(len(rows)) < inputs, limits, 1e30) - on_x @ x
        lower = np.where(np.arange(len(rows)) < inputs, -limits, 0.0) - on_x @ x
        eta, _, flag, _ = daqp.solve(hessian, cross @ x, on_eta, upper, lower,
                                     np.zeros(len(rows), dtype=c_int))
        if flag < 0:
            return f"no plan at step {step} (DAQP exit flag {flag})"
        if step >= 1:
            cost += 0.5 * (x @ x + (output @ np.concatenate([x, eta]))[0] ** 2) * TD
        x = (shift @ np.concatenate([x, eta]))[:n]
    return f"{cost:.4f}"


def basis(spec: str) -> tuple[np.ndarray, np.ndarray]:
    kind, s, rates = spec.split(":")
    s, rates = int(s), [float(r) for r in rates.split(",")]
    if kind == "lag":
        return laguerre(s, rates[0])
    if kind == "lqr":
        return lqr_modes(s, rates[0])
    if kind == "mix":
        return two_rates(s, rates)
    if kind == "kau":
        return kautz(s, *rates)
    raise SystemExit(f"{spec}: the kind must be lag, lqr, mix, kau or pre")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("bases", nargs="+", help="lag:S:NU, lqr:S:NU, mix:S:NU1,NU2, kau:S:A,W or pre:S:NU")
    args = parser.parse_args()
    print("| basis | J_cl, x0 = 0.3 |\n|---|---|")
    x0 = 0.3 * np.ones(N_STATES)
    for spec in args.bases:
        if spec.startswith("pre:"):
            _, s, nu = spec.split(":")
            result = prestabilized_loop(int(s), float(nu), x0)
        else:
            result = closed_loop(*basis(spec), x0)
        print(f"| {spec} | {result} |", flush=True)
