"""Parametrized infinite-horizon MPC with Laguerre basis functions (spec/pmpc.md).

``Controller(A, B, Q, R, x_bounds=..., u_bounds=..., nu=0.7, s=12, td=0.02)`` builds the
problem offline; ``step(x)`` returns the input to apply now, warm-started from the previous
step; ``bounds(x0)`` returns the upper bound J_s, the lower bound J~_s and the gap that bounds
the sub-optimality.

Real-time mode: ``budget=B`` stops every step after the first after B outer iterations and
then applies the shifted previous plan; with ``max_check_steps`` (Taylor steps per row check)
``work_bound()`` states the worst-case work of a step before running (iterations, Taylor steps,
added and dropped instants, Newton moves), and ``last_step()`` counts the same work of the
step just taken.

>>> import numpy as np
>>> from stabilis import pmpc
>>> A = np.diag(np.ones(3), 1)
>>> B = np.array([[0.0], [0.0], [0.0], [1.0]])
>>> inf = float("inf")
>>> c = pmpc.Controller(A, B, np.eye(4), np.eye(1), x_bounds=[(0.0, inf)] + [(-inf, inf)] * 3,
...                     u_bounds=[(-0.5, 0.5)])
>>> u = c.step([0.3, 0.3, 0.3, 0.3])
>>> bool(abs(u[0]) <= 0.5 + 1e-6)
True
"""
from . import _stabilis

Controller = _stabilis.pmpc.Controller

__all__ = ["Controller"]
