"""Chapter 10 figure: what coloured lidar errors do to the ESKF, and the remedies, against τ.

One call draws the lecture's figure from a
:class:`~kalman_course.chapters.coloured_noise.ColouredNoiseResult` (read by attribute):
the pose NEES of each filter against the time constant τ of the simulated lidar error,
over the shaded 95 % interval, on a log scale (a filter ten times overconfident is as far
from the band as one ten times underconfident), and beside it the accuracy, the ESKF/raw
position APE ratio. A marker is the mean over the seeds (NEES) or their median (ratio);
its whiskers span the seeds.
"""

from __future__ import annotations

import numpy as np

from kalman_course.core.validation import as_rows, as_scalar
from kalman_course.plotting.vocabulary import COLORS, CURVE_COLORS, _bounds, flag_spans, shade_spans

__all__ = ["plot_error_draws", "plot_coloured_noise"]

_AXES = "xyz"

#: Legend names of the filters of ``chapters.coloured_noise.REMEDIES``.
_LEGEND = {
    "plain": "plain ESKF (white R)",
    "inflated_R": "R × (1 + φ)/(1 − φ)",
    "fewer_observations": "one pose per 2τ",
    "augmented": "state augmented with the GM error",
}
_MARKERS = ("o", "s", "^", "D", "v", "P")
_NEES_TICKS = (0.5, 1, 2, 3, 6, 10, 20, 30, 60, 100, 200, 300, 600, 1000)


def _scores(result):
    """τ (T,), remedies (M,), per-seed NEES and position ratios (T, M, S), the NEES band."""
    for attr in ("time_constants", "remedies", "nees_pose", "position_ratio", "nees_band"):
        if not hasattr(result, attr):
            raise ValueError(f"result must be a ColouredNoiseResult (time_constants, remedies, nees_pose, "
                             f"position_ratio, nees_band); missing {attr!r}")
    taus = np.asarray(result.time_constants, dtype=float)
    remedies = tuple(result.remedies)
    nees = np.asarray(result.nees_pose, dtype=float)
    ratio = np.asarray(result.position_ratio, dtype=float)
    if taus.ndim != 1 or taus.size == 0 or not remedies:
        raise ValueError("result must hold at least one time constant and one remedy")
    expected = (taus.size, len(remedies))
    for name, arr in (("nees_pose", nees), ("position_ratio", ratio)):
        if arr.ndim != 3 or arr.shape[:2] != expected or arr.shape[2] == 0:
            raise ValueError(f"result.{name} must have shape ({expected[0]}, {expected[1]}, S), got {arr.shape}")
        if not np.isfinite(arr).all():
            raise ValueError(f"result.{name} must be finite")
    if (nees <= 0).any():
        raise ValueError("result.nees_pose must be positive (it is drawn on a log scale)")
    return taus, remedies, nees, ratio, _bounds(*result.nees_band)


def _whiskers(ax, x, centre, low, high, color, marker, label):
    """Markers at ``centre`` with bars from ``low`` to ``high``."""
    return ax.errorbar(x, centre, yerr=[centre - low, high - centre], fmt=marker, color=color, ms=6,
                       capsize=3, lw=1.2, label=label)


