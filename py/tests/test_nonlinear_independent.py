"""Issue 15 acceptance: nonlinear grey-box model files, on the independent cart-pole simulator
(independent_cartpole.py: numpy/scipy, no stabilis code) described to stabilis only by
data/cart_pole_nonlinear.toml (the full rigid-body equations, viscous and smoothed dry friction
as declared effects) and, for the FRF path, by the linear data/cart_pole.toml.

The first group needs no stabilis: the file's f and h are the simulator's equations of motion
(read with this module's own evaluator, at random states, inputs and parameters, with and
without each effect), the sensor offsets are what the generic `sensor_bias` effect describes,
the campaign's excitation separates dry from viscous friction (an independent regression on
the simulator's true states says which law moved the cart), and an offset on x is exactly a
start elsewhere (the cart-pole is translation invariant), so no tool can find it.

The acceptance group runs `stabilis discover --model FILE --data DIR --json OUT` (the
time-domain prediction-error criterion is the default for a `[nonlinear]` file) on campaigns
of the issue's size (4 experiments x 8300 samples at 100 Hz, the stronger excitation
ic.FRICTION_EXCITATION, the truth's M, m, l, J 2-5 % off the documented values), three seeds
per hidden truth; every seed is its own test case, so the pass rate is the count of passing
cases (the acceptance asks 3 of 3). It fails (does not skip) on a binary without issue 15.
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

import independent_cartpole as ic
from test_cartpole_independent import (bad_copy, cli, evaluate, param, read_log, refused,
                                       require_model_option)

DATA = Path(__file__).parent / "data"
MODEL = DATA / "cart_pole_nonlinear.toml"
LINEAR = DATA / "cart_pole.toml"
TOLERANCE = 0.20  # the tolerance on a hidden level, relative

# Hidden truths (Plant fields changed from the nominal class).
B_TRUE = 1.2  # cart viscous friction, N s/m (the file documents 0.5)
FC_TRUE = 0.3  # cart dry friction, N (the file documents 0.5), unsmoothed in the truth
OFFSET_THETA = 0.01  # pole angle sensor offset, rad (the case)
OFFSET_X = 0.02  # cart position sensor offset, m
CASES = {
    "nothing": {},
    "viscous": {"b": B_TRUE},
    "dry": {"coulomb": FC_TRUE, "coulomb_v": 0.0},
    "offset_theta": {"offset_theta": OFFSET_THETA},
    "offset_x": {"offset_x": OFFSET_X},
}
SEEDS = {"nothing": (101, 102, 103), "viscous": (111, 112, 113), "dry": (121, 122, 123),
         "offset_theta": (131, 132, 133), "offset_x": (141, 142, 143)}
EPS = 0.05  # the file's smoothing speed of the dry friction, m/s


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


@pytest.mark.parametrize("case", ["nothing", "viscous", "dry"])
def test_the_campaign_separates_dry_from_viscous_friction(case):
    # Under FRICTION_EXCITATION the cart moves faster than EPS on most samples (measured over
    # seeds 1-2: 70-76 %; faster than 0.1 m/s: 50-53 %) with the pole within 0.13 rad of
    # upright. An independent check that the motion holds the law: the force the true motion
    # implies beyond the command, regressed on each law, leaves the force disturbance
    # (0.05 N rms) for the right law and clearly more for the wrong one; the dry level comes
    # out 10 % high (the file's eps smooths what the truth does not), inside the 20 %.
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
        else:
            assert fit["dry"][1] < 0.65 * fit["viscous"][1], fit
            assert fit["dry"][0] == pytest.approx(FC_TRUE, rel=0.15), fit


# --- acceptance through the CLI -------------------------------------------------------------


@pytest.fixture(scope="module")
def campaigns(tmp_path_factory):
    """The campaign (4 x 8300 samples, FRICTION_EXCITATION) per (case, seed), simulated once."""
    cache = {}

    def get(case: str, seed: int) -> Path:
        if (case, seed) not in cache:
            out = tmp_path_factory.mktemp(f"nl_{case}_{seed}")
            ic.campaign(out, plant=replace(ic.Plant(), **CASES[case]), seed=seed,
                        **ic.FRICTION_EXCITATION)
            cache[case, seed] = out
        return cache[case, seed]

    return get


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


@pytest.mark.parametrize("case, seed", cases("viscous"))
def test_viscous_friction_is_found_as_the_viscous_effect(campaigns, tmp_path, case, seed):
    doc = discover(MODEL, campaigns(case, seed), tmp_path)
    assert doc["found"] == ["cart_viscous"], why(doc)
    b = param(doc, "b", "cart_viscous")
    assert abs(b / B_TRUE - 1) < TOLERANCE, (b, B_TRUE)


@pytest.mark.parametrize("case, seed", cases("dry"))
def test_dry_friction_is_found_as_the_dry_effect_at_its_level(campaigns, tmp_path, case, seed):
    # The truth's friction is unsmoothed, the file's smoothed over 0.05 m/s: the level is the
    # one the file's law fits best (the regression above puts it 10 % above the truth's).
    doc = discover(MODEL, campaigns(case, seed), tmp_path)
    assert doc["found"] == ["cart_coulomb"], why(doc)
    fc = param(doc, "fc", "cart_coulomb")
    assert abs(fc / FC_TRUE - 1) < TOLERANCE, (fc, FC_TRUE)


@pytest.mark.parametrize("case, seed", cases("offset_theta"))
def test_a_pole_angle_offset_is_found_as_sensor_bias(campaigns, tmp_path, case, seed):
    doc = discover(MODEL, campaigns(case, seed), tmp_path)
    assert doc["found"] == ["sensor_bias"], why(doc)
    bias = param(doc, "bias_theta", "sensor_bias")
    assert abs(bias / OFFSET_THETA - 1) < TOLERANCE, (bias, OFFSET_THETA)


@pytest.mark.parametrize("seed", SEEDS["nothing"])
def test_the_linear_file_keeps_the_frf_path_on_the_same_data(campaigns, tmp_path, seed):
    doc = discover(LINEAR, campaigns("nothing", seed), tmp_path)
    assert doc["found"] == [], why(doc)


@pytest.mark.parametrize("case, seed", cases("viscous", "dry"))
def test_the_linear_file_on_friction_data(campaigns, tmp_path, case, seed):
    # Through the FRF the linear file finds viscous friction at its level, and on dry friction
    # (no linear effect describes it) it finds nothing and says a misfit remains: the viscous
    # effect it tries there (at about 1.5 N s/m, the regression's equivalent) stays tentative.
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


def test_model_check_of_the_nonlinear_file_names_the_unstable_pole():
    done = cli("model", "check", MODEL)
    require_model_option(done)
    assert done.returncode == 0, done.stderr
    p = ic.documented_plant()
    jp = p.J + p.m * p.l**2
    pole = math.sqrt((p.M + p.m) * p.m * p.g * p.l / ((p.M + p.m) * jp - (p.m * p.l) ** 2))
    numbers = [float(x) for x in re.findall(r"[-+]?\d+\.\d+(?:[eE][-+]?\d+)?", done.stdout)]
    assert any(abs(x - pole) < 1e-3 * pole for x in numbers), (pole, done.stdout)
    assert "unstable" in done.stdout.lower(), done.stdout


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
    # within a few samples of moving. The prediction error cannot be computed: exit 2 with
    # the sample where it diverged, no panic, no output.
    path, _ = bad_copy(tmp_path, 'f.xdot = "(Jp*Px - mlc*Ptheta)/Delta"',
                       'f.xdot = "(Jp*Px - mlc*Ptheta)/Delta + 1e6*xdot^3"', MODEL)
    out = tmp_path / "out.json"
    done = cli("discover", "--model", path, "--data", campaigns("nothing", SEEDS["nothing"][0]),
               "--json", out)
    assert done.returncode == 2 and "panicked" not in done.stderr, done.stderr
    assert "diverg" in done.stderr.lower(), done.stderr
    assert re.search(r"sample\D{0,3}\d+", done.stderr), done.stderr
    assert not out.exists()
