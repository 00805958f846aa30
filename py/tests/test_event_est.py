"""stabilis.event_est: synthesis reproduces the paper's platoon design, the simulation
reproduces its communication rates, and bad input raises named errors."""
import numpy as np
import pytest

import stabilis
from stabilis import event_est


@pytest.fixture(scope="module")
def model():
    return event_est.platoon(3)


@pytest.fixture(scope="module")
def design(model):
    return event_est.synthesize(model, j_max=0.38, condition="cor12")


def test_platoon_model_matches_the_paper(model):
    assert model["A"].shape == (5, 5) and model["B"].shape == (5, 3)
    assert np.allclose(model["A"][1], [0.02, 1, -0.02, 0, 0])
    assert abs(model["F"][0, 0] + 0.361075) < 2e-6


def test_synthesis_reproduces_c_star_and_threshold_ratios(design):
    assert abs(design["c_star"] - 0.010205) / 0.010205 < 0.01
    d = [float(x[0, 0]) for x in design["delta"]]
    # Thesis: (0.107, 0.092, 0.106); the spec's reproduction: (0.1233, 0.1058, 0.1220).
    assert np.allclose(d, [0.1233, 0.1058, 0.1220], rtol=0.03)
    assert abs(d[1] / d[0] - 0.092 / 0.107) < 0.02
    assert design["bound"] <= 0.38 * (1 + 1e-3)
    assert design["stability_lmis"] == 8


def test_simulation_rates_at_the_paper_thresholds(model, design):
    paper = {"L": design["L"], "delta": [[[0.107]], [[0.092]], [[0.106]]]}
    run = event_est.simulate(model, paper, steps=50_000, loss=0.1, x0=[5, 0, 0, 0, 0], seed=3,
                             window_start=15_000)
    assert 0.05 <= run["rates"][1] <= 0.11
    assert run["rates"][0] < 0.05 and run["rates"][2] < 0.05
    assert run["error_power"] < 0.05


def test_more_budget_means_less_communication(model):
    small = event_est.synthesize(model, j_max=0.1)
    large = event_est.synthesize(model, j_max=0.3)
    r_small = event_est.simulate(model, small, steps=20_000, seed=1)["total_rate"]
    r_large = event_est.simulate(model, large, steps=20_000, seed=1)["total_rate"]
    assert r_large < r_small


def test_bad_input_raises_named_errors(model, design):
    with pytest.raises(ValueError, match="B has shape 5x3, expected 4x3"):
        event_est.synthesize(dict(model, A=np.eye(4)))
    with pytest.raises(ValueError, match="2-D"):
        event_est.synthesize(dict(model, C=np.ones(5)))
    with pytest.raises(stabilis.Error, match="J_max"):
        event_est.synthesize(model, j_max=0.001)
    with pytest.raises(stabilis.Error, match="not Schur stable"):
        event_est.synthesize(dict(model, F=np.zeros((3, 5)), A=2 * np.eye(5)))
    with pytest.raises(stabilis.Error, match="positive definite"):
        event_est.simulate(model, {"L": design["L"], "delta": [[[0.1]], [[-0.1]], [[0.1]]]}, steps=10)
    with pytest.raises(stabilis.Error):
        event_est.platoon(1)
