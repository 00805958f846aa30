"""Issue 16: Monte-Carlo detection power and false discoveries of the workbench, in-process and
on a Dask cluster, on the cart-pole model file (data/cart_pole.toml, declared effect
`cart_friction`, its `[controller]`) and nominal logs of the independent simulator
independent_cartpole.py.

The logs are short (2 experiments x 4 periods of 1000 samples at 100 Hz) so that the studies
stay within seconds; a campaign of the issue's 4 x 8300 samples takes about 0.2 s.
"""
from __future__ import annotations

import json
import math
import statistics
import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import pytest
from dask.distributed import Client, LocalCluster

import independent_cartpole as ic
import stabilis
from test_interop import stabilis_bin
from test_report_browser import measured_plots

MODEL = Path(__file__).parent / "data" / "cart_pole.toml"
SHORT = dict(experiments=2, periods=4, transient_samples=300)


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """Nominal logs (no friction) of the independent simulator."""
    out = tmp_path_factory.mktemp("cart_power")
    ic.campaign(out, plant=ic.Plant(), seed=5, **SHORT)
    return out


@pytest.fixture(scope="module")
def cluster():
    # Two worker processes of one thread: what a small remote cluster looks like.
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as c:
        yield c


STUDY = dict(effect="cart_friction", values=[0.0, 0.15, 0.4], campaigns=8, seed=11)


def test_dask_local_cluster_gives_the_in_process_result_to_the_bit(logs, cluster):
    local = stabilis.power(MODEL, [logs], threads=2, progress=False, **STUDY)
    seen = []
    with Client(cluster) as client:
        remote = stabilis.power(MODEL, [logs], client=client, batch=3,
                                progress=lambda done, total: seen.append((done, total)),
                                **STUDY)
    assert remote == local  # every float, every field
    # 24 campaigns in batches of 3: 8 tasks, progress after each.
    assert len(seen) == 8 and seen[-1] == (24, 24)
    assert [v["completed"] for v in local["values"]] == [8, 8, 8]
    # Not equal by being empty: the campaigns found friction at the largest value, with
    # estimates that differ between campaigns (each draws its own noise).
    top = local["values"][-1]
    assert top["detection_rate"] > 0.5 and top["estimate_std"] > 0


