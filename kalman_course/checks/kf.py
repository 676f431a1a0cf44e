"""Checks for chapter 03: the linear Kalman filter, graded on KITTI GNSS excerpts.

The states the checks use come from KITTI ground truth (positions and velocities of the
car), and the whole-run check filters the excerpts' noisy 1 Hz GNSS positions.
"""

from __future__ import annotations

import functools

import numpy as np

from kalman_course.filters import kf
from kalman_course import symbolic
from kalman_course.checks.harness import CheckFailed, call, check, expect_close, expect_shape, expect_symmetric
from kalman_course.data import load_kitti
from kalman_course.evaluation.metrics import rmse

#: Excerpts the KF checks run on, and the settings of the whole-run check.
EXCERPTS = ("cruise", "turns")
SIGMA_A = 1.0       # m/s², acceleration noise of the CV model
SIGMA_GNSS = 1.0    # m, per axis: the noise of the excerpts' noisy GNSS copy
SIGMA_V0 = 15.0     # m/s, initial velocity uncertainty: the car's speed is unknown at start


def cv_matrices_reference(T, sigma_a, dim=3):
    """(F, Q) of the constant-velocity model, blocked state [p (dim), v (dim)]."""
    return symbolic.cv_transition(T, dim), symbolic.cv_process_noise(T, sigma_a, dim)


def position_observation(dim=3):
    """G that picks the position out of the blocked CV state."""
    return np.hstack([np.eye(dim), np.zeros((dim, dim))])


@functools.lru_cache(maxsize=None)
def _kitti_states(name: str, count: int = 4, seed: int = 0):
    """A few CV states [p, v] from KITTI ground truth with random SPD covariances."""
    truth = load_kitti(name).truth
    rng = np.random.default_rng(seed)
    idx = rng.choice(len(truth.t), size=count, replace=False)
    cases = []
    for i in idx:
        A = rng.normal(size=(6, 6))
        cases.append((np.r_[truth.position[i], truth.velocity[i]], A @ A.T + 0.1 * np.eye(6)))
    return tuple(cases)


@check
def check_cv_process_noise(cv_matrices):
    """The learner's ``cv_matrices(T, sigma_a)`` returns (F, Q) of the 3-D CV model."""
    for T, sigma_a in ((1.0, 1.0), (0.1, 2.0), (0.5, 0.3)):
        result = call(cv_matrices, T, sigma_a)
        if not isinstance(result, tuple) or len(result) != 2:
            raise CheckFailed("cv_matrices must return a tuple (F, Q)")
        F, Q = cv_matrices_reference(T, sigma_a)
        expect_close(result[0], F, f"F for T={T}", hint="F = [[I, T I], [0, I]]")
        expect_close(result[1], Q, f"Q for T={T}, sigma_a={sigma_a}", mistakes=[
            (sigma_a * Q / sigma_a**2, "Q = G Q_v Gᵀ with Q_v = σ_a² I: square the standard deviation"),
            (symbolic.cv_process_noise_continuous(T, sigma_a**2, 3),
             "that is the continuous-white-noise Q; this exercise uses piecewise-constant "
             "acceleration, Q = G σ_a² Gᵀ with G = [T²/2 I; T I]"),
        ], hint="Q = σ_a² G Gᵀ with G = [T²/2 I; T I]")
        expect_symmetric(result[1], "Q")


@check
def check_kf_predict(kf_predict):
    """The learner's ``kf_predict(x_hat, P_hat, F, Q)`` on KITTI states."""
    F, Q = cv_matrices_reference(1.0, SIGMA_A)
    for name in EXCERPTS:
        for x_hat, P_hat in _kitti_states(name):
            result = call(kf_predict, x_hat, P_hat, F, Q)
            if not isinstance(result, tuple) or len(result) != 2:
                raise CheckFailed("kf_predict must return a tuple (x_check, P_check)")
            x_check, P_check = kf.kf_predict(x_hat, P_hat, F, Q)
            expect_close(result[0], x_check, "x_check", mistakes=[
                (F.T @ x_hat, "the prior mean is F x̂, not Fᵀ x̂")], hint="x̌ = F x̂")
            expect_close(result[1], P_check, "P_check", mistakes=[
                (F @ P_hat @ F.T, "process noise is missing: P̌ = F P̂ Fᵀ + Q"),
                (F @ P_hat @ F + Q, "transpose: P̌ = F P̂ Fᵀ + Q"),
                (F.T @ P_hat @ F + Q, "order: P̌ = F P̂ Fᵀ + Q, not Fᵀ P̂ F"),
            ], hint="P̌ = F P̂ Fᵀ + Q")


def _update_cases():
    G = position_observation()
    R = SIGMA_GNSS**2 * np.eye(3)
    for name in EXCERPTS:
        fixes = load_kitti(name).gnss.observations()
        for j, (x_check, P_check) in enumerate(_kitti_states(name)):
            yield x_check, P_check, fixes.position[j * 5], G, R


