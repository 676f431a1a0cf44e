"""What the symbolic topic modules share to offer their results as numpy functions.

:func:`lambdify_matrix` turns a SymPy matrix into a numpy function (each caller caches the
functions it builds, so SymPy runs once per process). The argument checks build on
:mod:`kalman_course.core.validation`; they add only what it does not say: a time step or a
noise level must be a real number (a string or a bool is refused, not converted), and a
number of spatial axes a positive integer.
"""

from __future__ import annotations

import math
import numbers
from typing import Callable, Sequence

import sympy as sp

from kalman_course.core.validation import as_scalar

__all__ = ["lambdify_matrix", "as_real", "as_time_step", "as_dimension"]


def lambdify_matrix(args: Sequence[sp.Symbol], expr) -> Callable:
    """Return a numpy function of ``args`` computing the matrix ``expr``.

    Parameters
    ----------
    args : sequence of sympy.Symbol
        The scalar arguments, in call order.
    expr : sympy Matrix, shape (r, c)
        The matrix to compute; common subexpressions are computed once.

    Returns
    -------
    callable
        ``fn(*values)`` returning an array of shape (r, c).
    """
    return sp.lambdify(list(args), sp.ImmutableMatrix(expr), modules="numpy", cse=True)


def as_real(value, name: str) -> float:
    """Return ``value`` as a finite float >= 0, refusing anything that is not a real number.

    Parameters
    ----------
    value : float or int
        The number (a Python or numpy real; ``bool``, ``str`` and ``None`` are refused).
    name : str
        The argument's name, used in the error message.

    Raises
    ------
    ValueError
        Naming ``name``, if ``value`` is not a real number, not finite or negative.
    """
    # fast path for the per-step calls of the filters: a finite float >= 0 (NaN fails the test)
    if type(value) is float and 0.0 <= value < math.inf:
        return value
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name} must be a real number, got {value!r}")
    return as_scalar(value, name, allow_zero=True)


def as_time_step(T) -> float:
    """Return the time step ``T`` (s) as a finite float >= 0 (see :func:`as_real`)."""
    return as_real(T, "T")


def as_dimension(dim) -> int:
    """Return ``dim``, the number of spatial axes, as a positive int.

    Raises
    ------
    ValueError
        If ``dim`` is not an integer >= 1 (a bool or a float such as 2.0 is refused).
    """
    if isinstance(dim, bool) or not isinstance(dim, numbers.Integral) or dim < 1:
        raise ValueError(f"dim must be a positive integer (number of spatial axes), got {dim!r}")
    return int(dim)
