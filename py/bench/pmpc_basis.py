"""Does another basis bring the parametrized MPC at s = 12 within 1 % of the discrete MPC at
N = 100 on the quadruple-integrator benchmark (spec/pmpc.md §8.4, x0 = 0.3*1, 1000 steps)?

The spec admits any orthonormal basis with a Hurwitz generator (§3.1, A1/A2). This script
closes the loop with three families of s functions, independently of stabilis.pmpc:
  * lag:S:NU        Laguerre functions (the crate's basis);
  * lqr:S:NU        the four closed-loop modes of the unconstrained LQR (so the unconstrained
                    optimum lies in the span exactly) and S - 4 Laguerre functions at NU;
  * mix:S:NU1,NU2   S/2 Laguerre functions at each of two rates.
A generator M' with start vector b becomes orthonormal through the Cholesky factor L of its
Gram matrix (M' G + G M'^T = -b b^T): M = L^-1 M' L, tau(0) = L^-1 b. The state trajectory
x(t) = Xi tau(t) solves Xi M - A Xi = B eta^T (A and M share no eigenvalue), so the plan's cost
is (|Xi|_Q^2 + |eta|^2) / 2 by orthonormality, and x(0) = Xi tau(0) = x0 are the n equalities.
The constraints |u| <= 0.5 and x_1 >= 0 are imposed on a grid (10 ms to 4 s, 0.1 s to 20 s)
instead of certified in continuous time, and each QP is solved by DAQP from scratch. J_cl is
the sampled cost of §8.4. With lag:12:1.8 this gives 12.440 against stabilis.pmpc's 12.439
(`pmpc_peers.py --scan-nu 1.8 --s 12`), and lag:10:1.3 12.465 against 12.462.

    .venv/bin/python py/bench/pmpc_basis.py lag:12:1.8 lqr:12:1.3 mix:12:1.0,3.0
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


def lqr_modes(s: int, nu: float) -> tuple[np.ndarray, np.ndarray]:
    """The unconstrained LQR's closed-loop modes (real 2x2 blocks for complex pairs) and s - 4
    Laguerre functions."""
    k = B.T @ sl.solve_continuous_are(A, B, np.eye(N_STATES), np.eye(1))
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


def basis(spec: str) -> tuple[np.ndarray, np.ndarray]:
    kind, s, rates = spec.split(":")
    s, rates = int(s), [float(r) for r in rates.split(",")]
    if kind == "lag":
        return laguerre(s, rates[0])
    if kind == "lqr":
        return lqr_modes(s, rates[0])
    if kind == "mix":
        return two_rates(s, rates)
    raise SystemExit(f"{spec}: the kind must be lag, lqr or mix")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("bases", nargs="+", help="lag:S:NU, lqr:S:NU or mix:S:NU1,NU2")
    args = parser.parse_args()
    print("| basis | J_cl, x0 = 0.3 |\n|---|---|")
    for spec in args.bases:
        print(f"| {spec} | {closed_loop(*basis(spec), 0.3 * np.ones(N_STATES))} |", flush=True)
