"""Checks for chapter 07: the three midpoint steps of IMU mechanisation, and a whole run.

Each step is compared with a closed form on synthetic motion (constant rate, constant
specific force) and with :func:`kalman_course.core.imu.midpoint_step` on KITTI samples; the
whole run with :func:`kalman_course.core.imu.dead_reckon` on a KITTI slice and with the exact
truth of a synthetic trajectory.
"""

from __future__ import annotations

import functools

import numpy as np

from kalman_course.core import so3
from kalman_course.checks.harness import CheckFailed, call, check, expect_close, expect_shape
from kalman_course.data import imu_trajectory, load_kitti
from kalman_course.core.imu import NavState, dead_reckon

#: The KITTI slice the whole-run check integrates: excerpt, first sample, number of samples.
RUN_SLICE = ("turns", 1000, 500)


def reference_attitude_step(R, w0, w1, b_w, dt):
    """R Exp((½(ω₀ + ω₁) − b_ω) T)."""
    return R @ so3.exp((0.5 * (w0 + w1) - b_w) * dt)


def reference_velocity_step(v, R0, R1, f0, f1, b_a, g, dt):
    """v + ½(R₀(f₀ − b_a) + R₁(f₁ − b_a)) T + g T."""
    return v + 0.5 * (R0 @ (f0 - b_a) + R1 @ (f1 - b_a)) * dt + g * dt


def reference_position_step(p, v0, v1, dt):
    """p + ½(v₀ + v₁) T."""
    return p + 0.5 * (v0 + v1) * dt


@functools.lru_cache(maxsize=None)
def _kitti_cases(count: int = 6, seed: int = 0):
    """Consecutive KITTI IMU sample pairs with the true attitude there and made-up biases."""
    ex = load_kitti("turns")
    rng = np.random.default_rng(seed)
    cases = []
    for k in rng.choice(np.arange(10, len(ex.imu) - 10), size=count, replace=False):
        nav = ex.truth.state_at(float(np.clip(ex.imu.t[k], ex.truth.t[0], ex.truth.t[-1])))
        cases.append(dict(R=nav.rotation, v=nav.velocity, p=nav.position,
                          f0=ex.imu.specific_force[k].copy(), f1=ex.imu.specific_force[k + 1].copy(),
                          w0=ex.imu.angular_rate[k].copy(), w1=ex.imu.angular_rate[k + 1].copy(),
                          b_a=rng.normal(size=3) * 0.05, b_w=rng.normal(size=3) * 0.01,
                          dt=float(ex.imu.t[k + 1] - ex.imu.t[k]), g=ex.gravity.copy()))
    return tuple(cases)


def _rotation_result(value, what):
    R = expect_shape(value, (3, 3), what)
    if not so3.is_rotation(R, tol=1e-9):
        raise CheckFailed(f"{what} is not a rotation matrix (RᵀR ≠ I). Hint: compose with Exp(φ), "
                          "not with the first-order I + [φ]×")
    return R


@check
def check_attitude_step(attitude_step):
    """``attitude_step(R, w0, w1, b_w, dt)`` returns the attitude at the next sample."""
    # closed form: a constant rate ω about a fixed axis for T seconds is Exp(ω T)
    R0 = so3.exp(np.array([0.2, -0.4, 1.0]))
    w = np.array([0.3, -0.1, 0.7])
    got = _rotation_result(call(attitude_step, R0, w, w, np.zeros(3), 0.5), "R_next (constant rate)")
    expect_close(got, R0 @ so3.exp(w * 0.5), "R_next for a constant rate", mistakes=[
        (so3.exp(w * 0.5) @ R0, "ω is measured in the body frame, so its rotation multiplies on the "
                                "right: R Exp(ω T), not Exp(ω T) R")],
        hint="R_next = R Exp(ω T) for a constant rate")
    for c in _kitti_cases():
        got = call(attitude_step, c["R"], c["w0"], c["w1"], c["b_w"], c["dt"])
        got = _rotation_result(got, "R_next")
        ref = reference_attitude_step(c["R"], c["w0"], c["w1"], c["b_w"], c["dt"])
        phi = (0.5 * (c["w0"] + c["w1"]) - c["b_w"]) * c["dt"]
        expect_close(got, ref, "R_next on KITTI samples", atol=1e-12, mistakes=[
            (so3.exp(phi) @ c["R"], "ω is a body-frame rate: R_next = R Exp(φ), not Exp(φ) R"),
            (c["R"] @ so3.exp(0.5 * (c["w0"] + c["w1"]) * c["dt"]), "subtract the gyro bias: ω̄ = ω − b_ω"),
            (c["R"] @ so3.exp((c["w0"] - c["b_w"]) * c["dt"]),
             "midpoint rule: use the mean of the two rates, ½(ω₀ + ω₁) − b_ω"),
        ], hint="R_next = R Exp((½(ω₀ + ω₁) − b_ω) T)")


