"""The bonus nominal-state EKF: its Jacobians against finite differences, and a run vs the ESKF."""

from __future__ import annotations

import numpy as np
import pytest

from kalman_course.filters import eskf, nominal_ekf
from kalman_course.core import so3
from kalman_course.evaluation.pose import evaluate
from kalman_course.data import load_kitti

G = np.array([0.0, 0.0, -9.8092])


def _xdot(x, f, w):
    q = x[6:10]
    a = f - x[10:13]
    om = w - x[13:16]
    # homogeneous rotation (valid off the unit sphere too), as the SymPy Jacobian assumes
    R = so3.quat_to_matrix(q) * (q @ q)
    return np.concatenate([x[3:6], R @ a + G, 0.5 * so3.quat_multiply(q, np.r_[0.0, om]), np.zeros(6)])


def _random_state(rng):
    q = so3.matrix_to_quat(so3.exp(rng.normal(size=3)))
    return np.concatenate([rng.normal(size=3), rng.normal(size=3) * 5, q, rng.normal(size=3) * 0.05,
                           rng.normal(size=3) * 0.005])


@pytest.mark.parametrize("seed", range(3))
def test_continuous_jacobian_matches_finite_differences(seed):
    rng = np.random.default_rng(seed)
    x = _random_state(rng)
    f, w = rng.normal(size=3) + np.r_[0, 0, 9.8], rng.normal(size=3) * 0.5
    h = 1e-6
    J = np.column_stack([(_xdot(x + h * e, f, w) - _xdot(x - h * e, f, w)) / (2 * h) for e in np.eye(16)])
    A = nominal_ekf.continuous_jacobian(x[6:10], f, w, x[10:13], x[13:16])
    np.testing.assert_allclose(A, J, atol=1e-6)


def test_discrete_step_is_I_plus_A_T_to_first_order():
    rng = np.random.default_rng(5)
    x = _random_state(rng)
    f, w = rng.normal(size=3) + np.r_[0, 0, 9.8], rng.normal(size=3) * 0.5
    errs = []
    for T in (1e-2, 5e-3):
        h = 1e-6
        J = np.column_stack([(nominal_ekf.propagate(x + h * e, f, w, f, w, T, G)
                              - nominal_ekf.propagate(x - h * e, f, w, f, w, T, G)) / (2 * h) for e in np.eye(16)])
        A = nominal_ekf.continuous_jacobian(x[6:10], f, w, x[10:13], x[13:16])
        # the step renormalises q, which removes the radial direction: compare on the tangent plane
        q = x[6:10]
        Pt = np.eye(16)
        Pt[6:10, 6:10] -= np.outer(q, q)
        errs.append(np.abs((J - (np.eye(16) + A * T)) @ Pt).max())
    assert errs[0] < 5e-3
    assert 3.0 < errs[0] / errs[1] < 5.0


def test_quaternion_noise_map():
    q = so3.matrix_to_quat(so3.exp(np.array([0.3, -0.5, 1.0])))
    d = np.array([1e-4, -2e-4, 3e-4])
    np.testing.assert_allclose(so3.quat_multiply(q, so3.quat_exp(d)), q + 0.5 * nominal_ekf.quat_xi(q) @ d, atol=1e-8)


def test_nominal_ekf_agrees_with_the_eskf_on_kitti():
    ex = load_kitti("cruise")
    k0, s0 = ex.initial_state()
    t_end = ex.imu.t[k0] + 15.0
    r = nominal_ekf.run_nominal_ekf(ex.imu, s0, "kitti_lidar", ex.gravity, lidar=ex.lidar, start=k0, t_end=t_end)
    e = eskf.run(ex.imu, s0, "kitti_lidar", ex.gravity, lidar=ex.lidar, start=k0, t_end=t_end)
    np.testing.assert_allclose(r.t, e.t)
    assert np.abs(r.position - e.position).max() < 5e-3
    np.testing.assert_allclose(np.linalg.norm(r.quaternion, axis=1), 1.0, atol=1e-12)
    assert np.array_equal(r.P, np.swapaxes(r.P, 1, 2))
    m = evaluate(r.t, r.position, r.rotation, ex.truth, r.P_pose)
    me = evaluate(e.t, e.position, e.rotation, ex.truth, e.P)
    assert m["ape_position"] == pytest.approx(me["ape_position"], rel=0.02)
    assert m["nees_pose"] == pytest.approx(me["nees_pose"], rel=0.05)
