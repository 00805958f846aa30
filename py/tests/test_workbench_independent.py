"""The workbench on logs of an independent simulator (independent_platform.py, written from the
spec and DESIGN.md with numpy/scipy and the official `mcap` writer, not with stabilis): what it
finds, the drag and gyroscopic parameters it recovers, the DESIGN.md variants it must accept and
the broken logs it must refuse by name."""
import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

import independent_platform as ip
import stabilis
from test_interop import stabilis_bin

DRAG = ip.Drag()
DRAG_TRUTH = {"c_alpha1": DRAG.c_alpha1, "c_alpha2": DRAG.c_alpha2, "l_alpha1": DRAG.l_alpha1,
              "l_alpha2": DRAG.l_alpha2, "l_alpha3": DRAG.l_alpha3, "l_alpha4": DRAG.l_alpha4}


def discover(*data, tmp):
    """`stabilis discover --data ... --json FILE`: (exit code, stderr, JSON document or None)."""
    out = Path(tmp) / "discover.json"
    done = subprocess.run([stabilis_bin(), "discover", "--system", "flying_platform", "--data",
                           *map(str, data), "--json", str(out)],
                          capture_output=True, text=True, check=False)
    doc = json.loads(out.read_text()) if done.returncode == 0 else None
    return done.returncode, done.stderr, doc


def campaign(tmp, **kw):
    cfg = ip.Config(**kw)
    return ip.write_runs(cfg, ip.simulate(cfg), Path(tmp))


def relative_errors(params, truth):
    return {k: params[k] / v - 1.0 for k, v in truth.items()}


def test_controller_stabilises_every_truth_and_excitation_is_the_orthogonal_design():
    # The simulator itself: the closed loop of each truth is stable (simulate raises otherwise),
    # and the logged excitation has the spec's structure (lines 1..20 only, DFT phase steps).
    cfg = ip.Config(drag=DRAG, c_omega_t0=0.1, periods=2, experiments=(4,), phase_draws=10)
    run = ip.simulate(cfg)[0]
    r = run.r[cfg.transient_samples:cfg.transient_samples + cfg.period_samples]
    spectrum = np.fft.fft(r, axis=0)
    power = np.abs(spectrum) ** 2
    excited = np.r_[1:21, 230:250]
    assert power[np.setdiff1d(np.arange(250), excited)].sum() < 1e-20 * power.sum()
    # e = 4: flap 1 of every unit (columns 0, 3, 6), DFT row k = 1: unit l lags by 120 l degrees.
    assert np.abs(r[:, [1, 2, 4, 5, 7, 8]]).max() == 0.0
    step = spectrum[1:21, 3] / spectrum[1:21, 0]
    assert np.allclose(step, np.exp(-2j * np.pi / 3), atol=1e-9)
    assert np.sqrt(np.mean(r[:, 0] ** 2)) == pytest.approx(cfg.lam[0], rel=1e-9)
    # The hover trim of spec §3.4 with M = 0.05 N m: 0.433 N of flap-2 force, m g0 / 3 upward.
    assert np.allclose(ip.trim(ip.Vehicle()), np.tile([0.0, -0.05 * np.sqrt(3) / 0.2, 26.16], 3))


def test_noise_free_frf_is_the_truths_exact_sampled_frf(tmp_path):
    # Drag, gyroscopic torque, actuator lag and a fractional in-loop delay, no noise, a long
    # transient: the workbench's closed-loop FRF estimate must be the plant's sampled FRF
    # (spec AT-16).
    quiet = dict(accel_noise=0.0, angular_noise=0.0, position_sigma=0.0, velocity_sigma=0.0,
                 attitude_sigma=0.0, gyro_sigma=0.0)
    cfg = ip.Config(drag=DRAG, c_omega_t0=0.05, delay_s=0.012, actuator_tau=0.02, periods=2,
                    transient_samples=1000, phase_draws=10, seed=5, **quiet)
    ip.write_runs(cfg, ip.simulate(cfg), tmp_path / "data")
    frf = stabilis.Workbench("flying_platform", data=[str(tmp_path / "data")]).frf()
    truth = ip.sampled_frf(cfg, frf["freqs_hz"])
    error = np.linalg.norm(frf["G"] - truth, axis=(1, 2)) / np.linalg.norm(truth, axis=(1, 2))
    assert error.max() < 1e-6


