"""Issue 15 acceptance: nonlinear grey-box model files, on the independent cart-pole simulator
(independent_cartpole.py: numpy/scipy, no stabilis code) described to stabilis only by
data/cart_pole_nonlinear.toml (the full rigid-body equations, viscous and smoothed dry friction
as declared effects) and, for the FRF path, by the linear data/cart_pole.toml.

The first group needs no stabilis: the file's f and h are the simulator's equations of motion
(read with the issue-12 tests' expression evaluator, at random states, inputs and parameters,
with and without each effect), the sensor offsets are what the generic `sensor_bias` effect describes,
the campaign's excitation separates dry from viscous friction (an independent regression on
the simulator's true states says which law moved the cart), an offset on x is exactly a start
elsewhere (the cart-pole is translation invariant), so no tool can find it, and, at the end of
this file, an independent prediction-error fit (a fixed-gain predictor of the nonlinear model
in absolute units, scipy least squares) finds each hidden level in the logs themselves.

The acceptance group runs `stabilis discover --model FILE --data DIR --json OUT` (the
time-domain prediction-error criterion is the default for a `[nonlinear]` file) on campaigns
of the issue's size (4 experiments x 8300 samples at 100 Hz, the stronger excitation
ic.FRICTION_EXCITATION, the truth's M, m, l, J 2-5 % off the documented values), three seeds
per hidden truth; every seed is its own test case, so the pass rate is the count of passing
cases (the acceptance asks 3 of 3); `stabilis.Model.from_file` must conclude as the CLI on the
first seed. It fails (does not skip) on a binary without issue 15.
"""
from __future__ import annotations

import json
import math
import re
import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import solve_discrete_are

import independent_cartpole as ic
from seeds import campaign_cases, campaign_seeds
from test_cartpole_independent import (bad_copy, campaign_cache, check_names_the_unstable_pole,
                                       cli, evaluate, param, python_model, read_log,
                                       refused, require_model_option)

DATA = Path(__file__).parent / "data"
MODEL = DATA / "cart_pole_nonlinear.toml"
LINEAR = DATA / "cart_pole.toml"
TOLERANCE = 0.20  # the issue's tolerance on a hidden level, relative

# Hidden truths (Plant fields changed from the nominal class).
B_TRUE = 1.2  # cart viscous friction, N s/m (the file documents 0.5)
FC_TRUE = 0.3  # cart dry friction, N (the file documents 0.5)
EPS = 0.05  # the file's smoothing speed of the dry friction, m/s
OFFSET_THETA = 0.01  # pole angle sensor offset, rad (the issue's case)
OFFSET_X = 0.02  # cart position sensor offset, m
FORCE_OFFSET = 0.2  # constant force on the cart, N (the excitation's rms is 1 N)
FLEX_HZ = 4.0  # a flexible appendage on the cart that no effect describes, Hz
CASES = {
    "nothing": {},
    "viscous": {"b": B_TRUE},
    "dry": {"coulomb": FC_TRUE, "coulomb_v": EPS},  # the file's law exactly
    "dry_sharp": {"coulomb": FC_TRUE, "coulomb_v": 0.0},  # unsmoothed: a sign
    "offset_theta": {"offset_theta": OFFSET_THETA},
    "offset_x": {"offset_x": OFFSET_X},
    "force_offset": {"force_offset": FORCE_OFFSET},
    "flex": {"flex_hz": FLEX_HZ},
}
SEEDS = {"nothing": (101, 102, 103), "viscous": (111, 112, 113), "dry": (121, 122, 123),
         "dry_sharp": (151, 152, 153), "offset_theta": (131, 132, 133),
         "offset_x": (141, 142, 143), "flex": (161, 162, 163), "force_offset": (171, 172, 173)}


# --- the nonlinear model file, read independently -----------------------------------------


def load_model(path: Path = MODEL) -> dict:
    with open(path, "rb") as f:
        return tomllib.load(f)


def value(v) -> float:
    return float(v["value"] if isinstance(v, dict) else v)


def additions(effect: dict) -> dict[tuple[str, ...], list[str]]:
    """The effect's `add` terms by target: ("Fc",) for a definition, ("f", state), ("h", output)."""
    out: dict[tuple[str, ...], list[str]] = {}
    for key, term in effect.get("add", {}).items():
        if key in ("f", "h") and isinstance(term, dict):
            for name, expr in term.items():
                out.setdefault((key, name), []).append(expr)
        else:
            out.setdefault((key,), []).append(term)
    return out


def model_functions(doc: dict, state, inputs, values: dict[str, float] | None = None,
                    effects=()) -> tuple[np.ndarray, np.ndarray]:
    """(f, h) of the file's [nonlinear] section at a state and input: documented parameter
    values where `values` has none, the `effects` added where their terms say."""
    names = {k: value(v) for k, v in doc["parameters"].items()}
    adds: dict[tuple[str, ...], list[str]] = {}
    for e in effects:
        names |= {k: value(v) for k, v in doc["effects"][e]["parameters"].items()}
        for target, terms in additions(doc["effects"][e]).items():
            adds.setdefault(target, []).extend(terms)
    names |= values or {}
    names |= dict(zip(doc["states"], map(float, state)))
    names |= dict(zip(doc["inputs"], map(float, inputs)))

    def total(target, expr):
        return evaluate(expr, names) + sum(evaluate(t, names) for t in adds.get(target, []))

    for k, expr in doc["definitions"].items():  # in file order: later ones see earlier ones
        names[k] = total((k,), expr)
    nl = doc["nonlinear"]
    f = np.array([total(("f", s), nl["f"][s]) for s in doc["states"]])
    h = np.array([total(("h", y), nl["h"][y]) for y in doc["outputs"]])
    return f, h


