"""Time one MPC step of the quadruple integrator (spec/pmpc.md §8.5) through Python:
stabilis.pmpc against DAQP, OSQP and ProxQP on the condensed discrete-time problem (ZOH,
DARE terminal cost, |u| <= 0.5, x_1 >= 0 at k = 1..N), all in one process and one run.

How each contender is called (the fastest way its Python API allows):
  * stabilis.pmpc: `Controller.step(x)`, warm-started from the previous working set, without
    and with the per-step iteration budgets given by --budget (default 4, 5, 6 and 8; the shifted
    previous plan is applied when a budget runs out; a budgeted controller also caps each row
    check at 100 Taylor steps, and its note gives the work bound stated before the run and the
    number of steps beyond it), for each basis size --s and decay rate --nu.
  * DAQP: one `daqp.Model`, `setup` once, then per step `update(f=, bupper=)` and `solve()`:
    H is factorised once and the working set carries over (hot start). The changed data (f x0
    and the state-bound rows) are computed into preallocated arrays (StepData), for every
    peer. DAQP's own `solve_time` leaves out `update`, which refreshes its LDP form (about
    half its step here).
  * OSQP: one `osqp.OSQP`, `setup` once, per step `update(q=, u=)` and `solve()`; warm start
    from the previous solution (its default), default iteration limit, eps_abs = eps_rel = 1e-6.
  * ProxQP (proxsuite dense): `init` once, per step `update(g=, u=)` and `solve()` warm-started
    from the previous result, default iteration limit, eps_abs = 1e-6.
On a failed solve a discrete controller applies its shifted previous sequence (counted).

Timing is CPU time of the calling thread (time.thread_time_ns) around the step call only,
Python call overhead included for every contender; the first step of every loop is excluded
(set-up / cold start). "Own solve time" is what each solver reports of itself: DAQP's, OSQP's
and ProxQP's `solve_time`, and pmpc's `last_step()["solve_time"]` (the whole Rust step). The
latter runs from caches the Python loop has emptied, DAQP's after its untimed `update` has
filled them (`EVICT=64` of `step_profile` shows the same effect in Rust alone); --evict puts
both in memory.
Trajectory sets: x0 = 0.3*1 for 1000 steps, and 10 starts drawn uniformly from [0, 0.2]^4
(seed 14; --starts N draws N, the first ten the same) for 250 steps each. The plant is exact:
the discrete inputs are held (ZOH), the pmpc input is its continuous plan u(t) = eta_u' tau(t)
over each interval (integrated exactly with the Laguerre generator). J_cl (mean over the starts) = sum_{k>=1} (x'x + u^2)/2 Td at the
samples (spec §8.4); J_int is the same cost integrated over the closed loop (Simpson's rule on
the 0.5 ms grid); the violation is the largest excess over |u| <= 0.5, x_1 >= 0 on that grid.

    .venv/bin/python -m pip install -c scripts/python-constraints.txt daqp osqp proxsuite
    .venv/bin/python py/bench/pmpc_peers.py [--s S ...] [--nu NU ...] [--budget B ...]
                                            [--peers daqp osqp proxqp] [--quick] [--starts N]
                                            [--evict MiB]
    .venv/bin/python py/bench/pmpc_peers.py --scan-nu 0.5 0.7 1.0 1.3 [--s 10 12]
    .venv/bin/python py/bench/pmpc_peers.py --switch-nu 1.3 1.8 [--s 12]
    .venv/bin/python py/bench/pmpc_peers.py --scan-horizons 80 82 83 90 92 93
    .venv/bin/python py/bench/pmpc_peers.py --chain 7
"""
import argparse
import os
import time

# One BLAS thread: the plant simulation's small expm calls otherwise spin worker threads that
# compete with the timed steps on a shared machine.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import scipy.linalg  # noqa: E402

import stabilis  # noqa: E402
from stabilis import pmpc  # noqa: E402

TD = 0.02
NU = 0.7
INF = float("inf")
A = np.diag(np.ones(3), 1)
B = np.array([[0.0], [0.0], [0.0], [1.0]])
GRID = 40  # 0.5 ms
# --evict MiB: an array written between DAQP's `update` and `solve` and before each pmpc step,
# so that both own solve times are measured from memory (the other columns then include it).
EVICT = None


