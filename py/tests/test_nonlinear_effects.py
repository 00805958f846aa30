"""User effects on a nonlinear Python model (`stabilis.Model(f=, h=, operating_point=)`).

A user trial found a matrix-form `stabilis.Effect` (a callable returning terms added to A, B,
C, D) silently ignored on such a model: the time-domain criterion integrates the nonlinear
model, which the matrix terms do not describe, so discovery never tried the effect and said
no candidate explains the misfit. Every route that gives an effect to the workbench
(`Model(effects=)`, `suspect`, `add`) must now either use it or refuse it by name.

The data come from the independent cart-pole simulator (independent_cartpole.py: numpy/scipy,
no stabilis code); the model is the one test_nonlinear_independent.py writes as callables.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import independent_cartpole as ic
from test_cartpole_independent import python_model
from test_nonlinear_independent import python_cart_pole

B_TRUE = 1.2  # cart viscous friction hidden in the logs, N s/m


@pytest.fixture(scope="module")
def short_viscous(tmp_path_factory):
    """One experiment of 3300 samples with viscous friction on the cart (seed 7)."""
    out = tmp_path_factory.mktemp("short_viscous")
    ic.campaign(out, plant=replace(ic.Plant(), b=B_TRUE), seed=7, experiments=1, periods=3,
                **ic.FRICTION_EXCITATION)
    return out


def matrix_viscous(stabilis):
    """Viscous friction as a matrix-form Effect: -b xdot added to the force on the cart, in
    the linearization at upright (what the user's trial wrote)."""

    def terms(p, m):
        a = np.zeros_like(m["A"])
        a[:, 1] = -p["b"] * m["B"][:, 0]
        return {"A": a}

    return stabilis.Effect("cart_viscous_m", {"b": 0.5}, terms, bounds={"b": (0.0, 20.0)})


MATRIX_REFUSED = r"effect cart_viscous_m: .*A, B, C, D.*nonlinear"


def test_a_matrix_form_effect_on_a_nonlinear_model_is_refused_by_name(short_viscous):
    # Not silently dropped: suspect, add and Model(effects=) each raise a ValueError naming
    # the effect and the way out; under criterion="frf" (the linearization) it is used.
    stabilis = python_model()
    data = [str(short_viscous)]
    wb = stabilis.Workbench(model=python_cart_pole(stabilis), data=data)
    with pytest.raises(ValueError, match=MATRIX_REFUSED):
        wb.suspect(matrix_viscous(stabilis))
    with pytest.raises(ValueError, match=MATRIX_REFUSED):
        wb.add(matrix_viscous(stabilis))
    with pytest.raises(ValueError, match=MATRIX_REFUSED):
        stabilis.Workbench(model=python_cart_pole(stabilis, effects=[matrix_viscous(stabilis)]),
                           data=data)
    frf = stabilis.Workbench(model=python_cart_pole(stabilis), data=data, criterion="frf")
    frf.suspect(matrix_viscous(stabilis))  # the linearization takes matrix terms
