"""A thrust-vectored hopper from independent_hopper.py (its own simulator, unstable in pitch,
a discrete PID, a low-pass gust): under the time criterion the lateral coefficients, which
the closed-loop logs determine poorly, get standard errors that cover the truth, where the
fixed predictor's were 5-11 times too small; under the FRF criterion a fitted model that the
file's controller cannot stabilise is named, exactly when its closed-loop eigenvalues say so;
the file's own gimbal lag, the same model as the built-in `actuator_lag`, is found, not
left tentative beside its twin; and under the time criterion the built-in lag, which the
selection misses, is added as the one candidate that explains the logs alone."""
from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest
from scipy.linalg import expm

import independent_hopper as ih
from test_interop import stabilis_bin

# Documented values 8-11 % off the simulator's (lg 0.60, Mth 36, Cq 3, Mv 2, Dv 8).
PARAMETERS = """
name = "hopper"
states = ["theta", "q", "v"]
inputs = ["dc"]
outputs = ["q", "theta", "ay"]

[parameters]
m   = { value = 40.0, fixed = true, unit = "kg" }
g   = { value = 9.81, fixed = true, unit = "m/s^2" }
J   = { value = 12.0, fixed = true, unit = "kg m^2" }
lg  = { value = 0.55, min = 0.1, max = 2.0, unit = "m" }
Mth = { value = 40.0, min = 0.0, max = 200.0, unit = "N m/rad" }
Cq  = { value = 3.3, min = 0.0, max = 50.0, unit = "N m s/rad" }
Mv  = { value = 1.8, min = -20.0, max = 20.0, unit = "N s" }
Dv  = { value = 7.2, min = 0.0, max = 100.0, unit = "N s/m" }

[definitions]
T = "m*g"
"""

NONLINEAR = PARAMETERS + """
[nonlinear]
f.theta = "q"
f.q = "(Mth*sin(theta) + Mv*v - Cq*q - T*lg*sin(dc))/J"
f.v = "(T*sin(theta + dc) - Dv*v)/m"
h.q = "q"
h.theta = "theta"
h.ay = "(T*sin(dc) - Dv*v)/m"
operating_point = { theta = 0, q = 0, v = 0, dc = 0 }
"""

LINEAR = PARAMETERS + """
[linear]
A = [[0, 1, 0], ["Mth/J", "-Cq/J", "Mv/J"], ["T/m", 0, "-Dv/m"]]
B = [[0], ["-T*lg/J"], ["T/m"]]
C = [[0, 1, 0], [1, 0, 0], [0, 0, "-Dv/m"]]
D = [[0], [0], ["T/m"]]

[effects.gimbal_lag]
description = "gimbal servo lag: the gimbal angle dg follows the command dc"
parameters = { tau = { value = 0.015, min = 0.0005, max = 0.2, unit = "s" } }
states = ["dg"]
A = { "dg,dg" = "-1/tau", "q,dg" = "-T*lg/J", "v,dg" = "T/m" }
B = { "dg,dc" = "1/tau", "q,dc" = "T*lg/J", "v,dc" = "-T/m" }
C = { "ay,dg" = "T/m" }
D = { "ay,dc" = "-T/m" }
"""

# The simulator's PID: xc[k+1] = xc[k] + h theta[k], u[k] = KI xc[k] + KP theta[k] + KD q[k].
CONTROLLER = f"""
[controller]
sample_rate_hz = 100
type = "discrete"
A = [[1.0]]
B = [[0.0, {ih.H}, 0.0]]
C = [[{ih.KI}]]
D = [[{ih.KD}, {ih.KP}, 0.0]]
"""


def discover(tmp_path, text, data, *args):
    model = tmp_path / "hopper.toml"
    model.write_text(text)
    out = tmp_path / "d.json"
    done = subprocess.run([stabilis_bin(), "discover", "--model", str(model), "--data", data,
                           "--json", str(out), *args], capture_output=True, text=True,
                          check=False)
    assert done.returncode == 0, done.stderr
    return json.loads(out.read_text())


