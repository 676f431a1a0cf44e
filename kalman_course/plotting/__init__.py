"""Plotting layer: one vocabulary for the whole course, and each chapter's figures.

- :mod:`~kalman_course.plotting.vocabulary` — the shared pieces: truth, measurements,
  estimate, ±3σ band, covariance ellipse, belief, consistency statistics, shaded spans,
  and the colours :data:`COLORS` (everything there is re-exported here, so
  ``from kalman_course.plotting import plot_truth, COLORS`` works);
- per chapter, whole figures built from the vocabulary so that lecture cells stay short:
  :mod:`~kalman_course.plotting.bayes` (01), :mod:`~kalman_course.plotting.gaussians` (02),
  :mod:`~kalman_course.plotting.kf` (03), :mod:`~kalman_course.plotting.eskf` (08),
  :mod:`~kalman_course.plotting.consistency` (09); also re-exported here;
- the intuition figures (:mod:`~kalman_course.plotting.intuition`: the Gaussian product
  of a scalar update, the gain's limits, P and K settling, a cloud through the radar, the
  IEKF on its cost) and the block diagrams (:mod:`~kalman_course.plotting.diagrams`: the
  Bayes filter's loop, the ESKF's loop); also re-exported here.

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
from kalman_course.plotting.gaussians import plot_conditional_slice, plot_conditioning
from kalman_course.plotting.kf import plot_innovations, plot_kf_1d, plot_kf_2d
from kalman_course.plotting.eskf import (plot_bias_estimates, plot_bias_sigmas, plot_error_norms, plot_outage_error,
                                         plot_pose_errors, plot_track_with_zoom)
from kalman_course.plotting.consistency import plot_gating, plot_monte_carlo, plot_sensitivity
from kalman_course.plotting.intuition import (plot_cost_iterates, plot_gain_convergence, plot_gain_limits,
                                              plot_gaussian_product, plot_kf_1d_steps, plot_radar_linearisation)
# chapter 10, real sensors
from kalman_course.plotting.coloured_noise import plot_coloured_noise, plot_error_draws
from kalman_course.plotting.visual_odometry import plot_drift_by_length, plot_vo_tracks
from kalman_course.plotting.initialisation import plot_p0_scaling, plot_standstill, plot_start_comparison
from kalman_course.plotting.bias_models import plot_bias_models
from kalman_course.plotting.diagrams import (Arrow, Box, Diagram, draw_block_diagram, plot_bayes_filter_diagram,
                                             plot_eskf_diagram)

__all__ = [
    # vocabulary
    "COLORS", "CURVE_COLORS", "plot_truth", "plot_measurements", "plot_estimate", "plot_sigma_band",
    "plot_error_with_band", "plot_covariance_ellipse", "covariance_ellipse_axes", "plot_belief",
    "plot_samples", "plot_consistency", "plot_consistency_curves", "plot_curves", "plot_track",
    "shade_spans", "flag_spans",
    # chapters
    "plot_belief_sequence", "plot_conditioning", "plot_conditional_slice", "plot_kf_1d", "plot_kf_2d",
    "plot_innovations",
    "plot_track_with_zoom", "plot_pose_errors", "plot_bias_estimates", "plot_bias_sigmas",
    "plot_outage_error", "plot_error_norms",
    "plot_monte_carlo", "plot_sensitivity", "plot_gating",
    # intuition figures and block diagrams
    "plot_gaussian_product", "plot_kf_1d_steps", "plot_gain_limits", "plot_gain_convergence",
    "plot_radar_linearisation", "plot_cost_iterates",
    "Box", "Arrow", "Diagram", "draw_block_diagram", "plot_bayes_filter_diagram", "plot_eskf_diagram",
    # chapter 10, real sensors
    "plot_error_draws", "plot_coloured_noise", "plot_vo_tracks", "plot_drift_by_length", "plot_standstill", "plot_start_comparison",
    "plot_p0_scaling", "plot_bias_models",
]
