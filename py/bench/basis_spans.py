"""Closed-loop cost of the parametrized MPC on the quadruple integrator for other basis spans
than one Laguerre decay rate: a design aid that tells whether a richer basis is worth a solver.

A span is a list of real decay rates p_1..p_s (repeats allowed), e.g. `1x6,3x6`: six at 1/s and
six at 3/s. Its orthonormal basis (Takenaka-Malmquist functions) has the generator
M = -diag(p) - strictly_lower(tau0 tau0') with tau0_k = sqrt(2 p_k), so M + M' = -tau0 tau0'
(spec/pmpc.md §3.2, F.1) and the Gram matrix is the identity (checked). A single rate repeated s
times is the Laguerre basis of `stabilis.pmpc`, which reproduces that controller's J_cl.

Every step solves the upper-bound problem of spec §4.2 from the measured state with the stage
constraints |u| <= 0.5, x_1 >= 0 sampled on a grid (20 ms to 6 s, 0.1 s to 30 s, tolerance
1e-6) by DAQP (one-shot, in the null space of the equalities). Sampling makes the solve only
nearly recursively feasible: when DAQP reports the sampled problem infeasible the step applies
the shifted previous plan, as the controller does when its budget runs out, and the fallbacks
are counted. The plant follows the plan exactly (x(Td) of the plan); J_cl is the sum of §8.4
over 1000 steps from x0 = 0.3*1, as in `pmpc_peers.py`.

    .venv/bin/python py/bench/basis_spans.py 1.8x12 1x6,3x6 1x4,2.5x8
"""
import argparse
import sys

import daqp
import numpy as np
import scipy.linalg
from ctypes import c_int

TD = 0.02
STEPS = 1000
A = np.diag(np.ones(3), 1)
B = np.array([[0.0], [0.0], [0.0], [1.0]])
N_STATES = 4
TOLERANCE = 1e-6
GRID = np.concatenate([np.arange(0.0, 6.0, 0.02), np.arange(6.0, 30.0, 0.1)])


def parse_span(text):
    """`1x6,3x6` -> [1.0]*6 + [3.0]*6."""
    rates = []
    for part in text.split(","):
        try:
            rate, count = part.split("x")
            rate, count = float(rate), int(count)
        except ValueError:
            raise SystemExit(f"basis_spans: span {text!r}: part {part!r} is not RATExCOUNT")
        if not rate > 0.0 or count < 1:
            raise SystemExit(f"basis_spans: span {text!r}: part {part!r} needs rate > 0, count >= 1")
        rates += [rate] * count
    return rates


def generator(rates):
    """(M, tau0) of the orthonormal basis with these decay rates."""
    p = np.asarray(rates)
    tau0 = np.sqrt(2.0 * p)
    m = -np.tril(np.outer(tau0, tau0), -1) - np.diag(p)
    gram = scipy.linalg.solve_continuous_lyapunov(m, -np.outer(tau0, tau0))
    if np.abs(gram - np.eye(len(p))).max() > 1e-8:
        raise SystemExit(f"basis_spans: rates {rates}: Gram matrix is not the identity")
    return m, tau0


class SampledMpc:
    """The upper-bound problem of one span, its equalities eliminated once."""

    def __init__(self, rates):
        m, self.tau0 = generator(rates)
        s = self.s = len(rates)
        dynamics = np.hstack([np.kron(np.eye(N_STATES), m.T) - np.kron(A, np.eye(s)),
                              -np.kron(B, np.eye(s))])
        self.initial = np.hstack([np.kron(np.eye(N_STATES), self.tau0[None, :]),
                                  np.zeros((N_STATES, s))])
        self.free = scipy.linalg.null_space(dynamics)
        taus = np.array([scipy.linalg.expm(m * t) @ self.tau0 for t in GRID])
        width = (N_STATES + 1) * s
        self.rows = np.zeros((2 * len(GRID), width))
        self.rows[:len(GRID), N_STATES * s:] = taus  # u(t)
        self.rows[len(GRID):, :s] = taus  # x_1(t)
        self.tau_td = scipy.linalg.expm(m * TD) @ self.tau0
        self.shift = scipy.linalg.expm(m * TD).T

    def solve(self, x):
        """The plan from state x, or None if DAQP finds the sampled problem infeasible."""
        c = self.initial @ self.free
        z0 = self.free @ np.linalg.lstsq(c, x, rcond=None)[0]
        z = self.free @ scipy.linalg.null_space(c)
        g = self.rows @ z0
        k = len(GRID)
        upper = np.concatenate([0.5 + TOLERANCE - g[:k], np.full(k, 1e30)])
        lower = np.concatenate([-0.5 - TOLERANCE - g[:k], -TOLERANCE - g[k:]])
        xi, _, flag, _ = daqp.solve(z.T @ z, z.T @ z0, self.rows @ z, upper, lower,
                                    np.zeros(2 * k, dtype=c_int))
        return z0 + z @ xi if flag >= 0 else None

    def shifted(self, plan):
        s = self.s
        return np.concatenate([self.shift @ plan[i * s:(i + 1) * s] for i in range(N_STATES + 1)])


def closed_loop(rates):
    """(J_cl, fallbacks) over STEPS steps from x0 = 0.3*1."""
    mpc = SampledMpc(rates)
    s = mpc.s
    x, cost, fallbacks, plan = np.full(N_STATES, 0.3), 0.0, 0, None
    for k in range(STEPS + 1):
        new = mpc.solve(x)
        if new is None:
            if plan is None:
                return float("nan"), fallbacks
            fallbacks += 1
            new = mpc.shifted(plan)
        plan = new
        u = plan[N_STATES * s:] @ mpc.tau0
        if k >= 1:
            cost += 0.5 * (x @ x + u * u) * TD
        x = np.array([plan[i * s:(i + 1) * s] @ mpc.tau_td for i in range(N_STATES)])
    return cost, fallbacks


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("spans", nargs="+", help="decay rates as RATExCOUNT[,RATExCOUNT...]")
    args = parser.parse_args()
    print("| span | s | J_cl | fallbacks |\n|---|---|---|---|")
    for text in args.spans:
        rates = parse_span(text)
        cost, fallbacks = closed_loop(rates)
        print(f"| {text} | {len(rates)} | {cost:.4f} | {fallbacks} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
