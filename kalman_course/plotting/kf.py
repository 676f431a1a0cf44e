"""Chapter 03 figures: a Kalman filter's run, one component or a 2-D track, with its bands."""

from __future__ import annotations

import numpy as np

from kalman_course.plotting.vocabulary import (_times, _vector, plot_consistency, plot_covariance_ellipse,
                                               plot_error_with_band, plot_estimate, plot_measurements, plot_sigma_band,
                                               plot_truth)

__all__ = ["plot_kf_1d", "plot_kf_2d", "plot_innovations", "plot_tuning_dashboard"]


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


def _legend_labels(labels):
    """The legend labels of a Kalman run's figure: the plain names, overridden by ``labels``."""
    names = {"truth": "truth", "measurements": "measurements", "estimate": "estimate"}
    if labels is None:
        return names
    unknown = set(labels) - set(names)
    if unknown:
        raise ValueError(f"labels has unknown roles {sorted(unknown)}; use {sorted(names)}")
    for role, text in labels.items():
        if not isinstance(text, str):
            raise ValueError(f"labels[{role!r}] must be a string, got {text!r}")
    return {**names, **labels}


def plot_kf_1d(t, truth, ys, hist, *, index=0, n_sigma=3, name="position", unit="m",
               figsize=(10, 6), labels=None):
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
    labels : dict, optional
        Legend labels by role, ``{"truth": ..., "measurements": ..., "estimate": ...}``
        (any subset); a lecture uses them to say which curve is real data and which is
        simulated. Missing roles keep the plain names.

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
    names = _legend_labels(labels)
    plot_truth(ax1, t, truth, label=names["truth"])
    if ys is not None:
        plot_measurements(ax1, t, ys, label=names["measurements"])
    plot_estimate(ax1, t, est, label=names["estimate"])
    ax1.set_ylabel(f"{name} [{unit}]")
    ax1.legend(loc="best", fontsize=8)
    plot_error_with_band(ax2, t, est - truth, sigma, n_sigma)
    ax2.set(xlabel="t [s]", ylabel=f"error [{unit}]")
    ax2.legend(loc="best", fontsize=8)
    fig.tight_layout()
    return fig


def plot_kf_2d(t, truth_xy, meas_xy, hist, *, indices=(0, 1), n_sigma=3, ellipse_every=10,
               names=("east", "north"), figsize=(12, 5), labels=None):
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
    labels : dict, optional
        Legend labels by role, ``{"truth": ..., "measurements": ..., "estimate": ...}``
        (any subset), to say which track is real data and which is simulated. Missing
        roles keep the plain names.

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
    legend = _legend_labels(labels)
    plot_truth(ax_map, truth_xy[:, 0], truth_xy[:, 1], label=legend["truth"])
    plot_measurements(ax_map, meas_xy[:, 0], meas_xy[:, 1], label=legend["measurements"])
    plot_estimate(ax_map, x_hat[:, i], x_hat[:, j], label=legend["estimate"])
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
    # above the error panels, not inside: the band fills them from the first seconds on
    ax_e1.legend(loc="lower right", bbox_to_anchor=(1.0, 1.0), ncol=2, fontsize=8, frameon=False)
    ax_e2.set_xlabel("t [s]")
    fig.tight_layout()
    return fig


