"""Chapter 09 figures: tuning and consistency.

Each function builds one whole figure of the lecture, so that a lecture cell is one call
and ``plt.show()``. The inputs are the chapter's result records
(:class:`~kalman_course.chapters.consistency.MonteCarloResult`,
:class:`~kalman_course.chapters.consistency.SensitivityRow`) read by attribute, or
plain arrays.
"""

from __future__ import annotations

import numpy as np

from kalman_course.evaluation.metrics import chi2_bounds
from kalman_course.plotting.vocabulary import (COLORS, CURVE_COLORS, _bounds, _vector, plot_consistency_curves,
                                               plot_curves, shade_spans)

__all__ = ["plot_monte_carlo", "plot_sensitivity", "plot_gating", "plot_whiteness"]

#: Line styles of the compared experiments, in order (the first solid).
_LINESTYLES = ("-", (0, (5, 3)), ":", "-.")


def plot_monte_carlo(runs, *, dofs=(("nees", 15), ("nis", 6)), colors=None, figsize=(11, 3.6)):
    """Run-averaged NEES and NIS of Monte Carlo experiments over their chi-square intervals.

    Parameters
    ----------
    runs : mapping of str to MonteCarloResult
        Legend label -> experiment (uses ``.t``, ``.n_runs`` and the fields named in
        ``dofs``, each (n_runs, K)). All must share ``t`` and ``n_runs``; the interval is
        ``chi2_bounds(dof, n_runs)``. The first experiment is drawn solid, the later ones
        dashed or dotted, so that curves lying on top of each other (the NIS of two
        tunings, say) all stay visible.
    dofs : sequence of (str, int)
        One panel per (field, degrees of freedom).
    colors : sequence of colour, optional
        One per experiment (default the course's comparison colours).
    figsize : tuple
        Figure size.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    if not hasattr(runs, "items") or len(runs) == 0:
        raise ValueError("runs must be a non-empty mapping of label -> Monte Carlo result")
    first = next(iter(runs.values()))
    t, n_runs = _vector(first.t, "runs t"), int(first.n_runs)
    for label, mc in runs.items():
        if int(mc.n_runs) != n_runs or np.shape(mc.t) != t.shape:
            raise ValueError(f"runs[{label!r}] must have the same times and number of runs as the first")
    fig, axes = plt.subplots(1, len(dofs), figsize=figsize, sharey=True, squeeze=False)
    for ax, (field, dof) in zip(axes[0], dofs):
        lo, hi = chi2_bounds(dof, n_runs)
        curves = {label: np.asarray(getattr(mc, field)).mean(axis=0) for label, mc in runs.items()}
        plot_consistency_curves(ax, t, curves, lo, hi, colors=colors,
                                linestyles=[_LINESTYLES[k % len(_LINESTYLES)] for k in range(len(curves))])
        ax.set(xlabel="t [s]", title=f"{field.upper()} averaged over {n_runs} runs (χ²({dof}))")
        ax.legend(loc="upper left", fontsize=8)    # a growing NEES leaves through the upper right
    axes[0, 0].set_ylabel("average")
    fig.tight_layout()
    return fig


def plot_sensitivity(sweeps, nis_bounds, *, figsize=(11, 6)):
    """Accuracy (top) and consistency (bottom) of the filter against each swept factor.

    Parameters
    ----------
    sweeps : mapping of str to (str, sequence of SensitivityRow)
        Column title (e.g. ``"Q factor"``) -> (the row attribute holding the factor, e.g.
        ``"q_factor"``, and the rows). Each row gives ``ape_position``,
        ``ape_attitude_deg``, ``nis`` and ``nees_pose``.
    nis_bounds : (float, float)
        The interval of the mean NIS (shaded), e.g. ``chi2_bounds(6, n_updates)``.
    figsize : tuple
        Figure size.

    Returns
    -------
    matplotlib.figure.Figure
        Two rows, one column per sweep, log-scaled factors on the x axis.
    """
    import matplotlib.pyplot as plt

    if not hasattr(sweeps, "items") or len(sweeps) == 0:
        raise ValueError("sweeps must be a non-empty mapping of title -> (factor attribute, rows)")
    lo, hi = _bounds(*nis_bounds)
    fig, axes = plt.subplots(2, len(sweeps), figsize=figsize, sharex="col", squeeze=False)
    for col, (name, (key, rows)) in enumerate(sweeps.items()):
        if len(rows) == 0:
            raise ValueError(f"sweeps[{name!r}] has no rows")
        x = [float(getattr(r, key)) for r in rows]
        top, bottom = axes[0, col], axes[1, col]
        top.plot(x, [r.ape_position for r in rows], "o-", color=COLORS["estimate"], label="position APE [m]")
        # not black: black is the truth's colour everywhere in the course
        top.plot(x, [r.ape_attitude_deg for r in rows], "s--", color=CURVE_COLORS[2], label="attitude APE [deg]")
        top.set(xscale="log", title=f"accuracy against the {name}")
        top.legend(fontsize=8)
        bottom.axhspan(lo, hi, color=COLORS["band"], alpha=0.5, lw=0, label="95 % interval of the mean NIS")
        bottom.plot(x, [r.nis for r in rows], "o-", color=COLORS["estimate"], label="mean NIS")
        bottom.plot(x, [r.nees_pose for r in rows], "s--", color=COLORS["prior"], label="mean pose NEES")
        bottom.axhline(6.0, color="0.4", lw=0.8)
        bottom.set(xscale="log", yscale="log", xlabel=name)
        bottom.legend(fontsize=8)
        for ax in (top, bottom):
            ax.minorticks_off()
            ax.set_xticks(x, [f"{v:g}" for v in x])
        bottom.set_yticks([1.5, 3, 6, 12, 24], ["1.5", "3", "6", "12", "24"])
    axes[0, 0].set_ylabel("APE: position [m], attitude [deg]")
    axes[1, 0].set_ylabel("mean NIS and pose NEES")
    fig.tight_layout()
    return fig


def plot_gating(errors, t_nis, nis, threshold, outlier_times=(), *, colors=(COLORS["prior"], COLORS["estimate"]),
                figsize=(10, 5.5)):
    """Position errors of filters with and without a gate, and the NIS against the gate.

    Parameters
    ----------
    errors : mapping of str to (array_like (N,), array_like (N,))
        Legend label -> (t, position error norm), e.g. ungated then gated.
    t_nis : array_like, shape (K,)
        Times of the tested observations, s.
    nis : array_like, shape (K,)
        NIS of each against the filter's prior.
    threshold : float
        The gate (drawn as a line).
    outlier_times : array_like, shape (L,)
        Times of the known outliers (shaded ±0.05 s in both panels).
    colors : sequence of colour
        One per entry of ``errors``: orange for the unprotected filter, blue for the gated one.
    figsize : tuple
        Figure size.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    t_nis = _vector(t_nis, "t_nis")
    nis = _vector(nis, "nis", n=t_nis.shape[0])
    threshold = float(threshold)
    if not np.isfinite(threshold) or threshold <= 0:
        raise ValueError(f"threshold must be a finite positive number, got {threshold!r}")
    outlier_times = np.asarray(outlier_times, dtype=float).reshape(-1)
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=figsize, sharex=True)
    for ax in (ax1, ax2):
        shade_spans(ax, np.column_stack([outlier_times - 0.05, outlier_times + 0.05]),
                    color=COLORS["marker"], alpha=0.15)
    plot_curves(ax1, errors, colors=colors)
    ax1.set(ylabel="position error [m]", title="shaded: map-matching failures")
    # both legends beside the panels: the errors peak and the rejected NIS sit high up anywhere in the run
    ax1.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    ax2.semilogy(t_nis, nis, ".", ms=3, color=COLORS["estimate"], label="NIS against the prior")
    ax2.axhline(threshold, color=COLORS["truth"], lw=0.8, label=f"gate {threshold:.2f}")
    ax2.set(xlabel="t [s]", ylabel="NIS")
    ax2.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    fig.tight_layout()
    return fig


