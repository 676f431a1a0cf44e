"""Chapter 02 figures: joint, marginal and conditional Gaussians."""

from __future__ import annotations

import numpy as np

from kalman_course.plotting.vocabulary import (COLORS, _covariance2, _vector, plot_covariance_ellipse,
                                               plot_samples)

__all__ = ["plot_conditioning"]


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
