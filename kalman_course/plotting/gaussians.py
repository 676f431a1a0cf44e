"""Chapter 02 figures: joint, marginal and conditional Gaussians."""

from __future__ import annotations

import numpy as np

from kalman_course.core.validation import as_real, as_scalar
from kalman_course.plotting.vocabulary import (COLORS, _covariance2, _vector, plot_covariance_ellipse,
                                               plot_samples)

__all__ = ["plot_conditioning", "plot_conditional_slice"]


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
    y_obs, cond_mean = as_real(y_obs, "y_obs"), as_real(cond_mean, "cond_mean")
    cond_var = as_scalar(cond_var, "cond_var")
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


def plot_conditional_slice(mean, cov, y_obs, *, samples=None, slice_x=None, n_sigma=(1, 2), band_sigma=3,
                           names=("x", "y"), figsize=(7, 7.5)):
    """Chapter 02: p(x | y) as the slice of a joint Gaussian along the measured y.

    Top: the joint's ellipses, the regression line E[x | y], the measured value of y as a
    horizontal line, and on it the conditional density (drawn upwards from the line, its
    height not in units of y), its mean and its ±``band_sigma``σ interval. Bottom, on the same
    x axis: the marginal p(x) before the measurement, the conditional p(x | y) after it,
    and optionally a histogram of Monte Carlo draws of x whose y fell near the measured one.
    Colours: joint and marginal as the prior, the conditional as the estimate, the measured
    y as a measurement, the simulated draws as truths.

    Parameters
    ----------
    mean : array_like, shape (2,)
        Joint mean ``[mu_x, mu_y]``.
    cov : array_like, shape (2, 2)
        Joint covariance, positive definite (``cov[1, 1] > 0``).
    y_obs : float
        The measured value of y.
    samples : array_like, shape (N, 2), optional
        Draws of the joint to scatter in the top panel.
    slice_x : array_like, shape (K,), optional
        The x of draws whose y fell within a narrow window around ``y_obs``.
    n_sigma : sequence of float
        Radii of the joint's ellipses (default 1 and 2).
    band_sigma : float
        Half-width of the conditional's interval drawn on the slice, in its standard
        deviations (default 3).
    names : (str, str)
        Names of the two variables.
    figsize : tuple
        Figure size.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    from kalman_course.core.gaussians import conditional, gaussian_pdf

    mean = _vector(mean, "mean", n=2)
    cov = _covariance2(cov)
    if not cov[1, 1] > 0:
        raise ValueError("cov[1, 1] must be > 0: y needs a spread to be conditioned on")
    y_obs = float(_vector([y_obs], "y_obs", n=1)[0])
    radii = [as_scalar(k, "n_sigma") for k in np.atleast_1d(n_sigma)]
    if not radii:
        raise ValueError("n_sigma must name at least one ellipse radius")
    band = as_scalar(band_sigma, "band_sigma")
    if slice_x is not None:
        slice_x = _vector(slice_x, "slice_x")
    x_name, y_name = names

    def given(y_value):
        m, v = conditional(mean[:1], mean[1:], cov[:1, :1], cov[:1, 1:], cov[1:, 1:], [y_value])
        return float(m[0]), float(v[0, 0])

    m, v = given(y_obs)
    s, sx, sy = np.sqrt(v), np.sqrt(cov[0, 0]), np.sqrt(cov[1, 1])
    reach = max(radii) + 0.6
    grid = np.linspace(mean[0] - reach * sx, mean[0] + reach * sx, 400)
    p_cond = gaussian_pdf(grid[:, None], [m], [[v]])

    fig, (top, bottom) = plt.subplots(2, 1, figsize=figsize, sharex=True,
                                      gridspec_kw=dict(height_ratios=(3, 2)))
    if samples is not None:
        plot_samples(top, samples, label="draws of the joint", zorder=0)
    for k, ls in zip(radii, ("-", "--", ":", "-.") * len(radii)):
        plot_covariance_ellipse(top, mean, cov, k, color=COLORS["prior"], ls=ls, label=f"joint {k:g}σ")
    y_line = np.array([mean[1] - reach * sy, mean[1] + reach * sy])
    top.plot([given(yv)[0] for yv in y_line], y_line, color=COLORS["estimate"], ls="--", lw=1.2,
             label=f"E[{x_name} | {y_name}] (regression line)")
    top.axhline(y_obs, color=COLORS["measurement"], lw=1.5, zorder=3, label=f"measured {y_name} = {y_obs:g}")
    top.plot([m - band * s, m + band * s], [y_obs, y_obs], color=COLORS["band"], lw=7, solid_capstyle="butt",
             label=f"±{band:g}σ of p({x_name} | {y_name})")
    lift = y_obs + 0.9 * sy * p_cond / p_cond.max()
    top.fill_between(grid, y_obs, lift, color=COLORS["estimate"], alpha=0.15, lw=0)
    top.plot(grid, lift, color=COLORS["estimate"], lw=1.5, label=f"p({x_name} | {y_name}) along the slice")
    top.plot([m], [y_obs], "o", color=COLORS["estimate"], zorder=5, label=f"E[{x_name} | {y_name} = {y_obs:g}]")
    top.set(ylabel=y_name, ylim=tuple(y_line), title=f"joint density, sliced where {y_name} was measured")
    top.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)

    bottom.plot(grid, gaussian_pdf(grid[:, None], mean[:1], cov[:1, :1]), color=COLORS["prior"],
                label=f"p({x_name}), before")
    bottom.plot(grid, p_cond, color=COLORS["estimate"], lw=2, label=f"p({x_name} | {y_name} = {y_obs:g})")
    if slice_x is not None:
        bottom.hist(slice_x, bins=60, density=True, histtype="step", color=COLORS["truth"], lw=1,
                    label=f"{slice_x.size:,} simulated draws\nwith {y_name} near {y_obs:g}")
    bottom.set(xlabel=x_name, ylabel="density", xlim=(grid[0], grid[-1]), title=f"{x_name} before and after")
    bottom.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    fig.tight_layout()
    return fig