def test_low_complexity_truth_finds_nothing(tmp_path):
    campaign(tmp_path / "data", periods=4, seed=1)
    code, err, doc = discover(tmp_path / "data", tmp=tmp_path)
    assert code == 0, err
    assert doc["found"] == []
    assert doc["unexplained"] is False
    assert doc["estimator"].lower().startswith("instrumental")


def test_drag_truth_finds_momentum_drag_with_its_parameters(tmp_path):
    campaign(tmp_path / "data", drag=DRAG, periods=6, seed=2)
    code, err, doc = discover(tmp_path / "data", tmp=tmp_path)
    assert code == 0, err
    assert doc["found"][0] == "momentum_drag"
    assert "fan_gyroscopic" not in doc["found"]
    assert doc["unexplained"] is False
    costs = [s["cost"] for s in doc["steps"]]
    assert costs[1] < 0.02 * costs[0]
    err = relative_errors(doc["steps"][-1]["params"], DRAG_TRUTH)
    for name in ("c_alpha1", "c_alpha2", "l_alpha2", "l_alpha4"):
        assert abs(err[name]) < 0.10, (name, err)
    assert abs(err["l_alpha3"]) < 0.15, err
    # l_alpha1 is weakly identifiable (spec AT-23 allows 35%).
    assert abs(err["l_alpha1"]) < 0.20, err


def test_drag_and_large_fan_inertia_finds_both_through_python(tmp_path):
    campaign(tmp_path / "data", drag=DRAG, c_omega_t0=0.1, periods=4, seed=3)
    result = stabilis.Workbench("flying_platform", data=[str(tmp_path / "data")]).discover()
    assert result["found"] == ["momentum_drag", "fan_gyroscopic"]
    params = result["steps"][-1]["params"]
    assert params["c_omega_t0"] == pytest.approx(0.1, rel=0.05)
    err = relative_errors(params, DRAG_TRUTH)
    for name in ("c_alpha1", "c_alpha2", "l_alpha2", "l_alpha4"):
        assert abs(err[name]) < 0.10, (name, err)


def test_paper_like_truth_finds_drag_delay_and_paper_size_gyroscopic(tmp_path):
    # Table-3 drag, the paper's C omega_T0 = 0.018 and a 15 ms in-loop delay beyond the hold.
    campaign(tmp_path / "data", drag=DRAG, c_omega_t0=0.018, delay_s=0.015, periods=6, seed=24)
    code, err, doc = discover(tmp_path / "data", tmp=tmp_path)
    assert code == 0, err
    assert doc["found"][0] == "momentum_drag"
    assert sorted(doc["found"]) == ["fan_gyroscopic", "input_delay", "momentum_drag"]
    assert doc["unexplained"] is False
    params = doc["steps"][-1]["params"]
    err = relative_errors(params, DRAG_TRUTH)
    for name in ("c_alpha1", "c_alpha2", "l_alpha2", "l_alpha4"):
        assert abs(err[name]) < 0.10, (name, err)
    # Spec AT-23 tolerances: C omega_T0 15%, T_d 3 ms, l3 0.004 m.
    assert params["c_omega_t0"] == pytest.approx(0.018, rel=0.15)
    assert params["td"] == pytest.approx(0.015, abs=0.003)
    assert params["l3"] == pytest.approx(0.079, abs=0.004)


def test_delay_alone_is_found_as_input_delay(tmp_path):
    # One sample of delay over this band is also nearly a one-sample lag: the delay is added
    # and fits best (the lag +6.4, a gap noise makes with p = 0.09), but not beyond doubt, so
    # it is tentative with the lag named as its rival (discover::rivals).
    campaign(tmp_path / "data", delay_s=0.01, periods=4, seed=21)
    code, err, doc = discover(tmp_path / "data", tmp=tmp_path)
    assert code == 0, err
    assert doc["found"] + doc["tentative"] == ["input_delay"]
    if doc["tentative"]:
        assert any(w.startswith("actuator_lag fits these data as well as input_delay")
                   for w in doc["tentative_why"]), doc["tentative_why"]
    assert doc["steps"][-1]["params"]["td"] == pytest.approx(0.01, abs=0.002)


