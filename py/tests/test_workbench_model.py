"""stabilis.Model from Python: a callable model, arrays as data, effects as discovery
candidates (one that adds a state), errors by name. The data are simulated here with scipy's
exact zero-order-hold discretisation of the truth (independent of stabilis)."""
from __future__ import annotations

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
    # The generic actuator_lag describes the same physics: offering the user's effect under
    # its own name must make discovery choose between the two, and the fitted time constant
    # must be the truth's either way (3 seed sets, all must pass).
    data = experiments(plant(42.0, 2.4, 31.0, lag=0.05), seeds=seeds)
    wb = stabilis.Workbench(model=model(effects=[LAG]), data=data, sample_rate_hz=FS)
    result = wb.discover()
    assert len(result["found"]) == 1 and result["found"][0] in ("slow_drive", "actuator_lag")
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
    with pytest.raises(ValueError, match=r"A has shape \(1, 2\), must be \(2, 2\)"):
        stabilis.Model(states=["q", "qdot"], inputs=["u"], outputs=["q"], parameters={"k": 1.0},
                       matrices=lambda p: (np.zeros((1, 2)), np.zeros((2, 1)), np.zeros((1, 2)),
                                           np.zeros((1, 1))))
    with pytest.raises(ValueError, match="states\\[1\\] \"q\" is named twice"):
        stabilis.Model(states=["q", "q"], inputs=["u"], outputs=["q"], parameters={},
                       matrices=matrices)

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


def test_a_bad_model_file_raises_model_error_naming_key_and_position(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "p"\nstates = ["x"]\ninputs = ["u"]\noutputs = ["x"]\n'
                   '[parameters]\na = 1.0\n[linear]\nA = [["-a*bb"]]\nB = [[1]]\nC = [[1]]\n')
    with pytest.raises(stabilis.ModelError, match=r'linear.A\[0\]\[0\]: unknown name "bb" at position 4'):
        stabilis.Model.from_file(str(bad))
