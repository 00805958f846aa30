"""stabilis.Workbench on the embedded flying-platform dataset (18 closed-loop experiments with
momentum drag and fan gyroscopic torque hidden in the truth)."""
import numpy as np
import pytest

import stabilis
from stabilis import flying_platform as fp


@pytest.fixture(scope="module")
def wb():
    return stabilis.Workbench("flying_platform")


def test_frf_has_the_paper_shape_and_positive_std(wb):
    frf = wb.frf()
    assert frf["G"].shape == (20, 6, 9) and frf["G"].dtype == np.complex128
    assert np.allclose(frf["freqs_hz"], np.arange(1, 21) * 0.2)
    assert (frf["std"] > 0).all()
    assert frf["estimator"] == "InstrumentalVariable"


def test_discover_finds_drag_then_gyroscopic(wb, tmp_path):
    result = wb.discover()
    assert result["found"] == ["momentum_drag", "fan_gyroscopic"]
    assert result["unexplained"] is False
    costs = [s["cost"] for s in result["steps"]]
    assert costs[-1] < 0.05 * costs[0]
    assert result["steps"][0]["added"] is None
    assert abs(result["steps"][-1]["params"]["c_alpha1"] - 2.388) < 0.24
    wb.report(tmp_path / "report")
    assert "<svg" in (tmp_path / "report" / "index.html").read_text()


def test_add_and_fit_lowers_the_cost():
    wb = stabilis.Workbench()
    nominal = wb.fit()["steps"][0]
    diagnosis = wb.diagnose()
    assert any(line["flagged"] for line in diagnosis["lines"])
    wb.add("momentum_drag")
    after = wb.fit()["steps"][0]
    # Each single fit weights with the noise estimated from its own residual, which inflates
    # the noise of a poor model and lowers its cost; even so drag removes over 95% of it and
    # brings the cost near the noise level (discover() reports both under one weighting).
    assert after["cost"] < 0.05 * nominal["cost"]
    assert nominal["normalized_cost"] > 10 and after["normalized_cost"] < 2
    assert after["std"]["c_alpha1"] > 0


def test_bad_input_raises():
    with pytest.raises(stabilis.SimError, match="not a shipped system.*--model FILE"):
        stabilis.Workbench("boat")
    with pytest.raises(stabilis.LogError):
        stabilis.Workbench(data=["/nonexistent/run.mcap"])
    wb = stabilis.Workbench()
    with pytest.raises(stabilis.Error, match="ground_effect"):
        wb.add("ground_effect")


# --- user-defined effects: a Python callable returning the extra state-space terms ---------


def vz_drag(p, m):
    """Linear drag on the vertical velocity: vz' += -d vz (state 2 of the hover model)."""
    dA = np.zeros_like(m["A"])
    dA[2, 2] = -p["d"]
    return {"A": dA}


@pytest.fixture(scope="module")
def drag_logs(tmp_path_factory):
    """The 18 closed-loop experiments of the paper's design from a truth with momentum drag
    only (linear hover dynamics, seed 12), as `stabilis sim flying-platform --scenario sysid`
    writes them: the data of crates/sim/tests/workbench_user_effect.rs."""
    out = tmp_path_factory.mktemp("drag")
    stabilis.sim.run("flying-platform", duration=0.0, out=str(out), seed=12,
                     scenario="sysid", effects="momentum_drag", dynamics="linear",
                     **{"lambda": (1.2, 0.8, 2.0)})
    return str(out)


def test_python_vertical_drag_matches_the_rust_user_effect(drag_logs):
    # Truth: the vz-vz entry of the momentum-drag hover model, computed by the
    # flying_platform crate independently of the workbench.
    truth = fp.Model("momentum_drag")
    a_truth, _ = truth.hover_matrices()
    expected = -a_truth[2, 2]
    assert abs(expected - 1.85) < 0.01
    wb = stabilis.Workbench(data=[drag_logs])
    before = wb.fit()["steps"][0]["cost"]
    wb.add(stabilis.Effect("vz_drag", {"d": 0.1}, vz_drag, bounds={"d": (0.0, 50.0)},
                           units={"d": "1/s"}))
    step = wb.fit()["steps"][0]
    d, std = step["params"]["vz_drag.d"], step["std"]["vz_drag.d"]
    # Against the independent truth: within three of the fit's own standard deviations (a
    # miss has probability 0.3 % if the reported std is right), and that std small enough for
    # the check to mean something (under 15 % of the truth).
    assert 0.0 < std < 0.15 * expected, std
    assert abs(d - expected) < 3.0 * std, (d, std, expected)
    assert step["cost"] < before
    assert step["effects"][-1] == "vz_drag"
    # The bare callable with its parameters is the same effect (named after the function).
    plain = stabilis.Workbench(data=[drag_logs])
    plain.add(vz_drag, params={"d": 0.1}, bounds={"d": (0.0, 50.0)})
    assert plain.fit()["steps"][0]["params"]["vz_drag.d"] == pytest.approx(d, rel=1e-9)


