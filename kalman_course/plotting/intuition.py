"""Intuition figures of chapters 03, 05 and 06: what the formulas look like.

- chapter 03: :func:`plot_gaussian_product` (prior × likelihood ∝ posterior on one axis)
  and :func:`plot_kf_1d_steps` (one such panel per step of a scalar filter);
  :func:`plot_gain_limits` (the scalar gain against R/P̌ with its two limits);
  :func:`plot_gain_convergence` (P and K of a filter settling to their steady state);
- chapter 05: :func:`plot_radar_linearisation` (a Gaussian cloud through the radar, next
  to the EKF's linearised ellipse);
- chapter 06: :func:`plot_cost_iterates` (the EKF step and the IEKF iterates on the
  contours of the MAP cost of one update).

The numbers come from :mod:`kalman_course.chapters.intuition` (or any object with the
same attributes); nothing here filters. Bad inputs raise ``ValueError`` naming the
argument, and nothing changes global Matplotlib state.
"""

from __future__ import annotations

import numpy as np

from kalman_course.core.gaussians import gaussian_pdf
from kalman_course.plotting.vocabulary import (COLORS, CURVE_COLORS, _covariance2, _vector, plot_covariance_ellipse,
                                               plot_samples)

__all__ = ["plot_gaussian_product", "plot_kf_1d_steps", "plot_gain_limits", "plot_gain_convergence",
           "plot_radar_linearisation", "plot_cost_iterates"]


# --------------------------------------------------------------------------------------
# validation
# --------------------------------------------------------------------------------------

def _moments(pair, name: str) -> tuple[float, float]:
    """(mean, variance) of a 1-D Gaussian, finite, variance > 0."""
    try:
        mean, var = (float(v) for v in pair)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a pair (mean, variance) of numbers, got {pair!r}") from None
    if not (np.isfinite(mean) and np.isfinite(var) and var > 0):
        raise ValueError(f"{name} must have a finite mean and a variance > 0, got ({mean}, {var})")
    return mean, var


def _attribute(obj, attr: str, name: str) -> np.ndarray:
    if not hasattr(obj, attr):
        raise ValueError(f"{name} must have an attribute {attr!r} (as a KF1DTable / KFHistory has)")
    return np.asarray(getattr(obj, attr), dtype=float)


def _density(x, mean, var):
    return gaussian_pdf(x[:, None], [mean], [[var]])


# --------------------------------------------------------------------------------------
# chapter 03
# --------------------------------------------------------------------------------------

def plot_gaussian_product(ax, prior, likelihood, posterior, *, previous=None, x=None, legend=True):
    """Prior, likelihood and posterior densities of one scalar update, on one axis.

    For a measurement y = x + n, n ~ N(0, r), the likelihood of x is N(x; y, r), and the
    posterior is the normalised product prior × likelihood.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Where to draw.
    prior, likelihood, posterior : (float, float)
        (mean, variance) of each; the likelihood's mean is the measurement.
    previous : (float, float), optional
        The posterior of the step before (drawn dotted), to show what prediction did.
    x : array_like, shape (N,), optional
        Abscissa; default ± 4 standard deviations around all the curves.
    legend : bool
        Add a legend.

    Returns
    -------
    dict of str to matplotlib.lines.Line2D
        ``"prior"``, ``"likelihood"``, ``"posterior"`` (and ``"previous"``).
    """
    curves = {"prior": _moments(prior, "prior"), "likelihood": _moments(likelihood, "likelihood"),
              "posterior": _moments(posterior, "posterior")}
    if previous is not None:
        curves = {"previous": _moments(previous, "previous"), **curves}
    if x is None:
        lo = min(m - 4 * np.sqrt(v) for m, v in curves.values())
        hi = max(m + 4 * np.sqrt(v) for m, v in curves.values())
        x = np.linspace(lo, hi, 400)
    x = _vector(x, "x")
    style = {"previous": dict(color=COLORS["posterior"], ls=":", lw=1.2, label="posterior of the step before"),
             "prior": dict(color=COLORS["prior"], lw=1.5, label="prior N(x̌, P̌)"),
             "likelihood": dict(color=COLORS["likelihood"], lw=1.5, label="likelihood N(y, r)"),
             "posterior": dict(color=COLORS["posterior"], lw=2.5, label="posterior N(x̂, P̂)")}
    lines = {}
    for key, (mean, var) in curves.items():
        (lines[key],) = ax.plot(x, _density(x, mean, var), **style[key])
        if key != "previous":
            ax.axvline(mean, color=style[key]["color"], lw=0.8, ls="--")
    ax.set_ylim(bottom=0)
    if legend:
        ax.legend(fontsize=8)
    return lines