@pytest.mark.parametrize("drag, found", [(None, ["actuator_lag"]),
                                         (DRAG, ["momentum_drag", "actuator_lag"])])
def test_actuator_lag_is_found_with_its_time_constant(tmp_path, drag, found):
    campaign(tmp_path / "data", drag=drag, actuator_tau=0.03, periods=4, seed=81)
    code, err, doc = discover(tmp_path / "data", tmp=tmp_path)
    assert code == 0, err
    assert doc["found"] == found
    assert doc["unexplained"] is False
    params = doc["steps"][-1]["params"]
    assert params["tau"] == pytest.approx(0.03, rel=0.05)
    if drag is not None:
        err = relative_errors(params, DRAG_TRUTH)
        assert abs(err["c_alpha1"]) < 0.10 and abs(err["c_alpha2"]) < 0.10, err


def test_velocity_log_filter_is_named_as_unexplained_misfit_in_the_velocity_rows(tmp_path):
    # Drag truth whose logged velocities pass a 30 ms filter (no candidate models it): drag is
    # added but only as tentative (a structured misfit remains next to it), and the rest is
    # reported as a structured misfit in the velocity rows only.
    campaign(tmp_path / "data", drag=DRAG, velocity_log_tau=0.03, periods=4, seed=92)
    code, err, doc = discover(tmp_path / "data", tmp=tmp_path)
    assert code == 0, err
    assert doc["found"] == []
    assert doc["tentative"] == ["momentum_drag"]
    assert doc["unexplained"] is True
    assert doc["verdict"]["kind"] == "unexplained_structured_misfit"
    assert doc["verdict"]["outputs"] and set(doc["verdict"]["outputs"]) <= {"vx", "vy", "vz"}


HEAVY = ip.Vehicle(mass=10.0, i1=0.09, i3=0.15, l3=0.12)


def test_other_vehicle_low_complexity_finds_nothing(tmp_path):
    # The workbench holds m = 8 kg and I1 = 0.07 kg m^2; another vehicle must still fit through
    # the identifiable ratios.
    campaign(tmp_path / "data", vehicle=HEAVY, periods=4, seed=101)
    code, err, doc = discover(tmp_path / "data", tmp=tmp_path)
    assert code == 0, err
    assert doc["found"] == []


def test_other_vehicle_drag_and_gyroscopic_through_identifiable_ratios(tmp_path):
    campaign(tmp_path / "data", vehicle=HEAVY, drag=DRAG, c_omega_t0=0.1, periods=4, seed=103)
    code, err, doc = discover(tmp_path / "data", tmp=tmp_path)
    assert code == 0, err
    assert doc["found"] == ["momentum_drag", "fan_gyroscopic"]
    p = doc["steps"][-1]["params"]
    m0, i1_0 = 8.0, 0.07  # the workbench's documented values
    # 3 C omega_T0 / I1 (roll-pitch rate coupling), 3 c_alpha2 / m (vz pole),
    # 3 l_alpha2 c_alpha1 / I1 (velocity -> moment).
    assert 3 * p["c_omega_t0"] / i1_0 == pytest.approx(3 * 0.1 / HEAVY.i1, rel=0.05)
    assert 3 * p["c_alpha2"] / m0 == pytest.approx(3 * DRAG.c_alpha2 / HEAVY.mass, rel=0.10)
    assert p["l_alpha2"] * p["c_alpha1"] / i1_0 == pytest.approx(
        DRAG.l_alpha2 * DRAG.c_alpha1 / HEAVY.i1, rel=0.10)


def test_other_sample_rate_nine_experiments_three_periods(tmp_path):
    # 100 Hz with 500-sample periods (still 0.2 Hz lines), only the nine S1 experiments.
    campaign(tmp_path / "data", drag=DRAG, sample_rate_hz=100.0, period_samples=500,
             transient_samples=300, periods=3, experiments=tuple(range(1, 10)), seed=4)
    code, err, doc = discover(tmp_path / "data", tmp=tmp_path)
    assert code == 0, err
    assert np.allclose(doc["frequencies_hz"], 0.2 * np.arange(1, 21))
    assert doc["found"][0] == "momentum_drag"
    assert "fan_gyroscopic" not in doc["found"]


