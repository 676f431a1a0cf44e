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

# chapters 04-06
from kalman_course.checks.motion import (  # noqa: E402
    check_ctrv_jacobian as ctrv_jacobian,
    check_ctrv_step as ctrv_step,
)
from kalman_course.checks.ekf import (  # noqa: E402
    check_ekf_update as ekf_update,
    check_iekf_mean_step as iekf_mean_step,
    check_iekf_update as iekf_update,
    check_radar_h as radar_h,
    check_radar_jacobian as radar_jacobian,
    check_radar_residual as radar_residual,
)

__all__ += ["ctrv_step", "ctrv_jacobian", "radar_h", "radar_jacobian", "radar_residual", "ekf_update",
            "iekf_mean_step", "iekf_update"]

# chapter 07
from kalman_course.checks.imu import (  # noqa: E402
    check_attitude_step as attitude_step,
    check_mechanisation_run as mechanisation_run,
    check_position_step as position_step,
    check_velocity_step as velocity_step,
)

__all__ += ["attitude_step", "velocity_step", "position_step", "mechanisation_run"]

# chapter 08
from kalman_course.checks.eskf import (  # noqa: E402
    check_eskf_covariance_update as eskf_covariance_update,
    check_eskf_discretisation as eskf_discretisation,
    check_eskf_error_dynamics as eskf_error_dynamics,
    check_eskf_gain as eskf_gain,
    check_eskf_inject as eskf_inject,
    check_eskf_noise_jacobian as eskf_noise_jacobian,
    check_eskf_pose_residual as eskf_pose_residual,
    check_eskf_propagate as eskf_propagate,
    check_eskf_reset as eskf_reset,
    check_eskf_run as eskf_run,
)

__all__ += ["eskf_error_dynamics", "eskf_noise_jacobian", "eskf_discretisation", "eskf_propagate",
            "eskf_pose_residual", "eskf_gain", "eskf_covariance_update", "eskf_inject", "eskf_reset",
            "eskf_run"]

# chapter 08, bonus
from kalman_course.checks.eskf import (  # noqa: E402
    check_nominal_ekf_jacobian as nominal_ekf_jacobian,
    check_nominal_ekf_observation as nominal_ekf_observation,
)

__all__ += ["nominal_ekf_observation", "nominal_ekf_jacobian"]

# chapter 09
from kalman_course.checks.consistency import (  # noqa: E402
    check_chi2_interval as chi2_interval,
    check_consistency_nees as consistency_nees,
    check_consistency_nis as consistency_nis,
    check_consistency_verdict as consistency_verdict,
    check_innovation_gate as innovation_gate,
)

__all__ += ["consistency_nees", "consistency_nis", "chi2_interval", "innovation_gate", "consistency_verdict"]