def test_model_file_names_and_controller_are_the_linear_files():
    doc, lin = load_model(), load_model(LINEAR)
    assert doc["name"] == ic.SYSTEM
    assert doc["states"] == ic.STATES and doc["inputs"] == ic.INPUTS
    assert doc["outputs"] == ic.OUTPUTS
    assert doc["parameters"] == lin["parameters"]
    assert doc["controller"] == lin["controller"]
    assert "linear" not in doc
    op = doc["nonlinear"]["operating_point"]
    assert set(op) == set(ic.STATES) | set(ic.INPUTS) and not any(op.values())
    assert set(doc["effects"]) == {"cart_viscous", "cart_coulomb"}
    assert doc["effects"]["cart_coulomb"]["parameters"]["eps"] == {"value": EPS, "fixed": True,
                                                                   "unit": "m/s"}


EFFECT_SETS = [(), ("cart_viscous",), ("cart_coulomb",), ("cart_viscous", "cart_coulomb")]


@pytest.mark.parametrize("effects", EFFECT_SETS, ids=["none", "viscous", "coulomb", "both"])
def test_model_file_is_the_simulators_nonlinear_plant(effects):
    # At 200 random states far from upright (|theta| up to 1.5 rad), inputs and parameters,
    # the file's f (the effects' terms added to Fc) against the simulator's `derivative`
    # (its dry friction smoothed over the file's eps), and h against the sensor's noise-free
    # reading.
    doc = load_model()
    rng = np.random.default_rng(15)
    for _ in range(200):
        p = ic.Plant(M=rng.uniform(0.3, 3), m=rng.uniform(0.05, 0.5), l=rng.uniform(0.1, 1),
                     J=rng.uniform(1e-4, 0.05), g=rng.uniform(9, 10.5),
                     b=rng.uniform(0, 5) if "cart_viscous" in effects else 0.0,
                     coulomb=rng.uniform(0.01, 3) if "cart_coulomb" in effects else 0.0,
                     coulomb_v=EPS)
        s = rng.uniform([-1, -2, -1.5, -4], [1, 2, 1.5, 4])
        force = rng.uniform(-10, 10)
        values = {"M": p.M, "m": p.m, "l": p.l, "J": p.J, "g": p.g, "b": p.b, "fc": p.coulomb}
        f, h = model_functions(doc, s, [force], values, effects)
        want = np.array(ic.derivative(p, list(s), force, 0.0, 0.0))
        assert np.allclose(f, want, rtol=1e-12, atol=1e-12 * np.abs(want).max()), (f, want)
        assert np.array_equal(h, s[[0, 2]])


def test_model_file_linearised_at_its_operating_point_is_the_linear_file():
    # Central differences of the file's f at the operating point against the linear file's
    # matrices (read by the issue-12 tests' reader) and the simulator's Jacobian.
    from test_cartpole_independent import model_matrices

    doc = load_model()
    op = doc["nonlinear"]["operating_point"]
    x0, u0 = np.array([op[s] for s in doc["states"]], float), [float(op["F"])]
    d = 1e-6
    a = np.column_stack([(model_functions(doc, x0 + d * e, u0)[0]
                          - model_functions(doc, x0 - d * e, u0)[0]) / (2 * d)
                         for e in np.eye(4)])
    b = (model_functions(doc, x0, [d])[0] - model_functions(doc, x0, [-d])[0]) / (2 * d)
    lin = model_matrices(load_model(LINEAR), {})
    assert np.allclose(a, lin["A"], rtol=0, atol=1e-7), (a, lin["A"])
    assert np.allclose(b, lin["B"][:, 0], rtol=0, atol=1e-7), (b, lin["B"])
    assert np.allclose(a, ic.linearised_truth(ic.documented_plant())[0], rtol=0, atol=1e-7)


# --- the simulator's new effects -----------------------------------------------------------


def quiet(**kw) -> ic.Config:
    """A short noise-free campaign of one experiment."""
    return ic.Config(experiments=1, periods=2, force_noise=0.0, torque_noise=0.0, x_sigma=0.0,
                     theta_sigma=0.0, **kw)


def controller_dc_gain() -> np.ndarray:
    """u / y of the file's controller at DC: Cc (I - Ac)^-1 Bc + Dc, (1, 2)."""
    c = load_model()["controller"]
    ac, bc, cc, dc = (np.array(c[k], float) for k in "ABCD")
    return cc @ np.linalg.solve(np.eye(4) - ac, bc) + dc


