"""Tests of the midpoint IMU mechanisation (kalman_course.core.imu)."""

from types import SimpleNamespace

import numpy as np
import pytest

from kalman_course.core import so3
from kalman_course.data import load_kitti
from kalman_course.core.imu import NavState, dead_reckon, midpoint_step

G = np.array([0.0, 0.0, -9.81])


def make_imu(t, f, w):
    return SimpleNamespace(t=np.asarray(t, float), specific_force=np.asarray(f, float),
                           angular_rate=np.asarray(w, float))


def test_at_rest_the_state_does_not_move():
    R = so3.exp(np.array([0.1, -0.2, 0.3]))
    f = R.T @ -G                                  # what an accelerometer at rest reads
    state = NavState(np.array([1.0, 2.0, 3.0]), np.zeros(3), R)
    out = midpoint_step(state, f, np.zeros(3), f, np.zeros(3), 0.01, G)
    np.testing.assert_allclose(out.position, state.position, atol=1e-15)
    np.testing.assert_allclose(out.velocity, 0.0, atol=1e-15)
    np.testing.assert_allclose(out.rotation, R, atol=1e-15)


def test_constant_rate_and_constant_acceleration_are_integrated_exactly():
    rng = np.random.default_rng(3)
    n = 301
    t = np.cumsum(np.r_[0.0, rng.uniform(0.005, 0.015, n - 1)])     # irregular steps
    w = np.array([0.02, -0.05, 0.3])
    a_nav = np.array([0.5, -0.2, 0.1])
    R0 = so3.exp(np.array([0.0, 0.1, 1.0]))
    R_true = R0 @ so3.exp(t[:, None] * w)
    f = np.einsum("kji,j->ki", R_true, a_nav - G)                    # f = Rᵀ(a − g)
    imu = make_imu(t, f, np.tile(w, (n, 1)))
    v0 = np.array([3.0, 1.0, 0.0])
    traj = dead_reckon(imu, NavState(np.zeros(3), v0, R0), G)
    np.testing.assert_allclose(traj.rotation, R_true, atol=1e-12)
    np.testing.assert_allclose(traj.velocity, v0 + t[:, None] * a_nav, atol=1e-10)
    np.testing.assert_allclose(traj.position, v0 * t[:, None] + 0.5 * a_nav * t[:, None] ** 2, atol=1e-10)


def test_dead_reckon_equals_repeated_midpoint_steps_with_biases():
    rng = np.random.default_rng(4)
    n = 200
    t = np.cumsum(np.r_[0.0, rng.uniform(0.003, 0.02, n - 1)])
    f = rng.normal([0.3, 0.1, 9.8], 0.5, (n, 3))
    w = rng.normal(0.0, 0.2, (n, 3))
    b_a, b_w = np.array([0.05, -0.02, 0.01]), np.array([1e-3, -2e-3, 5e-4])
    state = NavState(np.array([1.0, 2.0, 0.5]), np.array([5.0, -1.0, 0.2]), so3.exp(np.array([0.2, 0.1, -0.4])))
    traj = dead_reckon(make_imu(t, f, w), state, G, accel_bias=b_a, gyro_bias=b_w)
    s = state
    for k in range(n - 1):
        s = midpoint_step(s, f[k], w[k], f[k + 1], w[k + 1], t[k + 1] - t[k], G, b_a, b_w)
    np.testing.assert_allclose(traj.position[-1], s.position, atol=1e-9)
    np.testing.assert_allclose(traj.velocity[-1], s.velocity, atol=1e-10)
    np.testing.assert_allclose(traj.rotation[-1], s.rotation, atol=1e-12)
    # a bias added to the readings and subtracted again changes nothing
    plain = dead_reckon(make_imu(t, f - b_a, w - b_w), state, G)
    np.testing.assert_allclose(plain.position, traj.position, atol=1e-9)


def test_start_stop_and_state_accessor():
    t = np.arange(11) * 0.01
    imu = make_imu(t, np.tile(-G, (11, 1)), np.zeros((11, 3)))
    s0 = NavState(np.zeros(3), np.array([1.0, 0, 0]), np.eye(3))
    traj = dead_reckon(imu, s0, G, start=2, stop=7)
    assert len(traj) == 5 and traj.t[0] == t[2]
    np.testing.assert_allclose(traj.state(-1).position, [0.04, 0, 0], atol=1e-15)


@pytest.mark.parametrize("kwargs,msg", [
    (dict(dt=0.0), "dt must be a positive"),
    (dict(f0=np.zeros(2)), r"f0 must have shape \(3,\)"),
    (dict(gravity=np.zeros((3, 1))), "gravity must be a 1-D vector"),
    (dict(state=NavState(np.zeros(3), np.zeros(3), 2 * np.eye(3))), "state.rotation must be a rotation"),
])
def test_midpoint_step_rejects_bad_input(kwargs, msg):
    args = dict(state=NavState(np.zeros(3), np.zeros(3), np.eye(3)), f0=np.zeros(3), w0=np.zeros(3),
                f1=np.zeros(3), w1=np.zeros(3), dt=0.01, gravity=G)
    args.update(kwargs)
    with pytest.raises(ValueError, match=msg):
        midpoint_step(**args)


def test_dead_reckon_rejects_bad_input():
    s0 = NavState(np.zeros(3), np.zeros(3), np.eye(3))
    with pytest.raises(ValueError, match="imu.t must be strictly increasing"):
        dead_reckon(make_imu([0.0, 0.01, 0.01], np.zeros((3, 3)), np.zeros((3, 3))), s0, G)
    with pytest.raises(ValueError, match=r"imu.angular_rate must have shape \(3, 3\)"):
        dead_reckon(make_imu([0.0, 0.01, 0.02], np.zeros((3, 3)), np.zeros((2, 3))), s0, G)
    with pytest.raises(ValueError, match="missing 'angular_rate'"):
        dead_reckon(SimpleNamespace(t=[0.0], specific_force=np.zeros((1, 3))), s0, G)
    with pytest.raises(ValueError, match="select no samples"):
        dead_reckon(make_imu([0.0, 0.01], np.zeros((2, 3)), np.zeros((2, 3))), s0, G, start=5)


@pytest.mark.parametrize("name", ["cruise", "turns", "stop_go"])
def test_kitti_dead_reckoning_drift_is_in_the_expected_range(name):
    """Pure IMU from the true initial state drifts by metres, not tens of metres, in 30 s."""
    ex = load_kitti(name)
    k0, state = ex.initial_state()
    traj = dead_reckon(ex.imu, state, ex.gravity, start=k0)
    errors = []
    for horizon in (10.0, 30.0):
        k = int(np.searchsorted(traj.t, traj.t[0] + horizon))
        truth = ex.truth.interpolate(traj.t[k:k + 1]).position[0]
        errors.append(np.linalg.norm(traj.position[k] - truth))
    assert 0.1 < errors[0] < 3.0
    assert 2.0 < errors[1] < 10.0
