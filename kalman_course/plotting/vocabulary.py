"""The course's plotting vocabulary: every chapter draws the same things the same way.

The truth is a black line, measurements are grey dots, the estimate is a blue line with a
light-blue ±3σ band, covariances are ellipses, consistency statistics sit over their
shaded chi-square interval. Each function takes a Matplotlib ``ax`` and returns the
artists it adds, so cells can add titles, limits and legends as they like. The
per-chapter figures (:mod:`kalman_course.plotting.kf`, :mod:`~kalman_course.plotting.eskf`,
...) are built from these.

Nothing here changes global state: no ``rcParams``, no style sheets. Colours come from
:data:`COLORS`; any keyword argument (``color=...``, ``label=...``) overrides them.

Bad inputs (wrong shapes, lengths that do not match, NaN where a value is needed, a
covariance that is not symmetric positive semi-definite) raise ``ValueError`` naming the
argument.
"""

from __future__ import annotations

import types

import numpy as np

from kalman_course.core.linalg import symmetrise
from kalman_course.core.validation import (as_covariance, as_flag, as_increasing, as_matrix, as_real_array, as_rows,
                                           as_scalar, as_vector)

__all__ = [
    "COLORS",
    "plot_truth",
    "plot_measurements",
    "plot_estimate",
    "plot_sigma_band",
    "plot_error_with_band",
    "plot_covariance_ellipse",
    "covariance_ellipse_axes",
    "plot_belief",
    "plot_samples",
    "plot_consistency",
    "plot_consistency_curves",
    "plot_track",
    "shade_spans",
    "flag_spans",
    "plot_curves",
    "CURVE_COLORS",
]

#: The course's colours, by role (read-only).
COLORS = types.MappingProxyType({
    "truth": "black",
    "measurement": "0.55",      # grey dots
    "estimate": "tab:blue",
    "band": "#a6cee3",          # light blue
    "prior": "tab:orange",
    "likelihood": "tab:green",
    "posterior": "tab:blue",
    "ellipse": "tab:blue",
    "samples": "0.7",
    "bounds": "tab:red",
    "marker": "tab:red",        # true cell, observed value, ...
})

#: Colours, in order, of several curves compared in one panel (settings, variants, runs).
CURVE_COLORS = (COLORS["estimate"], COLORS["prior"], COLORS["likelihood"], COLORS["marker"],
                "tab:purple", "tab:brown")


# --------------------------------------------------------------------------------------
# validation
# --------------------------------------------------------------------------------------

def _vector(value, name: str, *, allow_nan: bool = False, n: int | None = None) -> np.ndarray:
    """A 1-D float array (an (N, 1) column is flattened); NaN marks a gap where ``allow_nan``."""
    arr = as_real_array(value, name)
    if arr.ndim == 2 and 1 in arr.shape:
        arr = arr.reshape(-1)  # accept (N, 1) columns such as ys[:, None]
    # the shared validator applies every rule but the NaN one, which is the plot's to make
    as_vector(np.where(np.isnan(arr), 0.0, arr) if allow_nan else arr, name, n)
    return arr


def _times(value, name: str = "t") -> np.ndarray:
    """Finite, strictly increasing sample times (N,) (1-D: a column is not flattened)."""
    return as_increasing(value, name)


def _axes(ax, name: str = "ax"):
    """``ax`` itself if it is a Matplotlib Axes; anything else is a ValueError naming ``name``."""
    from matplotlib.axes import Axes

    if not isinstance(ax, Axes):
        raise ValueError(f"{name} must be a Matplotlib Axes (for example fig.add_subplot() or plt.gca()), "
                         f"got {type(ax).__name__}: {ax!r:.60}")
    return ax


def _sigma(value, name: str, n: int) -> np.ndarray:
    arr = as_real_array(value, name)
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    arr = _vector(arr, name, n=n)
    if np.any(arr < 0):
        raise ValueError(f"{name} must be >= 0 (a standard deviation), min is {arr.min():.3g}")
    return arr


