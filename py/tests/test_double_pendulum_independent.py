"""The time criterion on a plant stabilis does not ship, read through coarse encoders: a double
inverted pendulum on a cart, simulated by independent_double_pendulum.py (numpy and scipy, no
stabilis code; LQR on a Kalman estimate at 200 Hz, links on 4096-count encoders that sit on
one count in 70-80 % of the samples), described by data/double_pendulum.toml. On these logs
the time criterion's verdict is a misfit whether or not something is hidden (README, "Coarsely
quantized outputs"); what the tests ask is that the verdict names why and what the FRF
criterion reads on the same logs, and that a hidden lag, which the selection misses there, is
added as the one candidate that explains the logs alone.
"""
from __future__ import annotations

from pathlib import Path

import pytest

import independent_double_pendulum as dp
from test_interop import discover_model_file

MODEL = Path(__file__).parent / "data" / "double_pendulum.toml"


def discover(tmp: Path, case: str, seed: int = 1) -> dict:
    return discover_model_file(MODEL, dp.campaign(tmp / "data", seed, case), tmp)


def warning(doc: dict, start: str) -> str:
    found = [w for w in doc["warnings"] if start in w]
    assert len(found) == 1, doc["warnings"]
    assert found[0] in doc["verdict_text"], doc["verdict_text"]
    return found[0]


def test_a_lag_the_selection_misses_is_added_as_the_one_that_explains_alone(tmp_path):
    # 15 ms lag: under the starting model's gain its candidate lowers the one-step
    # prediction error by nothing, and the selection ends in a misfit; fitted alone under its
    # own predictor it is the one candidate that explains the logs, and is added. Measured:
    # tau 15.00 ms ± 0.011 on seed 1, the one measured (the FRF criterion reads 14.9-15.0 ms
    # on seeds 1-3).
    # Before, a misfit with nothing found, the lag named only by the FRF cross-check.
    doc = discover(tmp_path, "d")
    text = doc["verdict_text"]
    assert doc["found"] == ["actuator_lag"] and not doc["unexplained"], text
    assert "actuator_lag was added after the selection" in text, text
    last = doc["steps"][-1]
    tau, std = last["params"]["tau"], last["std"]["tau"]
    assert abs(tau - 0.015) <= 3.0 * std, (tau, std)


def test_correct_logs_name_the_quantization_and_read_explained_under_the_frf_criterion(tmp_path):
    doc = discover(tmp_path, "a")
    assert doc["found"] == [] and doc["tentative"] == [], doc["verdict_text"]
    assert doc["unexplained"], doc["verdict_text"]
    quantized = warning(doc, "logged through a coarse quantizer")
    assert "th1 (step 1.5340e-3" in quantized and "x (step" not in quantized, quantized
    frf = warning(doc, "under the FRF criterion (--criterion frf")
    assert frf.endswith("the same logs read explained, nothing added"), frf


@pytest.mark.campaign  # about 6 minutes
def test_an_encoder_offset_is_added_alone_and_its_refit_kept(tmp_path):
    # A 0.01 rad offset of the first link's encoder. With each record's predictor started at
    # the operating point (not at its fitted state) a rod's viscous friction was added beside
    # it, and the final model's refit went to a cart mass a third of the documented one and
    # was not kept (the first link's length then fitted 1.79 m for 0.515). Now the offset
    # alone is added and the refit kept near the truth: seeds 1-3, bias 0.01002-0.01007, M
    # within 0.5 % and L1 within 0.7 % of the truth (1.04 kg, 0.515 m).
    doc = discover(tmp_path, "f")
    costs = [step["cost"] for step in doc["steps"]]
    assert all(b < a for a, b in zip(costs, costs[1:])), costs
    assert doc["found"] + doc["tentative"] == ["sensor_bias"], doc["verdict_text"]
    assert not any("refit under its own predictor" in w for w in doc["warnings"]), doc["warnings"]
    params = doc["steps"][-1]["params"]
    assert abs(params["bias_th1"] - 0.01) < 1e-4, params
    assert abs(params["M"] / dp.TRUE["M"] - 1) < 0.02, params
    assert abs(params["L1"] / dp.TRUE["L1"] - 1) < 0.02, params
