"""Issue 12 acceptance on a system stabilis does not ship: a cart-pole balanced by its own LQG
controller, simulated by independent_cartpole.py (numpy/scipy and the official `mcap` writer,
no stabilis code), described to stabilis only by the model file data/cart_pole.toml.

The first group checks the simulator and the model file without stabilis: the file's matrices
are the Jacobians of the nonlinear plant at upright, the file's controller is the simulator's,
the nonlinear closed loop matches the exact discretisation of its linearisation (delay
included), and the logs read back with the `mcap` package as DESIGN.md specifies.

The acceptance group runs `stabilis discover --model FILE --data DIR --json OUT` and
`stabilis.Workbench(model=stabilis.Model.from_file(FILE), data=[DIR]).discover()` on the
issue's campaign size (4 experiments x 8300 samples at 100 Hz) for each hidden truth, several
seeds each (every seed is its own test case, so the pass rate is the count of passing cases).
Where the binary or the Python package lacks issue 12's features the tests fail and say so.
"""
from __future__ import annotations

import ast
import json
import math
import re
import subprocess
import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

import independent_cartpole as ic
from seeds import campaign_cases
from test_interop import stabilis_bin

MODEL = Path(__file__).parent / "data" / "cart_pole.toml"
TOLERANCE = 0.15  # the parameter tolerance, relative

# Hidden truths (the Plant fields changed from the nominal class).
B_TRUE = 1.2  # cart viscous friction, N s/m (the file documents 0.5)
TAU_TRUE = 0.03  # actuator lag, s
TD_TRUE = 0.015  # transport delay, s (1.5 samples: fractional beyond the hold)
FLEX_HZ = 4.0  # flexible appendage on the cart (5 % damped, 0.05 kg)
CASES = {
    "nothing": {},
    "friction": {"b": B_TRUE},
    "lag": {"tau": TAU_TRUE},
    "delay": {"td": TD_TRUE},
    "friction+lag": {"b": B_TRUE, "tau": TAU_TRUE},
    "friction+delay": {"b": B_TRUE, "td": TD_TRUE},
    "flex": {"flex_hz": FLEX_HZ},
}
SEEDS = {"nothing": (1, 2, 3), "friction": (11, 12, 13), "lag": (21, 22, 23),
         "delay": (31, 32, 33), "friction+lag": (41, 42), "friction+delay": (51, 52),
         "flex": (61, 62)}


# --- the model file, read independently -------------------------------------------------

FUNCTIONS = {"sin": math.sin, "cos": math.cos, "tan": math.tan, "exp": math.exp,
             "log": math.log, "sqrt": math.sqrt, "abs": abs, "tanh": math.tanh}


def evaluate(expr, names: dict[str, float]) -> float:
    """A number, or an expression of the issue's grammar (+ - * / ^, parentheses, the listed
    functions, numbers, names) evaluated with Python's parser (^ read as power)."""
    if isinstance(expr, (int, float)):
        return float(expr)

    def walk(node):
        if isinstance(node, ast.Expression):
            return walk(node.body)
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)):
            return float(node.value)
        if isinstance(node, ast.Name):
            return names[node.id]
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            v = walk(node.operand)
            return -v if isinstance(node.op, ast.USub) else v
        if isinstance(node, ast.BinOp):
            a, b = walk(node.left), walk(node.right)
            ops = {ast.Add: np.add, ast.Sub: np.subtract, ast.Mult: np.multiply,
                   ast.Div: np.divide, ast.Pow: np.power}
            return float(ops[type(node.op)](a, b))
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name):
            return FUNCTIONS[node.func.id](*map(walk, node.args))
        raise ValueError(f"not in the grammar: {ast.dump(node)}")

    return walk(ast.parse(expr.replace("^", "**"), mode="eval"))


def load_model() -> dict:
    with open(MODEL, "rb") as f:
        return tomllib.load(f)


def model_matrices(doc: dict, values: dict[str, float], effects=()) -> dict[str, np.ndarray]:
    """A, B, C of the file at `values` (documented values where absent), `effects` added."""
    names = {}
    for k, v in doc["parameters"].items():
        names[k] = float(v["value"] if isinstance(v, dict) else v)
    for e in effects:
        for k, v in doc["effects"][e]["parameters"].items():
            names[k] = float(v["value"] if isinstance(v, dict) else v)
    names.update(values)
    for k, expr in doc["definitions"].items():  # in file order
        names[k] = evaluate(expr, names)
    out = {m: np.array([[evaluate(x, names) for x in row] for row in doc["linear"][m]])
           for m in ("A", "B", "C")}
    index = {"A": (doc["states"], doc["states"]), "B": (doc["states"], doc["inputs"]),
             "C": (doc["outputs"], doc["states"])}
    for e in effects:
        for m, terms in doc["effects"][e].items():
            if m in index:
                rows, cols = index[m]
                for key, expr in terms.items():
                    r, c = (s.strip() for s in key.split(","))
                    out[m][rows.index(r), cols.index(c)] += evaluate(expr, names)
    return out


