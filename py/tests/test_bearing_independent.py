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
    # Measured on seeds 1-5: c = 5.17, 4.60, 4.79, 5.08, 4.99 (0.2-8 %); the reported standard
    # error, 0.14-0.15, understates that spread (0.23).
    c = found["steps"][-1]["params"]["c"]
    assert abs(c - COUPLING) < 0.1 * COUPLING, c


@pytest.mark.parametrize("seed", SEEDS)
def test_uncoupled_axes_read_explained(tmp_path, seed):
    data = ib.campaign(tmp_path / "data", seed)
    for verb in ("compare", "discover"):
        doc = run(verb, data, tmp_path)
        assert doc["unexplained"] is False and doc["found"] == [], doc["verdict_text"]
        assert "no path" not in doc["verdict_text"], doc["verdict_text"]