@check
def check_velocity_step(velocity_step):
    """``velocity_step(v, R0, R1, f0, f1, b_a, g, dt)`` returns the velocity at the next sample."""
    g = np.array([0.0, 0.0, -9.8092])
    # closed form: a level car at rest reads f = (0, 0, +9.81) and keeps its velocity
    v = np.array([1.0, 2.0, 0.0])
    f_rest = -g
    got = call(velocity_step, v, np.eye(3), np.eye(3), f_rest, f_rest, np.zeros(3), g, 0.1)
    expect_close(got, v, "v_next for a level IMU whose specific force cancels gravity", mistakes=[
        (v + 2 * f_rest * 0.1, "gravity has the wrong sign: a = R (f − b_a) + g with g = (0, 0, −9.81), "
                               "so a resting accelerometer (f = +9.81 up) gives a = 0")],
        hint="a = R (f − b_a) + g; v_next = v + ½(a₀ + a₁) T")
    for c in _kitti_cases():
        R1 = reference_attitude_step(c["R"], c["w0"], c["w1"], c["b_w"], c["dt"])
        args = (c["v"], c["R"], R1, c["f0"], c["f1"], c["b_a"], c["g"], c["dt"])
        got = call(velocity_step, *args)
        ref = reference_velocity_step(*args)
        T = c["dt"]
        expect_close(got, ref, "v_next on KITTI samples", atol=1e-12, mistakes=[
            (ref - 2 * c["g"] * T, "gravity: a = R (f − b_a) + g with g = (0, 0, −9.81); add g, do not subtract it"),
            (c["v"] + 0.5 * (c["R"] @ (c["f0"] - c["b_a"]) + c["R"] @ (c["f1"] - c["b_a"])) * T + c["g"] * T,
             "the acceleration at the end of the step uses the NEW attitude R₁"),
            (c["v"] + 0.5 * (c["R"] @ c["f0"] + R1 @ c["f1"]) * T + c["g"] * T,
             "subtract the accelerometer bias: f − b_a"),
            (c["v"] + (c["R"] @ (c["f0"] - c["b_a"]) + c["g"]) * T,
             "midpoint rule: average the accelerations at both ends of the step"),
        ], hint="v_next = v + ½(R₀(f₀ − b_a) + R₁(f₁ − b_a)) T + g T")


@check
def check_position_step(position_step):
    """``position_step(p, v0, v1, dt)`` returns the position at the next sample."""
    # closed form: constant acceleration a from v0 gives p + v0 T + ½ a T²
    p, v0, a, T = np.array([1.0, -2.0, 0.5]), np.array([3.0, 1.0, 0.0]), np.array([0.5, -1.0, 0.2]), 0.2
    v1 = v0 + a * T
    got = call(position_step, p, v0, v1, T)
    expect_close(got, p + v0 * T + 0.5 * a * T * T, "p_next under constant acceleration", mistakes=[
        (p + v1 * T, "midpoint rule: use the mean velocity ½(v₀ + v₁), not the new one"),
        (p + v0 * T, "midpoint rule: use the mean velocity ½(v₀ + v₁), not the old one"),
    ], hint="p_next = p + ½(v₀ + v₁) T (exact for a constant acceleration)")
    for c in _kitti_cases():
        v1 = c["v"] + np.array([0.01, -0.02, 0.003])
        expect_close(call(position_step, c["p"], c["v"], v1, c["dt"]),
                     reference_position_step(c["p"], c["v"], v1, c["dt"]), "p_next on KITTI samples", atol=1e-12)


@check
def check_mechanisation_run(mechanise):
    """``mechanise(imu, state, g, start, stop)`` returns positions (n, 3), velocities, rotations."""
    # synthetic motion whose truth the midpoint rule reproduces exactly
    sc = imu_trajectory(3, duration=5.0)
    start = NavState(sc.position[0], sc.velocity[0], sc.rotation[0])
    g = np.array([0.0, 0.0, -9.8092])
    result = call(mechanise, sc.imu_clean, start, g, 0, len(sc.t))
    if not isinstance(result, tuple) or len(result) != 3:
        raise CheckFailed("mechanise must return a tuple (positions (n, 3), velocities (n, 3), rotations (n, 3, 3))")
    p = expect_shape(result[0], sc.position.shape, "positions")
    expect_close(p, sc.position, "positions on synthetic motion with clean readings", atol=1e-6,
                 hint=f"the error after 5 s is {np.linalg.norm(p[-1] - sc.position[-1]):.3g} m; the midpoint "
                      "rule reproduces this truth to round-off")
    name, k0, n = RUN_SLICE
    ex = load_kitti(name)
    nav = ex.truth.state_at(ex.imu.t[k0])
    result = call(mechanise, ex.imu, nav, ex.gravity, k0, k0 + n)
    if not isinstance(result, tuple) or len(result) != 3:
        raise CheckFailed("mechanise must return a tuple (positions, velocities, rotations)")
    ref = dead_reckon(ex.imu, nav, ex.gravity, start=k0, stop=k0 + n)
    expect_close(result[0], ref.position, f"positions on KITTI '{name}' samples {k0}..{k0 + n - 1}", atol=1e-6,
                 hint="KITTI's IMU timestamps are irregular (dt from 2.6 to 20 ms): give every step its "
                      "own dt = imu.t[k] − imu.t[k−1]")
    expect_close(result[1], ref.velocity, "velocities on KITTI", atol=1e-8)
    expect_close(result[2], ref.rotation, "rotations on KITTI", atol=1e-10)
