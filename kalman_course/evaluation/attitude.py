"""An attitude error split into heading and tilt, in a navigation frame whose z axis is up.

With the course's convention (error = estimate − true) the attitude error in the body frame
is δθ = Log(R_trueᵀ R) (:mod:`kalman_course.evaluation.pose`). The same small rotation seen
in the navigation frame is δθ_n = R_true δθ = Log(R R_trueᵀ). Its z component is the
**heading** error (a turn about the vertical, unobservable from gravity) and the length of
its horizontal part the **tilt** error (roll and pitch together, which make gravity leak
into the horizontal acceleration: 9.81 m/s² · sin(tilt)).
"""

from __future__ import annotations

import numpy as np

from kalman_course.core import so3

__all__ = ["heading_tilt_error"]


def _rotations(value, name: str) -> np.ndarray:
    """``value`` as a rotation (3, 3) or a stack (K, 3, 3); ValueError naming the bad matrix."""
    try:
        R = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a rotation (3, 3) or stack (K, 3, 3) of numbers, "
                         f"got {type(value).__name__}") from None
    if R.shape[-2:] != (3, 3) or R.ndim not in (2, 3) or not np.isfinite(R).all():
        raise ValueError(f"{name} must be a finite rotation (3, 3) or stack (K, 3, 3), got shape {R.shape}")
    return so3.as_rotations(R, name)


def heading_tilt_error(rotation, rotation_true) -> tuple[np.ndarray, np.ndarray]:
    """Heading and tilt parts of the attitude error, degrees.

    Parameters
    ----------
    rotation : array_like, shape (3, 3) or (K, 3, 3)
        Estimated attitude R_nb (body → navigation).
    rotation_true : array_like, same shape
        True attitude R_nb.

    Returns
    -------
    heading : numpy.ndarray, shape () or (K,)
        z component of δθ_n = Log(R R_trueᵀ), degrees, signed (positive: the estimate is
        turned anticlockwise about up from the truth).
    tilt : numpy.ndarray, shape () or (K,)
        Length of the x, y components of δθ_n, degrees, non-negative.

    Raises
    ------
    ValueError
        If the two are not finite (3, 3) matrices or stacks of the same shape, or a matrix
        is not a rotation (max |RᵀR − I| above
        :data:`~kalman_course.core.validation.ROTATION_TOL`, or a reflection); the message
        names the argument and, in a stack, the index of the first bad matrix.
    """
    R = _rotations(rotation, "rotation")
    R_true = _rotations(rotation_true, "rotation_true")
    if R.shape != R_true.shape:
        raise ValueError(f"rotation and rotation_true must have the same shape, got {R.shape} and {R_true.shape}")
    dtheta_n = so3.log(R @ np.swapaxes(R_true, -1, -2), check=False)   # both validated above
    heading = np.rad2deg(dtheta_n[..., 2])
    tilt = np.rad2deg(np.hypot(dtheta_n[..., 0], dtheta_n[..., 1]))
    return heading, tilt
