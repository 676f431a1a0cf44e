"""Trajectory alignment and absolute trajectory error (ATE).

An estimated trajectory and the ground truth usually live in different frames (a SLAM
system starts its own map at its first pose). Before comparing positions, the estimate is
aligned to the truth with the least-squares rigid (or similarity) transform of Umeyama
(1991), "Least-squares estimation of transformation parameters between two point
patterns", IEEE TPAMI 13(4).

:func:`align_poses` moves a whole pose trajectory (positions and attitudes) onto a
reference: by that least-squares transform (SE(3) or Sim(3)), by the transform that puts
its first pose onto the reference's first pose (the KITTI devkit's convention: every
sequence starts at the identity), or by a turn about the vertical axis and a translation
only (for a system that knows the direction of gravity but not its heading).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from kalman_course.core import so3
from kalman_course.core.validation import as_flag, as_matrix, as_rotation, as_scalar, as_vector
from kalman_course.evaluation.metrics import position_rmse

__all__ = ["umeyama", "apply_alignment", "ate_rmse", "align_poses", "AlignedPoses", "POSE_ALIGNMENTS"]

#: The alignments :func:`align_poses` offers.
POSE_ALIGNMENTS = ("se3", "sim3", "first", "yaw")


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


class AlignedPoses(NamedTuple):
    """A pose trajectory moved onto a reference by :func:`align_poses`.

    Attributes
    ----------
    position : numpy.ndarray, shape (N, 3)
        Aligned positions s R p_k + t, m.
    rotation : numpy.ndarray, shape (N, 3, 3)
        Aligned attitudes R R_k.
    R : numpy.ndarray, shape (3, 3)
        Rotation of the alignment.
    t : numpy.ndarray, shape (3,)
        Translation of the alignment, m.
    s : float
        Scale of the alignment (1.0 unless ``align="sim3"``).
    """

    position: np.ndarray
    rotation: np.ndarray
    R: np.ndarray
    t: np.ndarray
    s: float


def _rotation_stack(value, name: str, N: int | None = None) -> np.ndarray:
    """``value`` as N rotation matrices (N, 3, 3) (any N ≥ 1 when N is None)."""
    try:
        R = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a numeric array of shape (N, 3, 3), got {type(value).__name__}") from None
    if R.ndim != 3 or R.shape[1:] != (3, 3) or R.shape[0] == 0 or (N is not None and R.shape[0] != N):
        want = f"({N}, 3, 3)" if N is not None else "(N, 3, 3)"
        raise ValueError(f"{name} must have shape {want}, one rotation per pose, got {R.shape}")
    return so3.as_rotations(R, name)


def _yaw_alignment(src: np.ndarray, dst: np.ndarray, axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares turn ψ about the unit ``axis`` a and translation t with dst ≈ Exp(ψ a) src + t.

    With the centred points s_k, d_k and Exp(ψ a) = cos ψ (I − a aᵀ) + sin ψ [a]× + a aᵀ,
    Σ d_kᵀ Exp(ψ a) s_k = A cos ψ + B sin ψ + const with A = Σ (d_kᵀ s_k − (aᵀ d_k)(aᵀ s_k))
    and B = Σ d_kᵀ (a × s_k); it is largest at ψ = atan2(B, A).
    """
    mu_s, mu_d = src.mean(axis=0), dst.mean(axis=0)
    xs, xd = src - mu_s, dst - mu_d
    A = np.sum(xd * xs) - np.sum((xd @ axis) * (xs @ axis))
    B = np.sum(xd * np.cross(axis, xs))
    if np.hypot(A, B) == 0.0:
        raise ValueError("position: the points (or the reference's) do not spread across the horizontal "
                         "plane, so the turn about the vertical axis is undetermined")
    R = so3.exp(np.arctan2(B, A) * axis)
    return R, mu_d - R @ mu_s


def align_poses(position, rotation, ref_position, ref_rotation, align: str = "se3", *,
                vertical_axis: int = 2) -> AlignedPoses:
    """Move a pose trajectory onto a reference: positions s R p_k + t, attitudes R R_k.

    Parameters
    ----------
    position : array_like, shape (N, 3)
        Positions p_k of the trajectory to move, m.
    rotation : array_like, shape (N, 3, 3)
        Its attitudes R_k (body to its own frame); each a rotation matrix.
    ref_position : array_like, shape (N, 3)
        Reference positions at the same N times (for example the ground truth), m.
    ref_rotation : array_like, shape (N, 3, 3)
        Reference attitudes at the same times.
    align : {"se3", "sim3", "first", "yaw"}
        Which transform (R, t, s):

        - ``"se3"``: the least-squares rigid transform of the positions (:func:`umeyama`),
          s = 1; needs N ≥ 3 positions that are not all equal;
        - ``"sim3"``: the same with the least-squares scale s;
        - ``"first"``: the rigid transform that puts the first pose exactly onto the
          reference's first pose, R = R_ref,0 R_0ᵀ, t = p_ref,0 − R p_0 (the KITTI devkit's
          convention, where each trajectory starts at the identity);
        - ``"yaw"``: a turn about the vertical axis and a translation (4 degrees of
          freedom), least squares on the positions; for an estimate whose tilt is
          observable from gravity but whose heading is not.
    vertical_axis : {0, 1, 2}, keyword-only
        Index of the axis the ``"yaw"`` alignment turns about: 2 (z) for the course's
        navigation frame (z up); 1 (y) for KITTI camera poses (y points down). Ignored by
        the other alignments.

    Returns
    -------
    AlignedPoses
        ``(position (N, 3), rotation (N, 3, 3), R (3, 3), t (3,), s)``: the aligned
        trajectory and the transform.

    Raises
    ------
    ValueError
        If an argument has the wrong shape or is not finite, a matrix of ``rotation`` or
        ``ref_rotation`` is not a rotation (scaled, sheared or a reflection; named by its
        index), ``align`` or ``vertical_axis`` is not one of the listed values, or the
        alignment is undetermined (see :func:`umeyama`).
    """
    rotation = _rotation_stack(rotation, "rotation")
    N = rotation.shape[0]
    position = _points(position, "position", N)
    ref_rotation = _rotation_stack(ref_rotation, "ref_rotation", N)
    ref_position = _points(ref_position, "ref_position", N)
    if not isinstance(align, str) or align not in POSE_ALIGNMENTS:
        raise ValueError(f"align must be one of {', '.join(map(repr, POSE_ALIGNMENTS))}, got {align!r}")
    if (isinstance(vertical_axis, (bool, np.bool_)) or not isinstance(vertical_axis, (int, np.integer))
            or vertical_axis not in (0, 1, 2)):
        raise ValueError(f"vertical_axis must be 0, 1 or 2 (x, y or z), got {vertical_axis!r}")

    s = 1.0
    if align in ("se3", "sim3"):
        R, t, s = umeyama(position, ref_position, with_scale=(align == "sim3"))
    elif align == "first":
        # projected: two matrices each within ROTATION_TOL of SO(3) (printed with few
        # digits) can give a product twice as far from it
        R = so3.orthonormalise(ref_rotation[0] @ rotation[0].T)
        t = ref_position[0] - R @ position[0]
    else:
        R, t = _yaw_alignment(position, ref_position, np.eye(3)[int(vertical_axis)])
    return AlignedPoses(position=apply_alignment(position, R, t, s), rotation=R @ rotation, R=R, t=t, s=s)
