"""KITTI's odometry drift metric: relative pose error per distance travelled.

The KITTI odometry benchmark (Geiger et al., CVPR 2012) scores an odometry estimate by how
much it drifts over stretches of a given length, not by where it ends up: an absolute
error depends on when the first mistake happened, a drift rate does not. Written here from
its definition:

1. Along the *true* path, the distance travelled up to frame k is
   d_k = Σ_{i<k} |p_true,i+1 − p_true,i| (:func:`path_distance`).
2. A segment of length L starts at frame i (every ``step``-th frame, 10 in the KITTI
   devkit) and ends at the first frame j whose distance reaches d_i + L; starts with no
   such j are skipped (:func:`segments`).
3. Over a segment the true and the estimated motions are the relative poses
   ΔT = T_i⁻¹ T_j, i.e. Δp = R_iᵀ (p_j − p_i) and ΔR = R_iᵀ R_j, each expressed in its own
   body frame at i. Their disagreement E = ΔT_est⁻¹ ΔT_true has the rotation
   ΔR_estᵀ ΔR_true and a translation of length |Δp_true − Δp_est|.
4. The segment's translational error is |Δp_true − Δp_est| / L and its rotational error
   is angle(ΔR_estᵀ ΔR_true) / L (rad/m). The metric is the mean over all segments of all
   lengths, reported as a percentage (× 100) and in degrees per 100 m (× 180/π × 100);
   means per length are given too.

The segment lengths are (100, 200, …, 800) m as on the benchmark. The metric depends on
which body frame the poses belong to only through the lever arm between frames (a
rotation error of δ rad moves a point ℓ metres off the origin by ℓ δ): on KITTI, IMU and
camera poses differ by about 1.4 m, which changes the translational error by ~0.01 % of
the segment length.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kalman_course.core import so3
from kalman_course.core.validation import as_matrix, as_rows, as_vector

__all__ = ["SEGMENT_LENGTHS", "KITTI_STEP", "DriftResult", "path_distance", "segments", "drift"]

#: Segment lengths of the KITTI odometry benchmark, m.
SEGMENT_LENGTHS = (100.0, 200.0, 300.0, 400.0, 500.0, 600.0, 700.0, 800.0)

#: The benchmark starts a segment at every 10th frame.
KITTI_STEP = 10


@dataclass(frozen=True)
class DriftResult:
    """The drift metric of one estimate (see the module docstring).

    Attributes
    ----------
    translation_percent : float
        Mean over all segments of |Δp_true − Δp_est| / L, in % (NaN if there is no segment).
    rotation_deg_per_100m : float
        Mean over all segments of angle(ΔR_estᵀ ΔR_true) / L, in degrees per 100 m.
    lengths : numpy.ndarray, shape (L,)
        The segment lengths, m.
    translation_percent_by_length, rotation_deg_per_100m_by_length : numpy.ndarray, shape (L,)
        The same means over the segments of each length (NaN for a length with none).
    count_by_length : numpy.ndarray of int, shape (L,)
        Number of segments of each length.
    first, last : numpy.ndarray of int, shape (S,)
        Start and end frame of every segment.
    length : numpy.ndarray, shape (S,)
        Its nominal length L, m (the divisor).
    translation_error : numpy.ndarray, shape (S,)
        |Δp_true − Δp_est| of every segment, m.
    rotation_error : numpy.ndarray, shape (S,)
        angle(ΔR_estᵀ ΔR_true) of every segment, rad.
    """

    translation_percent: float
    rotation_deg_per_100m: float
    lengths: np.ndarray
    translation_percent_by_length: np.ndarray
    rotation_deg_per_100m_by_length: np.ndarray
    count_by_length: np.ndarray
    first: np.ndarray
    last: np.ndarray
    length: np.ndarray
    translation_error: np.ndarray
    rotation_error: np.ndarray

    @property
    def n_segments(self) -> int:
        """Number of segments S over all lengths."""
        return int(self.first.shape[0])


def _rotations(value, name: str, K: int) -> np.ndarray:
    """``value`` as rotation matrices of shape (K, 3, 3); ValueError naming ``name`` otherwise."""
    R = as_rows(value, name, (3, 3), K)          # real numbers, one (3, 3) per frame, finite (names the row)
    if not so3.is_rotation(R, tol=1e-6):
        raise ValueError(f"{name} must hold rotation matrices (orthonormal, det +1, to 1e-6)")
    return R


def _lengths(lengths) -> np.ndarray:
    L = as_vector(lengths, "lengths")
    if (L <= 0.0).any():
        raise ValueError(f"lengths must be positive segment lengths in metres, got {L}")
    return L


def _step(step) -> int:
    if isinstance(step, (bool, np.bool_)) or not isinstance(step, (int, np.integer)) or step < 1:
        raise ValueError(f"step must be a positive integer number of frames, got {step!r}")
    return int(step)


def path_distance(position) -> np.ndarray:
    """Distance travelled along a path up to each frame, d_k = Σ_{i<k} |p_i+1 − p_i|.

    Parameters
    ----------
    position : array_like, shape (K, 3)
        Positions, m (the true ones, for the drift metric).

    Returns
    -------
    numpy.ndarray, shape (K,)
        d_0 = 0, m.
    """
    p = as_matrix(position, "position", ("K", 3))
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])


def segments(distance, lengths=SEGMENT_LENGTHS, step: int = KITTI_STEP):
    """Every (start, end, length) segment of the drift metric.

    Parameters
    ----------
    distance : array_like, shape (K,)
        Distance travelled up to each frame (:func:`path_distance` of the truth), m,
        non-decreasing.
    lengths : array_like, shape (L,)
        Segment lengths, m.
    step : int
        A segment starts at frames 0, step, 2·step, …

    Returns
    -------
    first, last : numpy.ndarray of int, shape (S,)
        Start frame i and end frame j = the first frame with d_j ≥ d_i + L.
    length : numpy.ndarray, shape (S,)
        L of each segment, m. Ordered by length, then by start frame.
    """
    d = as_vector(distance, "distance")
    if (np.diff(d) < 0.0).any():
        raise ValueError("distance must be non-decreasing (a distance travelled along the path)")
    L = _lengths(lengths)
    starts = np.arange(0, d.shape[0], _step(step))
    first, last, length = [], [], []
    for length_m in L:
        ends = np.searchsorted(d, d[starts] + length_m, side="left")   # first j with d_j ≥ d_i + L
        ok = ends < d.shape[0]
        first.append(starts[ok])
        last.append(ends[ok])
        length.append(np.full(int(ok.sum()), length_m))
    return np.concatenate(first), np.concatenate(last), np.concatenate(length)


def _mean_by_length(values: np.ndarray, length: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    out = np.full(lengths.shape[0], np.nan)
    for n, length_m in enumerate(lengths):
        sel = length == length_m
        if sel.any():
            out[n] = float(np.mean(values[sel]))
    return out


def drift(position, rotation, true_position, true_rotation, lengths=SEGMENT_LENGTHS,
          step: int = KITTI_STEP) -> DriftResult:
    """KITTI's drift metric of an estimated trajectory against the truth at the same frames.

    Parameters
    ----------
    position : array_like, shape (K, 3)
        Estimated positions, m, one per frame.
    rotation : array_like, shape (K, 3, 3)
        Estimated attitudes R_nb (body → navigation).
    true_position : array_like, shape (K, 3)
        True positions at the same frames, m.
    true_rotation : array_like, shape (K, 3, 3)
        True attitudes.
    lengths : array_like, shape (L,)
        Segment lengths along the true path, m (default :data:`SEGMENT_LENGTHS`).
    step : int
        Frames between segment starts (default :data:`KITTI_STEP`, as the benchmark).

    Returns
    -------
    DriftResult
        Translational error in % and rotational error in °/100 m, averaged over all
        segments and per length; the per-segment errors.

    Raises
    ------
    ValueError
        If an array has the wrong shape or is not finite, a rotation is not one, or a
        length or the step is not positive.
    """
    p = as_matrix(position, "position", ("K", 3))
    K = p.shape[0]
    p_true = as_matrix(true_position, "true_position", (K, 3))
    R = _rotations(rotation, "rotation", K)
    R_true = _rotations(true_rotation, "true_rotation", K)
    L = _lengths(lengths)
    i, j, length = segments(path_distance(p_true), L, step)

    # relative motions ΔT = T_i⁻¹ T_j, each in its own body frame at i
    dp_est = np.einsum("kba,kb->ka", R[i], p[j] - p[i])
    dp_true = np.einsum("kba,kb->ka", R_true[i], p_true[j] - p_true[i])
    dR_est = np.swapaxes(R[i], -1, -2) @ R[j]
    dR_true = np.swapaxes(R_true[i], -1, -2) @ R_true[j]
    # E = ΔT_est⁻¹ ΔT_true: rotation ΔR_estᵀ ΔR_true, translation ΔR_estᵀ (Δp_true − Δp_est)
    t_err = np.linalg.norm(dp_true - dp_est, axis=1)
    r_err = so3.angle(np.swapaxes(dR_est, -1, -2) @ dR_true) if i.size else np.zeros(0)

    t_rate = 100.0 * t_err / length                           # % of the segment length
    r_rate = np.rad2deg(r_err / length) * 100.0               # degrees per 100 m
    mean = (lambda v: float(np.mean(v)) if v.size else float("nan"))
    counts = np.array([int(np.sum(length == length_m)) for length_m in L])
    return DriftResult(mean(t_rate), mean(r_rate), L.copy(), _mean_by_length(t_rate, length, L),
                       _mean_by_length(r_rate, length, L), counts, i, j, length, t_err, r_err)
