"""Tests of Umeyama alignment and ATE (kalman_course.evaluation.trajectory)."""

import numpy as np
import pytest

from kalman_course.core import so3
from kalman_course.evaluation.trajectory import apply_alignment, ate_rmse, umeyama


@pytest.fixture
def points():
    return np.random.default_rng(11).normal(0.0, 10.0, (100, 3))


@pytest.mark.parametrize("with_scale,scale", [(False, 1.0), (True, 0.7), (True, 1.3)])
def test_umeyama_recovers_a_known_transform(points, with_scale, scale):
    R = so3.exp(np.array([0.3, -1.2, 2.0]))
    t = np.array([5.0, -3.0, 1.0])
    dst = scale * points @ R.T + t
    R_est, t_est, s_est = umeyama(points, dst, with_scale=with_scale)
    np.testing.assert_allclose(R_est, R, atol=1e-12)
    np.testing.assert_allclose(t_est, t, atol=1e-10)
    assert np.isclose(s_est, scale)
    np.testing.assert_allclose(apply_alignment(points, R_est, t_est, s_est), dst, atol=1e-10)


def test_umeyama_never_returns_a_reflection(points):
    mirrored = points * np.array([1.0, 1.0, -1.0])
    R, _, _ = umeyama(points, mirrored)
    assert np.isclose(np.linalg.det(R), 1.0)


def test_ate_is_zero_for_a_rigidly_moved_copy_and_sees_noise(points):
    R = so3.exp(np.array([0.0, 0.0, 1.0]))
    moved = points @ R.T + 2.0
    assert ate_rmse(moved, points) < 1e-10
    assert ate_rmse(moved, points, align="none") > 1.0
    noisy = moved + np.random.default_rng(1).normal(0.0, 0.1, points.shape)
    assert 0.12 < ate_rmse(noisy, points) < 0.2          # ≈ 0.1·√3
    assert ate_rmse(2.0 * points, points, align="sim3") < 1e-10


def test_bad_input_is_named(points):
    with pytest.raises(ValueError, match=r"dst must have shape \(100, 3\)"):
        umeyama(points, points[:50])
    with pytest.raises(ValueError, match="at least 3 point pairs"):
        umeyama(points[:2], points[:2])
    with pytest.raises(ValueError, match="src points are all identical"):
        umeyama(np.ones((5, 3)), points[:5])
    with pytest.raises(ValueError, match="align must be 'se3', 'sim3' or 'none'"):
        ate_rmse(points, points, align="se2")


# ---------------------------------------------------------------------------------------
# align_poses: whole pose trajectories
# ---------------------------------------------------------------------------------------

from kalman_course.evaluation.trajectory import align_poses  # noqa: E402


@pytest.fixture
def poses(points):
    rotation = so3.exp(np.random.default_rng(12).normal(0.0, 1.0, (len(points), 3)))
    return points, rotation


def _moved(position, rotation, R, t, s=1.0):
    return s * position @ R.T + t, R @ rotation


@pytest.mark.parametrize("align, scale", [("se3", 1.0), ("sim3", 0.6), ("sim3", 2.5)])
def test_align_poses_recovers_a_known_similarity(poses, align, scale):
    p, R = poses
    A, t = so3.exp(np.array([0.4, -0.9, 2.2])), np.array([3.0, -7.0, 0.5])
    ref_p, ref_R = _moved(p, R, A, t, scale)
    out = align_poses(p, R, ref_p, ref_R, align)
    np.testing.assert_allclose(out.position, ref_p, atol=1e-10)
    np.testing.assert_allclose(out.rotation, ref_R, atol=1e-12)
    np.testing.assert_allclose(out.R, A, atol=1e-12)
    np.testing.assert_allclose(out.t, t, atol=1e-10)
    assert np.isclose(out.s, scale, rtol=1e-12)


def test_align_first_puts_the_first_pose_on_the_reference(poses):
    p, R = poses
    A, t = so3.exp(np.array([1.0, 0.2, -0.3])), np.array([1.0, 2.0, 3.0])
    ref_p, ref_R = _moved(p, R, A, t)
    noisy = p + np.random.default_rng(5).normal(0.0, 0.5, p.shape)
    noisy[0] = p[0]
    out = align_poses(noisy, R, ref_p, ref_R, "first")
    np.testing.assert_allclose(out.rotation[0], ref_R[0], atol=1e-12)
    np.testing.assert_allclose(out.position[0], ref_p[0], atol=1e-10)
    np.testing.assert_allclose(out.R, A, atol=1e-12)
    assert out.s == 1.0


@pytest.mark.parametrize("axis", [2, 1, 0])
def test_align_yaw_turns_about_the_vertical_only(poses, axis):
    p, R = poses
    A = so3.exp(1.3 * np.eye(3)[axis])
    t = np.array([0.5, -2.0, 4.0])
    ref_p, ref_R = _moved(p, R, A, t)
    out = align_poses(p, R, ref_p, ref_R, "yaw", vertical_axis=axis)
    np.testing.assert_allclose(out.R, A, atol=1e-12)
    np.testing.assert_allclose(out.position, ref_p, atol=1e-10)
    np.testing.assert_allclose(out.rotation, ref_R, atol=1e-12)
    # a tilt cannot be absorbed: the yaw alignment leaves it as error, se3 removes it
    tilted_p, tilted_R = _moved(p, R, so3.exp(0.2 * np.eye(3)[(axis + 1) % 3]), t)
    yaw_only = align_poses(p, R, tilted_p, tilted_R, "yaw", vertical_axis=axis)
    assert np.abs(yaw_only.position - tilted_p).max() > 0.1
    assert np.abs(align_poses(p, R, tilted_p, tilted_R).position - tilted_p).max() < 1e-9


def test_align_poses_names_bad_input(poses):
    p, R = poses
    mirrored = R.copy()
    mirrored[7] = -mirrored[7]
    with pytest.raises(ValueError, match=r"^rotation\[7\] is a reflection"):
        align_poses(p, mirrored, p, R)
    with pytest.raises(ValueError, match=r"^ref_rotation\[7\] is a reflection"):
        align_poses(p, R, p, mirrored)
    scaled = R.copy()
    scaled[2] *= 1.1
    with pytest.raises(ValueError, match=r"^ref_rotation\[2\] is not a rotation matrix"):
        align_poses(p, R, p, scaled)
    with pytest.raises(ValueError, match=r"ref_rotation must have shape \(100, 3, 3\)"):
        align_poses(p, R, p, R[:50])
    with pytest.raises(ValueError, match=r"position must have shape \(100, 3\)"):
        align_poses(p[:50], R, p, R)
    with pytest.raises(ValueError, match=r"rotation must have shape \(N, 3, 3\)"):
        align_poses(p, R[0], p, R)
    with pytest.raises(ValueError, match="align must be one of 'se3', 'sim3', 'first', 'yaw'"):
        align_poses(p, R, p, R, "none")
    with pytest.raises(ValueError, match="vertical_axis must be 0, 1 or 2"):
        align_poses(p, R, p, R, "yaw", vertical_axis=True)
    with pytest.raises(ValueError, match="vertical_axis must be 0, 1 or 2"):
        align_poses(p, R, p, R, "yaw", vertical_axis=np.array([1, 2]))
    line = np.zeros((5, 3))
    line[:, 2] = np.arange(5.0)                        # all on the vertical axis
    with pytest.raises(ValueError, match="turn about the vertical axis is undetermined"):
        align_poses(line, R[:5], line, R[:5], "yaw")
