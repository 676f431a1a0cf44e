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