def test_sensor_offsets_are_added_to_the_logs_and_the_loop_acts_on_them(tmp_path):
    # Noise-free, the logged outputs are the true ones plus the offsets (what sensor_bias
    # adds to h), also after an MCAP round trip. The controller acts on the offset reading:
    # the loop comes to rest where its DC gain G sends the force to zero, G (x + off_x,
    # off_theta) = 0, so the true cart sits at -off_x - G_theta / G_x off_theta (0.125 m
    # per 0.01 rad) with the pole upright, the true angle's mean unmoved.
    off = {"offset_x": 0.02, "offset_theta": 0.01}
    plain = ic.simulate(quiet(seed=3))[0]
    cfg = quiet(seed=3, plant=replace(ic.Plant(), **off))
    (run,) = ic.simulate(cfg)
    assert np.array_equal(run.y, run.state[:, [0, 2]] + [off["offset_x"], off["offset_theta"]])
    (path,) = ic.write_runs(cfg, [run], tmp_path)
    assert np.array_equal(read_log(path)[1]["/cart_pole/output"], run.y)
    g = controller_dc_gain()[0]
    rest = -off["offset_x"] - g[1] / g[0] * off["offset_theta"]
    start = cfg.transient_samples
    shift = run.state[start:].mean(0) - plain.state[start:].mean(0)
    assert shift[0] == pytest.approx(rest, rel=0.02), (shift, rest)
    assert abs(shift[2]) < 0.02 * off["offset_theta"], shift


def test_an_offset_on_x_is_exactly_a_start_elsewhere():
    # f does not depend on x: with an offset d on the x sensor, x + d obeys the same equations
    # and drives the same controller as the true x of a run started at x0 = d. The logs are
    # the same (to rounding): the offset is not in the data, whatever the estimator.
    for seed in (1, 2):
        cfg = ic.Config(experiments=1, periods=2, seed=seed, **ic.FRICTION_EXCITATION)
        moved = ic.simulate(replace(cfg, x0=OFFSET_X))[0]
        biased = ic.simulate(replace(cfg, plant=replace(cfg.plant, offset_x=OFFSET_X)))[0]
        assert np.allclose(biased.y, moved.y, rtol=0, atol=1e-12)
        assert np.allclose(biased.u, moved.u, rtol=0, atol=1e-12)
        assert not np.allclose(biased.state[:, 0], moved.state[:, 0], atol=0.1 * OFFSET_X)


def test_unsmoothed_dry_friction_is_the_limit_of_the_smoothed_one():
    p = replace(ic.Plant(), coulomb=FC_TRUE, coulomb_v=0.0)
    s = [0.0, 0.3, 0.02, -0.1]
    for v, sign in ((0.3, 1.0), (-0.3, -1.0), (0.0, 0.0)):
        s[1] = v
        smooth = ic.derivative(replace(p, coulomb_v=1e-9), s, 0.4, 0.0, 0.0)
        assert ic.derivative(p, s, 0.4, 0.0, 0.0) == pytest.approx(smooth, rel=1e-12, abs=1e-12)
        free = ic.derivative(replace(p, coulomb=0.0), s, 0.4 - sign * FC_TRUE, 0.0, 0.0)
        assert ic.derivative(p, s, 0.4, 0.0, 0.0) == pytest.approx(free, rel=1e-12, abs=1e-12)


def friction_regression(run: ic.Run, p: ic.Plant, skip: int) -> dict[str, tuple[float, float]]:
    """{law: (coefficient, rms residual)} of the force on the cart that the true motion implies
    beyond the logged command (mass matrix at the truth's values, accelerations by differences
    over each sample) fitted by least squares as -b xdot and as -fc tanh(xdot / EPS)."""
    ts = run.t[1] - run.t[0]
    s, u = run.state, run.u[:, 0]
    mid = (s[1:] + s[:-1]) / 2
    acc = np.diff(s, axis=0) / ts
    ml = p.m * p.l
    force = ((p.M + p.m) * acc[:, 1] + ml * np.cos(mid[:, 2]) * acc[:, 3]
             - ml * np.sin(mid[:, 2]) * mid[:, 3] ** 2)
    e, v = (force - u[:-1])[skip:], mid[skip:, 1]
    out = {"none": (0.0, float(np.sqrt(np.mean(e**2))))}
    for law, reg in (("viscous", -v), ("dry", -np.tanh(v / EPS))):
        c = reg @ e / (reg @ reg)
        out[law] = (float(c), float(np.sqrt(np.mean((e - c * reg) ** 2))))
    return out


@pytest.mark.parametrize("case", ["nothing", "viscous", "dry", "dry_sharp"])
def test_the_campaign_separates_dry_from_viscous_friction(case):
    # Under FRICTION_EXCITATION the cart moves faster than EPS on most samples (measured over
    # seeds 1-2: 70-76 %; faster than 0.1 m/s: 50-53 %) with the pole within 0.13 rad of
    # upright. An independent check that the motion holds the law: the force the true motion
    # implies beyond the command, regressed on each law, leaves the force disturbance
    # (0.05 N rms) for the right law and clearly more for the wrong one; the unsmoothed dry
    # level comes out 10 % high (the file's eps smooths what that truth does not).
    for seed in (1, 2):
        cfg = ic.Config(plant=replace(ic.Plant(), **CASES[case]), experiments=1, seed=seed,
                        **ic.FRICTION_EXCITATION)
        (run,) = ic.simulate(cfg)
        s = run.state[cfg.transient_samples:]
        assert np.mean(np.abs(s[:, 1]) > EPS) > 0.65, case
        assert np.mean(np.abs(s[:, 1]) > 2 * EPS) > 0.45, case
        assert np.abs(s[:, 2]).max() < 0.15 and np.abs(s[:, 0]).max() < 0.3, case
        fit = friction_regression(run, cfg.plant, cfg.transient_samples)
        floor = cfg.force_noise
        if case == "nothing":
            assert fit["none"][1] < 1.05 * floor, fit
            assert abs(fit["viscous"][0]) < 0.05 and abs(fit["dry"][0]) < 0.02, fit
        elif case == "viscous":
            assert fit["viscous"][1] < 1.05 * floor and fit["dry"][1] > 1.5 * floor, fit
            assert fit["viscous"][0] == pytest.approx(B_TRUE, rel=0.02), fit
        elif case == "dry":  # the file's law exactly
            assert fit["dry"][1] < 1.05 * floor and fit["viscous"][1] > 1.5 * floor, fit
            assert fit["dry"][0] == pytest.approx(FC_TRUE, rel=0.02), fit
        else:
            assert fit["dry"][1] < 0.65 * fit["viscous"][1], fit
            assert fit["dry"][0] == pytest.approx(FC_TRUE, rel=0.15), fit


