"""One plotting vocabulary for the whole course.

Every chapter draws the same things the same way: the truth is a black line, measurements
are grey dots, the estimate is a blue line with a light-blue ±3σ band, covariances are
ellipses. The basic functions take a Matplotlib ``ax`` and return the artists they add,
so cells can add titles, limits and legends as they like. Small per-chapter helpers
(:func:`plot_belief_sequence`, :func:`plot_conditioning`, :func:`plot_kf_1d`,
:func:`plot_kf_2d`) build whole figures so that notebook cells stay short.

Nothing here changes global state: no ``rcParams``, no style sheets. Colours come from
:data:`COLORS`; any keyword argument (``color=...``, ``label=...``) overrides them.

Bad inputs (wrong shapes, lengths that do not match, NaN where a value is needed, a
covariance that is not symmetric positive semi-definite) raise ``ValueError`` naming the
argument.
"""

from __future__ import annotations

import types
import numpy as np

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
    "plot_belief_sequence",
    "plot_conditioning",
    "plot_kf_1d",
    "plot_kf_2d",
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


# --------------------------------------------------------------------------------------
# validation
# --------------------------------------------------------------------------------------

def _vector(value, name: str, *, allow_nan: bool = False, n: int | None = None) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a 1-D array of numbers, got {type(value).__name__}") from None
    if arr.ndim == 2 and 1 in arr.shape and arr.size > 0:
        arr = arr.reshape(-1)  # accept (N, 1) columns such as ys[:, None]
    if arr.ndim != 1:
        raise ValueError(f"{name} must be 1-D, got shape {arr.shape}")
    if n is not None and arr.shape[0] != n:
        raise ValueError(f"{name} must have length {n} (as t), got {arr.shape[0]}")
    bad = np.isinf(arr) if allow_nan else ~np.isfinite(arr)
    if np.any(bad):
        what = "inf" if allow_nan else "NaN or inf"
        raise ValueError(f"{name} must not contain {what}")
    return arr


def _check_n_sigma(n_sigma) -> float:
    try:
        value = float(n_sigma)
    except (TypeError, ValueError):
        raise ValueError(f"n_sigma must be a positive number, got {n_sigma!r}") from None
    if not np.isfinite(value) or value <= 0:
        raise ValueError(f"n_sigma must be a positive number, got {n_sigma!r}")
    return value


def _sigma(value, name: str, n: int) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    arr = _vector(arr, name, n=n)
    if np.any(arr < 0):
        raise ValueError(f"{name} must be >= 0 (a standard deviation), min is {arr.min():.3g}")
    return arr