def _covariance2(cov, name: str = "cov") -> np.ndarray:
    return symmetrise(as_covariance(cov, name, 2, psd=True))


def _with_defaults(kwargs: dict, **defaults) -> dict:
    """Defaults overridden by the caller's keyword arguments."""
    out = dict(defaults)
    if "c" in kwargs:  # matplotlib's short alias would clash with our colour
        kwargs = dict(kwargs)
        kwargs["color"] = kwargs.pop("c")
    out.update(kwargs)
    return out


# --------------------------------------------------------------------------------------
# the vocabulary
# --------------------------------------------------------------------------------------

def plot_truth(ax, t, x, *, label="truth", **kwargs):
    """Draw the true value of a quantity as a black line.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Where to draw.
    t : array_like, shape (N,)
        Abscissa (time, or the first coordinate of a 2-D path).
    x : array_like, shape (N,)
        Ordinate (the true value, or the second coordinate).
    label : str
        Legend label.
    **kwargs
        Passed to ``ax.plot`` (override the course style).

    Returns
    -------
    matplotlib.lines.Line2D
    """
    _axes(ax)
    t = _vector(t, "t")
    x = _vector(x, "x", n=t.shape[0])
    (line,) = ax.plot(t, x, **_with_defaults(kwargs, color=COLORS["truth"], lw=1.5, label=label))
    return line


def plot_measurements(ax, t, y, *, label="measurements", **kwargs):
    """Draw measurements as grey dots; NaN entries (no measurement) are skipped.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Where to draw.
    t : array_like, shape (N,)
        Abscissa (time, or the first coordinate of measured positions).
    y : array_like, shape (N,) or (N, 1)
        Measurements; NaN marks a missing one.
    label : str
        Legend label.
    **kwargs
        Passed to ``ax.plot``.

    Returns
    -------
    matplotlib.lines.Line2D
    """
    _axes(ax)
    t = _vector(t, "t", allow_nan=True)
    y = _vector(y, "y", allow_nan=True, n=t.shape[0])
    (line,) = ax.plot(t, y, **_with_defaults(kwargs, color=COLORS["measurement"], marker=".",
                                             linestyle="none", markersize=4, label=label))
    return line


def plot_estimate(ax, t, x, *, label="estimate", **kwargs):
    """Draw an estimate as a blue line.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Where to draw.
    t : array_like, shape (N,)
        Abscissa.
    x : array_like, shape (N,)
        Estimated values, for example ``hist.x_hat[:, 0]``.
    label : str
        Legend label.
    **kwargs
        Passed to ``ax.plot``.

    Returns
    -------
    matplotlib.lines.Line2D
    """
    _axes(ax)
    t = _vector(t, "t")
    x = _vector(x, "x", n=t.shape[0])
    (line,) = ax.plot(t, x, **_with_defaults(kwargs, color=COLORS["estimate"], lw=1.5, label=label))
    return line


def plot_sigma_band(ax, t, center, sigma, n_sigma=3, *, label=None, **kwargs):
    """Shade ``center ± n_sigma·sigma`` in light blue.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Where to draw.
    t : array_like, shape (N,)
        Abscissa.
    center : array_like, shape (N,), or float
        Middle of the band (the estimate; 0 for an error plot).
    sigma : array_like, shape (N,), or float
        Standard deviation, for example ``np.sqrt(hist.P_hat[:, 0, 0])``; >= 0.
    n_sigma : float
        Half-width of the band in standard deviations (default 3).
    label : str, optional
        Legend label; default ``"±3σ"`` (with the actual ``n_sigma``).
    **kwargs
        Passed to ``ax.fill_between``.

    Returns
    -------
    matplotlib.collections.PolyCollection
    """
    _axes(ax)
    t = _vector(t, "t")
    n = t.shape[0]
    c = as_real_array(center, "center")
    c = _vector(np.full(n, float(c)) if c.ndim == 0 else c, "center", n=n)
    s = _sigma(sigma, "sigma", n)
    k = as_scalar(n_sigma, "n_sigma")
    if label is None:
        label = f"±{k:g}σ"
    return ax.fill_between(t, c - k * s, c + k * s,
                           **_with_defaults(kwargs, color=COLORS["band"], alpha=0.6, lw=0, label=label))


