"""Observation records: what a sensor reported, and when.

Filters take their measurements as one of these records, never as the data set objects
that also carry the ground truth. A record holds the values the sensor reported (with
its noise), so the noise-free solution cannot reach a filter by accident.

- :class:`PositionObservations` — times ``t`` (K,) and positions (K, 3), e.g. GNSS fixes.
- :class:`PoseObservations` — the same plus attitudes ``rotation`` (K, 3, 3), e.g. lidar
  map matching. It is a :class:`PositionObservations`, so a function that only needs the
  positions accepts it too.

Both are frozen and validate on construction: times finite and strictly increasing,
values finite, rotations orthonormal with det +1 to within :data:`ROTATION_TOL`. An
error names the field and the first bad row, for example ``ValueError: position[17] is
NaN``. The arrays are read-only float64 copies, so a record cannot change after it has
been checked.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from kalman_course.core.validation import ROTATION_TOL, as_increasing, as_rows, check_rotations

__all__ = ["PositionObservations", "PoseObservations"]

#: Largest accepted max-abs entry of RᵀR − I for a measured rotation. Rotations stored with
#: float64 round-off are ~1e-15 off; 1e-6 also admits matrices rebuilt from quaternions
#: printed with single-precision digits, and rejects anything that is not a rotation.


def _readonly(arr: np.ndarray) -> np.ndarray:
    """Return a float64 copy of ``arr`` that cannot be written to."""
    out = np.array(arr, dtype=np.float64, copy=True)
    out.setflags(write=False)
    return out


def _as_times(t) -> np.ndarray:
    """Return ``t`` as a finite, strictly increasing float64 vector (K,)."""
    return as_increasing(t, "t", count="K")


@dataclass(frozen=True, eq=False, repr=False)
class PositionObservations:
    """Positions reported by a sensor (e.g. GNSS fixes), in the navigation frame.

    Parameters
    ----------
    t : array_like, shape (K,)
        Observation times, s; finite and strictly increasing.
    position : array_like, shape (K, 3)
        Reported position at each time, navigation frame, m; finite. These are the
        sensor's values including its noise, not a ground-truth solution.

    Attributes
    ----------
    t : numpy.ndarray, shape (K,)
        Read-only float64 copy of ``t``.
    position : numpy.ndarray, shape (K, 3)
        Read-only float64 copy of ``position``.

    Raises
    ------
    ValueError
        If a field has the wrong shape, holds a NaN or an inf (the message names the first
        bad row, e.g. ``position[17] is NaN``), or ``t`` does not strictly increase.

    Examples
    --------
    >>> obs = PositionObservations([0.0, 1.0], [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    >>> len(obs), obs.position[1, 0]
    (2, 1.0)
    """

    t: np.ndarray
    position: np.ndarray

    def __post_init__(self) -> None:
        t = _as_times(self.t)
        position = as_rows(self.position, "position", (3,), t.shape[0], count="K")
        object.__setattr__(self, "t", _readonly(t))
        object.__setattr__(self, "position", _readonly(position))

    def __len__(self) -> int:
        """Number of observations K."""
        return int(self.t.shape[0])

    def __repr__(self) -> str:
        if len(self) == 0:
            return f"{type(self).__name__}(K=0)"
        return (f"{type(self).__name__}(K={len(self)}, "
                f"t=[{self.t[0]:g} … {self.t[-1]:g}] s)")

    def select(self, which) -> "PositionObservations":
        """Return the observations picked by ``which``, as a record of the same type.

        Parameters
        ----------
        which : slice, array_like of bool, shape (K,), or array_like of int
            Rows to keep: a slice, a boolean mask over the K observations, or increasing
            row indices. For example ``gnss.select((gnss.t < 100) | (gnss.t > 130))``
            removes the fixes of a 30 s outage.

        Returns
        -------
        PositionObservations or PoseObservations
            A new, validated record (``type(self)``) holding the selected rows. Fields of
            a subclass that are not one row per observation (e.g. a noise level) are kept.

        Raises
        ------
        ValueError
            Naming ``which``: a boolean mask that does not have shape (K,), an index out of
            range, indices that are not integers (floats, strings) or not 1-D, or indices
            that would put the times out of order (decreasing or repeated).
        """
        rows = _selected_rows(which, len(self))
        K = len(self)
        fields = {}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            per_row = isinstance(value, np.ndarray) and value.ndim >= 1 and value.shape[0] == K
            fields[f.name] = value[rows] if per_row else value    # e.g. a subclass's noise level
        return type(self)(**fields)


def _selected_rows(which, K: int) -> np.ndarray:
    """The increasing row indices (n,) that ``which`` (slice, bool mask (K,) or indices) picks."""
    expected = f"a slice, a boolean mask of shape ({K},) or integer row indices"
    if isinstance(which, slice):
        try:
            return _increasing(np.arange(K)[which])
        except (TypeError, ValueError) as exc:          # float bounds, a zero step
            raise ValueError(f"which must be {expected}; the slice {which!r} is not valid ({exc})") from None
    try:
        arr = np.asarray(which)
    except (TypeError, ValueError):                     # a ragged list
        arr = None
    if arr is None or arr.dtype.kind not in "biu" and not (arr.size == 0 and arr.dtype.kind == "f"):
        kind = f"dtype {arr.dtype}" if arr is not None else "a ragged list"
        raise ValueError(f"which must be {expected}, got {kind}: {which!r:.60}")
    if arr.dtype == bool:
        if arr.shape != (K,):
            raise ValueError(f"which must be a boolean mask of shape ({K},), got shape {arr.shape}")
        return np.flatnonzero(arr)
    if arr.ndim != 1:
        raise ValueError(f"which must be {expected} (1-D), got shape {arr.shape}")
    arr = arr.astype(np.int64)
    outside = (arr < -K) | (arr >= K)
    if outside.any():
        raise ValueError(f"which must hold row indices in [-{K}, {K}), got {int(arr[np.argmax(outside)])}")
    return _increasing(np.where(arr < 0, arr + K, arr))


def _increasing(arr: np.ndarray) -> np.ndarray:
    """``arr`` if its row indices increase strictly, else a ValueError naming ``which``."""
    step = np.diff(arr)
    if (step <= 0).any():
        k = int(np.argmax(step <= 0))
        raise ValueError(f"which must pick rows in increasing order (t must be strictly increasing): "
                         f"row {arr[k + 1]} after row {arr[k]}")
    return arr


@dataclass(frozen=True, eq=False, repr=False)
class PoseObservations(PositionObservations):
    """Poses reported by a sensor (e.g. lidar map matching): position and attitude.

    Parameters
    ----------
    t : array_like, shape (K,)
        Observation times, s; finite and strictly increasing.
    position : array_like, shape (K, 3)
        Reported position, navigation frame, m; finite.
    rotation : array_like, shape (K, 3, 3)
        Reported attitude R_nb (body to navigation frame); each matrix orthonormal with
        det +1, max |RᵀR − I| ≤ :data:`ROTATION_TOL`.

    Attributes
    ----------
    t : numpy.ndarray, shape (K,)
        Read-only float64 copy of ``t``.
    position : numpy.ndarray, shape (K, 3)
        Read-only float64 copy of ``position``.
    rotation : numpy.ndarray, shape (K, 3, 3)
        Read-only float64 copy of ``rotation``.

    Raises
    ------
    ValueError
        As :class:`PositionObservations`, and if a rotation is not orthonormal
        (``rotation[3] is not a rotation matrix (|RᵀR − I| = 0.2, ...)``) or is a
        reflection.
    """

    rotation: np.ndarray

    def __post_init__(self) -> None:
        super().__post_init__()
        rotation = as_rows(self.rotation, "rotation", (3, 3), len(self), count="K")
        check_rotations(rotation, "rotation")
        object.__setattr__(self, "rotation", _readonly(rotation))
