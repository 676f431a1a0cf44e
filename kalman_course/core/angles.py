"""Angles: the one wrapping convention of the course.

Every angle the course wraps (bearings, yaw residuals, simulated measurements) goes to
the half-open interval (−π, π]: +π stays +π and −π becomes +π, so that a bearing and its
residual are never ambiguous at the seam.
"""

from __future__ import annotations

import numpy as np

__all__ = ["wrap_angle"]


def wrap_angle(angle):
    """Wrap ``angle`` (rad, scalar or array) to (−π, π]; a scalar in gives a float out."""
    wrapped = np.pi - np.mod(np.pi - np.asarray(angle, dtype=float), 2.0 * np.pi)
    return float(wrapped) if np.ndim(wrapped) == 0 else wrapped