def plot_coloured_noise(result, *, accuracy: bool = True, figsize=None):
    """Pose NEES (and ESKF/raw position APE) of each filter against the lidar error's time constant.

    Parameters
    ----------
    result : ColouredNoiseResult
        From :func:`kalman_course.chapters.coloured_noise.coloured_noise`: ``time_constants``
        (T,) s, ``remedies`` (M,), ``nees_pose`` and ``position_ratio`` (T, M, S) per seed,
        ``nees_band`` the 95 % interval of the seed-averaged NEES at one time (drawn for
        scale; the verdicts are taken per time, see ``ColouredNoiseResult.verdict``).
    accuracy : bool
        Also draw the ESKF/raw position APE ratio in a left panel (default).
    figsize : tuple, optional
        Figure size (default (11, 4.6) with the accuracy panel, (7, 5) without).

    Returns
    -------
    matplotlib.figure.Figure
        NEES panel: the seed-and-time mean (marker), the per-seed time means (whiskers), the
        interval shaded and 6 marked, log y axis. Accuracy panel: the median ratio over the
        seeds (marker) and its range (whiskers), the raw poses at 1.

    Raises
    ------
    ValueError
        If ``result`` lacks a field, the shapes disagree, or a value is not finite.
    """
    import matplotlib.pyplot as plt

    taus, remedies, nees, ratio, (lo, hi) = _scores(result)
    accuracy = bool(accuracy)
    if figsize is None:
        figsize = (11, 4.6) if accuracy else (7, 5)
    fig, axes = plt.subplots(1, 2 if accuracy else 1, figsize=figsize, squeeze=False)
    axes = axes[0]
    ax_nees = axes[-1]
    x = np.arange(taus.size, dtype=float)
    width = 0.6 / max(len(remedies), 1)
    n_seeds = nees.shape[2]

    ax_nees.axhspan(lo, hi, color=COLORS["band"], alpha=0.5, lw=0,
                    label=f"95 % interval of the {n_seeds}-seed average at one time [{lo:.2f}, {hi:.2f}] "
                          "(for scale: a time mean varies less)")
    ax_nees.axhline(6.0, color="0.4", lw=0.8, ls="--", label="expected value 6")
    for j, remedy in enumerate(remedies):
        xj = x + (j - (len(remedies) - 1) / 2) * width
        color, marker = CURVE_COLORS[j % len(CURVE_COLORS)], _MARKERS[j % len(_MARKERS)]
        label = _LEGEND.get(remedy, remedy)
        per_seed = nees[:, j, :]
        _whiskers(ax_nees, xj, per_seed.mean(axis=1), per_seed.min(axis=1), per_seed.max(axis=1), color, marker,
                  label)
        if accuracy:
            r = ratio[:, j, :]
            _whiskers(axes[0], xj, np.median(r, axis=1), r.min(axis=1), r.max(axis=1), color, marker, label)

    ticks = ["white" if tau == 0 else f"{tau:g} s" for tau in taus]
    ax_nees.set_yscale("log")
    ax_nees.set(xlabel="time constant τ of the simulated lidar error", ylabel="mean pose NEES (6 dof)",
                title="consistency: pose NEES, mean over seeds and time")
    if accuracy:
        axes[0].axhline(1.0, color=COLORS["measurement"], lw=1.0, label="raw simulated poses")
        axes[0].set(xlabel="time constant τ of the simulated lidar error", ylabel="ESKF / raw position APE",
                    title="accuracy: median and range over the seeds")
    for ax in axes:
        ax.set_xticks(x, ticks)
    ax_nees.minorticks_off()                # plain numbers on the log axis, not 10^k
    bottom, top = ax_nees.get_ylim()
    ax_nees.set_yticks([v for v in _NEES_TICKS if bottom <= v <= top],
                       [f"{v:g}" for v in _NEES_TICKS if bottom <= v <= top])
    # one legend for both panels, below them: the markers reach every corner of the panels
    handles, labels = ax_nees.get_legend_handles_labels()
    if accuracy:
        extra = axes[0].get_legend_handles_labels()
        handles, labels = handles + extra[0][:1], labels + extra[1][:1]
    fig.tight_layout(rect=(0, 0.16 if accuracy else 0.2, 1, 1))
    fig.legend(handles, labels, loc="lower center", ncol=3 if accuracy else 2, fontsize=8, frameon=False)
    return fig


# ---------------------------------------------------------------------------------------
# the errors themselves, for intuition (lecture 10 §1)
# ---------------------------------------------------------------------------------------

