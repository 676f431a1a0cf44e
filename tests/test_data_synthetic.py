"""Tests of the seeded synthetic scenarios (kalman_course.data.synthetic).

The chapter 05 lidar + radar scenario moved to kalman_course.chapters.lidar_radar: see
test_lidar_radar.py."""

import numpy as np
import pytest

from kalman_course.core import so3
from kalman_course.data import cv_target, imu_trajectory, random_walk_1d
from kalman_course.data.synthetic import _analytic_motion
from kalman_course.core.imu import dead_reckon


def within_sd(sample_sd, sd, n, k=4.0):
    """True if a sample standard deviation from n draws is within k standard errors of sd."""
    return abs(sample_sd / sd - 1.0) < k / np.sqrt(2 * n)


def test_random_walk_statistics_and_reproducibility():
    rw = random_walk_1d(20000, q=0.5, r=2.0, seed=1, x0=3.0)
    assert len(rw) == 20000 and rw.x0 == 3.0
    w = np.diff(np.r_[rw.x0, rw.x])
    assert within_sd(w.std(), np.sqrt(0.5), len(w))
    assert within_sd((rw.z - rw.x).std(), np.sqrt(2.0), len(w))
    again = random_walk_1d(20000, q=0.5, r=2.0, seed=1, x0=3.0)
    np.testing.assert_array_equal(again.z, rw.z)
    assert not np.array_equal(random_walk_1d(20000, 0.5, 2.0, seed=2).z, rw.z)


def test_random_walk_rejects_bad_arguments():
    with pytest.raises(ValueError, match="n_steps must be a positive integer"):
        random_walk_1d(0, 1.0, 1.0, seed=1)
    with pytest.raises(ValueError, match="q must be a finite non-negative number"):
        random_walk_1d(10, -1.0, 1.0, seed=1)
    with pytest.raises(ValueError, match="seed must be a non-negative integer"):
        random_walk_1d(10, 1.0, 1.0, seed=None)


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_cv_target_follows_its_model(dim):
    sc = cv_target(5000, dt=0.1, sigma_a=0.5, sigma_meas=2.0, seed=3, dim=dim)
    assert sc.x.shape == (5000, 2 * dim) and sc.z.shape == (5000, dim) and sc.F.shape == (2 * dim, 2 * dim)
    prev = np.vstack([sc.x0, sc.x[:-1]])
    w = sc.x - prev @ sc.F.T                                  # = G a_k
    a = np.linalg.lstsq(sc.G, w.T, rcond=None)[0].T
    np.testing.assert_allclose(a @ sc.G.T, w, atol=1e-9)      # the noise lies in the span of G
    assert within_sd(a.std(), 0.5, a.size)
    np.testing.assert_allclose(sc.Q, 0.25 * sc.G @ sc.G.T)
    assert within_sd((sc.z - sc.x @ sc.H.T).std(), 2.0, sc.z.size)
    np.testing.assert_allclose(sc.t[:3], [0.1, 0.2, 0.3])


def test_cv_target_rejects_bad_dim_and_x0():
    with pytest.raises(ValueError, match="dim must be 1, 2 or 3"):
        cv_target(10, 0.1, 1.0, 1.0, seed=0, dim=4)
    with pytest.raises(ValueError, match=r"x0 must have shape \(4,\)"):
        cv_target(10, 0.1, 1.0, 1.0, seed=0, x0=np.zeros(3))


def test_imu_trajectory_truth_is_exact_under_the_midpoint_mechanisation():
    sc = imu_trajectory(seed=2, duration=60.0)
    replay = dead_reckon(sc.imu_clean, sc.state(0), sc.gravity)
    np.testing.assert_allclose(replay.position, sc.position, atol=1e-9)
    np.testing.assert_allclose(replay.rotation, sc.rotation, atol=1e-12)
    np.testing.assert_allclose(so3.quat_to_matrix(sc.quaternion), sc.rotation, atol=1e-12)
    # and it follows the analytic motion to integration accuracy
    _, _, R, omega, f, vel, acc = _analytic_motion(sc.t, sc.gravity)
    assert np.abs(sc.velocity - vel).max() < 1e-3
    assert np.abs(so3.log(np.swapaxes(R, 1, 2) @ sc.rotation)).max() < 1e-4
    np.testing.assert_array_equal(sc.imu_clean.angular_rate, omega)
    # body rate from finite differences of the analytic attitude
    dt = sc.t[1] - sc.t[0]
    num = so3.log(np.swapaxes(R[:-1], 1, 2) @ R[1:]) / dt
    np.testing.assert_allclose(num, 0.5 * (omega[1:] + omega[:-1]), atol=1e-5)
    # at the sample times f = Rᵀ(a − g)
    np.testing.assert_allclose(np.einsum("kij,kj->ki", R, f) + sc.gravity, acc, atol=1e-12)


def test_imu_trajectory_noise_and_biases_have_the_stated_densities():
    sc = imu_trajectory(seed=5, duration=100.0, rate=100.0, accel_bias_density=1e-3, gyro_bias_density=1e-4,
                        accel_bias0=(0.1, -0.1, 0.05), gyro_bias0=(1e-3, 0.0, -1e-3))
    dt = 0.01
    n_a = sc.imu.specific_force - sc.imu_clean.specific_force - sc.accel_bias
    n_w = sc.imu.angular_rate - sc.imu_clean.angular_rate - sc.gyro_bias
    assert within_sd(n_a.std(), 0.01 / np.sqrt(dt), n_a.size)
    assert within_sd(n_w.std(), 1.75e-4 / np.sqrt(dt), n_w.size)
    np.testing.assert_allclose(sc.accel_bias[0], [0.1, -0.1, 0.05])
    db = np.diff(sc.accel_bias, axis=0)
    assert within_sd(db.std(), 1e-3 * np.sqrt(dt), db.size)
    assert within_sd(np.diff(sc.gyro_bias, axis=0).std(), 1e-4 * np.sqrt(dt), db.size)


def test_imu_trajectory_without_noise_reads_clean_and_is_reproducible():
    quiet = imu_trajectory(seed=1, duration=5.0, accel_noise_density=0.0, gyro_noise_density=0.0,
                           accel_bias_density=0.0, gyro_bias_density=0.0)
    np.testing.assert_array_equal(quiet.imu.specific_force, quiet.imu_clean.specific_force)
    a, b = imu_trajectory(seed=9, duration=5.0), imu_trajectory(seed=9, duration=5.0)
    np.testing.assert_array_equal(a.imu.angular_rate, b.imu.angular_rate)
    assert len(a) == 501 and a.t[-1] == 5.0
    with pytest.raises(ValueError, match="rate must be a finite positive number"):
        imu_trajectory(seed=1, rate=0.0)
