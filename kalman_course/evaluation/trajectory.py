"""Trajectory alignment and absolute trajectory error (ATE).

An estimated trajectory and the ground truth usually live in different frames (a SLAM
system starts its own map at its first pose). Before comparing positions, the estimate is
aligned to the truth with the least-squares rigid (or similarity) transform of Umeyama
(1991), "Least-squares estimation of transformation parameters between two point
patterns", IEEE TPAMI 13(4).
"""

from __future__ import annotations

import numpy as np

from kalman_course.core.validation import as_flag, as_matrix, as_rotation, as_scalar, as_vector
from kalman_course.evaluation.metrics import position_rmse

__all__ = ["umeyama", "apply_alignment", "ate_rmse"]


def _points(value, name: str, N: int | None = None) -> np.ndarray:
    """``value`` as finite positions of shape (N, 3) (any N ≥ 1 when N is None)."""
    return as_matrix(value, name, (N if N is not None else "N", 3))


def umeyama(src, dst, with_scale: bool = False) -> tuple[np.ndarray, np.ndarray, float]:
    """Least-squares transform mapping points ``src`` onto ``dst``: dst ≈ s R src + t.

    Parameters
    ----------
    src : array_like, shape (N, 3)
        Points to be moved (for example estimated positions), m.
    dst : array_like, shape (N, 3)
        Corresponding target points (for example true positions), m.
    with_scale : bool
        If False (SE(3) alignment) s is fixed at 1; if True (Sim(3)) s is estimated too.

    Returns
    -------
    R : numpy.ndarray, shape (3, 3)
        Rotation, det R = +1.
    t : numpy.ndarray, shape (3,)
        Translation, m.
    s : float
        Scale (1.0 when ``with_scale`` is False).

    Raises
    ------
    ValueError
        If ``src`` or ``dst`` is not a finite (N, 3) array, the shapes differ, N < 3, the
        source points are all identical, or ``with_scale`` is not a bool.
    """
    src = _points(src, "src")
    dst = _points(dst, "dst", src.shape[0])
    with_scale = as_flag(with_scale, "with_scale")
    n = src.shape[0]
    if n < 3:
        raise ValueError(f"src and dst need at least 3 point pairs, got {n}")
    mu_s, mu_d = src.mean(axis=0), dst.mean(axis=0)
    xs, xd = src - mu_s, dst - mu_d
    var_s = np.sum(xs * xs) / n
    if var_s == 0.0:
        raise ValueError("src points are all identical; the alignment is undetermined")
    cov = xd.T @ xs / n
    U, D, Vt = np.linalg.svd(cov)
    S = np.ones(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0.0:
        S[2] = -1.0
    R = (U * S) @ Vt
    s = float(np.sum(D * S) / var_s) if with_scale else 1.0
    t = mu_d - s * R @ mu_s
    return R, t, s


def apply_alignment(points, R, t, s: float = 1.0) -> np.ndarray:
    """Apply a similarity transform: ``s R p + t`` for each row p of ``points``.

    Parameters
    ----------
    points : array_like, shape (N, 3)
        Positions to move, m.
    R : array_like, shape (3, 3)
        Rotation matrix (orthonormal, det R = +1, to 1e-6), as :func:`umeyama` returns.
    t : array_like, shape (3,)
        Translation, m.
    s : float, default 1.0
        Scale, > 0.

    Returns
    -------
    numpy.ndarray, shape (N, 3)
        The moved positions, m.

    Raises
    ------
    ValueError
        If an argument is not finite or has the wrong shape, ``R`` is not a rotation, or
        ``s`` is not positive.
    """
    points = _points(points, "points")
    R = as_rotation(R, "R")
    t = as_vector(t, "t", 3)
    s = as_scalar(s, "s")
    return s * points @ R.T + t


def ate_rmse(estimate, reference, align: str = "se3") -> float:
    """Absolute trajectory error: RMS of position differences after alignment.

    Parameters
    ----------
    estimate : array_like, shape (N, 3)
        Estimated positions, m.
    reference : array_like, shape (N, 3)
        True positions at the same times, m.
    align : {"se3", "sim3", "none"}
        Align the estimate to the reference with a rigid transform (default), a similarity
        transform, or not at all.

    Returns
    -------
    float
        sqrt(mean_k |p_ref,k − aligned(p_est,k)|²), m (:func:`~kalman_course.evaluation.metrics.position_rmse`
        of the aligned estimate).

    Raises
    ------
    ValueError
        If ``estimate`` or ``reference`` is not a finite (N, 3) array, their shapes
        differ, ``align`` is not one of the three names, or the alignment is undetermined
        (see :func:`umeyama`).
    """
    est = _points(estimate, "estimate")
    ref = _points(reference, "reference", est.shape[0])
    if align == "none":
        aligned = est
    elif align in ("se3", "sim3"):
        R, t, s = umeyama(est, ref, with_scale=(align == "sim3"))
        aligned = apply_alignment(est, R, t, s)
    else:
        raise ValueError(f"align must be 'se3', 'sim3' or 'none', got {align!r}")
    return position_rmse(aligned, ref)
