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


# ---------------------------------------------------------------------------------------
# what is not a rotation is refused (issue 27: safe on anyone's data)
# ---------------------------------------------------------------------------------------

SHEAR = np.array([[1.0, 0.2, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
NOT_ROTATIONS = [
    ("minus identity", -np.eye(3), "R is a reflection"),
    ("mirror", np.diag([1.0, 1.0, -1.0]), "R is a reflection"),
    ("scaled", 1.01 * np.eye(3), r"R is not a rotation matrix \(\|RᵀR − I\| = 0.0201"),
    ("sheared", SHEAR, "R is not a rotation matrix"),
    ("zero", np.zeros((3, 3)), "R is not a rotation matrix"),
]


@pytest.mark.parametrize("func", [so3.log, so3.matrix_to_quat, so3.angle, so3.to_rpy])
@pytest.mark.parametrize("label, M, message", NOT_ROTATIONS, ids=[c[0] for c in NOT_ROTATIONS])
def test_a_matrix_that_is_not_a_rotation_is_refused(func, label, M, message):
    with pytest.raises(ValueError, match=message):
        func(M)


@pytest.mark.parametrize("func", [so3.log, so3.matrix_to_quat, so3.angle, so3.to_rpy])
def test_a_stack_names_its_first_bad_matrix(func, rng):
    R = so3.exp(random_rotvecs(rng, 6))
    R[4] = R[4] @ np.diag([1.0, -1.0, 1.0])
    R[5] = 2.0 * R[5]
    with pytest.raises(ValueError, match=r"^R\[4\] is a reflection, not a rotation \(det = -1"):
        func(R)


def test_log_and_interpolate_name_their_arguments(rng):
    R = so3.exp(random_rotvecs(rng, 3))
    with pytest.raises(ValueError, match=r"^R0\[1\] is a reflection"):
        so3.interpolate(np.stack([R[0], -R[1]]), R[:2], 0.5)
    with pytest.raises(ValueError, match=r"^R1 is not a rotation matrix"):
        so3.interpolate(R[0], SHEAR, 0.5)


def test_what_was_silently_wrong_before():
    # a reflection's log was 0 and -I had the quaternion (0, 1, 0, 0): now both are errors,
    # and check=False still takes the old, unvalidated path
    mirror = np.diag([1.0, 1.0, -1.0])
    np.testing.assert_array_equal(so3.log(mirror, check=False), np.zeros(3))
    np.testing.assert_array_equal(so3.angle(mirror, check=False), 0.0)
    with pytest.raises(ValueError, match="reflection"):
        so3.log(mirror)
    with pytest.raises(ValueError, match="reflection"):
        so3.matrix_to_quat(-np.eye(3))


def test_round_off_within_the_tolerance_passes(rng):
    from kalman_course.core.validation import ROTATION_TOL
    R = so3.exp(random_rotvecs(rng, 20))
    printed = np.vectorize(lambda v: float(f"{v:.6e}"))(R)      # KITTI's 7 digits
    np.testing.assert_allclose(so3.log(printed), so3.log(R), atol=1e-5)
    for k in range(3):                                            # the one-matrix fast path too
        so3.log(printed[k])
    almost = np.eye(3) * (1.0 + 0.4 * ROTATION_TOL)
    so3.log(almost)
    with pytest.raises(ValueError, match="tolerance 1e-06"):
        so3.log(np.eye(3) * (1.0 + 0.6 * ROTATION_TOL))


def test_the_single_matrix_fast_path_applies_the_same_rule(rng):
    # log of one matrix checks with Python floats; the stack with numpy: they must agree
    from kalman_course.core.validation import ROTATION_TOL
    base = so3.exp(random_rotvecs(rng, 1))[0]
    for scale in (0.3, 0.45, 0.55, 0.7):
        bumped = base.copy()
        bumped[1, 2] += scale * ROTATION_TOL * 2.0            # |RᵀR − I| ≈ scale · 2e-6 · |R|
        err = np.abs(bumped.T @ bumped - np.eye(3)).max()
        single_ok = stack_ok = True
        try:
            so3.log(bumped)
        except ValueError:
            single_ok = False
        try:
            so3.log(bumped[None])
        except ValueError:
            stack_ok = False
        assert single_ok == stack_ok == (err <= ROTATION_TOL)


def test_as_rotations_returns_the_stack_and_names_it(rng):
    R = so3.exp(random_rotvecs(rng, 3))
    assert so3.as_rotations(R, "rotation") is R
    np.testing.assert_array_equal(so3.as_rotations(R.tolist(), "rotation"), R)
    with pytest.raises(ValueError, match=r"^rotation\[2\] is not a rotation matrix"):
        so3.as_rotations(np.stack([R[0], R[1], 3.0 * R[2]]), "rotation")
    with pytest.raises(ValueError, match=r"rotation must have shape \(3, 3\)"):
        so3.as_rotations(np.zeros((3, 4)), "rotation")


# ---------------------------------------------------------------------------------------
# roll, pitch, yaw
# ---------------------------------------------------------------------------------------

def test_rpy_is_z_then_y_then_x_as_products_of_axis_rotations():
    roll, pitch, yaw = 0.3, -0.7, 2.1
    expected = so3.exp([0.0, 0.0, yaw]) @ so3.exp([0.0, pitch, 0.0]) @ so3.exp([roll, 0.0, 0.0])
    np.testing.assert_allclose(so3.from_rpy(roll, pitch, yaw), expected, atol=1e-15)
    np.testing.assert_allclose(so3.from_rpy(0.5, 0.0, 0.0), so3.exp([0.5, 0.0, 0.0]), atol=1e-15)
    np.testing.assert_allclose(so3.from_rpy(0.0, 0.5, 0.0), so3.exp([0.0, 0.5, 0.0]), atol=1e-15)
    np.testing.assert_allclose(so3.from_rpy(0.0, 0.0, 0.5), so3.exp([0.0, 0.0, 0.5]), atol=1e-15)
    # a positive yaw turns the body's x axis (forward) towards the navigation frame's y
    assert so3.from_rpy(0.0, 0.0, 0.1)[1, 0] > 0.0


def _rpy_samples(rng):
    n = 400
    roll = rng.uniform(-np.pi, np.pi, n)
    pitch = rng.uniform(-np.pi / 2, np.pi / 2, n)
    yaw = rng.uniform(-np.pi, np.pi, n)
    special = np.array([0.0, 1e-12, -1e-9, np.pi - 1e-9, -np.pi + 1e-9, np.pi, 1.0])
    roll[:7], yaw[7:14] = special, special
    pitch[14:21] = special.clip(-np.pi / 2, np.pi / 2)
    pitch[21:27] = [np.pi / 2 - 1e-6, -np.pi / 2 + 1e-6, np.pi / 2 - 1e-7, -np.pi / 2 + 2e-7, 1e-13, -0.0]
    return roll, pitch, yaw


def test_rpy_round_trip_gives_the_angles_back(rng):
    roll, pitch, yaw = _rpy_samples(rng)
    R = so3.from_rpy(roll, pitch, yaw)
    assert R.shape == (400, 3, 3) and so3.is_rotation(R, tol=1e-14)
    got = so3.to_rpy(R)
    assert got.shape == (400, 3)
    # compare angles modulo 2π (π and −π are the same roll), and the matrices exactly
    # (outside the gimbal-lock band, where roll and yaw are separately defined)
    free = np.cos(pitch) >= so3.GIMBAL_LOCK
    assert free.sum() > 390
    wrapped = np.angle(np.exp(1j * (got - np.stack([roll, pitch, yaw], -1))))
    assert np.abs(wrapped[free]).max() < 1e-8
    np.testing.assert_allclose(so3.from_rpy(*got.T), R, atol=1e-12)
    assert (got[:, [0, 2]] > -np.pi).all() and (got[:, [0, 2]] <= np.pi).all()
    assert (np.abs(got[:, 1]) <= np.pi / 2).all()


def test_rpy_of_a_random_rotation_reproduces_it(rng):
    R = so3.exp(random_rotvecs(rng, 300))
    np.testing.assert_allclose(so3.from_rpy(*so3.to_rpy(R).T), R, atol=1e-12)
    for k in range(3):                                 # one matrix gives what the stack gives
        np.testing.assert_array_equal(so3.to_rpy(R[k]), so3.to_rpy(R)[k])


@pytest.mark.parametrize("pitch", [np.pi / 2, -np.pi / 2, np.pi / 2 - 1e-10, -np.pi / 2 + 3e-9])
def test_gimbal_lock_puts_the_turn_in_yaw(pitch):
    roll, yaw = 0.4, -1.1
    R = so3.from_rpy(roll, pitch, yaw)
    got_roll, got_pitch, got_yaw = so3.to_rpy(R)
    assert got_roll == 0.0
    assert abs(got_pitch - pitch) < 1e-7
    # only yaw − roll (pitch +π/2) or yaw + roll (pitch −π/2) is defined there
    combined = yaw - roll if pitch > 0 else yaw + roll
    assert abs(np.angle(np.exp(1j * (got_yaw - combined)))) < 1e-7
    np.testing.assert_allclose(so3.from_rpy(got_roll, got_pitch, got_yaw), R, atol=1e-8)


def test_rpy_broadcasts():
    assert so3.from_rpy(0.1, 0.2, 0.3).shape == (3, 3)
    assert so3.to_rpy(so3.from_rpy(0.1, 0.2, 0.3)).shape == (3,)
    assert so3.from_rpy(np.zeros(5), 0.2, 0.0).shape == (5, 3, 3)
    assert so3.from_rpy(np.zeros((2, 1)), np.zeros(4), 0.0).shape == (2, 4, 3, 3)
    assert so3.to_rpy(np.broadcast_to(np.eye(3), (2, 4, 3, 3))).shape == (2, 4, 3)


@pytest.mark.parametrize("kwargs, message", [
    (dict(roll=200.0, pitch=0.0, yaw=0.0), r"roll must be in radians, \|roll\| ≤ 2π, got 200 \(degrees\?"),
    (dict(roll=0.0, pitch=[0.0, -90.0], yaw=0.0), r"pitch must be in radians.*got -90"),
    (dict(roll=0.0, pitch=0.0, yaw=np.nan), "yaw must be finite"),
    (dict(roll="a", pitch=0.0, yaw=0.0), "roll must be an angle in radians"),
    (dict(roll=np.zeros(2), pitch=np.zeros(3), yaw=0.0), "roll, pitch and yaw must broadcast"),
])
def test_rpy_bad_input_is_named(kwargs, message):
    with pytest.raises(ValueError, match=message):
        so3.from_rpy(**kwargs)