def zoh(a, b, h):
    n, m = b.shape
    e = scipy.linalg.expm(np.block([[a, b], [np.zeros((m, n + m))]]) * h)
    return e[:n, :n], e[:n, n:]


def condensed(ad, bd, horizon):
    """Cost 1/2 U'HU + (F x0)'U; rows g_state U <= -e_state x0 (x_1,k >= 0, k = 1..N)."""
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
    qbar = np.eye(n * horizon)
    qbar[-n:, -n:] = p
    h = su.T @ qbar @ su + np.eye(horizon)
    f = su.T @ qbar @ sx
    sel = np.zeros((horizon, n * horizon))
    for k in range(horizon):
        sel[k, k * n] = 1.0
    return (h + h.T) / 2, f, -sel @ su, -sel @ sx


class Stopped(Exception):
    """A contender that stops its loop at the first failed solve."""


class Discrete:
    """Receding-horizon wrapper: solve, apply U[0], shifted previous sequence on failure (or
    stop the loop there, for a solver that then runs to its iteration limit for seconds)."""

    def __init__(self, solve, horizon, stop_on_failure=False):
        self.solve, self.horizon, self.stop = solve, horizon, stop_on_failure
        self.prev, self.failures, self.inner = None, 0, []

    def step(self, x):
        u, inner = self.solve(x)
        if u is None:
            self.failures += 1
            if self.stop:
                raise Stopped()
            u = np.append(self.prev[1:], 0.0)
        if inner is not None:
            self.inner.append(inner)
        self.prev = u
        return float(u[0])


class StepData:
    """The only data of the condensed problem that change with the state: f x and the upper
    bounds (|u| <= 0.5, then the state rows -e x), recomputed in place each step so that no
    peer pays for building arrays in its timed call."""

    def __init__(self, f, e, x0):
        n = f.shape[0]
        self.f, self.neg_e, self.fx = f, -e, f @ x0
        self.upper = np.concatenate([np.full(n, 0.5), -e @ x0])

    def at(self, x):
        np.matmul(self.f, x, out=self.fx)
        np.matmul(self.neg_e, x, out=self.upper[self.fx.shape[0]:])
        return self.fx, self.upper


def daqp_controller(h, f, g, e, x0):
    import daqp

    n = h.shape[0]
    model = daqp.Model()
    data = StepData(f, e, x0)
    model.setup(h, data.fx, g, data.upper, np.concatenate([np.full(n, -0.5), np.full(n, -1e30)]))

    def solve(x):
        fx, upper = data.at(x)
        model.update(f=fx, bupper=upper)
        if EVICT is not None:
            np.add(EVICT, 1.0, out=EVICT)
        sol, _, flag, info = model.solve()
        return (sol if flag >= 1 else None), info["solve_time"]

    return Discrete(solve, n)


def osqp_controller(h, f, g, e, x0):
    import osqp
    import scipy.sparse as sp

    n = h.shape[0]
    solver = osqp.OSQP()
    data = StepData(f, e, x0)
    solver.setup(sp.csc_matrix(np.triu(h)), data.fx, sp.csc_matrix(np.vstack([np.eye(n), g])),
                 np.concatenate([np.full(n, -0.5), np.full(n, -np.inf)]), data.upper,
                 verbose=False, eps_abs=1e-6, eps_rel=1e-6)

    def solve(x):
        fx, upper = data.at(x)
        solver.update(q=fx, u=upper)
        res = solver.solve()
        ok = res.info.status in ("solved", "solved inaccurate")
        return (np.array(res.x) if ok else None), res.info.solve_time

    return Discrete(solve, n)


