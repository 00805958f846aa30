"""The ducted-fan flying platform (Muehlebach and D'Andrea, "The Flying Platform").

``Model(effects, params)`` is the hover-linear model with switchable physical effects
(``momentum_drag``, ``fan_gyroscopic``, ``actuator_lag``, ``input_delay``), each with named
parameters, units and bounds; ``.state_space()`` and ``.frequency_response(omegas)`` give the
continuous-time matrices and the 6x9 transfer matrix from thrusts (F1x .. F3z) to
(vx vy vz wx wy wz). ``controller()`` is the paper's cascaded controller, ``experiment_design``
the 18 orthogonal multisine experiments, ``simulate`` and ``run_experiments`` the closed loop
into numpy arrays, ``gramian`` and ``optimal_l3`` the controllability design.

>>> import numpy as np
>>> from stabilis.flying_platform import Model
>>> m = Model.augmented()
>>> m.param_names[:2]
['c_alpha1', 'c_alpha2']
>>> a, b = m.hover_matrices()
>>> round(float(a[0, 0]), 4)
-0.8955
>>> m.frequency_response([1.0]).shape
(1, 6, 9)
"""
from ._arrays import real_arguments, real_array, real_scalar
from . import _stabilis

_native = _stabilis.flying_platform

Model = _native.Model
INPUT_NAMES = _native.INPUT_NAMES
OUTPUT_NAMES = _native.OUTPUT_NAMES
LOG_OUTPUT_NAMES = _native.LOG_OUTPUT_NAMES
STATE_NAMES = _native.STATE_NAMES


def effects():
    """The four effects with their parameter declarations (name, unit, lower, upper, default)."""
    return _native.effects()


@real_arguments
def controller(l3=0.079):
    """The cascaded controller's rate loop designed with lever arm ``l3``: gain ``k`` (9, 3),
    Riccati solution ``p``, closed-loop ``poles`` and hover ``trim`` (9,)."""
    return _native.controller(real_scalar(l3, "l3"))


@real_arguments
def experiment_design(seed=0, lambda_=None, periods=10):
    """The 18-experiment design: ``excitation`` (18, samples, 9) in N, ``omegas`` (rad/s),
    ``crest_factors``, ``excited`` input names per experiment. ``lambda_`` is the RMS per
    channel (flap 1, flap 2, vertical); the default keeps the flaps inside their limits."""
    lam = None if lambda_ is None else [real_scalar(v, "lambda_") for v in lambda_]
    return _native.experiment_design(int(seed), lam, int(periods))


def _set(set):
    return None if set is None else [(str(k), real_scalar(v, f"set[{k!r}]"))
                                     for k, v in dict(set).items()]


@real_arguments
def simulate(scenario="hover", duration=20.0, effects="momentum_drag,fan_gyroscopic,input_delay",
             td=0.015, dynamics="linear", noise_free=False, seed=0, log_delay_samples=0,
             set=None, step=None, excitation=None):
    """Closed-loop run (``"hover"``, ``"disturbance"`` or ``"step"``) into numpy arrays:
    ``t``, ``input`` (N, 9), ``output`` (N, 9: vx vy vz wx wy wz roll pitch yaw), ``position``,
    ``true_output``, ``excitation``. ``set`` maps effect parameters to values (``{"tau": 0.07}``);
    ``td`` is the in-loop delay of the ``input_delay`` effect."""
    exc = None if excitation is None else real_array(excitation, "excitation")
    st = None if step is None else [real_scalar(v, "step") for v in step]
    return _native.simulate(scenario, real_scalar(duration, "duration"), effects, real_scalar(td, "td"),
                            dynamics, bool(noise_free), int(seed), int(log_delay_samples), _set(set),
                            st, exc)


@real_arguments
def run_experiments(effects="momentum_drag,fan_gyroscopic,input_delay", td=0.015, dynamics="linear",
                    noise_free=False, seed=0, lambda_=None, periods=10, log_delay_samples=0, set=None):
    """The 18 closed-loop identification experiments: a list of dicts with the arrays of
    ``simulate`` and ``metadata`` (the MCAP ``experiment`` record)."""
    lam = None if lambda_ is None else [real_scalar(v, "lambda_") for v in lambda_]
    return _native.run_experiments(effects, real_scalar(td, "td"), dynamics, bool(noise_free),
                                   int(seed), lam, int(periods), int(log_delay_samples), _set(set))


@real_arguments
def gramian(mass=8.0, i1=0.07, l3=0.17, horizon=1.0):
    """Reachability Gramian ``w`` of the thrust-vectoring subsystem, its ``det`` and the
    closed form ``det_closed_form`` = g0^4 T^18 / 102400 (l3/I1)^12."""
    return _native.gramian(real_scalar(mass, "mass"), real_scalar(i1, "i1"), real_scalar(l3, "l3"),
                          real_scalar(horizon, "horizon"))


@real_arguments
def optimal_l3(i0=0.014, unit_mass=1.2, l1=0.1, delta=0.75, vertical_factor=2.0):
    """Lever arm maximising l3 / I1(l3) (0.16777 m with the paper's numbers)."""
    return _native.optimal_l3(real_scalar(i0, "i0"), real_scalar(unit_mass, "unit_mass"),
                              real_scalar(l1, "l1"), real_scalar(delta, "delta"),
                              real_scalar(vertical_factor, "vertical_factor"))


__all__ = ["Model", "effects", "controller", "experiment_design", "simulate", "run_experiments",
           "gramian", "optimal_l3", "INPUT_NAMES", "OUTPUT_NAMES", "LOG_OUTPUT_NAMES", "STATE_NAMES"]