# --- acceptance through the CLI -------------------------------------------------------------


@pytest.fixture(scope="module")
def campaigns(tmp_path_factory):
    """The campaign (4 x 8300 samples, FRICTION_EXCITATION) per (case, seed), simulated once."""
    return campaign_cache(tmp_path_factory, CASES, **ic.FRICTION_EXCITATION)


def discover(model: Path, data: Path, tmp: Path, *options: str) -> dict:
    """`stabilis discover --model model --data data --json OUT [options]`: exit 0, the JSON."""
    out = tmp / f"{model.stem}{''.join(options)}.json"
    done = cli("discover", "--model", model, "--data", data, "--json", out, *options)
    require_model_option(done)
    assert done.returncode == 0, done.stderr
    return json.loads(out.read_text())


def why(doc: dict):
    return doc["found"], doc["tentative"], doc.get("verdict_text")


def cases(*names):
    return [(c, s) for c in names for s in SEEDS[c]]


@pytest.mark.parametrize("case, seed", cases("nothing", "offset_x"))
def test_nothing_hidden_finds_nothing(campaigns, tmp_path, case, seed):
    # offset_x: the logs are those of the nominal cart started at x = OFFSET_X (see
    # test_an_offset_on_x_is_exactly_a_start_elsewhere), so nothing is hidden in them either.
    doc = discover(MODEL, campaigns(case, seed), tmp_path)
    assert doc["found"] == [] and doc["tentative"] == [], why(doc)
    # Nor does the innovations' coherence with the excitation flag a band.
    assert doc["steps"][-1]["residual_tests"]["coherence"]["band_hz"] is None, why(doc)


@pytest.mark.parametrize("case, seed", campaign_cases(SEEDS, "flex"))
def test_a_missing_mode_is_located_at_its_frequency(campaigns, tmp_path, case, seed):
    # The appendage's resonance is in no effect of the file: the verdict is a misfit, and it
    # says where: the band where the innovations cohere with the excitation holds FLEX_HZ, and
    # on each output the coherence peaks within the Hann window's main lobe (two bins) of it.
    doc = discover(MODEL, campaigns(case, seed), tmp_path)
    assert doc["unexplained"], why(doc)
    c = doc["steps"][-1]["residual_tests"]["coherence"]
    lo, hi = c["band_hz"]
    assert lo <= FLEX_HZ <= hi, c["band_hz"]
    assert f"{lo:.2f}-{hi:.2f} Hz" in doc["verdict_text"], doc["verdict_text"]
    for out in c["outputs"]:
        assert abs(out["peak"][0] - FLEX_HZ) <= 2 * c["resolution_hz"], (out, c["resolution_hz"])


# The hidden effect, the effect the discovery must name (and no other), its parameter, level.
FOUND = {"viscous": ("cart_viscous", "b", B_TRUE), "dry": ("cart_coulomb", "fc", FC_TRUE),
         "dry_sharp": ("cart_coulomb", "fc", FC_TRUE),
         "offset_theta": ("sensor_bias", "bias_theta", OFFSET_THETA),
         "force_offset": ("input_bias", "bias_F", FORCE_OFFSET)}


@pytest.mark.parametrize("case, seed", campaign_cases(SEEDS, *FOUND))
def test_a_hidden_effect_is_found_as_its_effect_at_its_level(campaigns, tmp_path, case, seed):
    # Viscous friction as cart_viscous, not cart_coulomb; dry friction as cart_coulomb, not
    # cart_viscous; the angle offset as sensor_bias (its bias_x stays unidentified: no test on
    # it); a constant force on the cart as input_bias, not as an angle offset (the loop holds
    # the force with a mean input, the offset by moving the cart with none). The unsmoothed dry friction is outside the file's class (smoothed over 0.05 m/s):
    # the best fit of the file's law leaves a misfit (23 % above the noise in the reference
    # below), so cart_coulomb may be tentative there, but it must be the only effect added,
    # its level the one the file's law fits best (8-10 % above the truth's by the references
    # here).
    effect, name, level = FOUND[case]
    doc = discover(MODEL, campaigns(case, seed), tmp_path)
    if case == "dry_sharp":
        assert doc["found"] + doc["tentative"] == [effect], why(doc)
    else:
        assert doc["found"] == [effect], why(doc)
    got = param(doc, name, effect)
    assert abs(got / level - 1) < TOLERANCE, (name, got, level)
    # And the error falls where it shows: the nonlinear predictor's 10-step fit rises on some
    # output by more than a point and falls on none by more than one.
    before, after = (dict(s["time_fit"]["prediction_error"]["k_step"])
                     for s in (doc["steps"][0], doc["steps"][-1]))
    change = [after[o] - before[o] for o in before]
    assert max(change) > 1.0 and min(change) > -1.0, (before, after)


