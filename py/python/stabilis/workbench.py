"""The model workbench: compare a model with measurements, see where it fails, discover the
missing physical effect, add it and watch the weighted error fall.

>>> import stabilis
>>> wb = stabilis.Workbench()          # the embedded flying-platform dataset
>>> result = wb.discover()
>>> result["found"]
['momentum_drag', 'fan_gyroscopic']

The workbench takes any model: ``stabilis.Workbench(model="plant.toml", data=[...])`` (a
model file, or a :class:`stabilis.Model` of Python callables), or a shipped system by name
(``stabilis.Workbench("cubli", data=[...])`` works on Cubli balancing logs by time-domain
prediction error). A user-defined effect is a :class:`stabilis.Effect`. In nonlinear form
(a nonlinear Python model) ``Effect(name, params, f=f, h=h)`` returns the terms added to the
model's ``f`` and ``h``. In matrix form (a linear model, or any model under
``criterion="frf"``) a Python callable ``func(params, model)`` receives the parameter values
``{name: float}`` and the model's matrices ``{"A", "B", "C", "D"}`` (numpy) and returns the
extra terms ``{"A": dA, ...}`` (same shapes) that are added to them::

    def vz_drag(p, m):
        dA = np.zeros_like(m["A"])
        dA[2, 2] = -p["d"]
        return {"A": dA}

    wb.add(stabilis.Effect("vz_drag", {"d": 0.1}, vz_drag, bounds={"d": (0.0, 50.0)}))
    wb.fit()["steps"][0]["params"]["vz_drag.d"]

A model file with a ``[nonlinear]`` section (``stabilis.Model.from_file``) is fitted and tested
by the one-step prediction error of its extended Kalman predictor in absolute units
(``stabilis.Workbench(..., criterion="time")``, the default for such a file; the constructor's
``criterion="frf"`` uses its linearization; ``discover()`` and the others take no arguments),
which tells dry from viscous friction and sees offsets (the generic ``sensor_bias`` on every
output and ``input_bias`` on every input).

Discovery tries the model's own effects and the generic ones every model gets: ``actuator_lag``
and ``input_delay`` on every input, and with two to four inputs (outputs) a lag on each input
(output) alone, ``actuator_lag_<input>`` (``sensor_lag_<output>``).

Exceptions raised inside the callable reach the caller unchanged; a wrong shape or a
non-finite entry raises ``ValueError`` naming the effect and the matrix.
"""
from . import _stabilis

Workbench = _stabilis.workbench.Workbench
Effect = _stabilis.workbench.Effect
Model = _stabilis.workbench.Model

__all__ = ["Workbench", "Effect", "Model"]
