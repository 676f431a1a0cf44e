"""EKF and iterated EKF: agreement with the linear KF, validation of every public function
(one table of bad inputs), the IEKF's stopping rule and the wrapped radar residual.

The chapters' experiments built on these steps are tested in test_lidar_radar.py
(chapter 05) and test_beacons.py (chapter 06)."""

import numpy as np
import pytest

from kalman_course.filters import ekf, kf
from kalman_course import symbolic


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



# ---------------------------------------------------------------------------------------
# bad inputs: each raises ValueError naming the argument (or the call whose result is bad)
# ---------------------------------------------------------------------------------------

X3, P3, Q3 = np.zeros(3), np.eye(3), np.eye(3)
Y2, R2, G23 = np.zeros(2), np.eye(2), np.eye(2, 3)
NOT_SYMMETRIC = np.array([[1.0, 0.5, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])


def _first2(s):
    return s[:2]


def _predict(**changes):
    args = dict(x_hat=X3, P_hat=P3, f=lambda s: s, F=np.eye(3), Q=Q3)
    args.update(changes)
    return lambda: ekf.ekf_predict(**args)


def _update(**changes):
    args = dict(x_check=X3, P_check=P3, y=Y2, g=_first2, G=G23, R=R2)
    args.update(changes)
    return lambda: ekf.ekf_update(**args)


def _iterated(**changes):
    args = dict(x_check=X3, P_check=P3, y=Y2, g=_first2, G=lambda s: G23, R=R2)
    args.update(changes)
    return lambda: ekf.iekf_update(**args)


BAD_INPUTS = [
    # ekf_predict
    ("predict: NaN in x_hat", _predict(x_hat=[0.0, np.nan, 0.0]), r"x_hat must be finite"),
    ("predict: x_hat a matrix", _predict(x_hat=np.zeros((3, 1))), r"x_hat must be a 1-D vector"),
    ("predict: P_hat not symmetric", _predict(P_hat=NOT_SYMMETRIC), r"P_hat must be symmetric"),
    ("predict: P_hat of the wrong size", _predict(P_hat=np.eye(2)), r"P_hat must have shape \(3, 3\)"),
    ("predict: negative variance in P_hat", _predict(P_hat=-P3), r"P_hat must have a non-negative diagonal"),
    ("predict: P_hat indefinite", _predict(P_hat=[[1.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 1.0]]),
     r"P_hat must be positive semi-definite"),
    ("predict: f not callable", _predict(f=np.eye(3)), r"f must be a callable"),
    ("predict: f returns the wrong length", _predict(f=_first2), r"f\(x_hat\) must have shape \(3,\)"),
    ("predict: f returns NaN", _predict(f=lambda s: s + np.nan), r"f\(x_hat\) must be finite"),
    ("predict: f returns text", _predict(f=lambda s: "abc"), r"f\(x_hat\) must be a 1-D vector .*real numbers"),
    ("predict: F of the wrong shape", _predict(F=np.eye(2)), r"F must have shape \(3, 3\)"),
    ("predict: F(x) of the wrong shape", _predict(F=lambda s: np.eye(3, 2)), r"F\(x_hat\) must have shape \(3, 3\)"),
    ("predict: NaN in F", _predict(F=np.full((3, 3), np.nan)), r"F must be finite"),
    ("predict: F(x) returns None", _predict(F=lambda s: None), r"F\(x_hat\) must be a 2-D matrix"),
    ("predict: Q not symmetric", _predict(Q=NOT_SYMMETRIC), r"Q must be symmetric"),
    ("predict: Q of the wrong size", _predict(Q=np.eye(2)), r"Q must have shape \(3, 3\)"),
    ("predict: B of the wrong height", _predict(B=np.ones((2, 2)), Q=np.eye(2)), r"B must have shape \(3, n\)"),
    ("predict: B(x) of the wrong height", _predict(B=lambda s: np.ones((2, 2)), Q=np.eye(2)),
     r"B\(x_hat\) must have shape \(3, n\)"),
    ("predict: Q does not match B", _predict(B=np.ones((3, 2)), Q=np.eye(3)), r"Q must have shape \(2, 2\)"),
    # ekf_update
    ("update: NaN measurement", _update(y=[1.0, np.nan]), r"y must be finite"),
    ("update: y a matrix", _update(y=np.zeros((2, 2))), r"y must be a 1-D vector"),
    ("update: NaN in x_check", _update(x_check=[np.inf, 0.0, 0.0]), r"x_check must be finite"),
    ("update: P_check not symmetric", _update(P_check=NOT_SYMMETRIC), r"P_check must be symmetric"),
    ("update: P_check of the wrong size", _update(P_check=np.eye(4)), r"P_check must have shape \(3, 3\)"),
    ("update: P_check indefinite", _update(P_check=[[1.0, 0.0, 0.0], [0.0, 1.0, 3.0], [0.0, 3.0, 1.0]]),
     r"P_check must be positive semi-definite"),
    ("update: R not positive definite", _update(R=np.zeros((2, 2))), r"R must be positive definite"),
    ("update: R of the wrong size", _update(R=np.eye(3)), r"R must have shape \(2, 2\)"),
    ("update: R not symmetric", _update(R=[[1.0, 0.5], [0.0, 1.0]]), r"R must be symmetric"),
    ("update: C of the wrong height", _update(C=np.eye(3), R=np.eye(3)), r"C must have shape \(2, "),
    ("update: g not callable", _update(g=G23), r"g must be a callable"),
    ("update: g returns the wrong length", _update(g=lambda s: s), r"g\(x_check\) must have shape \(2,\)"),
    ("update: g returns NaN", _update(g=lambda s: s[:2] * np.nan), r"g\(x_check\) must be finite"),
    ("update: G of the wrong shape", _update(G=np.eye(3)), r"G must have shape \(2, 3\)"),
    ("update: G(x) of the wrong shape", _update(G=lambda s: np.eye(2)), r"G\(x_check\) must have shape \(2, 3\)"),
    ("update: NaN in G", _update(G=np.full((2, 3), np.nan)), r"G must be finite"),
    ("update: residual not callable", _update(residual="wrap"), r"residual must be a callable"),
    ("update: residual returns the wrong length", _update(residual=lambda y, yp: (y - yp)[:1]),
     r"residual\(y, g\(x_check\)\) must have shape \(2,\)"),
    # iekf_update
    ("iterated: G not callable", _iterated(G=G23), r"G must be a callable"),
    ("iterated: max_iter 0", _iterated(max_iter=0), r"max_iter must be an integer >= 1"),
    ("iterated: max_iter not an integer", _iterated(max_iter=2.5), r"max_iter must be an integer >= 1"),
    ("iterated: max_iter a bool", _iterated(max_iter=True), r"max_iter must be an integer >= 1"),
    ("iterated: negative tol", _iterated(tol=-1e-9), r"tol must be a finite number >= 0"),
    ("iterated: NaN tol", _iterated(tol=np.nan), r"tol must be a finite number >= 0"),
    ("iterated: tol not a number", _iterated(tol="small"), r"tol must be a finite number >= 0"),
    ("iterated: NaN measurement", _iterated(y=[np.nan, 0.0]), r"y must be finite"),
    ("iterated: P_check not symmetric", _iterated(P_check=NOT_SYMMETRIC), r"P_check must be symmetric"),
    ("iterated: g(x) of the wrong length", _iterated(g=lambda s: s), r"g\(x_op\) must have shape \(2,\)"),
    ("iterated: G(x) of the wrong shape", _iterated(G=lambda s: np.eye(3)), r"G\(x_op\) must have shape \(2, 3\)"),
    ("iterated: residual of the wrong length", _iterated(residual=lambda y, yp: np.zeros(3)),
     r"residual\(y, g\(x_op\)\) must have shape \(2,\)"),
    # the observation helpers
    ("radar_residual: y of the wrong length", lambda: ekf.radar_residual([1.0, 0.1], [1.0, 0.2, 0.0]),
     r"y must have shape \(3,\)"),
    ("radar_residual: NaN in y_pred", lambda: ekf.radar_residual([1.0, 0.1, 0.0], [1.0, np.nan, 0.0]),
     r"y_pred must be finite"),
    ("lidar_observation: not a CTRV state", lambda: ekf.lidar_observation(np.zeros(4)), r"x must have shape \(5,\)"),
    ("lidar_jacobian: NaN in the state", lambda: ekf.lidar_jacobian([np.nan, 0, 0, 0, 0]), r"x must be finite"),
]


@pytest.mark.parametrize("call, message", [case[1:] for case in BAD_INPUTS], ids=[case[0] for case in BAD_INPUTS])
def test_bad_input_raises_a_value_error_naming_the_argument(call, message):
    with pytest.raises(ValueError, match=message):
        call()


def test_the_good_inputs_of_the_bad_input_table_pass():
    # the table changes one argument at a time; unchanged, each call must succeed
    for make in (_predict, _update, _iterated):
        make()()


def test_lidar_jacobian_cannot_be_changed_by_a_caller():
    G = ekf.lidar_jacobian(np.zeros(5))
    with pytest.raises(ValueError):
        G[0, 0] = 2.0
    np.testing.assert_array_equal(ekf.LIDAR_G, np.eye(2, 5))


def test_radar_residual_wraps_the_bearing_across_the_cut():
    e = ekf.radar_residual([10.0, -np.pi + 0.01, 1.0], [9.0, np.pi - 0.01, 0.5])
    np.testing.assert_allclose(e, [1.0, 0.02, 0.5], atol=1e-12)
    # exactly half a turn apart: the course's convention (−π, π] gives +π
    assert ekf.radar_residual([1.0, np.pi / 2, 0.0], [1.0, -np.pi / 2, 0.0])[1] == pytest.approx(np.pi)
    assert ekf.radar_residual([1.0, -np.pi / 2, 0.0], [1.0, np.pi / 2, 0.0])[1] == pytest.approx(np.pi)


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