def plant_values(p: ic.Plant) -> dict[str, float]:
    return {"M": p.M, "m": p.m, "l": p.l, "J": p.J, "g": p.g}


def test_model_file_names_match_the_simulator():
    doc = load_model()
    assert doc["name"] == ic.SYSTEM
    assert doc["states"] == ic.STATES and doc["inputs"] == ic.INPUTS
    assert doc["outputs"] == ic.OUTPUTS
    assert set(doc["parameters"]) == set(ic.DOCUMENTED)
    for k, v in ic.DOCUMENTED.items():
        assert doc["parameters"][k]["value"] == v


@pytest.mark.parametrize("plant", [ic.documented_plant(), ic.Plant(),
                                   replace(ic.Plant(), b=B_TRUE)],
                         ids=["documented", "truth", "truth-with-friction"])
def test_model_file_is_the_jacobian_of_the_nonlinear_plant_at_upright(plant):
    # Central differences of the simulator's nonlinear right-hand side at x = 0, theta = 0
    # against the file's expressions evaluated at the same parameter values (friction through
    # the declared effect).
    doc = load_model()
    effects = ("cart_friction",) if plant.b > 0 else ()
    values = plant_values(plant) | ({"b": plant.b} if plant.b > 0 else {})
    m = model_matrices(doc, values, effects)
    a, b = ic.linearised_truth(plant)
    assert np.allclose(m["A"], a, rtol=0, atol=1e-9), (m["A"], a)
    assert np.allclose(m["B"], b, rtol=0, atol=1e-9), (m["B"], b)
    assert np.array_equal(m["C"], np.array([[1, 0, 0, 0], [0, 0, 1, 0]], float))
    # The upright pole is unstable: eigenvalues 0, 0, +-p with p = sqrt((M+m) m g l / Delta).
    jp = plant.J + plant.m * plant.l**2
    p = math.sqrt((plant.M + plant.m) * plant.m * plant.g * plant.l
                  / ((plant.M + plant.m) * jp - (plant.m * plant.l) ** 2))
    if plant.b == 0:
        assert np.allclose(sorted(np.linalg.eigvals(m["A"]).real), [-p, 0, 0, p], atol=1e-9)


def test_model_file_controller_is_the_simulators_and_stabilises_every_truth():
    section = load_model()["controller"]
    assert section["type"] == "discrete" and section["sample_rate_hz"] == 100
    ctrl = ic.design_controller(ic.Config())
    # The file holds the simulator's design; recomputed with another LAPACK build (scipy's
    # bundled OpenBLAS picks kernels by CPU) it agrees to 2.7e-12 relative, not to the last bit.
    for name in "ABCD":
        assert np.allclose(np.array(section[name]), getattr(ctrl, name), rtol=1e-10, atol=0)
    file_ctrl = ic.Controller(*(np.array(section[n], float) for n in "ABCD"))
    for case in CASES.values():
        cfg = ic.Config(plant=replace(ic.Plant(), **case))
        assert ic.closed_loop_radius(cfg, file_ctrl) < 0.995, case


@pytest.mark.parametrize("case", [{}, {"td": 0.007}, {"td": TD_TRUE, "tau": TAU_TRUE, "b": 1.0},
                                  {"td": 0.02, "flex_hz": FLEX_HZ}, {"td": 0.01}],
                         ids=["rigid", "td-0.7-samples", "td-1.5-lag-friction",
                              "td-2-flex", "td-1-sample"])