@pytest.mark.parametrize("case", ["nothing", *campaign_seeds(*FOUND)])
def test_python_discover_with_the_nonlinear_file_concludes_as_the_cli(campaigns, tmp_path, case):
    stabilis = python_model()
    data = campaigns(case, SEEDS[case][0])
    wb = stabilis.Workbench(model=stabilis.Model.from_file(str(MODEL)), data=[str(data)])
    assert wb.discover()["found"] == discover(MODEL, data, tmp_path)["found"]


def test_a_model_with_every_parameter_held_is_discovered_from_python(campaigns, tmp_path):
    # Every parameter held at the simulator's value: the time criterion's fit has no column,
    # which once panicked (a PanicException `except Exception` misses). It concludes, with no
    # fitted parameter, through Python as through the CLI (the held values read a misfit on
    # these logs, where the fitted ones read explained: the model file is not the simulator's
    # plant to the last term).
    stabilis = python_model()
    text = MODEL.read_text()
    for name, truth in (("M", ic.Plant.M), ("l", ic.Plant.l), ("J", ic.Plant.J)):
        line = next(l for l in text.splitlines() if l.startswith(f"{name} = {{"))
        text = text.replace(line, f"{name} = {{ value = {truth!r}, fixed = true }}")
    held = tmp_path / "held.toml"
    held.write_text(text)
    data = campaigns("nothing", SEEDS["nothing"][0])
    doc = stabilis.Workbench(model=str(held), data=[str(data)]).discover()
    assert doc["steps"][0]["params"] == {}, doc["steps"][0]["params"]
    cli = discover(held, data, tmp_path)
    for key in ("found", "tentative", "unexplained"):
        assert doc[key] == cli[key], (key, why(doc), why(cli))


def test_python_criterion_keyword_is_checked(campaigns):
    # criterion="frf" fits the nonlinear file's linearization (its base step then equals the
    # CLI's --criterion frf); an unknown name and the time criterion on a linear file are
    # refused by name.
    stabilis = python_model()
    data = [str(campaigns("nothing", SEEDS["nothing"][0]))]
    wb = stabilis.Workbench(model=str(MODEL), data=data, criterion="frf")
    assert wb.fit()["found"] == []
    with pytest.raises(ValueError, match="unknown criterion"):
        stabilis.Workbench(model=str(MODEL), data=data, criterion="nope")
    with pytest.raises(Exception, match="needs a nonlinear model"):
        stabilis.Workbench(model=str(LINEAR), data=data, criterion="time")


@pytest.mark.parametrize("seed", SEEDS["nothing"])
def test_the_linear_file_keeps_the_frf_path_on_the_same_data(campaigns, tmp_path, seed):
    doc = discover(LINEAR, campaigns("nothing", seed), tmp_path)
    assert doc["found"] == [], why(doc)


@pytest.mark.parametrize("case, seed", cases("viscous", "dry", "dry_sharp"))
def test_the_linear_file_on_friction_data(campaigns, tmp_path, case, seed):
    # Through the FRF the linear file finds viscous friction at its level, and on dry friction
    # (no linear effect describes it) it finds nothing and says a misfit remains (measured on
    # the unsmoothed truth: its viscous effect tentative at about 1.5 N s/m, the regression's
    # equivalent).
    doc = discover(LINEAR, campaigns(case, seed), tmp_path)
    if case == "viscous":
        assert doc["found"] == ["cart_friction"], why(doc)
        b = param(doc, "b", "cart_friction")
        assert abs(b / B_TRUE - 1) < TOLERANCE, (b, B_TRUE)
    else:
        assert doc["found"] == [] and doc["unexplained"] is True, why(doc)


@pytest.mark.parametrize("seed", SEEDS["nothing"][:1])
def test_the_nonlinear_file_through_the_frf_path_is_its_linearisation(campaigns, tmp_path,
                                                                       seed):
    # `--criterion frf` fits the Jacobian model at the operating point, which is the linear
    # file's (test above): the base step's fit is the linear file's to 1e-4.
    data = campaigns("nothing", seed)
    doc = discover(MODEL, data, tmp_path, "--criterion", "frf")
    lin = discover(LINEAR, data, tmp_path)
    assert doc["found"] == [], why(doc)
    base, want = doc["steps"][0], lin["steps"][0]
    assert base["cost"] == pytest.approx(want["cost"], rel=1e-4), (base["cost"], want["cost"])
    for name in ("M", "l", "J"):
        got, ref = base["params"][name], want["params"][name]
        assert got == pytest.approx(ref, rel=1e-4), (name, got, ref)


@pytest.mark.parametrize("seed", SEEDS["viscous"])
def test_a_candidate_the_data_cannot_separate_is_not_scored(campaigns, seed):
    # Under the FRF criterion the smoothed dry friction, linearized at rest, is a viscous
    # friction: beside the viscous one its parameter is held, so its cost is that of the
    # documented value and no test applies; the line says so instead of a reduction.
    done = cli("discover", "--model", MODEL, "--data", campaigns("viscous", seed),
               "--criterion", "frf")
    assert done.returncode == 0, done.stderr
    held = [line for line in done.stdout.splitlines()
            if line.startswith("  not added:") and "+0 params" in line]
    assert held, done.stdout
    for line in held:
        assert "not testable at this fit" in line and "reduction" not in line, line


