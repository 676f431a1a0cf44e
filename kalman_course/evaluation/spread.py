"""The spread of one figure over repeated runs: median and range, and how many pass a bar.

A filter scored on one noise draw reports one number; over several seeded draws the same
figure (a ratio, a mean NEES) varies. :func:`spread` summarises such a sample by its
median and its range (smallest, largest), the honest summary of ten or so values, and
:meth:`Spread.count_above` says how many of them exceed an acceptance bar.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kalman_course.core.validation import as_real, as_vector

__all__ = ["Spread", "spread"]


@dataclass(frozen=True)
class Spread:
    """Median and range of a sample of one figure.

    Attributes
    ----------
    values : tuple of float
        The sample, in the order given (one value per run or seed).
    median, low, high : float
        Its median, smallest and largest value, in the sample's unit.
    """

    values: tuple
    median: float
    low: float
    high: float

    @property
    def n(self) -> int:
        """Number of values."""
        return len(self.values)

    def count_above(self, bar: float) -> int:
        """How many values exceed ``bar`` (strictly), in the sample's unit; ``bar`` must be a finite number."""
        return int(np.sum(np.asarray(self.values) > as_real(bar, "bar")))

    def text(self, spec: str = ".2f") -> str:
        """``"median (low–high)"`` with each number formatted by ``spec``."""
        return f"{self.median:{spec}} ({self.low:{spec}}–{self.high:{spec}})"


def spread(values, name: str = "values") -> Spread:
    """Median and range of a sample.

    Parameters
    ----------
    values : array_like, shape (n,)
        Finite numbers, n >= 1 (for example one ratio per noise seed).
    name : str
        Argument name for error messages.

    Returns
    -------
    Spread

    Raises
    ------
    ValueError
        If ``values`` is not a non-empty finite 1-D sample.
    """
    if not isinstance(name, str) or not name:
        raise ValueError(f"name must be a non-empty string (the argument's name in messages), got {name!r}")
    v = as_vector(values, name)
    return Spread(tuple(float(x) for x in v), float(np.median(v)), float(v.min()), float(v.max()))
