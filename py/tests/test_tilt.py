"""Tilt estimator bindings against an independent numpy implementation of the model, scipy's
generic least squares, and the paper's numbers."""
import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

import stabilis
from stabilis.tilt import G0, Estimator, d_criterion_bound, optimal_placement

RNG = np.random.default_rng(2017)
P = np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0], [0.2 / np.sqrt(3)] * 3])


def hat(w):
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def readings(p, omega, omega_dot, g, sigma=0.0):
    big = hat(omega) @ hat(omega) + hat(omega_dot)
    return p @ big.T - g + sigma * RNG.normal(size=p.shape)


def random_state():
    return RNG.normal(size=3), RNG.normal(size=3), Rotation.random(random_state=RNG).apply([0, 0, -G0])


def test_noise_free_sample_is_recovered():
    est = Estimator(P)
    omega, omega_dot, g = random_state()
    e = est.estimate(readings(P, omega, omega_dot, g))
    assert e["converged"] and e["g"].shape == (3,)
    np.testing.assert_allclose(e["g"], g, atol=1e-6)
    np.testing.assert_allclose(e["omega_dot"], omega_dot, atol=1e-6)
    np.testing.assert_allclose(np.abs(e["omega"]), np.abs(omega), atol=1e-6)
    np.testing.assert_allclose(e["omega_norm"], np.linalg.norm(omega), atol=1e-6)


def test_matches_a_generic_constrained_least_squares_solver():
    """scipy's Levenberg-Marquardt on the parametrisation (omega, omega_dot, gravity angles)
    started at the truth finds the same minimum as the fixed-point iteration."""
    est = Estimator(P)
    for _ in range(20):
        omega, omega_dot, g = random_state()
        m = readings(P, omega, omega_dot, g, sigma=0.05)

        def residual(x):
            gg = G0 * np.array([np.cos(x[7]) * np.sin(x[6]), np.sin(x[7]) * np.sin(x[6]), np.cos(x[6])])
            big = hat(x[:3]) @ hat(x[:3]) + hat(x[3:6])
            return (m - P @ big.T + gg).ravel()

        theta = np.arccos(g[2] / G0)
        x0 = np.concatenate([omega, omega_dot, [theta, np.arctan2(g[1], g[0])]])
        ref = least_squares(residual, x0, xtol=1e-14, ftol=1e-14, gtol=1e-14)
        e = est.estimate(m)
        assert e["cost"] <= 0.5 * np.sum(ref.fun**2) * (1 + 1e-9)
        gg = G0 * np.array([np.cos(ref.x[7]) * np.sin(ref.x[6]), np.sin(ref.x[7]) * np.sin(ref.x[6]), np.cos(ref.x[6])])
        np.testing.assert_allclose(e["g"], gg, atol=1e-6)


def test_batch_equals_single_samples():
    est = Estimator(P)
    batch = np.stack([readings(P, *random_state(), sigma=7.7e-3) for _ in range(7)])
    out = est.estimate(batch)
    assert out["g"].shape == (7, 3) and out["omega_matrix"].shape == (7, 3, 3)
    assert out["iterations"].shape == (7,) and out["converged"].dtype == bool
    for t in range(7):
        single = est.estimate(batch[t])
        np.testing.assert_array_equal(out["g"][t], single["g"])
        assert out["iterations"][t] == single["iterations"]


def test_least_squares_baseline_is_exact_for_four_sensors():
    est = Estimator(P)
    omega, omega_dot, g = random_state()
    ls = est.least_squares(readings(P, omega, omega_dot, g))
    np.testing.assert_allclose(ls["g_raw"], g, atol=1e-9)
    np.testing.assert_allclose(ls["omega_matrix"], hat(omega) @ hat(omega) + hat(omega_dot), atol=1e-9)
    assert not ls["rank_deficient"]


def test_tuning_of_the_paper_layout():
    t = Estimator(P).tuning
    assert t["q"] == pytest.approx(0.25)
    assert t["r"] == pytest.approx(0.97498, abs=1e-4)
    assert t["eigenvalues"][1] == pytest.approx(0.94790, abs=1e-4) and t["certified"]
    assert t["rule"] == "closed_form"
    assert Estimator(P, q=0.2, r=1.0).tuning["rule"] == "manual"


def test_fisher_and_cramer_rao_bound():
    f = Estimator(P).fisher([1.0, -0.5, 0.8], [2.0, 1.0, -1.0])
    assert f["rank"] == 8
    assert np.trace(f["crb_omega"]) == pytest.approx(0.8420, abs=1e-4)
    assert np.trace(f["crb_omega_dot"]) == pytest.approx(2.2419, abs=1e-4)
    assert np.trace(f["crb_tilt"]) == pytest.approx(1.2704, abs=1e-4)
    np.testing.assert_allclose(f["crb"], np.linalg.inv(f["information"]), rtol=1e-9, atol=1e-12)
    three = Estimator(0.05 * np.eye(3))
    singular = three.fisher([1.0, 1.0, 1.0], [0.0, 0.0, 0.0])
    assert singular["rank"] == 7 and singular["crb"] is None


def test_three_sensors_flag_omega_along_the_plane_normal():
    est = Estimator(0.05 * np.eye(3))
    m = readings(0.05 * np.eye(3), 2.0 * np.ones(3) / np.sqrt(3), np.zeros(3), np.array([0, 0, -G0]), 7.7e-4)
    e = est.estimate(m)
    assert e["omega_along_plane_normal"] and e["plane_alignment"] < 0.2
    assert np.isnan(Estimator(P).estimate(m[[0, 1, 2, 2]])["plane_alignment"])