def plot_error_with_band(ax, t, error, sigma, n_sigma=3, *, label="error", band_label=None, **kwargs):
    """Draw an estimation error with the filter's own ±n_sigma·σ band around zero.

    A consistent filter keeps about 99.7 % of a Gaussian error inside ±3σ.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Where to draw.
    t : array_like, shape (N,)
        Abscissa.
    error : array_like, shape (N,)
        Estimate minus truth.
    sigma : array_like, shape (N,), or float
        The filter's standard deviation of that component.
    n_sigma : float
        Half-width of the band in standard deviations (default 3).
    label : str
        Legend label of the error line.
    band_label : str, optional
        Legend label of the band (default ``"±3σ"``).
    **kwargs
        Passed to ``ax.plot`` for the error line.

    Returns
    -------
    (matplotlib.lines.Line2D, matplotlib.collections.PolyCollection)
        The error line and the band.
    """
    _axes(ax)
    t = _vector(t, "t")
    error = _vector(error, "error", n=t.shape[0])
    band = plot_sigma_band(ax, t, 0.0, sigma, n_sigma, label=band_label)
    (line,) = ax.plot(t, error, **_with_defaults(kwargs, color=COLORS["estimate"], lw=1.0, label=label))
    ax.axhline(0.0, color=COLORS["truth"], lw=0.6)
    return line, band


def covariance_ellipse_axes(cov, n_sigma=3):
    """Return the full axis lengths and orientation of a 2-D covariance ellipse.

    Parameters
    ----------
    cov : array_like, shape (2, 2)
        Symmetric positive semi-definite covariance.
    n_sigma : float
        Scale: the ellipse is the set of points at Mahalanobis distance ``n_sigma``.

    Returns
    -------
    width, height, angle : float
        ``width = 2 n_sigma sqrt(λ_max)`` along the direction at ``angle`` degrees from
        the first axis, ``height = 2 n_sigma sqrt(λ_min)`` across it.
    """
    cov = _covariance2(cov)
    k = as_scalar(n_sigma, "n_sigma")
    vals, vecs = np.linalg.eigh(cov)
    vals = np.clip(vals, 0.0, None)
    major = vecs[:, 1]
    angle = float(np.degrees(np.arctan2(major[1], major[0])))
    return 2 * k * float(np.sqrt(vals[1])), 2 * k * float(np.sqrt(vals[0])), angle


def plot_covariance_ellipse(ax, mean, cov, n_sigma=3, *, label=None, **kwargs):
    """Draw the ``n_sigma`` ellipse of a 2-D Gaussian.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Where to draw.
    mean : array_like, shape (2,)
        Centre.
    cov : array_like, shape (2, 2)
        Covariance, symmetric positive semi-definite.
    n_sigma : float
        Mahalanobis radius (default 3, about 98.9 % of the mass in 2-D).
    label : str, optional
        Legend label.
    **kwargs
        Passed to ``matplotlib.patches.Ellipse`` (for example ``color``, ``lw``,
        ``fill=True``).

    Returns
    -------
    matplotlib.patches.Ellipse
    """
    from matplotlib.patches import Ellipse

    _axes(ax)
    mean = _vector(mean, "mean", n=2)
    width, height, angle = covariance_ellipse_axes(cov, n_sigma)
    style = _with_defaults(kwargs, fill=False, lw=1.5, label=label)
    if "color" not in style and "edgecolor" not in style and "ec" not in style:
        style["edgecolor"] = COLORS["ellipse"]
    patch = Ellipse(xy=tuple(mean), width=width, height=height, angle=angle, **style)
    ax.add_patch(patch)
    return patch