def proxqp_controller(h, f, g, e, x0):
    import proxsuite

    n = h.shape[0]
    qp = proxsuite.proxqp.dense.QP(n, 0, 2 * n)
    qp.settings.eps_abs = 1e-6
    qp.settings.verbose = False
    qp.settings.initial_guess = proxsuite.proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
    c = np.vstack([np.eye(n), g])
    lo = np.concatenate([np.full(n, -0.5), np.full(n, -1e20)])
    qp.settings.compute_timings = True
    data = StepData(f, e, x0)
    qp.init(h, data.fx, None, None, c, lo, data.upper)
    qp.solve()  # a previous result must exist before the first warm-started update

    def solve(x):
        fx, upper = data.at(x)
        qp.update(g=fx, u=upper)
        qp.solve()
        ok = qp.results.info.status == proxsuite.proxqp.QPSolverOutput.PROXQP_SOLVED
        return (np.array(qp.results.x) if ok else None), qp.results.info.solve_time * 1e-6

    # From step ~340 of the x0 = 0.3 loop ProxQP reports failures, and once the shifted
    # sequence has been applied its solves run for seconds: its loops stop at the first failure.
    return Discrete(solve, n, stop_on_failure=True)


def laguerre_generator(s, nu):
    return np.tril(np.full((s, s), -2.0 * nu), -1) + np.diag(np.full(s, -nu))


def run_discrete(ctrl, ad, bd, x0, steps, sub):
    """Closed loop on the ZOH plant; `sub` = (A_sub, B_sub) propagates one 0.5 ms sub-step."""
    x, times, cost, viol, integral = x0.copy(), [], 0.0, -INF, 0.0
    for k in range(steps + 1):
        t0 = time.thread_time_ns()
        try:
            u = ctrl.step(x)
        except Stopped:
            return np.array(times[1:]) * 1e-9, (float("nan"), float("nan")), viol
        times.append(time.thread_time_ns() - t0)
        if k >= 1:
            cost += 0.5 * (x @ x + u * u) * TD
        viol = max(viol, abs(u) - 0.5)
        xs, stage = x.copy(), [0.5 * (x @ x + u * u)]
        for _ in range(GRID):
            xs = sub[0] @ xs + sub[1][:, 0] * u
            viol = max(viol, -xs[0])
            stage.append(0.5 * (xs @ xs + u * u))
        if k >= 1:
            integral += simpson(stage)
        x = ad @ x + bd[:, 0] * u
    return np.array(times[1:]) * 1e-9, (cost, integral), viol


def run_pmpc(ctrl, s, x0, steps, a=A, b=B, nu=NU):
    """Closed loop with the continuous plan: (x, tau) evolves by expm([[A, B U], [0, M]] h)."""
    n = a.shape[0]
    x, times, cost, viol, fallbacks, iters, own = x0.copy(), [], 0.0, -INF, 0, [], []
    integral, beyond, bound = 0.0, 0, ctrl.work_bound()
    ctrl.reset()
    for k in range(steps + 1):
        if EVICT is not None:
            np.add(EVICT, 1.0, out=EVICT)
        t0 = time.thread_time_ns()
        u = float(ctrl.step(x)[0])
        times.append(time.thread_time_ns() - t0)
        info = ctrl.last_step()
        fallbacks += info["fallback"]
        iters.append(info["iterations"])
        own.append(info["solve_time"])
        if bound and k >= 1:
            beyond += any(info[key] > limit for key, limit in bound.items())
        if k >= 1:
            cost += 0.5 * (x @ x + u * u) * TD
        x, stage, excess = apply_plan(np.asarray(ctrl.plan)[n * s:], x, s, nu, a, b)
        viol = max(viol, excess)
        if k >= 1:
            integral += simpson(stage)
    return (np.array(times[1:]) * 1e-9, (cost, integral), viol, fallbacks, np.array(iters[1:]),
            np.array(own[1:]), beyond)


def apply_plan(eta_u, x, s, nu, a=A, b=B):
    """One interval of the plant under the continuous plan u(t) = eta_u' tau(t): (x, tau)
    evolves by expm([[A, B eta_u'], [0, M]] h). Returns the state at T_d, the stage cost on the
    GRID sub-steps and the largest excess over |u| <= 0.5 and x_1 >= 0 there."""
    n = a.shape[0]
    aug = np.zeros((n + s, n + s))
    aug[:n, :n] = a
    aug[:n, n:] = b @ eta_u[None, :]
    aug[n:, n:] = laguerre_generator(s, nu)
    e = scipy.linalg.expm(aug * (TD / GRID))
    tau0 = np.full(s, np.sqrt(2 * nu))
    xi = np.concatenate([x, tau0])
    stage, viol = [0.5 * (x @ x + (eta_u @ tau0) ** 2)], -INF
    for _ in range(GRID):
        xi = e @ xi
        ut = eta_u @ xi[n:]
        viol = max(viol, -xi[0], abs(ut) - 0.5)
        stage.append(0.5 * (xi[:n] @ xi[:n] + ut * ut))
    return xi[:n], stage, viol


