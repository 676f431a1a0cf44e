"""Chapter 08 figures: the error-state Kalman filter on KITTI.

Each function builds one whole figure of the lecture from arrays (or, for
:func:`plot_bias_sigmas`, from filter results), so that a lecture cell is one call and
``plt.show()``. Angles come in radians and are drawn in degrees; gyroscope biases are
drawn in deg/h. The ESKF's error state is ordered [δp, δv, δθ, δb_a, δb_ω] (15), so its
standard deviations ``std`` (N, 15) have position in columns 0–2, attitude in 6–8, the
accelerometer bias in 9–11 and the gyroscope bias in 12–14.
"""

from __future__ import annotations

import numpy as np

from kalman_course.core.validation import as_rows, as_scalar
from kalman_course.plotting.vocabulary import (COLORS, CURVE_COLORS, _points, _sigma, _times, _vector, plot_curves,
                                               plot_error_with_band, plot_sigma_band, plot_track, shade_spans)

__all__ = ["plot_track_with_zoom", "plot_pose_errors", "plot_bias_estimates", "plot_bias_sigmas",
           "plot_outage_error", "plot_error_norms"]

_AXES = "xyz"
_RAD_PER_S_TO_DEG_PER_H = np.rad2deg(1.0) * 3600.0


def _rows(value, name: str, n: int, columns: int) -> np.ndarray:
    """``value`` as a finite float array of shape (n, columns): one row per time in t."""
    return as_rows(value, name, (columns,), n)


def plot_track_with_zoom(truth_xy, estimate_xy, measured_xy=None, *, zoom, title="", zoom_title="zoom",
                         estimate_label="ESKF", measured_label="lidar poses", figsize=(13, 5)):
    """The path from above, whole and zoomed: truth, measured positions and the estimate.

    Parameters
    ----------
    truth_xy : array_like, shape (N, 2) or (N, 3)
        True positions (east, north[, up]), m.
    estimate_xy : array_like, shape (M, 2) or (M, 3)
        The filter's positions, m.
    measured_xy : array_like, shape (L, 2) or (L, 3), optional
        Measured positions, m.
    zoom : ((float, float), (float, float))
        (east limits, north limits) of the right panel, m.
    title, zoom_title : str
        Titles of the left (whole) and right (zoomed) panels.
    estimate_label, measured_label : str
        Legend labels.
    figsize : tuple
        Figure size.

    Returns
    -------
    matplotlib.figure.Figure
        Two panels; the legend is on the zoomed one.
    """
    import matplotlib.pyplot as plt

    try:
        (x0, x1), (y0, y1) = zoom
        x0, x1, y0, y1 = (float(v) for v in (x0, x1, y0, y1))
    except (TypeError, ValueError):
        raise ValueError(f"zoom must be ((east_min, east_max), (north_min, north_max)), got {zoom!r}") from None
    if not (x0 < x1 and y0 < y1):
        raise ValueError(f"zoom limits must increase, got {zoom!r}")
    truth_xy, estimate_xy = _points(truth_xy, "truth_xy"), _points(estimate_xy, "estimate_xy")
    if measured_xy is not None:
        measured_xy = _points(measured_xy, "measured_xy", allow_nan=True)
    fig, axes = plt.subplots(1, 2, figsize=figsize)
    for ax in axes:
        plot_track(ax, truth_xy, estimate_xy, measured_xy, estimate_label=estimate_label,
                   measured_label=measured_label)
        ax.set(xlabel="east [m]", ylabel="north [m]")
    axes[0].set_title(title)
    axes[1].set(xlim=(x0, x1), ylim=(y0, y1), title=zoom_title)
    axes[1].legend()
    fig.tight_layout()
    return fig