def test_optimal_placement():
    positions, ratio = optimal_placement(4)
    assert positions.shape == (4, 3) and ratio == pytest.approx(1.0, abs=1e-9)
    np.testing.assert_allclose(positions.sum(axis=0), 0, atol=1e-12)
    np.testing.assert_allclose(positions.T @ positions, 4 / 3 * np.eye(3), atol=1e-12)
    assert Estimator(positions).d_criterion() == pytest.approx(d_criterion_bound(4), rel=1e-9)
    assert d_criterion_bound(4) == pytest.approx(2.0512e10, rel=1e-4)


def test_bad_input_raises_named_errors():
    est = Estimator(P)
    with pytest.raises(ValueError, match="at least 3"):
        Estimator(P[:2])
    with pytest.raises(ValueError, match=r"shape \(4, 3\)"):
        est.estimate(np.zeros((3, 3)))
    bad = np.tile([0.0, 0.0, G0], (4, 1))
    bad[2, 1] = np.nan
    with pytest.raises(ValueError, match="sensor 2"):
        est.estimate(bad)
    batch = np.stack([np.tile([0.0, 0.0, G0], (4, 1)), bad])
    with pytest.raises(ValueError, match="sample 1"):
        est.estimate(batch)
    with pytest.raises(stabilis.Error, match="coplanar with the pivot"):
        Estimator([[1, 0, 0], [0, 1, 0], [1, 1, 0]])
    with pytest.raises(ValueError, match="both step sizes"):
        Estimator(P, q=0.25)
    with pytest.raises(stabilis.Error, match="q"):
        Estimator(P, q=-1.0, r=1.0)
    with pytest.raises(stabilis.Error, match="at least 4"):
        optimal_placement(3)


def test_cli_reads_a_log_written_by_the_official_mcap_writer(tmp_path):
    """`stabilis tilt --data` on a log in the documented format written by the `mcap` package:
    its estimates equal the Python binding's, and beat least squares against /imu/truth."""
    import json
    import os
    import subprocess
    from pathlib import Path

    from mcap.writer import Writer

    repo = Path(__file__).resolve().parents[2]
    binary = Path(os.environ.get("STABILIS_BIN", repo / "target" / "release" / "stabilis"))
    if not binary.is_file():
        pytest.fail(f"stabilis binary not found at {binary}; build it with `cargo build --release -p sim`")

    def schema(writer, name, fields):
        data = json.dumps({"type": "object", "properties": {k: {"type": "number"} for k in ["t", *fields]}})
        return writer.register_schema(name=name, encoding="jsonschema", data=data.encode())

    accel_fields = [f"a{i}{c}" for i in range(1, 5) for c in "xyz"]
    states = [random_state() for _ in range(60)]
    readings_all = np.stack([readings(P, *s, sigma=7.7e-3) for s in states])
    path = tmp_path / "imu.mcap"
    with open(path, "wb") as f:
        writer = Writer(f)
        writer.start()
        accel = writer.register_channel(
            topic="/imu/accel", message_encoding="json", schema_id=schema(writer, "imu.accel", accel_fields)
        )
        truth = writer.register_channel(
            topic="/imu/truth", message_encoding="json", schema_id=schema(writer, "imu.truth", ["gx", "gy", "gz"])
        )
        meta = {"sensors": "4"}
        meta.update({f"p{i + 1}": ",".join(repr(float(v)) for v in P[i]) for i in range(4)})
        writer.add_metadata("imu", meta)
        for k, (state, m) in enumerate(zip(states, readings_all)):
            t = 0.02 * k
            ns = int(round(t * 1e9))
            msg = {"t": t, **{name: float(v) for name, v in zip(accel_fields, m.ravel())}}
            writer.add_message(accel, log_time=ns, publish_time=ns, data=json.dumps(msg).encode())
            g = state[2]
            msg = {"t": t, "gx": g[0], "gy": g[1], "gz": g[2]}
            writer.add_message(truth, log_time=ns, publish_time=ns, data=json.dumps(msg).encode())
        writer.finish()

    out = tmp_path / "estimates.mcap"
    done = subprocess.run(
        [str(binary), "tilt", "--data", str(path), "--out", str(out), "--json"],
        capture_output=True, text=True, check=False,
    )
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    assert report["samples"] == 60 and report["converged"] == 60
    assert report["errors"]["tilt_ml"] < report["errors"]["tilt_least_squares"]
    log = stabilis.read_mcap(out)
    _, fields = log["/tilt/estimate"]
    cli_g = np.stack([fields["gx"], fields["gy"], fields["gz"]], axis=1)
    np.testing.assert_allclose(cli_g, Estimator(P).estimate(readings_all)["g"], rtol=0, atol=1e-12)

    bad = tmp_path / "bad.mcap"
    with open(bad, "wb") as f:
        writer = Writer(f)
        writer.start()
        writer.register_channel(topic="/imu/accel", message_encoding="json",
                                schema_id=schema(writer, "imu.accel", accel_fields))
        writer.add_metadata("imu", {"sensors": "4", "p1": "1,0,0"})
        writer.finish()
    done = subprocess.run([str(binary), "tilt", "--data", str(bad)], capture_output=True, text=True, check=False)
    assert done.returncode == 2 and '"p2"' in done.stderr