def test_nonlinear_loop_at_tiny_amplitude_is_the_exact_discretised_linear_loop(case):
    # RK4 sub-stepping with the delayed hold switching mid-sample against the matrix
    # exponential of the linearised truth with the delay split exactly (two ways to the same
    # sampled system): equal to 1e-6 of the response when noise-free and tiny.
    cfg = ic.Config(plant=replace(ic.Plant(), **case), experiments=1, periods=1,
                    transient_samples=0, r_rms=1e-4, force_noise=0.0, torque_noise=0.0,
                    x_sigma=0.0, theta_sigma=0.0, theta0=1e-5, phase_draws=2, seed=4)
    run = ic.simulate(cfg)[0]
    az, bz, cz = ic.linear_closed_loop(cfg, ic.design_controller(cfg))
    z = np.zeros(az.shape[0])
    z[2] = cfg.theta0
    y = np.zeros_like(run.y)
    for k in range(len(run.t)):
        y[k] = cz @ z
        z = az @ z + bz * run.r[k, 0]
    assert np.abs(y - run.y).max() < 1e-6 * np.abs(run.y).max()


def test_excitation_is_the_periodic_multisine_and_the_pole_stays_near_upright():
    cfg = ic.Config(plant=replace(ic.Plant(), b=B_TRUE, tau=TAU_TRUE), experiments=2, seed=5)
    runs = ic.simulate(cfg)
    for run in runs:
        r = run.r[:, 0]
        periods = r[cfg.transient_samples:].reshape(cfg.periods, cfg.period_samples)
        assert np.abs(periods - periods[0]).max() < 1e-12
        power = np.abs(np.fft.rfft(periods[0])) ** 2
        excited = np.arange(1, cfg.lines + 1)
        assert power[np.setdiff1d(np.arange(len(power)), excited)].sum() < 1e-20 * power.sum()
        assert np.std(power[excited]) < 1e-9 * power[excited].mean()  # flat lines
        assert np.sqrt(np.mean(periods[0] ** 2)) == pytest.approx(cfg.r_rms, rel=1e-9)
        assert np.abs(run.state[:, 2]).max() < 0.1  # rad: near upright, mildly nonlinear
    # Fresh phases per experiment.
    assert not np.allclose(runs[0].r, runs[1].r)


def test_logs_read_back_with_the_mcap_package_as_design_specifies(tmp_path):
    cfg = ic.Config(experiments=2, periods=2, seed=6)
    runs = ic.simulate(cfg)
    paths = ic.write_runs(cfg, runs, tmp_path)
    for run, path in zip(runs, paths):
        with open(path, "rb") as f:
            reader = make_reader(f)
            summary = reader.get_summary()
            schemas = {s.id: s for s in summary.schemas.values()}
            channels = {c.topic: c for c in summary.channels.values()}
            assert set(channels) == {"/cart_pole/input", "/cart_pole/output",
                                     "/cart_pole/excitation"}
            for c in channels.values():
                assert c.message_encoding == "json"
                assert schemas[c.schema_id].encoding == "jsonschema"
            fields = {"/cart_pole/input": ["F"], "/cart_pole/output": ["x", "theta"],
                      "/cart_pole/excitation": ["F"]}
            for topic, names in fields.items():
                schema = json.loads(schemas[channels[topic].schema_id].data)
                assert set(schema["properties"]) == {"t", *names}
            got = {t: [] for t in fields}
            for _, channel, message in reader.iter_messages():
                msg = json.loads(message.data)
                assert message.log_time == round(msg["t"] * 1e9)
                got[channel.topic].append([msg["t"], *(msg[n] for n in fields[channel.topic])])
            meta = {m.name: m.metadata for m in reader.iter_metadata()}
        assert meta["experiment"] == {"sample_rate_hz": "100", "period_samples": "1000",
                                      "periods": "2", "transient_samples": "300",
                                      "excited": "F"}
        for topic, values in (("/cart_pole/input", run.u), ("/cart_pole/output", run.y),
                              ("/cart_pole/excitation", run.r)):
            table = np.array(got[topic])
            assert np.array_equal(table[:, 0], run.t)
            assert np.array_equal(table[:, 1:], values)


def test_csv_reads_back(tmp_path):
    cfg = ic.Config(experiments=1, periods=2, seed=7)
    run = ic.simulate(cfg)[0]
    ic.write_csv(run, tmp_path / "e.csv")
    assert (tmp_path / "e.csv").read_text().splitlines()[0] == "t,F,x,theta,r_F"
    table = np.loadtxt(tmp_path / "e.csv", delimiter=",", skiprows=1)
    assert np.allclose(table, np.column_stack([run.t, run.u, run.y, run.r]), rtol=1e-9,
                       atol=1e-12)