def final_params(doc):
    """Name to (value, standard error) of the final model's fitted parameters."""
    last = doc["steps"][-1]
    return {n: (v, last["std"].get(n)) for n, v in last["params"].items()}


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_time_criterion_s_errors_cover_the_poorly_determined_coefficients(tmp_path, seed):
    # Measured: Mv and Dv, fixed-predictor errors 0.06 and 0.15, are widened to 0.58 and
    # 1.4-1.5 (the widening's cap, so poorly determined), and every fitted parameter is within
    # 3 of its errors of the truth on 3 of 3 seeds; before, Dv sat 4.3-4.9 and Mv 3.8-5.4
    # errors off.
    data = ih.run(str(tmp_path / "data"), seed, "nominal")
    doc = discover(tmp_path, NONLINEAR + CONTROLLER, data)
    truth = ih.TRUTH
    params = final_params(doc)
    for name in ["lg", "Mth", "Cq", "Mv", "Dv"]:
        value, std = params[name]
        assert abs(value - truth[name]) <= 3.0 * std, (name, value, std, truth[name])
    assert "standard errors widened" in doc["verdict_text"], doc["verdict_text"]
    assert {"Mv", "Dv"} <= set(doc["steps"][-1]["poorly_determined"]), doc["steps"][-1]


def closed_loop_radius(params):
    """The spectral radius of the linearized hopper at `params` under the simulator's PID,
    sampled with a zero-order hold at 100 Hz: computed here, apart from the workbench."""
    m, g, J = 40.0, 9.81, 12.0
    T = m * g
    v = {k: params[k][0] for k in ["lg", "Mth", "Cq", "Mv", "Dv"]}
    a = np.array([[0, 1, 0], [v["Mth"] / J, -v["Cq"] / J, v["Mv"] / J], [T / m, 0, -v["Dv"] / m]])
    b = np.array([[0], [-T * v["lg"] / J], [T / m]])
    h = ih.H
    z = expm(np.block([[a, b], [np.zeros((1, 4))]]) * h)
    ad, bd = z[:3, :3], z[:3, 3:]
    k = np.array([[ih.KP, ih.KD, 0.0]])  # u = KP theta + KD q + KI xc
    loop = np.block([[ad + bd @ k, bd * ih.KI], [np.array([[h, 0, 0]]), np.ones((1, 1))]])
    return max(abs(np.linalg.eigvals(loop)))


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_fitted_model_the_controller_cannot_stabilise_is_named(tmp_path, seed):
    # Measured (FRF criterion, nominal logs): seed 3's fit is unstable with the PID (radius
    # 1.0066 against the truth's 0.9987) beside "explained"; seeds 1 and 2 are stable.
    data = ih.run(str(tmp_path / "data"), seed, "nominal")
    doc = discover(tmp_path, LINEAR + CONTROLLER, data)
    radius = closed_loop_radius(final_params(doc))
    named = "unstable in closed loop with the model file's controller" in doc["verdict_text"]
    assert named == (radius > 1.0), (radius, doc["verdict_text"])


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_files_own_lag_is_found_beside_its_built_in_twin(tmp_path, seed):
    # Before, `gimbal_lag` was tentative on 3 of 3 seeds: "actuator_lag fits these data as
    # well as gimbal_lag (cost +0.0 ...)"; the two fit to the same cost within 1e-7.
    data = ih.run(str(tmp_path / "data"), seed, "lag")
    doc = discover(tmp_path, LINEAR + CONTROLLER, data)
    assert doc["found"] == ["gimbal_lag"], (doc["found"], doc["verdict_text"])
    value, std = final_params(doc)["tau"]
    assert abs(value - ih.TRUTH["tau"]) <= 3.0 * std, (value, std)


def test_the_time_criterion_adds_the_gimbal_lag_the_selection_misses_on_most_seeds(tmp_path):
    # The nonlinear file has no lag of its own: the built-in `actuator_lag` is the candidate.
    # Under the starting model's predictor (the gust taken for white noise) the selection adds
    # nothing; fitted alone under its own predictor it explains the logs. Measured on seeds
    # 1-3: added on 2 and 3 (tau 24.5 ± 0.2 and 24.9 ± 2.3 ms for 25), seed 1 still a misfit
    # (as `fit --with actuator_lag` reads there); before, none of the 3.
    added = []
    for seed in [1, 2, 3]:
        data = ih.run(str(tmp_path / f"data{seed}"), seed, "lag")
        doc = discover(tmp_path, NONLINEAR + CONTROLLER, data)
        if doc["found"] == ["actuator_lag"]:
            value, std = final_params(doc)["tau"]
            assert abs(value - ih.TRUTH["tau"]) <= 3.0 * std, (seed, value, std)
            added.append(seed)
        else:
            assert doc["found"] == [] and doc["unexplained"], (seed, doc["verdict_text"])
    assert len(added) >= 2, added
