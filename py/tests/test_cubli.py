"""Cubli bindings against independent numpy formulas and the paper's numbers."""
import numpy as np
import pytest

import stabilis
from stabilis import cubli

RNG = np.random.default_rng(2017)


def skew(a):
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def random_state(p):
    g = RNG.normal(size=3)
    g *= p.gravity / np.linalg.norm(g)
    return g, RNG.normal(scale=0.1, size=3), RNG.normal(scale=0.1, size=3)


def test_reference_parameters_and_validation():
    p = cubli.Params()
    assert p.mg == pytest.approx(1.8639, abs=1e-4)
    assert p.theta0.shape == (3, 3)
    with pytest.raises(stabilis.Error, match="theta0"):
        cubli.Params(theta0=-np.eye(3) * 0.02)
    with pytest.raises(stabilis.Error, match="theta_w"):
        cubli.Params(theta_w=[3e-4, -1e-4, 3e-4])
    with pytest.raises(ValueError, match="m must have 3 elements"):
        cubli.Params(m=[0.1, 0.1])
    with pytest.raises(stabilis.Error, match="p_h"):
        cubli.invariants([0, 0, -9.81], [np.nan, 0, 0], [0, 0, 0])


def test_reduced_model_matches_numpy():
    p = cubli.Params()
    for _ in range(20):
        g, ph, pw = random_state(p)
        torque = RNG.normal(scale=0.1, size=3)
        w = np.linalg.solve(p.theta0, ph - pw)
        dg, dph, dpw = cubli.reduced_derivative(g, ph, pw, torque)
        np.testing.assert_allclose(dg, -np.cross(w, g), atol=1e-12)
        np.testing.assert_allclose(dph, -np.cross(w, ph) + np.cross(p.m, g), atol=1e-12)
        np.testing.assert_allclose(dpw, torque, atol=0)
        # Yaw momentum rate is zero for any torque (1.2).
        assert abs(dph @ g + ph @ dg) < 1e-12


def test_backstepping_matches_the_matrix_form():
    p = cubli.Params()
    a, b, c, d = 15.0, 18.0, 12.0, 1e-5
    ctrl = cubli.Backstepping(alpha=a, beta=b, gamma=c, delta=d)
    for _ in range(20):
        g, ph, pw = random_state(p)
        w = np.linalg.solve(p.theta0, ph - pw)
        gg = np.outer(g, g) / (g @ g)
        pperp = ph - gg @ ph
        k1 = np.eye(3) + (a + b * c + d) * p.theta0
        k2 = p.theta0 @ (a * skew(pperp) + b * skew(p.m) @ skew(g)) + skew(ph)
        k3 = c * (np.eye(3) + a * p.theta0 @ (np.eye(3) - gg))
        expected = k1 @ np.cross(p.m, g) + k2 @ w + k3 @ ph - c * pw
        np.testing.assert_allclose(ctrl.control(g, ph, pw), expected, rtol=1e-12, atol=1e-12)


def test_tilt_poles_and_tuning():
    ctrl = cubli.Backstepping()
    mg = cubli.Params().mg
    a, b, c = 18 * mg + 12, 15 * mg + 18 * mg * 12 + 1e-5 * mg, 12 * 15 * mg
    expected = np.sort(np.roots([1, a, b, c]).real)
    got = np.sort([s.real for s in ctrl.tilt_poles()])
    np.testing.assert_allclose(got, expected, rtol=1e-9)
    np.testing.assert_allclose(got, [-32.70, -12.0, -0.855], atol=0.01)
    np.testing.assert_allclose(cubli.tune([-30, -10, -1], 5.0, 1.0), (60, 36, 5, 100), rtol=1e-12)
    np.testing.assert_allclose(cubli.admissible_gamma([-30, -10, -1]), [(1, 10), (30, 41)], rtol=1e-9)
    np.testing.assert_allclose(cubli.admissible_gamma([-5 + 5j, -5 - 5j, -20]), [(20, 30)], rtol=1e-9)
    with pytest.raises(stabilis.Error, match="gamma_hat"):
        cubli.tune([-30, -10, -1], 20.0, 1.0)
    with pytest.raises(ValueError, match="3 entries"):
        cubli.tune([-30, -10], 5.0, 1.0)


def test_simulated_balance_conserves_yaw_momentum_and_converges():
    run = cubli.simulate("balance", duration=5.0, tilt_deg=3.0, noise=(0, 0, 0))
    n = len(run["t"])
    assert run["input"].shape == (n, 3) and run["output"].shape == (n, 9)
    yaw = np.einsum("ij,ij->i", run["p_h"], run["gravity"])
    assert np.max(np.abs(yaw - yaw[0])) < 1e-9 * max(1.0, np.linalg.norm(run["p_h"][0]))
    assert np.degrees(run["inclination"][-1]) < 0.01
    np.testing.assert_allclose(np.linalg.norm(run["gravity"], axis=1), 1.0, atol=1e-12)


def test_disturbance_reproduces_fig_1_6():
    run = cubli.simulate("disturbance", duration=5.0, noise=(0, 0, 0))
    phi = np.degrees(run["inclination"])
    assert phi.max() < 0.5
    assert np.all(phi[run["t"] >= 1.8] <= 0.025)
    assert np.linalg.norm(run["omega_w"][-1]) < 0.2
    assert run["disturbance"][0, 0] == pytest.approx(0.17)


