"""Chapter 03's GNSS scene: where the car truly was at the times of the fixes.

Shared by the lecture, the exercise and its checks (a graded kernel has no
:mod:`kalman_course.checks`).
"""

from __future__ import annotations

import numpy as np

from kalman_course.core.validation import as_rows
from kalman_course.data import load_kitti, simulate_gnss
from kalman_course.evaluation.metrics import rmse as rmse_per_axis

__all__ = ["truth_at", "position_rmse_over_seeds"]


def truth_at(name: str, t):
    """Ground-truth positions of KITTI excerpt ``name`` interpolated at times ``t``.

    Parameters
    ----------
    name : str
        The excerpt (``"cruise"``, ``"turns"``).
    t : array_like (N,)
        Times (s), within the excerpt.

    Returns
    -------
    ndarray (N, 3)
        Positions (m) in the excerpt's navigation frame.
    """
    truth = load_kitti(name).truth
    t = as_rows(t, "t")
    outside = (t < truth.t[0]) | (t > truth.t[-1])
    if outside.any():
        k = int(np.argmax(outside))
        raise ValueError(f"t must lie inside the truth of {name!r}, [{truth.t[0]:.4f}, {truth.t[-1]:.4f}] s; "
                         f"t[{k}] = {t[k]:.4f}")
    return np.column_stack([np.interp(t, truth.t, truth.position[:, i]) for i in range(3)])


def position_rmse_over_seeds(filter_fixes, gnss, truth_position, seeds, sigma: float = 1.0):
    """3-D position RMSE of simulated GNSS fixes and of a filter of them, one row per noise draw.

    The recorded positions (``gnss.position_true``, KITTI's OXTS GNSS/INS output, real) get
    fresh simulated white noise for each seed (:func:`kalman_course.data.simulate_gnss`);
    ``filter_fixes`` filters each draw. Nothing else changes between rows.

    Parameters
    ----------
    filter_fixes : callable
        ``filter_fixes(fixes)`` takes one simulated draw (a ``GnssData``) and returns the
        filtered positions, shape (M, 3), m.
    gnss : GnssData
        The excerpt's GNSS record (``load_kitti(name).gnss``).
    truth_position : array_like, shape (M, 3)
        Ground truth at the fix times, m.
    seeds : iterable of int
        Seeds of the noise draws.
    sigma : float
        σ of the simulated noise per axis, m.

    Returns
    -------
    raw, filtered : ndarray, shape (len(seeds),)
        RMSE of the simulated fixes and of the filter's positions against the truth, m.
    """
    truth_position = np.asarray(truth_position, dtype=float)
    if truth_position.shape != np.shape(gnss.position_true):
        raise ValueError(f"truth_position must have shape {np.shape(gnss.position_true)}, "
                         f"got {truth_position.shape}")

    def rmse(positions):
        return float(np.sqrt(np.sum(rmse_per_axis(positions, truth_position) ** 2)))   # 3-D, from the per-axis RMSE

    raw, filtered = [], []
    for seed in seeds:
        fixes = simulate_gnss(gnss, seed=int(seed), sigma=sigma)
        raw.append(rmse(fixes.position_noisy))
        filtered.append(rmse(filter_fixes(fixes)))
    if not raw:
        raise ValueError("seeds must name at least one seed")
    return np.array(raw), np.array(filtered)
