"""Checks for chapter 08: the pieces of the error-state Kalman filter, and a run on KITTI.

States come from KITTI ground truth (tilted attitudes, real IMU readings) with made-up
non-zero biases; F is also checked against a finite-difference Jacobian of one nominal
step, and the whole run against :func:`kalman_course.filters.eskf.run` on a 10 s slice of the
turns excerpt.
"""

from __future__ import annotations

import functools

import numpy as np

from kalman_course.filters import eskf
from kalman_course.core import so3
from kalman_course.core.linalg import symmetrise
from kalman_course.evaluation.metrics import position_rmse
from kalman_course.checks.harness import CheckFailed, call, check, expect_close, expect_shape, expect_symmetric
from kalman_course.data import load_kitti
from kalman_course.filters.eskf import NominalState
from kalman_course.filters.eskf_config import load_config

#: The whole-run check: excerpt and length of the slice (s).
RUN_EXCERPT, RUN_SECONDS = "turns", 10.0
DENSITY = np.array([0.03, 1e-3, 1.67e-4, 2.91e-6])


@functools.lru_cache(maxsize=None)
def _cases(count: int = 4, seed: int = 8):
    """(nominal state, f, ω) from KITTI truth and readings, with non-zero biases."""
    ex = load_kitti("turns")
    rng = np.random.default_rng(seed)
    out = []
    for k in rng.choice(np.arange(100, len(ex.imu) - 100), size=count, replace=False):
        nav = ex.truth.state_at(float(ex.imu.t[k]))
        tilt = so3.exp(rng.normal(size=3) * 0.3)           # tilt it more than a road does
        x = NominalState(nav.position, nav.velocity, nav.rotation @ tilt,
                         rng.normal(size=3) * 0.05, rng.normal(size=3) * 0.005)
        out.append((x, ex.imu.specific_force[k].copy(), ex.imu.angular_rate[k].copy()))
    return tuple(out)


def _error(nom, true):
    return np.concatenate([nom.position - true.position, nom.velocity - true.velocity,
                           so3.log(true.rotation.T @ nom.rotation),
                           nom.accel_bias - true.accel_bias, nom.gyro_bias - true.gyro_bias])


def _fd_transition(x, f, w, T, g, h=1e-6):
    x1 = eskf.nominal_step(x, f, w, f, w, T, g)
    J = np.zeros((15, 15))
    for i in range(15):
        d = np.zeros(15)
        d[i] = h
        J[:, i] = (_error(x1, eskf.nominal_step(eskf.inject(x, d), f, w, f, w, T, g))
                   - _error(x1, eskf.nominal_step(eskf.inject(x, -d), f, w, f, w, T, g))) / (2 * h)
    return J


@check
def check_eskf_error_dynamics(error_dynamics):
    """``error_dynamics(R, f, w, b_a, b_w)`` returns F_t (15, 15)."""
    g = np.array([0.0, 0.0, -9.8092])
    for x, f, w in _cases():
        args = (x.rotation, f, w, x.accel_bias, x.gyro_bias)
        got = expect_shape(call(error_dynamics, *args), (15, 15), "F_t")
        ref = eskf.error_dynamics(*args)
        a = f - x.accel_bias
        nav = ref.copy()
        nav[3:6, 6:9] = -so3.hat(x.rotation @ a)
        raw = ref.copy()
        raw[3:6, 6:9] = -x.rotation @ so3.hat(f)
        flip = ref.copy()
        flip[3:6, 6:9] *= -1
        theta = ref.copy()
        theta[6:9, 6:9] *= -1
        # first the finite-difference test: I + F_t T must be the Jacobian of one nominal step
        # (w.r.t. an injected error) up to the second-order terms ½ F_t² T²
        T = 1e-3
        J = _fd_transition(x, f, w, T, g)
        fd_err = np.abs(J - (np.eye(15) + got * T)).max()
        tol = np.abs(ref @ ref).max() * T * T + 1e-7
        expect_close(got, ref, "F_t", atol=1e-10, mistakes=[
            (nav, "navigation-frame specific force: the δv–δθ block is −R[a]× with a = f − b_a in the "
                  "BODY frame, not −[R a]×"),
            (raw, "use the bias-corrected specific force a = f − b_a inside [a]×"),
            (flip, "sign of the δv–δθ block: with Ř = R Exp(δθ), δv̇ = −R[a]× δθ + ..."),
            (theta, "sign of the δθ–δθ block: δθ̇ = −[ω − b_ω]× δθ + ..."),
        ], hint=f"I + F_t T differs from a finite-difference Jacobian of one IMU step by {fd_err:.2e} at "
                f"T = 1 ms (allowed: {tol:.1e}); compare block by block with the lecture")
        if fd_err > tol:
            raise CheckFailed(f"I + F_t T is not the Jacobian of one IMU step (finite-difference mismatch "
                              f"{fd_err:.2e} > {tol:.1e})")