def plot_kf_1d_steps(table, *, steps=None, unit="m", figsize=None):
    """Chapter 03: the Gaussian product of each step of a scalar Kalman filter.

    Parameters
    ----------
    table : KF1DTable
        From ``chapters.intuition.kf_1d_table`` (uses ``x_check``, ``P_check``, ``y``,
        ``x_hat``, ``P_hat``, ``r``).
    steps : sequence of int, optional
        Which steps to draw, one panel each (default the first three); steps without a
        measurement cannot be drawn.
    unit : str
        Unit of the state, for the x label.
    figsize : tuple, optional
        Default ``(4 * len(steps), 3.4)``.

    Returns
    -------
    matplotlib.figure.Figure
        One panel per step on a shared x axis, the legend underneath.
    """
    import matplotlib.pyplot as plt

    arrays = {a: _attribute(table, a, "table") for a in ("x_check", "P_check", "y", "K", "x_hat", "P_hat")}
    r = float(_attribute(table, "r", "table"))
    n = arrays["y"].shape[0]
    steps = list(range(min(3, n))) if steps is None else [int(k) for k in steps]
    if not steps:
        raise ValueError("steps must name at least one step")
    for k in steps:
        if not 0 <= k < n:
            raise ValueError(f"steps must be in [0, {n}), got {k}")
        if np.isnan(arrays["y"][k]):
            raise ValueError(f"step {k} has no measurement: there is no product to draw")
    if not (np.isfinite(r) and r > 0):
        raise ValueError(f"table.r must be a variance > 0, got {r}")
    fig, axes = plt.subplots(1, len(steps), figsize=figsize or (4 * len(steps), 3.4), squeeze=False)
    for ax, k in zip(axes[0], steps):
        previous = (arrays["x_hat"][k - 1], arrays["P_hat"][k - 1]) if k > 0 else None
        plot_gaussian_product(ax, (arrays["x_check"][k], arrays["P_check"][k]), (arrays["y"][k], r),
                              (arrays["x_hat"][k], arrays["P_hat"][k]), previous=previous, legend=False)
        ax.set_title(f"step {k}: P̌ = {arrays['P_check'][k]:.3g}, K = {arrays['K'][k]:.3g}", fontsize=10)
        ax.set_xlabel(f"x [{unit}]")
    axes[0][0].set_ylabel(f"density [1/{f'({unit})' if '/' in unit else unit}]")    # a density of x has unit 1/[x]
    handles, labels = [], []
    for ax in axes[0]:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    fig.tight_layout(rect=(0, 0.1, 1, 1))
    fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=8, frameon=False)
    return fig


