"""Pose errors of a navigation estimate against the ground truth: APE, RPE and pose NEES.

Chapters 08 and 09 of the course score the ESKF (and raw sensor poses) with
:func:`evaluate`. The estimate must be given at times where the truth has a pose, so no
interpolation error enters the score. With e_p = p − p_true and the attitude error
δθ = Log(R_trueᵀ R) (nominal minus true, radians):

- APE (absolute pose error): the RMSE of |e_p| and of the rotation angle |δθ|;
- RPE (relative pose error over Δ seconds): the same for the motion between t and t + Δ,
  expressed in the body frame at t, so that a constant offset does not count;
- pose NEES: [e_p, δθ]ᵀ P⁻¹ [e_p, δθ] with the filter's 6 × 6 [δp, δθ] block of P.
"""

from __future__ import annotations

import numpy as np

from kalman_course.core import so3
from kalman_course.core.validation import as_matrix, as_scalar, as_vector
from kalman_course.evaluation.metrics import normalised_squared, rmse
from kalman_course.evaluation.trajectory import ate_rmse

__all__ = ["evaluate", "POSE_INDEX", "TIME_TOL"]

#: Rows of [δp, δθ] in the ESKF's 15-dimensional error state [δp, δv, δθ, δb_a, δb_g].
POSE_INDEX = np.array([0, 1, 2, 6, 7, 8])

#: An estimate time matches a truth time if they differ by at most this much, s.
TIME_TOL = 1e-6

#: Pairs for the RPE are taken at t and the first time ≥ t + Δ − this slack, s (the
#: timestamps are not exactly regular).
_RPE_SLACK = 1e-3


def _rotations(value, name: str, K: int | None = None) -> np.ndarray:
    """Return ``value`` as K rotation matrices (K, 3, 3) (any K ≥ 1 when K is None).

    A matrix that is not a rotation (scaled, sheared, a reflection) is named by its index,
    ``rotation[12] is a reflection, not a rotation (det = -1, ...)``.
    """
    try:
        R = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a numeric array of shape (K, 3, 3), got {type(value).__name__}") from None
    if R.ndim != 3 or R.shape[1:] != (3, 3) or (K is not None and R.shape[0] != K) or R.shape[0] == 0:
        want = f"({K}, 3, 3), one matrix per time" if K is not None else "(N, 3, 3)"
        raise ValueError(f"{name} must have shape {want}, got {R.shape}")
    return so3.as_rotations(R, name)


def _truth_index(t: np.ndarray, truth_t: np.ndarray) -> np.ndarray:
    """Index into ``truth_t`` of each time in ``t``; ValueError naming the first that has none."""
    k = np.clip(np.searchsorted(truth_t, t - TIME_TOL), 0, len(truth_t) - 1)
    off = np.abs(truth_t[k] - t) > TIME_TOL
    if off.any():
        i = int(np.argmax(off))
        raise ValueError(f"evaluate needs estimates at the truth's times: t[{i}] = {t[i]:.6f} s "
                         f"is not one of truth.t (within {TIME_TOL:g} s)")
    return k


def _rms_angle(R_error: np.ndarray) -> float:
    """RMS rotation angle of the error rotations (N, 3, 3), degrees."""
    theta = so3.angle(R_error, check=False)      # products of validated rotations
    return float(np.rad2deg(rmse(theta, np.zeros_like(theta), axis=None)))