def test_other_period_and_files_given_one_by_one(tmp_path):
    # 200-sample periods at 50 Hz: 16 lines at 0.25..4 Hz; files listed instead of a directory.
    # Six seeds: the drag is found first in every one; its coefficients come within 10 % in at
    # least 5 of 6 (measured: 6 of 6 for c_alpha1, 5 of 6 for c_alpha2, the sixth 14 % off) and
    # within 20 % in all.
    close = 0
    for seed in range(1, 7):
        files = campaign(tmp_path / f"data{seed}", drag=DRAG, period_samples=200, lines=16,
                         periods=4, transient_samples=100, seed=seed)
        code, err, doc = discover(*files, tmp=tmp_path)
        assert code == 0, err
        assert np.allclose(doc["frequencies_hz"], 0.25 * np.arange(1, 17))
        assert doc["found"][0] == "momentum_drag", (seed, doc["found"])
        err = relative_errors(doc["steps"][-1]["params"], DRAG_TRUTH)
        worst = max(abs(err["c_alpha1"]), abs(err["c_alpha2"]))
        assert worst < 0.20, (seed, err)
        close += worst < 0.10
    assert close >= 5, close


def test_design_csv_of_a_drag_truth_proposes_momentum_drag_as_tentative(tmp_path):
    # A DESIGN.md CSV carries no excitation: the closed-loop FRF estimate is biased under
    # feedback, so what discovery adds is tentative, never found.
    cfg = ip.Config(drag=DRAG, periods=4, seed=7)
    (tmp_path / "data").mkdir()
    for run in ip.simulate(cfg):
        ip.write_csv(run, tmp_path / "data" / f"e{run.index:02d}.csv", reverse=run.index % 2 == 0)
    code, err, doc = discover(tmp_path / "data", tmp=tmp_path)
    assert code == 0, err
    assert doc["found"] == []
    assert doc["tentative"][0] == "momentum_drag"


def test_metadata_without_periods_detects_the_period_from_the_excitation_and_finds_drag(tmp_path):
    # DESIGN.md: the period fields are only for periodic excitation; here only the rate is given.
    # The logged multisine repeats exactly every 250 samples, so the workbench detects the
    # period from it and uses the periodic estimator (a Welch estimate would see the lines
    # between its bins only through window leakage and leave drag tentative). Seeds 21-25:
    # drag is added first on every one and found on at least 4 of 5 (measured: 4; seed 23
    # reads a misfit at p = 1.8e-3 on one machine and not on another, since the simulator's
    # process-noise root comes from an eigendecomposition with repeated eigenvalues, whose
    # vectors differ between LAPACK builds, so a seed is not the same draw everywhere).
    found = 0
    for seed in range(21, 26):
        cfg = ip.Config(drag=DRAG, periods=4, seed=seed)
        data = tmp_path / str(seed) / "data"
        data.mkdir(parents=True)
        for run in ip.simulate(cfg):
            ip.write_mcap(data / f"e{run.index:02d}.mcap", ip.run_topics(run),
                          {"sample_rate_hz": "50"})
        code, err, doc = discover(data, tmp=tmp_path / str(seed))
        assert code == 0, err
        assert doc["estimator"] == "instrumental_variable", seed
        assert doc["steps"][1]["added"] == "momentum_drag", (seed, doc["steps"][1]["added"])
        found += doc["found"] == ["momentum_drag"] and doc["tentative"] == []
        # The 200 samples before the last four whole periods are discarded as the transient:
        # the excited lines are those of the periodic path, multiples of 50 Hz / 250 = 0.2 Hz.
        lines = np.asarray(doc["frequencies_hz"]) / 0.2
        assert np.allclose(lines, np.round(lines), atol=1e-9), doc["frequencies_hz"]
    assert found >= 4, found