def test_model_check_of_the_nonlinear_file_names_the_unstable_pole():
    # Its linearisation is the linear file's, so the same eigenvalues +-p.
    check_names_the_unstable_pole(MODEL)


def test_model_check_names_the_frictions_the_linearization_cannot_tell_apart(tmp_path):
    # Linearized at rest, the smoothed dry friction is a viscous one (-fc/eps xdot): the
    # check says so before any data; a file whose base model has the same damping term
    # (the viscous friction written into the force) makes both candidates its aliases.
    done = cli("model", "check", MODEL, "--json")
    assert done.returncode == 0, done.stderr
    doc = json.loads(done.stdout)
    assert doc["rival_pairs"] == [["cart_viscous", "cart_coulomb"]], doc["rival_pairs"]
    assert doc["aliases"] == []
    damped = tmp_path / "damped.toml"
    damped.write_text(MODEL.read_text().replace('Fc = "F"', 'Fc = "F - 0.3*c0*xdot"').replace(
        "[parameters]\n", '[parameters]\nc0 = { value = 1.0, min = 0.0, max = 10.0 }\n'))
    done = cli("model", "check", damped)
    assert done.returncode == 0, done.stderr
    for effect, p in (("cart_viscous", "b"), ("cart_coulomb", "fc")):
        assert f"effect {effect}: {p} trades against c0" in done.stdout, done.stdout


# --- the same model as Python callables -------------------------------------------------------


def python_cart_pole(stabilis, **changes):
    """The file's base model (no friction) written as `stabilis.Model(f=, h=,
    operating_point=)`: the Lagrange equations of the simulator, in plain floats (a call of
    numpy on scalars costs several times more)."""
    doc = load_model()
    m, g = 0.2, 9.81  # fixed in the file

    def f(x, u, p):
        _, xd, th, thd = x.tolist()
        jp = p["J"] + m * p["l"] ** 2
        mlc = m * p["l"] * math.cos(th)
        px = float(u[0]) + m * p["l"] * math.sin(th) * thd**2
        pth = m * g * p["l"] * math.sin(th)
        det = (p["M"] + m) * jp - mlc**2
        return [xd, (jp * px - mlc * pth) / det, thd, ((p["M"] + m) * pth - mlc * px) / det]

    def h(x, u, p):
        return [x[0], x[2]]

    kw = dict(states=doc["states"], inputs=doc["inputs"], outputs=doc["outputs"],
              parameters=doc["parameters"], f=f, h=h,
              operating_point=doc["nonlinear"]["operating_point"])
    return stabilis.Model(**(kw | changes))


@pytest.fixture(scope="module")
def short_offset(tmp_path_factory):
    """A short campaign (1 x 3300 samples) with the issue's 0.01 rad angle offset: Python
    callables cost one interpreter call per model evaluation."""
    out = tmp_path_factory.mktemp("short_offset")
    ic.campaign(out, plant=replace(ic.Plant(), offset_theta=OFFSET_THETA), seed=7,
                experiments=1, periods=3, **ic.FRICTION_EXCITATION)
    return out


def test_python_callables_discover_as_the_model_file(short_offset):
    # The callables' linearization (central differences) is the file's (symbolic) to 1e-7;
    # discovery on them finds the offset as the file does, every fitted parameter the file's
    # to 1e-4 relative, the offset within the issue's 20 %.
    stabilis = python_model()
    model = python_cart_pole(stabilis)
    file = stabilis.Model.from_file(str(MODEL))
    for k, want in file.matrices().items():
        got = model.matrices()[k]
        assert np.allclose(got, want, rtol=1e-7, atol=1e-7), (k, got, want)
    data = [str(short_offset)]
    doc = stabilis.Workbench(model=model, data=data).discover()
    ref = stabilis.Workbench(model=file, data=data).discover()
    assert doc["found"] == ref["found"] == ["sensor_bias"], why(doc)
    # The cart position's offset is not determined (the cart's position enters nothing but
    # the loop, and each record's start state absorbs it): compared where the standard error
    # is below the value.
    std = ref["steps"][-1]["std"]
    for name, want in ref["steps"][-1]["params"].items():
        if std.get(name) is not None and std[name] < abs(want):
            assert doc["steps"][-1]["params"][name] == pytest.approx(want, rel=1e-4), name
    bias = param(doc, "bias_theta")
    assert abs(bias / OFFSET_THETA - 1) < TOLERANCE, bias


class Boom(Exception):
    pass


