"""Tests of kalman_course.core.so3 against identities, SymPy and finite differences."""

import numpy as np
import pytest
import sympy as sp

from kalman_course.core import so3


def random_rotvecs(rng, n, max_angle=np.pi):
    axis = rng.standard_normal((n, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    return axis * rng.uniform(0.0, max_angle, n)[:, None]


@pytest.fixture
def rng():
    return np.random.default_rng(7)


def test_hat_vee_roundtrip_and_cross_product(rng):
    a, b = rng.standard_normal((2, 5, 3))
    A = so3.hat(a)
    assert A.shape == (5, 3, 3)
    np.testing.assert_allclose(A, -np.swapaxes(A, 1, 2))
    np.testing.assert_allclose(A @ b[..., None], np.cross(a, b)[..., None])
    np.testing.assert_allclose(so3.vee(A), a)
    assert so3.hat(a[0]).shape == (3, 3)


def test_exp_matches_sympy_rodrigues():
    x, y, z = sp.symbols("x y z", real=True)
    K = sp.Matrix([[0, -z, y], [z, 0, -x], [-y, x, 0]])
    # the matrix exponential of [φ]× computed by SymPy, evaluated at a test point
    point = {x: sp.Rational(3, 10), y: sp.Rational(-1, 2), z: sp.Rational(4, 5)}
    expected = np.array(sp.N((K.subs(point)).exp(), 30), dtype=float)
    got = so3.exp(np.array([0.3, -0.5, 0.8]))
    np.testing.assert_allclose(got, expected, atol=1e-14)


def test_exp_is_rotation_and_matches_quaternion(rng):
    phi = random_rotvecs(rng, 200)
    R = so3.exp(phi)
    assert so3.is_rotation(R, tol=1e-13)
    np.testing.assert_allclose(R, so3.quat_to_matrix(so3.quat_exp(phi)), atol=1e-14)


@pytest.mark.parametrize("angle", [0.0, 1e-12, 1e-8, 1e-5, 1e-4, 1.1e-4, 0.1, 1.0, 3.0])
def test_exp_small_and_regular_angles_match_series(angle, rng):
    axis = rng.standard_normal(3)
    axis /= np.linalg.norm(axis)
    phi = angle * axis
    R = so3.exp(phi)
    # the power series, summed far enough, as an independent reference
    K = so3.hat(phi)
    ref, term = np.eye(3), np.eye(3)
    for k in range(1, 40):
        term = term @ K / k
        ref = ref + term
    np.testing.assert_allclose(R, ref, atol=1e-15)


def test_log_inverts_exp_over_the_whole_range(rng):
    phi = random_rotvecs(rng, 500, max_angle=np.pi - 1e-9)
    np.testing.assert_allclose(so3.log(so3.exp(phi)), phi, atol=1e-9)


@pytest.mark.parametrize("angle", [0.0, 1e-14, 1e-9, 1e-6, 1e-4, 2e-4, 1e-2])
def test_log_is_accurate_near_zero(angle, rng):
    axis = rng.standard_normal(3)
    axis /= np.linalg.norm(axis)
    phi = angle * axis
    np.testing.assert_allclose(so3.log(so3.exp(phi)), phi, rtol=1e-10, atol=1e-17)


@pytest.mark.parametrize("gap", [0.0, 1e-12, 1e-8, 1e-5, 1e-3, 5e-3, 2e-2])
def test_log_is_accurate_near_pi(gap, rng):
    for _ in range(20):
        axis = rng.standard_normal(3)
        axis /= np.linalg.norm(axis)
        phi = (np.pi - gap) * axis
        got = so3.log(so3.exp(phi))
        assert abs(np.linalg.norm(got) - (np.pi - gap)) < 1e-10
        if gap == 0.0:   # at exactly π, ±axis are both valid
            assert min(np.abs(got - phi).max(), np.abs(got + phi).max()) < 1e-7
        else:
            np.testing.assert_allclose(got, phi, atol=1e-7)
        np.testing.assert_allclose(so3.exp(got), so3.exp(phi), atol=1e-12)


def test_log_of_diagonal_half_turns():
    for d in ([1, -1, -1], [-1, 1, -1], [-1, -1, 1]):
        phi = so3.log(np.diag(d).astype(float))
        assert np.isclose(np.linalg.norm(phi), np.pi)
        np.testing.assert_allclose(so3.exp(phi), np.diag(d), atol=1e-15)


def test_quaternion_matrix_roundtrip_and_product(rng):
    phi = random_rotvecs(rng, 300)
    R = so3.exp(phi)
    q = so3.matrix_to_quat(R)
    assert np.all(q[:, 0] >= 0)
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-15)
    np.testing.assert_allclose(so3.quat_to_matrix(q), R, atol=1e-14)
    # Hamilton product composes rotations in the same order as matrices
    p = so3.matrix_to_quat(so3.exp(random_rotvecs(rng, 300)))
    np.testing.assert_allclose(so3.quat_to_matrix(so3.quat_multiply(p, q)),
                               so3.quat_to_matrix(p) @ R, atol=1e-14)
    # conjugate is the inverse
    ident = so3.quat_multiply(q, so3.quat_conjugate(q))
    np.testing.assert_allclose(ident, np.tile([1.0, 0, 0, 0], (300, 1)), atol=1e-15)


def test_quaternion_conventions_are_scalar_first_hamilton():
    # 90° about z: q = (cos 45°, 0, 0, sin 45°), maps x to y
    q = np.array([np.sqrt(0.5), 0.0, 0.0, np.sqrt(0.5)])
    np.testing.assert_allclose(so3.quat_to_matrix(q) @ [1.0, 0, 0], [0, 1.0, 0], atol=1e-15)
    # i ⊗ j = k (Hamilton)
    i, j = np.array([0.0, 1, 0, 0]), np.array([0.0, 0, 1, 0])
    np.testing.assert_allclose(so3.quat_multiply(i, j), [0, 0, 0, 1.0])


def test_matrix_to_quat_is_stable_for_every_largest_component():
    for phi in ([0.0, 0, 0], [np.pi, 0, 0], [0, np.pi, 0], [0, 0, np.pi], [3.1, 0.1, 0], [0.1, 0.2, 3.1]):
        R = so3.exp(np.array(phi))
        np.testing.assert_allclose(so3.quat_to_matrix(so3.matrix_to_quat(R)), R, atol=1e-15)


def test_quat_normalise_and_matrix_accept_scaled_quaternions():
    q = np.array([2.0, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(so3.quat_normalise(q), [1.0, 0, 0, 0])
    np.testing.assert_allclose(so3.quat_to_matrix(q), np.eye(3))
    with pytest.raises(ValueError, match="q must be non-zero"):
        so3.quat_normalise(np.zeros(4))


def test_right_jacobian_against_finite_differences_and_inverse(rng):
    for phi in list(random_rotvecs(rng, 10, max_angle=3.0)) + [np.zeros(3), np.array([1e-6, 0, 0])]:
        Jr = so3.right_jacobian(phi)
        eps = 1e-6
        num = np.empty((3, 3))
        for i in range(3):
            d = np.zeros(3)
            d[i] = eps
            plus = so3.log(so3.exp(phi).T @ so3.exp(phi + d))
            minus = so3.log(so3.exp(phi).T @ so3.exp(phi - d))
            num[:, i] = (plus - minus) / (2 * eps)
        np.testing.assert_allclose(Jr, num, atol=1e-8)
        np.testing.assert_allclose(so3.right_jacobian_inv(phi) @ Jr, np.eye(3), atol=1e-12)
        np.testing.assert_allclose(so3.left_jacobian(phi), so3.exp(phi) @ Jr, atol=1e-12)
        np.testing.assert_allclose(so3.left_jacobian_inv(phi) @ so3.left_jacobian(phi), np.eye(3), atol=1e-12)


def test_right_jacobian_inv_small_angle_series_matches_closed_form():
    phi_small = np.array([3e-5, -2e-5, 5e-5])
    phi_edge = phi_small / np.linalg.norm(phi_small) * 1.01e-4   # just on the closed-form side
    a, b = so3.right_jacobian_inv(phi_small), so3.right_jacobian_inv(phi_edge)
    assert np.abs(a - np.eye(3) - 0.5 * so3.hat(phi_small)).max() < 1e-9
    assert np.all(np.isfinite(b))
    with pytest.raises(ValueError, match="phi must have norm < π"):
        so3.right_jacobian_inv(np.array([4.0, 0, 0]))


def test_orthonormalise_projects_to_a_proper_rotation(rng):
    R = so3.exp(random_rotvecs(rng, 50))
    noisy = R + 1e-4 * rng.standard_normal(R.shape)
    fixed = so3.orthonormalise(noisy)
    assert so3.is_rotation(fixed, tol=1e-13)
    assert np.abs(fixed - R).max() < 1e-3
    np.testing.assert_allclose(so3.orthonormalise(R), R, atol=1e-14)


def test_interpolate_and_angle(rng):
    R0, R1 = so3.exp(random_rotvecs(rng, 2, max_angle=2.0))
    np.testing.assert_allclose(so3.interpolate(R0, R1, 0.0), R0, atol=1e-14)
    np.testing.assert_allclose(so3.interpolate(R0, R1, 1.0), R1, atol=1e-13)
    mid = so3.interpolate(R0, R1, 0.5)
    assert np.isclose(so3.angle(R0.T @ mid), so3.angle(mid.T @ R1))
    stack = so3.interpolate(np.stack([R0, R0]), np.stack([R1, R1]), np.array([0.25, 0.75]))
    assert stack.shape == (2, 3, 3)


@pytest.mark.parametrize("func,bad,msg", [
    (so3.hat, np.zeros(4), r"phi must have shape \(3\)"),
    (so3.exp, np.zeros((2, 2)), r"phi must have shape \(3\)"),
    (so3.log, np.eye(4), r"R must have shape \(3, 3\)"),
    (so3.quat_to_matrix, np.zeros(3), r"q must have shape \(4\)"),
    (so3.exp, np.array([np.nan, 0, 0]), "phi must be finite"),
])
def test_bad_input_names_the_argument(func, bad, msg):
    with pytest.raises(ValueError, match=msg):
        func(bad)


def test_log_handles_a_mixed_batch_of_angles(rng):
    angles = np.array([0.0, 1e-10, 1e-5, 0.5, 2.0, np.pi - 5e-3, np.pi - 1e-7, 3.0])
    axis = rng.standard_normal((len(angles), 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    phi = angles[:, None] * axis
    got = so3.log(so3.exp(phi))
    assert got.shape == (len(angles), 3)
    np.testing.assert_allclose(got, phi, atol=1e-9)
    for k in range(len(angles)):   # the batch gives what single calls give
        np.testing.assert_allclose(so3.log(so3.exp(phi[k])), got[k], atol=1e-15)


@pytest.mark.parametrize("func", [so3.exp, so3.right_jacobian, so3.left_jacobian, so3.right_jacobian_inv,
                                  so3.quat_exp, so3.hat])
def test_one_element_and_a_stack_give_the_same_result(func, rng):
    """Each map has a path for one element (floats) and one for a stack (numpy): they agree,
    on both sides of the small-angle switch."""
    angles = np.array([0.0, 1e-9, 0.5 * so3.SMALL_ANGLE, 2.0 * so3.SMALL_ANGLE, 0.3, 2.5])
    axis = rng.standard_normal((len(angles), 3))
    phi = angles[:, None] * axis / np.linalg.norm(axis, axis=1, keepdims=True)
    stacked = func(phi)
    for k in range(len(phi)):
        np.testing.assert_allclose(func(phi[k]), stacked[k], rtol=0, atol=1e-15)


def test_quaternion_maps_agree_one_by_one_and_stacked(rng):
    q = so3.matrix_to_quat(so3.exp(random_rotvecs(rng, 5)))
    p = so3.matrix_to_quat(so3.exp(random_rotvecs(rng, 5)))
    R, pq = so3.quat_to_matrix(2.0 * q), so3.quat_multiply(p, q)
    for k in range(5):
        np.testing.assert_allclose(so3.quat_to_matrix(2.0 * q[k]), R[k], atol=1e-15)
        np.testing.assert_allclose(so3.quat_multiply(p[k], q[k]), pq[k], atol=1e-15)


def test_check_false_gives_the_same_result_without_validating(rng):
    phi = random_rotvecs(rng, 4, max_angle=3.0)
    R = so3.exp(phi)
    np.testing.assert_array_equal(so3.exp(phi, check=False), R)
    np.testing.assert_array_equal(so3.log(R[0], check=False), so3.log(R[0]))
    np.testing.assert_array_equal(so3.hat(phi, check=False), so3.hat(phi))
    np.testing.assert_array_equal(so3.left_jacobian(phi[1], check=False), so3.left_jacobian(phi[1]))