def plot_belief(ax, belief, *, positions=None, label=None, **kwargs):
    """Draw a discrete belief (histogram filter) as a bar chart.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Where to draw.
    belief : array_like, shape (n,)
        Non-negative weights, one per cell (a belief, a likelihood, ...).
    positions : array_like, shape (n,), optional
        Cell positions; default ``0, 1, ..., n-1``.
    label : str, optional
        Legend label.
    **kwargs
        Passed to ``ax.bar``.

    Returns
    -------
    matplotlib.container.BarContainer
    """
    _axes(ax)
    belief = _vector(belief, "belief")
    if belief.size == 0:
        raise ValueError("belief must have at least one cell")
    if np.any(belief < 0):
        raise ValueError(f"belief must be non-negative, min is {belief.min():.3g}")
    pos = np.arange(belief.size) if positions is None else _vector(positions, "positions", n=belief.size)
    return ax.bar(pos, belief, **_with_defaults(kwargs, color=COLORS["posterior"], width=0.8, label=label))


def plot_samples(ax, points, *, label="samples", **kwargs):
    """Scatter 2-D samples as small grey dots.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Where to draw.
    points : array_like, shape (N, 2)
        Samples, one per row.
    label : str
        Legend label.
    **kwargs
        Passed to ``ax.scatter``.

    Returns
    -------
    matplotlib.collections.PathCollection
    """
    _axes(ax)
    pts = as_rows(points, "points", (2,))
    return ax.scatter(pts[:, 0], pts[:, 1], **_with_defaults(kwargs, s=4, color=COLORS["samples"],
                                                             label=label))


def plot_consistency(ax, t, values, lo, hi, *, label="NEES", **kwargs):
    """Draw a consistency statistic (NEES, NIS) with its chi-square acceptance interval.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Where to draw.
    t : array_like, shape (N,)
        Abscissa.
    values : array_like, shape (N,)
        The statistic per step; NaN (no measurement) is skipped.
    lo, hi : float
        Bounds of the acceptance interval (for example from ``metrics.chi2_bounds``).
    label : str
        Legend label of the statistic.
    **kwargs
        Passed to ``ax.plot``.

    Returns
    -------
    (matplotlib.lines.Line2D, matplotlib.collections.PolyCollection)
        The statistic and the shaded interval.
    """
    _axes(ax)
    t = _vector(t, "t")
    values = _vector(values, "values", allow_nan=True, n=t.shape[0])
    lo, hi = _bounds(lo, hi)
    band = ax.fill_between(t, lo, hi, color=COLORS["band"], alpha=0.5, lw=0,
                           label=f"[{lo:.2f}, {hi:.2f}]")
    (line,) = ax.plot(t, values, **_with_defaults(kwargs, color=COLORS["estimate"], lw=1.0, label=label))
    return line, band


