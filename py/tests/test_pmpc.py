"""stabilis.pmpc against the paper's quadruple-integrator numbers and numpy/scipy references."""
import numpy as np
import pytest
import scipy.linalg

import stabilis
from stabilis import pmpc

INF = float("inf")
A = np.diag(np.ones(3), 1)
B = np.array([[0.0], [0.0], [0.0], [1.0]])
X_BOUNDS = [(0.0, INF)] + [(-INF, INF)] * 3
U_BOUNDS = [(-0.5, 0.5)]
X0 = [0.3, 0.3, 0.3, 0.3]


def controller(s=12):
    return pmpc.Controller(A, B, np.eye(4), np.eye(1), x_bounds=X_BOUNDS, u_bounds=U_BOUNDS,
                           nu=0.7, s=s, td=0.02)


def test_bounds_match_the_paper():
    b = controller().bounds(X0)
    assert abs(b["upper"] - 13.953) < 0.01
    assert abs(b["lower"] - 10.910) < 0.02
    assert b["gap"] == pytest.approx(b["upper"] - b["lower"])


def test_closed_loop_against_scipy_plant():
    """Apply u(t) over each interval exactly (scipy expm of the augmented ZOH plant, with the
    plan sampled finely) and check cost, constraints and convergence."""
    c = controller()
    x = np.array(X0)
    cost = 0.0
    sub = 10
    h = 0.02 / sub
    aug = scipy.linalg.expm(np.block([[A, B], [np.zeros((1, 5))]]) * h)
    ad, bd = aug[:4, :4], aug[:4, 4:]
    for k in range(1001):
        u = c.step(x)
        assert abs(u[0]) <= 0.5 + 1e-6
        assert x[0] >= -1e-5
        if k >= 1:
            cost += 0.5 * (x @ x + u[0] ** 2) * 0.02
        # Piecewise-constant approximation of the planned input on a 2 ms grid.
        for i in range(sub):
            ui = c.input_at((i + 0.5) * h)
            x = ad @ x + bd @ ui
    # Spec 8.3 reproduction 12.98 (thesis 13.06); the 2 ms midpoint input adds a little error.
    assert abs(cost - 12.98) < 0.01 * 12.98
    assert np.linalg.norm(x) < 1e-2
    assert c.last_step()["fallback"] is False


def test_first_step_of_a_fast_large_basis_converges():
    """The cold first step at s = 16, nu = 1.8 needed 1002 iterations by first violations and
    failed the default limit of 1000; scanning rows for their worst violation takes about 40.
    The plan is checked on the plant itself (scipy's exact ZOH on a 1 ms grid over 20 s): the
    constraints hold and the integrated cost is the plan's cost."""
    c = pmpc.Controller(A, B, np.eye(4), np.eye(1), x_bounds=X_BOUNDS, u_bounds=U_BOUNDS,
                        nu=1.8, s=16, td=0.02)
    c.step(X0)
    info = c.last_step()
    assert info["fallback"] is False
    assert info["iterations"] <= 60
    h = 1e-3
    aug = scipy.linalg.expm(np.block([[A, B], [np.zeros((1, 5))]]) * h)
    ad, bd = aug[:4, :4], aug[:4, 4:]
    x = np.array(X0)
    cost = 0.0
    for k in range(20000):
        u = c.input_at((k + 0.5) * h)
        assert abs(u[0]) <= 0.5 + 1e-6
        assert x[0] >= -1e-5
        x_next = ad @ x + bd @ u
        cost += 0.5 * (0.5 * (x @ x + x_next @ x_next) + u[0] ** 2) * h
        x = x_next
    # Midpoint input and trapezoidal state on a 1 ms grid (measured: 1.6e-7 relative). The plan
    # decays to 0; open loop, the grid's error integrates up the chain (|x(20 s)| = 1.9e-4).
    assert cost == pytest.approx(info["cost"], rel=1e-5)
    assert np.linalg.norm(x) < 1e-3


def test_solve_time_is_the_rust_step_alone():
    """`last_step()["solve_time"]` times the Rust step: positive, and within the time the Python
    call takes around it (argument conversion and the returned array come on top)."""
    import time

    c = controller(10)
    x = np.array(X0)
    for _ in range(50):
        t0 = time.perf_counter()
        c.step(x)
        outer = time.perf_counter() - t0
        own = c.last_step()["solve_time"]
        assert 0.0 < own <= outer
        x = 0.99 * x


def test_bad_input():
    with pytest.raises(ValueError):
        pmpc.Controller(np.zeros((4, 3)), B, np.eye(4), np.eye(1), u_bounds=U_BOUNDS)
    c = controller()
    with pytest.raises(ValueError):
        c.step([0.1, 0.2])
    with pytest.raises(stabilis.Error):
        c.step([-0.1, 0.0, 0.0, 0.0])


