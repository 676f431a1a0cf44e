"""Chapter 10 figures: initialisation without the truth.

Each function builds one whole figure from the chapter's records
(:class:`~kalman_course.chapters.initialisation.RunErrors`,
:class:`~kalman_course.chapters.initialisation.StandstillStatistics`) read by attribute,
so a lecture cell is one call and ``plt.show()``:

- :func:`plot_standstill` — the detector's three statistics over time, their thresholds
  and the spans it calls still (optionally the true speed, for checking);
- :func:`plot_start_comparison` — position, heading and tilt errors of runs started in
  different ways (from an initialisation, from the truth) over time;
- :func:`plot_p0_scaling` — the same wrong start with P̂₀ scaled: each run's position,
  heading and tilt error with its n·σ as a dashed line of the same colour, and the pose
  NEES over its χ² interval.

Angles come in radians and are drawn in degrees; times are t [s].
"""

from __future__ import annotations

import numpy as np

from kalman_course.evaluation.metrics import chi2_bounds
from kalman_course.plotting.vocabulary import (COLORS, CURVE_COLORS, _vector, plot_consistency_curves,
                                               shade_spans)

__all__ = ["plot_standstill", "plot_start_comparison", "plot_p0_scaling"]

_FIELDS = ("t", "position_error", "position_sigma", "heading_error", "heading_sigma", "tilt_error",
           "tilt_sigma", "nees")

#: The standard gravity datasheets use for one g, m/s² (thresholds are drawn in mg).
_G0 = 9.80665


def _runs(runs, name: str) -> dict:
    """``runs`` as {label: {field: array}}, every field a finite-or-NaN vector on its own t."""
    if not hasattr(runs, "items") or len(runs) == 0:
        raise ValueError(f"{name} must be a non-empty mapping of label -> run errors (t, position_error, ...)")
    out = {}
    for label, run in runs.items():
        missing = [f for f in _FIELDS if not hasattr(run, f)]
        if missing:
            raise ValueError(f"{name}[{label!r}] must have {', '.join(_FIELDS)}; missing {', '.join(missing)}")
        t = _vector(run.t, f"{name}[{label!r}].t")
        out[label] = {"t": t, **{f: _vector(getattr(run, f), f"{name}[{label!r}].{f}", allow_nan=True,
                                            n=t.shape[0]) for f in _FIELDS[1:]}}
    return out


def _set_xlim(ax, xlim) -> None:
    """Set (start, end) time limits on a shared x axis; None leaves Matplotlib's."""
    if xlim is None:
        return
    try:
        lo, hi = (float(v) for v in xlim)
    except (TypeError, ValueError):
        raise ValueError(f"xlim must be (start, end) in s, got {xlim!r}") from None
    if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
        raise ValueError(f"xlim must be finite with start < end, got {xlim!r}")
    ax.set_xlim(lo, hi)