def plot_gain_limits(ax, ratio, gain, *, points=None, points_label="steps of the filter above"):
    """Chapter 03: the scalar gain K against R / P̌, with its two limits marked.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Where to draw.
    ratio : array_like, shape (N,)
        R / P̌ (> 0), increasing; drawn on a log axis.
    gain : array_like, shape (N,)
        The gain at each ratio (for y = x + n, between 0 and 1).
    points : array_like, shape (M, 2), optional
        (R / P̌, K) pairs to mark on the curve, for example the steps of a filter.
    points_label : str
        Legend label of ``points``.

    Returns
    -------
    matplotlib.lines.Line2D
        The curve.
    """
    ratio = _vector(ratio, "ratio")
    gain = _vector(gain, "gain", n=ratio.shape[0])
    if ratio.size < 2 or np.any(ratio <= 0) or np.any(np.diff(ratio) <= 0):
        raise ValueError("ratio must hold at least two increasing values > 0")
    (line,) = ax.plot(ratio, gain, color=COLORS["estimate"], lw=2, label="K = P̌ / (P̌ + R)")
    ax.set_xscale("log")
    ax.axhline(1.0, color=COLORS["likelihood"], lw=1, ls="--")
    ax.axhline(0.0, color=COLORS["prior"], lw=1, ls="--")
    ax.plot([1.0], [0.5], "o", mfc="none", mec=COLORS["truth"], mew=1.5, ms=11, label="R = P̌: K = ½", zorder=4)
    ax.annotate("R → 0: K → 1 (= G⁻¹)\ntrust the measurement", xy=(ratio[0], 1.0), xytext=(4, -6),
                textcoords="offset points", va="top", ha="left", fontsize=9, color=COLORS["likelihood"])
    ax.annotate("P̌ → 0: K → 0\nignore the measurement", xy=(ratio[-1], 0.0), xytext=(-4, 6),
                textcoords="offset points", va="bottom", ha="right", fontsize=9, color=COLORS["prior"])
    if points is not None:
        pts = np.asarray(points, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 2 or not np.all(np.isfinite(pts)) or np.any(pts[:, 0] <= 0):
            raise ValueError(f"points must have shape (M, 2) with finite entries and R / P̌ > 0, got {pts.shape}")
        ax.plot(pts[:, 0], pts[:, 1], "D", color=COLORS["marker"], ms=5, label=points_label)
    ax.set(xlabel="R / P̌  (measurement variance over prior variance)", ylabel="gain K", ylim=(-0.08, 1.08))
    ax.legend(loc="center left", fontsize=8)
    return line


def plot_gain_convergence(t, hist, *, index=0, steady=None, name="position", unit="m",
                          gain_labels=("position gain [–]", "velocity gain [1/s]"), t_max=None, figsize=(10, 5.5)):
    """Chapter 03: a variance and the gains of a Kalman run settling to their steady state.

    Parameters
    ----------
    t : array_like, shape (N,)
        Times of the steps.
    hist : KFHistory
        From ``kf.run_kf`` (uses ``P_check``, ``P_hat``, ``K``) with one measured component.
    index : int
        Which state's variance to draw.
    steady : SteadyState, optional
        From ``chapters.intuition.steady_state`` (uses ``P_check``, ``P_hat``, ``K``):
        drawn as dashed lines.
    name, unit : str
        For the variance's axis label.
    gain_labels : sequence of str
        Legend label of each row of K (one per state component).
    t_max : float, optional
        Right end of the time axis (default: the whole run).
    figsize : tuple
        Figure size.

    Returns
    -------
    matplotlib.figure.Figure
        Two panels sharing the time axis: the variance before and after each update
        (log scale, joined as a sawtooth), and the gains.
    """
    import matplotlib.pyplot as plt

    t = _vector(t, "t")
    P_check = _attribute(hist, "P_check", "hist")
    P_hat = _attribute(hist, "P_hat", "hist")
    K = _attribute(hist, "K", "hist")
    N = t.shape[0]
    if P_check.ndim != 3 or P_check.shape[0] != N or P_hat.shape != P_check.shape:
        raise ValueError(f"hist must hold P_check and P_hat of shape ({N}, n, n), got {P_check.shape}")
    n = P_check.shape[1]
    if K.ndim != 3 or K.shape[:2] != (N, n) or K.shape[2] != 1:
        raise ValueError(f"hist.K must have shape ({N}, {n}, 1): one measured component, got {K.shape}")
    if not 0 <= index < n:
        raise ValueError(f"index must be in [0, {n}), got {index}")
    if len(gain_labels) != n:
        raise ValueError(f"gain_labels must name each of the {n} rows of K, got {len(gain_labels)}")
    if t_max is not None:
        try:
            t_max = float(t_max)
        except (TypeError, ValueError):
            raise ValueError(f"t_max must be a number, got {t_max!r}") from None
        if not (np.isfinite(t_max) and t_max > t[0]):
            raise ValueError(f"t_max must be a finite time after the first one ({t[0]:g}), got {t_max}")
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=figsize, sharex=True)
    # the sawtooth: each update drops the variance (P̌ -> P̂), each prediction raises it again
    saw_t = np.repeat(t, 2)
    saw_P = np.column_stack([P_check[:, index, index], P_hat[:, index, index]]).reshape(-1)
    ax1.semilogy(saw_t, saw_P, color="0.6", lw=0.8, zorder=1)
    ax1.semilogy(t, P_check[:, index, index], "o", color=COLORS["prior"], ms=3.5,
                 label="prior variance P̌ (after prediction)")
    ax1.semilogy(t, P_hat[:, index, index], "o", color=COLORS["posterior"], ms=3.5,
                 label="posterior variance P̂ (after the update)")
    for k in range(n):
        ax2.plot(t, K[:, k, 0], "o-", color=CURVE_COLORS[k % len(CURVE_COLORS)], lw=1, ms=3.5, label=gain_labels[k])
    if steady is not None:
        sP_check = _attribute(steady, "P_check", "steady")
        sP_hat = _attribute(steady, "P_hat", "steady")
        sK = _attribute(steady, "K", "steady")
        if sP_check.shape != (n, n) or sP_hat.shape != (n, n) or sK.shape != (n, 1):
            raise ValueError(f"steady must hold P_check, P_hat ({n}, {n}) and K ({n}, 1)")
        ax1.axhline(sP_check[index, index], color=COLORS["prior"], ls="--", lw=1)
        ax1.axhline(sP_hat[index, index], color=COLORS["posterior"], ls="--", lw=1, label="steady state")
        for k in range(n):
            ax2.axhline(sK[k, 0], color=CURVE_COLORS[k % len(CURVE_COLORS)], ls="--", lw=1,
                        label="steady state" if k == n - 1 else None)
    ax1.set_ylabel(f"{name} variance [{unit}²]")
    ax1.legend(loc="upper right", fontsize=8)
    ax2.set(xlabel="t [s]", ylabel="gain K")
    ax2.legend(loc="upper right", fontsize=8)
    if t_max is not None:
        ax2.set_xlim(t[0] - 0.02 * (t_max - t[0]), t_max)
    fig.tight_layout()
    return fig