def run_switched(s, nus, x0, steps):
    """Closed loop of one unbudgeted controller per decay rate in `nus`, all stepped from the
    same state; the plan of least predicted cost is applied. Each step's plan costs at most the
    shifted plan applied before, which lies in its own basis's span, so the value still
    decreases. Returns J_cl, the largest excess and how often each rate was applied."""
    ctrls = [quad_pmpc(s, nu) for nu in nus]
    x, cost, viol, picks = x0.copy(), 0.0, -INF, np.zeros(len(nus), dtype=int)
    for k in range(steps + 1):
        plans = []
        for i, c in enumerate(ctrls):
            u = float(c.step(x)[0])
            plans.append((c.last_step()["cost"], i, u))
        _, i, u = min(plans)
        picks[i] += 1
        if k >= 1:
            cost += 0.5 * (x @ x + u * u) * TD
        x, _, excess = apply_plan(np.asarray(ctrls[i].plan)[4 * s:], x, s, nus[i])
        viol = max(viol, excess)
    return cost, viol, picks


def simpson(values):
    """Composite Simpson's rule over one sample interval on the GRID sub-steps (GRID even)."""
    v = np.asarray(values)
    return (v[0] + v[-1] + 4.0 * v[1:-1:2].sum() + 2.0 * v[2:-1:2].sum()) * TD / GRID / 3.0


def stats(t):
    return np.median(t), t.mean(), np.percentile(t, 99), t.max()


def scan_horizons(horizons):
    """Discrete MPC (DAQP) from x0 = 0.3 for 1000 steps at each horizon: does it stabilize?"""
    ad, bd = zoh(A, B, TD)
    sub = zoh(A, B, TD / GRID)
    x0 = np.full(4, 0.3)
    print("| N | J_cl | failed solves | |x(20 s)| |\n|---|---|---|---|")
    for hz in horizons:
        h, f, g, e = condensed(ad, bd, hz)
        ctrl = daqp_controller(h, f, g, e, x0)
        x = x0.copy()
        for _ in range(STEPS_SCAN + 1):
            x = ad @ x + bd[:, 0] * ctrl.step(x)
        cost = run_discrete(daqp_controller(h, f, g, e, x0), ad, bd, x0, STEPS_SCAN, sub)[1][0]
        print(f"| {hz} | {cost:.4g} | {ctrl.failures} | {np.linalg.norm(x):.2e} |", flush=True)


STEPS_SCAN = 1000


def chain(n, s, horizon):
    """Chain of n integrators from x0 = 0.1*1 (spec §8.6): pmpc (s) against DAQP (horizon)."""
    a = np.diag(np.ones(n - 1), 1)
    b = np.zeros((n, 1))
    b[-1, 0] = 1.0
    x0 = np.full(n, 0.1)
    ad, bd = zoh(a, b, TD)
    sub = zoh(a, b, TD / GRID)
    ctrl = pmpc.Controller(a, b, np.eye(n), np.eye(1), x_bounds=[(0.0, INF)] + [(-INF, INF)] * (n - 1),
                           u_bounds=[(-0.5, 0.5)], nu=NU, s=s, td=TD)
    t, (cost, integral), viol, *_ = run_pmpc(ctrl, s, x0, STEPS_SCAN, a, b)
    print("| controller | variables | median | mean | p99 | max (us) | J_cl | J_int | violation |\n"
          "|---|---|---|---|---|---|---|---|---|")
    print(f"| pmpc s={s} | {(n + 1) * s} | " + " | ".join(f"{1e6 * v:.1f}" for v in stats(t))
          + f" | {cost:.4g} | {integral:.4g} | {viol:.1e} |", flush=True)
    h, f, g, e = condensed(ad, bd, horizon)
    d = daqp_controller(h, f, g, e, x0)
    t, (cost, integral), viol = run_discrete(d, ad, bd, x0, STEPS_SCAN, sub)
    print(f"| daqp N={horizon} | {horizon} (condensed; {(horizon + 1) * n + horizon} sparse) | "
          + " | ".join(f"{1e6 * v:.1f}" for v in stats(t))
          + f" | {cost:.4g} | {integral:.4g} | {viol:.1e} | failures {d.failures}", flush=True)


