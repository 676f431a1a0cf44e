"""Plotting layer: one vocabulary for the whole course, and each chapter's figures.

- :mod:`~kalman_course.plotting.vocabulary` — the shared pieces: truth, measurements,
  estimate, ±3σ band, covariance ellipse, belief, consistency statistics, shaded spans,
  and the colours :data:`COLORS` (everything there is re-exported here, so
  ``from kalman_course.plotting import plot_truth, COLORS`` works);
- per chapter, whole figures built from the vocabulary so that lecture cells stay short:
  :mod:`~kalman_course.plotting.bayes` (01), :mod:`~kalman_course.plotting.gaussians` (02),
  :mod:`~kalman_course.plotting.kf` (03), :mod:`~kalman_course.plotting.eskf` (08),
  :mod:`~kalman_course.plotting.consistency` (09); also re-exported here.

A new chapter's figures go in a new module here, built from the vocabulary; a new kind of
mark that several chapters draw goes in the vocabulary. Nothing here changes global
state (no ``rcParams``, no style sheets), and bad inputs raise ``ValueError`` naming the
argument.
"""

from kalman_course.plotting.vocabulary import (COLORS, CURVE_COLORS, covariance_ellipse_axes, flag_spans,
                                               plot_belief, plot_consistency, plot_consistency_curves,
                                               plot_covariance_ellipse, plot_curves, plot_error_with_band,
                                               plot_estimate, plot_measurements, plot_samples, plot_sigma_band,
                                               plot_track, plot_truth, shade_spans)
from kalman_course.plotting.bayes import plot_belief_sequence
from kalman_course.plotting.gaussians import plot_conditioning
from kalman_course.plotting.kf import plot_kf_1d, plot_kf_2d
from kalman_course.plotting.eskf import (plot_bias_estimates, plot_bias_sigmas, plot_error_norms, plot_outage_error,
                                         plot_pose_errors, plot_track_with_zoom)
from kalman_course.plotting.consistency import plot_gating, plot_monte_carlo, plot_sensitivity

__all__ = [
    # vocabulary
    "COLORS", "CURVE_COLORS", "plot_truth", "plot_measurements", "plot_estimate", "plot_sigma_band",
    "plot_error_with_band", "plot_covariance_ellipse", "covariance_ellipse_axes", "plot_belief",
    "plot_samples", "plot_consistency", "plot_consistency_curves", "plot_curves", "plot_track",
    "shade_spans", "flag_spans",
    # chapters
    "plot_belief_sequence", "plot_conditioning", "plot_kf_1d", "plot_kf_2d",
    "plot_track_with_zoom", "plot_pose_errors", "plot_bias_estimates", "plot_bias_sigmas",
    "plot_outage_error", "plot_error_norms",
    "plot_monte_carlo", "plot_sensitivity", "plot_gating",
]