# --------------------------------------------------------------------------------------
# chapter 05
# --------------------------------------------------------------------------------------

def plot_radar_linearisation(clouds, *, titles=None, n_sigma=3, figsize=None):
    """Chapter 05: Gaussian position clouds and their image under the radar model.

    Top row: each cloud in Cartesian coordinates with its ``n_sigma`` ellipse and the
    radar at the origin. Bottom row: the samples' true (φ, ρ), the ellipse of their
    sample moments, and the EKF's linearised ellipse around g(μ) with covariance G P Gᵀ.

    Parameters
    ----------
    clouds : sequence of RadarCloud
        From ``chapters.intuition.radar_cloud`` (uses ``mean_xy``, ``cov_xy``,
        ``samples_xy``, ``samples_polar``, ``lin_mean``, ``lin_cov``, ``sample_mean``,
        ``sample_cov``, ``inside_share``), one column each.
    titles : sequence of str, optional
        One title per column.
    n_sigma : float
        Size of the drawn ellipses.
    figsize : tuple, optional
        Default ``(4.2 * len(clouds), 7.5)``.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    clouds = list(clouds)
    if not clouds:
        raise ValueError("clouds must hold at least one RadarCloud")
    if titles is not None and len(titles) != len(clouds):
        raise ValueError(f"titles must have one entry per cloud ({len(clouds)}), got {len(titles)}")
    fig, axes = plt.subplots(2, len(clouds), figsize=figsize or (4.2 * len(clouds), 7.5), squeeze=False)
    for c, cloud in enumerate(clouds):
        name = f"clouds[{c}]"
        mean_xy = _vector(_attribute(cloud, "mean_xy", name), f"{name}.mean_xy", n=2)
        cov_xy = _covariance2(_attribute(cloud, "cov_xy", name))
        samples_xy = _attribute(cloud, "samples_xy", name)
        polar = _attribute(cloud, "samples_polar", name)
        lin_mean = _vector(_attribute(cloud, "lin_mean", name), f"{name}.lin_mean", n=2)
        lin_cov = _covariance2(_attribute(cloud, "lin_cov", name))
        s_mean = _vector(_attribute(cloud, "sample_mean", name), f"{name}.sample_mean", n=2)
        s_cov = _covariance2(_attribute(cloud, "sample_cov", name))
        share = float(_attribute(cloud, "inside_share", name))
        if samples_xy.ndim != 2 or samples_xy.shape[1] != 2 or polar.shape != samples_xy.shape:
            raise ValueError(f"{name}.samples_xy and .samples_polar must both have shape (N, 2)")
        top, bottom = axes[0, c], axes[1, c]
        plot_samples(top, samples_xy, s=3, label="samples of N(μ, P)")
        plot_covariance_ellipse(top, mean_xy, cov_xy, n_sigma, label=f"{n_sigma:g}σ ellipse of P")
        top.plot([0.0], [0.0], "^", color=COLORS["marker"], ms=9, label="radar")
        # keep the radar in view, with the cloud
        xs = np.r_[samples_xy[:, 0], 0.0]
        ys = np.r_[samples_xy[:, 1], 0.0]
        pad = 0.08 * max(np.ptp(xs), np.ptp(ys))
        top.set(xlim=(xs.min() - pad, xs.max() + pad), ylim=(ys.min() - pad, ys.max() + pad),
                xlabel="x [m]", ylabel="y [m]", aspect="equal")
        if titles is not None:
            top.set_title(titles[c], fontsize=10)
        # bottom: bearing on the x axis, range on the y axis; ellipses swapped to match
        swap = np.array([[0, 1], [1, 0]])
        plot_samples(bottom, polar[:, ::-1], s=3, label="samples through g")
        plot_covariance_ellipse(bottom, s_mean[::-1], swap @ s_cov @ swap, n_sigma, color=COLORS["truth"],
                                ls="--", label="their mean and covariance")
        plot_covariance_ellipse(bottom, lin_mean[::-1], swap @ lin_cov @ swap, n_sigma, color=COLORS["estimate"],
                                lw=2, label="EKF: g(μ), G P Gᵀ")
        bottom.plot(*lin_mean[::-1], "+", color=COLORS["estimate"], ms=10, mew=2)
        bottom.plot(*s_mean[::-1], "x", color=COLORS["truth"], ms=8, mew=1.5)
        bottom.set(xlabel="bearing φ [rad]", ylabel="range ρ [m]")
        bottom.set_title(f"{100 * share:.1f} % inside the EKF's {n_sigma:g}σ ellipse", fontsize=10)
    handles_top, labels_top = axes[0, 0].get_legend_handles_labels()
    handles_bot, labels_bot = axes[1, 0].get_legend_handles_labels()
    fig.tight_layout(rect=(0, 0.06, 1, 1))
    fig.legend(handles_top + handles_bot, labels_top + labels_bot, loc="lower center",
               ncol=len(labels_top + labels_bot), fontsize=8, frameon=False, markerscale=1.5)
    return fig


# --------------------------------------------------------------------------------------
# chapter 06
# --------------------------------------------------------------------------------------

def _levels(J: np.ndarray, count: int) -> np.ndarray:
    """Contour levels above the grid's minimum, spaced geometrically (costs span decades)."""
    lo = float(np.min(J))
    span = float(np.max(J)) - lo
    return lo + span * np.geomspace(1e-3, 1.0, count)


