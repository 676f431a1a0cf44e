"""kalman-course: reference implementations, data, checks and tooling for the course.

The package is layered; each subpackage imports only from the layers below it
(``tests/test_layering.py`` enforces this):

==============  ==========================================================================
``core``        validation, SO(3), the shared linear algebra (gain, Joseph update), angles,
                Gaussian algebra, IMU mechanisation
``symbolic``    the SymPy models and derivations, with their registry
``filters``     histogram filter, KF, EKF/IEKF, ESKF, nominal-state EKF
``evaluation``  metrics, chi-square statistics, trajectory alignment   (beside ``data``)
``data``        KITTI excerpts and seeded synthetic scenarios
``chapters``    each chapter's experiments and scenarios
``plotting``    the plot vocabulary and per-chapter figures
``checks``      the graders, one per graded skill
``tooling``     authoring, grading, review, export, notebook execution, benchmarks, CLI
==============  ==========================================================================

Lectures import the modules they use by their short names, for example
``from kalman_course import kf, eskf, checks``. Importing the package has no side
effects: it sets no print options, no plotting style and no random state, and a short
name imports its module only when it is first asked for.
"""

import importlib

__version__ = "0.1.0"

# short name -> module, for the library modules the lectures use
_SHORT_NAMES = {
    "validation": "kalman_course.core.validation",
    "so3": "kalman_course.core.so3",
    "gaussians": "kalman_course.core.gaussians",
    "imu": "kalman_course.core.imu",
    "bayes": "kalman_course.filters.bayes",
    "kf": "kalman_course.filters.kf",
    "ekf": "kalman_course.filters.ekf",
    "eskf": "kalman_course.filters.eskf",
    "eskf_config": "kalman_course.filters.eskf_config",
    "nominal_ekf": "kalman_course.filters.nominal_ekf",
    "metrics": "kalman_course.evaluation.metrics",
    "trajectory": "kalman_course.evaluation.trajectory",
}


def __getattr__(name: str):
    if name in _SHORT_NAMES:
        return importlib.import_module(_SHORT_NAMES[name])
    raise AttributeError(f"module 'kalman_course' has no attribute {name!r}")


def __dir__():
    return sorted([*globals(), *_SHORT_NAMES])