def evaluate(t, position, rotation, truth, P=None, rpe_delta: float = 1.0) -> dict:
    """Pose errors of an estimate against the truth at the same times.

    Parameters
    ----------
    t : array_like, shape (K,)
        Times of the estimate, s; each must be one of ``truth.t`` (within ``TIME_TOL``)
        and they must increase.
    position : array_like, shape (K, 3)
        Estimated position p, navigation frame, m.
    rotation : array_like, shape (K, 3, 3)
        Estimated attitude R (R_nb, body to navigation).
    truth : TruthData
        Anything with ``t`` (N,) s, ``position`` (N, 3) m and ``rotation`` (N, 3, 3),
        for example ``load_kitti("turns").truth``.
    P : array_like, shape (K, 15, 15) or (K, 6, 6), optional
        The filter covariance (or just its [δp, δθ] block), for the 6-dof pose NEES; each
        symmetric positive definite.
    rpe_delta : float
        Time separation Δ of the relative pose error, s; positive.

    Returns
    -------
    dict
        ``ape_position`` (RMSE of |p − p_true|, m), ``ape_attitude_deg`` (RMS rotation angle
        of R_trueᵀ R, degrees), ``rpe_position`` and ``rpe_attitude_deg`` (the same for the
        relative pose over ``rpe_delta``; NaN if no two times are that far apart),
        ``nees_pose`` (mean 6-dof NEES; NaN without P), ``position_error`` (K, 3) = p −
        p_true, ``attitude_error`` (K, 3) = Log(R_trueᵀ R) (nominal − true, rad),
        ``nees`` (K,) (NaN without P), and its two 3-dof blocks ``nees_position`` (K,)
        and ``nees_attitude`` (K,), each from its own block of P (a 6-dof NEES near 6 can
        hide one block above 3 and one below).

    Raises
    ------
    ValueError
        If an argument has the wrong shape or is not finite, a matrix of ``rotation`` or
        ``truth.rotation`` is not a rotation (max |RᵀR − I| above
        :data:`~kalman_course.core.validation.ROTATION_TOL`, or a reflection; the message
        names its index), a time is not one of the truth's, or a covariance is not
        symmetric positive definite.
    """
    t = as_vector(t, "t")
    K = t.shape[0]
    if K == 0:                     # as_vector may let an empty vector through
        raise ValueError("t must not be empty, got shape (0,)")
    if K > 1 and (np.diff(t) <= 0.0).any():
        raise ValueError("t must be strictly increasing")
    p = as_matrix(position, "position", (K, 3))
    R = _rotations(rotation, "rotation", K)
    rpe_delta = as_scalar(rpe_delta, "rpe_delta")
    for attr in ("t", "position", "rotation"):
        if not hasattr(truth, attr):
            raise ValueError(f"truth must have t, position and rotation; missing {attr!r}")

    k = _truth_index(t, np.asarray(truth.t, dtype=float))
    p_true = np.asarray(truth.position, dtype=float)[k]
    R_true = _rotations(truth.rotation, "truth.rotation")[k]
    position_error = p - p_true
    R_error = np.swapaxes(R_true, -1, -2) @ R
    attitude_error = so3.log(R_error, check=False)     # a product of validated rotations
    out = {
        # the absolute trajectory error without alignment: sqrt(mean_k |p_k − p_true,k|²)
        "ape_position": ate_rmse(p, p_true, align="none"),
        "ape_attitude_deg": _rms_angle(R_error),
        "position_error": position_error,
        "attitude_error": attitude_error,
    }

    # relative pose error: the motion from t_i to t_j ≈ t_i + Δ, in the body frame at t_i
    j = np.searchsorted(t, t + rpe_delta - _RPE_SLACK)
    has_pair = j < K
    i, j = np.nonzero(has_pair)[0], j[has_pair]
    if i.size:
        step_true = np.einsum("kji,kj->ki", R_true[i], p_true[j] - p_true[i])
        step_est = np.einsum("kji,kj->ki", R[i], p[j] - p[i])
        turn_true = np.swapaxes(R_true[i], -1, -2) @ R_true[j]
        turn_est = np.swapaxes(R[i], -1, -2) @ R[j]
        out["rpe_position"] = ate_rmse(step_est, step_true, align="none")
        out["rpe_attitude_deg"] = _rms_angle(np.swapaxes(turn_true, -1, -2) @ turn_est)
    else:
        out["rpe_position"] = out["rpe_attitude_deg"] = float("nan")

    if P is not None:
        P = np.asarray(P, dtype=float)
        if P.shape not in ((K, 15, 15), (K, 6, 6)):
            raise ValueError(f"P must have shape ({K}, 15, 15) or ({K}, 6, 6), got {P.shape}")
        P_pose = P if P.shape[-1] == 6 else P[:, POSE_INDEX][:, :, POSE_INDEX]
        # the NEES, through the function nees() is built on (chapter 09 withholds nees itself)
        error = np.concatenate([position_error, attitude_error], axis=1)
        nees = normalised_squared(error, P_pose, "error", "P")
        out["nees"] = nees
        out["nees_pose"] = float(np.mean(nees))
        for key, block in (("nees_position", slice(0, 3)), ("nees_attitude", slice(3, 6))):
            out[key] = normalised_squared(error[:, block], P_pose[:, block, block], "error", "P")
    else:
        for key in ("nees", "nees_position", "nees_attitude"):
            out[key] = np.full(K, np.nan)
        out["nees_pose"] = float("nan")
    return out