def test_stabilis_info_reads_the_logs(tmp_path):
    cfg = ic.Config(experiments=1, periods=2, seed=8)
    (path,) = ic.write_runs(cfg, ic.simulate(cfg), tmp_path)
    done = subprocess.run([stabilis_bin(), "info", str(path)], capture_output=True, text=True,
                          check=False)
    assert done.returncode == 0, done.stderr
    for line in ("/cart_pole/input: 2300 messages", "/cart_pole/output: 2300 messages",
                 "/cart_pole/excitation: 2300 messages", "fields: x theta",
                 "period_samples = 1000", "excited = F"):
        assert line in done.stdout, (line, done.stdout)


# --- acceptance through the CLI and Python ----------------------------------------------


def campaign_cache(tmp_path_factory, cases: dict[str, dict], **settings):
    """get(case, seed): the directory of the campaign Config(**settings) with the Plant fields
    cases[case] at that seed, simulated on first use."""
    cache = {}

    def get(case: str, seed: int) -> Path:
        if (case, seed) not in cache:
            out = tmp_path_factory.mktemp(f"{case.replace('+', '_')}_{seed}")
            ic.campaign(out, plant=replace(ic.Plant(), **cases[case]), seed=seed, **settings)
            cache[case, seed] = out
        return cache[case, seed]

    return get


@pytest.fixture(scope="module")
def campaigns(tmp_path_factory):
    """The issue's campaign (4 x 8300 samples) per (case, seed), simulated once."""
    return campaign_cache(tmp_path_factory, CASES)


def cli(*args):
    return subprocess.run([stabilis_bin(), *map(str, args)], capture_output=True, text=True,
                          check=False)


def require_model_option(done):
    """Fails (does not skip) when the binary predates `--model` or `model check` (issue 12)."""
    err = done.stderr
    missing = ("unexpected argument '--model'", "unrecognized subcommand 'model'")
    if done.returncode == 2 and any(m in err for m in missing):
        pytest.fail(f"{stabilis_bin()} lacks issue 12's model files (not built): {err}")


def discover_cli(data: Path, tmp: Path) -> dict:
    out = tmp / "discover.json"
    done = cli("discover", "--model", MODEL, "--data", data, "--json", out)
    require_model_option(done)
    assert done.returncode == 0, done.stderr
    return json.loads(out.read_text())


def python_model():
    import stabilis

    if not hasattr(stabilis, "Model"):
        pytest.fail("stabilis.Model is missing (issue 12 not built into the Python package)")
    return stabilis


def discover_python(data: Path) -> dict:
    stabilis = python_model()
    wb = stabilis.Workbench(model=stabilis.Model.from_file(str(MODEL)), data=[str(data)])
    return wb.discover()


def param(doc: dict, name: str, effect: str | None = None) -> float:
    """A fitted parameter of the last step, under its plain name or `effect.name`."""
    params = doc["steps"][-1]["params"]
    for key in (name, f"{effect}.{name}"):
        if key in params:
            return params[key]
    raise AssertionError(f"no parameter {name!r} in {sorted(params)}")


def check_explained(doc):
    assert doc["found"] == [], doc["found"]
    assert doc["tentative"] == [], doc["tentative"]
    assert doc["unexplained"] is False, doc.get("verdict_text")
    assert doc["verdict"]["kind"] == "explained_to_noise_level", doc["verdict"]


def check_found(doc, case):
    truth = CASES[case]
    expected = sorted({"b": "cart_friction", "tau": "actuator_lag", "td": "input_delay"}[k]
                      for k in truth)
    assert sorted(doc["found"]) == expected, (doc["found"], doc["tentative"],
                                              doc.get("verdict_text"))
    assert doc["unexplained"] is False, doc.get("verdict_text")
    assert doc["verdict"]["kind"] == "explained_to_noise_level", doc["verdict"]
    for name, effect in (("b", "cart_friction"), ("tau", "actuator_lag"), ("td", "input_delay")):
        if name in truth:
            value = param(doc, name, effect)
            assert abs(value / truth[name] - 1.0) < TOLERANCE, (name, value, truth[name])
    # Every added step lowers the cost.
    costs = [s["cost"] for s in doc["steps"]]
    assert all(b < a for a, b in zip(costs, costs[1:])), costs


def check_flex(doc):
    assert doc["found"] == [], (doc["found"], doc.get("verdict_text"))
    assert doc["unexplained"] is True, doc.get("verdict_text")
    verdict = doc["verdict"]
    assert verdict["kind"] == "unexplained_structured_misfit", verdict
    assert verdict["outputs"] and set(verdict["outputs"]) <= {"x", "theta"}, verdict
    assert verdict["band_hz"] is not None, verdict
    lo, hi = verdict["band_hz"]
    assert lo <= FLEX_HZ <= hi and hi - lo < 3.0, verdict  # the mode, not the whole band


