"""A car above its critical speed from independent_car.py (its own simulator, unstable,
doubling in 0.32 s, a yaw-rate loop at 100 Hz, a low-pass wind force of 0.3 s), read under the
time criterion (the model file is `[nonlinear]`): the selection, which scores every candidate
under the starting model's predictor, cannot add a 20 ms tyre lag there (that predictor takes
the wind for white noise, and the starting fit it was designed at ran to the rear cornering
stiffness's fifth), so the one candidate that explains the logs fitted alone under its own
predictor is added; on nominal logs nothing is added."""
from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

import independent_car as ic
from seeds import campaign_seeds
from test_interop import stabilis_bin

MODEL = Path(__file__).parent / "data" / "car.toml"


def discover(data: str, tmp_path: Path) -> dict:
    out = tmp_path / "d.json"
    done = subprocess.run([stabilis_bin(), "discover", "--model", str(MODEL), "--data", data,
                           "--json", str(out)], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    return json.loads(out.read_text())


@pytest.mark.parametrize("seed", campaign_seeds(1, 2, 3))
def test_a_tyre_lag_the_selection_misses_is_added_as_the_one_that_explains_alone(tmp_path,
                                                                                  seed):
    # Measured on seeds 1-3: sigma 0.596 ± 0.042 (widened), 0.6006 ± 0.0046, 0.6037 ± 0.0043
    # for 0.6, each explained (p > 0.999, > 0.999, 0.052). Before, a misfit with nothing found
    # on 3 of 3 (p = 1e-85), and `tyre_lag` named only by the FRF cross-check.
    doc = discover(ic.run(str(tmp_path / "data"), "tyrelag", seed), tmp_path)
    text = doc["verdict_text"]
    assert doc["found"] == ["tyre_lag"] and doc["unexplained"] is False, text
    assert "tyre_lag was added after the selection" in text, text
    last = doc["steps"][-1]
    value, std = last["params"]["sigma"], last["std"]["sigma"]
    assert abs(value - ic.TRUTH["sigma"]) <= 3.0 * std, (value, std)


@pytest.mark.parametrize("seed", campaign_seeds(1, 2, 3))
def test_nominal_logs_add_nothing(tmp_path, seed):
    # Measured on seeds 1-3: explained on 1 and 3; seed 2 reads a misfit (p = 1.5e-3), as it
    # did before effects were added after the selection, and five candidates explain it
    # alone, each near where it vanishes (an input delay of 0), so none is added.
    doc = discover(ic.run(str(tmp_path / "data"), "nominal", seed), tmp_path)
    assert doc["found"] == [] and doc["tentative"] == [], doc["verdict_text"]
