"""Input validation shared by every public function of the package.

Each helper takes the argument's *name* so that the error says which argument was wrong
and what was expected, for example ``ValueError: P_hat must be symmetric (max |P - P.T| =
0.3)``. Helpers return float arrays so callers can use them directly.

The filters' public steps sit in learners' loops, so the array helpers have a fast path:
a float64 ndarray of the right shape that passes the strict form of the rules (finite,
exactly symmetric, non-negative diagonal, a Cholesky factor where positive definiteness
is asked for) is returned as it is after a few cheap numpy calls. Anything else takes the
full path, which converts, applies the rules with their tolerances and raises the
ValueError naming the argument.
"""

from __future__ import annotations

import numpy as np

#: Relative tolerance used to decide that a covariance is symmetric.
SYMMETRY_RTOL = 1e-9


def as_vector(value, name: str, n: int | None = None) -> np.ndarray:
    """Return ``value`` as a finite 1-D float array of length ``n`` (any length if None)."""
    if (type(value) is np.ndarray and value.dtype == np.float64 and value.ndim == 1
            and (n is None or value.shape[0] == n) and np.isfinite(value).all()):
        return value
    arr = np.asarray(value, dtype=float)
    if arr.ndim != 1:
        raise ValueError(f"{name} must be a 1-D vector of shape ({n if n is not None else 'n'},), "
                         f"got shape {arr.shape}")
    if n is not None and arr.shape[0] != n:
        raise ValueError(f"{name} must have shape ({n},), got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} must be finite, got NaN or inf")
    return arr


def as_seed(seed) -> int:
    """Return ``seed`` as a non-negative int for ``numpy.random.default_rng``."""
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    return int(seed)


def as_scalar(value, name: str, *, allow_zero: bool = False) -> float:
    """Return ``value`` as a finite positive float (or non-negative with ``allow_zero``)."""
    kind = "non-negative" if allow_zero else "positive"
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a finite {kind} number, got {value!r}") from None
    if not np.isfinite(v) or v < 0.0 or (v == 0.0 and not allow_zero):
        raise ValueError(f"{name} must be a finite {kind} number, got {value!r}")
    return v


def as_matrix(value, name: str, shape: tuple[int | None, int | None] = (None, None)) -> np.ndarray:
    """Return ``value`` as a finite 2-D float array whose shape matches ``shape`` (None = any)."""
    if (type(value) is np.ndarray and value.dtype == np.float64 and value.ndim == 2
            and shape[0] in (None, value.shape[0]) and shape[1] in (None, value.shape[1])
            and np.isfinite(value).all()):
        return value
    arr = np.asarray(value, dtype=float)
    rows, cols = shape
    expected = f"({rows if rows is not None else 'm'}, {cols if cols is not None else 'n'})"
    if arr.ndim != 2:
        raise ValueError(f"{name} must be a 2-D matrix of shape {expected}, got shape {arr.shape}")
    if (rows is not None and arr.shape[0] != rows) or (cols is not None and arr.shape[1] != cols):
        raise ValueError(f"{name} must have shape {expected}, got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} must be finite, got NaN or inf")
    return arr


def as_covariance(value, name: str, n: int | None = None, *, positive_definite: bool = False) -> np.ndarray:
    """Return ``value`` as an (n, n) symmetric covariance matrix.

    Parameters
    ----------
    value : array_like, shape (n, n)
        The candidate covariance.
    name : str
        Argument name used in error messages.
    n : int, optional
        Required dimension.
    positive_definite : bool
        If True, also require a Cholesky factorisation to exist (use it for R and for
        anything that is inverted).

    Raises
    ------
    ValueError
        If the matrix is not square, not of size n, not finite, not symmetric, has a
        negative diagonal, or (when requested) is not positive definite.
    """
    if (type(value) is np.ndarray and value.dtype == np.float64 and value.ndim == 2
            and value.shape[0] == value.shape[1] and value.shape[0] > 0
            and (n is None or value.shape[0] == n) and np.isfinite(value).all()
            and (value == value.T).all() and value.diagonal().min() >= 0):
        if not positive_definite:
            return value
        try:
            np.linalg.cholesky(value)
            return value
        except np.linalg.LinAlgError:
            pass
    arr = np.asarray(value, dtype=float)
    if arr.ndim != 2 or arr.shape[0] != arr.shape[1]:
        raise ValueError(f"{name} must be a square covariance matrix, got shape {arr.shape}")
    if n is not None and arr.shape != (n, n):
        raise ValueError(f"{name} must have shape ({n}, {n}), got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} must be finite, got NaN or inf")
    asym = np.abs(arr - arr.T).max() if arr.size else 0.0
    scale = max(np.abs(arr).max() if arr.size else 0.0, 1e-300)
    if asym > SYMMETRY_RTOL * scale:
        raise ValueError(f"{name} must be symmetric, max |{name} - {name}.T| = {asym:.3g}")
    if (arr.diagonal() < 0).any():
        raise ValueError(f"{name} must have a non-negative diagonal (variances), got {np.diag(arr)}")
    if positive_definite:
        try:
            np.linalg.cholesky(arr)
        except np.linalg.LinAlgError:
            raise ValueError(f"{name} must be positive definite (Cholesky failed; "
                             f"smallest eigenvalue {np.linalg.eigvalsh(arr).min():.3g})") from None
    return arr


def as_process_noise(Q, B, n: int) -> np.ndarray:
    """Validate Q (and its Jacobian B) and return the state-space noise B Q Bᵀ, (n, n).

    ``B`` None means Q is already (n, n) in state space. Q may be singular.
    """
    if B is None:
        return as_covariance(Q, "Q", n)
    B = as_matrix(B, "B", (n, None))
    Q = as_covariance(Q, "Q", B.shape[1])
    return B @ Q @ B.T


def as_observation_noise(R, C, m: int) -> np.ndarray:
    """Validate R (and its Jacobian C) and return the measurement-space noise C R Cᵀ, (m, m).

    ``C`` None means R is already (m, m). R must be positive definite.
    """
    if C is None:
        return as_covariance(R, "R", m, positive_definite=True)
    C = as_matrix(C, "C", (m, None))
    R = as_covariance(R, "R", C.shape[1], positive_definite=True)
    return C @ R @ C.T
