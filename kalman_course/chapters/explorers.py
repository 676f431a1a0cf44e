"""Chapters 03 and 09: sliders for Q and R that redraw a filter's estimate and consistency live.

Each explorer is one figure function, drawn once in the lecture as a static figure (what
nbval checks and the HTML export shows), and the same function behind a pair of
log-scale sliders (ipywidgets) for a learner running the notebook.
"""
from __future__ import annotations

import numpy as np

from kalman_course import symbolic
from kalman_course.chapters.consistency import scaled_config
from kalman_course.evaluation import metrics
from kalman_course.evaluation.consistency import average_band
from kalman_course.evaluation.pose import evaluate
from kalman_course.filters import eskf, kf
from kalman_course.plotting.kf import plot_tuning_dashboard

__all__ = ["cv_tuning_figure", "eskf_tuning_figure", "slider_explorer", "cv_tuning_explorer",
           "eskf_tuning_explorer"]


def cv_tuning_figure(runs, x0, P0, dt: float, sigma_a: float, sigma: float, skip: int = 10):
    """Chapter 03: the CV filter with σ_a and σ on simulated runs: one run's position, NEES and NIS over the runs.

    Parameters
    ----------
    runs : sequence of CVTarget
        Simulated 1-D CV runs (``t``, ``x`` truth (N, 2), ``z`` measurements (N, 1)).
    x0 : array_like, shape (2,)
        Prior mean at step 0.
    P0 : array_like, shape (2, 2)
        Prior covariance at step 0.
    dt : float
        Step of the runs, s.
    sigma_a, sigma : float
        The filter's acceleration σ (m/s²) and measurement σ (m).
    skip : int
        Steps of the start-up transient (from P0) left out of the verdicts' averages.

    Returns
    -------
    matplotlib.figure.Figure
    """
    if len(runs) == 0:
        raise ValueError("runs must hold at least one simulated run")
    F, G = symbolic.cv_transition(dt), symbolic.cv_observation_matrix(1)
    Q, R = symbolic.cv_process_noise(dt, sigma_a), np.array([[float(sigma) ** 2]])
    hists = [kf.run_kf(x0, P0, F, Q, G, R, run.z) for run in runs]
    nees_runs = np.array([metrics.nees(h.x_hat - run.x, h.P_hat) for h, run in zip(hists, runs)])   # (n, N)
    nis_runs = np.array([metrics.normalised_squared(h.innovation, h.S, "innovation", "S") for h in hists])
    nees, nis = nees_runs.mean(axis=0), nis_runs.mean(axis=0)
    n = len(runs)
    nees_lo, nees_hi = metrics.chi2_bounds(2, n)          # at each step: n independent runs
    nis_lo, nis_hi = metrics.chi2_bounds(1, n)
    first, run = hists[0], runs[0]
    verdicts = ", ".join(f"mean {name} {b.mean:.2f} (band {b.lo:.2f}–{b.hi:.2f}, {b.verdict})"
                         for name, b in (("NEES", average_band(nees_runs[:, skip:], 2)),
                                         ("NIS", average_band(nis_runs[:, skip:], 1))))
    return plot_tuning_dashboard(
        run.t, run.x[:, 0], first.x_hat[:, 0], np.sqrt(first.P_hat[:, 0, 0]), run.z[:, 0],
        {f"NEES, mean of {n} runs (2 dof)": (nees, nees_lo, nees_hi),
         f"NIS, mean of {n} runs (1 dof)": (nis, nis_lo, nis_hi)},
        title=(f"simulated CV target; filter σ_a = {sigma_a:.3g} m/s², σ = {sigma:.3g} m\n{verdicts} "
               f"after {skip} steps"))


