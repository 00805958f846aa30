"""Accelerometer-only tilt, angular velocity and angular acceleration estimation for a rigid
body rotating about a non-accelerated pivot (Muehlebach and D'Andrea, IEEE TCST 2017).

``Estimator(positions)`` takes the sensor positions (N, 3) in metres relative to the pivot;
``.estimate(m)`` takes one sample (N, 3) or a batch (T, N, 3) of body-frame accelerometer
readings in m/s^2 and returns a dict of arrays (``g``, ``omega``, ``omega_dot``, ...).
``.fisher(omega, omega_dot, g, sigma)`` gives the Fisher information and Cramer-Rao bound,
``optimal_placement(n)`` a D-optimal layout.

>>> import numpy as np
>>> from stabilis.tilt import Estimator, G0
>>> p = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [0.2 / np.sqrt(3)] * 3])
>>> est = Estimator(p)
>>> e = est.estimate(np.tile([0.0, 0.0, G0], (4, 1)))  # at rest, z up
>>> bool(np.allclose(e["g"], [0, 0, -G0]))
True
"""
from ._arrays import real_array, real_scalar

from . import _stabilis

_native = _stabilis.tilt

G0 = _native.G0


class Estimator:
    """Maximum-likelihood estimator for a fixed sensor layout.

    ``q``, ``r``: step sizes (default: the paper's rule q = 1/N, r = r*), ``tol``: relative
    stopping tolerance, ``max_iterations``: budget, ``biases``: calibrated biases (N, 3)
    subtracted from every reading.
    """

    def __init__(self, positions, q=None, r=None, tol=1e-8, max_iterations=10_000, biases=None):
        b = None if biases is None else real_array(biases, "biases")
        self._native = _native.Estimator(
            real_array(positions, "positions"), q, r, tol, max_iterations, b
        )

    @property
    def positions(self):
        """Sensor positions (N, 3)."""
        return self._native.positions

    @property
    def tuning(self):
        """Step sizes and the Theorem-2 certificate: q, r, eigenvalues, spectral_radius, certified."""
        return self._native.tuning

    def estimate(self, measurements):
        """Estimates from one sample (N, 3) or a batch (T, N, 3)."""
        return self._native.estimate(real_array(measurements, "measurements"))

    def least_squares(self, measurements):
        """The baseline linear least-squares method on one sample or a batch."""
        return self._native.least_squares(real_array(measurements, "measurements"))

    def fisher(self, omega, omega_dot, g=(0.0, 0.0, -G0), sigma=1.0):
        """Fisher information and Cramer-Rao bound at one state (parameters omega, omega_dot, n)."""
        return self._native.fisher(
            real_array(omega, "omega").tolist(),
            real_array(omega_dot, "omega_dot").tolist(),
            real_array(g, "g").tolist(),
            real_scalar(sigma, "sigma"),
        )

    def d_criterion(self, g=(0.0, 0.0, -G0)):
        """D-criterion (2.64) of the layout for gravity g in the body frame."""
        return self._native.d_criterion(real_array(g, "g").tolist())

    def __repr__(self):
        return repr(self._native)


def optimal_placement(n):
    """(positions (n, 3), ratio): a D-optimal layout of n >= 4 sensors on the unit sphere and
    its D-criterion as a fraction of the bound (1 for every n from 4 to 20 except 5)."""
    return _native.optimal_placement(int(n))


def d_criterion_bound(n):
    """Upper bound (n g0^2)^3 (2n/3)^6 of the D-criterion over layouts in the unit ball."""
    return _native.d_criterion_bound(int(n))


__all__ = ["Estimator", "optimal_placement", "d_criterion_bound", "G0"]
