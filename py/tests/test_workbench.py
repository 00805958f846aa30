"""stabilis.Workbench on the embedded flying-platform dataset (18 closed-loop experiments with
momentum drag and fan gyroscopic torque hidden in the truth)."""
import numpy as np
import pytest

import stabilis


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
    before = wb.fit()["steps"][0]["cost"]
    diagnosis = wb.diagnose()
    assert any(line["flagged"] for line in diagnosis["lines"])
    wb.add("momentum_drag")
    after = wb.fit()["steps"][0]
    assert after["cost"] < 0.01 * before
    assert after["std"]["c_alpha1"] > 0


def test_bad_input_raises():
    with pytest.raises(ValueError, match="unknown system"):
        stabilis.Workbench("boat")
    with pytest.raises(stabilis.LogError):
        stabilis.Workbench(data=["/nonexistent/run.mcap"])
    wb = stabilis.Workbench()
    with pytest.raises(stabilis.Error, match="ground_effect"):
        wb.add("ground_effect")
