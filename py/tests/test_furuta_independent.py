"""The workbench on a Furuta pendulum simulated by independent_furuta.py (numpy and scipy only,
no stabilis code): the model file data/furuta.toml is the pendulum's full Lagrangian, its
inertia, mass, motor constant and dampings free.

Under the FRF criterion a nonlinear model is its linearization at the operating point: driven
hard, the true model reads a misfit there, and the verdict says what the time-domain criterion
(the nonlinear model itself) reads. A filter on the pendulum angle, which the time-domain
criterion does not search, is named through the FRF criterion's reading. Every (case, seed) is
its own case.
"""
from __future__ import annotations

import json
from pathlib import Path

import pytest

import independent_furuta as fu
from seeds import campaign_seeds
from test_interop import run_cli

MODEL = Path(__file__).parent / "data" / "furuta.toml"
TIME_READING = ("under the time-domain criterion (--criterion time: the nonlinear model itself) "
                "the same logs read explained")


def run(verb: str, data: Path, tmp: Path, *extra: str) -> dict:
    out = tmp / f"{verb}.json"
    done = run_cli(verb, "--model", str(MODEL), "--data", str(data), "--json", str(out), *extra)
    assert done.returncode == 0, done.stderr
    return json.loads(out.read_text())


@pytest.mark.parametrize("seed", (1, 2, 3))
def test_a_hard_driven_true_model_reads_the_linearizations_misfit_and_the_time_reading(tmp_path,
                                                                                     seed):
    # Measured at 2.5 V rms: cost 21.6-47.6 times the noise (p = 1e-104 .. 1e-179), every seed
    # followed by the time-domain reading, explained with nothing added.
    fu.campaign(tmp_path / "data", seed, amplitude=2.5)
    doc = run("discover", tmp_path / "data", tmp_path, "--criterion", "frf")
    assert doc["unexplained"] is True, doc["verdict_text"]
    assert doc["found"] == [], doc["verdict_text"]
    assert any(TIME_READING in w for w in doc["warnings"]), doc["verdict_text"]


@pytest.mark.parametrize("seed", (1, 2))
def test_a_gently_driven_true_model_reads_explained_under_the_frf_criterion(tmp_path, seed):
    fu.campaign(tmp_path / "data", seed, amplitude=0.5)
    doc = run("discover", tmp_path / "data", tmp_path, "--criterion", "frf")
    assert doc["unexplained"] is False, doc["verdict_text"]
    assert doc["found"] == [], doc["verdict_text"]


@pytest.mark.parametrize("seed", campaign_seeds(1, 2))
def test_a_filter_on_the_pendulum_angle_is_named_through_the_frf_reading(tmp_path, seed):
    # A 4 ms filter on alpha: the time-domain criterion reads a misfit (with a wrong actuator
    # lag tentative) and ends with the FRF criterion's reading, a misfit too but with
    # sensor_lag_alpha (4.02-4.03 ms); fitting it by name gives 3.98-3.99 ms.
    data = tmp_path / "data"
    fu.campaign(data, seed, amplitude=1.5, alpha_filter=0.004)
    doc = run("discover", data, tmp_path)
    assert doc["unexplained"] is True, doc["verdict_text"]
    said = " ".join(doc["warnings"])
    assert "sensor_lag_alpha tentative" in said, doc["verdict_text"]
    assert "`fit --with sensor_lag_alpha`" in said, doc["verdict_text"]
    fit = run("fit", data, tmp_path, "--with", "sensor_lag_alpha")
    tau = fit["steps"][-1]["params"]["tau_alpha"]
    assert abs(tau - 0.004) < 0.02 * 0.004, tau
