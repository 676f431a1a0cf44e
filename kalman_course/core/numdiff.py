"""Numerical differentiation: the finite-difference Jacobian used to check analytic ones.

Central differences,

    J[:, j] ≈ (f(x + h e_j) − f(x − h e_j)) / (2 h),

have a truncation error O(h²) (the second derivative cancels), so with h = 1e-6 a smooth
function's Jacobian comes out to about 1e-9 relative accuracy: round-off, of order
ε·|f| / h ≈ 1e-10·|f|, and truncation, of order h²·|f'''| ≈ 1e-12·|f'''|, are both small.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from kalman_course.core.validation import as_scalar, as_vector

__all__ = ["numerical_jacobian"]


def numerical_jacobian(f: Callable[[np.ndarray], np.ndarray], x, h: float = 1e-6) -> np.ndarray:
    """Jacobian ∂f/∂x of a vector function at ``x`` by central differences.

    Parameters
    ----------
    f : callable
        ``f(x)`` takes a state ``x`` of shape (n,) and returns a 1-D array of shape (m,).
        It is called 2 n times, at ``x ± h e_j`` for each unit vector e_j.
    x : array_like, shape (n,)
        The point at which to differentiate; finite.
    h : float
        Step in each coordinate (same units as that coordinate), > 0. The default suits
        coordinates of order one; for an angle wrapped to (−π, π], keep ``x`` away from ±π
        by more than ``h`` or the difference straddles the seam.

    Returns
    -------
    J : numpy.ndarray, shape (m, n)
        ``J[i, j] ≈ ∂f_i/∂x_j`` at ``x``.

    Raises
    ------
    ValueError
        If ``x`` is not a finite 1-D vector, ``h`` is not a finite positive number, or
        ``f`` does not return a finite 1-D array of one fixed length.
    """
    x = as_vector(x, "x")
    h = as_scalar(h, "h")
    n = x.shape[0]
    columns = []
    for j in range(n):
        step = np.zeros(n)
        step[j] = h
        f_plus = _evaluate(f, x + step)
        f_minus = _evaluate(f, x - step)
        if f_plus.shape != f_minus.shape or (columns and f_plus.shape != columns[0].shape):
            raise ValueError("f must return a 1-D array of the same length at every x, "
                             f"got shapes {f_plus.shape} and {f_minus.shape}")
        columns.append((f_plus - f_minus) / (2.0 * h))
    if not columns:                          # n = 0: the Jacobian of f at an empty x
        return np.zeros((_evaluate(f, x).shape[0], 0))
    return np.stack(columns, axis=1)


def _evaluate(f, x: np.ndarray) -> np.ndarray:
    """f(x) as a finite 1-D float array, or a ValueError naming ``f``."""
    value = np.asarray(f(x), dtype=float)
    if value.ndim != 1:
        raise ValueError(f"f must return a 1-D array of shape (m,), got shape {value.shape}")
    if not np.isfinite(value).all():
        raise ValueError(f"f must return finite values, got NaN or inf at x = {x}")
    return value