@check
def check_kf_gain(kf_gain):
    """The learner's ``kf_gain(P_check, G, R)`` returns (K, S)."""
    for x_check, P_check, _, G, R in _update_cases():
        result = call(kf_gain, P_check, G, R)
        if not isinstance(result, tuple) or len(result) != 2:
            raise CheckFailed("kf_gain must return a tuple (K, S)")
        S = kf.innovation_covariance(P_check, G, R)
        K = kf.kf_gain(P_check, G, S)
        expect_close(result[1], S, "S", mistakes=[
            (G @ P_check @ G.T, "S = G P̌ Gᵀ + R: the measurement noise is missing")])
        expect_close(result[0], K, "K", mistakes=[
            (P_check @ G.T @ np.linalg.inv(R), "K = P̌ Gᵀ S⁻¹ with S = G P̌ Gᵀ + R, not R⁻¹"),
            (P_check @ G.T @ np.linalg.inv(G @ P_check @ G.T), "S = G P̌ Gᵀ + R: R is missing"),
        ], hint="K = P̌ Gᵀ (G P̌ Gᵀ + R)⁻¹")


@check(uses=("kf_gain",))
def check_kf_update(kf_update):
    """The learner's ``kf_update(x_check, P_check, y, G, R)`` returns (x_hat, P_hat)."""
    for x_check, P_check, y, G, R in _update_cases():
        result = call(kf_update, x_check, P_check, y, G, R)
        if not isinstance(result, tuple) or len(result) != 2:
            raise CheckFailed("kf_update must return a tuple (x_hat, P_hat)")
        ref = kf.kf_update(x_check, P_check, y, G, R, joseph=True)
        I_KG = np.eye(6) - ref.K @ G
        expect_close(result[0], ref.x_hat, "x_hat", mistakes=[
            (x_check - ref.K @ ref.innovation, "sign of the innovation: it is y − G x̌ (measured "
                                               "minus predicted), and the mean moves towards y"),
        ], hint="x̂ = x̌ + K (y − G x̌)")
        expect_close(result[1], ref.P_hat, "P_hat", mistakes=[
            (I_KG @ P_check @ I_KG.T, "the Joseph form needs its second term: + K R Kᵀ"),
            (P_check - ref.K @ G, "P̂ = (I − K G) P̌: multiply by P̌"),
        ], hint="Joseph form: P̂ = (I − K G) P̌ (I − K G)ᵀ + K R Kᵀ")
        expect_symmetric(result[1], "P_hat")


def reference_gnss_kf(t, y, sigma_a=SIGMA_A, sigma_gnss=SIGMA_GNSS, sigma_v0=SIGMA_V0):
    """Reference CV Kalman filter on GNSS positions.

    The prior at step 0 is the first fix with zero velocity (covariance σ_gnss² for position,
    σ_v0² for velocity); every later step predicts over its own time step and updates.

    Returns
    -------
    x_hat : ndarray, shape (N, 6)
    P_hat : ndarray, shape (N, 6, 6)
    """
    G, R = position_observation(), sigma_gnss**2 * np.eye(3)
    x = np.r_[y[0], np.zeros(3)]
    P = np.diag(np.r_[np.full(3, sigma_gnss**2), np.full(3, sigma_v0**2)])
    xs, Ps = [x], [P]
    for k in range(1, len(t)):
        F, Q = cv_matrices_reference(t[k] - t[k - 1], sigma_a)
        x, P = kf.kf_predict(x, P, F, Q)
        x, P = kf.kf_update(x, P, y[k], G, R, joseph=True)[:2]
        xs.append(x)
        Ps.append(P)
    return np.array(xs), np.array(Ps)


def truth_at(name: str, t):
    """Ground-truth positions of excerpt ``name`` interpolated at times ``t``, shape (N, 3)."""
    truth = load_kitti(name).truth
    return np.column_stack([np.interp(t, truth.t, truth.position[:, i]) for i in range(3)])


@check
def check_gnss_kf_run(run_gnss_kf):
    """The learner's ``run_gnss_kf(t, y, sigma_a, sigma_gnss)`` on the KITTI excerpts' noisy GNSS."""
    for name in EXCERPTS:
        fixes = load_kitti(name).gnss.observations()
        result = call(run_gnss_kf, fixes.t, fixes.position, SIGMA_A, SIGMA_GNSS)
        if not isinstance(result, tuple) or len(result) != 2:
            raise CheckFailed("run_gnss_kf must return a tuple (x_hat (N, 6), P_hat (N, 6, 6))")
        x_ref, P_ref = reference_gnss_kf(fixes.t, fixes.position)
        x_hat = expect_shape(result[0], x_ref.shape, "x_hat")
        truth = truth_at(name, fixes.t)
        # 3-D position RMSE = norm of the per-axis RMSEs (NaN in a learner's x_hat stays NaN)
        err = np.linalg.norm(rmse(x_hat[:, :3], truth, axis=0))
        err_ref = np.linalg.norm(rmse(x_ref[:, :3], truth, axis=0))
        expect_close(x_hat, x_ref, f"x_hat on the '{name}' excerpt", rtol=1e-6, atol=1e-6,
                     hint=f"your position RMSE against ground truth is {err:.3f} m, the reference "
                          f"reaches {err_ref:.3f} m. Check the initial covariance (the start "
                          "velocity is unknown) and the time step of each prediction")
        expect_close(result[1], P_ref, f"P_hat on the '{name}' excerpt", rtol=1e-6, atol=1e-9)