def plot_error_draws(t, draws, *, sigma, axis: int = 0, title: str = "", figsize=(11, 6.5)):
    """One simulated position-error sequence per panel, over ±σ and ±2σ lines.

    Parameters
    ----------
    t : array_like, shape (K,)
        Observation times, s.
    draws : mapping of str to ErrorDraw
        Panel title -> a draw of an error model at ``t``
        (:meth:`kalman_course.data.observation_errors.ObservationErrors.draw`), one to four.
        Where a draw has map-matching failures, the observations inside a jump are shaded
        and the outliers circled.
    sigma : float
        σ of the drawn position component, m (the dashed lines at ±σ, dotted at ±2σ).
    axis : int
        Position component drawn: 0, 1 or 2 (x, y, z of the navigation frame).
    title : str
        Figure title (say there that the errors are simulated).
    figsize : tuple
        Figure size.

    Returns
    -------
    matplotlib.figure.Figure
        One panel per draw, sharing t [s]. The panels without failures share one vertical
        scale (at least ±3σ), so that their errors compare at a glance; a panel with
        failures scales to its jumps and outliers.

    Raises
    ------
    ValueError
        If ``t`` is not increasing, ``draws`` is empty, holds more than four entries or a
        draw of the wrong length, ``sigma`` is not positive or ``axis`` is not 0, 1 or 2.
    """
    import matplotlib.pyplot as plt

    t = as_rows(t, "t")
    if len(t) < 2 or (np.diff(t) <= 0.0).any():
        raise ValueError("t must hold at least two strictly increasing times")
    if not hasattr(draws, "items") or not 1 <= len(draws) <= 4:
        raise ValueError("draws must be a mapping of 1 to 4 labels -> error draws")
    sigma = as_scalar(sigma, "sigma")
    if isinstance(axis, bool) or axis not in (0, 1, 2):
        raise ValueError(f"axis must be 0, 1 or 2 (x, y, z), got {axis!r}")
    rows = {}
    for label, draw in draws.items():
        error = np.asarray(draw.error, dtype=float) if hasattr(draw, "error") else None
        if error is None or error.shape != (len(t), 6):
            raise ValueError(f"draws[{label!r}] must be an error draw with error of shape ({len(t)}, 6), "
                             f"one row per time in t")
        jumps, outliers = getattr(draw, "jumps", None), getattr(draw, "outliers", None)
        rows[label] = (error[:, axis], None if jumps is None else np.asarray(jumps, dtype=bool),
                       None if outliers is None else np.asarray(outliers, dtype=bool))
    plain = [np.abs(e).max() for e, jumps, outliers in rows.values() if jumps is None and outliers is None]
    limit = 1.1 * max([3.0 * sigma] + plain)

    fig, axes = plt.subplots(len(rows), 1, figsize=figsize, sharex=True, squeeze=False)
    axes = axes[:, 0]
    for ax, (label, (e, jumps, outliers)) in zip(axes, rows.items()):
        if jumps is not None:
            shade_spans(ax, flag_spans(t, jumps), label="inside a jump (a wrong match held)")
        for k, style in ((1, "--"), (2, ":")):
            ax.axhline(k * sigma, color=COLORS["bounds"], lw=0.8, ls=style, label=f"±{k}σ")
            ax.axhline(-k * sigma, color=COLORS["bounds"], lw=0.8, ls=style)
        ax.axhline(0.0, color=COLORS["truth"], lw=0.6)
        ax.plot(t, e, ".-", color=COLORS["estimate"], ms=2.5, lw=0.6, label="error of each simulated pose")
        if outliers is not None and outliers.any():
            ax.plot(t[outliers], e[outliers], "o", mfc="none", color=COLORS["marker"], ms=7, label="outlier")
        if jumps is None and outliers is None:
            ax.set_ylim(-limit, limit)
        ax.set_title(label, fontsize=10, loc="left")
        ax.set_ylabel(f"δp_{_AXES[axis]} [m]")
    axes[-1].set_xlabel("t [s]")
    handles, labels = [], []
    for ax in axes:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    if title:
        fig.suptitle(title)
    fig.tight_layout(rect=(0, 0, 0.8, 1))
    fig.legend(handles, labels, loc="center left", bbox_to_anchor=(0.8, 0.5), fontsize=8, frameon=False)
    return fig
