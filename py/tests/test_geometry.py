"""Geometry bindings against scipy.spatial.transform.Rotation and closed forms."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import stabilis
from stabilis.geometry import matrix_set, s2, so3

RNG = np.random.default_rng(20181)


def rotation_vectors(n):
    """Random rotation vectors with angles spread over (0, pi), near 0 and near pi."""
    axes = RNG.normal(size=(n, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    angles = np.concatenate(
        [
            RNG.uniform(0.0, np.pi - 1e-6, n - 2 * (n // 4)),
            10.0 ** RNG.uniform(-12, -2, n // 4),
            np.pi - 10.0 ** RNG.uniform(-6, -2, n // 4),
        ]
    )
    return axes * angles[:, None]


def hat_reference(w):
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def test_exp_and_log_match_scipy_rotvec():
    w = rotation_vectors(400)
    r = so3.exp(w)
    assert r.shape == (400, 3, 3)
    np.testing.assert_allclose(r, Rotation.from_rotvec(w).as_matrix(), rtol=0, atol=1e-12)
    back = so3.log(r)
    np.testing.assert_allclose(back, w, rtol=0, atol=1e-12)
    np.testing.assert_allclose(back, Rotation.from_matrix(r).as_rotvec(), rtol=0, atol=1e-12)


def test_single_item_equals_batch_row():
    w = rotation_vectors(8)
    r = so3.exp(w)
    for i in range(8):
        single = so3.exp(w[i])
        assert single.shape == (3, 3)
        np.testing.assert_array_equal(single, r[i])
    assert so3.log(r[0]).shape == (3,)
    assert so3.exp([0.1, 0.2, 0.3]).shape == (3, 3)  # lists are accepted


def test_euler_zyx_matches_scipy_intrinsic_zyx():
    angles = np.column_stack(
        [
            RNG.uniform(-np.pi, np.pi, 300),
            RNG.uniform(-np.pi / 2 + 1e-3, np.pi / 2 - 1e-3, 300),
            RNG.uniform(-np.pi, np.pi, 300),
        ]
    )  # (roll, pitch, yaw)
    scipy_r = Rotation.from_euler("ZYX", angles[:, ::-1]).as_matrix()
    r = so3.from_euler_zyx(angles)
    np.testing.assert_allclose(r, scipy_r, rtol=0, atol=1e-12)
    ours = so3.euler_zyx(r)
    np.testing.assert_allclose(ours, Rotation.from_matrix(r).as_euler("ZYX")[:, ::-1], rtol=0, atol=1e-11)
    np.testing.assert_allclose(ours, angles, rtol=0, atol=1e-11)


def test_euler_zyx_at_gimbal_lock_reconstructs_rotation():
    for pitch in (np.pi / 2, -np.pi / 2):
        r = so3.from_euler_zyx([0.4, pitch, -1.1])
        roll, p, yaw = so3.euler_zyx(r)
        assert roll == 0.0
        np.testing.assert_allclose(so3.from_euler_zyx([roll, p, yaw]), r, rtol=0, atol=1e-12)


def test_hat_vee_and_jacobians():
    w = rotation_vectors(64)
    v = RNG.normal(size=(64, 3))
    k = so3.hat(w)
    np.testing.assert_allclose(k @ v[:, :, None], np.cross(w, v)[:, :, None], rtol=0, atol=1e-15)
    np.testing.assert_array_equal(so3.vee(k), w)
    np.testing.assert_array_equal(so3.hat(w[0]), hat_reference(w[0]))
    r = so3.exp(w)
    jr, jl = so3.right_jacobian(w), so3.left_jacobian(w)
    np.testing.assert_allclose(jl, r @ jr, rtol=0, atol=1e-13)
    eye = np.broadcast_to(np.eye(3), (64, 3, 3))
    np.testing.assert_allclose(jr @ so3.right_jacobian_inverse(w), eye, rtol=0, atol=1e-10)
    np.testing.assert_allclose(jl @ so3.left_jacobian_inverse(w), eye, rtol=0, atol=1e-10)
    # Right Jacobian against central differences through scipy.
    eps = 1e-6
    for wi in w[:16]:
        base = Rotation.from_rotvec(wi).inv()
        columns = [
            ((base * Rotation.from_rotvec(wi + d)).as_rotvec() - (base * Rotation.from_rotvec(wi - d)).as_rotvec())
            / (2 * eps)
            for d in np.eye(3) * eps
        ]
        np.testing.assert_allclose(np.column_stack(columns), so3.right_jacobian(wi), rtol=0, atol=1e-8)


def test_s2_projection_and_tangent_projector():
    x = RNG.normal(size=(100, 3)) * 20
    p = s2.project(x)
    np.testing.assert_allclose(np.linalg.norm(p, axis=1), s2.G0, rtol=1e-15)
    np.testing.assert_allclose(p, s2.G0 * x / np.linalg.norm(x, axis=1, keepdims=True), rtol=1e-14)
    np.testing.assert_allclose(s2.project(x[0], radius=2.0), 2.0 * x[0] / np.linalg.norm(x[0]), rtol=1e-14)
    t = s2.tangent_projector(x)
    np.testing.assert_allclose(t @ t, t, atol=1e-15)
    np.testing.assert_allclose(t @ x[:, :, None], 0.0, atol=1e-13)


def test_matrix_set_projection():
    w, h = RNG.normal(size=(50, 3)), RNG.normal(size=(50, 3))
    members = np.array([hat_reference(a) @ hat_reference(a) + hat_reference(b) for a, b in zip(w, h)])
    np.testing.assert_allclose(matrix_set.project(members), members, rtol=0, atol=1e-12)
    f = matrix_set.factors(members)
    assert f.shape == (50, 2, 3)
    np.testing.assert_allclose(f[:, 1], h, rtol=0, atol=1e-14)
    np.testing.assert_allclose(np.abs(np.sum(f[:, 0] * w, axis=1)), np.sum(w * w, axis=1), rtol=1e-9)
    # Projection of a general matrix: symmetric part has eigenvalues (-s, -s, 0), idempotent.
    a = RNG.normal(size=(50, 3, 3))
    p = matrix_set.project(a)
    np.testing.assert_allclose(matrix_set.project(p), p, atol=1e-12)
    ev = np.linalg.eigvalsh((p + p.transpose(0, 2, 1)) / 2)
    np.testing.assert_allclose(ev[:, 0], ev[:, 1], atol=1e-12)
    np.testing.assert_allclose(ev[:, 2], 0.0, atol=1e-12)


@pytest.mark.parametrize(
    "function, bad, expected",
    [
        (so3.exp, np.zeros(4), r"w must have shape \(3,\) or \(N, 3\), got \(4,\)"),
        (so3.log, np.zeros((3, 4)), r"r must have shape \(3, 3\) or \(N, 3, 3\), got \(3, 4\)"),
        (matrix_set.project, np.zeros((2, 2, 3, 3)), r"a must have shape \(3, 3\) or \(N, 3, 3\)"),
        (s2.project, np.zeros((5, 2)), r"x must have shape \(3,\) or \(N, 3\), got \(5, 2\)"),
    ],
)
def test_bad_shapes_raise_value_error(function, bad, expected):
    with pytest.raises(ValueError, match=expected):
        function(bad)


def test_nan_raises_value_error():
    with pytest.raises(ValueError, match="w contains NaN"):
        so3.exp([np.nan, 0.0, 0.0])
    with pytest.raises(ValueError, match="a contains NaN"):
        matrix_set.project(np.full((3, 3), np.inf))


def test_degenerate_input_raises_stabilis_error():
    with pytest.raises(stabilis.Error, match="x is the zero vector"):
        s2.project(np.zeros(3))
    with pytest.raises(stabilis.Error, match="r is not a rotation matrix"):
        so3.log(np.diag([1.0, 1.0, -1.0]))