def test_state_is_read_from_arrays_of_any_layout_and_from_sequences():
    """A contiguous float64 array is read in place, everything else as a sequence: each form of
    the same state gives the same input, bit for bit, from a fresh controller."""
    x = np.array([0.3, 0.0, 0.3, 0.0, 0.3, 0.0, 0.3, 0.0])
    forms = [x[::2].copy(), x[::2], list(x[::2]), tuple(x[::2]),
             np.array([0.3, 0.3, 0.3, 0.3], dtype=np.float32)]
    inputs = [controller().step(form)[0] for form in forms]
    assert inputs[0] != 0.0
    assert inputs[:4] == [inputs[0]] * 4
    # float32 0.3 is another state: a close input, not the same one.
    assert inputs[4] == pytest.approx(inputs[0], rel=1e-5)
    c = controller()
    with pytest.raises(ValueError, match="x must be"):
        c.step("0.3")
    with pytest.raises(ValueError, match="x must be"):
        c.step(np.full((2, 2), 0.3))


def test_complex_and_non_numeric_arrays_are_refused_not_truncated():
    # numpy complex values would otherwise reach the solver as their real parts (a
    # ComplexWarning at most); the TypeError names the dtype (pyo3 notes the argument).
    with pytest.raises(TypeError, match="expected real numbers; got dtype complex128") as error:
        pmpc.Controller(A + 0j, B, np.eye(4), np.eye(1), u_bounds=U_BOUNDS)
    assert "while processing 'a'" in error.value.__notes__
    with pytest.raises(TypeError, match="got dtype object"):
        pmpc.Controller(A, B, np.eye(4).astype(object), np.eye(1), u_bounds=U_BOUNDS)
    c = controller()
    with pytest.raises(TypeError, match="x must hold real numbers; got dtype complex128"):
        c.step(np.array(X0) + 1j)
    with pytest.raises(TypeError, match="x must hold real numbers; got dtype complex"):
        c.step([0.3 + 1j, 0.3, 0.3, 0.3])
    with pytest.raises(TypeError, match="expected real numbers; got dtype complex128"):
        c.bounds(np.array(X0) + 0j)


def test_plan_before_the_step_and_huge_sizes_are_refused():
    c = controller()
    c.step(X0)
    with pytest.raises(ValueError, match="t = -1"):
        c.input_at(-1.0)
    with pytest.raises(ValueError, match="t = NaN"):
        c.input_at(float("nan"))
    for s in (5000, 100000):
        with pytest.raises(ValueError, match="too large"):
            controller(s=s)


def test_budget_bounds_every_step_and_keeps_the_constraints():
    """With a per-step budget of 6 iterations (the real-time budget at s = 10) every step after
    the first stays within it (the shifted previous plan is applied when it runs out) and the
    input stays in bounds."""
    c = pmpc.Controller(A, B, np.eye(4), np.eye(1), x_bounds=X_BOUNDS, u_bounds=U_BOUNDS,
                        nu=0.7, s=10, td=0.02, budget=6)
    x = np.array(X0)
    aug = scipy.linalg.expm(np.block([[A, B], [np.zeros((1, 5))]]) * 0.02)
    ad, bd = aug[:4, :4], aug[:4, 4:]
    fallbacks = 0
    for k in range(300):
        u = c.step(x)
        info = c.last_step()
        if k >= 1:
            assert info["iterations"] <= 6
        fallbacks += info["fallback"]
        assert abs(u[0]) <= 0.5 + 1e-6
        x = ad @ x + bd @ u
    assert x[0] >= -1e-5
    assert fallbacks > 0  # the budget binds on this trajectory
    with pytest.raises(ValueError, match="budget"):
        pmpc.Controller(A, B, np.eye(4), np.eye(1), u_bounds=U_BOUNDS, budget=0)


def test_work_bound_holds_on_every_step_of_the_real_time_configuration():
    """s = 10, nu = 1.3, budget 3, 100 Taylor steps per check: the stated bound is the closed
    form of the docs (2 constrained rows, a working set of s - 4 instants, 3 Newton moves per
    addition), and every step after the first stays within it on the x0 = 0.3 loop."""
    c = pmpc.Controller(A, B, np.eye(4), np.eye(1), x_bounds=X_BOUNDS, u_bounds=U_BOUNDS,
                        nu=1.3, s=10, td=0.02, budget=3, max_check_steps=100)
    adds = 3 * 2
    bound = c.work_bound()
    assert bound == {"iterations": 3, "taylor_steps": 3 * 2 * 100, "adds": adds,
                     "drops": (10 - 4) * (1 + adds * (2 + 3)), "moves": adds}
    aug = scipy.linalg.expm(np.block([[A, B], [np.zeros((1, 5))]]) * 0.02)
    ad, bd = aug[:4, :4], aug[:4, 4:]
    x, fallbacks, busiest = np.array(X0), 0, dict.fromkeys(bound, 0)
    for k in range(300):
        u = c.step(x)
        info = c.last_step()
        if k >= 1:
            for key in bound:
                assert info[key] <= bound[key], (k, key, info)
                busiest[key] = max(busiest[key], info[key])
        fallbacks += info["fallback"]
        x = ad @ x + bd @ u
    assert fallbacks > 0 and busiest["iterations"] == 3  # the budget binds
    assert busiest["adds"] > 0 and busiest["drops"] > 0
    assert pmpc.Controller(A, B, np.eye(4), np.eye(1), u_bounds=U_BOUNDS).work_bound() is None
    with pytest.raises(ValueError, match="max_check_steps"):
        pmpc.Controller(A, B, np.eye(4), np.eye(1), u_bounds=U_BOUNDS, max_check_steps=0)
