"""Graders for the exercises: one check per graded skill.

Grader cells call them as ``checks.<name>(learner_object)``. Each prints one constant
line, ``<name>: passed``, or raises :class:`CheckFailed` with a hint.

A check is written once: ``@check`` on ``def check_<name>(...)`` in the chapter's module
below registers it, and this package exposes every registered check as ``checks.<name>``
(:func:`registered` lists them). A new chapter's module is added to the import below.
"""

from kalman_course.checks.harness import SUCCESS, CheckFailed, registered
from kalman_course.checks.hints import more_hints

# Importing a chapter's module runs its @check decorators, which register its checks.
from kalman_course.checks import (  # noqa: F401  (imported for registration)
    bayes,        # chapter 01
    gaussians,    # chapter 02
    kf,           # chapter 03
    motion,       # chapter 04
    ekf,          # chapters 05-06
    imu,          # chapter 07
    eskf,         # chapter 08 and its bonus
    consistency,  # chapter 09
    real_sensors,  # chapter 10
)


def _expose_registered_checks() -> list[str]:
    """Bind each registered check to ``checks.<name>``; return the names bound."""
    namespace = globals()
    for name, check_fn in registered().items():
        if name in namespace:                      # a submodule, CheckFailed, ...
            raise ValueError(f"check name {name!r} collides with kalman_course.checks.{name}; "
                             f"rename check_{name}")
        namespace[name] = check_fn
    return list(registered())


__all__ = ["CheckFailed", "SUCCESS", "registered", "more_hints", *_expose_registered_checks()]
