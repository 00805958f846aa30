"""Rigid-body geometry: the rotation group SO(3), the sphere S2 and the set M of the tilt
estimator.

Every function takes a single item (``(3,)`` vector or ``(3, 3)`` matrix) or a batch
(``(N, 3)`` or ``(N, 3, 3)``) and returns the same layout. Bad shapes and NaN raise
``ValueError``; degenerate input (a zero vector, a matrix that is not a rotation) raises
``stabilis.Error``.

>>> import numpy as np
>>> from stabilis.geometry import so3
>>> r = so3.exp(np.array([0.0, 0.0, np.pi / 2]))
>>> bool(np.allclose(r @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]))
True
"""
from types import SimpleNamespace

from ._arrays import real_array

from . import _stabilis

_native = _stabilis.geometry


def _float_array_input(function):
    """Wraps a native function so that it accepts anything ``numpy.asarray`` does."""

    def call(x, *args, **kwargs):
        return function(real_array(x, function.__name__), *args, **kwargs)

    call.__name__ = function.__name__
    call.__doc__ = function.__doc__
    return call


def _namespace(module, names):
    return SimpleNamespace(**{n: _float_array_input(getattr(module, n)) for n in names})


so3 = _namespace(
    _native.so3,
    [
        "hat",
        "vee",
        "exp",
        "log",
        "euler_zyx",
        "from_euler_zyx",
        "right_jacobian",
        "left_jacobian",
        "right_jacobian_inverse",
        "left_jacobian_inverse",
    ],
)
"""SO(3): hat/vee, exp/log (rotation vectors), ZYX Euler angles (roll, pitch, yaw) with
R = Rz(yaw) Ry(pitch) Rx(roll), and the right/left Jacobians with their inverses."""

s2 = _namespace(_native.s2, ["project", "tangent_projector"])
"""Sphere of radius r (default G0 = 9.81): projection and tangent-space projector."""
s2.G0 = _native.s2.G0

matrix_set = _namespace(_native.matrix_set, ["project", "factors"])
"""The set M = {[w]x^2 + [h]x}: Frobenius projection and the factors (w, h) of the projection."""

__all__ = ["so3", "s2", "matrix_set"]
