"""Checks for chapters 05 and 06: radar observation, residual, EKF update, iterated EKF.

The radar cases are the car's true CTRV states on a KITTI excerpt seen by a radar parked
in the middle of it (so bearings cover every quadrant, including both sides of ±π). The
EKF and IEKF updates are graded on the chapter 06 scenario: priors of the reference
filter on KITTI, precise range–bearing measurements to beacons along the road.
"""

from __future__ import annotations

import functools

import numpy as np

from kalman_course import symbolic
from kalman_course.chapters import beacons
from kalman_course.core.angles import wrap_angle
from kalman_course.core.linalg import gain, innovation_covariance, short_update
from kalman_course.filters import ekf
from kalman_course.checks.harness import CheckFailed, call, check, expect_close, expect_shape, expect_symmetric
from kalman_course.chapters.motion import kitti_model_states

RADAR_EXCERPT = "turns"
R_RADAR = np.diag([0.09, 0.0009, 0.09])


@functools.lru_cache(maxsize=None)
def radar_states(count: int = 10, seed: int = 2):
    """CTRV states of the KITTI car relative to a radar in the middle of the excerpt,
    plus two states straddling the negative x axis (the bearing's ±π cut)."""
    _, states = kitti_model_states(RADAR_EXCERPT, "ctrv")
    radar = states[len(states) // 2, :2] + np.array([3.0, 2.0])
    rng = np.random.default_rng(seed)
    picked = states[rng.choice(len(states), size=count, replace=False)].copy()
    picked[:, :2] -= radar
    cut = picked[:2].copy()
    cut[0, :2] = [-25.0, 0.3]
    cut[1, :2] = [-25.0, -0.3]
    return tuple(np.vstack([picked, cut]))


def _radar_mistakes(x):
    px, py, v, psi, _ = x
    ref = symbolic.radar_observation(x)
    atan = ref.copy()
    atan[1] = np.arctan(py / px)
    speed = ref.copy()
    speed[2] = v
    return [(atan, "φ = atan2(p_y, p_x): arctan(p_y / p_x) loses the quadrant when p_x < 0"),
            (speed, "the range rate is the velocity projected on the line of sight, "
                    "(p_x v_x + p_y v_y) / ρ, not the speed")]


@check
def check_radar_h(radar_h):
    """The learner's ``radar_h(x)`` for a CTRV state [p_x, p_y, v, ψ, ω]."""
    for x in radar_states():
        got = expect_shape(call(radar_h, x), (3,), "radar_h(x)")
        expect_close(got, symbolic.radar_observation(x), f"radar_h at p = ({x[0]:.1f}, {x[1]:.1f}) m",
                     mistakes=_radar_mistakes(x), hint="h(x) = [ρ, atan2(p_y, p_x), (p_x v_x + p_y v_y)/ρ] "
                                                       "with v_x = v cos ψ, v_y = v sin ψ")


@check
def check_radar_jacobian(radar_jacobian):
    """The learner's ``radar_jacobian(x)``, shape (3, 5), against SymPy's."""
    for x in radar_states():
        G = symbolic.radar_jacobian(x)
        got = expect_shape(call(radar_jacobian, x), (3, 5), "radar_jacobian(x)")
        no_heading = G.copy()
        no_heading[2, 3] = 0.0
        sign = G.copy()
        sign[1, :2] *= -1
        expect_close(got, G, f"radar_jacobian at p = ({x[0]:.1f}, {x[1]:.1f}) m", rtol=1e-7, atol=1e-10,
                     mistakes=[(no_heading, "the range rate depends on the heading through v_x = v cos ψ, "
                                            "v_y = v sin ψ: ∂ρ̇/∂ψ = v (p_y cos ψ − p_x sin ψ)/ρ"),
                               (sign, "∂φ/∂p_x = −p_y/ρ² and ∂φ/∂p_y = p_x/ρ²: check the signs")],
                     hint="differentiate each row of h(x) with respect to [p_x, p_y, v, ψ, ω]")


@check
def check_radar_residual(radar_residual):
    """The learner's ``radar_residual(y, y_pred)``: bearings wrapped to (−π, π]."""
    rng = np.random.default_rng(5)
    pairs = []
    for x in radar_states():
        y_pred = symbolic.radar_observation(x)
        y = y_pred + np.array([0.3, 0.03, 0.3]) * rng.standard_normal(3)
        y[1] = wrap_angle(y[1])
        pairs.append((y, y_pred))
    # a target crossing the negative x axis, both ways
    pairs.append((np.array([25.0, -np.pi + 0.01, 1.0]), np.array([25.2, np.pi - 0.02, 1.1])))
    pairs.append((np.array([25.0, np.pi - 0.01, 1.0]), np.array([24.9, -np.pi + 0.005, 0.8])))
    for y, y_pred in pairs:
        expected = ekf.radar_residual(y, y_pred)
        got = expect_shape(call(radar_residual, y, y_pred), (3,), "radar_residual(y, y_pred)")
        expect_close(got, expected, f"radar_residual with predicted bearing {y_pred[1]:.3f} rad and "
                     f"measured {y[1]:.3f} rad", mistakes=[
                         (y - y_pred, "the bearing difference must be wrapped to (−π, π]: across the "
                                      "negative x axis the raw difference is nearly 2π"),
                         (y_pred - y, "the residual is measured minus predicted, y − h(x̌)")],
                     hint="e = y − y_pred, then wrap e[1] into (−π, π]")


@functools.lru_cache(maxsize=None)
def beacon_update_cases(count: int = 6):
    """(x_check, P_check, y, beacon positions, R) from the reference IEKF on the chapter 06 KITTI scenario."""
    sc = beacons.kitti_beacons()
    ref = beacons.run_beacon_filter(sc, iterated=True)
    cases = []
    steps = np.linspace(1, len(sc.t) - 1, count).astype(int)
    for k in steps:
        T = sc.t[k] - sc.t[k - 1]
        F = symbolic.cv_transition(T, 2)
        x_check, P_check = ekf.ekf_predict(ref.x_hat[k - 1], ref.P_hat[k - 1], lambda s: F @ s, F,
                                           symbolic.cv_process_noise(T, 2.0, 2))
        cases.append((x_check, P_check, sc.z[k], sc.beacons[sc.nearest[k]], sc.R))
    # the very first update, from the wide prior: strongly nonlinear
    cases.append((sc.x0, sc.P0, sc.z[0], sc.beacons[sc.nearest[0]], sc.R))
    return tuple(cases)


def _pair(result, what: str):
    if not isinstance(result, tuple) or len(result) < 2:
        raise CheckFailed(f"{what} must return a tuple (x_hat, P_hat, ...)")
    return result


@check
def check_ekf_update(ekf_update):
    """The learner's ``ekf_update(x_check, P_check, y, g, G, R, residual)`` → (x_hat, P_hat)."""
    for x_check, P_check, y, positions, R in beacon_update_cases():
        g, G = beacons.beacon_observation(positions), beacons.beacon_jacobian(positions)
        result = _pair(call(ekf_update, x_check, P_check, y, g, G, R, beacons.bearings_residual), "ekf_update")
        ref = ekf.ekf_update(x_check, P_check, y, g, G, R, residual=beacons.bearings_residual)
        Gm = G(x_check)
        linear = x_check + ref.K @ beacons.bearings_residual(y, Gm @ x_check)
        unwrapped = x_check + ref.K @ (y - g(x_check))
        expect_close(result[0], ref.x_hat, "x_hat", rtol=1e-7, atol=1e-8, mistakes=[
            (linear, "the predicted measurement is g(x̌), the nonlinear model; G x̌ is only its "
                     "linearisation's slope times the state"),
            (unwrapped, "use the residual function you are given, so that bearings are wrapped"),
        ], hint="x̂ = x̌ + K r(y, g(x̌)) with K = P̌ Gᵀ (G P̌ Gᵀ + R)⁻¹ and G evaluated at x̌")
        expect_close(result[1], ref.P_hat, "P_hat", rtol=1e-6, atol=1e-10, mistakes=[
            (P_check, "the covariance must shrink: P̂ = (I − K G) P̌")], hint="P̂ = (I − K G) P̌")
        expect_symmetric(result[1], "P_hat")


def _gain_at(P_check, G_op, R):
    """K = P̌ Gᵀ (G P̌ Gᵀ + R)⁻¹ for a Jacobian G_op evaluated at some linearisation point."""
    GP = G_op @ P_check
    return gain(GP, innovation_covariance(GP, G_op, R))


def _iekf_step_reference(x_check, P_check, x_op, y, g, G, R):
    Gm = G(x_op)
    K = _gain_at(P_check, Gm, R)
    r = beacons.bearings_residual(y, g(x_op))
    return x_check + K @ (r - Gm @ (x_check - x_op)), K, r, Gm


@check
def check_iekf_mean_step(iekf_mean_step):
    """The learner's ``iekf_mean_step(x_check, P_check, x_op, y, g, G, R, residual)`` → x_next."""
    for x_check, P_check, y, positions, R in beacon_update_cases():
        g, G = beacons.beacon_observation(positions), beacons.beacon_jacobian(positions)
        # linearise at the prior, then at the first iterate
        x1 = _iekf_step_reference(x_check, P_check, x_check, y, g, G, R)[0]
        for x_op in (x_check, x1):
            expected, K, r, Gm = _iekf_step_reference(x_check, P_check, x_op, y, g, G, R)
            got = expect_shape(call(iekf_mean_step, x_check, P_check, x_op, y, g, G, R, beacons.bearings_residual),
                               (4,), "iekf_mean_step(...)")
            if x_op is x_check:
                where = "at the first iteration (x_op = x̌)"
            else:
                where = "at the second iteration (x_op ≠ x̌)"
            expect_close(got, expected, f"the iterate {where}", rtol=1e-7, atol=1e-8, mistakes=[
                (x_op + K @ r, "the step starts from the prior: x_{i+1} = x̌ + K (r − G (x̌ − x_op)); "
                               "the linearisation point only enters through g(x_op) and G"),
                (x_op + K @ (r - Gm @ (x_check - x_op)), "the step starts from the prior x̌, not from "
                                                         "x_op: x_{i+1} = x̌ + K (r − G (x̌ − x_op))"),
                (x_check + K @ (r + Gm @ (x_check - x_op)), "sign: g(x) ≈ g(x_op) + G (x − x_op), so the "
                                                            "correction is − G (x̌ − x_op)"),
                (x_check + K @ r, "the term − G (x̌ − x_op) is missing; it vanishes only at the first "
                                  "iteration"),
            ], hint="x_{i+1} = x̌ + K_i (r(y, g(x_i)) − G_i (x̌ − x_i)), with G_i and K_i at x_i")


@check
def check_iekf_update(iekf_update):
    """The learner's ``iekf_update(x_check, P_check, y, g, G, R, residual, tol, max_iter)``
    → (x_hat, P_hat, iterations)."""
    for x_check, P_check, y, positions, R in beacon_update_cases():
        g, G = beacons.beacon_observation(positions), beacons.beacon_jacobian(positions)
        result = call(iekf_update, x_check, P_check, y, g, G, R, beacons.bearings_residual, 1e-6, 20)
        if not isinstance(result, tuple) or len(result) != 3:
            raise CheckFailed("iekf_update must return a tuple (x_hat, P_hat, iterations)")
        ref = ekf.iekf_update(x_check, P_check, y, g, G, R, residual=beacons.bearings_residual, tol=1e-6,
                              max_iter=20)
        expect_close(result[0], ref.x_hat, "x_hat", rtol=1e-6, atol=1e-7,
                     hint="iterate x_op ← x̌ + K (r(y, g(x_op)) − G (x̌ − x_op)) until the step is "
                          "below tol")
        # covariance mistakes: the EKF's (G at x̌), or shrinking P inside the loop
        G0 = G(x_check)
        K0 = _gain_at(P_check, G0, R)
        at_prior = short_update(P_check, K0, G0 @ P_check)
        P_loop = P_check
        x_op = x_check
        for _ in range(ref.iterations):
            Gi = G(x_op)
            Ki = _gain_at(P_loop, Gi, R)
            x_op = x_check + Ki @ (beacons.bearings_residual(y, g(x_op)) - Gi @ (x_check - x_op))
            P_loop = short_update(P_loop, Ki, Gi @ P_loop)
        expect_close(result[1], ref.P_hat, "P_hat", rtol=1e-5, atol=1e-9, mistakes=[
            (at_prior, "the final covariance uses K and G of the last linearisation, not those at x̌"),
            (P_loop, "only the mean iterates: form P̂ = (I − K G) P̌ once, after the loop, from the "
                     "prior P̌"),
        ], hint="P̂ = (I − K G) P̌ with K, G at the last iterate")
        if int(result[2]) != ref.iterations:
            raise CheckFailed(f"iterations is {result[2]}, the reference needs {ref.iterations}: count one "
                              "per linearisation and stop as soon as max |x_{i+1} − x_i| <= tol")