def _covariance2(cov, name: str = "cov") -> np.ndarray:
    arr = np.asarray(cov, dtype=float)
    if arr.shape != (2, 2):
        raise ValueError(f"{name} must be a 2x2 covariance matrix, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite")
    scale = max(np.max(np.abs(arr)), 1e-300)
    if abs(arr[0, 1] - arr[1, 0]) > 1e-9 * scale:
        raise ValueError(f"{name} must be symmetric, |{name}[0,1] - {name}[1,0]| = "
                         f"{abs(arr[0, 1] - arr[1, 0]):.3g}")
    eig = np.linalg.eigvalsh(0.5 * (arr + arr.T))
    if eig[0] < -1e-12 * scale:
        raise ValueError(f"{name} must be positive semi-definite, smallest eigenvalue {eig[0]:.3g}")
    return 0.5 * (arr + arr.T)


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
    t = _vector(t, "t")
    n = t.shape[0]
    c = np.asarray(center, dtype=float)
    c = _vector(np.full(n, float(c)) if c.ndim == 0 else c, "center", n=n)
    s = _sigma(sigma, "sigma", n)
    k = _check_n_sigma(n_sigma)
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
    k = _check_n_sigma(n_sigma)
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
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ValueError(f"points must have shape (N, 2), got {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise ValueError("points must be finite")
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
    t = _vector(t, "t")
    values = _vector(values, "values", allow_nan=True, n=t.shape[0])
    lo, hi = float(lo), float(hi)
    if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
        raise ValueError(f"need finite bounds with lo <= hi, got lo={lo}, hi={hi}")
    band = ax.fill_between(t, lo, hi, color=COLORS["band"], alpha=0.5, lw=0,
                           label=f"[{lo:.2f}, {hi:.2f}]")
    (line,) = ax.plot(t, values, **_with_defaults(kwargs, color=COLORS["estimate"], lw=1.0, label=label))
    return line, band


# --------------------------------------------------------------------------------------
# per-chapter figures
# --------------------------------------------------------------------------------------

def plot_belief_sequence(beliefs, *, titles=None, true_cells=None, doors=None, figsize=None):
    """Chapter 01: one bar chart per belief, stacked, with the true cell and the doors.

    Parameters
    ----------
    beliefs : sequence of array_like, each shape (n,)
        The beliefs to show, top to bottom.
    titles : sequence of str, optional
        One title per panel.
    true_cells : sequence of int, optional
        The robot's true cell in each panel (a red line).
    doors : array_like of bool, shape (n,), optional
        Which cells have a door (shaded grey in every panel).
    figsize : tuple, optional
        Figure size; default ``(8, 1.8 * len(beliefs))``.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    beliefs = [_vector(b, f"beliefs[{i}]") for i, b in enumerate(beliefs)]
    if not beliefs:
        raise ValueError("beliefs must contain at least one belief")
    n = beliefs[0].size
    for i, b in enumerate(beliefs):
        if b.size != n:
            raise ValueError(f"beliefs[{i}] has {b.size} cells, beliefs[0] has {n}")
    k = len(beliefs)
    for name, seq in (("titles", titles), ("true_cells", true_cells)):
        if seq is not None and len(seq) != k:
            raise ValueError(f"{name} must have one entry per belief ({k}), got {len(seq)}")
    door_mask = None
    if doors is not None:
        door_mask = np.asarray(doors, dtype=bool)
        if door_mask.shape != (n,):
            raise ValueError(f"doors must have shape ({n},), got {door_mask.shape}")
    fig, axes = plt.subplots(k, 1, figsize=figsize or (8, 1.8 * k), sharex=True, squeeze=False)
    axes = axes[:, 0]
    top = max(float(np.max(b)) for b in beliefs) * 1.1 or 1.0
    for i, (ax, b) in enumerate(zip(axes, beliefs)):
        if door_mask is not None:
            for c in np.flatnonzero(door_mask):
                ax.axvspan(c - 0.5, c + 0.5, color="0.9", lw=0,
                           label="door" if c == np.flatnonzero(door_mask)[0] else None)
        plot_belief(ax, b, label="belief")
        if true_cells is not None:
            ax.axvline(true_cells[i], color=COLORS["marker"], lw=2, label="true cell")
        if titles is not None:
            ax.set_title(titles[i], fontsize=10)
        ax.set_ylim(0, top)
        ax.set_ylabel("p")
    axes[0].legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("cell")
    axes[-1].xaxis.set_major_locator(MaxNLocator(integer=True))
    fig.tight_layout()
    return fig


def plot_conditioning(mean, cov, y_obs, cond_mean, cond_var, *, samples=None, n_sigma=2,
                      names=("x", "y"), figsize=(10, 4)):
    """Chapter 02: a joint Gaussian of (x, y), the slice y = y_obs, and p(x) vs p(x | y).

    Parameters
    ----------
    mean : array_like, shape (2,)
        Joint mean ``[mu_x, mu_y]``.
    cov : array_like, shape (2, 2)
        Joint covariance.
    y_obs : float
        Observed value of y.
    cond_mean, cond_var : float
        Mean and variance of ``p(x | y = y_obs)`` (from ``gaussians.conditional``).
    samples : array_like, shape (N, 2), optional
        Samples of the joint to scatter.
    n_sigma : float
        Radius of the drawn ellipses.
    names : (str, str)
        Names of the two variables for the axis labels.
    figsize : tuple
        Figure size.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    from kalman_course.core.gaussians import gaussian_pdf

    mean = _vector(mean, "mean", n=2)
    cov = _covariance2(cov)
    y_obs, cond_mean, cond_var = float(y_obs), float(cond_mean), float(cond_var)
    if not all(np.isfinite([y_obs, cond_mean, cond_var])) or cond_var <= 0:
        raise ValueError("y_obs and cond_mean must be finite and cond_var > 0")
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=figsize)
    if samples is not None:
        plot_samples(ax1, samples)
    for k in range(1, int(np.floor(n_sigma)) + 1):
        plot_covariance_ellipse(ax1, mean, cov, k, label=f"joint {k}σ" if k == int(n_sigma) else None)
    ax1.axhline(y_obs, color=COLORS["marker"], lw=1.5, label=f"observed {names[1]} = {y_obs:g}")
    ax1.plot([cond_mean], [y_obs], "o", color=COLORS["posterior"], label="conditional mean")
    ax1.set(xlabel=names[0], ylabel=names[1], title="joint density")
    ax1.legend(loc="upper left", fontsize=8)
    sx = np.sqrt(cov[0, 0])
    grid = np.linspace(mean[0] - 4 * sx, mean[0] + 4 * sx, 400)
    ax2.plot(grid, gaussian_pdf(grid[:, None], mean[:1], cov[:1, :1]), color=COLORS["prior"],
             label=f"marginal p({names[0]})")
    ax2.plot(grid, gaussian_pdf(grid[:, None], [cond_mean], [[cond_var]]), color=COLORS["posterior"],
             label=f"conditional p({names[0]} | {names[1]})")
    ax2.set(xlabel=names[0], ylabel="density", title="marginal vs conditional")
    ax2.legend(fontsize=8)
    fig.tight_layout()
    return fig