def plot_innovations(t, cases, *, n_sigma=3, figsize=(12, 5)):
    """Chapter 03: a filter's innovations (residuals) against their ±3√S band, and their autocorrelation.

    Parameters
    ----------
    t : array_like, shape (N,)
        Times of the innovations, s.
    cases : mapping of str to (innovation, S, whiteness)
        Label -> scalar innovations (N,), their variances S (N,), and the
        :class:`~kalman_course.evaluation.consistency.Whiteness` of the same sequence.
        One row of the left column per case; the right panel overlays the autocorrelations.
    n_sigma : float
        Width of the band, in standard deviations √S.
    figsize : tuple
        Figure size.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    from kalman_course.plotting.vocabulary import COLORS, CURVE_COLORS

    t = _times(t, "t")
    if not hasattr(cases, "items") or len(cases) == 0:
        raise ValueError("cases must be a non-empty mapping of label -> (innovation, S, whiteness)")
    fig = plt.figure(figsize=figsize)
    grid = fig.add_gridspec(len(cases), 2, width_ratios=(2.2, 1.0))
    ax_acf = fig.add_subplot(grid[:, 1])
    band = 0.0
    for row, (label, (nu, S, whiteness)) in enumerate(cases.items()):
        nu, S = _vector(nu, f"cases[{label!r}] innovation"), _vector(S, f"cases[{label!r}] S")
        if len(nu) != len(t) or len(S) != len(t):
            raise ValueError(f"cases[{label!r}]: innovation and S must have {len(t)} values, as t")
        color = CURVE_COLORS[row % len(CURVE_COLORS)]
        ax = fig.add_subplot(grid[row, 0])
        plot_error_with_band(ax, t, nu, np.sqrt(S), n_sigma, label="innovation y − G x̌", color=color)
        ax.set(ylabel="innovation [m]", title=label)
        ax.legend(loc="upper right", fontsize=8)
        if row == len(cases) - 1:
            ax.set_xlabel("t [s]")
        ax_acf.plot(whiteness.lags, whiteness.autocorrelation[0], "o-", color=color,
                    label=f"{label}: {'white' if whiteness.white else 'not white'}")
        band = max(band, whiteness.band)
    ax_acf.axhspan(-band, band, color=COLORS["band"], alpha=0.5, lw=0, label="±1.96/√N (white)")
    ax_acf.axhline(0.0, color="0.4", lw=0.8)
    ax_acf.set(xlabel="lag [steps]", ylabel="autocorrelation of ν/√S", title="one run")
    ax_acf.legend(fontsize=8)
    fig.tight_layout()
    return fig


def plot_tuning_dashboard(t, truth, estimate, sigma, measurements, consistency, *, n_sigma=3, title=None,
                          name="position", unit="m", labels=None, figsize=(11, 6.5)):
    """Chapters 03 and 09: one filter setting at a glance (what a tuning slider redraws).

    Top: one state component, its truth, the measurements and the estimate with its ±3σ
    band. Below: each consistency statistic over time with its acceptance band.

    Parameters
    ----------
    t : array_like, shape (N,)
        Times, s.
    truth, estimate, sigma : array_like, shape (N,)
        True value, estimate and the filter's σ of the component.
    measurements : array_like, shape (N,) or None
        Measurements of the component (NaN where none), or None.
    consistency : mapping of str to (values, lo, hi)
        Label (e.g. "NEES averaged over 30 runs") -> statistic per step (N,) and its band.
    n_sigma : float
        Width of the estimate's band.
    title : str, optional
        Figure title (a verdict, say).
    name, unit : str
        For the first panel's axis label.
    labels : dict, optional
        Legend labels by role, as for :func:`plot_kf_1d` (e.g. to draw an error against a
        zero "truth").
    figsize : tuple
        Figure size.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    legend = _legend_labels(labels)
    t = _vector(t, "t")
    n = len(t)
    truth, estimate = _vector(truth, "truth", n=n), _vector(estimate, "estimate", n=n)
    sigma = _vector(sigma, "sigma", n=n)
    if not hasattr(consistency, "items") or len(consistency) == 0:
        raise ValueError("consistency must be a non-empty mapping of label -> (values, lo, hi)")
    fig, axes = plt.subplots(1 + len(consistency), 1, figsize=figsize, sharex=True,
                             gridspec_kw={"height_ratios": [2.0] + [1.0] * len(consistency)})
    top = axes[0]
    plot_sigma_band(top, t, estimate, sigma, n_sigma)
    plot_truth(top, t, truth, label=legend["truth"])
    if measurements is not None:
        plot_measurements(top, t, _vector(measurements, "measurements", allow_nan=True, n=n),
                          label=legend["measurements"])
    plot_estimate(top, t, estimate, label=legend["estimate"])
    top.set_ylabel(f"{name} [{unit}]")
    top.legend(loc="best", fontsize=8)
    for ax, (label, (values, lo, hi)) in zip(axes[1:], consistency.items()):
        plot_consistency(ax, t, values, lo, hi, label=label)
        ax.set_yscale("log")
        ax.legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("t [s]")
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig
