"""stabilis.flying_platform: models and effects, controller, design, simulation, and the 18
sysid MCAP files read with the official `mcap` package."""
import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

import stabilis
from stabilis import flying_platform as fp

REPO = Path(__file__).resolve().parents[2]

A_PRINTED_DIAG = [-0.896, -0.896, -1.852, 0, 0, 0, 0.856, 0.856, -5.366]


def stabilis_bin():
    path = Path(os.environ.get("STABILIS_BIN", REPO / "target" / "release" / "stabilis"))
    if not path.is_file():
        pytest.fail(f"stabilis binary not found at {path}; build it with `cargo build --release -p sim`")
    return str(path)


def test_effects_declare_named_parameters_with_bounds():
    names = [e["name"] for e in fp.effects()]
    assert names == ["momentum_drag", "fan_gyroscopic", "actuator_lag", "input_delay"]
    drag = fp.effects()[0]["params"]
    assert [p["name"] for p in drag] == ["c_alpha1", "c_alpha2", "l_alpha1", "l_alpha2", "l_alpha3", "l_alpha4"]
    assert all(p["lower"] <= p["default"] <= p["upper"] for e in fp.effects() for p in e["params"])


def test_augmented_model_matches_printed_diagonal_and_has_unstable_pair():
    m = fp.Model.augmented()
    a, b = m.hover_matrices()
    np.testing.assert_allclose(np.diag(a), A_PRINTED_DIAG, atol=0.004)
    assert b.shape == (9, 9)
    assert max(p.real for p in m.poles()) > 4.5
    low = fp.Model("")
    assert all(abs(p) < 1e-9 for p in low.poles())


def test_parameter_vector_and_errors():
    m = fp.Model("input_delay,fan_gyroscopic")
    assert m.param_names == ["c_omega_t0", "td"]
    np.testing.assert_allclose(m.parameter_vector(), [0.018, 0.045])
    m.set_parameter_vector([0.01, 0.02])
    assert m.parameter("td") == 0.02
    with pytest.raises(ValueError, match="effect parameter vector"):
        m.set_parameter_vector([0.01])
    with pytest.raises(stabilis.Error, match="td"):
        m.set_parameter("td", 1.0)
    with pytest.raises(stabilis.Error, match="wind"):
        fp.Model("momentum_drag,wind")


def test_frequency_response_matches_python_control_of_state_space():
    # The reference is python-control's evaluation of the model's state space (ss and
    # frequency_response), times the pure delay e^{-j w delay} that a state space cannot hold.
    import control
    m = fp.Model.augmented()
    m.enable("actuator_lag")
    ss = m.state_space()
    w = np.array([0.5, 2.0, 10.0])
    g = m.frequency_response(w)
    n_out, n_in = ss["c"].shape[0], ss["b"].shape[1]
    system = control.ss(ss["a"], ss["b"], ss["c"], np.zeros((n_out, n_in)))
    response = control.frequency_response(system, w)
    ref = np.moveaxis(np.asarray(response.complex).reshape(n_out, n_in, len(w)), -1, 0)
    ref = ref * np.exp(-1j * w * ss["delay"])[:, None, None]
    assert g.shape == ref.shape
    np.testing.assert_allclose(g, ref, rtol=1e-9, atol=1e-12)


def test_controller_poles_and_design_optimum():
    c = fp.controller()
    np.testing.assert_allclose(sorted(p.real for p in c["poles"]), [-50.12, -50.12, -29.09], atol=0.05)
    assert c["k"].shape == (9, 3)
    assert abs(fp.optimal_l3() - 0.16777) < 1e-5
    g = fp.gramian(8.0, 0.07, 0.17, 1.0)
    assert abs(g["det"] - 3807.033) < 1e-2 and abs(g["det_closed_form"] - 3807.033) < 1e-2


def test_experiment_design_is_orthogonal_multisine():
    d = fp.experiment_design(seed=2)
    x = d["excitation"]
    assert x.shape == (18, 2700, 9)
    period = x[0, 200:450, 0]
    spec = np.fft.fft(period)
    assert np.all(np.abs(spec[1:21]) > 1e-6)
    assert np.sum(np.abs(spec[21:230]) ** 2) < 1e-20 * np.sum(np.abs(spec) ** 2)
    assert max(d["crest_factors"]) < 2.1
    assert d["excited"][0] == "F1x,F2x,F3x" and d["excited"][17] == "F1z,F2z,F3z"


def test_hover_and_disturbance_simulation():
    run = fp.simulate("hover", duration=20.0, seed=1)
    assert run["input"].shape == (1000, 9) and run["output"].shape == (1000, 9)
    rms = np.sqrt(np.mean(run["position"][200:] ** 2, axis=0))
    assert np.all(rms[:2] < 0.03) and rms[2] < 0.01
    kick = fp.simulate("disturbance", duration=3.0, noise_free=True)
    peak = np.degrees(np.max(np.abs(kick["true_output"][:, 7])))
    assert 2.0 < peak < 5.0
    with pytest.raises(stabilis.SimError, match="diverged"):
        fp.simulate("hover", duration=10.0, td=0.045)


def test_sysid_cli_writes_18_mcap_files_readable_by_mcap(tmp_path):
    done = subprocess.run([stabilis_bin(), "sim", "flying-platform", "--scenario", "sysid", "--periods", "2",
                           "--out", str(tmp_path)], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    files = sorted(tmp_path.glob("*.mcap"))
    assert len(files) == 18
    for e, path in enumerate(files):
        with open(path, "rb") as f:
            reader = make_reader(f)
            meta = {}
            for record in reader.iter_metadata():
                if record.name == "experiment":
                    meta = dict(record.metadata)
            assert meta["sample_rate_hz"] == "50" and meta["period_samples"] == "250"
            assert meta["periods"] == "2" and meta["transient_samples"] == "200"
            excited = meta["excited"].split(",")
            columns = {}
            for schema, channel, message in reader.iter_messages():
                assert schema.encoding == "jsonschema" and channel.message_encoding == "json"
                columns.setdefault(channel.topic, []).append(json.loads(message.data))
        assert set(columns) >= {"/flying_platform/input", "/flying_platform/output", "/flying_platform/excitation"}
        assert len(columns["/flying_platform/input"]) == 700
        out = columns["/flying_platform/output"][0]
        assert set(out) == {"t", "vx", "vy", "vz", "wx", "wy", "wz", "roll", "pitch", "yaw"}
        exc = columns["/flying_platform/excitation"]
        energy = {name: sum(m[name] ** 2 for m in exc) for name in fp.INPUT_NAMES}
        assert {n for n, v in energy.items() if v > 0} == set(excited), f"experiment {e + 1}"
        # Hover trim is in the logged input: about m g0 / 3 per fan.
        fz = np.mean([m["F1z"] for m in columns["/flying_platform/input"]])
        assert abs(fz - 8.0 * 9.81 / 3) < 1.0


def test_run_experiments_into_arrays_matches_design():
    runs = fp.run_experiments(periods=1, seed=4, noise_free=True)
    assert len(runs) == 18
    d = fp.experiment_design(seed=4, periods=1)
    np.testing.assert_allclose(runs[5]["excitation"], d["excitation"][5])
    assert runs[5]["metadata"]["excited"] == "F1z,F2z,F3z"


def test_generic_sim_run_front_end():
    log = stabilis.sim.run("flying-platform", 5.0, seed=2, scenario="step", step=(0.5, 0.0, 0.0))
    t, out = log["/flying_platform/output"]
    assert len(t) == 250 and set(out) >= {"vx", "wx", "roll"}
    assert log.metadata["experiment"]["scenario"] == "step"
    _, pos = log["/flying_platform/position"]
    assert abs(pos["x"][-1] - 0.5) < 0.05