CHECKS = {"nothing": check_explained, "flex": check_flex}


def check(case, doc):
    CHECKS.get(case, lambda d: check_found(d, case))(doc)


@pytest.mark.parametrize("case, seed", campaign_cases(SEEDS))
def test_cli_discover_with_the_model_file(campaigns, tmp_path, case, seed):
    check(case, discover_cli(campaigns(case, seed), tmp_path))


@pytest.mark.parametrize("seed", [71, 72])
def test_coulomb_friction_is_no_lag_or_delay_and_stays_unexplained(tmp_path, seed):
    # Model-class mismatch: 0.1 N of Coulomb friction (no effect describes it). The viscous
    # friction may be proposed (it is the nearest friction), lag and delay may not, and the
    # nonlinear remainder must not be called noise.
    ic.campaign(tmp_path / "data", plant=replace(ic.Plant(), coulomb=0.1), seed=seed)
    doc = discover_cli(tmp_path / "data", tmp_path)
    assert set(doc["found"] + doc["tentative"]) <= {"cart_friction"}, doc
    assert doc["unexplained"] is True, doc.get("verdict_text")


@pytest.mark.parametrize("seed", [73, 74])
def test_a_random_odd_multisine_shows_dry_friction_as_distortion(tmp_path, seed):
    # The even lines and every fourth odd line left out of the multisine: 0.2 N of Coulomb
    # friction puts its harmonics there, so the distortion test flags them, sizes them within
    # the band in units of the FRF's noise reference, and the viscous friction that absorbs
    # them is at most tentative, naming the distortion. The same campaign without friction
    # flags nothing and names no distortion.
    for coulomb in (0.2, 0.0):
        data = tmp_path / f"coulomb_{coulomb}"
        ic.campaign(data, plant=replace(ic.Plant(), coulomb=coulomb), seed=seed,
                    random_odd=True, **ic.FRICTION_EXCITATION)
        doc = discover_cli(data, tmp_path)
        test = doc["distortion"]
        # Lines 1..70 of a 1000-sample period: 27 excited, 42 left out between them.
        assert test["lines_within_band"] == 42, test["lines_within_band"]
        flagged = {o["output"]: o["flagged_hz"] for o in test["outputs"]}
        why = " ".join(doc["tentative_why"] or [])
        if coulomb:
            assert flagged["theta"] and flagged["x"], flagged
            sizes = {o["output"]: o["within_band"] for o in test["outputs"]}
            assert sizes["theta"] > 2.0, sizes
            assert "cart_friction" not in doc["found"], doc["found"]
            assert "nonlinear distortion" in why, why
        else:
            assert not any(flagged.values()), flagged
            assert "nonlinear distortion" not in why, why


@pytest.mark.parametrize("case", list(CASES))
def test_python_discover_with_the_model_file(campaigns, tmp_path, case):
    # The first seed's data: Python must accept and conclude as the CLI does.
    data = campaigns(case, SEEDS[case][0])
    doc = discover_python(data)
    check(case, doc)
    assert doc["found"] == discover_cli(data, tmp_path)["found"]


def test_model_check_names_the_unstable_pole():
    check_names_the_unstable_pole(MODEL)


def check_names_the_unstable_pole(model: Path):
    """`stabilis model check model` exits 0 and prints +-p, the upright pole's eigenvalues at
    the documented values, calling the model unstable."""
    done = cli("model", "check", model)
    require_model_option(done)
    assert done.returncode == 0, done.stderr
    p = ic.documented_plant()
    jp = p.J + p.m * p.l**2
    pole = math.sqrt((p.M + p.m) * p.m * p.g * p.l / ((p.M + p.m) * jp - (p.m * p.l) ** 2))
    numbers = [float(x) for x in re.findall(r"[-+]?\d+\.\d+(?:[eE][-+]?\d+)?", done.stdout)]
    assert any(abs(x - pole) < 1e-3 * pole for x in numbers), (pole, done.stdout)
    assert any(abs(x + pole) < 1e-3 * pole for x in numbers), (-pole, done.stdout)
    assert "unstable" in done.stdout.lower()


# --- bad model files ----------------------------------------------------------------------


