"""Trajectory alignment and absolute trajectory error (ATE).

An estimated trajectory and the ground truth usually live in different frames (a SLAM
system starts its own map at its first pose). Before comparing positions, the estimate is
aligned to the truth with the least-squares rigid (or similarity) transform of Umeyama
(1991), "Least-squares estimation of transformation parameters between two point
patterns", IEEE TPAMI 13(4).
"""

from __future__ import annotations

import numpy as np

from kalman_course.core.validation import as_matrix

__all__ = ["umeyama", "apply_alignment", "ate_rmse"]


def _points(value, name: str, n: int | None = None) -> np.ndarray:
    return as_matrix(value, name, (n, 3))


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
        If the shapes differ, N < 3, or the source points are all identical.
    """
    src = _points(src, "src")
    dst = _points(dst, "dst", src.shape[0])
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
    """Return ``s R p + t`` for each row p of ``points`` (N, 3)."""
    points = _points(points, "points")
    return s * points @ np.asarray(R, dtype=float).T + np.asarray(t, dtype=float)


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
        sqrt(mean_k |p_ref,k − aligned(p_est,k)|²), m.
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
    return float(np.sqrt(np.mean(np.sum((ref - aligned) ** 2, axis=1))))