@check
def check_eskf_noise_jacobian(noise_jacobian):
    """``noise_jacobian(R, bias_model)`` returns B_t (15, 12) or (15, 6)."""
    for x, _, _ in _cases():
        for model, cols in (("random_walk", 12), ("constant", 6)):
            got = expect_shape(call(noise_jacobian, x.rotation, model), (15, cols), f"B_t ({model} bias)")
            ref = eskf.noise_jacobian(x.rotation, model)
            wrong = ref.copy()
            wrong[3:6, 0:3] = np.eye(3)
            expect_close(got, ref, f"B_t ({model} bias)", atol=1e-12, mistakes=[
                (wrong, "n_a is accelerometer noise in the BODY frame; it enters δv̇ rotated: R n_a"),
            ], hint="columns n_a, n_ω, n_ba, n_bω; rows δp, δv, δθ, δb_a, δb_ω "
                    "(the constant-bias model has no bias columns)")


@check
def check_eskf_discretisation(discretise):
    """``discretise(F_t, B_t, T)`` returns (F, B); checked through the blocks of B Q Bᵀ."""
    for x, f, w in _cases():
        F_t = eskf.error_dynamics(x.rotation, f, w, x.accel_bias, x.gyro_bias)
        B_t = eskf.noise_jacobian(x.rotation)
        for T in (0.01, 0.004):
            result = call(discretise, F_t, B_t, T)
            if not isinstance(result, tuple) or len(result) != 2:
                raise CheckFailed("discretise must return a tuple (F, B)")
            F_ref, B_ref = eskf.discretise(F_t, B_t, T)
            expect_close(result[0], F_ref, f"F for T = {T}", atol=1e-12, mistakes=[
                (F_t * T, "F = I + F_t T: the identity is missing")])
            B = expect_shape(result[1], B_ref.shape, f"B for T = {T}")
            Qd = B @ eskf.process_noise(DENSITY, T) @ B.T
            blocks = (("δv", 3, DENSITY[0]), ("δθ", 6, DENSITY[1]), ("δb_a", 9, DENSITY[2]), ("δb_ω", 12, DENSITY[3]))
            for name, i, s in blocks:
                got = Qd[i, i]
                exact = s * s * T
                if i >= 9:
                    mistakes = [(s * s * T * T, "T where √T belongs: a random walk's variance grows with T, so "
                                                "its column of B scales with √T"),
                                (s * s, "the random-walk column of B must be scaled by √T")]
                else:
                    mistakes = [(s * s, "√T where T belongs: with per-sample variance σ²/T in Q, a "
                                        "white-noise column of B scales with T"),
                                (s * s / T, "the white-noise column of B must be scaled by T")]
                expect_close(got, exact, f"the {name} block of B Q Bᵀ for T = {T}", rtol=1e-9, atol=0.0,
                             mistakes=mistakes, hint="B Q Bᵀ must add σ² T on every block")
            expect_close(B, B_ref, f"B for T = {T}", atol=1e-14)