def bad_copy(tmp: Path, old: str, new: str, model: Path = MODEL) -> tuple[Path, str]:
    """A copy of `model` in tmp with the one occurrence of `old` replaced by `new`."""
    text = model.read_text()
    assert text.count(old) == 1, old
    path = tmp / f"bad_{model.name}"
    path.write_text(text.replace(old, new))
    return path, path.read_text()


def refused(path: Path, data: Path, tmp: Path) -> str:
    """`discover --model path` on good data: exit 2, no panic, no output; its stderr, which
    names the file."""
    out = tmp / "out.json"
    done = cli("discover", "--model", path, "--data", data, "--json", out)
    require_model_option(done)
    assert done.returncode == 2, done.stderr
    assert path.name in done.stderr and "panicked" not in done.stderr, done.stderr
    assert not out.exists()
    return done.stderr


def positions(text: str, expr: str, name: str) -> set[str]:
    """The numbers that locate `name`: its 0- or 1-based column in the expression, the file
    line holding it."""
    col = expr.index(name)
    line = next(i for i, s in enumerate(text.splitlines(), 1) if expr in s)
    return {str(col), str(col + 1), str(line)}


@pytest.mark.parametrize("old, new, key, bad", [
    ('"(M + m)*m*g*l/Delta"', '"(M + m)*m*g*l/Deltta"', "linear", "Deltta"),
    ('"-b*Jp/Delta"', '"-bb*Jp/Delta"', "cart_friction", "bb"),
], ids=["linear-A", "effect-A"])
def test_unknown_name_is_refused_naming_file_key_name_and_position(campaigns, tmp_path, old,
                                                                    new, key, bad):
    path, text = bad_copy(tmp_path, old, new)
    err = refused(path, campaigns("nothing", SEEDS["nothing"][0]), tmp_path)
    assert key in err and bad in err, err
    where = positions(text, new.strip('"'), bad)
    assert any(re.search(rf"(?<!\d){n}(?!\d)", err) for n in where), (where, err)
    with pytest.raises(python_model().Error, match=re.escape(bad)):
        python_model().Model.from_file(str(path))


@pytest.mark.parametrize("old, new", [
    ("     [0, 0, 0, 1],", "     [0, 0, 1],"),
    ('     [0, 0, 0, 1],\n     [0, 0, "(M + m)*m*g*l/Delta", 0]]', "     [0, 0, 0, 1]]"),
], ids=["ragged-row", "three-rows"])
def test_non_square_a_is_refused_with_the_sizes(campaigns, tmp_path, old, new):
    path, _ = bad_copy(tmp_path, old, new)
    err = refused(path, campaigns("nothing", SEEDS["nothing"][0]), tmp_path)
    assert re.search(r"\bA\b", err), err
    assert re.search(r"(?<!\d)3(?!\d)", err) and re.search(r"(?<!\d)4(?!\d)", err), err
    with pytest.raises(python_model().Error, match="linear.A"):
        python_model().Model.from_file(str(path))
    assert "panicked" not in err
    assert not (tmp_path / "out.json").exists()


# --- the same model in Python: a callable and a stabilis.Effect ----------------------------


def cart_pole_matrices(p):
    """(A, B, C, D) of the file's [linear] section, written in numpy."""
    plant = ic.Plant(M=p["M"], m=p["m"], l=p["l"], J=p["J"], g=p["g"])
    a, b, c = ic.nominal_linear(plant)
    return a, b, c, np.zeros((2, 1))


def cart_friction(p, m):
    """The file's cart_friction terms: the force -b xdot enters where F does (an effect's
    callable receives its own parameters and the model's matrices)."""
    d_a = np.zeros_like(m["A"])
    d_a[:, 1] = -p["b"] * m["B"][:, 0]
    return {"A": d_a}


def python_cart_pole(stabilis, matrices=cart_pole_matrices):
    """The model file's content as a Python model (parameters as in the file's tables)."""
    effect = stabilis.Effect("cart_friction", {"b": 0.5}, cart_friction, bounds={"b": (0.0, 20.0)})
    return stabilis.Model(states=ic.STATES, inputs=ic.INPUTS, outputs=ic.OUTPUTS,
                          parameters=load_model()["parameters"], matrices=matrices,
                          effects=[effect], name=ic.SYSTEM)


@pytest.mark.parametrize("case", ["friction", "lag"])
def test_python_model_with_a_callable_and_an_effect(campaigns, case):
    stabilis = python_model()
    wb = stabilis.Workbench(model=python_cart_pole(stabilis),
                            data=[str(campaigns(case, SEEDS[case][0]))])
    check(case, wb.discover())