def plot_whiteness(cases, *, colors=None, figsize=(11, 3.8)):
    """Innovation autocorrelation of one run per case (left), the portmanteau test over seeds (right).

    Parameters
    ----------
    cases : mapping of str to WhitenessRuns
        Legend label -> :class:`~kalman_course.chapters.consistency.WhitenessRuns` (uses
        ``.tests``, each with ``lags``, ``autocorrelation`` (m, L), ``band``,
        ``statistic`` and ``threshold``; and ``.seeds``). All share the lags and the
        threshold. Left: the first run's autocorrelation of every whitened component
        (thin) and their mean (thick), with the ±band of a white sequence. Right: each
        run's Ljung–Box statistic against its χ² threshold, log scale.
    colors : sequence of colour, optional
        One per case (default the course's comparison colours).
    figsize : tuple
        Figure size.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    if not hasattr(cases, "items") or len(cases) == 0:
        raise ValueError("cases must be a non-empty mapping of label -> WhitenessRuns")
    colors = CURVE_COLORS if colors is None else colors
    first = next(iter(cases.values())).tests[0]
    for label, runs in cases.items():
        if len(runs.tests) == 0 or not np.array_equal(runs.tests[0].lags, first.lags):
            raise ValueError(f"cases[{label!r}] must have tests with the same lags as the first case")
    fig, (left, right) = plt.subplots(1, 2, figsize=figsize)
    band = max(float(runs.tests[0].band) for runs in cases.values())
    left.axhspan(-band, band, color=COLORS["band"], alpha=0.5, lw=0, label="±1.96/√N (white)")
    left.axhline(0.0, color="0.4", lw=0.8)
    for k, (label, runs) in enumerate(cases.items()):
        w, c = runs.tests[0], colors[k % len(colors)]
        for row in w.autocorrelation:
            left.plot(w.lags, row, "-", color=c, lw=0.6, alpha=0.5)
        left.plot(w.lags, w.autocorrelation.mean(axis=0), "o-", color=c, lw=1.8,
                  label=f"{label}: seed {runs.seeds[0]}, mean of the {len(w.autocorrelation)} components")
    left.set(xlabel="lag [updates]", ylabel="autocorrelation of whitened innovations",
             title="one run per case")
    left.legend(fontsize=8)
    for k, (label, runs) in enumerate(cases.items()):
        right.plot(np.arange(len(runs.tests)), runs.statistics, "o", color=colors[k % len(colors)],
                   label=f"{label}: {runs.n_white} of {len(runs.tests)} white")
    right.axhline(first.threshold, color=COLORS["truth"], lw=0.8,
                  label=f"95 % threshold χ²({first.autocorrelation.size}) = {first.threshold:.1f}")
    right.set(yscale="log", xlabel="run (seed index)", ylabel="Ljung–Box statistic",
              title="portmanteau test over seeds")
    right.legend(fontsize=8)
    fig.tight_layout()
    return fig