@check
def check_eskf_propagate(propagate_covariance):
    """``propagate_covariance(P, F, B, Q)`` returns P̌ (15, 15), symmetric positive definite."""
    rng = np.random.default_rng(2)
    for x, f, w in _cases():
        A = rng.normal(size=(15, 15)) * 0.1
        P = A @ A.T + 1e-4 * np.eye(15)
        F, B = eskf.discretise(eskf.error_dynamics(x.rotation, f, w, x.accel_bias, x.gyro_bias),
                               eskf.noise_jacobian(x.rotation), 0.01)
        Q = eskf.process_noise(DENSITY, 0.01)
        got = expect_shape(call(propagate_covariance, P, F, B, Q), (15, 15), "P_check")
        ref = eskf.propagate_covariance(P, F, B, Q)
        expect_symmetric(got, "P_check")
        if np.linalg.eigvalsh(symmetrise(got)).min() <= 0.0:
            raise CheckFailed("P_check is not positive definite")
        half = F @ P @ F
        expect_close(got, ref, "P_check", rtol=1e-9, atol=1e-15, mistakes=[
            (F @ P @ F.T, "the process noise is missing: P̌ = F P̂ Fᵀ + B Q Bᵀ"),
            (0.5 * (half + half.T) + B @ Q @ B.T, "transpose: F P̂ Fᵀ, not F P̂ F"),
        ], hint="P̌ = F P̂ Fᵀ + B Q Bᵀ")


@check
def check_eskf_pose_residual(pose_residual):
    """``pose_residual(p_check, R_check, p_meas, R_meas)`` returns y (6,)."""
    rng = np.random.default_rng(3)
    for x, _, _ in _cases():
        p_m = x.position + rng.normal(size=3) * 0.2
        R_m = x.rotation @ so3.exp(rng.normal(size=3) * 0.01)
        got = call(pose_residual, x.position, x.rotation, p_m, R_m)
        ref = eskf.pose_residual(x.position, x.rotation, p_m, R_m)
        expect_close(got, ref, "y", atol=1e-12, mistakes=[
            (np.r_[-ref[:3], ref[3:]], "sign of the position residual: error = nominal − true, so "
                                       "y = p̌ − p_meas (prediction minus measurement)"),
            (np.r_[ref[:3], -ref[3:]], "sign of the attitude residual: Ř ≈ R_meas Exp(δθ), so "
                                       "δθ = Log(R_measᵀ Ř), not Log(Řᵀ R_meas)"),
            (-ref, "sign of the residual: prediction minus measurement, y = [p̌ − p_m; Log(R_mᵀ Ř)]"),
            (np.r_[ref[:3], so3.log(x.rotation @ R_m.T)], "the attitude error lives in the body frame: "
                                                           "Log(R_measᵀ Ř), not Log(Ř R_measᵀ)"),
        ], hint="y = [p̌ − p_meas; Log(R_measᵀ Ř)]")


def _update_case(seed=4):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(15, 15)) * 0.05
    P = A @ A.T + np.diag(np.r_[np.full(3, 0.04), np.full(3, 0.01), np.full(3, 1e-4), np.full(3, 4e-4), np.full(3, 1e-6)])
    R = np.diag(np.r_[np.full(3, 0.04), np.full(3, np.deg2rad(0.3) ** 2)])
    return P, eskf.POSE_G.copy(), R


@check
def check_eskf_gain(kalman_gain):
    """``kalman_gain(P, G, R)`` returns K (15, 6)."""
    for seed in (4, 5):
        P, G, R = _update_case(seed)
        got = call(kalman_gain, P, G, R)
        ref = eskf.kalman_gain(P, G, R)
        expect_close(got, ref, "K", rtol=1e-8, atol=1e-12, mistakes=[
            (P @ G.T @ np.linalg.inv(G @ P @ G.T), "S = G P Gᵀ + R: the observation noise R is missing"),
            (P @ G.T @ np.linalg.inv(R), "K = P Gᵀ S⁻¹ with S = G P Gᵀ + R, not R⁻¹"),
        ], hint="K = P Gᵀ (G P Gᵀ + R)⁻¹")


@check
def check_eskf_covariance_update(update_covariance):
    """``update_covariance(P, K, G, R)`` returns P̂ (Joseph form, valid for any K)."""
    for seed in (4, 5):
        P, G, R = _update_case(seed)
        K_opt = eskf.kalman_gain(P, G, R)
        for K, label in ((K_opt, "the optimal gain"), (0.7 * K_opt, "a sub-optimal gain 0.7 K")):
            got = call(update_covariance, P, K, G, R)
            expect_symmetric(got, "P_hat")
            if np.linalg.eigvalsh(symmetrise(np.asarray(got, dtype=float))).min() < 0.0:
                raise CheckFailed("P_hat is not positive semi-definite")
            ref = eskf.update_covariance(P, K, G, R)
            A = np.eye(15) - K @ G
            expect_close(got, ref, f"P_hat with {label}", rtol=1e-8, atol=1e-14, mistakes=[
                (A @ P @ A.T, "the Joseph form needs its second term: + K R Kᵀ"),
                (A @ P, "(I − K G) P̌ is right only for the optimal gain; the Joseph form "
                        "(I − K G) P̌ (I − K G)ᵀ + K R Kᵀ holds for any K and stays symmetric"),
            ], hint="P̂ = (I − K G) P̌ (I − K G)ᵀ + K R Kᵀ")