def plot_standstill(stats, spans, *, gravity_tolerance_mg=2.0, rate_max_dps=0.5, vibration_max_mg=2.0,
                    truth=None, xlim=None, figsize=(11, 6.5)):
    """The standstill detector at work: its statistics, thresholds and the spans it finds.

    Parameters
    ----------
    stats : StandstillStatistics
        From :func:`kalman_course.chapters.initialisation.standstill_statistics` (uses
        ``t_start``, ``t_end``, ``gravity_deviation``, ``mean_rate``, ``vibration``); each
        window is drawn at its centre.
    spans : array_like, shape (K, 2)
        The still spans, s (from ``detect_standstill``), shaded in every panel.
    gravity_tolerance_mg, rate_max_dps, vibration_max_mg : float
        The thresholds, drawn as red lines.
    truth : (array_like (M,), array_like (M,)), optional
        (t, true speed in m/s), drawn in a fourth panel: the check the detector never sees.
    xlim : (float, float), optional
        Time limits, s.
    figsize : tuple
        Figure size.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    for f in ("t_start", "t_end", "gravity_deviation", "mean_rate", "vibration"):
        if not hasattr(stats, f):
            raise ValueError(f"stats must be a StandstillStatistics (t_start, t_end, gravity_deviation, "
                             f"mean_rate, vibration); missing {f!r}")
    t0 = _vector(stats.t_start, "stats.t_start")
    t = 0.5 * (t0 + _vector(stats.t_end, "stats.t_end", n=t0.shape[0]))
    panels = [("| |f̄| − g | [mg]", stats.gravity_deviation, 1.0 / (_G0 * 1e-3), gravity_tolerance_mg),
              ("|ω̄| [°/s]", stats.mean_rate, np.rad2deg(1.0), rate_max_dps),
              ("vibration [mg]", stats.vibration, 1.0 / (_G0 * 1e-3), vibration_max_mg)]
    n_panels = 3 + (truth is not None)
    fig, axes = plt.subplots(n_panels, 1, figsize=figsize, sharex=True)
    for ax, (ylabel, values, scale, threshold) in zip(axes, panels):
        values = _vector(values, f"stats {ylabel}", n=t.shape[0])
        shade_spans(ax, spans, label="still")
        ax.plot(t, values * scale, color=COLORS["estimate"], lw=0.8, label="statistic")
        ax.axhline(float(threshold), color=COLORS["bounds"], lw=1.0, ls="--", label="threshold")
        ax.set(ylabel=ylabel, yscale="log")
    axes[0].legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small")  # beside the data
    if truth is not None:
        if len(truth) != 2:
            raise ValueError("truth must be a pair (t, speed)")
        tt = _vector(truth[0], "truth t")
        speed = _vector(truth[1], "truth speed", n=tt.shape[0])
        shade_spans(axes[3], spans, label="still")
        axes[3].plot(tt, speed, color=COLORS["truth"], lw=1.0, label="true speed (not used)")
        axes[3].set(ylabel="speed [m/s]")
        axes[3].legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small")
    axes[-1].set(xlabel="t [s]")
    _set_xlim(axes[-1], xlim)
    fig.tight_layout()
    return fig


def plot_start_comparison(runs, *, agreement_time=None, title="", xlim=None, figsize=(11, 7)):
    """Position, heading and tilt errors over time of runs started in different ways.

    Parameters
    ----------
    runs : mapping of str to RunErrors
        Legend label -> a run's errors (attributes ``t``, ``position_error`` (m),
        ``heading_error`` and ``tilt_error`` (rad), and the other fields of
        :class:`~kalman_course.chapters.initialisation.RunErrors`).
    agreement_time : float, optional
        Time from which the runs agree, s (a vertical line; not drawn if inf).
    title : str
        Figure title.
    xlim : (float, float), optional
        Time limits, s (e.g. the first seconds after the start).
    figsize : tuple
        Figure size.

    Returns
    -------
    matplotlib.figure.Figure
        Three panels sharing t [s].
    """
    import matplotlib.pyplot as plt

    data = _runs(runs, "runs")
    fig, axes = plt.subplots(3, 1, figsize=figsize, sharex=True)
    panels = (("position_error", 1.0, "position error [m]"), ("heading_error", np.rad2deg(1.0), "heading error [°]"),
              ("tilt_error", np.rad2deg(1.0), "tilt error [°]"))
    for ax, (field, scale, ylabel) in zip(axes, panels):
        for (label, run), color in zip(data.items(), CURVE_COLORS):
            ax.plot(run["t"], run[field] * scale, color=color, lw=1.0, label=label)
        ax.set(ylabel=ylabel)
        if agreement_time is not None and np.isfinite(agreement_time):
            ax.axvline(float(agreement_time), color=COLORS["truth"], lw=0.8, ls=":",
                       label=f"agree from {float(agreement_time):.1f} s")
    axes[1].axhline(0.0, color=COLORS["truth"], lw=0.6)
    axes[0].legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small")  # beside the data
    axes[0].set_title(title)
    axes[-1].set(xlabel="t [s]")
    _set_xlim(axes[-1], xlim)
    fig.tight_layout()
    return fig


def plot_p0_scaling(runs, *, n_sigma=3, dof=6, log=True, title="", xlim=None, figsize=(11, 10)):
    """The same wrong start with P̂₀ scaled: errors, their n·σ and the pose NEES over time.

    Each run's error is a solid line and its filter's n·σ (of the same norm or angle) a
    dashed line of the same colour: where the solid line stays above the dashed one, the
    filter is surer than it should be. The bottom panel shows the pose NEES against its
    95 % χ² interval for one run.

    Parameters
    ----------
    runs : mapping of str to RunErrors
        Legend label (e.g. "P̂₀ × 0.01") -> that run's errors (``t``, ``position_error``,
        ``position_sigma`` (m), ``heading_error``, ``heading_sigma``, ``tilt_error``,
        ``tilt_sigma`` (rad), ``nees``); heading is drawn as |error|. All share ``t``.
    n_sigma : float
        Multiple of σ drawn dashed.
    dof : int
        Degrees of freedom of the NEES (6 for position and attitude).
    log : bool
        Logarithmic y axes (errors and σ's span decades when P̂₀ is scaled by 100).
    title : str
        Figure title.
    xlim : (float, float), optional
        Time limits, s (e.g. the first seconds after the start).
    figsize : tuple
        Figure size.

    Returns
    -------
    matplotlib.figure.Figure
        Four panels sharing t [s]: position, heading, tilt, NEES.
    """
    import matplotlib.pyplot as plt

    data = _runs(runs, "runs")
    k = float(n_sigma)
    if not np.isfinite(k) or k <= 0:
        raise ValueError(f"n_sigma must be a positive number, got {n_sigma!r}")
    if len(data) > len(CURVE_COLORS):
        raise ValueError(f"runs can hold at most {len(CURVE_COLORS)} runs (one colour each), got {len(data)}")
    fig, axes = plt.subplots(4, 1, figsize=figsize, sharex=True)
    deg = np.rad2deg(1.0)
    panels = (("position_error", "position_sigma", 1.0, "position error [m]"),
              ("heading_error", "heading_sigma", deg, "|heading error| [°]"),
              ("tilt_error", "tilt_sigma", deg, "tilt error [°]"))
    for (label, run), color in zip(data.items(), CURVE_COLORS):
        for i, (error, sigma, scale, _) in enumerate(panels):
            names = (f"{label}: error", f"{label}: {k:g}σ") if i == 0 else (None, None)
            axes[i].plot(run["t"], np.abs(run[error]) * scale, color=color, lw=1.0, label=names[0])
            axes[i].plot(run["t"], k * run[sigma] * scale, color=color, lw=1.0, ls="--", label=names[1])
    for ax, (*_, ylabel) in zip(axes, panels):
        ax.set(ylabel=ylabel)
        if log:
            ax.set_yscale("log")
    lo, hi = chi2_bounds(dof)
    t_ref = next(iter(data.values()))["t"]
    for label, run in data.items():
        if run["t"].shape != t_ref.shape or not np.allclose(run["t"], t_ref):
            raise ValueError(f"runs[{label!r}] must share the first run's times for the NEES panel")
    plot_consistency_curves(axes[3], t_ref, {label: run["nees"] for label, run in data.items()}, lo, hi,
                            log=True, band_label=f"95 % interval of χ²({dof}) [{lo:.2f}, {hi:.2f}]")
    axes[3].set(ylabel=f"pose NEES ({dof} dof)", xlabel="t [s]")
    axes[0].legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small")
    axes[3].legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small")
    axes[0].set_title(title)
    _set_xlim(axes[-1], xlim)
    fig.tight_layout()
    return fig
