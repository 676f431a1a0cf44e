"""EKF and iterated EKF: agreement with the linear KF, validation, the IEKF's stopping rule,
angle wrapping, and the chapters' acceptance numbers."""

import numpy as np
import pytest

from kalman_course.filters import ekf, kf
from kalman_course import symbolic
from kalman_course.data import ctrv_lidar_radar


def _spd(rng, n):
    A = rng.normal(size=(n, n))
    return A @ A.T + n * np.eye(n)


def test_with_linear_models_the_ekf_is_the_kf():
    rng = np.random.default_rng(0)
    n, m = 4, 2
    x, P = rng.normal(size=n), _spd(rng, n)
    F, Q = rng.normal(size=(n, n)), _spd(rng, n)
    G, R, y = rng.normal(size=(m, n)), _spd(rng, m), rng.normal(size=m)
    xe, Pe = ekf.ekf_predict(x, P, lambda s: F @ s, F, Q)
    xk, Pk = kf.kf_predict(x, P, F, Q)
    np.testing.assert_allclose(xe, xk)
    np.testing.assert_allclose(Pe, Pk)
    for joseph in (False, True):
        ue = ekf.ekf_update(xk, Pk, y, lambda s: G @ s, G, R, joseph=joseph)
        uk = kf.kf_update(xk, Pk, y, G, R, joseph=joseph)
        for a, b in zip(ue, uk):
            np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-12)
        # a linear observation: the IEKF converges at its second linearisation to the same answer
        ui = ekf.iekf_update(xk, Pk, y, lambda s: G @ s, lambda s: G, R, joseph=joseph)
        np.testing.assert_allclose(ui.x_hat, uk.x_hat, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(ui.P_hat, uk.P_hat, rtol=1e-10, atol=1e-12)
        assert ui.iterations == 2 and ui.converged


def test_predict_accepts_callable_jacobians_and_noise_jacobian():
    x = np.array([5.0, 2.0, 5.0, 0.5, 0.1])
    P = np.diag([0.1, 0.1, 1.0, 0.2, 0.05])
    T, Qw = 0.1, np.diag([9.0, 0.09])
    x1, P1 = ekf.ekf_predict(x, P, lambda s: symbolic.ctrv_step(s, T), lambda s: symbolic.ctrv_jacobian(s, T),
                             Qw, lambda s: symbolic.ctrv_noise_jacobian(s, T))
    F, B = symbolic.ctrv_jacobian(x, T), symbolic.ctrv_noise_jacobian(x, T)
    np.testing.assert_allclose(x1, symbolic.ctrv_step(x, T))
    np.testing.assert_allclose(P1, F @ P @ F.T + B @ Qw @ B.T)
    assert np.array_equal(P1, P1.T)


def test_validation_names_the_argument():
    x, P = np.zeros(3), np.eye(3)
    with pytest.raises(ValueError, match="f must be a callable"):
        ekf.ekf_predict(x, P, np.eye(3), np.eye(3), np.eye(3))
    with pytest.raises(ValueError, match="F must have shape"):
        ekf.ekf_predict(x, P, lambda s: s, np.eye(2), np.eye(3))
    with pytest.raises(ValueError, match="P_hat must be symmetric"):
        ekf.ekf_predict(x, np.triu(np.ones((3, 3))), lambda s: s, np.eye(3), np.eye(3))
    with pytest.raises(ValueError, match="f\\(x_hat\\) must have shape"):
        ekf.ekf_predict(x, P, lambda s: s[:2], np.eye(3), np.eye(3))
    with pytest.raises(ValueError, match="G must have shape"):
        ekf.ekf_update(x, P, np.zeros(2), lambda s: s[:2], np.eye(3), np.eye(2))
    with pytest.raises(ValueError, match="R must be positive definite"):
        ekf.ekf_update(x, P, np.zeros(2), lambda s: s[:2], np.eye(2, 3), np.zeros((2, 2)))
    with pytest.raises(ValueError, match="max_iter"):
        ekf.iekf_update(x, P, np.zeros(2), lambda s: s[:2], lambda s: np.eye(2, 3), np.eye(2), max_iter=0)
    with pytest.raises(ValueError, match="callables"):
        ekf.iekf_update(x, P, np.zeros(2), lambda s: s[:2], np.eye(2, 3), np.eye(2))


def test_wrap_angle_and_the_radar_residual():
    np.testing.assert_allclose(ekf.wrap_angle([np.pi, -np.pi, 3 * np.pi, 0.1, -0.1]),
                               [np.pi, np.pi, np.pi, 0.1, -0.1], atol=1e-12)
    assert ekf.wrap_angle(2 * np.pi + 0.2) == pytest.approx(0.2)
    e = ekf.radar_residual([10.0, -np.pi + 0.01, 1.0], [9.0, np.pi - 0.01, 0.5])
    np.testing.assert_allclose(e, [1.0, 0.02, 0.5], atol=1e-12)


def test_radar_update_across_the_branch_cut_is_small_with_the_wrapped_residual():
    # target just above the negative x axis, measured just below it
    x = np.array([-20.0, 0.05, 3.0, 0.2, 0.0])
    P = np.diag([0.5, 0.5, 1.0, 0.1, 0.01])
    R = np.diag([0.09, 0.0009, 0.09])
    y = symbolic.radar_observation(np.array([-20.0, -0.05, 3.0, 0.2, 0.0]))
    wrapped = ekf.ekf_update(x, P, y, symbolic.radar_observation, symbolic.radar_jacobian, R,
                             residual=ekf.radar_residual)
    raw = ekf.ekf_update(x, P, y, symbolic.radar_observation, symbolic.radar_jacobian, R)
    assert abs(wrapped.innovation[1]) < 0.01
    assert np.linalg.norm(wrapped.x_hat[:2] - x[:2]) < 0.2
    assert np.linalg.norm(raw.x_hat[:2] - x[:2]) > 5.0


def test_iekf_one_iteration_is_the_ekf_and_it_reports_iterations():
    x = np.array([3.0, 1.0, 2.0, 0.3, 0.0])
    P = np.diag([4.0, 4.0, 1.0, 0.5, 0.1])
    R = np.diag([0.01, 1e-4, 0.01])
    y = symbolic.radar_observation(np.array([4.0, 2.5, 2.0, 0.3, 0.0]))
    args = (x, P, y, symbolic.radar_observation, symbolic.radar_jacobian, R)
    e = ekf.ekf_update(*args, residual=ekf.radar_residual)
    one = ekf.iekf_update(*args, residual=ekf.radar_residual, max_iter=1)
    np.testing.assert_allclose(one.x_hat, e.x_hat)
    np.testing.assert_allclose(one.P_hat, e.P_hat)
    assert one.iterations == 1 and not one.converged
    full = ekf.iekf_update(*args, residual=ekf.radar_residual, tol=1e-10)
    assert full.converged and 2 < full.iterations < 20
    # at convergence the iterate is a stationary point of the MAP cost (Gauss–Newton)
    G = symbolic.radar_jacobian(full.x_hat)
    r = ekf.radar_residual(y, symbolic.radar_observation(full.x_hat))
    grad = np.linalg.solve(P, full.x_hat - x) - G.T @ np.linalg.solve(R, r)
    assert np.max(np.abs(grad)) < 1e-6
    # and it fits the precise measurement better than the single EKF step
    r_ekf = ekf.radar_residual(y, symbolic.radar_observation(e.x_hat))
    assert np.linalg.norm(r[:2]) < np.linalg.norm(r_ekf[:2])


def test_lidar_radar_fusion_meets_the_article_targets():
    res = ekf.fuse_lidar_radar(ctrv_lidar_radar(0))
    assert res.rmse["px"] <= 0.11 and res.rmse["py"] <= 0.11
    assert res.rmse["vx"] <= 0.52 and res.rmse["vy"] <= 0.52
    # each sensor alone is worse than both together
    for kwargs in ({"use_radar": False}, {"use_lidar": False}):
        alone = ekf.fuse_lidar_radar(ctrv_lidar_radar(0), **kwargs)
        assert alone.rmse["px"] + alone.rmse["py"] > res.rmse["px"] + res.rmse["py"]


def test_iekf_beats_the_ekf_on_precise_beacons_and_ties_on_far_ones():
    sc = ekf.kitti_beacons("turns", 1)
    e, i = ekf.run_beacon_filter(sc), ekf.run_beacon_filter(sc, iterated=True)
    assert i.position_rmse < 0.5 * e.position_rmse
    assert 2.0 < i.mean_nees < 6.0 < e.mean_nees
    far = ekf.kitti_beacons("turns", 1, offset=100.0, sigma_range=0.5)
    e, i = ekf.run_beacon_filter(far), ekf.run_beacon_filter(far, iterated=True)
    assert abs(i.position_rmse - e.position_rmse) < 0.02 * e.position_rmse


def test_kitti_ctrv_beats_raw_gnss():
    from kalman_course.data import load_kitti

    for name in ("cruise", "turns", "stop_go"):
        res = ekf.run_kitti_ctrv(load_kitti(name))
        assert res.ekf_rmse < 0.9 * res.gnss_rmse, name
