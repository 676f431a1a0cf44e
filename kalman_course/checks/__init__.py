"""Graders for the exercises: one check per graded skill.

Grader cells call them as ``checks.<name>(learner_object)``. Each prints one constant
line, ``<name>: passed``, or raises :class:`CheckFailed` with a hint.
"""

from kalman_course.checks.harness import SUCCESS, CheckFailed
from kalman_course.checks.bayes import (
    check_door_likelihood as door_likelihood,
    check_histogram_filter as histogram_filter,
    check_histogram_predict as histogram_predict,
    check_histogram_update as histogram_update,
)
from kalman_course.checks.gaussians import (
    check_conditional_covariance as conditional_covariance,
    check_conditional_mean as conditional_mean,
    check_linear_map_moments as linear_map_moments,
)
from kalman_course.checks.kf import (
    check_cv_process_noise as cv_process_noise,
    check_gnss_kf_run as gnss_kf_run,
    check_kf_gain as kf_gain,
    check_kf_predict as kf_predict,
    check_kf_update as kf_update,
)

__all__ = [
    "CheckFailed", "SUCCESS",
    # chapter 01
    "door_likelihood", "histogram_update", "histogram_predict", "histogram_filter",
    # chapter 02
    "conditional_mean", "conditional_covariance", "linear_map_moments",
    # chapter 03
    "cv_process_noise", "kf_predict", "kf_gain", "kf_update", "gnss_kf_run",
]

# chapter 07
from kalman_course.checks.imu import (  # noqa: E402
    check_attitude_step as attitude_step,
    check_mechanisation_run as mechanisation_run,
    check_position_step as position_step,
    check_velocity_step as velocity_step,
)

__all__ += ["attitude_step", "velocity_step", "position_step", "mechanisation_run"]
