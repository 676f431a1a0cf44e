"""Input validation shared by every public function of the package.

Each helper takes the argument's *name* so that the error says which argument was wrong
and what was expected, for example ``ValueError: P_hat must be symmetric (max |P - P.T| =
0.3)``. Helpers return float arrays so callers can use them directly.

The filters' public steps sit in learners' loops, so the array helpers have a fast path:
a float64 ndarray of the right shape that passes the strict form of the rules (finite,
exactly symmetric, non-negative diagonal, a Cholesky factor where positive
(semi-)definiteness is asked for) is returned as it is after a few cheap numpy calls.
Anything else takes the full path, which converts, applies the rules with their
tolerances and raises the ValueError naming the argument. Either way the caller's array
may come back itself (not a copy): callers never write into a validated argument.

The rules for a covariance (:func:`as_covariance`): square, finite, symmetric to a
relative tolerance :data:`SYMMETRY_RTOL`, non-negative variances on the diagonal; with
``psd=True`` also positive semi-definite, meaning that its smallest eigenvalue is not
below ``-PSD_RTOL`` times its largest (a singular covariance, such as a zero variance for
a state known exactly, passes; round-off of order 1e-16 relative passes; a clearly
indefinite matrix such as [[1, 2], [2, 1]], eigenvalues 3 and −1, fails); with
``positive_definite=True``, a Cholesky factor must exist (use it for anything inverted).
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from kalman_course.core.linalg import symmetrise

#: Relative tolerance used to decide that a covariance is symmetric.
SYMMETRY_RTOL = 1e-9

#: Relative tolerance of the positive semi-definiteness test: the smallest eigenvalue may
#: be as low as ``-PSD_RTOL`` times the largest. Round-off in a filter's covariance is
#: of order 1e-16 relative, far inside it.
PSD_RTOL = 1e-9

#: Largest max |RᵀR − I| accepted for a rotation matrix (measured attitudes carry round-off).
ROTATION_TOL = 1e-6


def _as_float_array(value, name: str, expected: str) -> np.ndarray:
    """``value`` as a float ndarray, or a ValueError naming ``name`` if it holds no numbers.

    Accepts anything numpy reads as real numbers (lists, ints, float32, object arrays of
    numbers such as SymPy floats); rejects strings, complex numbers, ``None`` and ragged
    nested lists with a message saying what ``name`` should be (``expected``).
    """
    try:
        arr = np.asarray(value)
        if arr.dtype.kind in "iuf":              # int, unsigned, float (not bool: a flag)
            return arr.astype(float, copy=False)
        if arr.dtype.kind == "O" and value is not None:
            return arr.astype(float)
    except (TypeError, ValueError):          # a ragged list, or an object that is no number
        pass
    kind = type(value).__name__ if not isinstance(value, np.ndarray) else f"array of dtype {value.dtype}"
    raise ValueError(f"{name} must be {expected} of real numbers, got {kind}: {_short_repr(value)}")


def _short_repr(value) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _shape_text(shape: tuple[int | str | None, ...], letters: str = "mn") -> str:
    """(2, None) -> "(2, n)", ("N", 3) -> "(N, 3)": a free dimension shows its letter."""
    text = [str(d) if d is not None else letters[i] for i, d in enumerate(shape)]
    return "(" + ", ".join(text) + ("," if len(shape) == 1 else "") + ")"


def as_vector(value, name: str, n: int | None = None) -> np.ndarray:
    """Return ``value`` as a finite 1-D float array of length ``n``.

    Parameters
    ----------
    value : array_like, shape (n,)
        The candidate vector.
    name : str
        Argument name used in error messages.
    n : int, optional
        Required length; None accepts any length but 0.

    Returns
    -------
    numpy.ndarray, shape (n,)
        ``value`` itself when it already is a finite float64 vector, else a converted copy.

    Raises
    ------
    ValueError
        If ``value`` holds no real numbers, is not 1-D, has the wrong length, is empty, or
        holds NaN or inf.
    """
    if (type(value) is np.ndarray and value.dtype == np.float64 and value.ndim == 1
            and (value.shape[0] == n if n is not None else value.shape[0] > 0)
            and np.isfinite(value).all()):
        return value
    expected = f"a 1-D vector of shape {_shape_text((n,), 'n')}"
    arr = _as_float_array(value, name, expected)
    if arr.ndim != 1:
        hint = ""
        if arr.ndim == 2 and 1 in arr.shape:
            hint = f" (a row or column matrix; pass a 1-D array, e.g. {name}.ravel())"
        raise ValueError(f"{name} must be {expected}, got shape {arr.shape}{hint}")
    if n is not None and arr.shape[0] != n:
        raise ValueError(f"{name} must have shape ({n},), got {arr.shape}")
    if arr.shape[0] == 0 and n is None:
        raise ValueError(f"{name} must not be empty, got shape (0,)")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} must be finite, got NaN or inf at index "
                         f"{int(np.flatnonzero(~np.isfinite(arr))[0])}")
    return arr


def as_rows(value, name: str, tail: tuple[int, ...] = (), n: int | None = None, *, offset: int = 0,
            count: str = "N") -> np.ndarray:
    """Return ``value`` as a finite float array of shape (n, *tail): one row per sample.

    For records of samples (IMU readings, observations): a NaN or inf is reported by the
    index of its row, ``imu.angular_rate[1234] is NaN``, counted from ``offset`` (the index
    of the first row in the caller's record).

    Parameters
    ----------
    value : array_like, shape (n, *tail)
        The record.
    name : str
        Argument name used in error messages.
    tail : tuple of int
        The shape of one row; () for a vector of scalars.
    n : int, optional
        Required number of rows; None accepts any.
    offset : int
        Index of the first row, for the messages.
    count : str
        The letter that names the number of rows in messages (``N``, ``K``).

    Raises
    ------
    ValueError
        If ``value`` holds no real numbers, has another shape, or a NaN or inf (naming the
        first such row).
    """
    rows = count if n is None else f"{count}={n}"
    want = f"({rows},)" if not tail else "(" + ", ".join([rows, *map(str, tail)]) + ")"
    expected = f"a 1-D array of shape {want}" if not tail else f"a numeric array of shape {want}"
    try:
        arr = np.asarray(value)
        if arr.dtype.kind == "c":                # complex: numpy would drop the imaginary part
            raise TypeError(name)
        arr = arr.astype(np.float64, copy=False)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be {expected}, got {_short_repr(value)}") from None
    if arr.shape[1:] != tuple(tail) or arr.ndim != 1 + len(tail) or (n is not None and arr.shape[0] != n):
        rule = f"be {expected}" if not tail else f"have shape {want}"
        raise ValueError(f"{name} must {rule}, got shape {arr.shape}")
    finite = np.isfinite(arr)
    if not finite.all():
        k = int(np.argmin(finite.reshape(len(arr), -1).all(axis=1)))
        raise ValueError(f"{name}[{k + offset}] is {'NaN' if np.isnan(arr[k]).any() else 'inf'}")
    return arr


def as_increasing(value, name: str, *, count: str = "N") -> np.ndarray:
    """Return ``value`` as a finite, strictly increasing 1-D float array (times, for example).

    Raises ValueError naming ``name`` as :func:`as_rows` does, and naming the first sample
    that does not increase (``t must be strictly increasing: t[3] = 1 <= t[2] = 2``).
    """
    arr = as_rows(value, name, count=count)
    step = np.diff(arr)
    if (step <= 0.0).any():
        k = int(np.argmax(step <= 0.0)) + 1
        raise ValueError(f"{name} must be strictly increasing: {name}[{k}] = {arr[k]:g} <= "
                         f"{name}[{k - 1}] = {arr[k - 1]:g}")
    return arr


def as_real_array(value, name: str, *, allow_empty: bool = False) -> np.ndarray:
    """Return ``value`` as a non-empty float array of any shape; NaN and inf are kept.

    For functions that define what NaN means themselves (a missing measurement, an
    RMSE that propagates it).

    Parameters
    ----------
    value : array_like
        Real numbers, any shape.
    name : str
        Argument name used in error messages.
    allow_empty : bool
        If True, an empty array is returned as it is (an empty batch of angles).

    Returns
    -------
    numpy.ndarray
        ``value`` as float (itself when it already is a float64 ndarray).

    Raises
    ------
    ValueError
        If ``value`` holds no real numbers (a string, complex numbers, ``None``, a ragged
        list) or is empty (unless ``allow_empty``).
    """
    arr = _as_float_array(value, name, "an array")
    if arr.size == 0 and not allow_empty:
        raise ValueError(f"{name} must not be empty, got shape {arr.shape}")
    return arr


def as_flag(value, name: str) -> bool:
    """Return ``value`` as a bool; anything else (0 and 1 included) is a ValueError naming it."""
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be True or False, got {_short_repr(value)}")
    return bool(value)


def as_seed(seed) -> int:
    """Return ``seed`` as a non-negative int for ``numpy.random.default_rng``."""
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    return int(seed)


def as_seeds(seeds, name: str = "seeds") -> tuple[int, ...]:
    """Return ``seeds`` (a non-empty sequence of non-negative ints) as a tuple of ints.

    A string, a single number, a bool or a float among them is a ValueError naming ``name``.
    """
    expected = "a non-empty sequence of non-negative integers"
    if isinstance(seeds, (str, bytes)) or not np.iterable(seeds) or np.ndim(seeds) != 1:
        raise ValueError(f"{name} must be {expected}, got {_short_repr(seeds)}")
    out = []
    for i, seed in enumerate(seeds):
        if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise ValueError(f"{name}[{i}] must be a non-negative integer, got {seed!r}")
        out.append(int(seed))
    if not out:
        raise ValueError(f"{name} must be {expected}, got an empty one")
    return tuple(out)


def as_scalar(value, name: str, *, allow_zero: bool = False) -> float:
    """Return ``value`` as a finite positive float (or non-negative with ``allow_zero``)."""
    kind = "non-negative" if allow_zero else "positive"
    if isinstance(value, (str, bytes, bool, np.bool_)):   # float("2") and float(True) work
        raise ValueError(f"{name} must be a finite {kind} number, got {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a finite {kind} number, got {value!r}") from None
    if not np.isfinite(v) or v < 0.0 or (v == 0.0 and not allow_zero):
        raise ValueError(f"{name} must be a finite {kind} number, got {value!r}")
    return v


def as_matrix(value, name: str, shape: tuple[int | str | None, int | str | None] = (None, None), *,
              missing_rows: bool = False) -> np.ndarray:
    """Return ``value`` as a finite 2-D float array whose shape matches ``shape``.

    Parameters
    ----------
    value : array_like, shape (m, n)
        The candidate matrix.
    name : str
        Argument name used in error messages.
    shape : tuple of (int, str or None, int, str or None)
        Required (rows, columns). None or a letter (the letter used in error messages,
        for example ``("N", 3)``) accepts any size but 0.
    missing_rows : bool
        If True, a row that is entirely NaN is allowed (a time step without a
        measurement); every other row must still be finite.

    Returns
    -------
    numpy.ndarray, shape (m, n)
        ``value`` itself when it already is a finite float64 matrix, else a converted copy.

    Raises
    ------
    ValueError
        If ``value`` holds no real numbers, is not 2-D, has the wrong shape (the message
        says when it is the transpose of the expected one), is empty, or holds NaN or inf
        (other than whole NaN rows with ``missing_rows``).
    """
    expected = _shape_text(shape)
    rows, cols = (d if isinstance(d, (int, np.integer)) else None for d in shape)
    if (type(value) is np.ndarray and value.dtype == np.float64 and value.ndim == 2
            and (value.shape[0] == rows if rows is not None else value.shape[0] > 0)
            and (value.shape[1] == cols if cols is not None else value.shape[1] > 0)
            and np.isfinite(value).all()):
        return value
    arr = _as_float_array(value, name, f"a 2-D matrix of shape {expected}")
    if arr.ndim != 2:
        raise ValueError(f"{name} must be a 2-D matrix of shape {expected}, got shape {arr.shape}")
    if (rows is not None and arr.shape[0] != rows) or (cols is not None and arr.shape[1] != cols):
        transposed = ((rows is None or arr.shape[1] == rows) and (cols is None or arr.shape[0] == cols))
        hint = f" (the transpose of the expected shape: pass {name}.T?)" if transposed else ""
        raise ValueError(f"{name} must have shape {expected}, got {arr.shape}{hint}")
    if (rows is None and arr.shape[0] == 0) or (cols is None and arr.shape[1] == 0):
        raise ValueError(f"{name} must not be empty, got shape {arr.shape}")
    finite = np.isfinite(arr)
    if not finite.all():
        if missing_rows:
            bad_rows = ~(finite.all(axis=1) | np.isnan(arr).all(axis=1))
            if not bad_rows.any():
                return arr
            row = int(np.flatnonzero(bad_rows)[0])
            if np.isinf(arr[row]).any():
                raise ValueError(f"{name} must not contain inf, row {row} is {arr[row]} "
                                 f"(a missing row is all NaN)")
            raise ValueError(f"{name} rows must be all finite or all NaN (missing), "
                             f"row {row} is only partly NaN: {arr[row]}")
        row, col = np.argwhere(~finite)[0]
        raise ValueError(f"{name} must be finite, got NaN or inf at [{row}, {col}]")
    return arr


def as_covariance(value, name: str, n: int | None = None, *, psd: bool = False,
                  positive_definite: bool = False) -> np.ndarray:
    """Return ``value`` as an (n, n) covariance matrix: symmetric, finite, variances >= 0.

    Parameters
    ----------
    value : array_like, shape (n, n)
        The candidate covariance.
    name : str
        Argument name used in error messages.
    n : int, optional
        Required dimension; None accepts any but 0.
    psd : bool
        If True, also require positive semi-definiteness: the smallest eigenvalue must
        not be below ``-PSD_RTOL`` times the largest. Singular covariances pass. Use it
        for a filter's P and for Q.
    positive_definite : bool
        If True, also require a Cholesky factorisation to exist (use it for R and for
        anything that is inverted). Implies ``psd``.

    Returns
    -------
    numpy.ndarray, shape (n, n)
        ``value`` itself when it passes the strict fast checks, else a converted copy.

    Raises
    ------
    ValueError
        If the matrix holds no real numbers, is not square, not of size n, empty, not
        finite, not symmetric, has a negative diagonal, or (when requested) is not
        positive semi-definite or not positive definite.

    Notes
    -----
    The fast path (a float64 ndarray, exactly symmetric) costs one Cholesky
    factorisation when ``psd`` or ``positive_definite`` is asked for; only a matrix whose
    factorisation fails (a singular or an indefinite one) pays for the eigenvalues.
    """
    if (type(value) is np.ndarray and value.dtype == np.float64 and value.ndim == 2
            and value.shape[0] == value.shape[1]
            and (value.shape[0] == n if n is not None else value.shape[0] > 0)
            and np.isfinite(value).all() and (value == value.T).all()):
        if not (psd or positive_definite):
            if value.diagonal().min() >= 0:
                return value
        else:
            try:
                # succeeds only for a positive definite matrix (so its diagonal is > 0)
                np.linalg.cholesky(value)
                return value
            except np.linalg.LinAlgError:
                # singular or indefinite: the eigenvalues decide, without the conversions
                if (not positive_definite and value.diagonal().min() >= 0
                        and _is_psd(value)):
                    return value
    expected = f"({n}, {n})" if n is not None else "(n, n)"
    arr = _as_float_array(value, name, f"a square covariance matrix of shape {expected}")
    if arr.ndim != 2 or arr.shape[0] != arr.shape[1]:
        raise ValueError(f"{name} must be a square covariance matrix of shape {expected}, "
                         f"got shape {arr.shape}")
    if n is not None and arr.shape != (n, n):
        raise ValueError(f"{name} must have shape ({n}, {n}), got {arr.shape}")
    if arr.size == 0:
        raise ValueError(f"{name} must not be empty, got shape {arr.shape}")
    if not np.isfinite(arr).all():
        row, col = np.argwhere(~np.isfinite(arr))[0]
        raise ValueError(f"{name} must be finite, got NaN or inf at [{row}, {col}]")
    asym = np.abs(arr - arr.T).max()
    scale = max(np.abs(arr).max(), 1e-300)
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
    elif psd and not _is_psd(symmetrise(arr)):
        eigenvalues = np.linalg.eigvalsh(symmetrise(arr))
        raise ValueError(f"{name} must be positive semi-definite (a covariance): its smallest "
                         f"eigenvalue is {eigenvalues[0]:.3g}, its largest {eigenvalues[-1]:.3g}")
    return arr


def _is_psd(P: np.ndarray) -> bool:
    """The rule: a symmetric P is positive semi-definite if λ_min >= −PSD_RTOL · λ_max."""
    eigenvalues = np.linalg.eigvalsh(P)                  # ascending
    return bool(eigenvalues[0] >= -PSD_RTOL * max(eigenvalues[-1], 0.0))


def as_process_noise(Q, B, n: int) -> np.ndarray:
    """Validate Q (and its Jacobian B) and return the state-space noise B Q Bᵀ, (n, n).

    ``B`` None means Q is already (n, n) in state space. Q may be singular but must be
    positive semi-definite (an indefinite Q would make the prior covariance indefinite).
    """
    if B is None:
        return as_covariance(Q, "Q", n, psd=True)
    B = as_matrix(B, "B", (n, None))
    Q = as_covariance(Q, "Q", B.shape[1], psd=True)
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


def as_rotation(value, name: str) -> np.ndarray:
    """Return ``value`` as a (3, 3) rotation matrix: RᵀR = I within ROTATION_TOL and det R = +1.

    Raises ValueError naming ``name`` for a wrong shape, a NaN, a matrix that is not
    orthonormal or a reflection (det −1).
    """
    R = as_matrix(value, name, (3, 3))
    error = float(np.abs(R.T @ R - np.eye(3)).max())
    (a, b, c), (d, e, f), (g, h, i) = R.tolist()
    det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)
    if error > ROTATION_TOL or det <= 0.0:
        raise ValueError(f"{name} must be a rotation matrix (RᵀR = I within {ROTATION_TOL:g}, det +1), "
                         f"got max |RᵀR − I| = {error:.3g}, det = {det:.3g}")
    return R


def check_rotations(R: np.ndarray, name: str) -> None:
    """Raise ValueError naming the first matrix of ``R`` (a float array (3, 3) or (..., 3, 3))
    that is not a rotation: max |RᵀR − I| above :data:`ROTATION_TOL` (scaled, sheared, far
    from orthonormal) or det R ≤ 0 (a reflection).

    ``name`` labels the whole array; a stack's message adds the index of the bad matrix
    (``rotation[3] is a reflection, not a rotation (det = -1, expected +1)``).
    """
    stack = R.reshape(-1, 3, 3)
    if stack.shape[0] == 0:
        return
    error = np.abs(np.swapaxes(stack, -1, -2) @ stack - np.eye(3)).max(axis=(-2, -1))
    det = np.linalg.det(stack)
    bad = (error > ROTATION_TOL) | (det <= 0.0)
    if not bad.any():
        return
    k = int(np.argmax(bad))
    label = name if R.ndim == 2 else f"{name}[{', '.join(map(str, np.unravel_index(k, R.shape[:-2])))}]"
    if error[k] > ROTATION_TOL:
        raise ValueError(f"{label} is not a rotation matrix (|RᵀR − I| = {error[k]:.3g}, tolerance {ROTATION_TOL:g})")
    raise ValueError(f"{label} is a reflection, not a rotation (det = {det[k]:.3g}, expected +1)")


def as_rotations(value, name: str, n: int | None = None, *, count: str = "K") -> np.ndarray:
    """Return ``value`` as a stack of rotation matrices, shape (n, 3, 3).

    Each matrix must be a rotation by the rule of :func:`check_rotations`, whose message
    names the first one that is not.

    Parameters
    ----------
    value : array_like, shape (n, 3, 3)
        The stack.
    name : str
        Argument name used in error messages.
    n : int, optional
        Required number of matrices; None accepts any.
    count : str
        The letter that names the number of matrices in messages.

    Raises
    ------
    ValueError
        If ``value`` holds no real numbers, has another shape, holds a NaN or inf, or a
        matrix that is not a rotation (not orthonormal, or a reflection).
    """
    R = as_rows(value, name, (3, 3), n, count=count)
    check_rotations(R, name)
    return R


def as_int(value, name: str, *, minimum: int | None = None, allow_none: bool = False) -> int | None:
    """Return ``value`` as a Python int (not a bool, not a float), at least ``minimum``.

    ``allow_none`` lets ``None`` through (an optional slice bound); anything else that is
    not an integer is a ValueError naming ``name``.
    """
    if value is None and allow_none:
        return None
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        what = "an integer" + (" or None" if allow_none else "")
        raise ValueError(f"{name} must be {what}, got {_short_repr(value)}")
    if minimum is not None and value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {int(value)}")
    return int(value)


def as_real(value, name: str) -> float:
    """Return ``value`` as a finite float (any sign); strings, bools and arrays are a ValueError."""
    if not isinstance(value, (bool, np.bool_, str, bytes)):
        try:
            v = float(value) if np.ndim(value) == 0 and not np.iscomplexobj(value) else None
        except (TypeError, ValueError):
            v = None
        if v is not None and math.isfinite(v):
            return v
    raise ValueError(f"{name} must be a finite real number, got {_short_repr(value)}")


def as_path(value, name: str) -> Path:
    """Return ``value`` (a str or path-like) as a Path; anything else is a ValueError naming ``name``."""
    if isinstance(value, (str, os.PathLike)) and str(os.fspath(value)):
        return Path(value)
    raise ValueError(f"{name} must be a file path (str or pathlib.Path), got {_short_repr(value)}")


def require_file(path: Path, what: str) -> Path:
    """Raise unless ``path`` is an existing regular file: FileNotFoundError if it is missing,
    ValueError if it is a directory or something else; both messages name the path and ``what``
    it should have been (``a KITTI excerpt file``)."""
    if path.is_file():
        return path
    if path.is_dir():
        raise ValueError(f"{path} is a directory, not {what}")
    if path.exists():
        raise ValueError(f"{path} is not a regular file, not {what}")
    raise FileNotFoundError(f"{path}: no such file ({what})")
