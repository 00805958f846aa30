"""The own-system workbench on a lightly damped plant stabilis does not ship: a two-mass spring
under its experimenter's state feedback, simulated by independent_twomass.py (numpy and scipy,
no stabilis code) with a non-periodic excitation, so that a Welch estimate carries the
comparison. Its mode (3.8 Hz, 0.3 Hz half-power width with the hidden friction) is narrower
than two bins of a Welch estimate from 45 s records (0.19 Hz bins); 180 s records resolve it
(0.06 Hz). The model is compared with each line through the window's kernel, so coarse bins
cost precision, not truth. Each (record length, seed) is its own case, so the pass rate is the
count of passing cases.
"""
from __future__ import annotations

from pathlib import Path

import pytest

import independent_twomass as tm
from test_interop import discover_model_file

MODEL = Path(__file__).parent / "data" / "twomass.toml"
B2 = 0.8  # the hidden friction of mass 2, N s/m


def discover(tmp: Path, b2: float, seconds: float, seed: int) -> dict:
    data = tm.campaign(tmp / "data", tm.Plant(b2=b2), seconds=seconds, seed=seed)
    return discover_model_file(MODEL, data, tmp)


@pytest.mark.parametrize("seconds", (45.0, 180.0))
@pytest.mark.parametrize("seed", (1, 2, 3))
@pytest.mark.parametrize("b2", (B2, 0.0))
def test_the_hidden_friction_is_found_whether_or_not_the_bins_resolve_the_mode(
        tmp_path, b2, seed, seconds):
    """On the 45 s records a model compared with each line at its own frequency drew a friction
    of mass 1 that is not there into the model in 2 of 3 seeds, and its stiffness came out 8
    standard errors off; seen through the window's kernel it finds what is hidden on either
    length (measured b2 0.797-0.800, k 189.7-190.3, m2 0.479-0.481)."""
    doc = discover(tmp_path, b2, seconds, seed)
    assert doc["found"] == (["friction2"] if b2 else []), doc["verdict_text"]
    assert doc["tentative"] == [], doc["tentative_why"]
    params = doc["steps"][-1]["params"]
    assert params["k"] == pytest.approx(190.0, rel=0.005), params
    assert params["m2"] == pytest.approx(0.48, rel=0.01), params
    if b2:
        assert params["b2"] == pytest.approx(b2, rel=0.05), params