class Sentinel(Exception):
    pass


def test_an_error_in_the_users_callable_reaches_the_caller_unchanged(campaigns):
    stabilis = python_model()

    def broken(p):
        raise Sentinel(f"no matrices for M = {p['M']}")

    with pytest.raises(Sentinel, match="no matrices for M"):
        model = python_cart_pole(stabilis, matrices=broken)
        stabilis.Workbench(model=model, data=[str(campaigns("nothing", 1))]).discover()


# --- the campaign carries the information the acceptance asks for -------------------------


def read_log(path: Path) -> tuple[dict[str, str], dict[str, np.ndarray]]:
    """(experiment metadata, {topic: samples x fields}) of one log, read with `mcap`."""
    cols = {"/cart_pole/input": ["F"], "/cart_pole/output": ["x", "theta"],
            "/cart_pole/excitation": ["F"]}
    rows = {t: [] for t in cols}
    with open(path, "rb") as f:
        reader = make_reader(f)
        for _, channel, message in reader.iter_messages(topics=list(cols)):
            msg = json.loads(message.data)
            rows[channel.topic].append([msg[n] for n in cols[channel.topic]])
        meta = next(m.metadata for m in reader.iter_metadata() if m.name == "experiment")
    return meta, {t: np.array(v) for t, v in rows.items()}