@check
def check_eskf_inject(inject):
    """``inject(nominal, dx)`` removes the estimated error: returns the corrected NominalState."""
    rng = np.random.default_rng(6)
    for true, _, _ in _cases():
        dx = np.r_[rng.normal(size=3) * 0.2, rng.normal(size=3) * 0.05, rng.normal(size=3) * 0.01,
                   rng.normal(size=3) * 0.01, rng.normal(size=3) * 1e-3]
        nom = NominalState(true.position + dx[0:3], true.velocity + dx[3:6], true.rotation @ so3.exp(dx[6:9]),
                           true.accel_bias + dx[9:12], true.gyro_bias + dx[12:15])
        got = call(inject, nom, dx)
        for field in ("position", "velocity", "rotation", "accel_bias", "gyro_bias"):
            if not hasattr(got, field):
                raise CheckFailed(f"inject must return a NominalState; the result has no {field!r}")
        R = expect_shape(got.rotation, (3, 3), "rotation after injection")
        if not so3.is_rotation(R, tol=1e-9):
            raise CheckFailed("the rotation after injection is not orthonormal (RᵀR ≠ I). Hint: inject "
                              "with Ř Exp(−δθ); the first-order Ř (I − [δθ]×) is not a rotation")
        expect_close(got.position, true.position, "position after injection", atol=1e-12, mistakes=[
            (nom.position + dx[0:3], "error = nominal − true, so p̂ = p̌ − δp")])
        expect_close(got.velocity, true.velocity, "velocity after injection", atol=1e-12, mistakes=[
            (nom.velocity + dx[3:6], "error = nominal − true, so v̂ = v̌ − δv")])
        expect_close(R, true.rotation, "rotation after injection", atol=1e-12, mistakes=[
            (nom.rotation @ so3.exp(dx[6:9]), "sign: Ř = R Exp(δθ), so R̂ = Ř Exp(−δθ)"),
            (so3.exp(-dx[6:9]) @ nom.rotation, "δθ is a body-frame error: multiply on the right, Ř Exp(−δθ)"),
        ])
        expect_close(got.accel_bias, true.accel_bias, "accelerometer bias after injection", atol=1e-12, mistakes=[
            (nom.accel_bias + dx[9:12], "sign of the bias correction: δb = b̌ − b, so b̂ = b̌ − δb")])
        expect_close(got.gyro_bias, true.gyro_bias, "gyroscope bias after injection", atol=1e-12, mistakes=[
            (nom.gyro_bias + dx[12:15], "sign of the bias correction: δb = b̌ − b, so b̂ = b̌ − δb")])


@check
def check_eskf_reset(reset_covariance):
    """``reset_covariance(P, dx)`` returns G P Gᵀ with the reset Jacobian of this convention."""
    rng = np.random.default_rng(7)
    P, _, _ = _update_case(9)
    for _ in range(3):
        dx = np.r_[rng.normal(size=6) * 0.1, rng.normal(size=3) * 3e-3, rng.normal(size=6) * 1e-3]
        got = expect_shape(call(reset_covariance, P, dx), (15, 15), "P after reset")
        expect_symmetric(got, "P after reset")
        G1 = np.eye(15)
        G1[6:9, 6:9] = np.eye(3) + 0.5 * so3.hat(dx[6:9])
        first = G1 @ P @ G1.T
        exact = eskf.reset_covariance(P, dx, exact=True)
        if np.allclose(got, exact, rtol=1e-9, atol=1e-15):
            continue
        G2 = np.eye(15)
        G2[6:9, 6:9] = np.eye(3) - 0.5 * so3.hat(dx[6:9])
        expect_close(got, first, "P after reset", rtol=1e-9, atol=1e-15, mistakes=[
            (G2 @ P @ G2.T, "sign of the reset Jacobian: for error = nominal − true, "
                            "δθ⁺ ≈ δθ − δθ̂ + ½[δθ̂]× δθ, so its attitude block is I + ½[δθ̂]×"),
            (P, "the covariance is unchanged; this exercise asks for the exact reset G P Gᵀ"),
        ], hint="P ← G P Gᵀ, G = I except G[6:9, 6:9] = I + ½[δθ̂]×")


