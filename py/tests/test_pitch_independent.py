"""An aircraft's pitch axis from independent_pitch.py (its own simulator), described by a
linear model file: a structural mode the gyro sees, offered as an effect with states of its
own, is found with its frequency, damping and gain; a power study of the nominal model,
whose normal acceleration sees the elevator through the feed-through, finds no effect that is
not there; and the time criterion on a nonlinear model file documented 17-20 % off reads the
truth, in calm air and in a low-pass gust."""
from __future__ import annotations

import json
import math
import subprocess

import pytest

import independent_pitch as ip
from test_interop import stabilis_bin

BASE = """
name = "pitch"
states = ["alpha", "q"]
inputs = ["de"]
outputs = ["q", "nz"]

[parameters]                 # documented values 17-20 % off the simulator's
Za = { value = -1.0, max = 0.0, unit = "1/s" }
Ma = { value = 8.0, unit = "1/s^2" }
Mq = { value = -1.8, max = 0.0, unit = "1/s" }
Md = { value = -10.0, unit = "1/s^2" }
Zd = { value = -0.12, unit = "1/s" }
V  = { value = 150.0, fixed = true, unit = "m/s" }

[linear]
A = [["Za", 1], ["Ma", "Mq"]]
B = [["Zd"], ["Md"]]
C = [[0, 1], ["V*Za", 0]]
D = [[0], ["V*Zd"]]
"""

BENDING = """
[effects.bending]
description = "structural mode driven by the elevator, its rate seen by the gyro"
parameters = { wb = { value = 45.0, min = 10.0, max = 150.0, unit = "rad/s" }, zb = { value = 0.05, min = 0.001, max = 0.5 }, kb = { value = 0.3, unit = "rad/s per rad" } }
states = ["eta", "etad"]
A = { "eta,etad" = 1, "etad,eta" = "-wb^2", "etad,etad" = "-2*zb*wb" }
B = { "etad,de" = "kb" }
C = { "q,etad" = 1 }
"""

# The simulator's controller: u[k] = kq q[k-1] - kn nz[k-1] - ki xi[k] + r[k],
# xi[k+1] = xi[k] + T nz[k-1], on the state xc = (q[k-1], nz[k-1], xi[k]).
CONTROLLER = """
[controller]
sample_rate_hz = 100
type = "discrete"
A = [[0, 0, 0], [0, 0, 0], [0, 0.01, 1]]
B = [[1, 0], [0, 1], [0, 0]]
C = [[0.4, -0.02, -0.03]]
D = [[0, 0]]
"""

SHORT = dict(records=2, periods=6, sub=5)  # 2 x 6000 samples at 100 Hz

# The same aircraft in nonlinear form, so that the time criterion is the default.
NONLINEAR = BASE.split("[linear]")[0] + """
[definitions]
alphadot = "Za*alpha + q + Zd*de"

[nonlinear]
f.alpha = "alphadot"
f.q = "Ma*alpha + Mq*q + Md*de"
h.q = "q"
h.nz = "V*(Za*alpha + Zd*de)"
operating_point = { alpha = 0, q = 0, de = 0 }
"""


@pytest.mark.parametrize("seed", [1, 2])
def test_a_structural_mode_offered_with_its_states_is_found(tmp_path, seed):
    data = ip.campaign(str(tmp_path / "data"), seed, "bending", **SHORT)
    model = tmp_path / "pitch.toml"
    model.write_text(BASE + BENDING)
    out = tmp_path / "discover.json"
    done = subprocess.run([stabilis_bin(), "discover", "--model", str(model), "--data", data,
                           "--json", str(out)], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    doc = json.loads(out.read_text())
    assert doc["found"] == ["bending"], doc["verdict_text"]
    last = doc["steps"][-1]
    cfg = ip.CFG
    truth = {"wb": 2 * math.pi * cfg["bend_f"], "zb": cfg["bend_z"],
             "kb": cfg["bend_kb"] * cfg["bend_phi"]}
    for name, want in truth.items():
        got, se = last["params"][name], last["std"][name]
        assert abs(got - want) <= 3 * se, (name, got, se, want)


def test_a_power_study_with_a_feed_through_finds_nothing_that_is_not_there(tmp_path):
    # Before the simulated loops followed the fits' convention for the feed-through, 8 of 10
    # nominal campaigns read a discovery.
    data = ip.campaign(str(tmp_path / "data"), 1, "nominal", **SHORT)
    model = tmp_path / "pitch.toml"
    model.write_text(BASE + CONTROLLER)
    out = tmp_path / "power.json"
    done = subprocess.run([stabilis_bin(), "power", "--model", str(model), "--data", data,
                           "--effect", "actuator_lag", "--values", "0,0.01", "--campaigns", "10",
                           "--json", str(out)], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    doc = json.loads(out.read_text())
    zero, lag = sorted(doc["values"], key=lambda v: v["value"])
    # Nominal level 1 % per campaign: 3 of 10 has a probability below 2e-4 there.
    assert zero["completed"] == 10 and zero["false_discovery_rate"] <= 0.2, zero
    assert zero["unexplained_rate"] <= 0.2, zero
    # A 10 ms lag is found with its size (measured: 10 of 10, mean 9.97 ms).
    assert lag["detection_rate"] >= 0.8, lag
    assert abs(lag["estimate_mean"] - 0.01) < 0.001, lag


@pytest.mark.parametrize("seed", [1, 2, 3])
@pytest.mark.parametrize("case", ["nominal", "lag"])
@pytest.mark.parametrize("gust", [0.0, ip.CFG["gust_rms"]])
def test_the_time_criterion_reaches_the_truth_from_documented_values_far_off(
        tmp_path, seed, case, gust):
    # Before, from the documented values alone, the prediction-error fit stopped at Za 40-50
    # standard errors off in calm air and kept a found servo lag's lift slope 70 off, a misfit
    # on 6 of 6 seeds each; in the low-pass gust the right model read a misfit too, and the
    # lag stayed tentative with Ma 17-21 standard errors off. With the FRF fit as a second
    # start, a refit kept when likelier, and the innovations whitened by their autoregression:
    # calm, seeds 1-6, explained and the lag found on 6 of 6 each, every parameter within 2.1
    # standard errors; gust, seeds 1-4, 4 of 4 each, within 4.0 (tau within 2.8): those
    # standard errors assume innovations the autoregression whitens only approximately.
    data = ip.campaign(str(tmp_path / "data"), seed, case, gust_rms=gust, **SHORT)
    model = tmp_path / "pitch.toml"
    model.write_text(NONLINEAR)
    out = tmp_path / "discover.json"
    done = subprocess.run([stabilis_bin(), "discover", "--model", str(model), "--data", data,
                           "--json", str(out)], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    doc = json.loads(out.read_text())
    assert doc["weighting"].startswith("time-domain prediction error"), doc["weighting"]
    assert doc["found"] == ([] if case == "nominal" else ["actuator_lag"]), doc["verdict_text"]
    assert doc["verdict_text"].startswith("explained"), doc["verdict_text"]
    last = doc["steps"][-1]
    truth = dict(ip.TRUTH, tau=ip.CFG["tau"])
    within = 3.0 if gust == 0.0 else 4.5
    for name, got in last["params"].items():
        if name == "V":
            continue
        se = last["std"][name]
        assert abs(got - truth[name]) <= within * se, (name, got, se, truth[name])