def plot_pose_errors(t, position_error, attitude_error, std, *, n_sigma=3, figsize=(13, 6)):
    """A 2×3 grid: position and attitude error per axis, each with the filter's ±3σ band.

    Parameters
    ----------
    t : array_like, shape (N,)
        Times, s.
    position_error : array_like, shape (N, 3)
        Estimate − truth, m.
    attitude_error : array_like, shape (N, 3)
        Rotation-vector attitude error, rad (drawn in degrees).
    std : array_like, shape (N, 15)
        The filter's standard deviations of the error state (position in columns 0–2,
        attitude in 6–8), e.g. ``result.std()``.
    n_sigma : float
        Half-width of the bands.
    figsize : tuple
        Figure size.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    t = _times(t, "t")
    n = t.shape[0]
    position_error = _rows(position_error, "position_error", n, 3)
    attitude_error = _rows(attitude_error, "attitude_error", n, 3)
    std = _rows(std, "std", n, 15)
    n_sigma = as_scalar(n_sigma, "n_sigma")
    fig, axes = plt.subplots(2, 3, figsize=figsize, sharex=True)
    for i, axis in enumerate(_AXES):
        plot_error_with_band(axes[0, i], t, position_error[:, i], std[:, i], n_sigma)
        axes[0, i].set(title=f"position error {axis}", ylabel="error [m]")
        plot_error_with_band(axes[1, i], t, np.rad2deg(attitude_error[:, i]), np.rad2deg(std[:, 6 + i]), n_sigma)
        axes[1, i].set(title=f"attitude error {axis}", ylabel="error [deg]", xlabel="t [s]")
    axes[0, 0].legend()
    fig.tight_layout()
    return fig


def plot_bias_estimates(t, accel_bias, gyro_bias, *, accel_sigma=None, gyro_sigma=None, n_sigma=3,
                        figsize=(12, 5)):
    """The estimated accelerometer (m/s²) and gyroscope (deg/h) biases, one panel per axis.

    With the filter's σ of each bias, each panel also shades the estimate ± n_sigma·σ, so
    that "indistinguishable from zero" can be read off: zero inside the band.

    Parameters
    ----------
    t : array_like, shape (N,)
        Times, s.
    accel_bias : array_like, shape (N, 3)
        b_a, m/s².
    gyro_bias : array_like, shape (N, 3)
        b_ω, rad/s (drawn in deg/h).
    accel_sigma, gyro_sigma : array_like, shape (N, 3), optional
        The filter's σ of b_a (m/s²) and of b_ω (rad/s), e.g. ``res.std()[:, 9:12]`` and
        ``res.std()[:, 12:15]``; both or neither.
    n_sigma : float
        Half-width of the bands.
    figsize : tuple
        Figure size.

    Returns
    -------
    matplotlib.figure.Figure
        Two rows (accelerometer, gyroscope) of three panels (x, y, z).
    """
    import matplotlib.pyplot as plt

    t = _times(t, "t")
    n = t.shape[0]
    if (accel_sigma is None) != (gyro_sigma is None):
        raise ValueError("accel_sigma and gyro_sigma must be given together (or neither)")
    rows = [("b_a", "m/s²", _rows(accel_bias, "accel_bias", n, 3), 1.0, accel_sigma, "accel_sigma"),
            ("b_ω", "deg/h", _rows(gyro_bias, "gyro_bias", n, 3), _RAD_PER_S_TO_DEG_PER_H, gyro_sigma, "gyro_sigma")]
    rows = [(symbol, unit, values, scale, None if sigma is None else _rows(sigma, sigma_name, n, 3))
            for symbol, unit, values, scale, sigma, sigma_name in rows]
    n_sigma = as_scalar(n_sigma, "n_sigma")
    fig, axes = plt.subplots(2, 3, figsize=figsize, sharex=True)
    for row, (symbol, unit, values, scale, sigma) in zip(axes, rows):
        for i, (ax, axis) in enumerate(zip(row, _AXES)):
            if sigma is not None:
                plot_sigma_band(ax, t, values[:, i] * scale, sigma[:, i] * scale, n_sigma)
            ax.plot(t, values[:, i] * scale, color=CURVE_COLORS[i], label=f"{symbol} {axis} estimate")
            ax.axhline(0.0, color="black", lw=0.6)
            ax.set(ylabel=f"{symbol} {axis} [{unit}]")
            ax.legend(loc="upper right", fontsize=7)
    for ax in axes[1]:
        ax.set_xlabel("t [s]")
    fig.tight_layout()
    return fig


def plot_bias_sigmas(results, *, axis=2, figsize=(12, 3.5)):
    """The filters' own σ of the accelerometer and gyroscope bias on one axis, log scale.

    Parameters
    ----------
    results : mapping of str to EskfResult
        Legend label -> a filter run (uses ``.t`` and ``.std()``); at least one.
    axis : int
        0, 1 or 2 for x, y, z.
    figsize : tuple
        Figure size.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    if not hasattr(results, "items") or len(results) == 0:
        raise ValueError("results must be a non-empty mapping of label -> ESKF result")
    if axis not in (0, 1, 2):
        raise ValueError(f"axis must be 0, 1 or 2, got {axis!r}")
    accel, gyro = {}, {}
    for label, result in results.items():
        if not (hasattr(result, "t") and callable(getattr(result, "std", None))):
            raise ValueError(f"results[{label!r}] must be an ESKF result with .t and .std()")
        std = result.std()
        accel[label] = (result.t, std[:, 9 + axis])
        gyro[label] = (result.t, std[:, 12 + axis] * _RAD_PER_S_TO_DEG_PER_H)
    fig, axes = plt.subplots(1, 2, figsize=figsize)
    # runs may coincide for most of the time: later runs dashed so that every one shows
    styles = ["-", (0, (5, 3)), (0, (1, 2)), (0, (6, 2, 1, 2))] * len(results)
    plot_curves(axes[0], accel, linestyles=styles, lw=1.5)
    plot_curves(axes[1], gyro, linestyles=styles, lw=1.5)
    axes[0].set(xlabel="t [s]", ylabel="σ of b_a [m/s²]", title=f"σ of the accelerometer bias, {_AXES[axis]}")
    axes[1].set(xlabel="t [s]", ylabel="σ of b_ω [deg/h]", title=f"σ of the gyroscope bias, {_AXES[axis]}")
    for ax in axes:
        ax.set_yscale("log")
        ax.legend()
    fig.tight_layout()
    return fig