def test_errors_in_the_callable_become_python_exceptions():
    wb = stabilis.Workbench()

    class Boom(RuntimeError):
        pass

    def raises(p, m):
        raise Boom("inside the effect")

    with pytest.raises(Boom, match="inside the effect"):
        wb.add(stabilis.Effect("boom", {"k": 1.0}, raises))
    # A larger A adds states; a smaller one is refused with both sizes.
    with pytest.raises(ValueError, match="returned A with 3 rows; the model has 9 states"):
        wb.add(stabilis.Effect("small", {"k": 1.0}, lambda p, m: {"A": np.eye(3)}))
    with pytest.raises(ValueError, match="nan"):
        wb.add(stabilis.Effect("nan", {"k": 1.0},
                               lambda p, m: {"B": np.full_like(m["B"], np.nan)}))
    with pytest.raises(ValueError, match="use A, B, C or D"):
        wb.add(stabilis.Effect("key", {"k": 1.0}, lambda p, m: {"E": m["A"]}))
    with pytest.raises(TypeError, match="must return a dict"):
        wb.add(stabilis.Effect("list", {"k": 1.0}, lambda p, m: [m["A"]]))
    with pytest.raises(TypeError, match="callable"):
        stabilis.Effect("nofunc", {"k": 1.0}, 3)
    with pytest.raises(TypeError, match="needs params"):
        wb.add(vz_drag)
    with pytest.raises(TypeError, match="go with a callable"):
        wb.add("momentum_drag", params={"k": 1.0})
    # Raising only away from the documented value: caught when the fit reaches it.
    def late(p, m):
        if p["k"] != 0.5:
            raise Boom("k left its documented value")
        return {}

    wb.add(stabilis.Effect("late", {"k": 0.5}, late, bounds={"k": (0.0, 1.0)}))
    with pytest.raises(Boom, match="documented value"):
        wb.fit()


# --- the Cubli workbench on `stabilis sim cubli` logs --------------------------------------


def cubli_logs(directory, **hidden):
    """Four 40 s balancing runs at 100 Hz with a 0.01 N m multisine on the commanded torques
    and the default sensor noise; `hidden` are `stabilis sim cubli` options of the truth."""
    paths = []
    for seed, tilt in [(31, 5.0), (32, -4.0), (33, 3.0), (34, -4.5)]:
        path = str(directory / f"run{seed}.mcap")
        stabilis.sim.run("cubli", duration=40.0, out=path, seed=seed, tilt_deg=tilt,
                         excitation_rms=0.01, **hidden)
        paths.append(path)
    return paths


def test_cubli_finds_hidden_viscous_friction_within_15_percent(tmp_path):
    c = 2e-5
    wb = stabilis.Workbench("cubli", data=cubli_logs(tmp_path, viscous=(c, c, c)))
    assert wb.system == "cubli"
    nominal = wb.compare()
    assert nominal["found"] == [] and len(nominal["steps"]) == 1
    diagnosis = wb.diagnose()
    flagged = [ch["channel"] for ch in diagnosis["channels"] if ch["flagged"]]
    assert set(flagged) & {"p_w1", "p_w2", "p_w3"}, diagnosis
    result = wb.discover()
    assert result["found"] == ["wheel_viscous_friction"]
    assert result["unexplained"] is False
    est = result["steps"][-1]["params"]["wheel_viscous_friction"]
    assert abs(est - c) < 0.15 * c, est
    costs = [s["cost"] for s in result["steps"]]
    assert costs[-1] < costs[0]
    wb.report(tmp_path / "report")
    html = (tmp_path / "report" / "index.html").read_text()
    assert "<svg" in html and "wheel_viscous_friction" in html
    wb.add("wheel_viscous_friction")
    fitted = wb.fit()["steps"][0]
    assert fitted["params"]["wheel_viscous_friction"] == pytest.approx(est, rel=1e-9)
    assert fitted["std"]["wheel_viscous_friction"] > 0
    with pytest.raises(ValueError, match="no FRF"):
        wb.frf()
    with pytest.raises(ValueError, match="named candidates"):
        wb.add(stabilis.Effect("vz_drag", {"d": 0.1}, vz_drag))
    with pytest.raises(stabilis.Error, match="wheel_coulomb_friction"):
        wb.add("ground_effect")


def test_cubli_clean_logs_find_nothing(tmp_path):
    wb = stabilis.Workbench("cubli", data=cubli_logs(tmp_path))
    result = wb.discover()
    assert result["found"] == []
    assert result["unexplained"] is False


def test_cubli_bad_input_raises(tmp_path):
    with pytest.raises(ValueError, match="needs logs"):
        stabilis.Workbench("cubli")
    with pytest.raises(stabilis.LogError):
        stabilis.Workbench("cubli", data=[str(tmp_path / "missing.mcap")])


def test_frf_docstring_describes_the_returned_dict(wb):
    doc = stabilis.Workbench.frf.__doc__
    assert "(freqs_hz, G, std)" not in doc
    frf = wb.frf()
    assert isinstance(frf, dict)
    for key in frf:
        assert f"`{key}`" in doc, key
    assert f'"{frf["estimator"]}"' in doc


def test_cubli_sample_rate_hz_that_contradicts_the_logs_is_a_value_error(tmp_path):
    path = str(tmp_path / "run.mcap")
    stabilis.sim.run("cubli", duration=10.0, out=path, seed=1, tilt_deg=3.0)
    with pytest.raises(ValueError, match="sample_rate_hz=50 contradicts the data, which were recorded at 100 Hz"):
        stabilis.Workbench("cubli", data=[path], sample_rate_hz=50.0)