def plot_consistency_curves(ax, t, curves, lo, hi, *, log=True, band_label=None, colors=None, lw=1.0,
                            linestyles=None):
    """Draw several runs of a consistency statistic over one shaded chi-square interval.

    For comparing settings: the NEES of a well-tuned and a badly tuned filter, or of
    several initial covariances, against the interval a consistent filter stays inside.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Where to draw.
    t : array_like, shape (N,)
        Abscissa shared by the curves.
    curves : mapping of str to array_like, shape (N,)
        Legend label -> the statistic per step (NaN skipped); at least one.
    lo, hi : float
        The acceptance interval (for example ``metrics.chi2_bounds(dof, n_runs)``).
    log : bool
        Logarithmic y axis (default), which shows a factor-of-ten error as clearly as a
        factor of ten below.
    band_label : str, optional
        Legend label of the interval; default ``"95 % interval [lo, hi]"``.
    colors : sequence of colour, optional
        One per curve; default :data:`CURVE_COLORS` in order.
    lw : float
        Line width of the curves.
    linestyles : sequence of Matplotlib line styles, optional
        One per curve; default all solid. Give the later curves dashes (``("-", "--")``)
        when they may lie on top of the earlier ones, so that every curve stays visible.

    Returns
    -------
    (list of matplotlib.lines.Line2D, matplotlib.collections.PolyCollection)
        The curves in the order of ``curves``, and the interval.
    """
    _axes(ax)
    t = _vector(t, "t")
    if not hasattr(curves, "items") or len(curves) == 0:
        raise ValueError("curves must be a non-empty mapping of label -> values")
    lo, hi = _bounds(lo, hi)
    log = as_flag(log, "log")
    colors = CURVE_COLORS if colors is None else tuple(colors)
    if len(colors) < len(curves):
        raise ValueError(f"colors must give one colour per curve ({len(curves)}), got {len(colors)}")
    linestyles = ("-",) * len(curves) if linestyles is None else tuple(linestyles)
    if len(linestyles) < len(curves):
        raise ValueError(f"linestyles must give one line style per curve ({len(curves)}), got {len(linestyles)}")
    band = ax.fill_between(t, lo, hi, color=COLORS["band"], alpha=0.5, lw=0,
                           label=band_label or f"95 % interval [{lo:.3g}, {hi:.3g}]")
    lines = []
    for (label, values), color, style in zip(curves.items(), colors, linestyles):
        values = _vector(values, f"curves[{label!r}]", allow_nan=True, n=t.shape[0])
        (line,) = ax.plot(t, values, color=color, lw=lw, ls=style, label=label)
        lines.append(line)
    if log:
        ax.set_yscale("log")
    return lines, band


def plot_track(ax, truth_xy, estimate_xy, measured_xy=None, *, estimate_label="estimate",
               measured_label="measurements"):
    """Draw a 2-D path seen from above: truth, measured positions and the estimate.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Where to draw.
    truth_xy : array_like, shape (N, 2) or (N, 3)
        True positions; only the first two columns (east, north) are drawn.
    estimate_xy : array_like, shape (M, 2) or (M, 3)
        Estimated positions.
    measured_xy : array_like, shape (L, 2) or (L, 3), optional
        Measured positions (grey dots); NaN rows are skipped.
    estimate_label, measured_label : str
        Legend labels.

    Returns
    -------
    list of matplotlib.lines.Line2D
        Truth, measurements (if given) and estimate lines.

    Notes
    -----
    Sets an equal aspect ratio, so that a circle looks like one.
    """
    _axes(ax)
    truth_xy = _points(truth_xy, "truth_xy")
    estimate_xy = _points(estimate_xy, "estimate_xy")
    lines = [plot_truth(ax, truth_xy[:, 0], truth_xy[:, 1])]
    if measured_xy is not None:
        measured_xy = _points(measured_xy, "measured_xy", allow_nan=True)
        lines.append(plot_measurements(ax, measured_xy[:, 0], measured_xy[:, 1], label=measured_label))
    lines.append(plot_estimate(ax, estimate_xy[:, 0], estimate_xy[:, 1], label=estimate_label))
    ax.set_aspect("equal")
    return lines


def shade_spans(ax, spans, *, label=None, **kwargs):
    """Shade intervals of the x axis: outages, interpolated data, outlier bursts.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Where to draw.
    spans : array_like, shape (K, 2)
        (start, end) of each interval, start <= end; K may be 0.
    label : str, optional
        Legend label, given to the first span only.
    **kwargs
        Passed to ``ax.axvspan`` (default light grey, behind the lines).

    Returns
    -------
    list of matplotlib.patches.Polygon
        One per span.
    """
    _axes(ax)
    spans = as_real_array(spans, "spans", allow_empty=True)
    if spans.size % 2:
        raise ValueError(f"spans must be (start, end) pairs, an array of shape (K, 2), got shape {spans.shape}")
    spans = spans.reshape(-1, 2) if spans.size else np.empty((0, 2))
    if not np.all(np.isfinite(spans)):
        raise ValueError("spans must be finite")
    if np.any(spans[:, 1] < spans[:, 0]):
        raise ValueError("spans must be (start, end) pairs with start <= end")
    style = _with_defaults(kwargs, color="0.88", lw=0, zorder=0)
    return [ax.axvspan(a, b, label=label if i == 0 else None, **style) for i, (a, b) in enumerate(spans)]


