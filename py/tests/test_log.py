"""stabilis.read_mcap / read_csv: numpy arrays out, named exceptions for bad files."""
import json
from pathlib import Path

import numpy as np
import pytest

import stabilis


def test_installed_package_is_tested():
    # The tests must exercise the built wheel, not the source tree.
    source = Path(__file__).resolve().parents[1] / "python" / "stabilis"
    assert Path(stabilis.__file__).resolve().parent != source


def test_read_mcap_gives_columns_and_metadata(tmp_path):
    path = tmp_path / "run.mcap"
    run = stabilis.sim.run("wheel-pendulum", 1.0, out=path, seed=2)
    log = stabilis.read_mcap(path)
    assert isinstance(log, stabilis.Log) and log.complete and log.problem is None
    assert sorted(log) == ["/wheel_pendulum/input", "/wheel_pendulum/output", "/wheel_pendulum/state"]
    t, fields = log["/wheel_pendulum/output"]
    assert t.dtype == np.float64 and t.shape == (201,)
    assert list(fields) == ["phi", "phi_dot", "omega_w"]
    # What was written is what is read, bit for bit.
    for topic, (t_run, fields_run) in run.items():
        t_log, fields_log = log[topic]
        np.testing.assert_array_equal(t_log, t_run)
        for name in fields_run:
            np.testing.assert_array_equal(fields_log[name], fields_run[name])
    assert log.experiment["sample_rate_hz"] == "200"
    assert log.metadata["experiment"]["seed"] == "2"


def test_read_csv(tmp_path):
    path = tmp_path / "measured.csv"
    path.write_text("t,w1,w2\n0,1.5,-2\n0.01,2.5,-3\n")
    t, fields = stabilis.read_csv(path)
    np.testing.assert_array_equal(t, [0.0, 0.01])
    np.testing.assert_array_equal(fields["w2"], [-2.0, -3.0])


def test_missing_file_is_a_log_error(tmp_path):
    with pytest.raises(stabilis.LogError, match="file not found: .*absent.mcap"):
        stabilis.read_mcap(tmp_path / "absent.mcap")
    with pytest.raises(stabilis.Error, match="file not found"):
        stabilis.read_csv(tmp_path / "absent.csv")


def test_not_mcap_is_named(tmp_path):
    path = tmp_path / "notes.mcap"
    path.write_text("not a log")
    with pytest.raises(stabilis.LogError, match="not an MCAP file"):
        stabilis.read_mcap(path)


def test_missing_topic_lists_the_available_ones(tmp_path):
    path = tmp_path / "run.mcap"
    stabilis.sim.run("wheel-pendulum", 0.1, out=path)
    with pytest.raises(stabilis.LogError, match=r'missing channel "/cubli/output" in .*available: /wheel_pendulum/input'):
        stabilis.read_mcap(path, topics=["/cubli/output"])


def test_csv_problems_are_named(tmp_path):
    cases = {
        "no_t.csv": ("x\n1\n", 'missing field "t"'),
        "nan.csv": ("t,x\n0,nan\n", 'field "x" in .* is not a finite number'),
        "word.csv": ("t,x\n0,abc\n", r'line 2, column "x": "abc" is not a number'),
    }
    for name, (content, message) in cases.items():
        path = tmp_path / name
        path.write_text(content)
        with pytest.raises(stabilis.LogError, match=message):
            stabilis.read_csv(path)


def test_exception_hierarchy():
    assert issubclass(stabilis.LogError, stabilis.Error)
    assert issubclass(stabilis.SimError, stabilis.Error)
    assert issubclass(stabilis.Error, Exception)
    assert not issubclass(stabilis.Error, ValueError)


def test_wrong_argument_types_raise_type_error_not_a_crash():
    with pytest.raises(TypeError):
        stabilis.log._native.read_mcap(42)
    with pytest.raises(TypeError):
        stabilis.sim._native.run("wheel-pendulum", [1, 2])


def test_summary_is_json_serialisable(tmp_path):
    run = stabilis.sim.run("wheel-pendulum", 0.5)
    json.dumps(run.summary)
    assert run.out is None