@pytest.fixture(scope="module")
def small_campaign():
    cfg = ip.Config(periods=2, experiments=tuple(range(1, 10)), seed=8, phase_draws=10)
    return cfg, ip.simulate(cfg)


def write_with(cfg, runs, directory, mutate):
    """The campaign as MCAP files, experiment 5 changed by mutate(topics) -> topics."""
    directory.mkdir()
    for run in runs:
        topics = ip.run_topics(run)
        if run.index == 5:
            topics = mutate(topics)
        ip.write_mcap(directory / f"e{run.index:02d}.mcap", topics, ip.metadata(cfg, run))


def nan_in_wy(topics):
    t, names, v = topics["/flying_platform/output"]
    v = v.copy()
    v[100, names.index("wy")] = np.nan
    return {**topics, "/flying_platform/output": (t, names, v)}


def without_wz(topics):
    t, names, v = topics["/flying_platform/output"]
    keep = [i for i, n in enumerate(names) if n != "wz"]
    return {**topics, "/flying_platform/output": (t, [names[i] for i in keep], v[:, keep])}


def one_output_short(topics):
    t, names, v = topics["/flying_platform/output"]
    return {**topics, "/flying_platform/output": (t[:-1], names, v[:-1])}


def without_input(topics):
    return {k: v for k, v in topics.items() if k != "/flying_platform/input"}


@pytest.mark.parametrize("mutate, named", [
    (nan_in_wy, ['"wy"', "/flying_platform/output", "not a finite number"]),
    (without_wz, ['missing field "wz"', "/flying_platform/output"]),
    (one_output_short, ["length mismatch", "/flying_platform/output", "e05.mcap", "700", "699"]),
    (without_input, ['missing channel "/flying_platform/input"', "e05.mcap"]),
])
def test_broken_logs_are_refused_by_name(small_campaign, tmp_path, mutate, named):
    cfg, runs = small_campaign
    write_with(cfg, runs, tmp_path / "data", mutate)
    code, err, _ = discover(tmp_path / "data", tmp=tmp_path)
    assert code == 2
    for part in named:
        assert part in err, (part, err)
    assert not (tmp_path / "discover.json").exists()


def test_nan_in_csv_is_refused_by_name(small_campaign, tmp_path):
    _, runs = small_campaign
    (tmp_path / "data").mkdir()
    for run in runs:
        y = run.y.copy()
        if run.index == 3:
            y[50, ip.OUTPUTS.index("wx")] = np.nan
        ip.write_csv(ip.Run(run.index, run.t, run.u, run.r, y), tmp_path / "data" / f"e{run.index}.csv")
    code, err, _ = discover(tmp_path / "data", tmp=tmp_path)
    assert code == 2
    assert '"wx"' in err and "e3.csv" in err and "line 52" in err and "not a finite number" in err


def with_position_topic(topics):
    t = topics["/flying_platform/output"][0]
    return {**topics, "/flying_platform/position": (t, ["x", "y", "z"], np.zeros((len(t), 3)))}


def test_extra_topics_are_ignored(small_campaign, tmp_path):
    # DESIGN.md names the topics the workbench reads; others (here a position topic in one
    # experiment) may be present.
    cfg, runs = small_campaign
    write_with(cfg, runs, tmp_path / "data", with_position_topic)
    code, err, doc = discover(tmp_path / "data", tmp=tmp_path)
    assert code == 0, err
    assert len(doc["frequencies_hz"]) == 20


def test_too_little_data_is_refused_by_name(tmp_path):
    cfg = ip.Config(periods=2, experiments=(1, 2, 3, 4, 5), seed=10, phase_draws=10)
    ip.write_runs(cfg, ip.simulate(cfg), tmp_path / "five")
    code, err, _ = discover(tmp_path / "five", tmp=tmp_path)
    assert code == 2 and "at least 9 experiments" in err, err
    cfg = ip.Config(periods=1, experiments=tuple(range(1, 10)), seed=10, phase_draws=10)
    ip.write_runs(cfg, ip.simulate(cfg), tmp_path / "one")
    code, err, _ = discover(tmp_path / "one", tmp=tmp_path)
    assert code == 2 and "at least 2 periods" in err, err
