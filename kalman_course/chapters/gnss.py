"""Chapter 03's GNSS scene: where the car truly was at the times of the fixes.

Shared by the lecture, the exercise and its checks (a graded kernel has no
:mod:`kalman_course.checks`).
"""

from __future__ import annotations

import numpy as np

from kalman_course.data import load_kitti

__all__ = ["truth_at"]


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
    return np.column_stack([np.interp(t, truth.t, truth.position[:, i]) for i in range(3)])
