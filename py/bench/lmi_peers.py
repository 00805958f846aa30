"""Peer of benches/benches/event_est.rs: the same Step-1 SDP (Cor 13, H-free, noise scaled to
unit Kalman cost, same margins) written in CVXPY and solved by Clarabel's Python interface,
timed per platoon size (wall time including CVXPY's compilation, and the solver's own time).

    .venv/bin/python py/bench/lmi_peers.py 3 4 6 8
"""
import sys
import time

import cvxpy as cp
import numpy as np
import scipy.linalg as sla

from stabilis import event_est


def sym(m):
    return (m + m.T) / 2


def step1(model):
    a, b, c, f = model["A"], model["B"], model["C"], model["F"]
    w, v_sqrt = model["W"], model["V_sqrt"]
    n, p = a.shape[0], c.shape[0]
    af = a + b @ f
    v = v_sqrt @ v_sqrt.T
    prior = sla.solve_discrete_are(a.T, c.T, v, w)
    gain = prior @ c.T @ np.linalg.inv(c @ prior @ c.T + w)
    post = (np.eye(n) - gain @ c) @ prior
    s = 1.0 / np.trace(post)
    a_kf = (np.eye(n) - gain @ c) @ a
    p_scale = np.linalg.norm(sla.solve_discrete_lyapunov(a_kf.T, np.eye(n)))
    eps, stab_eps = 1e-8, 1e-8 * p_scale
    wh = np.linalg.cholesky(w) * np.sqrt(s)
    vh = v_sqrt * np.sqrt(s)
    nv = vh.shape[1]
    P = cp.Variable((n, n), symmetric=True)
    U = cp.Variable((n, p))
    X = cp.Variable((p + nv, p + nv), symmetric=True)
    cons = [
        sym(cp.bmat([[P, P @ a - U @ c @ a], [(P @ a - U @ c @ a).T, P - np.eye(n)]])) >> eps * np.eye(2 * n),
        sym(cp.bmat([[P, -U @ wh, (P - U @ c) @ vh],
                     [(-U @ wh).T, X[:p, :p], X[:p, p:]],
                     [((P - U @ c) @ vh).T, X[p:, :p], X[p:, p:]]])) >> eps * np.eye(n + p + nv),
        sym(cp.bmat([[P, P @ af], [(P @ af).T, P]])) >> stab_eps * np.eye(2 * n),
    ]
    for m in range(p):
        t = (P - p * U[:, m:m + 1] @ c[m:m + 1, :]) @ af
        cons.append(sym(cp.bmat([[P, t], [t.T, P]])) >> stab_eps * np.eye(2 * n))
    prob = cp.Problem(cp.Minimize(cp.trace(X)), cons)
    t0 = time.perf_counter()
    prob.solve(solver=cp.CLARABEL)
    wall = time.perf_counter() - t0
    L = np.linalg.solve(P.value, U.value)
    return L, np.sqrt(np.trace(X.value) / s), wall, prob.solver_stats.solve_time, prob.status


def main(sizes):
    print("| M | CVXPY + Clarabel Step 1 (wall) | solver time | status | c* |")
    print("|---|---|---|---|---|")
    for m in sizes:
        model = event_est.platoon(m)
        _, c_star, wall, solve, status = step1(model)
        print(f"| {m} | {wall:.2f} s | {solve:.2f} s | {status} | {c_star:.5f} |", flush=True)


if __name__ == "__main__":
    main([int(a) for a in sys.argv[1:]] or [3, 4, 6])
