"""The Cubli, a reaction-wheel cube that balances on its corner or an edge and jumps up from a face.

Model in generalized momenta, the backstepping balancing controller with the paper's tuning
method, the feedback-linearizing guiding controller, jump-up learning, and ``simulate`` for
closed-loop runs (the same scenarios and defaults as ``stabilis sim cubli``).

>>> import numpy as np
>>> from stabilis import cubli
>>> ctrl = cubli.Backstepping()
>>> up = -cubli.Params().m / np.linalg.norm(cubli.Params().m) * 9.81
>>> bool(np.allclose(ctrl.control(up, np.zeros(3), np.zeros(3)), 0.0))
True
"""
import numpy as np

from . import _stabilis
from . import sim as _sim
from ._arrays import real_arguments

_native = _stabilis.cubli

Params = _native.Params
Backstepping = _native.Backstepping
GuidingController = _native.GuidingController
reduced_derivative = real_arguments(_native.reduced_derivative)
invariants = real_arguments(_native.invariants)
momenta = real_arguments(_native.momenta)
tune = _native.tune  # poles may be complex
admissible_gamma = _native.admissible_gamma  # poles may be complex
nominal_wheel_speeds = real_arguments(_native.nominal_wheel_speeds)
learn_jump = real_arguments(_native.learn_jump)


def _stack(fields, names):
    return np.column_stack([fields[n] for n in names])


def simulate(scenario="balance", duration=5.0, seed=0, out=None, **options):
    """Runs ``stabilis sim cubli --scenario <scenario>`` and returns numpy arrays.

    ``scenario`` is ``"balance"``, ``"disturbance"`` or ``"jump-up"``; further keyword options
    are the command-line options with underscores (``tilt_deg=3``, ``noise=(0, 0, 0)``,
    ``viscous=(1e-5,) * 3``, ``gyro_bias=(0.01, 0, 0)``, ``excitation_rms=0.01``; for
    ``jump-up``: ``jump="corner"`` or ``"edge"``, ``brake_spread=0.01``, ``trials=6``). For the
    edge jump ``inclination`` is the angle about edge e1 from upright on the edge. Writes an
    MCAP log to ``out`` if given. Returns a dict with ``t`` (N,), ``input`` (N, 3) motor torques,
    ``output`` (N, 9) measured ``wx wy wz w1 w2 w3 gx gy gz``, the true ``omega_h``, ``omega_w``,
    ``gravity`` (N, 3), ``quaternion`` (N, 4, w first), ``p_h``, ``p_w`` (N, 3), ``inclination``
    (N,), ``excitation``/``disturbance`` (N, 3) when present, and ``summary``.
    """
    log = _sim.run("cubli", duration, out=out, seed=seed, scenario=scenario, **options)
    t, inputs = log["/cubli/input"]
    _, outputs = log["/cubli/output"]
    _, state = log["/cubli/state"]
    result = {
        "t": t,
        "input": _stack(inputs, ["T1", "T2", "T3"]),
        "output": _stack(outputs, ["wx", "wy", "wz", "w1", "w2", "w3", "gx", "gy", "gz"]),
        "omega_h": _stack(state, ["wx", "wy", "wz"]),
        "omega_w": _stack(state, ["w1", "w2", "w3"]),
        "gravity": _stack(state, ["gx", "gy", "gz"]),
        "quaternion": _stack(state, ["qw", "qx", "qy", "qz"]),
        "p_h": _stack(state, ["phx", "phy", "phz"]),
        "p_w": _stack(state, ["pwx", "pwy", "pwz"]),
        "inclination": state["inclination"],
        "summary": log.summary,
    }
    for topic in ("excitation", "disturbance"):
        name = f"/cubli/{topic}"
        if name in log:
            result[topic] = _stack(log[name][1], ["T1", "T2", "T3"])
    return result


__all__ = [
    "Params",
    "Backstepping",
    "GuidingController",
    "reduced_derivative",
    "invariants",
    "momenta",
    "tune",
    "admissible_gamma",
    "nominal_wheel_speeds",
    "learn_jump",
    "simulate",
]
