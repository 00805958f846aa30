"""Interoperability with the official Python `mcap` package, in both directions."""
import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.writer import Writer

import stabilis

REPO = Path(__file__).resolve().parents[2]


def stabilis_bin():
    """The `stabilis` binary: $STABILIS_BIN (set by scripts/test.sh) or target/release."""
    path = Path(os.environ.get("STABILIS_BIN", REPO / "target" / "release" / "stabilis"))
    if not path.is_file():
        pytest.fail(f"stabilis binary not found at {path}; build it with "
                    "`cargo build --release -p sim` or set STABILIS_BIN")
    return str(path)


def discover_model_file(model: Path, data: Path, tmp: Path) -> dict:
    """`stabilis discover --model MODEL --data DATA --json FILE` (exit code 0 asserted): the JSON."""
    out = tmp / "discover.json"
    done = subprocess.run([stabilis_bin(), "discover", "--model", str(model), "--data",
                           str(data), "--json", str(out)], capture_output=True, text=True,
                          check=False)
    assert done.returncode == 0, done.stderr
    return json.loads(out.read_text())


def run_cli(*args):
    return subprocess.run([stabilis_bin(), *args], capture_output=True, text=True, check=False)


def test_log_of_stabilis_sim_reads_with_the_official_reader(tmp_path):
    path = tmp_path / "run.mcap"
    done = run_cli("sim", "wheel-pendulum", "--duration", "2", "--seed", "3", "--out", str(path))
    assert done.returncode == 0, done.stderr

    rows = {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        for schema, channel, message in reader.iter_messages():
            assert schema.encoding == "jsonschema"
            assert channel.message_encoding == "json"
            data = json.loads(message.data)
            assert message.log_time == round(data["t"] * 1e9)
            rows.setdefault(channel.topic, []).append(data)
            schema_json = json.loads(schema.data)
            assert schema_json["type"] == "object"
            assert set(schema_json["properties"]) == set(data)
            assert all(p["type"] == "number" for p in schema_json["properties"].values())
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}

    assert summary.statistics.message_count == 3 * 401
    assert metadata["experiment"]["sample_rate_hz"] == "200"
    assert metadata["experiment"]["system"] == "wheel-pendulum"
    assert all(isinstance(v, str) for v in metadata["experiment"].values())
    state = rows["/wheel_pendulum/state"]
    assert len(state) == 401
    # The values: the run starts at 5 degrees of tilt and is balanced after two seconds.
    assert state[0]["phi"] == np.radians(5.0)
    assert abs(np.degrees(state[-1]["phi"])) < 0.2
    assert [r["t"] for r in state] == pytest.approx(np.arange(401) / 200.0, abs=1e-12)
    # Our own reader sees the same numbers.
    t, fields = stabilis.read_mcap(path)["/wheel_pendulum/state"]
    np.testing.assert_array_equal(fields["omega_w"], [r["omega_w"] for r in state])


def write_with_official_writer(path):
    """A log as another tool would write it: two topics, jsonschema, an experiment record."""
    t = np.arange(50) / 100.0
    with open(path, "wb") as f:
        writer = Writer(f)
        writer.start()
        schema = writer.register_schema(
            name="cubli.output",
            encoding="jsonschema",
            data=json.dumps({
                "type": "object",
                "properties": {k: {"type": "number"} for k in ["t", "wx", "wy", "wz"]},
            }).encode(),
        )
        output = writer.register_channel(topic="/cubli/output", message_encoding="json", schema_id=schema)
        schema_in = writer.register_schema(
            name="cubli.input",
            encoding="jsonschema",
            data=json.dumps({"type": "object", "properties": {"t": {"type": "number"}, "T1": {"type": "number"}}}).encode(),
        )
        inputs = writer.register_channel(topic="/cubli/input", message_encoding="json", schema_id=schema_in)
        writer.add_metadata("experiment", {"sample_rate_hz": "100", "excited": "T1"})
        for k, tk in enumerate(t):
            ns = int(round(tk * 1e9))
            msg = {"t": tk, "wx": np.sin(tk), "wy": np.cos(tk), "wz": 0.5 * k}
            writer.add_message(output, log_time=ns, publish_time=ns, data=json.dumps(msg).encode())
            if k % 2 == 0:
                writer.add_message(inputs, log_time=ns, publish_time=ns, data=json.dumps({"t": tk, "T1": -tk}).encode())
        writer.finish()
    return t


def test_messages_written_out_of_time_order_read_as_the_official_reader_orders_them(tmp_path):
    """MCAP lets a writer put its messages out of time order (here three blocks of a topic in
    separate chunks, the last first). stabilis reads them in time order, as the official reader
    does with log_time_order=True, marks the topic, and refuses a message repeated at one time."""
    rng = np.random.default_rng(3)
    t = np.arange(60) / 100.0
    x = rng.standard_normal(60)

    def write(path, order):
        with open(path, "wb") as f:
            writer = Writer(f, chunk_size=200)
            writer.start()
            channel = writer.register_channel(topic="/rig/output", message_encoding="json", schema_id=0)
            for k in order:
                ns = int(round(t[k] * 1e9))
                writer.add_message(channel, log_time=ns, publish_time=ns,
                                   data=json.dumps({"t": t[k], "x": x[k]}).encode())
            writer.finish()

    path = tmp_path / "blocks.mcap"
    write(path, [*range(40, 60), *range(20, 40), *range(0, 20)])
    with open(path, "rb") as f:
        official = [json.loads(m.data) for _, _, m in make_reader(f).iter_messages(log_time_order=True)]
    tt, fields = stabilis.read_mcap(path)["/rig/output"]
    np.testing.assert_array_equal(tt, [m["t"] for m in official])
    np.testing.assert_array_equal(fields["x"], [m["x"] for m in official])
    np.testing.assert_array_equal(fields["x"], x)
    done = run_cli("info", str(path), "--json")
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["topics"]["/rig/output"]["reordered"] is True

    repeated = tmp_path / "repeated.mcap"
    write(repeated, [*range(0, 30), 12, *range(30, 60)])
    done = run_cli("info", str(repeated))
    assert done.returncode != 0
    assert "messages 12 and 30 are both at t = 0.12 s" in done.stderr, done.stderr


def test_log_of_the_official_writer_reads_with_stabilis_info(tmp_path):
    path = tmp_path / "foreign.mcap"
    t = write_with_official_writer(path)
    done = run_cli("info", str(path), "--json")
    assert done.returncode == 0, done.stderr
    info = json.loads(done.stdout)
    assert info["complete"] is True
    assert info["messages"] == 75
    assert info["topics"]["/cubli/output"] == {"messages": 50, "span": [0.0, 0.49], "fields": ["wx", "wy", "wz"],
                                               "stamped_by_log_time": False, "reordered": False}
    assert info["topics"]["/cubli/input"]["messages"] == 25
    assert info["metadata"]["experiment"] == {"sample_rate_hz": "100", "excited": "T1"}

    log = stabilis.read_mcap(path)
    tt, fields = log["/cubli/output"]
    np.testing.assert_array_equal(tt, t)
    np.testing.assert_array_equal(fields["wy"], np.cos(t))

    missing = run_cli("info", str(path), "--topic", "/cubli/state")
    assert missing.returncode == 2
    assert 'missing channel "/cubli/state"' in missing.stderr
