"""Closed-loop cost of the parametrized MPC on the quadruple integrator for other basis spans
than one Laguerre decay rate: a design aid that tells whether a richer basis is worth a solver.

A span is a list of decay rates p_1..p_s (repeats allowed), e.g. `1x6,3x6`: six at 1/s and six
at 3/s; a complex rate `1.8+0.5i` stands for the pair 1.8 +- 0.5i (Kautz functions), so
`1.8x10,1.8+0.5ix1` has 12 functions. The Takenaka-Malmquist functions of the rates have the
generator M = -diag(p) - strictly_lower(tau0 tau0^H), tau0_k = sqrt(2 Re p_k), so that
M + M^H = -tau0 tau0^H (spec/pmpc.md §3.2, F.1). For real rates that is the basis; for
conjugate pairs the real basis is the orthonormalized span of the real and imaginary parts
(the nonzero eigenvectors of their Gram matrix). The Gram matrix of the result is checked to be
the identity. A single rate repeated s times is the Laguerre basis of `stabilis.pmpc`, which
reproduces that controller's J_cl.

Every step solves the upper-bound problem of spec §4.2 from the measured state with the stage
constraints |u| <= 0.5, x_1 >= 0 sampled on a grid (20 ms to 6 s, 0.1 s to 30 s, tolerance
1e-6) by DAQP (one-shot, in the null space of the equalities). Sampling makes the solve only
nearly recursively feasible: when DAQP reports the sampled problem infeasible the step applies
the shifted previous plan, as the controller does when its budget runs out, and the fallbacks
are counted. The plant follows the plan exactly (x(Td) of the plan); J_cl is the sum of §8.4
over 1000 steps from x0 = 0.3*1, as in `pmpc_peers.py`.

    .venv/bin/python py/bench/basis_spans.py 1.8x12 1x6,3x6 1.8x10,1.8+0.5ix1
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
    """`1x6,3x6` -> [1]*6 + [3]*6; `2+1ix2` -> [2+1j, 2-1j]*2."""
    rates = []
    for part in text.split(","):
        try:
            rate, count = part.split("x")
            rate, count = complex(rate.replace("i", "j")), int(count)
        except ValueError:
            raise SystemExit(f"basis_spans: span {text!r}: part {part!r} is not RATExCOUNT")
        if not rate.real > 0.0 or count < 1:
            raise SystemExit(f"basis_spans: span {text!r}: part {part!r} needs Re rate > 0, "
                             "count >= 1")
        rates += ([rate, rate.conjugate()] if rate.imag else [rate]) * count
    return rates


def generator(rates):
    """(M, tau0) of the real orthonormal basis spanned by these rates' functions."""
    p = np.asarray(rates, complex)
    s = len(p)
    tau0 = np.sqrt(2.0 * p.real).astype(complex)
    mc = -np.tril(np.outer(tau0, tau0.conj()), -1) - np.diag(p)
    # The real and imaginary parts xi = (Re tau, Im tau) obey xi' = a xi; their span is real.
    a = np.block([[mc.real, -mc.imag], [mc.imag, mc.real]])
    xi0 = np.concatenate([tau0.real, tau0.imag])
    lam, v = np.linalg.eigh(scipy.linalg.solve_continuous_lyapunov(a, -np.outer(xi0, xi0)))
    keep = lam > 1e-9 * lam.max()
    if keep.sum() != s:
        raise SystemExit(f"basis_spans: rates {rates}: the real span has {keep.sum()} functions, "
                         f"not {s} (is every complex rate paired?)")
    v, root = v[:, keep], np.sqrt(lam[keep])
    m = (v.T @ a @ v) * root[None, :] / root[:, None]
    tau = (v.T @ xi0) / root
    gram = scipy.linalg.solve_continuous_lyapunov(m, -np.outer(tau, tau))
    if np.abs(gram - np.eye(s)).max() > 1e-8:
        raise SystemExit(f"basis_spans: rates {rates}: Gram matrix is not the identity")
    return m, tau


class SampledMpc:
    """The upper-bound problem of one span, its equalities eliminated once."""

    def __init__(self, rates):
        m, self.tau0 = generator(rates)
        s = self.s = len(rates)
        dynamics = np.hstack([np.kron(np.eye(N_STATES), m.T) - np.kron(A, np.eye(s)),
                              -np.kron(B, np.eye(s))])
        free = scipy.linalg.null_space(dynamics)
        initial = np.hstack([np.kron(np.eye(N_STATES), self.tau0[None, :]),
                             np.zeros((N_STATES, s))]) @ free
        # Plans are z0(x) + z xi: z0 the least-norm plan through x, z the plans through 0.
        self.particular = free @ np.linalg.pinv(initial)
        self.z = free @ scipy.linalg.null_space(initial)
        taus = np.array([scipy.linalg.expm(m * t) @ self.tau0 for t in GRID])
        self.rows = np.zeros((2 * len(GRID), (N_STATES + 1) * s))
        self.rows[:len(GRID), N_STATES * s:] = taus  # u(t)
        self.rows[len(GRID):, :s] = taus  # x_1(t)
        self.rows_z = self.rows @ self.z
        self.hessian = self.z.T @ self.z
        self.sense = np.zeros(len(self.rows), dtype=c_int)
        step = scipy.linalg.expm(m * TD)
        self.tau_td = step @ self.tau0
        self.shift = step.T

    def solve(self, x):
        """The plan from state x, or None if DAQP finds the sampled problem infeasible."""
        z0 = self.particular @ x
        g = self.rows @ z0
        k = len(GRID)
        upper = np.concatenate([0.5 + TOLERANCE - g[:k], np.full(k, 1e30)])
        lower = np.concatenate([-0.5 - TOLERANCE - g[:k], -TOLERANCE - g[k:]])
        xi, _, flag, _ = daqp.solve(self.hessian, self.z.T @ z0, self.rows_z, upper, lower,
                                    self.sense)
        return z0 + self.z @ xi if flag >= 0 else None

    def shifted(self, plan):
        s = self.s
        return np.concatenate([self.shift @ plan[i * s:(i + 1) * s] for i in range(N_STATES + 1)])


def closed_loop(rates):
    """(J_cl, fallbacks) over STEPS steps from x0 = 0.3*1; J_cl is NaN if the first step has
    no plan (nothing to fall back on)."""
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
    parser.add_argument("spans", nargs="+",
                        help="decay rates as RATExCOUNT[,RATExCOUNT...], RATE real or a+bi")
    args = parser.parse_args()
    print("| span | s | J_cl | fallbacks |\n|---|---|---|---|")
    for text in args.spans:
        rates = parse_span(text)
        cost, fallbacks = closed_loop(rates)
        if np.isnan(cost):
            print(f"| {text} | {len(rates)} | no sampled plan from x0 | - |", flush=True)
        else:
            print(f"| {text} | {len(rates)} | {cost:.4f} | {fallbacks} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
