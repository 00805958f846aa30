"""The own-system workbench on a plant outside mechanics: an exothermic stirred-tank reactor at
its unstable steady state (+0.047 1/s), held by a PI loop sampled at 1 s, simulated by
independent_cstr.py (numpy only, no stabilis code) with slowly drifting feed conditions, and
logged as CSV in kelvin and seconds. The model file data/cstr.toml is the nonlinear reactor
with the reaction's rate constant, the heat of reaction and the heat transfer free.

A 3 s thermocouple lag and a 3 s coolant delay lie beyond the 0.5 s the generic lag and delay
were once bounded by; the candidates' ranges now follow the data's frequency resolution.
Logs in Celsius or as deviations are refused by name under the time criterion, and logs in
minutes are named by the clock they fit. The time criterion reads the drifting reactor through
its innovations' autoregression. On a second rig (an analyser measuring CA too, an LQR,
white process noise) the time criterion reads the reactor explained, and a thermocouple offset
the rate constant absorbs is named beside the misfit it leaves. Every (case, seed) is its own
case.
"""
from __future__ import annotations

import json
from pathlib import Path

import pytest

import independent_cstr as ic
from test_interop import run_cli

MODEL = Path(__file__).parent / "data" / "cstr.toml"
SEEDS = (1, 2, 3)


def discover(data: Path, tmp: Path, *extra: str, model: Path = MODEL) -> dict:
    out = tmp / "discover.json"
    done = run_cli("discover", "--model", str(model), "--data", str(data), "--json", str(out),
                   *extra)
    assert done.returncode == 0, done.stderr
    return json.loads(out.read_text())


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("hidden,effect,name", [("lag", "actuator_lag", "tau"),
                                               ("delay", "input_delay", "td")])
def test_a_lag_or_delay_of_three_samples_is_found_under_the_frf_criterion(tmp_path, hidden,
                                                                          effect, name, seed):
    # Measured: tau 2.83-2.95 s, td 2.98-3.03 s on seeds 1-3 (the time criterion below).
    ic.campaign(tmp_path / "data", seed, hidden=hidden)
    doc = discover(tmp_path / "data", tmp_path, "--criterion", "frf")
    assert doc["found"] == [effect], doc["verdict_text"]
    assert doc["unexplained"] is False, doc["verdict_text"]
    value = doc["steps"][-1]["params"][name]
    assert abs(value - 3.0) < 0.1 * 3.0, (name, value)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("hidden", ["none", "lag"])
def test_the_time_criterion_reads_the_drifting_reactor_through_its_noise_model(tmp_path,
                                                                                hidden, seed):
    # The feed drift is a slow coloured disturbance the loop answers. With white innovations
    # assumed, the right model read a misfit on 3 of 3 seeds with UA 774-800 for 833.3, and
    # the lag stayed tentative; with the innovations whitened by their autoregression, seeds
    # 1-3: explained with UA 832.4-833.5, and the lag found at tau 2.87-2.91 s, UA 828-832.
    ic.campaign(tmp_path / "data", seed, hidden=hidden)
    doc = discover(tmp_path / "data", tmp_path)
    assert doc["weighting"].startswith("time-domain prediction error"), doc["weighting"]
    assert doc["found"] == ([] if hidden == "none" else ["actuator_lag"]), doc["verdict_text"]
    assert doc["unexplained"] is False, doc["verdict_text"]
    params = doc["steps"][-1]["params"]
    assert abs(params["UA"] / 833.333 - 1) < 0.01, params
    if hidden == "lag":
        assert abs(params["tau"] - 3.0) < 0.1 * 3.0, params


@pytest.mark.parametrize("units", ["C", "deviations"])
def test_logs_in_other_units_or_as_deviations_are_refused_under_the_time_criterion(tmp_path,
                                                                                   units):
    data = tmp_path / "data"
    ic.campaign(data, 1, units="C" if units == "C" else "K", records=2)
    if units == "deviations":
        for f in data.glob("*.csv"):
            lines = f.read_text().splitlines()
            rows = [[float(v) for v in line.split(",")] for line in lines[1:]]
            f.write_text("\n".join([lines[0]] + [
                f"{t},{tc - ic.TC0},{temp - ic.T0},{r}" for t, tc, temp, r in rows]) + "\n")
    done = run_cli("discover", "--model", str(MODEL), "--data", str(data))
    assert done.returncode == 2, done.stdout
    assert "the logged input Tc averages" in done.stderr, done.stderr
    assert "operating point holds at 300.0017" in done.stderr, done.stderr
    assert ("degrees Celsius against kelvin" in done.stderr) == (units == "C"), done.stderr
    # The FRF criterion compares deviations: the same logs read explained, nothing added.
    frf = discover(data, tmp_path, "--criterion", "frf")
    assert frf["found"] == [] and frf["unexplained"] is False, frf["verdict_text"]


def test_logs_in_minutes_are_named_by_the_clock_they_fit(tmp_path):
    ic.campaign(tmp_path / "data", 1, clock="min")
    doc = discover(tmp_path / "data", tmp_path, "--criterion", "frf")
    text = doc["verdict_text"]
    assert "parameters fitted far from their documented values" in text, text
    assert "with their clock scaled by 60.0" in text, text
    assert "minutes against seconds" in text, text


def analyser_model(tmp: Path) -> Path:
    """The model file with the analyser's CA as a second output."""
    model = tmp / "cstr_analyser.toml"
    model.write_text(MODEL.read_text().replace('outputs = ["T"]', 'outputs = ["T", "CA"]')
                     .replace('h.T = "T"', 'h.T = "T"\nh.CA = "CA"'))
    return model


@pytest.mark.parametrize("seed", SEEDS)
def test_the_analyser_rig_reads_explained_with_the_true_constants(tmp_path, seed):
    # Measured on seeds 1-3: UA 832.6 / 834.0 / 832.9 (± 1.5-1.6) for 833.3, k0 1.200e9
    # (± 3e5) on each.
    ic.campaign(tmp_path / "data", seed, loop="lqr")
    doc = discover(tmp_path / "data", tmp_path, model=analyser_model(tmp_path))
    assert doc["found"] == [] and doc["unexplained"] is False, doc["verdict_text"]
    params = doc["steps"][-1]["params"]
    assert abs(params["UA"] / 833.333 - 1) < 0.005, params
    assert abs(params["k0"] / 1.2e9 - 1) < 0.001, params


@pytest.mark.parametrize("seed", SEEDS)
def test_a_thermocouple_offset_the_rate_constant_absorbs_is_named_beside_the_misfit(tmp_path,
                                                                                   seed):
    # The loop regulates the offset away and k0 absorbs it 3.5 % low, so adding the offset
    # lowers the prediction error by almost nothing and the selection leaves it out; the
    # temperature's innovations still correlate with the excitation (a misfit), and fitted
    # alone the generic sensor offset explains the logs. Measured on seeds 1-3: bias_T 0.63 /
    # 0.46 / 0.40 (± 0.09) for 0.5, the coolant's offset named beside it.
    ic.campaign(tmp_path / "data", seed, hidden="offset", loop="lqr")
    doc = discover(tmp_path / "data", tmp_path, model=analyser_model(tmp_path))
    text = doc["verdict_text"]
    assert doc["unexplained"] is True, text
    assert "leaves the innovations uncorrelated with the excitation" in text, text
    bias = float(text.split("sensor_bias (bias_T = ")[1].split(" ")[0])
    assert abs(bias - 0.5) < 0.2, text
