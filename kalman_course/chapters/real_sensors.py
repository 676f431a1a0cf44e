"""Lecture 10 ("Real sensors"): the checks of the formulas it shows.

The chapter's experiments live in their own modules (:mod:`~kalman_course.chapters.coloured_noise`,
:mod:`~kalman_course.chapters.visual_odometry`, :mod:`~kalman_course.chapters.initialisation`,
:mod:`~kalman_course.chapters.bias_models`). This module holds the few pieces the lecture
needs besides them, so that its cells stay short:

- :func:`normalised_draws` — many independent short draws of an error model, each
  component divided by its σ, for sample checks of the stationary variance, the
  correlation exp(−Δt/τ) and the variance of a mean;
- :func:`mean_variance_factor` — Var(mean of N successive Gauss–Markov errors) / (σ²/N),
  exactly, whose limit is the inflation factor (1 + φ)/(1 − φ);
- :func:`relative_jacobian_by_differences` — the relative-pose residual of §2
  differentiated by central differences in the error state (the check of its Jacobian);
- :func:`segment_errors` — KITTI's drift metric for given segments, written from its
  definition (the check of :func:`kalman_course.evaluation.drift.drift`).

Everything drawn or sampled here is simulated from a seed (error models of
:mod:`kalman_course.data.observation_errors`); nothing reads KITTI data.
"""

from __future__ import annotations

import numpy as np

from kalman_course.core import so3
from kalman_course.core.numdiff import numerical_jacobian
from kalman_course.core.validation import as_matrix, as_rotation, as_rotations, as_rows, as_seed, as_vector
from kalman_course.data.observation_errors import ObservationErrors
from kalman_course.filters.eskf_relative import relative_motion, relative_pose_residual

__all__ = ["normalised_draws", "mean_variance_factor", "relative_jacobian_by_differences",
           "segment_errors"]



# ---------------------------------------------------------------------------------------
# §1: sample checks of the Gauss–Markov formulas
# ---------------------------------------------------------------------------------------

def normalised_draws(model: ObservationErrors, t, repeats: int, seed: int) -> np.ndarray:
    """Many independent draws of ``model`` at ``t``, each component divided by its σ.

    Parameters
    ----------
    model : WhiteErrors or GaussMarkovErrors
        The error model (σ's positive).
    t : array_like, shape (K,)
        Observation times, s, strictly increasing.
    repeats : int
        Independent draws, each from the same generator in turn.
    seed : int
        Seed of ``numpy.random.default_rng``.

    Returns
    -------
    numpy.ndarray, shape (6 · repeats, K)
        One row per component and draw: e / σ, which for a stationary model has unit
        variance at every time. The six components of a draw are independent, so the
        rows are 6 · repeats independent sequences.
    """
    if not isinstance(model, ObservationErrors):
        raise ValueError(f"model must be an error model (WhiteErrors, GaussMarkovErrors), got {type(model).__name__}")
    sigma = np.r_[np.full(3, model.sigma_position), np.full(3, np.deg2rad(model.sigma_attitude_deg))]
    if (sigma <= 0.0).any():
        raise ValueError("model must have positive sigma_position and sigma_attitude_deg to normalise by them")
    if isinstance(repeats, bool) or not isinstance(repeats, (int, np.integer)) or repeats < 1:
        raise ValueError(f"repeats must be a positive integer, got {repeats!r}")
    rng = np.random.default_rng(as_seed(seed))
    t = as_rows(t, "t")
    rows = [(model.draw(t, rng).error / sigma).T for _ in range(int(repeats))]
    return np.concatenate(rows, axis=0)


def mean_variance_factor(phi: float, n: int) -> float:
    """Var(mean of n successive errors) / (σ²/n) for a stationary AR(1) error with coefficient φ.

    Successive errors correlate as Cov(e_i, e_j) = σ² φ^|i−j|, so

        Var(ē) = σ²/n · [1 + 2 Σ_{j=1}^{n−1} (1 − j/n) φ^j],

    the bracket is returned. It is 1 for white errors (φ = 0) and tends to
    (1 + φ)/(1 − φ) as n → ∞ (:func:`kalman_course.chapters.coloured_noise.inflation_factor`).

    Parameters
    ----------
    phi : float
        φ = exp(−Δt/τ), in [0, 1).
    n : int
        Number of successive errors averaged, ≥ 1.
    """
    phi = float(as_vector([phi], "phi", 1)[0])
    if not 0.0 <= phi < 1.0:
        raise ValueError(f"phi must lie in [0, 1) (φ = exp(−Δt/τ)), got {phi!r}")
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n must be a positive integer, got {n!r}")
    j = np.arange(1, int(n))
    return float(1.0 + 2.0 * np.sum((1.0 - j / n) * phi ** j))


