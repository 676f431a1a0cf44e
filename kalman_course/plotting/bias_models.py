"""Chapter 10 figure: the true (simulated) IMU biases against two filters' estimates ±3σ.

Built from the vocabulary: the truth is the black line, each filter's estimate a line in
the course's comparison colours with its ±3σ band shaded in the same colour. Gyroscope
biases are drawn in °/h, accelerometer biases in mg (1 mg = 9.80665e-3 m/s²).
"""

from __future__ import annotations

import numpy as np

from kalman_course.plotting.vocabulary import CURVE_COLORS, _vector, plot_estimate, plot_sigma_band, plot_truth

__all__ = ["plot_bias_models"]

_AXES = "xyz"
_RAD_PER_S_TO_DEG_PER_H = np.rad2deg(1.0) * 3600.0
_MS2_TO_MG = 1e3 / 9.80665
_STYLES = ("-", (0, (5, 3)), (0, (1, 2)), (0, (6, 2, 1, 2)))


def _bias_rows(value, name: str, n: int) -> np.ndarray:
    arr = np.asarray(value, dtype=float) if not isinstance(value, str) else None
    if arr is None or arr.shape != (n, 3) or not np.isfinite(arr).all():
        shape = None if arr is None else arr.shape
        raise ValueError(f"{name} must be a finite array of shape ({n}, 3) (one row per time), got {shape}")
    return arr


def _axis(value, name: str) -> int:
    if isinstance(value, bool) or value not in (0, 1, 2):
        raise ValueError(f"{name} must be 0, 1 or 2 (x, y, z), got {value!r}")
    return int(value)


def plot_bias_models(t, true_accel_bias, true_gyro_bias, results, *, gyro_axis=2, accel_axis=0,
                     n_sigma=3, zoom_from=None, title="", figsize=(12, 4)):
    """The simulated true bias and each filter's estimate ±n_sigma·σ, gyroscope and accelerometer.

    Parameters
    ----------
    t : array_like, shape (N,)
        Times of the true biases, s.
    true_accel_bias : array_like, shape (N, 3)
        The simulated accelerometer bias b_a, m/s² (drawn in mg).
    true_gyro_bias : array_like, shape (N, 3)
        The simulated gyroscope bias b_ω, rad/s (drawn in °/h).
    results : mapping of str to EskfResult
        Legend label -> a filter run (uses ``.t``, ``.accel_bias``, ``.gyro_bias`` and
        ``.std()``), one to four of them, e.g. the random-walk and constant-bias runs of
        :func:`kalman_course.chapters.bias_models.run_bias_models`.
    gyro_axis, accel_axis : int
        The axis drawn for each sensor: 0, 1 or 2 (x, y, z).
    n_sigma : float
        Half-width of the bands in standard deviations.
    zoom_from : float, optional
        If given (s), the vertical limits cover the truth, the estimates and their bands
        from this time on only: the turn-on bias converges in the first seconds and would
        otherwise hide the drift. Default: Matplotlib's limits.
    title : str
        Figure title (say there what is simulated).
    figsize : tuple
        Figure size.

    Returns
    -------
    matplotlib.figure.Figure
        Two panels, gyroscope (left) and accelerometer (right), t [s] on both.
    """
    import matplotlib.pyplot as plt

    t = _vector(t, "t")
    b_a = _bias_rows(true_accel_bias, "true_accel_bias", t.shape[0])
    b_w = _bias_rows(true_gyro_bias, "true_gyro_bias", t.shape[0])
    gyro_axis, accel_axis = _axis(gyro_axis, "gyro_axis"), _axis(accel_axis, "accel_axis")
    if not hasattr(results, "items") or not 1 <= len(results) <= len(_STYLES):
        raise ValueError(f"results must be a mapping of 1 to {len(_STYLES)} labels -> ESKF results")
    for label, res in results.items():
        if not (all(hasattr(res, a) for a in ("t", "accel_bias", "gyro_bias")) and callable(getattr(res, "std", None))):
            raise ValueError(f"results[{label!r}] must be an ESKF result with .t, .accel_bias, .gyro_bias and .std()")

    if zoom_from is not None:
        zoom_from = float(_vector([zoom_from], "zoom_from")[0])
        if zoom_from >= t[-1]:
            raise ValueError(f"zoom_from must be before the last time ({t[-1]:.4g} s), got {zoom_from:g}")

    fig, (ax_w, ax_a) = plt.subplots(1, 2, figsize=figsize)
    true_w = b_w[:, gyro_axis] * _RAD_PER_S_TO_DEG_PER_H
    true_a = b_a[:, accel_axis] * _MS2_TO_MG
    plot_truth(ax_w, t, true_w, label="true bias (simulated)", lw=1.5)
    plot_truth(ax_a, t, true_a, label="true bias (simulated)", lw=1.5)
    shown = {ax_w: [true_w[t >= (zoom_from or t[0])]], ax_a: [true_a[t >= (zoom_from or t[0])]]}
    for (label, res), color, style in zip(results.items(), CURVE_COLORS, _STYLES):
        std = res.std()
        panels = ((ax_w, res.gyro_bias[:, gyro_axis], std[:, 12 + gyro_axis], _RAD_PER_S_TO_DEG_PER_H),
                  (ax_a, res.accel_bias[:, accel_axis], std[:, 9 + accel_axis], _MS2_TO_MG))
        late = np.asarray(res.t) >= (zoom_from or res.t[0])
        for ax, estimate, sigma, scale in panels:
            plot_sigma_band(ax, res.t, estimate * scale, sigma * scale, n_sigma, color=color, alpha=0.18,
                            label=f"{label} ±{n_sigma:g}σ")
            plot_estimate(ax, res.t, estimate * scale, color=color, linestyle=style, label=label)
            shown[ax] += [((estimate - n_sigma * sigma) * scale)[late], ((estimate + n_sigma * sigma) * scale)[late]]
    if zoom_from is not None:
        for ax, values in shown.items():
            values = np.concatenate(values)
            lo, hi = float(values.min()), float(values.max())
            pad = 0.05 * (hi - lo) or 1.0
            ax.set_ylim(lo - pad, hi + pad)
    ax_w.set(xlabel="t [s]", ylabel=f"b_ω {_AXES[gyro_axis]} [°/h]",
             title=f"gyroscope bias, {_AXES[gyro_axis]} axis")
    ax_a.set(xlabel="t [s]", ylabel=f"b_a {_AXES[accel_axis]} [mg]",
             title=f"accelerometer bias, {_AXES[accel_axis]} axis")
    ax_a.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)   # beside the curves
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return fig
