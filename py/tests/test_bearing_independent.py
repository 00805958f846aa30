"""A path the model lacks is named, and the effect that adds it is found: a magnetic bearing's
two axes, modelled uncoupled (data/bearing.toml), logged by independent_bearing.py (numpy and
scipy only, no stabilis code) with the spin coupling their velocities (c = 5 1/s) or not.
`compare` (no candidates) reads a misfit and names the cross paths, where the model's response
is zero; `discover` finds the file's suspected gyroscopic coupling near the truth; uncoupled
logs read explained with neither. Every (case, seed) is its own case.
"""
from __future__ import annotations

import json
from pathlib import Path

import pytest

import independent_bearing as ib
from test_interop import run_cli

MODEL = Path(__file__).parent / "data" / "bearing.toml"
SEEDS = (1, 2, 3)
COUPLING = 5.0


def run(verb: str, data: Path, tmp: Path) -> dict:
    out = tmp / f"{verb}.json"
    done = run_cli(verb, "--model", str(MODEL), "--data", str(data), "--json", str(out))
    assert done.returncode == 0, done.stderr
    return json.loads(out.read_text())


@pytest.mark.parametrize("seed", SEEDS)
def test_coupled_axes_are_named_and_their_coupling_found(tmp_path, seed):
    data = ib.campaign(tmp_path / "data", seed, COUPLING)
    compared = run("compare", data, tmp_path)
    text = compared["verdict_text"]
    assert compared["unexplained"] is True, text
    assert "the model has no path" in text and "ix->ys" in text and "iy->xs" in text, text
    found = run("discover", data, tmp_path)
    assert found["found"] == ["gyroscopic"], found["verdict_text"]
    assert found["unexplained"] is False, found["verdict_text"]
    # The estimate against its own reported standard error, which must be informative.
    # Measured on seeds 1-20: mean 4.955, spread 0.184 against a mean reported error 0.168;
    # the farthest, seed 2, 4.44 at 3.7 errors (before the record's transient was taken out of
    # the FRF: mean 4.991, spread 0.146, error 0.149, seed 2 at 4.63).
    step = found["steps"][-1]
    c, se = step["params"]["c"], step["std"]["c"]
    assert se < 0.05 * COUPLING, (c, se)
    assert abs(c - COUPLING) < 4 * se, (c, se)


@pytest.mark.parametrize("seed", SEEDS)
def test_uncoupled_axes_read_explained(tmp_path, seed):
    data = ib.campaign(tmp_path / "data", seed)
    for verb in ("compare", "discover"):
        doc = run(verb, data, tmp_path)
        assert doc["unexplained"] is False and doc["found"] == [], doc["verdict_text"]
        assert "no path" not in doc["verdict_text"], doc["verdict_text"]