# ---------------------------------------------------------------------------------------
# §2: the relative-pose Jacobian and the drift metric, checked from their definitions
# ---------------------------------------------------------------------------------------

def relative_jacobian_by_differences(p_clone, R_clone, p_check, R_check, h: float = 1e-6) -> np.ndarray:
    """∂y/∂δx_a (6, 21) of the relative-pose residual, by central differences.

    The nominal clone (p̌_c, Ř_c) and current pose (p̌, Ř) are held fixed; an error
    δx_a = [δp, δv, δθ, δb_a, δb_ω, δp_c, δθ_c] (21) defines the true poses by
    error = nominal − true (p = p̌ − δp, R = Ř Exp(−δθ), the same for the clone), and the
    measurement is the true increment, noise-free. Then y(δx_a) =
    :func:`~kalman_course.filters.eskf_relative.relative_pose_residual` ≈ G_rel δx_a,
    and its numerical Jacobian at 0 is G_rel at the nominal poses.

    Parameters
    ----------
    p_clone, p_check : array_like, shape (3,)
        Nominal positions of the clone and of the current pose, m.
    R_clone, R_check : array_like, shape (3, 3)
        Their nominal attitudes R_nb.
    h : float
        Difference step (m, rad).

    Returns
    -------
    numpy.ndarray, shape (6, 21)
    """
    p_c, p = as_vector(p_clone, "p_clone", 3), as_vector(p_check, "p_check", 3)
    R_c, R = as_rotation(R_clone, "R_clone"), as_rotation(R_check, "R_check")

    def residual(dx):
        p_true_c, R_true_c = p_c - dx[15:18], R_c @ so3.exp(-dx[18:21])
        p_true, R_true = p - dx[0:3], R @ so3.exp(-dx[6:9])
        dp_m, dR_m = relative_motion(p_true_c, R_true_c, p_true, R_true)
        return relative_pose_residual(p_c, R_c, p, R, dp_m, dR_m)

    return numerical_jacobian(residual, np.zeros(21), h)


def segment_errors(position, rotation, true_position, true_rotation, first, last, length):
    """KITTI's drift errors of given segments, computed from the definition, one segment at a time.

    For a segment from frame i to frame j of nominal length L:
    Δp = R_iᵀ (p_j − p_i) and ΔR = R_iᵀ R_j for the estimate and the truth; the
    translational error is |Δp_true − Δp_est| / L and the rotational error
    angle(ΔR_estᵀ ΔR_true) / L.

    Parameters
    ----------
    position, true_position : array_like, shape (K, 3)
        Estimated and true positions, m.
    rotation, true_rotation : array_like, shape (K, 3, 3)
        Estimated and true attitudes R_nb.
    first, last : array_like of int, shape (S,)
        Start and end frame of each segment.
    length : array_like, shape (S,)
        Nominal length of each segment, m.

    Returns
    -------
    translation_percent : numpy.ndarray, shape (S,)
        100 |Δp_true − Δp_est| / L.
    rotation_deg_per_100m : numpy.ndarray, shape (S,)
        100 · degrees(angle(ΔR_estᵀ ΔR_true)) / L.
    """
    p = as_matrix(position, "position", ("K", 3))
    K = p.shape[0]
    p_true = as_matrix(true_position, "true_position", (K, 3))
    R = as_rotations(rotation, "rotation", K)
    R_true = as_rotations(true_rotation, "true_rotation", K)
    first = np.asarray(first)
    last = np.asarray(last)
    length = as_vector(length, "length")
    if first.shape != length.shape or last.shape != length.shape or first.dtype.kind not in "iu" \
            or last.dtype.kind not in "iu" or (first < 0).any() or (last >= K).any() or (first > last).any():
        raise ValueError(f"first and last must be integer frame indices 0 <= first <= last < {K}, one per length")
    translation, rotation_rate = [], []
    for i, j, L in zip(first, last, length):
        dp_est, dp_true = R[i].T @ (p[j] - p[i]), R_true[i].T @ (p_true[j] - p_true[i])
        dR_est, dR_true = R[i].T @ R[j], R_true[i].T @ R_true[j]
        translation.append(100.0 * np.linalg.norm(dp_true - dp_est) / L)
        rotation_rate.append(100.0 * np.rad2deg(so3.angle(dR_est.T @ dR_true)) / L)
    return np.array(translation), np.array(rotation_rate)
