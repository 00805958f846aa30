"""Time one MPC step of the quadruple integrator (spec/pmpc.md §8.5) through the Python
binding of stabilis.pmpc against DAQP and OSQP on the condensed discrete-time problem
(horizon N = 100, ZOH, DARE terminal cost, |u| <= 0.5, x_1 >= 0 at k = 1..N).

Each controller runs its own 20 s closed loop; the time per step (mean, median) and the
closed-loop cost sum_{k=1}^{1000} (x'x + u^2)/2 * Td are printed. Python call overhead is
included for every contender.

    .venv/bin/pip install daqp osqp   # the `bench` extra of py/pyproject.toml
    .venv/bin/python py/bench/pmpc_peers.py
"""
import time

import numpy as np
import scipy.linalg
import scipy.sparse

from stabilis import pmpc

TD = 0.02
STEPS = 1000
N = 100
INF = float("inf")
A = np.diag(np.ones(3), 1)
B = np.array([[0.0], [0.0], [0.0], [1.0]])
X0 = np.full(4, 0.3)


def zoh(a, b, h):
    n, m = b.shape
    e = scipy.linalg.expm(np.block([[a, b], [np.zeros((m, n + m))]]) * h)
    return e[:n, :n], e[:n, n:]


def condensed(ad, bd, horizon):
    """Cost 1/2 U'HU + (F x0)'U and rows G U <= lim - E x0 (u box, then x_1 >= 0)."""
    n = ad.shape[0]
    p = scipy.linalg.solve_discrete_are(ad, bd, np.eye(n), np.eye(1))
    sx = np.zeros((n * horizon, n))
    su = np.zeros((n * horizon, horizon))
    powers = [np.eye(n)]
    for k in range(horizon):
        powers.append(ad @ powers[-1])
        sx[k * n:(k + 1) * n] = powers[k + 1]
        for j in range(k + 1):
            su[k * n:(k + 1) * n, j:j + 1] = powers[k - j] @ bd
    qbar = np.kron(np.eye(horizon), np.eye(n))
    qbar[-n:, -n:] = p
    h = su.T @ qbar @ su + np.eye(horizon)
    f = su.T @ qbar @ sx
    sel = np.zeros((horizon, n * horizon))
    for k in range(horizon):
        sel[k, k * n] = 1.0
    g_state = -sel @ su  # -x_1,k <= 0
    e_state = -sel @ sx
    return (h + h.T) / 2, f, g_state, e_state


def closed_loop(step, ad, bd):
    x = X0.copy()
    times, cost = [], 0.0
    for k in range(STEPS + 1):
        t0 = time.perf_counter()
        u = step(x)
        times.append(time.perf_counter() - t0)
        if k >= 1:
            cost += 0.5 * (x @ x + u * u) * TD
        x = ad @ x + bd[:, 0] * u
    return np.array(times), cost


def main():
    ad, bd = zoh(A, B, TD)
    h, f, g_state, e_state = condensed(ad, bd, N)
    results = {}

    # DAQP: simple bounds on U, general rows for the state constraint.
    def daqp_step(x):
        import daqp

        bu = np.concatenate([np.full(N, 0.5), -e_state @ x])
        bl = np.concatenate([np.full(N, -0.5), np.full(N, -1e30)])
        sol, _, flag, _ = daqp.solve(h, f @ x, g_state, bu, bl)
        if flag < 1:
            raise RuntimeError(f"DAQP exit flag {flag}")
        return float(sol[0])

    results["daqp N=100"] = closed_loop(daqp_step, ad, bd)

    import osqp

    a_osqp = scipy.sparse.csc_matrix(np.vstack([np.eye(N), g_state]))
    solver = osqp.OSQP()
    solver.setup(scipy.sparse.csc_matrix(np.triu(h)), f @ X0, a_osqp,
                 np.concatenate([np.full(N, -0.5), np.full(N, -np.inf)]),
                 np.concatenate([np.full(N, 0.5), -e_state @ X0]),
                 verbose=False, eps_abs=1e-6, eps_rel=1e-6, polish=True, max_iter=100000)

    state = {"prev": None, "failures": 0}

    def osqp_step(x):
        # As the Rust baseline: on failure apply the shifted previous sequence and count it.
        solver.update(q=f @ x, u=np.concatenate([np.full(N, 0.5), -e_state @ x]))
        res = solver.solve()
        if res.info.status in ("solved", "solved inaccurate"):
            state["prev"] = np.array(res.x)
        else:
            state["failures"] += 1
            state["prev"] = np.append(state["prev"][1:], 0.0)
        return float(state["prev"][0])

    results["osqp N=100"] = closed_loop(osqp_step, ad, bd)
    print(f"osqp failures (shifted previous sequence applied): {state['failures']}")

    for s in (8, 12):
        ctrl = pmpc.Controller(A, B, np.eye(4), np.eye(1),
                               x_bounds=[(0.0, INF)] + [(-INF, INF)] * 3,
                               u_bounds=[(-0.5, 0.5)], nu=0.7, s=s, td=TD)

        def pmpc_step(x, ctrl=ctrl):
            return float(ctrl.step(x)[0])

        # The parametrized plan is continuous in time; here it is applied as a zero-order
        # hold of u(kTd) on the same ZOH plant as the discrete peers.
        results[f"stabilis.pmpc s={s}"] = closed_loop(pmpc_step, ad, bd)

    print(f"{'controller':24s} {'mean':>10s} {'median':>10s} {'J_cl':>8s}")
    for name, (times, cost) in results.items():
        print(f"{name:24s} {1e6 * times.mean():8.1f}us {1e6 * np.median(times):8.1f}us {cost:8.3f}")


if __name__ == "__main__":
    main()