def plot_cost_iterates(U, V, J, path, *, model=None, truth=None, dims=(0, 1),
                       names=("east [m]", "north [m]"), levels=14, figsize=(11, 5.6)):
    """Chapter 06: the EKF's single step and the IEKF's iterates on the contours of the cost.

    Parameters
    ----------
    U, V, J : array_like, shape (nv, nu)
        Grid and cost values (``chapters.intuition.cost_on_plane`` of ``map_cost``).
    path : array_like, shape (k + 1, n)
        x̌ and the iterates (``chapters.intuition.iekf_iterates``): row 1 is the EKF step.
    model : array_like, shape (nv, nu), optional
        The Gauss–Newton model of the cost at x̌ on the same grid, drawn dashed in the
        left panel: the EKF jumps to its minimum.
    truth : array_like, shape (n,), optional
        The true state, marked with a star.
    dims : (int, int)
        The state components on the two axes.
    names : (str, str)
        Axis labels.
    levels : int
        Number of contour levels.
    figsize : tuple
        Figure size.

    Returns
    -------
    matplotlib.figure.Figure
        Left: the EKF step from x̌ (and the quadratic model it minimises); right: the IEKF
        iterates to the minimum of J.
    """
    import matplotlib.pyplot as plt

    U, V, J = (np.asarray(a, dtype=float) for a in (U, V, J))
    if U.ndim != 2 or U.shape != V.shape or U.shape != J.shape or min(U.shape) < 2:
        raise ValueError(f"U, V and J must be 2-D grids of one shape, got {U.shape}, {V.shape}, {J.shape}")
    if not np.all(np.isfinite(J)):
        raise ValueError("J must be finite")
    path = np.asarray(path, dtype=float)
    i, j = (int(d) for d in dims)
    if path.ndim != 2 or path.shape[0] < 2 or not 0 <= max(i, j) < path.shape[1] or i == j:
        raise ValueError(f"path must have shape (k + 1, n) with k >= 1 and dims two of its columns, got {path.shape}")
    if model is not None:
        model = np.asarray(model, dtype=float)
        if model.shape != J.shape or not np.all(np.isfinite(model)):
            raise ValueError(f"model must be finite with the shape of J {J.shape}")
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=figsize, sharex=True, sharey=True)
    cost_levels = _levels(J, levels)
    for ax in (ax1, ax2):
        ax.contour(U, V, J, levels=cost_levels, colors="0.55", linewidths=0.8)
        ax.plot(*path[0, [i, j]], "o", color=COLORS["prior"], ms=9, label="prior mean x̌", zorder=5)
        if truth is not None:
            tr = _vector(truth, "truth", n=path.shape[1])
            ax.plot(tr[i], tr[j], "*", color=COLORS["truth"], ms=14, label="truth", zorder=7)
        ax.set(xlabel=names[0], ylabel=names[1], aspect="equal")
    if model is not None:
        ax1.contour(U, V, model, levels=_levels(model, max(levels // 2, 2)), colors=COLORS["prior"],
                    linewidths=0.9, linestyles="--")
        ax1.plot([], [], "--", color=COLORS["prior"], lw=0.8, label="quadratic model at x̌")
    ax1.plot([], [], color="0.55", lw=0.8, label="cost J(x)")
    ax1.annotate("", xy=path[1, [i, j]], xytext=path[0, [i, j]],
                 arrowprops=dict(arrowstyle="-|>", color=COLORS["marker"], lw=2))
    ax1.plot(*path[1, [i, j]], "s", color=COLORS["marker"], ms=8, label="EKF x̂ (one step)", zorder=6)
    ax1.set_title("EKF: one Gauss–Newton step from x̌", fontsize=10)
    ax2.plot(path[:, i], path[:, j], "-", color=COLORS["estimate"], lw=1.5, zorder=4)
    ax2.plot(path[1:, i], path[1:, j], "o", color=COLORS["estimate"], ms=5, label="IEKF iterates 1, 2, …",
             zorder=6)
    ax2.annotate("1 = EKF", path[1, [i, j]], xytext=(7, 2), textcoords="offset points", fontsize=9,
                 color=COLORS["estimate"])
    ax2.plot(*path[-1, [i, j]], "D", mfc="none", mec=COLORS["estimate"], mew=1.5, ms=15,
             label=f"IEKF x̂ (after {path.shape[0] - 1})", zorder=6)
    ax2.set_title("IEKF: relinearise at each iterate, down to the minimum of J", fontsize=10)
    for ax in (ax1, ax2):
        ax.legend(loc="upper left", bbox_to_anchor=(0.0, -0.12), ncol=2, fontsize=8, frameon=False)
    fig.subplots_adjust(left=0.07, right=0.98, top=0.94, bottom=0.2, wspace=0.12)
    return fig