def trajectory_sets(quick=False, starts=10):
    """(title, starts, steps): x0 = 0.3*1 for 1000 steps, and `starts` starts in [0, 0.2]^4
    (seed 14; the first ten are the benchmark's set, more pool a steadier tail)."""
    sets = [("x0 = 0.3, 1000 steps", [np.full(4, 0.3)], 1000)]
    if not quick:
        rng = np.random.default_rng(14)
        sets.append((f"{starts} starts in [0, 0.2]^4, 250 steps",
                     list(rng.uniform(0, 0.2, (starts, 4))), 250))
    return sets


def quad_pmpc(s, nu, budget=None):
    """A budgeted controller also caps each row check at 100 Taylor steps, as the Rust bench and
    tests do, so that its work bound is finite and small."""
    real_time = {"budget": budget, "max_check_steps": 100} if budget else {}
    return pmpc.Controller(A, B, np.eye(4), np.eye(1), x_bounds=[(0.0, INF)] + [(-INF, INF)] * 3,
                           u_bounds=[(-0.5, 0.5)], nu=nu, s=s, td=TD, **real_time)


def scan_nu(ss, nus):
    """Closed-loop cost of pmpc (unbudgeted) over the basis decay rate nu, on both sets."""
    sets = trajectory_sets()
    print("| s | nu | J_cl x0 = 0.3 | J_int | iterations max | J_cl random | J_int | iterations max |")
    print("|---|---|---|---|---|---|---|---|")
    for s in ss:
        for nu in nus:
            cells = []
            for _, starts, steps in sets:
                try:
                    out = [run_pmpc(quad_pmpc(s, nu), s, x0, steps, nu=nu) for x0 in starts]
                except stabilis.Error as e:
                    # A basis too fast for its size has no feasible plan from the start.
                    cells.append(f"{e} | | ")
                    continue
                cost, integral = np.mean([o[1] for o in out], axis=0)
                cells.append(f"{cost:.4f} | {integral:.4f} | {max(o[4].max() for o in out)}")
            print(f"| {s} | {nu:g} | " + " | ".join(cells) + " |", flush=True)


def switched(ss, nus):
    """J_cl of the least-cost plan over several decay rates per step, on both sets."""
    print("| s | decay rates | J_cl x0 = 0.3 | applied per rate | J_cl random | applied per rate |"
          " max violation |\n|---|---|---|---|---|---|---|")
    for s in ss:
        cells, viol = [], -INF
        for _, starts, steps in trajectory_sets():
            out = [run_switched(s, nus, x0, steps) for x0 in starts]
            viol = max(viol, *(o[1] for o in out))
            picks = sum(o[2] for o in out)
            cells.append(f"{np.mean([o[0] for o in out]):.4f} | {' / '.join(map(str, picks))}")
        print(f"| {s} | {', '.join(f'{nu:g}' for nu in nus)} | " + " | ".join(cells)
              + f" | {viol:.1e} |", flush=True)