def test_excited_run_has_known_excitation_and_hidden_bias(tmp_path):
    out = tmp_path / "cubli.mcap"
    run = cubli.simulate(
        "balance", duration=6.0, excitation_rms=0.01, gyro_bias=(0.01, 0, 0), noise=(0, 0, 0), out=str(out)
    )
    assert out.exists()
    exc = run["excitation"]
    np.testing.assert_allclose(exc[:200], exc[200:400], atol=1e-15)
    np.testing.assert_allclose(np.sqrt(np.mean(exc[:200] ** 2, axis=0)), 0.01, rtol=1e-9)
    np.testing.assert_allclose(run["output"][:, 0] - run["omega_h"][:, 0], 0.01, atol=1e-12)
    log = stabilis.read_mcap(str(out))
    assert log.metadata["experiment"]["excited"] == "T1,T2,T3"


def test_learning_from_twenty_percent_too_slow():
    trials = cubli.learn_jump(trials=8, start_scale=0.8)
    assert not trials[0]["success"]
    first = next(i for i, t in enumerate(trials) if t["success"])
    assert first <= 5 and all(t["success"] for t in trials[first:])
    np.testing.assert_allclose(trials[-1]["theta"], [570.5, -606.3, 0.0], atol=1.0)
    np.testing.assert_allclose(cubli.nominal_wheel_speeds(), [514.14, -514.14, 0.0], atol=0.05)


def test_guiding_controller_refuses_ninety_degrees():
    guide = cubli.GuidingController()
    # Rotate the upright cube by 90 degrees about a horizontal axis.
    up = np.array([1.0, 1.0, 1.0]) / np.sqrt(3)
    axis = np.cross(up, [0, 0, 1.0])
    angle = np.arccos(up[2])
    q_up = np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * axis / np.linalg.norm(axis)])
    tilt = np.array([np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0, 0.0])

    def qmul(a, b):
        w1, x1, y1, z1 = a
        w2, x2, y2, z2 = b
        return np.array([
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ])

    with pytest.raises(stabilis.Error, match="singular"):
        guide.control(qmul(tilt, q_up), np.zeros(3), np.zeros(3))
    torque = guide.control(q_up, np.zeros(3), np.zeros(3))
    assert torque.shape == (3,) and np.all(np.isfinite(torque))


def _edge_lock_speed(theta0_scale, m, kappa):
    """Closed form for the face -> edge e1 jump with the Lock brake and efficiency kappa:
    Theta_w kappa theta = (I_e + Theta_w) sqrt(2 |m_perp||g| (1 - cos phi0) / I_e)."""
    p = cubli.Params()
    i_e = p.theta0[0, 0] * theta0_scale
    tw = p.theta_w[0]
    m_perp = np.array([0.0, m[1], m[2]])
    mgl = np.linalg.norm(m_perp) * p.gravity
    cos_phi0 = m_perp[2] / np.linalg.norm(m_perp)
    return (i_e + tw) / (tw * kappa) * np.sqrt(2 * mgl * (1 - cos_phi0) / i_e)


def test_edge_jump_learning_from_twenty_percent_too_slow():
    p = cubli.Params()
    nominal = cubli.nominal_wheel_speeds(jump="edge")
    i_e, tw = p.theta0[0, 0], p.theta_w[0]
    mgl = np.linalg.norm(p.m[1:]) * p.gravity
    closed = np.sqrt(2 * i_e * mgl * (1 - np.cos(np.pi / 4))) / tw
    np.testing.assert_allclose(nominal, [closed, 0.0, 0.0], rtol=1e-9)
    trials = cubli.learn_jump(trials=8, start_scale=0.8, jump="edge")
    assert not trials[0]["success"]
    first = next(i for i, t in enumerate(trials) if t["success"])
    assert first < 5 and all(t["success"] for t in trials[first:])
    # The true plant of the scenario: 5 % heavier housing, shifted centre of mass, kappa = 0.9.
    star = _edge_lock_speed(1.05, 0.97 * p.m + [0.002, -0.002, 0.0], 0.90)
    assert abs(trials[-1]["theta"][0] - star) < 0.5
    assert all(t["theta"][1] == 0.0 and t["theta"][2] == 0.0 for t in trials)


def test_edge_jump_with_random_brake_efficiency():
    trials = cubli.learn_jump(trials=12, jump="edge", brake_spread=0.01, seed=3)
    assert len({t["brake"] for t in trials}) == 12
    assert all(t["success"] for t in trials[6:])
    with pytest.raises(ValueError, match="jump"):
        cubli.learn_jump(jump="face")


def test_simulated_edge_jump_ends_balanced_on_the_edge():
    run = cubli.simulate("jump-up", duration=4.0, seed=2, jump="edge")
    assert run["summary"]["final_inclination_deg"] < 0.5
    assert np.all(run["input"][:, 1:] == 0.0)
    assert np.all(run["omega_h"][:, 1:] == 0.0)
    assert np.max(np.abs(run["inclination"][-100:])) < np.radians(0.5)
