"""Angles: the one wrapping convention of the course.

Every angle the course wraps (bearings, yaw residuals, simulated measurements) goes to
the half-open interval (−π, π]: +π stays +π and −π becomes +π, so that a bearing and its
residual are never ambiguous at the seam.
"""

from __future__ import annotations

import numpy as np

from kalman_course.core.validation import as_real_array

__all__ = ["wrap_angle"]


def wrap_angle(angle):
    """Wrap ``angle`` (rad, scalar or array) to (−π, π]; a scalar in gives a float out.

    NaN stays NaN (a missing value); an infinite angle, which has no direction, and
    anything that is not real numbers (a string, ``None``, complex numbers) raise a
    ValueError naming ``angle``.
    """
    arr = as_real_array(angle, "angle", allow_empty=True)
    if np.isinf(arr).any():
        where = f" at index {int(np.flatnonzero(np.isinf(arr))[0])}" if arr.ndim else ""
        raise ValueError(f"angle must be finite (or NaN for a missing value), got inf{where}")
    wrapped = np.pi - np.mod(np.pi - arr, 2.0 * np.pi)
    return float(wrapped) if np.ndim(wrapped) == 0 else wrapped