def test_cli_in_process_and_on_the_scheduler_agree_with_python(logs, cluster, tmp_path):
    args = [stabilis_bin(), "power", "--model", str(MODEL), "--data", str(logs),
            "--effect", STUDY["effect"], "--values", ",".join(map(str, STUDY["values"])),
            "--campaigns", str(STUDY["campaigns"]), "--seed", str(STUDY["seed"])]
    here = subprocess.run(args + ["--json", str(tmp_path / "here.json"), "--report",
                                  str(tmp_path / "report")], capture_output=True, text=True)
    assert here.returncode == 0, here.stderr
    assert "campaigns" in here.stderr  # progress: done/total and rate
    env = dict(os.environ, STABILIS_PYTHON=sys.executable,
               PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    there = subprocess.run(args + ["--json", str(tmp_path / "there.json"), "--scheduler",
                                   cluster.scheduler_address], capture_output=True, text=True,
                           env=env)
    assert there.returncode == 0, there.stderr
    a = json.loads((tmp_path / "here.json").read_text())
    b = json.loads((tmp_path / "there.json").read_text())
    assert a == b
    # A JSON file stabilis writes names its writer (so that only its own files are replaced);
    # the rest is Python's result.
    assert a.pop("written_by").startswith("stabilis ")
    py = stabilis.power(MODEL, [logs], progress=False, **STUDY)
    assert py == a
    # The fields.
    assert a["effect"] == "cart_friction" and a["campaigns"] == 8
    for v in a["values"]:
        assert {"value", "detection_rate", "ci", "other_found_rate", "unexplained_rate",
                "estimate_mean", "estimate_std"} <= set(v)
    assert set(a["min_detectable"]) >= {"value", "ci"}
    html = (tmp_path / "report" / "index.html").read_text()
    assert html.count("<svg") >= 2 and "power" in html
    assert json.loads((tmp_path / "report" / "power.json").read_text()) == {**a, "written_by": b["written_by"]}


def test_scheduler_without_the_python_package_says_what_is_missing(logs, tmp_path):
    env = dict(os.environ, STABILIS_PYTHON=sys.executable, PYTHONPATH=str(tmp_path))
    env.pop("PYTHONHOME", None)
    r = subprocess.run([stabilis_bin(), "power", "--model", str(MODEL), "--data", str(logs),
                        "--effect", "cart_friction", "--values", "0", "--campaigns", "1",
                        "--scheduler", "tcp://127.0.0.1:1"], capture_output=True, text=True,
                       env=dict(env, PYTHONNOUSERSITE="1"), cwd=tmp_path)
    if r.returncode == 0:
        pytest.skip("this interpreter finds stabilis outside PYTHONPATH")
    assert r.returncode == 2, r.stderr
    assert "must import stabilis and dask.distributed" in r.stderr


def cochran_armitage_z(values, successes, trials):
    """Cochran-Armitage trend statistic (scores = the values), standard normal under no trend."""
    n = sum(trials)
    p = sum(successes) / n
    t = sum(x * (s - m * p) for x, s, m in zip(values, successes, trials))
    var = p * (1 - p) * (sum(m * x * x for x, m in zip(values, trials))
                         - sum(m * x for x, m in zip(values, trials)) ** 2 / n)
    return t / math.sqrt(var)


LADDER = [0.0, 0.05, 0.1, 0.15, 0.2, 0.3, 0.6]
B_LARGE = 0.6


def test_power_rises_with_the_friction_and_reaches_95_percent_where_one_campaign_is_clear(
        logs, tmp_path):
    r = stabilis.power(MODEL, [logs], effect="cart_friction", values=LADDER, campaigns=20,
                       seed=2, progress=False)
    rates = [v["detection_rate"] for v in r["values"]]
    done = [v["completed"] for v in r["values"]]
    assert done == [20] * len(LADDER) and not r["failures"]
    z = cochran_armitage_z(LADDER, [round(p * 20) for p in rates], done)
    print("power", dict(zip(LADDER, rates)), "trend z", z, "min detectable",
          r["min_detectable"], "noise ratio", r["noise_ratio"])
    assert z > 3.09, z  # one-sided p < 0.001 for a rising trend
    # No significant fall anywhere: later rates stay within the earlier interval.
    for i in range(1, len(LADDER)):
        assert rates[i] >= r["values"][i - 1]["ci"][0], (LADDER[i], rates)
    # The campaigns have the logs' noise (calibrated to the period-to-period noise).
    assert all(0.8 < q < 1.25 for q in r["noise_ratio"]), r["noise_ratio"]
    # Where one campaign of the independent simulator (not the power study's) finds friction
    # with a wide margin, the study's power is at least 95 % and the estimate unbiased.
    clear = tmp_path / "clear"
    ic.campaign(clear, plant=replace(ic.Plant(), b=B_LARGE), seed=9, **SHORT)
    d = stabilis.Workbench(model=stabilis.Model.from_file(MODEL), data=[clear]).discover()
    assert d["found"] == ["cart_friction"]
    first = {c["effect"]: c for c in d["steps"][0]["candidates"]}["cart_friction"]
    assert first["p_value"] < 1e-6 * d["level"], first
    top = r["values"][-1]
    assert top["detection_rate"] >= 0.95, top
    assert abs(top["estimate_mean"] / B_LARGE - 1) < 0.05, top
    md = r["min_detectable"]
    assert LADDER[0] < md["value"] < B_LARGE
    # The sizing: a fit of the model with the friction sizes b on these logs about as
    # precisely as on the study's simulated records, and that error is the scatter of the
    # campaigns' estimates where all find it (measured here: logs / simulated 1.32, logs /
    # scatter 0.82; logs / simulated 0.88-1.38 over 12 seeds of these short logs).
    s = r["sizing"]
    print("sizing", s, "scatter at", B_LARGE, top["estimate_std"])
    assert s["warnings"] == [] and s["trades_against"] == [], s
    assert 1 / 1.5 < s["logs_std"] / s["simulated_std"] < 1.5, s
    assert 1 / 1.6 < s["logs_std"] / top["estimate_std"] < 1.6, (s, top)


NONLINEAR = Path(__file__).parent / "data" / "cart_pole_nonlinear.toml"


@pytest.mark.parametrize("seed", [11, 12])
def test_a_nonlinear_model_file_simulates_its_equations_and_finds_its_effect(logs, seed):
    # The campaigns integrate the file's nonlinear equations (its linearization's campaigns
    # differ from them by the pole's swing) with noise calibrated to the independent
    # simulator's logs. The nominal model is then explained, with no effect found, in 6 of 6
    # campaigns per seed, and a viscous friction of 0.5 N s/m found in 6 of 6 (measured: 8 of 8
    # at 0.5, 1 of 8 at 0.2, where 3 of 8 read unexplained: the misfit seen, the effect not
    # yet significant).
    r = stabilis.power(NONLINEAR, [logs], effect="cart_viscous", values=[0.0, 0.5],
                       campaigns=6, seed=seed, threads=2, progress=False)
    assert "nonlinear equations integrated" in r["policy"]
    zero, half = r["values"]
    assert zero["completed"] == 6 and half["completed"] == 6
    assert zero["false_discovery_rate"] == 0 and zero["unexplained_rate"] == 0, zero
    assert half["detection_rate"] == 1 and abs(half["estimate_mean"] - 0.5) < 0.05, half
    # The simulated noise is the logs' on every output.
    assert all(0.85 < x < 1.15 for x in r["noise_ratio"]), r["noise_ratio"]


@pytest.mark.parametrize("seed", [11, 12])
def test_an_effect_seen_but_not_confirmed_is_counted_tentative(logs, seed):
    # At 100 Hz a lag of a fifth of a sample fits the logs as a delay does: the discovery
    # adds one and names the other its rival, so the effect is seen but not found (measured:
    # 4 of 8 tentative at 2 ms for both seeds, none found; at 8 ms 8 of 8 and 6 of 8 found,
    # the rest tentative; nothing at 0).
    r = stabilis.power(MODEL, [logs], effect="actuator_lag", values=[0.0, 0.002, 0.008],
                       campaigns=8, seed=seed, threads=2, progress=False)
    zero, small, large = r["values"]
    assert zero["tentative_rate"] == 0 and zero["detection_rate"] == 0, zero
    assert small["tentative_rate"] >= 0.25 and small["detection_rate"] <= 0.25, small
    assert large["detection_rate"] >= 0.5, large
    for v in r["values"]:
        assert v["detection_rate"] + v["tentative_rate"] <= 1, v


def test_the_criterion_of_a_study_is_the_users_choice(logs):
    # Under the FRF criterion the file's smoothed dry friction, linearized at rest, is a
    # viscous friction too: the two are rivals the data cannot tell apart, so the viscous
    # friction that the time criterion finds in 6 of 6 campaigns is found in none (tentative),
    # while the nominal campaigns stay explained.
    r = stabilis.power(NONLINEAR, [logs], effect="cart_viscous", values=[0.0, 0.5],
                       campaigns=6, seed=11, threads=2, progress=False, criterion="frf")
    assert r["policy"].endswith("under the FRF criterion"), r["policy"]
    zero, half = r["values"]
    assert zero["unexplained_rate"] == 0 and zero["false_discovery_rate"] == 0, zero
    assert half["detection_rate"] == 0 and half["unexplained_rate"] == 0, half
    with pytest.raises(stabilis.SimError, match="needs a nonlinear model"):
        stabilis.power(MODEL, [logs], effect="cart_friction", values=[0.0], campaigns=1,
                       progress=False, criterion="time")
    with pytest.raises(ValueError, match="unknown criterion"):
        stabilis.power(MODEL, [logs], effect="cart_friction", values=[0.0], campaigns=1,
                       progress=False, criterion="FRF")


def test_false_discovery_rate_at_zero_is_within_the_level_and_monte_carlo_error(logs):
    n = 100
    r = stabilis.power(MODEL, [logs], effect="cart_friction", values=[0.0], campaigns=n,
                       seed=4, progress=False)
    v = r["values"][0]
    level = r["level"]
    assert level == 0.01
    # Any effect found while the nominal model is the truth, against the discovery's nominal
    # level plus two binomial standard errors of a rate at that level over n campaigns.
    bound = level + 2 * math.sqrt(level * (1 - level) / n)
    print("false discoveries", v["false_discovery_rate"], v["false_discovery_ci"],
          "bound", bound, "unexplained", v["unexplained_rate"])
    assert v["completed"] == n
    assert v["false_discovery_rate"] <= bound, v
    # The verdict's noise test ("unexplained") is not an effect found; on logs of 4 periods
    # it rejects the true model more often than its nominal level (4 of 100 measured), as its
    # noise reference comes from 3 degrees of freedom of period-to-period variation per line.
    assert v["unexplained_rate"] <= 0.1, v


def test_a_diverging_campaign_is_counted_and_named_and_the_study_goes_on(logs):
    # A transport delay of 0.1 s destabilises the experimenter's loop.
    r = stabilis.power(MODEL, [logs], effect="input_delay", values=[0.0, 0.1], campaigns=2,
                       seed=1, progress=False)
    assert [v["completed"] for v in r["values"]] == [2, 0]
    assert [v["failed"] for v in r["values"]] == [0, 2]
    assert len(r["failures"]) == 2 and all("diverges" in f["error"] for f in r["failures"])
    assert all(f["value"] == 0.1 for f in r["failures"])


def test_bad_studies_are_refused_by_name(logs, tmp_path):
    with pytest.raises(stabilis.Error, match="must increase"):
        stabilis.power(MODEL, [logs], effect="cart_friction", values=[0.2, 0.1], campaigns=1)
    with pytest.raises(stabilis.Error, match="no_such_effect"):
        stabilis.power(MODEL, [logs], effect="no_such_effect", values=[0.1], campaigns=1)
    bare = tmp_path / "no_controller.toml"
    bare.write_text(MODEL.read_text().split("[controller]")[0])
    with pytest.raises(stabilis.Error, match=r"\[controller\]"):
        stabilis.power(bare, [logs], effect="cart_friction", values=[0.1], campaigns=1)
    with pytest.raises(TypeError, match="path of a model file"):
        stabilis.power(stabilis.Model.from_file(MODEL), [logs], effect="cart_friction",
                       values=[0.1], campaigns=1)


def test_every_plot_of_the_power_report_draws_in_a_browser(logs, tmp_path):
    report = tmp_path / "report"
    stabilis.power(MODEL, [logs], effect="cart_friction", values=[0.0, 0.2, 0.4], campaigns=3,
                   progress=False, report=report)
    html = (report / "index.html").read_text()
    assert "<script" not in html
    plots = measured_plots(html, tmp_path)
    # Power with its band, the other rates, the estimates.
    assert len(plots) == 3, plots
    for p in plots:
        assert p["width"] > 100 and p["height"] > 100 and p["marks"] >= 2, p
    assert "power" in plots[0]["title"]


def test_the_study_scales_noise_that_hides_the_effect_otherwise_and_says_so(tmp_path):
    # The independent simulator's pole torque disturbance enters where the noise the study
    # estimates (the Kalman predictor's, calibrated to the logs' period-to-period noise) does
    # not put it: with ten times its default, the calibrated noise hides the cart's friction
    # 2.6 times as much as the logged noise does (a fit sizes b to ±0.037 on the simulated
    # records, ±0.014 on the logs: the logs' error is the scatter of independent logs,
    # test_the_logs_error_of_the_friction_is_the_scatter_of_independent_logs). The study
    # scales its noise by that ratio (0.38 on both seeds), its records then size b as the
    # logs do (measured again), and the noise check names the price: the scaled noise is
    # below the logs' on both outputs (0.38 in all). With the default noise (the README's
    # study) the two errors agree, nothing is scaled and the check says nothing.
    for seed in (1, 2):
        plain, torque = tmp_path / f"plain{seed}", tmp_path / f"torque{seed}"
        ic.campaign(plain, plant=ic.Plant(), seed=seed)
        ic.campaign(torque, plant=ic.Plant(), seed=seed, torque_noise=0.02)
        quiet = stabilis.power(MODEL, [plain], effect="cart_friction", values=[0.0],
                               campaigns=1, seed=3, progress=False)
        assert quiet["noise_warnings"] == [], quiet["noise_warnings"]
        assert quiet["sizing"]["rescaled"] is None, quiet["sizing"]
        r = stabilis.power(MODEL, [torque], effect="cart_friction", values=[0.0],
                           campaigns=1, seed=3, progress=False)
        s = r["sizing"]
        print(seed, "sizing", s)
        scale = s["rescaled"]
        assert scale is not None and scale["factor"] < 1 / 1.5, s
        assert abs(scale["factor"] - s["logs_std"] / scale["unscaled_std"]) < 1e-9, s
        assert 1 / 1.15 < s["logs_std"] / s["simulated_std"] < 1.15, s
        assert any("scales every noise source by" in w for w in s["warnings"]), s
        assert not any("likely too" in w for w in s["warnings"]), s
        print(seed, [(w["output"], w["band_hz"], round(w["ratio"], 2))
                     for w in r["noise_warnings"]])
        totals = [w for w in r["noise_warnings"] if w["band_hz"] is None]
        assert sorted(w["output"] for w in totals) == ["theta", "x"], r["noise_warnings"]
        for w in r["noise_warnings"]:
            assert w["ratio"] < 1 / 1.15 and "scaled its noise by" in w["message"], w


@pytest.mark.campaign
def test_the_logs_error_of_the_friction_is_the_scatter_of_independent_logs(tmp_path):
    # The sizing's error on the logs is what independent logs bear out: 8 seeds of the
    # cart-pole with a friction of 0.06 and ten times the pole torque noise; the estimates'
    # standard deviation against the mean reported error (measured 0.0122 against 0.0142, a
    # ratio 0.86; an 8-sample standard deviation is itself uncertain by about 27 %).
    estimates, errors = [], []
    for seed in range(1, 9):
        d = tmp_path / f"torque{seed}"
        ic.campaign(d, plant=ic.Plant(b=0.06), seed=seed, torque_noise=0.02)
        s = stabilis.power(MODEL, [d], effect="cart_friction", values=[0.0], campaigns=1,
                           seed=3, progress=False)["sizing"]
        estimates.append(s["logs_estimate"])
        errors.append(s["logs_std"])
    ratio = statistics.stdev(estimates) / statistics.mean(errors)
    print("scatter / reported error", ratio, estimates, errors)
    assert 0.5 < ratio < 1.6, (estimates, errors)


@pytest.mark.campaign
def test_the_scaled_studys_rates_are_the_rates_of_independent_records(tmp_path):
    # What the scaling along the effect is for: the study's detection rates, prepared from
    # nominal logs with ten times the pole torque noise, against how often the discovery finds
    # the friction in independent records that have it (20 seeds per value). Measured with 40
    # records and 20 campaigns (README): records 10 %, 58 %, 100 % at b = 0.06, 0.08, 0.1;
    # the study 15-25 %, 65-85 %, 100 % on seeds 1 and 2; unscaled 0 %, 0 %, 0 %. The two 95 %
    # intervals must overlap at 0.08 and 0.1 (at 0.06 the unscaled study's 0 % would too).
    from scipy.stats import binomtest

    values = [0.08, 0.1]
    records = {}
    for b in values:
        found = 0
        for seed in range(1, 21):
            d = tmp_path / f"b{b}_{seed}"
            ic.campaign(d, plant=ic.Plant(b=b), seed=seed, torque_noise=0.02)
            wb = stabilis.Workbench(model=str(MODEL), data=sorted(str(p) for p in d.iterdir()))
            found += "cart_friction" in wb.discover()["found"]
        records[b] = found
    for seed in (1, 2):
        d = tmp_path / f"nominal{seed}"
        ic.campaign(d, plant=ic.Plant(), seed=seed, torque_noise=0.02)
        r = stabilis.power(MODEL, [d], effect="cart_friction", values=values, campaigns=20,
                           seed=3, progress=False)
        assert r["sizing"]["rescaled"] is not None, r["sizing"]
        for v in r["values"]:
            ci = binomtest(records[v["value"]], 20).proportion_ci(method="exact")
            print(seed, v["value"], "study", v["detection_rate"], v["ci"],
                  "records", records[v["value"]], "of 20")
            assert v["ci"][0] <= ci.high and ci.low <= v["ci"][1], (v, records)
