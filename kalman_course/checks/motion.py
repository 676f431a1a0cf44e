"""Checks for chapter 04: the CTRV step and its Jacobian, graded on KITTI states.

The states are the car's true CTRV states [p_x, p_y, v, ψ, ω] on the KITTI excerpts
(ω from the gyro), plus the same states driving straight (ω = 0 exactly), where the
closed form divides by zero and the straight-line limit must take over.
"""

from __future__ import annotations

import functools

import numpy as np

from kalman_course import symbolic
from kalman_course.checks.harness import CheckFailed, call, check, expect_close, expect_shape
from kalman_course.chapters.motion import kitti_model_states

EXCERPTS = ("turns", "stop_go")
STEPS = (0.1, 1.0)


@functools.lru_cache(maxsize=None)
def kitti_ctrv_cases(count: int = 6, seed: int = 4):
    """(state, T) pairs: KITTI CTRV states at two step lengths, turning and straight."""
    rng = np.random.default_rng(seed)
    cases = []
    for name in EXCERPTS:
        _, states = kitti_model_states(name, "ctrv")
        moving = states[states[:, 2] > 2.0]
        # the states turning hardest, then random ones, then the same driving straight
        hardest = moving[np.argsort(-np.abs(moving[:, 4]))[:2]]
        picked = np.vstack([hardest, moving[rng.choice(len(moving), size=count - 2, replace=False)]])
        straight = picked[:2].copy()
        straight[:, 4] = 0.0
        for state in np.vstack([picked, straight]):
            for T in STEPS:
                cases.append((state, T))
    return tuple(cases)


def _straight_line(x, T):
    px, py, v, psi, om = x
    return np.array([px + v * T * np.cos(psi), py + v * T * np.sin(psi), v, psi + om * T, om])


@check
def check_ctrv_step(ctrv_step):
    """The learner's ``ctrv_step(x, T)`` (noise-free) against the derived model."""
    for x, T in kitti_ctrv_cases():
        expected = symbolic.ctrv_step(x, T)
        got = expect_shape(call(ctrv_step, x, T), (5,), f"ctrv_step(x, T={T})")
        px, py, v, psi, om = x
        mistakes = []
        if om != 0.0:
            flipped = expected.copy()
            flipped[1] = py + v / om * (np.cos(psi + om * T) - np.cos(psi))
            mistakes.append((flipped, "p_y: the integral of v sin(ψ + ω t) is "
                                      "v/ω (cos ψ − cos(ψ + ω T)); check the order of the cosines"))
            mistakes.append((_straight_line(x, T), "with ω ≠ 0 the car turns: use the closed form, "
                                                   "the straight line is only the ω → 0 limit"))
        else:
            no_heading = expected.copy()
            no_heading[0], no_heading[1] = px + v * T, py
            mistakes.append((no_heading, "straight-line branch: the car moves along its heading, "
                                         "p_x += v T cos ψ and p_y += v T sin ψ"))
        where = "driving straight (ω = 0)" if om == 0.0 else f"turning at ω = {om:.3f} rad/s"
        expect_close(got, expected, f"ctrv_step at a KITTI state {where}, T = {T} s", rtol=1e-7,
                     atol=1e-7, mistakes=mistakes,
                     hint="p_x += v/ω (sin(ψ + ω T) − sin ψ), p_y += v/ω (cos ψ − cos(ψ + ω T)), "
                          "ψ += ω T; for |ω| tiny use the straight line")


@check
def check_ctrv_jacobian(ctrv_jacobian):
    """The learner's ``ctrv_jacobian(x, T)`` against SymPy's, turning and at ω = 0."""
    for x, T in kitti_ctrv_cases():
        expected = symbolic.ctrv_jacobian(x, T)
        got = call(ctrv_jacobian, x, T)
        if np.shape(got) == (5, 4):
            raise CheckFailed("ctrv_jacobian has shape (5, 4): differentiate with respect to all five "
                              "state components, ω included")
        got = expect_shape(got, (5, 5), f"ctrv_jacobian(x, T={T})")
        mistakes = []
        if x[4] == 0.0:
            no_omega = expected.copy()
            no_omega[:2, 4] = 0.0
            mistakes.append((no_omega, "at ω = 0 the turn rate still bends the path: ∂p_x/∂ω = "
                                       "−v T² sin ψ / 2 and ∂p_y/∂ω = v T² cos ψ / 2 (the limit of the "
                                       "turning Jacobian), not 0"))
        where = "driving straight (ω = 0)" if x[4] == 0.0 else f"turning at ω = {x[4]:.3f} rad/s"
        expect_close(got, expected, f"ctrv_jacobian at a KITTI state {where}, T = {T} s", rtol=1e-6,
                     atol=1e-7, mistakes=mistakes,
                     hint="compare your Jacobian with finite differences of your ctrv_step")