def eskf_tuning_figure(excerpt, q_factor: float, r_factor: float, config="kitti_lidar"):
    """Chapter 09: the KITTI ESKF with Q and R scaled: east position, pose NEES and NIS over time.

    Parameters
    ----------
    excerpt : KittiExcerpt
        Real IMU and ground truth; its shipped lidar poses (simulated from the truth).
    q_factor, r_factor : float
        Factors on the process noise Q and the lidar noise R
        (:func:`~kalman_course.chapters.consistency.scaled_config`).
    config : EskfConfig or str
        The configuration the factors scale.

    Returns
    -------
    matplotlib.figure.Figure
    """
    k0, s0 = excerpt.initial_state()
    res = eskf.run(excerpt.imu, s0, scaled_config(config, q_factor, r_factor), excerpt.gravity,
                   lidar=excerpt.lidar, start=k0)
    m = evaluate(res.t, res.position, res.rotation, excerpt.truth, res.P)
    nis = metrics.normalised_squared(np.asarray(res.innovation), np.asarray(res.S), "innovation", "S")
    nees_band, nis_band = average_band(m["nees"], 6), average_band(nis, 6)
    lo1, hi1 = metrics.chi2_bounds(6)                       # one value: the band a single step lies in
    t = res.t - res.t[0]
    return plot_tuning_dashboard(
        t, np.zeros_like(t), m["position_error"][:, 0], np.sqrt(res.P[:, 0, 0]), None,
        {"pose NEES (6 dof), truth: KITTI's": (m["nees"], lo1, hi1), "NIS (6 dof)": (nis, lo1, hi1)},
        name="east position error", labels={"truth": "zero error", "estimate": "error against KITTI's truth"},
        title=(f"real IMU and truth, simulated lidar poses; Q × {q_factor:.3g}, R × {r_factor:.3g}\n"
               + ", ".join(f"mean {name} {b.mean:.2f} (band {b.lo:.2f}–{b.hi:.2f}, {b.verdict})"
                           for name, b in (("pose NEES", nees_band), ("NIS", nis_band)))))


def slider_explorer(draw, sliders):
    """Log-scale sliders that redraw ``draw(**values)`` whenever one moves.

    Parameters
    ----------
    draw : callable
        ``draw(**values)`` returns a matplotlib figure.
    sliders : mapping of str to (description, value, min, max)
        Keyword name -> the slider's label, start value and range (all > 0; log scale).

    Returns
    -------
    ipywidgets.VBox
        The sliders above the figure; display it in a notebook.
    """
    import ipywidgets
    import matplotlib.pyplot as plt
    from IPython.display import display

    widgets = {}
    for name, (description, value, low, high) in sliders.items():
        if not 0.0 < low <= value <= high:
            raise ValueError(f"sliders[{name!r}] needs 0 < min <= value <= max, got {low}, {value}, {high}")
        widgets[name] = ipywidgets.FloatLogSlider(value=value, base=10, min=np.log10(low), max=np.log10(high),
                                                  step=0.05, description=description, continuous_update=False,
                                                  style={"description_width": "initial"},
                                                  layout=ipywidgets.Layout(width="480px"))
    out = ipywidgets.Output()

    def redraw(_change=None):
        with out:
            out.clear_output(wait=True)
            fig = draw(**{name: w.value for name, w in widgets.items()})
            display(fig)
            plt.close(fig)

    for w in widgets.values():
        w.observe(redraw, "value")
    redraw()
    return ipywidgets.VBox([*widgets.values(), out])


def cv_tuning_explorer(runs, x0, P0, dt: float, sigma_a: float, sigma: float):
    """Sliders for the filter's σ_a and σ over :func:`cv_tuning_figure` (chapter 03)."""
    return slider_explorer(
        lambda sigma_a, sigma: cv_tuning_figure(runs, x0, P0, dt, sigma_a, sigma),
        {"sigma_a": ("filter σ_a [m/s²]", sigma_a, sigma_a / 30, sigma_a * 30),
         "sigma": ("filter σ [m]", sigma, sigma / 10, sigma * 10)})


def eskf_tuning_explorer(excerpt, config="kitti_lidar"):
    """Sliders for the Q and R factors over :func:`eskf_tuning_figure` (chapter 09)."""
    return slider_explorer(
        lambda q_factor, r_factor: eskf_tuning_figure(excerpt, q_factor, r_factor, config),
        {"q_factor": ("Q factor", 1.0, 0.01, 100.0), "r_factor": ("R factor", 1.0, 0.1, 10.0)})