def flag_spans(t, flags) -> np.ndarray:
    """The intervals of ``t`` where ``flags`` is set, for :func:`shade_spans`.

    Parameters
    ----------
    t : array_like, shape (N,)
        Sample times, increasing.
    flags : array_like of bool, shape (N,)
        True for each flagged sample (for example ``imu.interpolated``).

    Returns
    -------
    numpy.ndarray, shape (K, 2)
        (time of the first, time of the last flagged sample) of each run of consecutive
        flagged samples, in order; K = 0 when nothing is flagged.
    """
    t = _times(t, "t")
    flags = np.asarray(flags)
    if flags.shape != t.shape or flags.dtype != bool:
        raise ValueError(f"flags must be a boolean array of shape {t.shape} (as t), got "
                         f"{flags.dtype} of shape {flags.shape}")
    padded = np.concatenate([[False], flags, [False]]).astype(np.int8)
    change = np.flatnonzero(np.diff(padded))   # run starts, then one past each run's end
    first, last = change[0::2], change[1::2] - 1
    return np.column_stack([t[first], t[last]]) if first.size else np.empty((0, 2))


def plot_curves(ax, curves, *, colors=None, linestyles=None, lw=1.0):
    """Draw several curves, each with its own abscissa, in the course's comparison colours.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Where to draw.
    curves : mapping of str to (array_like (N,), array_like (N,))
        Legend label -> (t, values); NaN values are skipped. At least one.
    colors : sequence of colour, optional
        One per curve; default :data:`CURVE_COLORS` in order.
    linestyles : sequence of Matplotlib line styles, optional
        One per curve (dashes keep a curve visible where it lies on another); default solid.
    lw : float
        Line width.

    Returns
    -------
    list of matplotlib.lines.Line2D
        In the order of ``curves``.
    """
    _axes(ax)
    if not hasattr(curves, "items") or len(curves) == 0:
        raise ValueError("curves must be a non-empty mapping of label -> (t, values)")
    colors = CURVE_COLORS if colors is None else tuple(colors)
    if len(colors) < len(curves):
        raise ValueError(f"colors must give one colour per curve ({len(curves)}), got {len(colors)}")
    linestyles = ("-",) * len(curves) if linestyles is None else tuple(linestyles)
    if len(linestyles) < len(curves):
        raise ValueError(f"linestyles must give one line style per curve ({len(curves)}), got {len(linestyles)}")
    lines = []
    for (label, pair), color, style in zip(curves.items(), colors, linestyles):
        if len(pair) != 2:
            raise ValueError(f"curves[{label!r}] must be a pair (t, values)")
        t = _vector(pair[0], f"curves[{label!r}] t")
        values = _vector(pair[1], f"curves[{label!r}] values", allow_nan=True, n=t.shape[0])
        (line,) = ax.plot(t, values, color=color, linestyle=style, lw=lw, label=label)
        lines.append(line)
    return lines


def _points(value, name: str, *, allow_nan: bool = False) -> np.ndarray:
    """(N, 2) or (N, 3) positions as a float array; all-NaN rows are gaps where ``allow_nan``."""
    arr = as_matrix(value, name, ("N", None), missing_rows=allow_nan)
    if arr.shape[1] not in (2, 3):
        raise ValueError(f"{name} must have shape (N, 2) or (N, 3), got {arr.shape}")
    return arr


def _bounds(lo, hi) -> tuple[float, float]:
    try:
        lo, hi = float(lo), float(hi)
    except (TypeError, ValueError):
        raise ValueError(f"lo and hi must be numbers, got lo={lo!r}, hi={hi!r}") from None
    if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
        raise ValueError(f"need finite bounds with lo <= hi, got lo={lo}, hi={hi}")
    return lo, hi