@check
def check_eskf_run(run_eskf):
    """``run_eskf(ex, t_end, cfg)`` returns (t, positions, rotations, P) at the lidar times."""
    ex = load_kitti(RUN_EXCERPT)
    cfg = load_config("kitti_lidar")
    k0, s0 = ex.initial_state()
    t_end = float(ex.imu.t[k0] + RUN_SECONDS)
    result = call(run_eskf, ex, t_end, cfg)
    if not isinstance(result, tuple) or len(result) != 4:
        raise CheckFailed("run_eskf must return a tuple (t, positions, rotations, P)")
    ref = eskf.run(ex.imu, s0, cfg, ex.gravity, lidar=ex.lidar, start=k0, t_end=t_end)
    t = expect_shape(result[0], ref.t.shape, "t")
    expect_close(t, ref.t, "the update times", atol=1e-9)
    p = expect_shape(result[1], ref.position.shape, "positions")
    truth = ex.truth.position[np.searchsorted(ex.truth.t, ref.t - 1e-6)]
    err = position_rmse(p, truth)
    err_ref = position_rmse(ref.position, truth)
    expect_close(p, ref.position, f"positions on the first {RUN_SECONDS:.0f} s of '{RUN_EXCERPT}'",
                 rtol=0.0, atol=1e-6,
                 hint=f"your position RMSE against ground truth is {err:.4f} m, the reference's "
                      f"{err_ref:.4f} m. Check the observation noise (R holds variances) and every piece above")
    expect_close(result[2], ref.rotation, "rotations", atol=1e-6)
    P = expect_shape(result[3], ref.P.shape, "P")
    expect_close(P, ref.P, "P at the update times", rtol=1e-3, atol=5e-9)


# ---------------------------------------------------------------------------------------
# Bonus: the nominal-state EKF
# ---------------------------------------------------------------------------------------

@check
def check_nominal_ekf_observation(align_quaternion):
    """``align_quaternion(q_check, q_meas)`` returns ±q_meas, whichever is closer to q_check."""
    rng = np.random.default_rng(11)
    for _ in range(6):
        q = so3.matrix_to_quat(so3.exp(rng.normal(size=3)))
        q_m = so3.matrix_to_quat(so3.quat_to_matrix(q) @ so3.exp(rng.normal(size=3) * 0.01))
        for sign in (1.0, -1.0):
            got = call(align_quaternion, q, sign * q_m)
            expect_close(got, q_m, "the aligned measured quaternion", atol=1e-12, mistakes=[
                (-q_m, "q and −q are the same rotation, but the EKF subtracts quaternions: pick the sign "
                       "of q_meas that makes q_measᵀ q̌ ≥ 0"),
            ], hint="return q_meas if q_meas · q_check ≥ 0, else −q_meas")


@check
def check_nominal_ekf_jacobian(nominal_jacobian):
    """``nominal_jacobian(q, f, w, b_a, b_w)`` returns A = ∂ẋ/∂x (16, 16)."""
    from kalman_course.filters import nominal_ekf

    for x, f, w in _cases():
        q = so3.matrix_to_quat(x.rotation)
        got = expect_shape(call(nominal_jacobian, q, f, w, x.accel_bias, x.gyro_bias), (16, 16), "A")
        ref = nominal_ekf.continuous_jacobian(q, f, w, x.accel_bias, x.gyro_bias)
        flip = ref.copy()
        flip[6:10, 13:16] *= -1
        expect_close(got, ref, "A", atol=1e-10, mistakes=[
            (flip, "q̇ = ½ q ⊗ (0, ω − b_ω): the gyro bias enters with a minus sign, ∂q̇/∂b_ω = −½ Ξ(q)"),
        ], hint="compare block by block: ṗ = v, v̇ = R(q)(f − b_a) + g, q̇ = ½ q ⊗ (0, ω − b_ω)")