def _history_component(hist, index: int, n: int):
    x_hat = np.asarray(getattr(hist, "x_hat", None), dtype=float)
    P_hat = np.asarray(getattr(hist, "P_hat", None), dtype=float)
    if x_hat.ndim != 2 or P_hat.ndim != 3 or P_hat.shape[0] != x_hat.shape[0]:
        raise ValueError("hist must have x_hat (N, n) and P_hat (N, n, n), as a KFHistory")
    if x_hat.shape[0] != n:
        raise ValueError(f"hist has {x_hat.shape[0]} steps, t has {n}")
    if not 0 <= index < x_hat.shape[1]:
        raise ValueError(f"index must be in [0, {x_hat.shape[1]}), got {index}")
    return x_hat, P_hat


def plot_kf_1d(t, truth, ys, hist, *, index=0, n_sigma=3, name="position", unit="m",
               figsize=(10, 6)):
    """Chapter 03: one state component of a Kalman run, and its error with the ±3σ band.

    Parameters
    ----------
    t : array_like, shape (N,)
        Times of the steps.
    truth : array_like, shape (N,)
        True value of the component.
    ys : array_like, shape (N,) or (N, 1), optional
        Measurements of the component (NaN = none); None to draw none.
    hist : KFHistory
        Result of ``kf.run_kf`` (uses ``x_hat`` and ``P_hat``).
    index : int
        Which state component to show.
    n_sigma : float
        Half-width of the bands (default 3).
    name, unit : str
        For the axis labels.
    figsize : tuple
        Figure size.

    Returns
    -------
    matplotlib.figure.Figure
        Two panels sharing the time axis.
    """
    import matplotlib.pyplot as plt

    t = _vector(t, "t")
    truth = _vector(truth, "truth", n=t.shape[0])
    x_hat, P_hat = _history_component(hist, index, t.shape[0])
    est = x_hat[:, index]
    sigma = np.sqrt(np.clip(P_hat[:, index, index], 0.0, None))
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=figsize, sharex=True)
    plot_sigma_band(ax1, t, est, sigma, n_sigma)
    plot_truth(ax1, t, truth)
    if ys is not None:
        plot_measurements(ax1, t, ys)
    plot_estimate(ax1, t, est)
    ax1.set_ylabel(f"{name} [{unit}]")
    ax1.legend(loc="best", fontsize=8)
    plot_error_with_band(ax2, t, est - truth, sigma, n_sigma)
    ax2.set(xlabel="t [s]", ylabel=f"error [{unit}]")
    ax2.legend(loc="best", fontsize=8)
    fig.tight_layout()
    return fig


