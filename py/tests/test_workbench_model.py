"""stabilis.Model from Python: a callable model, arrays as data, effects as discovery
candidates (one that adds a state), errors by name. The data are simulated here with scipy's
exact zero-order-hold discretisation of the truth (independent of stabilis)."""
from __future__ import annotations

import threading

import numpy as np
import pytest
from scipy.signal import cont2discrete, dlsim

import stabilis

FS = 50.0
PERIOD = 250
PERIODS = 6
TRANSIENT = 250


def plant(k, c, g, lag=0.0):
    """q'' = -k q - c q' + g u (through a first-order lag when lag > 0); y = q."""
    a = np.array([[0.0, 1.0], [-k, -c]])
    b = np.array([[0.0], [g]])
    if lag > 0:
        a = np.block([[a, b], [np.zeros((1, 2)), -np.ones((1, 1)) / lag]])
        b = np.array([[0.0], [0.0], [1.0 / lag]])
    cm = np.zeros((1, a.shape[0]))
    cm[0, 0] = 1.0
    return a, b, cm


def experiments(truth, seeds=(1, 2, 3), noise=2e-3):
    """Open-loop periodic multisine records: y = truth(u) + white noise, u = r."""
    a, b, c = truth
    ad, bd, cd, dd, _ = cont2discrete((a, b, c, np.zeros((1, 1))), 1.0 / FS, method="zoh")
    n = TRANSIENT + PERIOD * PERIODS
    out = []
    for seed in seeds:
        rng = np.random.default_rng(seed)
        t = np.arange(PERIOD) / FS
        period = sum(np.cos(2 * np.pi * (FS / PERIOD) * line * t + rng.uniform(0, 2 * np.pi))
                     for line in range(1, 40))
        r = np.tile(period, n // PERIOD + 2)[:n] / 4.0
        _, y, _ = dlsim((ad, bd, cd, dd, 1.0 / FS), r)
        y = y[:, :1] + noise * rng.standard_normal((n, 1))
        # The plant's start-up (time constant 2/c, about 40 samples) is cut off.
        out.append({"u": r[TRANSIENT:], "y": y[TRANSIENT:], "r": r[TRANSIENT:]})
    return out


def matrices(p):
    a, b, c = plant(p["k"], p["c"], p["g"])
    return a, b, c, np.zeros((1, 1))


def lag_effect(p, m):
    """A first-order lag on the input: one more state (the model's matrices are padded)."""
    n = m["A"].shape[0]
    tau = p["tau"]
    d_a = np.zeros((n + 1, n + 1))
    d_a[:n, n] = m["B"][:, 0]
    d_a[n, n] = -1.0 / tau
    d_b = np.zeros((n + 1, 1))
    d_b[:n, 0] = -m["B"][:, 0]
    d_b[n, 0] = 1.0 / tau
    return {"A": d_a, "B": d_b}


def model(**kw):
    return stabilis.Model(states=["q", "qdot"], inputs=["u"], outputs=["q"], name="oscillator",
                          parameters={"k": (40.0, 1.0, 400.0), "c": {"value": 2.0, "min": 0.0},
                                      "g": 30.0},
                          matrices=matrices, **kw)


LAG = stabilis.Effect("slow_drive", {"tau": 0.01}, lag_effect, bounds={"tau": (1e-3, 1.0)})


def test_a_callable_model_on_arrays_explains_its_own_truth():
    data = experiments(plant(42.0, 2.4, 31.0))
    result = stabilis.Workbench(model=model(), data=data, sample_rate_hz=FS).discover()
    assert result["found"] == [], result["found"]
    assert result["unexplained"] is False
    params = result["steps"][-1]["params"]
    for name, truth in (("k", 42.0), ("c", 2.4), ("g", 31.0)):
        assert abs(params[name] / truth - 1) < 0.02, (name, params[name])


@pytest.mark.parametrize("seeds", [(1, 2, 3), (4, 5, 6), (7, 8, 9)])
def test_a_user_effect_that_adds_a_state_is_a_discovery_candidate(seeds):
    # The generic actuator_lag describes the same physics: offered under its own name, the
    # user's effect fits exactly as well, so discovery adds one of the two as tentative and
    # names the other as its rival; the fitted time constant is the truth's either way (3
    # seed sets, all must pass).
    data = experiments(plant(42.0, 2.4, 31.0, lag=0.05), seeds=seeds)
    wb = stabilis.Workbench(model=model(effects=[LAG]), data=data, sample_rate_hz=FS)
    result = wb.discover()
    assert result["found"] == [] and len(result["tentative"]) == 1, result["tentative"]
    added = result["tentative"][0]
    assert added in ("slow_drive", "actuator_lag")
    other = "actuator_lag" if added == "slow_drive" else "slow_drive"
    assert any(w.startswith(other) and "do not tell them apart" in w
               for w in result["tentative_why"]), result["tentative_why"]
    params = result["steps"][-1]["params"]
    tau = params.get("slow_drive.tau", params.get("tau"))
    assert abs(tau / 0.05 - 1) < 0.05, params


def test_suspect_offers_an_effect_without_enabling_it():
    data = experiments(plant(42.0, 2.4, 31.0))
    wb = stabilis.Workbench(model=model(), data=data, sample_rate_hz=FS)
    wb.suspect(LAG)
    step = wb.compare()["steps"][0]
    assert "slow_drive.tau" not in step["params"]
    names = [c["effect"] for c in wb.discover()["steps"][0]["candidates"]]
    assert "slow_drive" in names and "actuator_lag" in names and "input_delay" in names


class Boom(Exception):
    pass


def test_errors_name_the_problem_and_user_exceptions_pass_through():
    # A model without name= is "model" in its messages until a workbench names it.
    with pytest.raises(ValueError, match=r"^model: A has shape \(1, 2\), must be \(2, 2\)"):
        stabilis.Model(states=["q", "qdot"], inputs=["u"], outputs=["q"], parameters={"k": 1.0},
                       matrices=lambda p: (np.zeros((1, 2)), np.zeros((2, 1)), np.zeros((1, 2)),
                                           np.zeros((1, 1))))
    with pytest.raises(ValueError, match="states\\[1\\] \"q\" is named twice"):
        stabilis.Model(states=["q", "q"], inputs=["u"], outputs=["q"], parameters={},
                       matrices=matrices)

    with pytest.raises(ValueError, match=r"invalid k = bounds \[5, 0.1\]: the lower bound \(min\) exceeds"):
        stabilis.Model(states=["q", "qdot"], inputs=["u"], outputs=["q"],
                       parameters={"k": (1.0, 5.0, 0.1), "c": 2.0, "g": 30.0}, matrices=matrices)
    # A wrong type names the argument and what it must be (the binding's own message did not).
    wrong = [(dict(states="q"), r"^model: states must be a list of names \(str\).*; got str"),
             (dict(parameters=[1.0]), "parameters must be a dict .*; got list"),
             (dict(parameters={"k": {"value": 1.0, "unit": 3}}), "parameter k: unit must be a string")]
    for change, message in wrong:
        kw = dict(states=["q", "qdot"], inputs=["u"], outputs=["q"],
                  parameters={"k": 1.0, "c": 2.0, "g": 30.0}, matrices=matrices)
        with pytest.raises(TypeError, match=message):
            stabilis.Model(**(kw | change))
    for change, message in [(dict(params=0.5), "effect e: params must map names"),
                            (dict(bounds={"b": 3}), r"effect e: bounds must map parameter names to \(min, max\)"),
                            (dict(units={"b": 3}), r"effect e: units must map parameter names to units")]:
        with pytest.raises(TypeError, match=message):
            stabilis.Effect(**({"name": "e", "params": {"b": 0.5}, "func": lag_effect} | change))

    def boom(p):
        raise Boom("no model today")

    with pytest.raises(Boom, match="no model today"):
        stabilis.Model(states=["q"], inputs=["u"], outputs=["q"], parameters={"k": 1.0},
                       matrices=boom)
    with pytest.raises(ValueError, match="columns; the model has 1"):
        stabilis.Workbench(model=model(), data=[{"u": np.zeros((100, 2)), "y": np.zeros(100)}],
                           sample_rate_hz=FS)
    with pytest.raises(ValueError, match="sample_rate_hz"):
        stabilis.Workbench(model=model(), data=experiments(plant(42.0, 2.4, 31.0)))
    # A misspelt key would drop the excitation and change the estimator without a word.
    e = experiments(plant(42.0, 2.4, 31.0), seeds=(1,))[0]
    renamed = {"u": e["u"], "y": e["y"], "excitation": e["r"]}
    with pytest.raises(ValueError, match="data\\[0\\] has the key 'excitation'; an experiment holds"):
        stabilis.Workbench(model=model(), data=[renamed], sample_rate_hz=FS)
    # Arrays are named as numpy indexes them: data[1], row 100 (0-based both).
    two = experiments(plant(42.0, 2.4, 31.0), seeds=(1, 2))
    two[1]["y"] = np.array(two[1]["y"], dtype=float)
    two[1]["y"][100] = np.nan
    with pytest.raises(Exception, match=r"output of data\[1\], sample 100 is not a finite number"):
        stabilis.Workbench(model=model(), data=two, sample_rate_hz=FS)


def test_a_model_undefined_beside_its_start_is_refused_not_fitted():
    # The model's f gives NaN for k below its documented 40 and the truth is 38: every step of
    # the fit towards the truth failed, and compare returned k = 40 with a standard error as
    # if it had converged. Now the fit names the wall and the user's error reaches the caller.
    def f(x, u, p):
        if p["k"] < 40.0:
            return [float("nan"), float("nan")]
        return [x[1], -p["k"] * x[0] - p["c"] * x[1] + p["g"] * u[0]]

    m = stabilis.Model(states=["q", "qdot"], inputs=["u"], outputs=["q"], name="oscillator",
                       parameters={"k": (40.0, 1.0, 400.0), "c": {"value": 2.0, "min": 0.0},
                                   "g": 30.0},
                       f=f, h=lambda x, u, p: [x[0]], operating_point={"q": 0.0, "qdot": 0.0, "u": 0.0})
    wb = stabilis.Workbench(model=m, data=experiments(plant(38.0, 2.4, 31.0)), sample_rate_hz=FS)
    with pytest.raises(ValueError, match=r"model oscillator: f\(x, u, params\)\[0\] = NaN"):
        wb.compare()
    # The same model defined everywhere fits k to the truth.
    fine = stabilis.Model(states=["q", "qdot"], inputs=["u"], outputs=["q"], name="oscillator",
                          parameters={"k": (40.0, 1.0, 400.0), "c": {"value": 2.0, "min": 0.0},
                                      "g": 30.0},
                          f=lambda x, u, p: [x[1], -p["k"] * x[0] - p["c"] * x[1] + p["g"] * u[0]],
                          h=lambda x, u, p: [x[0]],
                          operating_point={"q": 0.0, "qdot": 0.0, "u": 0.0})
    doc = stabilis.Workbench(model=fine, data=experiments(plant(38.0, 2.4, 31.0)),
                             sample_rate_hz=FS).compare()
    assert abs(doc["steps"][-1]["params"]["k"] / 38.0 - 1.0) < 0.01, doc["steps"][-1]["params"]


def test_a_bad_model_file_raises_model_error_naming_key_and_position(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "p"\nstates = ["x"]\ninputs = ["u"]\noutputs = ["x"]\n'
                   '[parameters]\na = 1.0\n[linear]\nA = [["-a*bb"]]\nB = [[1]]\nC = [[1]]\n')
    with pytest.raises(stabilis.ModelError, match=r'linear.A\[0\]\[0\]: unknown name "bb" at position 4'):
        stabilis.Model.from_file(str(bad))


def test_complex_string_and_object_arrays_are_refused_naming_the_key_and_dtype():
    # numpy would cast complex data to their real part with only a ComplexWarning, and parse
    # strings as numbers; the workbench refuses both (README "Guarantees").
    e = experiments(plant(42.0, 2.4, 31.0), seeds=(1,))[0]
    bad = [("u", e["u"] + 1j * e["u"], r'data\[0\]\["u"\] must hold real numbers; got dtype complex128'),
           ("y", e["y"].astype(str), r'data\[0\]\["y"\] must hold real numbers; got dtype <U'),
           ("r", e["r"].astype(object), r'data\[0\]\["r"\] must hold real numbers; got dtype object')]
    for key, value, message in bad:
        with pytest.raises(TypeError, match=message):
            stabilis.Workbench(model=model(), data=[{**e, key: value}], sample_rate_hz=FS)
    # What the user's callables return goes through the same conversion.
    with pytest.raises(TypeError, match="model oscillator: B must hold real numbers; got dtype complex128"):
        stabilis.Model(states=["q", "qdot"], inputs=["u"], outputs=["q"], name="oscillator",
                       parameters={"k": 1.0},
                       matrices=lambda p: (np.eye(2), np.ones((2, 1)) * 1j, np.ones((1, 2)),
                                           np.zeros((1, 1))))
    with pytest.raises(TypeError, match=r"model nl: h\(x, u, params\) must hold real numbers; got dtype complex128"):
        stabilis.Model(states=["q"], inputs=["u"], outputs=["q"], name="nl", parameters={"k": 1.0},
                       f=lambda x, u, p: [-p["k"] * x[0] + u[0]], h=lambda x, u, p: [x[0] + 0j],
                       operating_point={"q": 0.0, "u": 0.0})
    wb = stabilis.Workbench(model=model(), data=[e], sample_rate_hz=FS)
    with pytest.raises(TypeError, match="effect cdrag: A must hold real numbers; got dtype complex128"):
        wb.add(lambda p, m: {"A": np.zeros((2, 2)) * p["d"] * 1j}, params={"d": 0.1}, name="cdrag")
    # Real dtypes (integers, booleans) are still read as numbers.
    wb = stabilis.Workbench(model=model(), data=[{**e, "u": (e["u"] > 0).astype(int)}],
                            sample_rate_hz=FS)
    assert wb.system == "oscillator"


def test_a_missing_model_file_is_a_model_error_naming_the_path(tmp_path):
    missing = tmp_path / "absent.toml"
    with pytest.raises(stabilis.ModelError, match=r"model file not found: .*absent\.toml"):
        stabilis.Model.from_file(str(missing))
    with pytest.raises(stabilis.ModelError, match=r"model file not found: .*absent\.toml"):
        stabilis.Workbench(model=str(missing), data=experiments(plant(42.0, 2.4, 31.0)),
                           sample_rate_hz=FS)
    with pytest.raises(stabilis.ModelError, match=f"cannot read model file {tmp_path}"):
        stabilis.Model.from_file(str(tmp_path))


def csv_logs(directory, data, fs):
    """The experiments as CSV logs (t, u, q, r_u) sampled at `fs`."""
    for i, e in enumerate(data):
        n = len(e["u"])
        np.savetxt(directory / f"e{i}.csv", np.column_stack([np.arange(n) / fs, e["u"], e["y"], e["r"]]),
                   delimiter=",", header="t,u,q,r_u", comments="")
    return [str(directory)]


def test_sample_rate_hz_that_contradicts_the_logs_is_a_value_error(tmp_path):
    paths = csv_logs(tmp_path, experiments(plant(42.0, 2.4, 31.0)), FS)
    with pytest.raises(ValueError, match="sample_rate_hz=100 contradicts the data, which were recorded at 50 Hz"):
        stabilis.Workbench(model=model(), data=paths, sample_rate_hz=2 * FS)
    # The logs' own rate, given again, is accepted and is the rate used.
    given = stabilis.Workbench(model=model(), data=paths, sample_rate_hz=FS).compare()
    own = stabilis.Workbench(model=model(), data=paths).compare()
    assert given["steps"][0]["cost"] == own["steps"][0]["cost"]
    # The embedded flying-platform dataset carries its rate (50 Hz) too.
    with pytest.raises(ValueError, match="sample_rate_hz=200 contradicts the data, which were recorded at 50 Hz"):
        stabilis.Workbench(sample_rate_hz=200.0)


def test_two_workbenches_of_one_python_model_keep_their_own_exceptions():
    # Each workbench keeps its own slot for a user's exception and its own stop flag: a
    # workbench whose model raises on one thread while another workbench of the same
    # stabilis.Model runs on a second thread gets its exception, and the other its result,
    # the one it gives alone. (With one slot per stabilis.Model the second run was stopped
    # and raised the first one's exception.)
    data = experiments(plant(42.0, 2.4, 31.0))
    running = threading.Event()
    calls = {"B": 0}

    def shared(p):
        thread = threading.current_thread().name
        if thread == "A":
            raise Boom("A's model fails")
        if thread == "B":
            calls["B"] += 1
            if calls["B"] == 20:
                running.set()
        return matrices(p)

    m = stabilis.Model(states=["q", "qdot"], inputs=["u"], outputs=["q"], name="oscillator",
                       parameters={"k": (40.0, 1.0, 400.0), "c": {"value": 2.0, "min": 0.0},
                                   "g": 30.0},
                       matrices=shared)
    alone = stabilis.Workbench(model=m, data=data, sample_rate_hz=FS).discover()
    a = stabilis.Workbench(model=m, data=data, sample_rate_hz=FS)
    b = stabilis.Workbench(model=m, data=data, sample_rate_hz=FS)
    out = {}

    def run_a():
        running.wait(60)
        try:
            a.fit()
            out["A"] = "returned"
        except Boom as e:
            out["A"] = str(e)
            out["A while B ran"] = not out_b_done.is_set()

    def run_b():
        try:
            out["B"] = b.discover()
        except BaseException as e:  # noqa: BLE001 - the test reports what B raised
            out["B"] = repr(e)
        out_b_done.set()

    out_b_done = threading.Event()
    threads = [threading.Thread(target=run_a, name="A"), threading.Thread(target=run_b, name="B")]
    for t in threads:
        t.start()
    for t in threads:
        t.join(300)
    assert out["A"] == "A's model fails", out
    assert out["A while B ran"], "B ended before A raised: the test did not overlap them"
    assert isinstance(out["B"], dict), out["B"]
    assert out["B"]["found"] == alone["found"] and out["B"]["unexplained"] is False
    assert out["B"]["steps"][-1]["cost"] == pytest.approx(alone["steps"][-1]["cost"], rel=1e-12)
