"""SymPy derivations behind the course: each one stated once, proved, and reusable.

Every model and formula of the course is written here once, symbolically; SymPy proves the
derivation steps (:meth:`Derivation.verify`), derives the Jacobians and turns the results
into cached numpy functions that the filters use. The modules, by topic:

=================  =========================================================================
``equations``      :class:`Equation`, :class:`Derivation`, the zero test, explicit symbolic
                   matrices, the :func:`derivation_builder` decorator
``stepwise``       :class:`Step`: an equation displayed in compact form (δv̇, [a]×, Exp(δθ))
                   and proved on its explicit model, for derivations shown line by line
``registry``       :func:`derivations` and :func:`derivation`: every builder of the topic
                   modules, in course order
``gaussians``      Schur block inverse, moments of a linear map, Gaussian conditioning (02)
``kalman``         the gain as trace minimiser, the update as conditioning, the CV model and
                   its numeric matrices ``cv_transition``, ``cv_process_noise``, ... (03)
``motion``         CV/CA/CTRV/CTRA and the ω → 0 series; ``motion_step``,
                   ``motion_jacobian``, ``ctrv_step``, ``ctrv_jacobian``, ... (04)
``radar``          the radar h(x) and its Jacobian (05)
``eskf``           the ESKF error dynamics, discretisation and reset (08)
``numeric``        lambdify and the argument checks the numeric functions share
=================  =========================================================================

This module only re-exports their public names, so ``symbolic.cv_process_noise(...)``,
``symbolic.derivation("kalman_gain")`` or ``symbolic.ctrv_step(...)`` work as they read.
A new formula goes into the topic module it belongs to, as a builder decorated with
:func:`derivation_builder`; a new topic module is also listed in ``registry.TOPICS``.
"""

from kalman_course.symbolic import eskf, gaussians, kalman, motion, radar, registry
from kalman_course.symbolic.equations import (
    EQUATION_KINDS,
    Derivation,
    Equation,
    derivation_builder,
    is_zero,
    symbol_matrix,
)
from kalman_course.symbolic.gaussians import gaussian_conditioning, linear_map_moments, schur_block_inverse
from kalman_course.symbolic.kalman import (
    cv_model,
    cv_noise_jacobian,
    cv_observation_matrix,
    cv_process_noise,
    cv_process_noise_continuous,
    cv_transition,
    kalman_gain,
    kf_update_conditioning,
)
from kalman_course.symbolic.motion import (
    MOTION_MODELS,
    OMEGA_SERIES_THRESHOLD,
    SERIES_ORDER,
    ca_model,
    ctra_model,
    ctrv_jacobian,
    ctrv_model,
    ctrv_noise_jacobian,
    ctrv_step,
    cv_planar_model,
    motion_jacobian,
    motion_noise_jacobian,
    motion_process_noise,
    motion_state_names,
    motion_step,
)
from kalman_course.symbolic.radar import radar_jacobian, radar_model, radar_observation
from kalman_course.symbolic.registry import derivation, derivations

__all__ = [
    # data model and registry
    "EQUATION_KINDS", "Equation", "Derivation", "derivation_builder", "is_zero", "symbol_matrix",
    "derivations", "derivation",
    # Gaussians (02)
    "schur_block_inverse", "linear_map_moments", "gaussian_conditioning",
    # Kalman filter and the CV model (03)
    "kalman_gain", "kf_update_conditioning", "cv_model", "cv_transition", "cv_process_noise",
    "cv_process_noise_continuous", "cv_noise_jacobian", "cv_observation_matrix",
    # planar motion models (04)
    "MOTION_MODELS", "OMEGA_SERIES_THRESHOLD", "SERIES_ORDER", "cv_planar_model", "ca_model",
    "ctrv_model", "ctra_model", "motion_state_names", "motion_step", "motion_jacobian",
    "motion_noise_jacobian", "motion_process_noise", "ctrv_step", "ctrv_jacobian", "ctrv_noise_jacobian",
    # radar (05)
    "radar_model", "radar_observation", "radar_jacobian",
    # the topic modules themselves (``from kalman_course.symbolic import eskf``)
    "eskf", "gaussians", "kalman", "motion", "radar", "registry",
]
