"""stabilis.sim.run: the wheel pendulum balances, falls without control, and bad options are named."""
import numpy as np
import pytest

import stabilis

RATE = 200.0


def test_balances_from_five_degrees():
    run = stabilis.sim.run("wheel-pendulum", 4.0, seed=11)
    t, state = run["/wheel_pendulum/state"]
    _, inputs = run["/wheel_pendulum/input"]
    assert t.shape == (801,) and t[-1] == 4.0
    assert state["phi"][0] == pytest.approx(np.radians(5.0), abs=0)
    last_second = state["phi"][t >= 3.0]
    assert np.max(np.abs(np.degrees(last_second))) < 0.2
    assert np.max(np.abs(inputs["tau"])) <= 0.2
    assert run.summary["samples"] == 801


def test_measurements_are_state_plus_seeded_noise():
    a = stabilis.sim.run("wheel-pendulum", 1.0, seed=5)
    b = stabilis.sim.run("wheel-pendulum", 1.0, seed=5)
    c = stabilis.sim.run("wheel-pendulum", 1.0, seed=6)
    _, ya = a["/wheel_pendulum/output"]
    _, xa = a["/wheel_pendulum/state"]
    np.testing.assert_array_equal(ya["phi"], b["/wheel_pendulum/output"][1]["phi"])
    assert not np.array_equal(ya["phi"], c["/wheel_pendulum/output"][1]["phi"])
    noise = ya["phi"] - xa["phi"]
    assert np.std(noise) == pytest.approx(1e-3, rel=0.2)


def test_options_are_passed_through():
    run = stabilis.sim.run("wheel-pendulum", 1.5, no_control=True, tilt_deg=2.0, noise=(0, 0, 0))
    t, state = run["/wheel_pendulum/state"]
    _, output = run["/wheel_pendulum/output"]
    np.testing.assert_array_equal(state["phi"], output["phi"])
    assert np.degrees(np.max(np.abs(state["phi"]))) > 45.0
    assert run.experiment["controller"] == "none"
    assert run.experiment["initial_tilt_deg"] == "2"


def test_out_writes_the_same_run(tmp_path):
    path = tmp_path / "run.mcap"
    run = stabilis.sim.run("wheel-pendulum", 0.5, out=path)
    assert run.out == str(path)
    t, fields = stabilis.read_mcap(path)["/wheel_pendulum/input"]
    np.testing.assert_array_equal(fields["tau"], run["/wheel_pendulum/input"][1]["tau"])


def test_bad_options_are_named():
    with pytest.raises(stabilis.SimError, match="unrecognized subcommand 'unicycle'"):
        stabilis.sim.run("unicycle", 1.0)
    with pytest.raises(stabilis.SimError, match="invalid duration = -1"):
        stabilis.sim.run("wheel-pendulum", -1.0)
    with pytest.raises(stabilis.SimError, match="unexpected argument '--wheels'"):
        stabilis.sim.run("wheel-pendulum", 1.0, wheels=3)
    with pytest.raises(stabilis.SimError, match="tilt-deg"):
        stabilis.sim.run("wheel-pendulum", 1.0, tilt_deg=120)
    with pytest.raises(stabilis.SimError, match="invalid value 'abc'"):
        stabilis.sim.run("wheel-pendulum", 1.0, tilt_deg="abc")


def test_wrong_lengths_are_value_errors():
    with pytest.raises(ValueError, match="length mismatch for noise standard deviations: expected 3, found 2"):
        stabilis.sim.run("wheel-pendulum", 1.0, noise=(0.1, 0.1))


def test_lqr_gain_matches_scipy_dare():
    """The gain of the run equals the discrete LQR of the ZOH linearisation solved by SciPy."""
    from scipy.linalg import solve_discrete_are
    from scipy.signal import cont2discrete

    theta_0 = 3.34e-3 + 0.204 * 0.085**2
    theta_w, mass_length, c_b, c_w, g = 0.57e-3, 0.419 * 0.075 + 0.204 * 0.085, 1.02e-3, 0.05e-3, 9.81
    a = np.array([
        [0.0, 1.0, 0.0],
        [mass_length * g / theta_0, -c_b / theta_0, c_w / theta_0],
        [-mass_length * g / theta_0, c_b / theta_0, -c_w / theta_w - c_w / theta_0],
    ])
    b = np.array([[0.0], [-1.0 / theta_0], [1.0 / theta_w + 1.0 / theta_0]])
    ad, bd, *_ = cont2discrete((a, b, np.eye(3), np.zeros((3, 1))), 1.0 / RATE)
    q = np.diag([1.0 / np.radians(1.0) ** 2, 1.0 / 0.5**2, 1.0 / 20.0**2])
    r = np.array([[1.0 / 0.05**2]])
    p = solve_discrete_are(ad, bd, q, r)
    k = np.linalg.solve(r + bd.T @ p @ bd, bd.T @ p @ ad).ravel()
    run = stabilis.sim.run("wheel-pendulum", 0.1)
    np.testing.assert_allclose(run.summary["gain"], k, rtol=1e-8)
    assert max(abs(np.linalg.eigvals(ad - bd @ k[None, :]))) < 1.0