def periodic_frf(directory: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(freqs, G, std): Y/U on the excited lines per period and experiment, averaged."""
    ratios = []
    for path in sorted(directory.glob("*.mcap")):
        meta, log = read_log(path)
        n, periods = int(meta["period_samples"]), int(meta["periods"])
        start = int(meta["transient_samples"])

        def spectrum(topic):
            return np.fft.rfft(log[topic][start:].reshape(periods, n, -1), axis=1)

        rf = np.abs(spectrum("/cart_pole/excitation")[0, :, 0])
        excited = np.flatnonzero(rf > 1e-6 * rf.max())  # the lines the excitation carries
        uf, yf = spectrum("/cart_pole/input"), spectrum("/cart_pole/output")
        ratios.append(yf[:, excited] / uf[:, excited])
    g = np.concatenate(ratios)
    rate = float(meta["sample_rate_hz"])
    return excited * rate / n, g.mean(0), g.std(0) / np.sqrt(len(g))


def scipy_fit(freqs, g, std, effects):
    """Weighted least squares of the sampled FRF over M, l, J and `effects` (scipy)."""
    from scipy.optimize import least_squares

    start = {"M": 1.0, "l": 0.3, "J": 0.006, "b": 0.5, "tau": 0.01, "td": 0.005}
    names = ["M", "l", "J", *effects]
    x0 = np.array([start[k] for k in names])

    def residual(x):
        p = replace(ic.documented_plant(), **dict(zip(names, x)))
        r = (ic.sampled_frf(p, freqs, 0.01) - g) / std
        return np.concatenate([r.real.ravel(), r.imag.ravel()])

    lower = [0.1, 0.05, 0.0] + [0.0] * len(effects)
    fit = least_squares(residual, x0, x_scale=x0, bounds=(lower, np.inf))
    return dict(zip(names, fit.x)), float(np.mean(fit.fun**2) * 2)


@pytest.mark.parametrize("case, effects", [("nothing", []), ("friction", ["b"]),
                                           ("delay", ["td"])])
def test_the_logs_identify_the_hidden_effect_with_scipy(campaigns, case, effects):
    # An independent reference for the acceptance: the right structure fitted to the periodic
    # FRF of the logs (read back with `mcap`) by scipy reaches the noise level (normalised cost
    # near 1 for a complex residual counted as two reals) and recovers the hidden parameter to
    # 3 %, where the nominal model misses by far more than the noise.
    freqs, g, std = periodic_frf(campaigns(case, SEEDS[case][0]))
    assert np.allclose(freqs, 0.1 * np.arange(1, 71))
    _, nominal = scipy_fit(freqs, g, std, [])
    params, cost = scipy_fit(freqs, g, std, effects)
    assert cost < 1.5, cost
    for name in effects:
        assert abs(params[name] / CASES[case][name] - 1) < 0.03, (name, params)
        assert nominal > 50 * cost, (nominal, cost)


def test_no_candidate_explains_the_flexible_mode_and_its_misfit_is_at_the_mode(campaigns):
    # Friction, lag and delay fitted together leave the appendage's misfit far above the noise,
    # and over half of it lies within 0.7 Hz of the mode: the band the verdict should name.
    freqs, g, std = periodic_frf(campaigns("flex", SEEDS["flex"][0]))
    params, cost = scipy_fit(freqs, g, std, ["b", "tau", "td"])
    assert cost > 5, (cost, params)
    fitted = ic.sampled_frf(replace(ic.documented_plant(), **params), freqs, 0.01)
    misfit = (np.abs((fitted - g) / std) ** 2).sum(axis=1)
    near = np.abs(freqs - FLEX_HZ) <= 0.7
    assert misfit[near].sum() > 0.5 * misfit.sum(), misfit


def test_python_model_is_the_model_file():
    # The callable and the effect above against the file's expressions (read independently).
    doc = load_model()
    values = plant_values(ic.Plant()) | {"b": B_TRUE}
    a, b, c, d = cart_pole_matrices(values)
    file = model_matrices(doc, values, ("cart_friction",))
    d_a = cart_friction({"b": B_TRUE}, {"A": a, "B": b, "C": c, "D": d})["A"]
    assert np.allclose(a + d_a, file["A"], rtol=1e-14, atol=1e-14)
    assert np.allclose(b, file["B"], rtol=1e-14) and np.array_equal(c, file["C"])


def closed_loop_fit(directory: Path, values: dict[str, float], effects=()) -> np.ndarray:
    """Fit % per output (x, theta) of the file's model at `values` in the loop with the file's
    controller, driven by the logged excitation from zero state, scored after the transient
    (the closed-loop re-simulation of the issue's item 5b, computed independently)."""
    doc = load_model()
    ac, bc, cc, dc = (np.array(doc["controller"][k], float) for k in "ABCD")
    m = model_matrices(doc, values, effects)
    ad, bd = ic.zoh(m["A"], m["B"], 1.0 / doc["controller"]["sample_rate_hz"])
    sim, meas = [], []
    for path in sorted(directory.glob("*.mcap")):
        meta, log = read_log(path)
        r, y = log["/cart_pole/excitation"][:, 0], log["/cart_pole/output"]
        x, xc, ys = np.zeros(4), np.zeros(4), np.zeros_like(y)
        for k in range(len(r)):
            ys[k] = m["C"] @ x
            u = cc @ xc + dc @ ys[k] + r[k]
            xc = ac @ xc + bc @ ys[k]
            x = ad @ x + bd @ u
        start = int(meta["transient_samples"])
        sim.append(ys[start:])
        meas.append(y[start:])
    yh, y = np.concatenate(sim), np.concatenate(meas)
    return 100 * (1 - np.linalg.norm(y - yh, axis=0) / np.linalg.norm(y - y.mean(0), axis=0))


def test_file_controller_re_simulates_the_logged_loop(campaigns):
    # The [controller] section's convention checked against the logs: with the truth's
    # parameters the re-simulated loop follows the measured one (what the force disturbance
    # leaves: about 72 % on x, 85 % on theta), and on friction data the model with the
    # friction re-simulates clearly better than the one without.
    truth = plant_values(ic.Plant())
    fit = closed_loop_fit(campaigns("nothing", SEEDS["nothing"][0]), truth)
    assert fit[0] > 65 and fit[1] > 80, fit
    friction = campaigns("friction", SEEDS["friction"][0])
    without = closed_loop_fit(friction, truth)
    with_b = closed_loop_fit(friction, truth | {"b": B_TRUE}, ("cart_friction",))
    assert (with_b > without + 10).all(), (with_b, without)


@pytest.mark.parametrize("case", ["nothing", "friction"])
def test_workbench_closed_loop_re_simulation_matches_the_independent_one(campaigns, tmp_path,
                                                                          case):
    # The last step's fitted model is the truth to within the noise, so the workbench's
    # closed-loop fit % must be the independent re-simulation's at the truth to a point.
    data = campaigns(case, SEEDS[case][0])
    doc = discover_cli(data, tmp_path)
    loop = doc["steps"][-1]["time_fit"].get("closed_loop")
    assert loop is not None, doc["steps"][-1]["time_fit"].get("closed_loop_error")
    got = dict(loop["fit"])
    truth = plant_values(ic.Plant()) | {"b": CASES[case].get("b", 0.0)}
    want = closed_loop_fit(data, truth, ("cart_friction",))
    assert abs(got["x"] - want[0]) < 1.0 and abs(got["theta"] - want[1]) < 1.0, (got, want)