def plot_kf_2d(t, truth_xy, meas_xy, hist, *, indices=(0, 1), n_sigma=3, ellipse_every=10,
               names=("east", "north"), figsize=(12, 5)):
    """Chapter 03: a 2-D track (truth, measurements, estimate, covariance ellipses) and the
    error of each coordinate with its ±3σ band.

    Parameters
    ----------
    t : array_like, shape (N,)
        Times of the steps.
    truth_xy : array_like, shape (N, 2)
        True positions.
    meas_xy : array_like, shape (N, 2)
        Measured positions (NaN rows = none).
    hist : KFHistory
        Result of ``kf.run_kf``; positions are the state components ``indices``.
    indices : (int, int)
        State components holding the two coordinates (``(0, 1)`` in the blocked CV
        state ``[p_x, p_y, v_x, v_y]``).
    n_sigma : float
        Size of ellipses and bands.
    ellipse_every : int
        Draw an ellipse every this many steps (0 for none).
    names : (str, str)
        Axis names.
    figsize : tuple
        Figure size.

    Returns
    -------
    matplotlib.figure.Figure
        The track on the left, the two error panels on the right.
    """
    import matplotlib.pyplot as plt

    t = _vector(t, "t")
    n = t.shape[0]
    truth_xy = np.asarray(truth_xy, dtype=float)
    meas_xy = np.asarray(meas_xy, dtype=float)
    for arr, label in ((truth_xy, "truth_xy"), (meas_xy, "meas_xy")):
        if arr.shape != (n, 2):
            raise ValueError(f"{label} must have shape ({n}, 2), got {arr.shape}")
    i, j = (int(k) for k in indices)
    x_hat, P_hat = _history_component(hist, max(i, j), n)
    if isinstance(ellipse_every, bool) or not isinstance(ellipse_every, (int, np.integer)) or ellipse_every < 0:
        raise ValueError(f"ellipse_every must be an integer >= 0, got {ellipse_every!r}")
    fig = plt.figure(figsize=figsize)
    grid = fig.add_gridspec(2, 2, width_ratios=(1.1, 1))
    ax_map = fig.add_subplot(grid[:, 0])
    ax_e1 = fig.add_subplot(grid[0, 1])
    ax_e2 = fig.add_subplot(grid[1, 1], sharex=ax_e1)
    plot_truth(ax_map, truth_xy[:, 0], truth_xy[:, 1])
    plot_measurements(ax_map, meas_xy[:, 0], meas_xy[:, 1])
    plot_estimate(ax_map, x_hat[:, i], x_hat[:, j])
    if ellipse_every:
        block = np.ix_([i, j], [i, j])
        for k in range(0, n, ellipse_every):
            plot_covariance_ellipse(ax_map, x_hat[k, [i, j]], P_hat[k][block], n_sigma,
                                    label=f"±{n_sigma:g}σ ellipse" if k == 0 else None)
    ax_map.set(xlabel=f"{names[0]} [m]", ylabel=f"{names[1]} [m]", aspect="equal")
    ax_map.legend(loc="best", fontsize=8)
    for ax, col, k, name in ((ax_e1, 0, i, names[0]), (ax_e2, 1, j, names[1])):
        plot_error_with_band(ax, t, x_hat[:, k] - truth_xy[:, col],
                             np.sqrt(np.clip(P_hat[:, k, k], 0, None)), n_sigma)
        ax.set_ylabel(f"{name} error [m]")
    ax_e1.legend(loc="upper right", fontsize=8)
    ax_e2.set_xlabel("t [s]")
    fig.tight_layout()
    return fig