def main():
    global EVICT
    ap = argparse.ArgumentParser()
    ap.add_argument("--scan-horizons", type=int, nargs="*", default=None,
                    help="only scan the discrete MPC's stabilizing horizons (e.g. 80 81 82 83 92 93)")
    ap.add_argument("--scan-nu", type=float, nargs="*", default=None,
                    help="only the closed-loop cost of pmpc over these basis decay rates (1/s)")
    ap.add_argument("--switch-nu", type=float, nargs="*", default=None,
                    help="only the closed-loop cost of applying, per step, the least-cost plan "
                         "of one controller per decay rate given (1/s)")
    ap.add_argument("--chain", type=int, default=None,
                    help="only the chain of n integrators: pmpc s = 12 against DAQP N = 450")
    ap.add_argument("--s", type=int, nargs="*", default=[8, 10, 12], help="pmpc basis sizes")
    ap.add_argument("--nu", type=float, nargs="*", default=[NU],
                    help="pmpc basis decay rates (1/s); the thesis's 0.7 by default")
    ap.add_argument("--budget", type=int, nargs="*", default=[4, 5, 6, 8],
                    help="pmpc per-step iteration budgets to run besides the unbudgeted one")
    ap.add_argument("--peers", nargs="*", default=["daqp", "osqp", "proxqp"],
                    choices=["daqp", "osqp", "proxqp"], help="discrete-time contenders to run")
    ap.add_argument("--quick", action="store_true", help="x0 = 0.3 set only")
    ap.add_argument("--starts", type=int, default=10,
                    help="random starts of the second set (the first ten are the benchmark's)")
    ap.add_argument("--evict", type=int, default=0,
                    help="MiB written before each pmpc step and between DAQP's update and solve "
                         "(compare the own solve times only)")
    args = ap.parse_args()
    if args.evict:
        EVICT = np.zeros(args.evict << 17)
    if args.scan_horizons:
        scan_horizons(args.scan_horizons)
        return
    if args.scan_nu:
        scan_nu(args.s, args.scan_nu)
        return
    if args.switch_nu:
        switched(args.s, args.switch_nu)
        return
    if args.chain:
        chain(args.chain, 12, 450)
        return
    ad, bd = zoh(A, B, TD)
    sub = zoh(A, B, TD / GRID)
    problems = {hz: condensed(ad, bd, hz) for hz in (93, 100)}
    makers = {"daqp": daqp_controller, "osqp": osqp_controller, "proxqp": proxqp_controller}
    for title, starts, steps in trajectory_sets(args.quick, args.starts):
        rows = {}
        for s in args.s:
            for nu in args.nu:
                for budget in [None] + args.budget:
                    ctrl = quad_pmpc(s, nu, budget)
                    out = [run_pmpc(ctrl, s, x0, steps, nu=nu) for x0 in starts]
                    t = np.concatenate([o[0] for o in out])
                    it = np.concatenate([o[4] for o in out])
                    own = np.concatenate([o[5] for o in out])
                    name = f"stabilis.pmpc s={s}" + (f" nu={nu:g}" if nu != NU else "") + (
                        f" budget {budget}" if budget else "")
                    note = (f"own solve time median {1e6 * np.median(own):.1f} us; "
                            f"fallbacks {sum(o[3] for o in out)}, iterations "
                            f"median {np.median(it):.0f} max {it.max()}")
                    if budget:
                        bound = ctrl.work_bound()
                        note += (f"; work bound {bound['iterations']} iterations, "
                                 f"{bound['taylor_steps']} Taylor steps, {bound['drops']} drops: "
                                 f"exceeded on {sum(o[6] for o in out)} steps")
                    rows[name] = (t, np.mean([o[1] for o in out], axis=0),
                                  max(o[2] for o in out), note)
        for name in args.peers:
            for hz, (h, f, g, e) in problems.items():
                out, inner, fails = [], [], 0
                for x0 in starts:
                    ctrl = makers[name](h, f, g, e, x0)
                    out.append(run_discrete(ctrl, ad, bd, x0, steps, sub))
                    inner += ctrl.inner[1:]
                    fails += ctrl.failures
                t = np.concatenate([o[0] for o in out])
                note = f"own solve time median {1e6 * np.median(inner):.1f} us; failures {fails}"
                if ctrl.stop and fails:
                    note += f" (loops stopped there; {len(t)} steps timed)"
                rows[f"{name} N={hz}"] = (t, np.mean([o[1] for o in out], axis=0),
                                          max(o[2] for o in out), note)
        print(f"\n{title} (CPU time per step, us)", flush=True)
        print("| controller | median | mean | p99 | max | J_cl | J_int | max violation | note |")
        print("|---|---|---|---|---|---|---|---|---|")
        for name, (t, (cost, integral), viol, note) in rows.items():
            med, mean, p99, mx = (1e6 * v for v in stats(t))
            print(f"| {name} | {med:.1f} | {mean:.1f} | {p99:.1f} | {mx:.1f} | {cost:.3f} | "
                  f"{integral:.3f} | {viol:.1e} | {note} |")


if __name__ == "__main__":
    main()