def plot_outage_error(t, error, sigma, outage, *, n_sigma=3, title="", label="horizontal error",
                      outage_label="no observations", figsize=(9, 3.5)):
    """The size of an error through an outage of the observations, under the filter's bound.

    The error drawn is a norm (never negative), so the band is one-sided: from 0 to
    ``n_sigma`` times the filter's RMS of that norm.

    Parameters
    ----------
    t : array_like, shape (N,)
        Times, s.
    error : array_like, shape (N,)
        The norm of the error (e.g. the horizontal error ‖e_xy‖), m; not negative.
    sigma : array_like, shape (N,)
        The filter's RMS of that norm, m: √(trace of the error's covariance block), e.g.
        √(P_xx + P_yy).
    outage : (float, float)
        Start and end of the outage, s (shaded grey).
    n_sigma : float
        Height of the band in units of ``sigma``.
    title, label : str
        Title and legend label of the error.
    outage_label : str
        Legend label of the shaded outage.
    figsize : tuple
        Figure size.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    try:
        start, end = (float(v) for v in outage)
    except (TypeError, ValueError):
        raise ValueError(f"outage must be (start, end) in s, got {outage!r}") from None
    if not (np.isfinite(start) and np.isfinite(end) and start <= end):
        raise ValueError(f"outage must be finite with start <= end, got {outage!r}")
    t = _times(t, "t")
    error = _vector(error, "error", n=t.shape[0])
    if np.any(error < 0):
        raise ValueError("error must be a norm (not negative); draw a signed error with plot_error_with_band")
    sigma = _sigma(sigma, "sigma", t.shape[0])
    n_sigma = as_scalar(n_sigma, "n_sigma")
    fig, ax = plt.subplots(figsize=figsize)
    shade_spans(ax, [(start, end)], label=outage_label, color="0.93")
    # a band from 0 to n·σ: centred at n·σ/2 with half-width n·σ/2
    half = 0.5 * sigma
    plot_sigma_band(ax, t, n_sigma * half, half, n_sigma, label=f"0 to {n_sigma:g}σ")
    ax.plot(t, error, color=COLORS["estimate"], lw=1.0, label=label)
    ax.set(xlabel="t [s]", ylabel=f"{label} [m]", title=title, ylim=(0, None))
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0))  # beside the axes: the band fills the top
    fig.tight_layout()
    return fig


def plot_error_norms(curves, *, spans=None, span_label=None, colors=None, title="",
                     ylabel="position error [m]", figsize=(11, 3.5)):
    """Error norms of several runs over time, with shaded spans (e.g. interpolated IMU data).

    Parameters
    ----------
    curves : mapping of str to (array_like (N,), array_like (N,))
        Legend label -> (t, |error|).
    spans : array_like, shape (K, 2), optional
        Intervals to shade, e.g. ``flag_spans(imu.t, imu.interpolated)``.
    span_label : str, optional
        Legend label of the spans.
    colors : sequence of colour, optional
        One per curve (default the course's comparison colours).
    title, ylabel : str
        Title and y label.
    figsize : tuple
        Figure size.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=figsize)
    if spans is not None:
        shade_spans(ax, spans, label=span_label)
    plot_curves(ax, curves, colors=colors, lw=0.8)
    ax.set(xlabel="t [s]", ylabel=ylabel, title=title)
    ax.legend()
    fig.tight_layout()
    return fig