def test_python_callables_errors_are_named_or_the_users_own():
    stabilis = python_model()
    op = load_model()["nonlinear"]["operating_point"]

    def boom(x, u, p):
        raise Boom("from the user's f")

    with pytest.raises(Boom, match="user's f"):
        python_cart_pole(stabilis, f=boom)
    with pytest.raises(ValueError, match=r"f\(x, u, params\) returned 3 values, expected 4"):
        python_cart_pole(stabilis, f=lambda x, u, p: [0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match=r"h\(x, u, params\)\[1\] = NaN"):
        python_cart_pole(stabilis, h=lambda x, u, p: [x[0], float("nan")])
    with pytest.raises(ValueError, match="operating_point is missing \"thetadot\""):
        python_cart_pole(stabilis, operating_point={k: v for k, v in op.items()
                                                    if k != "thetadot"})
    with pytest.raises(ValueError, match="neither a state nor an input"):
        python_cart_pole(stabilis, operating_point=op | {"omega": 0.0})
    with pytest.raises(ValueError, match="needs operating_point"):
        python_cart_pole(stabilis, operating_point=None)
    with pytest.raises(TypeError, match="matrices= .* or both f= and h="):
        python_cart_pole(stabilis, matrices=lambda p: None)
    with pytest.raises(TypeError, match="h must be callable"):
        python_cart_pole(stabilis, h=3)


# --- named errors -----------------------------------------------------------------------------


@pytest.mark.parametrize("old, new, names", [
    ("thetadot = 0, F = 0 }", "F = 0 }", ["operating_point", "thetadot"]),
    (", F = 0 }", " }", ["operating_point", r"\bF\b"]),
    ('f.xdot = "(Jp*Px - mlc*Ptheta)/Delta"', 'f.xdot = "1/x"', [r"f\.xdot"]),
    ('h.theta = "theta"', 'h.theta = "log(theta)"', [r"h\.theta"]),
], ids=["operating-point-without-thetadot", "operating-point-without-F",
        "f-infinite-at-operating-point", "h-infinite-at-operating-point"])
def test_bad_nonlinear_file_is_refused_naming_file_and_key(campaigns, tmp_path, old, new,
                                                             names):
    # Exit 2 from `discover` and from `model check`, stderr naming the file and the key, no
    # panic, no output written (`refused`).
    path, _ = bad_copy(tmp_path, old, new, MODEL)
    err = refused(path, campaigns("nothing", SEEDS["nothing"][0]), tmp_path)
    for name in names:
        assert re.search(name, err), (name, err)
    done = cli("model", "check", path)
    assert done.returncode == 2 and path.name in done.stderr, done.stderr
    assert all(re.search(n, done.stderr) for n in names), done.stderr


def test_a_diverging_predictor_is_refused_naming_the_sample(campaigns, tmp_path):
    # f.xdot with a cubic blow-up in xdot: finite (zero) at the operating point, infinite
    # within a few samples of moving (this file's fixed-gain predictor: from sample 3). The
    # prediction error cannot be computed: exit 2 with the sample where it diverged, no
    # panic, no output.
    path, _ = bad_copy(tmp_path, 'f.xdot = "(Jp*Px - mlc*Ptheta)/Delta"',
                       'f.xdot = "(Jp*Px - mlc*Ptheta)/Delta + 1e6*xdot^3"', MODEL)
    out = tmp_path / "out.json"
    done = cli("discover", "--model", path, "--data", campaigns("nothing", SEEDS["nothing"][0]),
               "--json", out)
    assert done.returncode == 2 and "panicked" not in done.stderr, done.stderr
    assert "diverg" in done.stderr.lower(), done.stderr
    assert re.search(r"sample\D{0,3}\d+", done.stderr), done.stderr
    assert not out.exists()


# --- the logs carry what the acceptance asks: an independent prediction-error fit ---------


def cart_pole_rhs(p: dict[str, np.ndarray], s: np.ndarray, force: np.ndarray) -> np.ndarray:
    """The file's f with both frictions, vectorised: parameters (P, 1), states (P, E, 4)."""
    m, g = 0.2, 9.81  # fixed in the file
    xd, th, thd = s[..., 1], s[..., 2], s[..., 3]
    fc = force - p["b"] * xd - p["fc"] * np.tanh(xd / EPS)
    jp = p["J"] + m * p["l"] ** 2
    mlc = m * p["l"] * np.cos(th)
    px = fc + m * p["l"] * np.sin(th) * thd**2
    pth = m * g * p["l"] * np.sin(th)
    det = (p["M"] + m) * jp - mlc**2
    return np.stack([xd, (jp * px - mlc * pth) / det, thd, ((p["M"] + m) * pth - mlc * px) / det],
                    axis=-1)


def predictor_gain(cfg: ic.Config) -> tuple[np.ndarray, np.ndarray]:
    """(K, W): the stationary Kalman gain of the documented linearised model for the
    campaign's force and torque disturbances and sensor noise, and the whitening of its
    innovations (W' S W = I)."""
    ts = 1.0 / cfg.sample_rate_hz
    p = ic.documented_plant()
    a, b, c = ic.nominal_linear(p)
    jp = p.J + p.m * p.l**2
    d = (p.M + p.m) * jp - (p.m * p.l) ** 2
    torque = np.array([[0.0], [-p.m * p.l / d], [0.0], [(p.M + p.m) / d]])
    ad, bd = ic.zoh(a, b, ts)
    _, td = ic.zoh(a, torque, ts)
    q = cfg.force_noise**2 * bd @ bd.T + cfg.torque_noise**2 * td @ td.T + 1e-14 * np.eye(4)
    r = np.diag([cfg.x_sigma**2, cfg.theta_sigma**2])
    pp = solve_discrete_are(ad.T, c.T, q, r)
    s = c @ pp @ c.T + r
    return pp @ c.T @ np.linalg.inv(s), np.linalg.cholesky(np.linalg.inv(s))


def prediction_errors(params: list[dict[str, float]], u: np.ndarray, y: np.ndarray,
                      gain: np.ndarray, ts: float, skip: int) -> np.ndarray:
    """One-step prediction errors (P, samples - skip, E, 2) of a fixed-gain predictor of the
    nonlinear model, in absolute units from the operating point, for P parameter sets at once:
    e = y - h(x) - bias, x += K e, then RK4 (two steps) over the sample with the held input."""
    names = ("M", "l", "J", "b", "fc", "bias_x", "bias_theta")
    p = {n: np.array([q.get(n, 0.0) for q in params])[:, None] for n in names}
    bias = np.stack([p["bias_x"], p["bias_theta"]], axis=-1)
    s = np.zeros((len(params), u.shape[1], 4))
    out = np.empty((len(params), *y.shape))
    h = ts / 2
    for k in range(len(u)):
        e = y[k] - s[..., [0, 2]] - bias
        out[:, k] = e
        s = s + e @ gain.T
        for _ in range(2):
            k1 = cart_pole_rhs(p, s, u[k])
            k2 = cart_pole_rhs(p, s + 0.5 * h * k1, u[k])
            k3 = cart_pole_rhs(p, s + 0.5 * h * k2, u[k])
            k4 = cart_pole_rhs(p, s + h * k3, u[k])
            s = s + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return out[:, skip:]


SCALE = {"M": 1.0, "l": 0.3, "J": 0.006, "b": 1.0, "fc": 0.3, "bias_theta": 0.01}


def prediction_error_fit(cfg: ic.Config, paths: list[Path], extra: list[str]):
    """scipy least_squares of the whitened prediction errors over M, l, J and `extra` from
    the documented values (bias from 0): ({name: value}, cost per residual)."""
    from scipy.optimize import least_squares

    logs = [read_log(path)[1] for path in paths]
    u = np.column_stack([log["/cart_pole/input"][:, 0] for log in logs])
    y = np.stack([log["/cart_pole/output"] for log in logs], axis=1)
    gain, white = predictor_gain(cfg)
    names = ["M", "l", "J", *extra]
    start = {"M": 1.0, "l": 0.3, "J": 0.006, "b": 0.5, "fc": 0.5, "bias_theta": 0.0}
    scale = np.array([SCALE[n] for n in names])
    cache = {}

    def batch(x):  # residuals at x and at x + h e_j (the Jacobian's differences), one pass
        key = x.tobytes()
        if key not in cache:
            steps = 1e-6 * scale
            xs = [x] + [x + steps[j] * np.eye(len(x))[j] for j in range(len(x))]
            e = prediction_errors([dict(zip(names, v)) for v in xs], u, y, gain,
                                  1.0 / cfg.sample_rate_hz, cfg.transient_samples)
            r = (e @ white).reshape(len(xs), -1)
            cache.clear()
            cache[key] = r[0], ((r[1:] - r[0]) / steps[:, None]).T
        return cache[key]

    fit = least_squares(lambda x: batch(x)[0], np.array([start[n] for n in names]),
                        jac=lambda x: batch(x)[1], x_scale=scale, method="lm")
    return dict(zip(names, fit.x)), float(np.mean(fit.fun**2))


@pytest.mark.parametrize("case, right, wrong, most", [
    ("nothing", [], None, 1.1), ("viscous", ["b"], ["fc"], 1.1),
    # The slower reference fits (half a minute to two minutes each) run with the campaigns.
    pytest.param("dry", ["fc"], ["b"], 1.1, marks=pytest.mark.campaign),
    pytest.param("dry_sharp", ["fc"], ["b"], 1.5, marks=pytest.mark.campaign),
    pytest.param("offset_theta", ["bias_theta"], [], 1.1, marks=pytest.mark.campaign),
], ids=["nothing", "viscous", "dry", "dry_sharp", "offset_theta"])
def test_the_logs_identify_the_hidden_effect_by_prediction_error(tmp_path, case, right, wrong,
                                                                  most):
    # An independent reference for the acceptance, on one experiment of the campaign (the
    # first seed's settings): a fixed-gain nonlinear predictor in absolute units fitted by
    # scipy reaches the noise level (cost per whitened residual near 1; measured 0.97-1.00)
    # with the right effect and recovers its level within the acceptance's 20 % (measured:
    # b 1.201, fc 0.300, bias 0.01002), while the wrong effect, or none, stays far above it
    # (measured: 1.86 for dry on viscous data, 2.51 for viscous on dry, 5.11 without the
    # bias). The unsmoothed dry friction is outside the file's class: the file's law fits it
    # at 1.23 with fc 0.325, viscous at 3.87.
    cfg = ic.Config(plant=replace(ic.Plant(), **CASES[case]), experiments=1,
                    seed=SEEDS[case][0], **ic.FRICTION_EXCITATION)
    paths = ic.write_runs(cfg, ic.simulate(cfg), tmp_path)
    params, cost = prediction_error_fit(cfg, paths, right)
    assert cost < most, (cost, params)
    truth = {"b": B_TRUE, "fc": FC_TRUE, "bias_theta": OFFSET_THETA}
    for name in right:
        assert abs(params[name] / truth[name] - 1) < TOLERANCE, (name, params)
    if wrong is not None:
        other, other_cost = prediction_error_fit(cfg, paths, wrong)
        assert other_cost > 1.4 * cost, (other_cost, cost, other)
