"""Lecture 07 ("Rotations and IMU mechanisation"): attitude integration and the flat frame.

Two experiments that the lecture's last sections run, in the pieces its cells call.

**Quaternion attitude integration and its order** (§6). The attitude kinematics
q̇ = ½ q ⊗ (0, ω) are integrated from rates ω_k sampled every T seconds by three rules:

- ``"euler"``: q_{k+1} = (q_k + ½ T q_k ⊗ (0, ω_k)) / |·|, the naive step with the rate at
  the start of the step, renormalised;
- ``"zeroth_order"``: q_{k+1} = q_k ⊗ Exp_q(ω̄ T), ω̄ = ½(ω_k + ω_{k+1}): the rate is taken
  constant over the step, at its mean;
- ``"first_order"``: q_{k+1} = q_k ⊗ Exp_q(ω̄ T + T²/12 ω_k × ω_{k+1}): the rate is taken
  linear over the step; the cross product is the coning correction (Solà writes its
  quaternion form, q_k ⊗ (Exp_q(ω̄ T) + T²/24 (0, ω_k × ω_{k+1})), :func:`sola_increment`).

"Zeroth" and "first" name the polynomial the rate is assumed to follow inside a step, not
the order of accuracy; the lecture measures that, on a coning motion with a closed-form
attitude (:func:`coning_attitude`) and on a rate linear in time whose attitude comes from
a fine RK4 reference (:func:`reference_attitude`).

**The flat, non-rotating navigation frame** (§7). What the mechanisation leaves out (the
Earth's rotation, Coriolis, transport rate, the change of gravity over the drive) and the
IMU's own errors are each put into one of a few error channels, and the position error
each would cause without aiding is grown over a horizon (:func:`position_error_growth`);
:func:`chain_position_error` computes the same numbers another way, from the linear error
chain, to check the closed forms.

Nothing here reads data except :func:`drive_extent`, which measures a KITTI ground truth
(real data); the trajectories of §6 are simulated (deterministic, no randomness).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import sympy as sp

from kalman_course.chapters.eskf_bias import EARTH_RATE, earth_rate
from kalman_course.core import so3
from kalman_course.core.validation import as_matrix, as_real_array, as_rotation, as_rows, as_scalar, as_vector

__all__ = [
    "RULES", "coning_attitude", "coning_rate", "coning_rate_integral", "reference_attitude",
    "step_rotation_vectors", "sola_increment", "local_errors", "integrate_quaternion",
    "integrate_rotation_matrix", "attitude_error", "max_attitude_errors", "halving_ratios",
    "loglog_slope", "coning_correction_residual",
    "EARTH_RADIUS", "DriveExtent", "drive_extent", "ErrorSource", "neglected_terms", "imu_error_sources",
    "error_budget", "CHANNELS", "GROWTH_POWER", "position_error_growth", "chain_position_error",
]

#: The attitude integration rules, in the order the lecture shows them.
RULES = ("euler", "zeroth_order", "first_order")

#: The Earth's mean radius R_E (IUGG), m.
EARTH_RADIUS = 6.371e6


# ---------------------------------------------------------------------------------------
# §6 — attitude integration
# ---------------------------------------------------------------------------------------

def _times(t, name: str = "t") -> np.ndarray:
    t = as_vector(t, name)
    if len(t) > 1 and np.any(np.diff(t) <= 0.0):
        raise ValueError(f"{name} must be strictly increasing")
    return t


def _cone(cone_angle, cone_rate) -> tuple[float, float]:
    beta = as_scalar(cone_angle, "cone_angle")
    if beta >= math.pi:
        raise ValueError(f"cone_angle must be in (0, π) rad, got {cone_angle!r}")
    if isinstance(cone_rate, (str, bytes, bool, np.bool_)):
        raise ValueError(f"cone_rate must be a finite number of rad/s, got {cone_rate!r}")
    try:
        rate = float(cone_rate)
    except (TypeError, ValueError):
        raise ValueError(f"cone_rate must be a finite number of rad/s, got {cone_rate!r}") from None
    if not math.isfinite(rate):
        raise ValueError(f"cone_rate must be a finite number of rad/s, got {cone_rate!r}")
    return beta, rate


def coning_attitude(t, cone_angle, cone_rate) -> np.ndarray:
    """Attitude of a classical coning motion, in closed form.

    q(t) = (cos β/2, sin(β/2) cos Ω t, sin(β/2) sin Ω t, 0): a rotation by the fixed angle β
    about a horizontal axis that turns about z at the rate Ω, so the body z axis sweeps a
    cone of half-angle β around the navigation z axis.

    Parameters
    ----------
    t : array_like, shape (N,)
        Times, s.
    cone_angle : float
        β, rad, in (0, π).
    cone_rate : float
        Ω, rad/s (either sign).

    Returns
    -------
    numpy.ndarray, shape (N, 4)
        Unit quaternions q_nb (w, x, y, z), Hamilton, body → navigation.
    """
    t = as_vector(t, "t")
    beta, rate = _cone(cone_angle, cone_rate)
    c, s = math.cos(0.5 * beta), math.sin(0.5 * beta)
    return np.stack([np.full_like(t, c), s * np.cos(rate * t), s * np.sin(rate * t), np.zeros_like(t)], -1)


def coning_rate(t, cone_angle, cone_rate) -> np.ndarray:
    """Body angular rate ω(t) = 2 vec(q* ⊗ q̇) of :func:`coning_attitude`, in closed form.

    ω(t) = (−Ω sin β sin Ω t, Ω sin β cos Ω t, −2 Ω sin²(β/2)): its x–y part turns at Ω, so
    ω_k × ω_{k+1} ≠ 0 on every step (the axis of rotation moves: coning).

    Parameters
    ----------
    t : array_like, shape (N,)
        Times, s.
    cone_angle, cone_rate : float
        β (rad) and Ω (rad/s), as in :func:`coning_attitude`.

    Returns
    -------
    numpy.ndarray, shape (N, 3)
        ω in the body frame, rad/s.
    """
    t = as_vector(t, "t")
    beta, rate = _cone(cone_angle, cone_rate)
    amplitude = rate * math.sin(beta)
    return np.stack([-amplitude * np.sin(rate * t), amplitude * np.cos(rate * t),
                     np.full_like(t, -2.0 * rate * math.sin(0.5 * beta) ** 2)], -1)


def coning_rate_integral(t, cone_angle, cone_rate) -> np.ndarray:
    """∫ ω dt of :func:`coning_rate` over each interval [t_k, t_{k+1}], in closed form.

    What an IMU that outputs angle increments ("delta angles") would report: the exact
    integral, where the trapezoid ½(ω_k + ω_{k+1}) T misses the rate's curvature.

    Parameters
    ----------
    t : array_like, shape (N,)
        Interval ends, s, strictly increasing, N ≥ 2.
    cone_angle, cone_rate : float
        β (rad) and Ω (rad/s).

    Returns
    -------
    numpy.ndarray, shape (N − 1, 3)
        Rotation-vector increments, rad.
    """
    t = _times(t)
    if len(t) < 2:
        raise ValueError("t must hold at least two times (one interval)")
    beta, rate = _cone(cone_angle, cone_rate)
    t0, t1 = t[:-1], t[1:]
    s = math.sin(beta)
    return np.stack([s * (np.cos(rate * t1) - np.cos(rate * t0)), s * (np.sin(rate * t1) - np.sin(rate * t0)),
                     -2.0 * rate * math.sin(0.5 * beta) ** 2 * (t1 - t0)], -1)


def _q_times_pure(q, w) -> tuple[float, float, float, float]:
    """q ⊗ (0, w) for a quaternion q and a vector w given as float tuples."""
    qw, qx, qy, qz = q
    wx, wy, wz = w
    return (-qx * wx - qy * wy - qz * wz, qw * wx + qy * wz - qz * wy,
            qw * wy - qx * wz + qz * wx, qw * wz + qx * wy - qy * wx)


def reference_attitude(rate, t, q0, substeps: int = 8) -> np.ndarray:
    """High-accuracy solution of q̇ = ½ q ⊗ (0, ω(t)) by classical Runge–Kutta (RK4).

    An independent reference for the rules of :data:`RULES`: a fourth-order method of a
    different family, evaluating ω between the samples, with ``substeps`` RK4 steps per
    interval of ``t``; the result is normalised at each output time only.

    Parameters
    ----------
    rate : callable
        ω(t): a float time in s → array_like (3,), body frame, rad/s.
    t : array_like, shape (N,)
        Output times, s, strictly increasing.
    q0 : array_like, shape (4,)
        Quaternion at ``t[0]`` (normalised here).
    substeps : int
        RK4 steps per output interval (≥ 1).

    Returns
    -------
    numpy.ndarray, shape (N, 4)
        Unit quaternions at ``t``.
    """
    if not callable(rate):
        raise ValueError(f"rate must be a callable t -> omega (3,), got {type(rate).__name__}")
    t = _times(t)
    q = _unit(q0, "q0")
    if isinstance(substeps, (bool, np.bool_)) or not isinstance(substeps, (int, np.integer)) or substeps < 1:
        raise ValueError(f"substeps must be a positive integer, got {substeps!r}")

    def omega(time):
        return tuple(as_vector(rate(time), "rate(t)", 3).tolist())

    out = np.empty((len(t), 4))
    out[0] = q
    state = tuple(q.tolist())
    for k in range(len(t) - 1):
        h = (t[k + 1] - t[k]) / substeps
        for j in range(substeps):
            s = t[k] + j * h
            # stages of q̇ = ½ q ⊗ (0, ω), the ½ folded into the weights
            k1 = _q_times_pure(state, omega(s))
            w_mid = omega(s + 0.5 * h)
            k2 = _q_times_pure(tuple(a + 0.25 * h * b for a, b in zip(state, k1)), w_mid)
            k3 = _q_times_pure(tuple(a + 0.25 * h * b for a, b in zip(state, k2)), w_mid)
            k4 = _q_times_pure(tuple(a + 0.5 * h * b for a, b in zip(state, k3)), omega(s + h))
            state = tuple(a + h / 12.0 * (b1 + 2.0 * b2 + 2.0 * b3 + b4)
                          for a, b1, b2, b3, b4 in zip(state, k1, k2, k3, k4))
        norm = math.sqrt(sum(a * a for a in state))
        out[k + 1] = [a / norm for a in state]
    return out


def _unit(q, name: str) -> np.ndarray:
    """q / |q| for a quaternion argument (4,), with errors that name the argument."""
    q = as_vector(q, name, 4)
    n = float(np.linalg.norm(q))
    if n == 0.0:
        raise ValueError(f"{name} must be a non-zero quaternion (w, x, y, z), got norm 0")
    return q / n


def _rule(rule) -> str:
    if rule not in RULES:
        raise ValueError(f"rule must be one of {RULES}, got {rule!r}")
    return rule


def _step(T) -> float:
    return as_scalar(T, "T")


def _steps(T, n: int) -> np.ndarray:
    """T as one positive step per interval, shape (n,): a number for all, or an array (n,)."""
    if np.ndim(T) == 0:
        return np.full(n, _step(T))
    steps = as_vector(T, "T", n)
    if np.any(steps <= 0.0):
        raise ValueError("T must hold positive step lengths (s)")
    return steps


def step_rotation_vectors(w, T, rule, rate_integrals=None) -> np.ndarray:
    """The rotation vector φ_k of each step under a rule that integrates with Exp.

    - ``"zeroth_order"``: φ_k = ω̄_k T = ½(ω_k + ω_{k+1}) T (or the given ∫ω);
    - ``"first_order"``: φ_k = ω̄_k T + T²/12 ω_k × ω_{k+1}, the coning correction added.

    Parameters
    ----------
    w : array_like, shape (n + 1, 3)
        Body rates ω_k at the samples, rad/s.
    T : float or array_like, shape (n,)
        Sample interval, s: one for all steps, or each step's own (real IMU clocks are irregular).
    rule : {"zeroth_order", "first_order"}
    rate_integrals : array_like, shape (n, 3), optional
        ∫ω over each interval (rad), used instead of the trapezoid ½(ω_k + ω_{k+1}) T.

    Returns
    -------
    numpy.ndarray, shape (n, 3)
        φ_k, rad; the step is q_{k+1} = q_k ⊗ Exp_q(φ_k), R_{k+1} = R_k Exp(φ_k).
    """
    w = as_rows(w, "w", (3,))
    if len(w) < 2:
        raise ValueError("w must hold at least two samples (one step)")
    T = _steps(T, len(w) - 1)[:, None]
    if _rule(rule) == "euler":
        raise ValueError("rule 'euler' adds q ⊗ (0, ω) T / 2 and renormalises; it has no rotation vector "
                         "(use integrate_quaternion)")
    if rate_integrals is None:
        phi = 0.5 * (w[:-1] + w[1:]) * T
    else:
        phi = as_rows(rate_integrals, "rate_integrals", (3,), n=len(w) - 1).copy()
    if rule == "first_order":
        phi += (T * T / 12.0) * np.cross(w[:-1], w[1:])
    return phi


def sola_increment(w0, w1, T) -> np.ndarray:
    """Solà's quaternion form of the first-order step: Exp_q(ω̄ T) + T²/24 (0, ω_k × ω_{k+1}), normalised.

    A small rotation vector φ enters a quaternion as (1, φ/2), so the rotation-vector
    correction T²/12 ω_k × ω_{k+1} of :func:`step_rotation_vectors` appears here halved and
    added to the quaternion instead of inside the exponential.

    Parameters
    ----------
    w0, w1 : array_like, shape (3,)
        ω_k and ω_{k+1}, body frame, rad/s.
    T : float
        The step, s.

    Returns
    -------
    numpy.ndarray, shape (4,)
        The unit increment δq_k (the step is q_{k+1} = q_k ⊗ δq_k).
    """
    w0, w1, T = as_vector(w0, "w0", 3), as_vector(w1, "w1", 3), _step(T)
    dq = so3.quat_exp(0.5 * (w0 + w1) * T)
    dq[1:] += (T * T / 24.0) * np.cross(w0, w1)
    return dq / np.linalg.norm(dq)


def local_errors(rate0, rate_change, steps, substeps: int = 64) -> dict[str, np.ndarray]:
    """Error of one step of each Exp rule on a rate linear in time, for several step lengths.

    The rate is ω(t) = ω₀ + ω̇ t on [0, T]; the true attitude at T comes from
    :func:`reference_attitude` (``substeps`` RK4 steps), starting from the identity.

    Parameters
    ----------
    rate0 : array_like, shape (3,)
        ω₀, rad/s.
    rate_change : array_like, shape (3,)
        ω̇, rad/s².
    steps : array_like, shape (n,)
        Step lengths T, s.
    substeps : int
        RK4 steps of the reference per step.

    Returns
    -------
    dict of str to numpy.ndarray, each shape (n,)
        "zeroth_order" and "first_order": angle to the reference, rad; "sola_vs_exp": angle
        between Solà's quaternion form (:func:`sola_increment`) and the first-order Exp form.
    """
    w0 = as_vector(rate0, "rate0", 3)
    w_dot = as_vector(rate_change, "rate_change", 3)
    steps = as_vector(steps, "steps")
    if np.any(steps <= 0.0):
        raise ValueError("steps must be positive step lengths (s)")
    identity = np.array([1.0, 0.0, 0.0, 0.0])
    out = {"zeroth_order": [], "first_order": [], "sola_vs_exp": []}
    for T in steps:
        truth = reference_attitude(lambda s: w0 + s * w_dot, [0.0, T], identity, substeps)[-1]
        w = np.stack([w0, w0 + T * w_dot])
        for rule in ("zeroth_order", "first_order"):
            out[rule].append(float(attitude_error(integrate_quaternion(identity, w, T, rule)[-1], truth)))
        exp_form = so3.quat_exp(step_rotation_vectors(w, T, "first_order")[0])
        out["sola_vs_exp"].append(float(attitude_error(sola_increment(w[0], w[1], T), exp_form)))
    return {k: np.array(v) for k, v in out.items()}


def integrate_quaternion(q0, w, T, rule, rate_integrals=None) -> np.ndarray:
    """Integrate the attitude quaternion over the samples with one of :data:`RULES`.

    Each step is q_{k+1} = (q_k ⊗ δq_k) / |q_k ⊗ δq_k| with δq_k = (1, ½ ω_k T) for
    ``"euler"`` (that is, q_k + ½ T q_k ⊗ (0, ω_k), renormalised) and δq_k = Exp_q(φ_k) of
    :func:`step_rotation_vectors` otherwise (a unit quaternion: the division only removes
    round-off).

    Parameters
    ----------
    q0 : array_like, shape (4,)
        Attitude at the first sample (normalised here).
    w : array_like, shape (n + 1, 3)
        Body rates ω_k, rad/s.
    T : float or array_like, shape (n,)
        Sample interval(s), s.
    rule : str
        One of :data:`RULES`.
    rate_integrals : array_like, shape (n, 3), optional
        ∫ω per interval for the Exp rules (see :func:`step_rotation_vectors`).

    Returns
    -------
    numpy.ndarray, shape (n + 1, 4)
        q_k, unit quaternions.
    """
    q = _unit(q0, "q0")
    w = as_rows(w, "w", (3,))
    if len(w) < 2:
        raise ValueError("w must hold at least two samples (one step)")
    if _rule(rule) == "euler":
        if rate_integrals is not None:
            raise ValueError("rate_integrals is for the Exp rules; rule 'euler' uses the rate at each step's start")
        T = _steps(T, len(w) - 1)[:, None]
        increments = np.concatenate([np.ones((len(w) - 1, 1)), 0.5 * T * w[:-1]], axis=1)
    else:
        increments = so3.quat_exp(step_rotation_vectors(w, T, rule, rate_integrals))
    out = np.empty((len(w), 4))
    out[0] = q
    for k, dq in enumerate(increments):
        p = so3.quat_multiply(out[k], dq)
        out[k + 1] = p / math.sqrt(float(p @ p))
    return out


def integrate_rotation_matrix(R0, w, T, rule, rate_integrals=None) -> np.ndarray:
    """The rotation-matrix twin of :func:`integrate_quaternion` for the Exp rules.

    R_{k+1} = R_k Exp(φ_k), φ_k from :func:`step_rotation_vectors`. The same rule as the
    quaternion version, written with the other representation: the two agree to round-off.

    Parameters
    ----------
    R0 : array_like, shape (3, 3)
        R_nb at the first sample.
    w : array_like, shape (n + 1, 3)
        Body rates, rad/s.
    T : float or array_like, shape (n,)
        Sample interval(s), s.
    rule : {"zeroth_order", "first_order"}
    rate_integrals : array_like, shape (n, 3), optional
        ∫ω per interval.

    Returns
    -------
    numpy.ndarray, shape (n + 1, 3, 3)
    """
    R0 = as_rotation(R0, "R0")
    steps = so3.exp(step_rotation_vectors(w, T, rule, rate_integrals))
    out = np.empty((len(steps) + 1, 3, 3))
    out[0] = R0
    for k, step in enumerate(steps):
        np.dot(out[k], step, out=out[k + 1])
    return out


def attitude_error(q_est, q_true) -> np.ndarray:
    """Angle of the rotation between two attitudes, 2 atan2(|vec(q_true* ⊗ q_est)|, |scalar|).

    Parameters
    ----------
    q_est, q_true : array_like, shape (N, 4) or (4,)
        Quaternions (normalised here); q and −q are the same attitude.

    Returns
    -------
    numpy.ndarray, shape (N,) or ()
        Angles in [0, π], rad.
    """
    q_est, q_true = _quaternions(q_est, "q_est"), _quaternions(q_true, "q_true")
    if q_est.shape != q_true.shape and q_est.ndim == q_true.ndim == 2:
        raise ValueError(f"q_est and q_true must have the same number of rows, got {q_est.shape} and {q_true.shape}")
    d = so3.quat_multiply(so3.quat_conjugate(so3.quat_normalise(q_true)), so3.quat_normalise(q_est))
    return 2.0 * np.arctan2(np.linalg.norm(d[..., 1:], axis=-1), np.abs(d[..., 0]))


def _quaternions(q, name: str) -> np.ndarray:
    """A quaternion (4,) or a stack (N, 4), finite and non-zero; errors name ``name``."""
    q = as_real_array(q, name)
    if q.ndim not in (1, 2) or q.shape[-1] != 4:
        raise ValueError(f"{name} must have shape (4,) or (N, 4), got {q.shape}")
    if not np.isfinite(q).all():
        raise ValueError(f"{name} must be finite, got NaN or inf")
    if (np.linalg.norm(q, axis=-1) == 0.0).any():
        raise ValueError(f"{name} must not hold a zero quaternion")
    return q


def _strides(strides) -> list[int]:
    try:
        out = [int(s) for s in strides]
    except (TypeError, ValueError):
        raise ValueError(f"strides must be positive integers, got {strides!r}") from None
    if not out or any(s < 1 or s != x for s, x in zip(out, strides)):
        raise ValueError(f"strides must be a non-empty sequence of positive integers, got {strides!r}")
    return out


def max_attitude_errors(q_true, w, T, rule, strides=(1, 2, 4, 8), rate_integrals=None) -> np.ndarray:
    """Largest attitude error of a rule on the same motion sampled ever more coarsely.

    The finest grid has its samples ``T`` apart; stride m keeps every m-th sample (step
    m T). Each grid is integrated from the true attitude at its first sample and compared
    with the truth at every one of its samples; the largest angle is returned.

    Parameters
    ----------
    q_true : array_like, shape (N, 4)
        True attitude at the samples of the finest grid.
    w : array_like, shape (N, 3)
        True body rates at the same samples, rad/s.
    T : float
        Interval of the finest grid, s.
    rule : str
        One of :data:`RULES`.
    strides : sequence of int
        Sample strides m; (N − 1) must be a multiple of each.
    rate_integrals : array_like, shape (N − 1, 3), optional
        Exact ∫ω over each fine interval (summed m at a time for stride m).

    Returns
    -------
    numpy.ndarray, shape (len(strides),)
        max_k angle(q_est,k, q_true,k), rad.
    """
    w = as_rows(w, "w", (3,))
    q_true = as_rows(q_true, "q_true", (4,), n=len(w))
    T = _step(T)
    strides = _strides(strides)
    if rate_integrals is not None:
        rate_integrals = as_rows(rate_integrals, "rate_integrals", (3,), n=len(w) - 1)
    errors = []
    for m in strides:
        if (len(w) - 1) % m:
            raise ValueError(f"strides: {len(w) - 1} intervals are not a multiple of stride {m}")
        incs = None if rate_integrals is None else rate_integrals.reshape(-1, m, 3).sum(axis=1)
        q = integrate_quaternion(q_true[0], w[::m], m * T, rule, incs)
        errors.append(float(attitude_error(q, q_true[::m]).max()))
    return np.array(errors)


def halving_ratios(errors) -> np.ndarray:
    """e(2T) / e(T) for errors at steps T, 2T, 4T, ...: about 2^p for a rule of order p.

    Parameters
    ----------
    errors : array_like, shape (n,)
        Positive errors at successively doubled steps, n ≥ 2.

    Returns
    -------
    numpy.ndarray, shape (n − 1,)
    """
    e = as_vector(errors, "errors")
    if len(e) < 2 or np.any(e <= 0.0):
        raise ValueError("errors must hold at least two positive numbers")
    return e[1:] / e[:-1]


def loglog_slope(steps, errors) -> float:
    """Least-squares slope of log(error) against log(step): the measured order p.

    Parameters
    ----------
    steps, errors : array_like, shape (n,)
        Positive step sizes and the errors at them, n ≥ 2, steps not all equal.

    Returns
    -------
    float
    """
    h = as_vector(steps, "steps")
    e = as_vector(errors, "errors", len(h))
    if len(h) < 2 or np.any(h <= 0.0) or np.any(e <= 0.0) or np.ptp(h) == 0.0:
        raise ValueError("steps and errors must hold at least two positive numbers, steps not all equal")
    return float(np.polyfit(np.log(h), np.log(e), 1)[0])


def coning_correction_residual() -> tuple[sp.Matrix, sp.Matrix]:
    """SymPy check of the first-order rule's two terms for a rate linear over the step.

    With φ̇ = J_r⁻¹(φ) ω ≈ ω + ½ φ × ω and φ(t) ≈ ∫₀ᵗ ω, the rotation vector of a step is
    φ(T) ≈ ∫₀ᵀ ω dt + ½ ∫₀ᵀ (∫₀ᵗ ω ds) × ω(t) dt. For ω(t) = ω_k + (ω_{k+1} − ω_k) t/T the
    first term is ½(ω_k + ω_{k+1}) T and the second T²/12 ω_k × ω_{k+1}.

    Returns
    -------
    (sympy.Matrix, sympy.Matrix), each (3, 1)
        ∫ω − ½(ω_k + ω_{k+1}) T and ½∫(∫ω) × ω − T²/12 ω_k × ω_{k+1}, simplified: both zero
        when the formulas hold, for symbolic ω_k, ω_{k+1} and T.
    """
    T, t, s = sp.symbols("T t s", positive=True)
    w0 = sp.Matrix(sp.symbols("omega_k_x omega_k_y omega_k_z", real=True))
    w1 = sp.Matrix(sp.symbols("omega_k1_x omega_k1_y omega_k1_z", real=True))

    def omega(x):
        return w0 + (w1 - w0) * x / T

    first = omega(t).integrate((t, 0, T))
    angle_so_far = omega(s).integrate((s, 0, t))
    second = (sp.Rational(1, 2) * angle_so_far.cross(omega(t))).integrate((t, 0, T))
    return (sp.simplify(first - (w0 + w1) * T / 2),
            sp.simplify(second - T ** 2 / 12 * w0.cross(w1)))


# ---------------------------------------------------------------------------------------
# §7 — the flat, non-rotating frame: what it leaves out, and how big that is
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class DriveExtent:
    """The size of a drive, measured on its ground truth.

    Attributes
    ----------
    duration : float
        t_last − t_first, s.
    top_speed : float
        max |v|, m/s.
    mean_speed : float
        Path length / duration, m/s.
    path_length : float
        Σ |p_{k+1} − p_k|, m.
    max_distance : float
        d, the largest horizontal distance from the start, m.
    height_range : float
        Δh = max z − min z, m.
    """

    duration: float
    top_speed: float
    mean_speed: float
    path_length: float
    max_distance: float
    height_range: float


def drive_extent(truth) -> DriveExtent:
    """Measure a drive's duration, speeds and extent from its ground truth.

    Parameters
    ----------
    truth : object
        With ``t`` (K,) s, ``position`` (K, 3) m and ``velocity`` (K, 3) m/s in a z-up
        navigation frame, K ≥ 2; for example ``load_kitti("seq00").truth``.

    Returns
    -------
    DriveExtent
    """
    for field in ("t", "position", "velocity"):
        if not hasattr(truth, field):
            raise ValueError(f"truth must have t (K,), position (K, 3) and velocity (K, 3); missing {field!r}")
    t = _times(truth.t, "truth.t")
    if len(t) < 2:
        raise ValueError("truth.t must hold at least two times")
    p = as_matrix(truth.position, "truth.position", (len(t), 3))
    v = as_matrix(truth.velocity, "truth.velocity", (len(t), 3))
    duration = float(t[-1] - t[0])
    path = float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())
    return DriveExtent(duration=duration, top_speed=float(np.linalg.norm(v, axis=1).max()),
                       mean_speed=path / duration, path_length=path,
                       max_distance=float(np.linalg.norm(p[:, :2] - p[0, :2], axis=1).max()),
                       height_range=float(np.ptp(p[:, 2])))


#: The error channels of :func:`position_error_growth`: how an error reaches the position.
CHANNELS = ("acceleration", "tilt_rate", "heading_rate", "accel_white", "gyro_white",
            "accel_bias_walk", "gyro_bias_walk")

#: channel -> p, the position error of :func:`position_error_growth` grows as t^p.
GROWTH_POWER = {"acceleration": 2.0, "tilt_rate": 3.0, "heading_rate": 2.0, "accel_white": 1.5,
                "gyro_white": 2.5, "accel_bias_walk": 2.5, "gyro_bias_walk": 3.5}


@dataclass(frozen=True)
class ErrorSource:
    """One error source of the budget: a term the mechanisation neglects, or an IMU error.

    Attributes
    ----------
    name : str
        Short label.
    what : str
        What it is and how its size is computed.
    source : str
        Where the number comes from: "computed constant" (physical constants and the
        latitude), "computed from real truth" (constants and the KITTI ground truth),
        "course config (yaml)" (kitti_lidar.yaml), "IMU metadata (data)" (the noise densities
        shipped with the KITTI IMU record), "ESKF: real IMU, sim. lidar" (the filter's σ at
        the end of a run on the real IMU with simulated lidar poses).
    size : float
        Its size in SI units: rad/s, m/s² for constants; a density for white noises
        (m/s²/√Hz, rad/s/√Hz) and bias random walks (m/s³/√Hz, rad/s²/√Hz).
    unit : str
        The unit of ``size``.
    channel : str
        How it reaches the position (one of :data:`CHANNELS`).
    """

    name: str
    what: str
    source: str
    size: float
    unit: str
    channel: str


def _gravity(gravity) -> float:
    if np.ndim(gravity) == 0:
        return as_scalar(gravity, "gravity")
    g = float(np.linalg.norm(as_vector(gravity, "gravity", 3)))
    if g == 0.0:
        raise ValueError("gravity must be a non-zero vector")
    return g


def neglected_terms(latitude_deg, extent: DriveExtent, gravity, radius=EARTH_RADIUS,
                    rate=EARTH_RATE) -> dict[str, ErrorSource]:
    """Size of each term the flat, non-rotating navigation frame neglects, for one drive.

    - Earth rate about up, Ω sin φ: a rate the gyro senses and the frame does not turn by;
      it turns the heading (channel ``heading_rate``);
    - Earth rate about north, Ω cos φ: the same about a horizontal axis; it tilts the
      attitude (``tilt_rate``);
    - Coriolis, |2 Ω × v| ≤ 2 Ω v_max (equality for an east–west velocity; its horizontal
      part is 2 Ω sin φ v for any heading): an acceleration (``acceleration``);
    - transport rate, v_max / R_E: how fast a local-level frame would have to turn to stay
      level while driving (``tilt_rate``);
    - direction of gravity, g d / R_E: the horizontal part of the true gravity at the
      drive's largest distance d from the start, where the plumb line is tilted by d / R_E
      against the start's (``acceleration``; the transport rate's effect seen from a frame
      fixed at the start, so not to be added to it);
    - magnitude of gravity, 2 g Δh / R_E: the free-air change over the drive's height range
      Δh (``acceleration``).

    Parameters
    ----------
    latitude_deg : float
        Geodetic latitude φ, degrees (Karlsruhe, where KITTI drove: about 49.0).
    extent : DriveExtent
        The drive's top speed v_max, largest distance d and height range Δh.
    gravity : float or array_like (3,)
        g, m/s² (a vector's norm is used).
    radius : float
        R_E, m.
    rate : float
        Ω_E, rad/s.

    Returns
    -------
    dict of str to ErrorSource
        Keyed "earth_rate_up", "earth_rate_north", "coriolis", "transport_rate",
        "gravity_direction", "gravity_magnitude"; every size is a magnitude (≥ 0; south of
        the equator Ω sin φ is negative, its size is |Ω sin φ|).
    """
    if not isinstance(extent, DriveExtent):
        raise ValueError(f"extent must be a DriveExtent (see drive_extent), got {type(extent).__name__}")
    g = _gravity(gravity)
    R = as_scalar(radius, "radius")
    earth = earth_rate(latitude_deg, rate)
    v, d, dh = extent.top_speed, extent.max_distance, extent.height_range
    terms = [
        ErrorSource("earth_rate_up", "Earth rate about up, Ω sin φ", "computed constant", abs(earth.vertical),
                    "rad/s", "heading_rate"),
        ErrorSource("earth_rate_north", "Earth rate about north, Ω cos φ", "computed constant", earth.horizontal,
                    "rad/s", "tilt_rate"),
        ErrorSource("coriolis", "Coriolis, 2Ω v at the top speed", "computed from real truth", 2.0 * earth.total * v,
                    "m/s^2", "acceleration"),
        ErrorSource("transport_rate", "transport rate, v/R_E at the top speed", "computed from real truth",
                    v / R, "rad/s", "tilt_rate"),
        ErrorSource("gravity_direction", "gravity's direction, g d/R_E", "computed from real truth",
                    g * d / R, "m/s^2", "acceleration"),
        ErrorSource("gravity_magnitude", "gravity's magnitude, 2g Δh/R_E", "computed from real truth",
                    2.0 * g * dh / R, "m/s^2", "acceleration"),
    ]
    return {term.name: term for term in terms}


def imu_error_sources(config, metadata=None, filter_std=None) -> dict[str, ErrorSource]:
    """The IMU's own error sources as the course models them, in the budget's terms.

    Parameters
    ----------
    config : EskfConfig
        The filter's settings (``load_config("kitti_lidar")``): the white-noise densities of
        the accelerometer (m/s²/√Hz) and gyroscope (rad/s/√Hz) and the bias random-walk
        densities (m/s³/√Hz, rad/s²/√Hz).
    metadata : mapping, optional
        The densities the data ship with (keys "accel" and "gyro", same units; KITTI's
        ``provenance["imu"]["metadata_noise_densities"]``): rows for the white noises the
        configuration inflated.
    filter_std : array_like, shape (15,), optional
        σ of the ESKF's error state [δp, δv, δθ, δb_a, δb_ω] at the end of a run: rows for
        the accelerometer- and gyro-bias σ the filter reaches (the larger horizontal axis,
        x or y: on a level car these tilt the attitude).

    Returns
    -------
    dict of str to ErrorSource
        "accel_white", "gyro_white", "accel_bias_walk", "gyro_bias_walk", then
        "accel_white_metadata", "gyro_white_metadata" and "accel_bias_sigma",
        "gyro_bias_sigma" when given.
    """
    if not hasattr(config, "si"):
        raise ValueError(f"config must be an EskfConfig (load_config), got {type(config).__name__}")
    model = "course config (yaml)"
    rows = [
        ErrorSource("accel_white", "accelerometer white noise n_a", model,
                    config.si("process.accel_noise"), "m/s^2/sqrt(Hz)", "accel_white"),
        ErrorSource("gyro_white", "gyroscope white noise n_ω", model,
                    config.si("process.gyro_noise"), "rad/s/sqrt(Hz)", "gyro_white"),
        ErrorSource("accel_bias_walk", "accelerometer-bias random walk n_ba", model,
                    config.si("process.accel_bias_noise"), "m/s^3/sqrt(Hz)", "accel_bias_walk"),
        ErrorSource("gyro_bias_walk", "gyro-bias random walk n_bω", model,
                    config.si("process.gyro_bias_noise"), "rad/s^2/sqrt(Hz)", "gyro_bias_walk"),
    ]
    if metadata is not None:
        if not hasattr(metadata, "get") or "accel" not in metadata or "gyro" not in metadata:
            raise ValueError("metadata must be a mapping with the densities 'accel' and 'gyro'")
        rows += [
            ErrorSource("accel_white_metadata", "accelerometer white noise n_a", "IMU metadata (data)",
                        as_scalar(metadata["accel"], "metadata['accel']"), "m/s^2/sqrt(Hz)", "accel_white"),
            ErrorSource("gyro_white_metadata", "gyroscope white noise n_ω", "IMU metadata (data)",
                        as_scalar(metadata["gyro"], "metadata['gyro']"), "rad/s/sqrt(Hz)", "gyro_white"),
        ]
    if filter_std is not None:
        std = as_vector(filter_std, "filter_std", 15)
        rows += [
            ErrorSource("accel_bias_sigma", "accelerometer-bias σ reached (x, y)", "ESKF: real IMU, sim. lidar",
                        float(std[9:11].max()), "m/s^2", "acceleration"),
            ErrorSource("gyro_bias_sigma", "gyro-bias σ reached (x, y)", "ESKF: real IMU, sim. lidar",
                        float(std[12:14].max()), "rad/s", "tilt_rate"),
        ]
    return {row.name: row for row in rows}


def error_budget(sources, horizons, *, gravity=9.8092, speed=None) -> np.ndarray:
    """Position error of each source after each horizon (:func:`position_error_growth`).

    Parameters
    ----------
    sources : sequence of ErrorSource
        The rows.
    horizons : array_like, shape (H,)
        Horizons t, s.
    gravity : float
        g, m/s².
    speed : float, optional
        v, m/s, for the sources in the ``heading_rate`` channel.

    Returns
    -------
    numpy.ndarray, shape (len(sources), H)
        Metres (a σ for the white-noise rows).
    """
    sources = list(sources)
    if not sources or not all(isinstance(s, ErrorSource) for s in sources):
        raise ValueError("sources must be a non-empty sequence of ErrorSource")
    t = as_vector(horizons, "horizons")
    return np.array([position_error_growth(s.channel, s.size, t, gravity=gravity,
                                           speed=speed if s.channel == "heading_rate" else None)
                     for s in sources])


def _channel(channel) -> str:
    if channel not in CHANNELS:
        raise ValueError(f"channel must be one of {CHANNELS}, got {channel!r}")
    return channel


def _horizon(t) -> np.ndarray:
    try:
        arr = np.asarray(t, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"t must be a horizon in s or an array of them, got {t!r}") from None
    if not np.isfinite(arr).all() or np.any(arr < 0.0):
        raise ValueError(f"t must be finite and non-negative, got {t!r}")
    return arr


def position_error_growth(channel, size, t, *, gravity=9.8092, speed=None):
    """Position error after a horizon t of unaided integration, from one error source.

    Deterministic sources (the error itself):

    - ``acceleration`` a (m/s²), constant: ½ a t²;
    - ``tilt_rate`` ω (rad/s), constant: the tilt grows as ω t and tips gravity into the
      horizontal, g ω t, so the position error is g ω t³ / 6;
    - ``heading_rate`` ω (rad/s), constant: the heading grows as ω t and turns the velocity
      v by it, so the cross-track error is ½ v ω t² (``speed`` v needed).

    White-noise sources (the standard deviation, per axis), from a density σ:

    - ``accel_white`` σ (m/s²/√Hz): σ t^{3/2} / √3;
    - ``gyro_white`` σ (rad/s/√Hz), through the tilt: g σ t^{5/2} / √20;
    - ``accel_bias_walk`` σ (m/s³/√Hz): σ t^{5/2} / √20;
    - ``gyro_bias_walk`` σ (rad/s²/√Hz), through the tilt: g σ t^{7/2} / √252.

    Parameters
    ----------
    channel : str
        One of :data:`CHANNELS`.
    size : float
        The source's size in SI units (see above), ≥ 0.
    t : float or array_like
        Horizon(s), s, ≥ 0.
    gravity : float
        g, m/s², for the channels that go through the tilt.
    speed : float, optional
        v, m/s, for ``heading_rate`` (and only for it).

    Returns
    -------
    float or numpy.ndarray (shape of ``t``)
        Position error (or its σ), m.
    """
    channel = _channel(channel)
    a = as_scalar(size, "size", allow_zero=True)
    g = as_scalar(gravity, "gravity")
    t = _horizon(t)
    if channel == "heading_rate":
        if speed is None:
            raise ValueError("speed is needed for the heading_rate channel (the velocity the heading turns)")
        v = as_scalar(speed, "speed", allow_zero=True)
    elif speed is not None:
        raise ValueError(f"speed is only used by the heading_rate channel, not {channel!r}")
    out = {
        "acceleration": lambda: 0.5 * a * t ** 2,
        "tilt_rate": lambda: g * a * t ** 3 / 6.0,
        "heading_rate": lambda: 0.5 * v * a * t ** 2,
        "accel_white": lambda: a * t ** 1.5 / math.sqrt(3.0),
        "gyro_white": lambda: g * a * t ** 2.5 / math.sqrt(20.0),
        "accel_bias_walk": lambda: a * t ** 2.5 / math.sqrt(20.0),
        "gyro_bias_walk": lambda: g * a * t ** 3.5 / math.sqrt(252.0),
    }[channel]()
    return float(out) if out.ndim == 0 else out


def _nilpotent_exp(M: np.ndarray) -> np.ndarray:
    """exp(M) of a nilpotent matrix, as its power series (finite, hence exact up to round-off)."""
    out = np.eye(len(M))
    term = np.eye(len(M))
    for k in range(1, len(M) + 1):
        term = term @ M / k
        out += term
    if np.abs(term @ M).max() != 0.0:
        raise ValueError("M must be nilpotent")
    return out


#: channel -> (gain of each link of the integrator chain from the source to p, source is noise)
_CHAINS = {
    "acceleration": (("1", "1"), False), "tilt_rate": (("g", "1", "1"), False),
    "heading_rate": (("v", "1"), False), "accel_white": (("1", "1"), True),
    "gyro_white": (("g", "1", "1"), True), "accel_bias_walk": (("1", "1", "1"), True),
    "gyro_bias_walk": (("1", "g", "1", "1"), True),
}


def chain_position_error(channel, size, t, *, gravity=9.8092, speed=None) -> float:
    """:func:`position_error_growth` computed another way: from the linear error chain.

    The source drives a chain of integrators x_0 → x_1 → … → p (for ``gyro_white``:
    n_ω → δθ → δv → δp, the δθ → δv link with gain g); the chain's matrix F is nilpotent,
    so exp(F t) is a finite sum. A constant source is a state with zero derivative and
    p(t) = [exp(F t) x(0)]_p; a white-noise source gives the variance of p through Van
    Loan's matrix exp([[−F, Q], [0, Fᵀ]] t). No closed form is used.

    Parameters
    ----------
    channel, size, t, gravity, speed
        As in :func:`position_error_growth`; ``t`` a single horizon; ``speed`` is read only
        by ``heading_rate``.

    Returns
    -------
    float
        Position error (or its σ), m.
    """
    channel = _channel(channel)
    a = as_scalar(size, "size", allow_zero=True)
    g = as_scalar(gravity, "gravity")
    horizon = as_scalar(t, "t", allow_zero=True)
    v = as_scalar(speed, "speed", allow_zero=True) if channel == "heading_rate" else 0.0
    gains, noise = _CHAINS[channel]
    value = {"1": 1.0, "g": g, "v": v}
    n = len(gains) + 1                   # source, the integrated states, p last
    F = np.zeros((n, n))
    for i, gain in enumerate(gains):
        F[i + 1, i] = value[gain]
    if not noise:
        x0 = np.zeros(n)
        x0[0] = a
        return float((_nilpotent_exp(F * horizon) @ x0)[-1])
    # white noise of density a drives the first integrated state: x_1' = gain_0 n(t), then
    # x_{j+1}' = gain_j x_j down to p; the source itself is no state here
    m = len(gains)
    G = F[1:, 1:]
    Q = np.zeros((m, m))
    Q[0, 0] = (value[gains[0]] * a) ** 2
    vl = np.zeros((2 * m, 2 * m))
    vl[:m, :m] = -G
    vl[:m, m:] = Q
    vl[m:, m:] = G.T
    E = _nilpotent_exp(vl * horizon)
    P = E[m:, m:].T @ E[:m, m:]               # exp(G t) · exp(−G t) ∫ … = ∫ exp(G s) Q exp(Gᵀ s) ds
    return float(math.sqrt(max(P[-1, -1], 0.0)))
