"""Distributed event-based state estimation over a lossy broadcast network (Muehlebach and
Trimpe, LMI-based synthesis).

Every agent estimates the full state, reconstructs the plant input from its own estimate and
broadcasts its measurement only when the innovation exceeds its threshold. ``synthesize``
designs the gains L and thresholds delta by two LMI steps on Clarabel; ``simulate`` runs the
networked closed loop and returns communication rates and error power.

>>> from stabilis import event_est
>>> model = event_est.platoon(3)
>>> design = event_est.synthesize(model, j_max=0.38)
>>> round(design["c_star"], 4)
0.0102
>>> run = event_est.simulate(model, design, steps=5000, seed=1)
>>> run["total_rate"] < 0.2
True
"""
import numpy as np

from . import _stabilis

_native = _stabilis.event_est


def platoon(vehicles):
    """The vehicle platoon of the paper (Ts = 20 ms, LQR with Q = I, R = 100 I): a dict with
    A, B, C, F, outputs, inputs (per-agent block sizes), W, V_sqrt (design covariances) and
    noise_output, noise_input (uniform half-widths used in simulation)."""
    return _native.platoon_model(int(vehicles))


def _f64(m):
    return np.asarray(m, dtype=np.float64)


def synthesize(model, j_max=None, condition="cor12"):
    """Gains and thresholds for ``model`` (a dict as returned by :func:`platoon`).

    ``j_max``: bound on the error power (default 37 times the full-communication cost c*);
    ``condition``: inter-agent stability condition, "thm11", "cor12", "cor13" or "none".
    Returns a dict with L, delta (list of per-agent matrices), delta_unit, c_star, true_h2,
    kalman_cost, bound (certified), g1_hinf, status, solve_time, stability_lmis.
    Raises ValueError on bad shapes and stabilis.Error when the LMIs are infeasible.
    """
    return _native.synthesize(
        _f64(model["A"]), _f64(model["B"]), _f64(model["C"]), _f64(model["F"]),
        [int(v) for v in model["outputs"]], [int(v) for v in model["inputs"]],
        _f64(model["W"]), _f64(model["V_sqrt"]),
        None if j_max is None else float(j_max), str(condition),
    )


def simulate(model, design, steps, loss=0.1, x0=None, seed=0, local_update=False,
             communicated_inputs=False, window_start=0, noise=True):
    """Runs the networked closed loop for ``steps`` samples with packet loss ``loss``.

    ``design``: dict with L and delta (e.g. from :func:`synthesize`); ``noise``: use the
    model's uniform noise half-widths. Returns a dict with rates (per agent), total_rate,
    error_power, agent_error_power, max_inter_agent_error, max_state.
    """
    no = model.get("noise_output") if noise else None
    ni = model.get("noise_input") if noise else None
    return _native.simulate(
        _f64(model["A"]), _f64(model["B"]), _f64(model["C"]), _f64(model["F"]),
        [int(v) for v in model["outputs"]], [int(v) for v in model["inputs"]],
        _f64(design["L"]), [_f64(np.atleast_2d(d)) for d in design["delta"]], int(steps),
        float(loss), None if x0 is None else [float(v) for v in x0],
        None if no is None else [float(v) for v in no], None if ni is None else [float(v) for v in ni],
        int(seed), bool(local_update), bool(communicated_inputs), int(window_start),
    )


__all__ = ["platoon", "synthesize", "simulate"]
