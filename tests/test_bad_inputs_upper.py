"""Bad input at every public boundary, part 3: the chapters, plotting and symbolic layers.

Issue 27. The scheme of ``tests/test_validation.py`` and ``tests/test_bad_inputs_modules.py``
(whose bad-value kinds and :func:`assert_names` are imported, not copied): each public
function of kalman_course.chapters.*, kalman_course.plotting.* and kalman_course.symbolic.*
with a cheap call is listed once with good arguments and the kind of each argument; every
argument is then replaced, one at a time, by each bad value of its kind, and the call must
raise exactly ``ValueError`` naming the argument. Each listed function's good call must
pass. Functions whose only cheap call needs a whole filter run or figure of real data are
in :data:`EXEMPT`, each with its reason; :func:`test_every_public_function_has_cases`
fails when one of these modules gains a public function that is neither listed nor exempt.
"""

from __future__ import annotations

import importlib
import inspect
import math
import pkgutil
import re
from types import SimpleNamespace

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

import kalman_course.chapters  # noqa: E402
import kalman_course.plotting  # noqa: E402
import kalman_course.symbolic  # noqa: E402
from test_bad_inputs_modules import ALL_KINDS  # noqa: E402
from test_validation import assert_refused  # noqa: E402

from kalman_course.chapters import (beacons, bias_models, coloured_noise, consistency, conventions,  # noqa: E402
                                    corridor, eskf_bias, gnss, initialisation, intuition, kf_tuning, lidar_radar,
                                    mechanisation, motion, real_sensors, visual_odometry, wrong_models)
from kalman_course.data.observation_errors import WhiteErrors  # noqa: E402
from kalman_course.evaluation.consistency import innovation_whiteness  # noqa: E402
from kalman_course.plotting import (bayes as pbayes, coloured_noise as pcoloured, eskf as peskf,  # noqa: E402
                                    gaussians as pgaussians, intuition as pintuition, kf as pkf,
                                    visual_odometry as pvo, vocabulary)
from kalman_course.symbolic import equations, kalman, motion as smotion, numeric, radar, registry  # noqa: E402

# ---------------------------------------------------------------------------------------
# good values
# ---------------------------------------------------------------------------------------

I2, I3 = np.eye(2), np.eye(3)
Z2, Z3 = np.zeros(2), np.zeros(3)
F2 = np.array([[1.0, 0.1], [0.0, 1.0]])
G12 = np.array([[1.0, 0.0]])
K21 = np.array([[0.5], [0.1]])
R1 = np.array([[0.5]])
Q_UNIT = np.array([1.0, 0.0, 0.0, 0.0])
T5 = np.linspace(0.0, 0.4, 5)
W5 = np.tile([0.1, 0.2, 0.3], (5, 1))
Q5 = np.tile(Q_UNIT, (5, 1))
ROUTE = np.column_stack([np.arange(8.0), np.zeros(8), np.zeros(8)])
ROUTE_R = np.tile(I3, (8, 1, 1))
X_CTRV = np.array([0.0, 0.0, 5.0, 0.1, 0.2])
BEACONS = np.array([[10.0, 0.0], [0.0, 10.0]])
SAMPLES = np.random.default_rng(0).standard_normal((50, 2))
CASE = conventions.example_case(seed=0)
FORCE = np.array([0.1, 0.2, 9.8])
RATE = np.array([0.01, 0.02, 0.1])
GRAVITY = np.array([0.0, 0.0, -9.8092])
P15 = np.eye(15)
BELIEF = np.full(5, 0.2)
NU5 = np.random.default_rng(1).standard_normal(5)
WHITE5 = innovation_whiteness(NU5[:, None], np.ones((5, 1, 1)), max_lag=2)


def _g(x):
    return np.asarray(x)[:1]


def _G(x):
    return G12


def _cost(x):
    return float(np.asarray(x) @ np.asarray(x))


def _rate(t):
    return np.array([0.1, 0.2, 0.3])


class _Axes:
    """Placeholder of a good ``ax``: a fresh Axes is made at call time (no figure at import)."""

    def __repr__(self):
        return "AXES"


AXES = _Axes()


def bad_objects():
    """A record or result of the package where something else was passed."""
    return [("None", None, False), ("number", 3, False), ("string", "abc", False), ("object", object(), False)]


def bad_choices():
    """One of a few names (a rule, a model, a remedy)."""
    return [("unknown", "nope", False), ("None", None, False), ("number", 3, False), ("list", ["cv"], False)]


def bad_strict_flags():
    """A flag: True or False only (never 1, 'yes' or the string 'False')."""
    return [("int 1", 1, False), ("string False", "False", False), ("None", None, False)]


def bad_seed_lists():
    return [("empty", [], False), ("negative", [-1], False), ("float", [1.5], False), ("string", "12", False),
            ("None", None, False), ("bool", [True], False)]


def bad_axes():
    return [("None", None, False), ("number", 3, False), ("string", "ax", False)]


def bad_correlations():
    return [("above one", 1.5, False), ("below minus one", -1.5, False), ("NaN", math.nan, False),
            ("string", "0.5", False), ("None", None, False), ("bool", True, False)]


def bad_latitudes():
    """A latitude in degrees: radians would pass silently, a value outside [-90, 90] must not."""
    return [("above 90", 120.0, False), ("below -90", -95.0, False), ("NaN", math.nan, False),
            ("string", "49", False), ("None", None, False), ("bool", True, False)]


def bad_rotations():
    """One rotation matrix (3, 3)."""
    nan = I3.copy()
    nan[1, 1] = np.nan
    return [("scaled", 2.0 * I3, False), ("reflection", np.diag([1.0, 1.0, -1.0]), False), ("NaN", nan, False),
            ("(2, 2)", I2, False), ("1-D", np.ones(3), False), ("string", "abc", False), ("None", None, False)]


LOCAL_KINDS = {"rotation": bad_rotations, "obj": bad_objects, "choice": bad_choices, "strict_flag": bad_strict_flags,
               "seeds": bad_seed_lists, "ax": bad_axes, "rho": bad_correlations, "latitude": bad_latitudes}
KINDS = {**ALL_KINDS, **LOCAL_KINDS}

# The plotting functions validate their data arguments through shared helpers (the
# vocabulary's _vector, _points, _times and _covariance2, and as_rows), each tried with every
# bad value of its kinds on the functions of FULL_PLOTS. The other plotting functions get, for
# each data argument, its size errors (checked against the function's other arguments) and
# one or two representatives of the rest: a figure per case is what makes the file slow.
DATA_KINDS = {"vector", "rows", "times", "matrix", "psd", "pd", "real", "rotations", "covs"}
FULL_PLOTS = {"plot_truth", "plot_sigma_band", "plot_track", "plot_samples", "plot_pose_errors",
              "plot_covariance_ellipse", "flag_spans"}
REPRESENTATIVES = {"string", "NaN", "decreasing", "wrong tail", "indefinite"}


def _tried(fn, kind: str, label: str, size_only: bool) -> bool:
    """Whether the bad value ``label`` of ``kind`` is tried on ``fn`` (see FULL_PLOTS)."""
    module = getattr(fn, "wrapped", fn).__module__
    if not module.startswith("kalman_course.plotting") or kind not in DATA_KINDS or fn.__name__ in FULL_PLOTS:
        return True
    return size_only or label in REPRESENTATIVES


_SPARE: dict = {}   # a clean Axes, made by the first call that needs one (not at import)


def _clean_axes():
    """An Axes with nothing drawn on it: the spare one while no call has drawn on it, else a new
    one (on a Figure outside pyplot, so that nothing needs closing). Most bad calls raise before
    drawing, so one Axes serves many of them."""
    ax = _SPARE.get("ax")
    if (ax is None or len(ax.get_children()) != _SPARE["children"] or ax.get_yscale() != "linear"
            or ax.get_aspect() != "auto"):
        from matplotlib.figure import Figure

        ax = Figure().add_subplot()
        _SPARE.update(ax=ax, children=len(ax.get_children()))
    return ax


def plot_closed(fn):
    """``fn`` (a figure-making function) whose figures are closed after each call."""
    def call(**kwargs):
        if kwargs.get("ax") is AXES:
            kwargs["ax"] = _clean_axes()
        try:
            return fn(**kwargs)
        finally:
            plt.close("all")
    call.__name__ = fn.__name__
    call.wrapped = fn
    return call


# ---------------------------------------------------------------------------------------
# the public functions: (function, good kwargs, {arg: (kind, params)}, {arg: sized_by})
# ---------------------------------------------------------------------------------------

SPECS = [
    # chapters.beacons
    (beacons.beacon_observation, dict(beacons=BEACONS), {"beacons": ("rows", (2, (2,)))}, {}),
    (beacons.beacon_jacobian, dict(beacons=BEACONS), {"beacons": ("rows", (2, (2,)))}, {}),
    (beacons.bearings_residual, dict(y=[1.0, 0.1, 2.0, 0.2], y_pred=[1.0, 0.0, 2.0, 0.0]),
     {"y": ("vector", (4,)), "y_pred": ("vector", (4,))}, {"y": "y_pred", "y_pred": "y"}),
    # chapters.coloured_noise
    (coloured_noise.inflation_factor, dict(time_constant=1.0, interval=0.1),
     {"time_constant": ("nonneg", ()), "interval": ("scalar", ())}, {}),
    (coloured_noise.decimation_step, dict(time_constant=1.0, interval=0.1),
     {"time_constant": ("nonneg", ()), "interval": ("scalar", ())}, {}),
    (coloured_noise.remedy_label, dict(remedy="inflated_R", time_constant=1.0, interval=0.1),
     {"remedy": ("choice", ()), "time_constant": ("nonneg", ()), "interval": ("scalar", ())}, {}),
    # chapters.consistency
    (consistency.simple_update, dict(P=I2, K=K21, G=G12),
     {"P": ("matrix", (2, 2)), "K": ("matrix", (2, 1)), "G": ("matrix", (1, 2))}, {"P": "K", "K": "G", "G": "K"}),
    (consistency.joseph_update, dict(P=I2, K=K21, G=G12, R=R1),
     {"P": ("matrix", (2, 2)), "K": ("matrix", (2, 1)), "G": ("matrix", (1, 2)), "R": ("psd", (1,))},
     {"P": "K", "K": "G", "G": "K", "R": "K"}),
    (consistency.symmetrise, dict(P=F2), {"P": ("matrix", (2, 2))}, {}),
    (consistency.covariance_health, dict(P=I2), {"P": ("matrix", (2, 2))}, {}),
    (consistency.roundoff_experiment, dict(form="joseph", symmetric=False, steps=5, T=0.1, q=1e-6, r=1e-4, p0=1e4),
     {"form": ("choice", ()), "symmetric": ("strict_flag", ()), "steps": ("count", ()), "T": ("scalar", ()),
      "q": ("nonneg", ()), "r": ("scalar", ()), "p0": ("scalar", ())}, {}),
    (consistency.combined_verdict, dict(nees_verdict="consistent", nis_verdict="overconfident"),
     {"nees_verdict": ("choice", ()), "nis_verdict": ("choice", ())}, {}),
    (consistency.scaled_config, dict(config="kitti_lidar", q_factor=2.0, r_factor=0.5),
     {"config": ("config", ()), "q_factor": ("scalar", ()), "r_factor": ("scalar", ())}, {}),
    # chapters.corridor
    (corridor.scenario, dict(world=corridor.CORRIDOR, seed=0, steps=4, p_correct=0.85, step_probs={1: 1.0}),
     {"world": ("vector", (len(corridor.CORRIDOR),)), "seed": ("seed", ()), "steps": ("count", ()),
      "p_correct": ("prob", ()), "step_probs": ("obj", ())}, {}),
    (corridor.corridor_scenario, dict(seed=0, steps=4, p_correct=0.85),
     {"seed": ("seed", ()), "steps": ("count", ()), "p_correct": ("prob", ())}, {}),
    # chapters.eskf_bias
    (eskf_bias.earth_rate, dict(latitude_deg=49.0), {"latitude_deg": ("latitude", ()), "rate": ("scalar", ())}, {}),
    (eskf_bias.frozen_bias, dict(config="kitti_lidar"), {"config": ("config", ())}, {}),
    # chapters.real_sensors
    (real_sensors.normalised_draws, dict(model=WhiteErrors(0.2, 0.3), t=T5, repeats=2, seed=0),
     {"model": ("errors", ()), "t": ("times", (5,)), "repeats": ("count", ()), "seed": ("seed", ())}, {}),
    (real_sensors.mean_variance_factor, dict(phi=0.5, n=10), {"phi": ("rho", ()), "n": ("count", ())}, {}),
    (real_sensors.relative_jacobian_by_differences, dict(p_clone=Z3, R_clone=I3, p_check=np.array([1.0, 0, 0]),
                                                         R_check=I3),
     {"p_clone": ("vector", (3,)), "R_clone": ("rotation", ()), "p_check": ("vector", (3,)),
      "R_check": ("rotation", ()), "h": ("scalar", ())}, {}),
    (real_sensors.segment_errors, dict(position=ROUTE, rotation=ROUTE_R, true_position=ROUTE, true_rotation=ROUTE_R,
                                       first=[0, 2], last=[4, 6], length=[4.0, 4.0]),
     {"position": ("matrix", (8, 3)), "rotation": ("rotations", (8,)), "true_position": ("matrix", (8, 3)),
      "true_rotation": ("rotations", (8,))}, {"position": "true_position", "true_position": "position",
                                              "rotation": "position", "true_rotation": "position"}),
    # chapters.intuition
    (intuition.kf_1d_table, dict(x0=0.0, P0=1.0, ys=[1.0, 2.0, 3.0], q=0.1, r=0.5),
     {"x0": ("any_real", ()), "P0": ("nonneg", ()), "ys": ("vector", (3,)), "q": ("nonneg", ()),
      "r": ("scalar", ())}, {}),
    (intuition.scalar_gain, dict(P_check=1.0, R=0.5, g=1.0), {"P_check": ("nonneg", ()), "R": ("nonneg", ())}, {}),
    (intuition.steady_state, dict(F=F2, Q=0.1 * I2, G=G12, R=R1),
     {"F": ("matrix", (2, 2)), "Q": ("psd", (2,)), "G": ("matrix", (1, 2)), "R": ("pd", (1,)),
      "rtol": ("scalar", ()), "max_steps": ("count", ())}, {"Q": "F", "R": "G", "G": "F"}),
    (intuition.cross_range_covariance, dict(mean_xy=[10.0, 5.0], sigma_across=1.0, sigma_along=0.1),
     {"mean_xy": ("vector", (2,)), "sigma_across": ("nonneg", ()), "sigma_along": ("nonneg", ())}, {}),
    (intuition.radar_cloud, dict(mean_xy=np.array([10.0, 5.0]), cov_xy=I2, n_samples=50, seed=0, n_sigma=3.0),
     {"mean_xy": ("vector", (2,)), "cov_xy": ("psd", (2,)), "n_samples": ("count", ()), "seed": ("seed", ()),
      "n_sigma": ("scalar", ())}, {}),
    (intuition.map_cost, dict(x=Z2, x_check=Z2, P_check=I2, y=[0.5], g=_g, R=R1),
     {"x": ("vector", (2,)), "x_check": ("vector", (2,)), "P_check": ("pd", (2,)), "y": ("vector", (1,)),
      "g": ("callable", ()), "R": ("pd", (1,))}, {"x": "x_check", "x_check": "P_check", "y": "R"}),
    (intuition.gauss_newton_cost, dict(x=Z2, x_op=Z2, x_check=Z2, P_check=I2, y=[0.5], g=_g, G=_G, R=R1),
     {"x": ("vector", (2,)), "x_op": ("vector", (2,)), "x_check": ("vector", (2,)), "P_check": ("pd", (2,)),
      "y": ("vector", (1,)), "g": ("callable", ()), "G": ("callable", ()), "R": ("pd", (1,))},
     {"x": "x_check", "x_op": "x_check", "x_check": "P_check", "y": "R"}),
    (intuition.cost_on_plane, dict(cost=_cost, point=Z2, u=[-1.0, 0.0, 1.0], v=[-1.0, 1.0]),
     {"cost": ("callable", ()), "point": ("vector", (2,)), "u": ("vector", (3,)), "v": ("vector", (2,))}, {}),
    (intuition.iekf_iterates, dict(x_check=Z2, P_check=I2, y=[0.5], g=_g, G=_G, R=R1, max_iter=3),
     {"x_check": ("vector", (2,)), "P_check": ("psd", (2,)), "y": ("vector", (1,)), "g": ("callable", ()),
      "G": ("callable", ()), "R": ("pd", (1,)), "max_iter": ("count", ()), "tol": ("nonneg", ())},
     {"x_check": "P_check", "y": "R"}),
    (intuition.truncated_normal_moments, dict(mu=0.0, sigma=1.0, low=-1.0, high=2.0),
     {"mu": ("any_real", ()), "sigma": ("scalar", ())}, {}),
    (intuition.information_trial, dict(mu=Z2, P_check=I2, G=G12, R=R1, seeds=[0, 1], n_runs=5),
     {"mu": ("vector", (2,)), "P_check": ("psd", (2,)), "G": ("matrix", (1, 2)), "R": ("pd", (1,)),
      "seeds": ("seeds", ()), "n_runs": ("count", ()), "bias": ("vector", (1,)), "R_true": ("psd", (1,))},
     {"mu": "P_check", "G": "P_check", "R": "G", "bias": "G", "R_true": "G"}),
    (intuition.correlated_pair_covariance, dict(sigma_x=1.0, sigma_y=2.0, rho=0.5),
     {"sigma_x": ("nonneg", ()), "sigma_y": ("nonneg", ()), "rho": ("rho", ())}, {}),
    (intuition.window_slice, dict(samples=SAMPLES, y_obs=0.0, half_width=0.5),
     {"samples": ("rows", (50, (2,))), "y_obs": ("any_real", ()), "half_width": ("scalar", ())}, {}),
    (intuition.ellipse_highest_point, dict(mean=Z2, cov=I2, n_sigma=2.0, n_points=101),
     {"mean": ("vector", (2,)), "cov": ("psd", (2,)), "n_sigma": ("scalar", ()), "n_points": ("count", ())}, {}),
    # chapters.mechanisation
    (mechanisation.coning_attitude, dict(t=T5, cone_angle=0.1, cone_rate=2.0),
     {"t": ("vector", (5,)), "cone_angle": ("any_real", ()), "cone_rate": ("any_real", ())}, {}),
    (mechanisation.coning_rate, dict(t=T5, cone_angle=0.1, cone_rate=2.0),
     {"t": ("vector", (5,)), "cone_angle": ("any_real", ()), "cone_rate": ("any_real", ())}, {}),
    (mechanisation.coning_rate_integral, dict(t=T5, cone_angle=0.1, cone_rate=2.0),
     {"t": ("times", (5,)), "cone_angle": ("any_real", ()), "cone_rate": ("any_real", ())}, {}),
    (mechanisation.reference_attitude, dict(rate=_rate, t=T5, q0=Q_UNIT, substeps=2),
     {"rate": ("callable", ()), "t": ("times", (5,)), "q0": ("vector", (4,)), "substeps": ("count", ())}, {}),
    (mechanisation.step_rotation_vectors, dict(w=W5, T=0.1, rule="first_order"),
     {"w": ("rows", (5, (3,))), "T": ("scalar", ()), "rule": ("choice", ())}, {}),
    (mechanisation.sola_increment, dict(w0=RATE, w1=RATE, T=0.1),
     {"w0": ("vector", (3,)), "w1": ("vector", (3,)), "T": ("scalar", ())}, {}),
    (mechanisation.local_errors, dict(rate0=RATE, rate_change=RATE, steps=[0.1, 0.05], substeps=4),
     {"rate0": ("vector", (3,)), "rate_change": ("vector", (3,)), "steps": ("vector", (2,)),
      "substeps": ("count", ())}, {}),
    (mechanisation.integrate_quaternion, dict(q0=Q_UNIT, w=W5, T=0.1, rule="euler"),
     {"q0": ("vector", (4,)), "w": ("rows", (5, (3,))), "T": ("scalar", ()), "rule": ("choice", ())}, {}),
    (mechanisation.integrate_rotation_matrix, dict(R0=I3, w=W5, T=0.1, rule="first_order"),
     {"R0": ("rotation", ()), "w": ("rows", (5, (3,))), "T": ("scalar", ()), "rule": ("choice", ())}, {}),
    (mechanisation.attitude_error, dict(q_est=Q5, q_true=Q5),
     {"q_est": ("rows", (5, (4,))), "q_true": ("rows", (5, (4,)))}, {"q_est": "q_true", "q_true": "q_est"}),
    (mechanisation.max_attitude_errors, dict(q_true=Q5, w=W5, T=0.1, rule="first_order", strides=(1, 2)),
     {"q_true": ("rows", (5, (4,))), "w": ("rows", (5, (3,))), "T": ("scalar", ()), "rule": ("choice", ())},
     {"q_true": "w", "w": "q_true"}),
    (mechanisation.halving_ratios, dict(errors=[8.0, 4.0, 2.0]), {"errors": ("vector", (3,))}, {}),
    (mechanisation.loglog_slope, dict(steps=[0.1, 0.2, 0.4], errors=[1.0, 4.0, 16.0]),
     {"steps": ("vector", (3,)), "errors": ("vector", (3,))}, {"steps": "errors", "errors": "steps"}),
    (mechanisation.position_error_growth, dict(channel="tilt_rate", size=1e-4, t=10.0),
     {"channel": ("choice", ()), "size": ("any_real", ()), "gravity": ("scalar", ())}, {}),
    (mechanisation.chain_position_error, dict(channel="tilt_rate", size=1e-4, t=10.0),
     {"channel": ("choice", ()), "size": ("any_real", ()), "t": ("scalar", ()), "gravity": ("scalar", ())}, {}),
    # chapters.motion
    (motion.noise_inside_step, dict(model="ctrv", x=X_CTRV, T=0.1, w=np.array([0.1, 0.01]), n_nodes=4),
     {"model": ("choice", ()), "x": ("vector", (5,)), "T": ("scalar", ()), "n_nodes": ("count", ())}, {}),
    (motion.noise_covariance_check, dict(model="ctrv", x=X_CTRV, T=0.1, sigmas=[1.0, 0.5], seeds=range(1),
                                         n_samples=50),
     {"model": ("choice", ()), "x": ("vector", (5,)), "T": ("scalar", ()), "sigmas": ("vector", (2,)),
      "n_samples": ("count", ())}, {}),
    # chapters.conventions
    (conventions.as_convention, dict(value=("nominal - true", "right")), {"value": ("choice", ())}, {}),
    (conventions.error_state, dict(nominal=CASE.nominal, true=CASE.true, convention=conventions.COURSE),
     {"nominal": ("obj", ()), "true": ("obj", ()), "convention": ("choice", ())}, {}),
    (conventions.nominal_with_error, dict(true=CASE.true, dx=CASE.dx, convention=conventions.COURSE),
     {"true": ("obj", ()), "dx": ("vector", (15,)), "convention": ("choice", ())}, {}),
    (conventions.inject, dict(nominal=CASE.nominal, dx_hat=CASE.dx, convention=conventions.COURSE),
     {"nominal": ("obj", ()), "dx_hat": ("vector", (15,)), "convention": ("choice", ())}, {}),
    (conventions.attitude_error_to_left, dict(R_check=I3, dtheta_right=RATE),
     {"R_check": ("rotation", ()), "dtheta_right": ("vector", (3,))}, {}),
    (conventions.error_dynamics, dict(nominal=CASE.nominal, specific_force=FORCE, angular_rate=RATE,
                                      convention=conventions.COURSE),
     {"nominal": ("obj", ()), "specific_force": ("vector", (3,)), "angular_rate": ("vector", (3,)),
      "convention": ("choice", ())}, {}),
    (conventions.flow, dict(state=CASE.true, specific_force=FORCE, angular_rate=RATE, gravity=GRAVITY, t=0.1),
     {"state": ("obj", ()), "specific_force": ("vector", (3,)), "angular_rate": ("vector", (3,)),
      "gravity": ("vector", (3,)), "t": ("any_real", ())}, {}),
    (conventions.velocity_rate, dict(rotation=I3, specific_force=FORCE, gravity=GRAVITY),
     {"rotation": ("rotation", ()), "specific_force": ("vector", (3,)), "gravity": ("vector", (3,)),
      "gravity_sign": ("any_real", ())}, {}),
    (conventions.example_case, dict(seed=0, error_scale=1e-4),
     {"seed": ("seed", ()), "error_scale": ("scalar", ()), "gravity": ("vector", (3,))}, {}),
    (conventions.injection_miss, dict(true=CASE.true, dx=CASE.dx, made_in=conventions.COURSE,
                                      injected_with=conventions.CONVENTIONS[1]),
     {"true": ("obj", ()), "dx": ("vector", (15,)), "made_in": ("choice", ()), "injected_with": ("choice", ())}, {}),
    (conventions.seed_framework_dynamics, dict(nominal=CASE.nominal, specific_force=FORCE, angular_rate=RATE),
     {"nominal": ("obj", ()), "specific_force": ("vector", (3,)), "angular_rate": ("vector", (3,)),
      "force_frame": ("choice", ())}, {}),
    # chapters.initialisation
    (initialisation.roll_pitch_from_force, dict(specific_force=FORCE), {"specific_force": ("vector", (3,))}, {}),
    (initialisation.rotation_from_euler, dict(roll=0.1, pitch=0.2, yaw=0.3),
     {"roll": ("any_real", ()), "pitch": ("any_real", ()), "yaw": ("any_real", ())}, {}),
    (initialisation.euler_from_rotation, dict(R=I3), {"R": ("rotation", ())}, {}),
    (initialisation.tilt_sigma, dict(gravity_tolerance=0.02, gravity_norm=9.81, accel_bias_sigma=0.01),
     {"gravity_tolerance": ("nonneg", ()), "gravity_norm": ("scalar", ()), "accel_bias_sigma": ("nonneg", ())}, {}),
    (initialisation.heading_from_fixes, dict(p_a=Z3, p_b=np.array([10.0, 5.0, 0.0]), sigma=1.0),
     {"p_a": ("vector", (3,)), "p_b": ("vector", (3,)), "sigma": ("nonneg", ())}, {}),
    (initialisation.heading_sigma, dict(sigma=1.0, distance=10.0, turn=0.01),
     {"sigma": ("nonneg", ()), "distance": ("scalar", ())}, {}),
    (initialisation.speed_for_heading, dict(sigma=1.0, heading_sigma_max=0.05, interval=2.0),
     {"sigma": ("nonneg", ()), "heading_sigma_max": ("scalar", ()), "interval": ("scalar", ())}, {}),
    (initialisation.lag_corrected_velocity, dict(p_a=Z3, p_b=np.array([1.0, 0.0, 0.0]), t_a=0.0, t_b=1.0,
                                                 t=np.array([0.0, 0.5, 1.0]), acceleration=np.zeros((3, 3))),
     {"p_a": ("vector", (3,)), "p_b": ("vector", (3,)), "t_a": ("any_real", ()), "t_b": ("any_real", ()),
      "t": ("times", (3,)), "acceleration": ("rows", (3, (3,)))}, {"t": "acceleration", "acceleration": "t"}),
    (initialisation.initial_covariance, dict(rotation=I3, sigma_position=1.0, sigma_velocity=0.5, sigma_tilt=0.01,
                                             sigma_heading=0.05),
     {"rotation": ("rotation", ()), "sigma_tilt": ("nonneg", ()), "sigma_heading": ("nonneg", ()),
      "config": ("config", ())}, {}),
    (initialisation.settling_time, dict(t=T5, values=[3.0, 2.0, 1.0, 0.5, 0.2], threshold=1.0),
     {"t": ("times", (5,)), "values": ("vector", (5,)), "threshold": ("nonneg", ())},
     {"t": "values", "values": "t"}),
    (initialisation.scale_blocks, dict(P0=P15, factors={"position": 2.0}),
     {"P0": ("psd", (15,)), "factors": ("obj", ())}, {}),
    # chapters.lidar_radar
    (lidar_radar.ctrv_to_cartesian, dict(states=np.tile(X_CTRV, (3, 1))), {"states": ("rows", (3, (5,)))}, {}),
    (lidar_radar.initial_ctrv_state, dict(z_lidar=[1.0, 2.0], R_lidar=0.0225 * I2),
     {"z_lidar": ("vector", (2,)), "R_lidar": ("psd", (2,)), "sigma_v": ("scalar", ()), "sigma_yaw": ("scalar", ()),
      "sigma_yaw_rate": ("scalar", ())}, {}),
    (lidar_radar.radar_position_fix, dict(z_radar=[10.0, 0.1, 1.0], R_radar=np.diag([0.09, 9e-4, 0.09])),
     {"z_radar": ("vector", (3,)), "R_radar": ("psd", (3,))}, {}),
    (lidar_radar.cartesian_rmse, dict(estimate_cart=np.ones((3, 4)), truth_cart=np.zeros((3, 4))),
     {"estimate_cart": ("rows", (3, (4,))), "truth_cart": ("rows", (3, (4,)))},
     {"estimate_cart": "truth_cart", "truth_cart": "estimate_cart"}),
    # chapters.visual_odometry
    (visual_odometry.anchor, dict(position=ROUTE, rotation=ROUTE_R, true_position=Z3, true_rotation=I3, frame=2),
     {"position": ("rows", (8, (3,))), "rotation": ("rotations", (8,)), "true_position": ("vector", (3,)),
      "true_rotation": ("rotation", ()), "frame": ("int", ((0, 7),))}, {"rotation": "position"}),
    (visual_odometry.block_nis, dict(innovation=np.ones((4, 6)), S=np.tile(np.eye(6), (4, 1, 1)), block=slice(0, 3)),
     {"innovation": ("rows", (4, (6,))), "S": ("covs", (4, 6)), "block": ("obj", ())},
     {"innovation": "S", "S": "innovation"}),
    (visual_odometry.white_increments, dict(true_position=ROUTE, true_rotation=ROUTE_R, t=np.arange(8.0) * 0.1,
                                            std=(0.01, 0.001), seed=0),
     {"true_position": ("rows", (8, (3,))), "true_rotation": ("rotations", (8,)), "t": ("times", (8,)),
      "std": ("vector", (2,)), "seed": ("seed", ())},
     {"true_position": "t", "true_rotation": "t", "t": "true_position"}),
    (visual_odometry.yaw_error, dict(rotation=ROUTE_R, true_rotation=ROUTE_R),
     {"rotation": ("rotations", (8,)), "true_rotation": ("rotations", (8,))},
     {"rotation": "true_rotation", "true_rotation": "rotation"}),
    (visual_odometry.yaw_variance, dict(rotation=ROUTE_R, P=np.tile(P15, (8, 1, 1))),
     {"rotation": ("rotations", (8,)), "P": ("covs", (8, 15))}, {"rotation": "P", "P": "rotation"}),
    (visual_odometry.rotation_increments, dict(rotation=ROUTE_R), {"rotation": ("rotations", (8,))}, {}),
    (visual_odometry.tilt_misalignment, dict(dtheta_vo=W5, dtheta_gyro=W5 * 1.01),
     {"dtheta_vo": ("rows", (5, (3,))), "dtheta_gyro": ("rows", (5, (3,)))},
     {"dtheta_vo": "dtheta_gyro", "dtheta_gyro": "dtheta_vo"}),
    # plotting
    (plot_closed(pbayes.plot_belief_sequence), dict(beliefs=[BELIEF, BELIEF]), {"beliefs": ("obj", ())}, {}),
    (plot_closed(pcoloured.plot_error_draws),
     dict(t=T5, draws={"white": WhiteErrors(0.2, 0.3).draw(T5, np.random.default_rng(0))}, sigma=0.2),
     {"t": ("times", (5,)), "sigma": ("scalar", ())}, {"t": "draws"}),
    (plot_closed(peskf.plot_pose_errors), dict(t=T5, position_error=np.zeros((5, 3)), attitude_error=np.zeros((5, 3)),
                                               std=np.ones((5, 15))),
     {"t": ("times", (5,)), "position_error": ("rows", (5, (3,))), "attitude_error": ("rows", (5, (3,))),
      "std": ("rows", (5, (15,))), "n_sigma": ("scalar", ())},
     {"t": "position_error", "position_error": "t", "attitude_error": "t", "std": "t"}),
    (plot_closed(peskf.plot_bias_estimates), dict(t=T5, accel_bias=np.zeros((5, 3)), gyro_bias=np.zeros((5, 3))),
     {"t": ("times", (5,)), "accel_bias": ("rows", (5, (3,))), "gyro_bias": ("rows", (5, (3,)))},
     {"t": "accel_bias", "accel_bias": "t", "gyro_bias": "t"}),
    (plot_closed(peskf.plot_outage_error), dict(t=T5, error=np.ones(5), sigma=np.ones(5), outage=(0.1, 0.2)),
     {"t": ("times", (5,)), "error": ("vector", (5,)), "sigma": ("vector", (5,)), "n_sigma": ("scalar", ())},
     {"t": "error", "error": "t", "sigma": "t"}),
    (plot_closed(peskf.plot_track_with_zoom), dict(truth_xy=ROUTE[:, :2], estimate_xy=ROUTE[:, :2],
                                                   zoom=((0.0, 3.0), (-1.0, 1.0))),
     {"truth_xy": ("rows", (8, (2,))), "estimate_xy": ("rows", (8, (2,)))}, {}),
    (plot_closed(pgaussians.plot_conditioning), dict(mean=Z2, cov=np.array([[1.0, 0.5], [0.5, 1.0]]), y_obs=0.5,
                                                     cond_mean=0.25, cond_var=0.75),
     {"mean": ("vector", (2,)), "cov": ("psd", (2,)), "y_obs": ("any_real", ()), "cond_mean": ("any_real", ()),
      "cond_var": ("scalar", ())}, {}),
    (plot_closed(pgaussians.plot_conditional_slice), dict(mean=Z2, cov=np.array([[1.0, 0.5], [0.5, 1.0]]), y_obs=0.5),
     {"mean": ("vector", (2,)), "cov": ("pd", (2,)), "y_obs": ("any_real", ())}, {}),
    (plot_closed(pintuition.plot_gain_limits), dict(ax=AXES, ratio=np.array([0.1, 1.0, 10.0]),
                                                    gain=np.array([0.9, 0.5, 0.1])),
     {"ratio": ("vector", (3,)), "gain": ("vector", (3,))}, {"ratio": "gain", "gain": "ratio"}),
    (plot_closed(pkf.plot_innovations), dict(t=T5, cases={"a": (NU5, np.ones(5), WHITE5)}),
     {"t": ("times", (5,)), "cases": ("obj", ())}, {}),
    (plot_closed(pvo.plot_vo_tracks), dict(truth_xy=ROUTE[:, :2], tracks={"vo": ROUTE[:, :2]}),
     {"truth_xy": ("rows", (8, (2,))), "tracks": ("obj", ())}, {}),
    (plot_closed(vocabulary.plot_truth), dict(ax=AXES, t=T5, x=np.ones(5)),
     {"ax": ("ax", ()), "t": ("vector", (5,)), "x": ("vector", (5,))}, {"t": "x", "x": "t"}),
    (plot_closed(vocabulary.plot_measurements), dict(ax=AXES, t=T5, y=np.ones(5)),
     {"ax": ("ax", ()), "t": ("vector", (5,))}, {"t": "y"}),
    (plot_closed(vocabulary.plot_estimate), dict(ax=AXES, t=T5, x=np.ones(5)),
     {"ax": ("ax", ()), "t": ("vector", (5,)), "x": ("vector", (5,))}, {"t": "x", "x": "t"}),
    (plot_closed(vocabulary.plot_sigma_band), dict(ax=AXES, t=T5, center=np.ones(5), sigma=np.ones(5)),
     {"ax": ("ax", ()), "t": ("vector", (5,)), "center": ("vector", (5,)), "sigma": ("vector", (5,)),
      "n_sigma": ("scalar", ())}, {"t": "center", "center": "t", "sigma": "t"}),
    (plot_closed(vocabulary.plot_error_with_band), dict(ax=AXES, t=T5, error=np.ones(5), sigma=np.ones(5)),
     {"ax": ("ax", ()), "t": ("vector", (5,)), "error": ("vector", (5,)), "sigma": ("vector", (5,)),
      "n_sigma": ("scalar", ())}, {"t": "error", "error": "t", "sigma": "t"}),
    (plot_closed(vocabulary.plot_covariance_ellipse), dict(ax=AXES, mean=Z2, cov=I2),
     {"ax": ("ax", ()), "mean": ("vector", (2,)), "cov": ("psd", (2,)), "n_sigma": ("scalar", ())}, {}),
    (vocabulary.covariance_ellipse_axes, dict(cov=I2), {"cov": ("psd", (2,)), "n_sigma": ("scalar", ())}, {}),
    (plot_closed(vocabulary.plot_belief), dict(ax=AXES, belief=BELIEF),
     {"ax": ("ax", ()), "belief": ("vector", (5,)), "positions": ("vector", (5,))}, {"positions": "belief"}),
    (plot_closed(vocabulary.plot_samples), dict(ax=AXES, points=SAMPLES),
     {"ax": ("ax", ()), "points": ("rows", (50, (2,)))}, {}),
    (plot_closed(vocabulary.plot_consistency), dict(ax=AXES, t=T5, values=np.ones(5), lo=0.5, hi=2.0),
     {"ax": ("ax", ()), "t": ("vector", (5,)), "values": ("vector", (5,))}, {"t": "values", "values": "t"}),
    (plot_closed(vocabulary.plot_consistency_curves), dict(ax=AXES, t=T5, curves={"a": np.ones(5)}, lo=0.5, hi=2.0),
     {"ax": ("ax", ()), "t": ("vector", (5,)), "curves": ("obj", ()), "log": ("strict_flag", ())}, {"t": "curves"}),
    (plot_closed(vocabulary.plot_track), dict(ax=AXES, truth_xy=ROUTE[:, :2], estimate_xy=ROUTE[:, :2]),
     {"ax": ("ax", ()), "truth_xy": ("rows", (8, (2,))), "estimate_xy": ("rows", (8, (2,)))}, {}),
    (plot_closed(vocabulary.shade_spans), dict(ax=AXES, spans=[(0.0, 1.0)]), {"ax": ("ax", ()), "spans": ("obj", ())},
     {}),
    (vocabulary.flag_spans, dict(t=T5, flags=np.array([False, True, True, False, False])),
     {"t": ("times", (5,)), "flags": ("obj", ())}, {}),
    (plot_closed(vocabulary.plot_curves), dict(ax=AXES, curves={"a": (T5, np.ones(5))}),
     {"ax": ("ax", ()), "curves": ("obj", ())}, {}),
    # symbolic
    (kalman.cv_transition, dict(T=0.1, dim=2), {"T": ("scalar", ()), "dim": ("dim", ())}, {}),
    (kalman.cv_noise_jacobian, dict(T=0.1, dim=2), {"T": ("scalar", ()), "dim": ("dim", ())}, {}),
    (kalman.cv_process_noise, dict(T=0.1, sigma_a=1.0, dim=2),
     {"T": ("scalar", ()), "sigma_a": ("nonneg", ()), "dim": ("dim", ())}, {}),
    (kalman.cv_process_noise_continuous, dict(T=0.1, q=1.0, dim=2),
     {"T": ("scalar", ()), "q": ("nonneg", ()), "dim": ("dim", ())}, {}),
    (kalman.cv_observation_matrix, dict(dim=2), {"dim": ("dim", ())}, {}),
    (smotion.motion_state_names, dict(model="ctrv"), {"model": ("choice", ())}, {}),
    (smotion.motion_step, dict(model="ctrv", x=X_CTRV, T=0.1),
     {"model": ("choice", ()), "x": ("vector", (5,)), "T": ("scalar", ()), "w": ("vector", (2,))}, {}),
    (smotion.motion_jacobian, dict(model="ctrv", x=X_CTRV, T=0.1),
     {"model": ("choice", ()), "x": ("vector", (5,)), "T": ("scalar", ())}, {}),
    (smotion.motion_noise_jacobian, dict(model="ctrv", x=X_CTRV, T=0.1),         # CTRA's lambdify costs 0.7 s
     {"model": ("choice", ()), "x": ("vector", (5,)), "T": ("scalar", ())}, {}),
    (smotion.motion_process_noise, dict(model="ctrv", x=X_CTRV, T=0.1, sigmas=[1.0, 0.5]),
     {"model": ("choice", ()), "x": ("vector", (5,)), "T": ("scalar", ()), "sigmas": ("vector", (2,))}, {}),
    (smotion.ctrv_step, dict(x=X_CTRV, T=0.1), {"x": ("vector", (5,)), "T": ("scalar", ()), "w": ("vector", (2,))},
     {}),
    (smotion.ctrv_jacobian, dict(x=X_CTRV, T=0.1), {"x": ("vector", (5,)), "T": ("scalar", ())}, {}),
    (smotion.ctrv_noise_jacobian, dict(x=X_CTRV, T=0.1), {"x": ("vector", (5,)), "T": ("scalar", ())}, {}),
    (radar.radar_observation, dict(x=X_CTRV + [3.0, 4.0, 0, 0, 0]),
     {"x": ("vector", (5,)), "model": ("choice", ())}, {}),
    (radar.radar_jacobian, dict(x=X_CTRV + [3.0, 4.0, 0, 0, 0]),
     {"x": ("vector", (5,)), "model": ("choice", ())}, {}),
    (numeric.as_real, dict(value=1.0, name="value"), {"value": ("nonneg", ())}, {}),
    (numeric.as_time_step, dict(T=0.1), {"T": ("scalar", ())}, {}),
    (numeric.as_dimension, dict(dim=2), {"dim": ("dim", ())}, {}),
    (equations.symbol_matrix, dict(name="P", rows=2, cols=2),
     {"name": ("name", ()), "rows": ("count", ()), "cols": ("count", ())}, {}),
    (registry.derivation, dict(name="linear_map_moments"), {"name": ("choice", ())}, {}),
]

# Bad values that are right for some arguments.
ALLOWED = {
    # any number of rows or values where the argument itself fixes it
    ("beacon_observation", "beacons", "wrong count"), ("beacon_jacobian", "beacons", "wrong count"),
    ("coning_attitude", "t", "wrong length"), ("coning_rate", "t", "wrong length"),
    ("coning_rate_integral", "t", "wrong count"), ("reference_attitude", "t", "wrong count"),
    ("step_rotation_vectors", "w", "wrong count"), ("integrate_quaternion", "w", "wrong count"),
    ("integrate_rotation_matrix", "w", "wrong count"), ("ctrv_to_cartesian", "states", "wrong count"),
    ("window_slice", "samples", "wrong count"), ("plot_samples", "points", "wrong count"),
    ("cost_on_plane", "u", "wrong length"), ("cost_on_plane", "v", "wrong length"),
    ("local_errors", "steps", "wrong length"), ("halving_ratios", "errors", "wrong length"),
    ("plot_belief", "belief", "wrong length"), ("kf_1d_table", "ys", "wrong length"),
    ("plot_track_with_zoom", "truth_xy", "wrong count"), ("plot_track_with_zoom", "estimate_xy", "wrong count"),
    ("plot_track", "truth_xy", "wrong count"), ("plot_track", "estimate_xy", "wrong count"),
    ("rotation_increments", "rotation", "wrong count"), ("plot_vo_tracks", "truth_xy", "wrong count"),
    ("anchor", "position", "wrong count"), ("block_nis", "innovation", "wrong count"),
    ("tilt_misalignment", "dtheta_vo", "wrong count"), ("cartesian_rmse", "estimate_cart", "wrong count"),
    ("yaw_error", "rotation", "wrong count"), ("yaw_variance", "rotation", "wrong count"),
    ("white_increments", "true_position", "wrong count"), ("settling_time", "t", "wrong length"),
    ("lag_corrected_velocity", "t", "wrong count"), ("segment_errors", "position", "wrong rows"),
    ("attitude_error", "q_est", "wrong count"),
    # an (N, 1) column or (1, N) row is flattened by the plotting vocabulary (ys[:, None])
    *{(fn, arg, label) for fn in ("plot_truth", "plot_measurements", "plot_estimate", "plot_sigma_band",
                                  "plot_error_with_band", "plot_consistency", "plot_consistency_curves",
                                  "plot_belief", "plot_outage_error", "plot_gain_limits")
      for arg in ("t", "x", "center", "sigma", "error", "values", "belief", "positions", "ratio", "gain")
      for label in ("column (n, 1)", "row (1, n)")},
    # a scalar σ is broadcast over the samples
    ("plot_sigma_band", "sigma", "scalar"), ("plot_error_with_band", "sigma", "scalar"),
    ("plot_outage_error", "sigma", "scalar"), ("plot_sigma_band", "center", "scalar"),
    # T = 0 is the identity step; 0 and 1 are a perfect and an always-wrong door sensor
    *{(fn.__name__, "T", "zero") for fn in (kalman.cv_transition, kalman.cv_noise_jacobian, kalman.cv_process_noise,
                                            kalman.cv_process_noise_continuous, smotion.motion_step,
                                            smotion.motion_jacobian, smotion.motion_noise_jacobian,
                                            smotion.motion_process_noise, smotion.ctrv_step, smotion.ctrv_jacobian,
                                            smotion.ctrv_noise_jacobian, numeric.as_time_step)},
    *{(fn, "dim", "four") for fn in ("cv_transition", "cv_noise_jacobian", "cv_process_noise",
                                     "cv_process_noise_continuous", "cv_observation_matrix", "as_dimension")},
    ("scenario", "p_correct", "zero"), ("scenario", "p_correct", "one"),
    ("corridor_scenario", "p_correct", "zero"), ("corridor_scenario", "p_correct", "one"),
    ("chain_position_error", "t", "zero"),
    # optional arguments whose None is the default
    ("motion_step", "w", "None"), ("ctrv_step", "w", "None"), ("information_trial", "bias", "None"),
    ("information_trial", "R_true", "None"), ("plot_belief", "positions", "None"),
    ("initial_covariance", "config", "None"),
    # a NaN state is a time without ground truth (a Udacity log's missing rows)
    ("ctrv_to_cartesian", "states", "NaN"), ("ctrv_to_cartesian", "states", "inf"),
    # the argument fixes the size: a corridor of any number of cells, any number of sample
    # times, a state of any size (the cost is any callable of it)
    ("scenario", "world", "wrong length"), ("normalised_draws", "t", "wrong count"),
    ("cost_on_plane", "point", "wrong length"),
    # NaN marks a step without a measurement (documented; the filter skips it, the plot too)
    ("kf_1d_table", "ys", "NaN"), ("plot_consistency", "values", "NaN"),
    # plot_track draws measured positions through plot_measurements: a missing fix is a NaN row
    ("plot_measurements", "t", "NaN"),
    # arrays of variances give one gain per pair (documented broadcast)
    ("scalar_gain", "P_check", "list"), ("scalar_gain", "R", "list"),
    # T = 0 is the identity step (documented T >= 0, as for the symbolic models above)
    ("noise_inside_step", "T", "zero"),
    # a (1, 3) record is one reading: the documented (n, 3) form with n = 1
    ("roll_pitch_from_force", "specific_force", "row (1, n)"),
    # positions (N, 3) are documented: only east and north are drawn
    ("plot_track_with_zoom", "truth_xy", "wrong tail"), ("plot_track_with_zoom", "estimate_xy", "wrong tail"),
    ("plot_track", "truth_xy", "wrong tail"), ("plot_track", "estimate_xy", "wrong tail"),
    ("plot_vo_tracks", "truth_xy", "wrong tail"),
    # a 2-D mean given as a (2, 1) column or (1, 2) row is flattened, as every data argument of the vocabulary
    *{(fn, "mean", label) for fn in ("plot_conditioning", "plot_conditional_slice", "plot_covariance_ellipse")
      for label in ("column (n, 1)", "row (1, n)")},
}

# Names a message may use instead of the argument's.
ALSO = {("as_convention", "value"): {"convention"}}

# Public functions without a table entry, and why: each needs a whole filter run on a KITTI
# excerpt or on a simulated scenario (seconds to minutes), a result object of one, or builds
# a SymPy derivation (exercised by tests/test_symbolic.py). The fuzz script
# /work/scratch/fuzz_upper.py tries many of them with short excerpts.
EXEMPT_MODULES = {"kalman_course.symbolic.eskf", "kalman_course.symbolic.gaussians", "kalman_course.symbolic.stepwise",
                  "kalman_course.chapters.explorers", "kalman_course.plotting.diagrams"}
EXEMPT = {
    "kitti_beacons", "run_beacon_filter", "runs_over_seeds", "config_for_spec", "frozen_bias_covariance",
    "run_bias_models", "compare_bias_models", "earth_rotation", "earth_rotation_table", "coloured_noise",
    "monte_carlo", "full_state_error", "sensitivity", "whiteness_runs", "inject_outliers", "run_gated",
    "injection_error", "identify_injection", "mixing_table", "error_rate", "dynamics_residual",
    "bias_in_sigmas", "outage_study", "outage_seed_errors", "lidar_seed_spread", "paired_ratio",
    "seed_spread_table", "lidar_source", "gnss_source", "sources_line", "truth_at", "position_rmse_over_seeds",
    "standstill_statistics", "detect_standstill", "level", "initialise_from_gnss", "initialise_from_pose",
    "run_errors", "compare_starts", "p0_block_study", "p0_scaling", "scalar_conditioning", "check_chain",
    "innovation_tuning", "sigma_for_unit_nis", "ctrv_lidar_radar", "read_udacity_log", "figure_eight_lidar_radar",
    "fuse_lidar_radar", "compare_cv_ctrv", "position_nees", "run_kitti_ctrv", "kitti_acceleration",
    "kitti_sigma_a_sweep", "coning_correction_residual", "drive_extent", "neglected_terms", "imu_error_sources",
    "error_budget", "kitti_model_states", "horizon_errors", "predicted_paths", "setup", "run_absolute",
    "run_relative_vo", "run_imu_gnss", "tune_std", "score", "compare", "table", "white_increment_track",
    "white_increment_runs", "simulated_imu", "consistency_score", "run_increments", "linearisation_runs",
    "yaw_change_at_dropouts", "clock_offset_runs", "gyro_increments", "frame_lag", "vo_tilt", "realigned",
    "tuned_relative_std", "vio_variants", "linearisation_table", "vio_table", "corridor_trials",
    # plots of result objects of the runs above
    "plot_bias_models", "plot_coloured_noise", "plot_monte_carlo", "plot_sensitivity", "plot_gating",
    "plot_whiteness", "plot_standstill", "plot_start_comparison", "plot_p0_scaling", "plot_gaussian_product",
    "plot_kf_1d_steps", "plot_gain_convergence", "plot_radar_linearisation", "plot_cost_iterates", "plot_kf_1d",
    "plot_kf_2d", "plot_tuning_dashboard", "plot_bias_sigmas", "plot_error_norms", "plot_drift_by_length",
    # the SymPy layer's builders and helpers (tests/test_symbolic.py)
    "derivation_builder", "is_zero", "has_matrix_symbols", "canonical", "exact_inverse", "kalman_gain",
    "kf_update_conditioning", "cv_model", "cv_planar_model", "ca_model", "ctrv_model", "ctra_model",
    "radar_model", "lambdify_matrix", "builders", "derivations",
}


# Cases that still fail (issue 27): each is marked a strict xfail, so fixing one shows up as
# an XPASS to delete from here. Empty: every case of the table passes; a bad value that is
# right for an argument goes to ALLOWED with its reason instead.
KNOWN_GAPS: set[str] = set()


# Bad values outside the kinds, each once reported wrong: a whole stack of scaled or NaN
# rotations (an error naming so3's ``R``, or a silent result), a frozen-bias config that is
# no configuration (AttributeError; the table's "config" kind has None and {} as well).
_NAN_ROUTE = ROUTE_R.copy()
_NAN_ROUTE[:, 1, 1] = np.nan
EXTRA_CASES = [
    (real_sensors.segment_errors, "true_rotation", "2·I every frame", np.tile(2.0 * I3, (8, 1, 1))),
    (real_sensors.segment_errors, "rotation", "2·I every frame", np.tile(2.0 * I3, (8, 1, 1))),
    (real_sensors.segment_errors, "true_rotation", "NaN every frame", _NAN_ROUTE),
    (real_sensors.segment_errors, "true_rotation", "reflected every frame",
     np.tile(np.diag([1.0, 1.0, -1.0]), (8, 1, 1))),
    (eskf_bias.frozen_bias, "config", "an empty dict", {}),
    (eskf_bias.frozen_bias, "config", "a tuple", ("kitti_lidar",)),
    (vocabulary.plot_samples, "points", "complex ndarray", SAMPLES + 1j),
]


def _cases():
    for fn, good, kinds, sized_by in SPECS:
        for arg, (kind, params) in kinds.items():
            for label, bad, size_only in KINDS[kind](*params):
                if (fn.__name__, arg, label) in ALLOWED or not _tried(fn, kind, label, size_only):
                    continue
                expected = {arg, sized_by.get(arg, arg)} if size_only else {arg}
                expected |= ALSO.get((fn.__name__, arg), set())
                case_id = f"{fn.__name__}-{arg}-{label}"
                marks = [pytest.mark.xfail(strict=True, reason="issue 27: not yet validated")] \
                    if case_id in KNOWN_GAPS else []
                yield pytest.param(fn, good, arg, bad, expected, id=case_id, marks=marks)
    for target, arg, label, bad in EXTRA_CASES:
        fn, good = next((fn, good) for fn, good, *_ in SPECS if getattr(fn, "wrapped", fn) is target)
        yield pytest.param(fn, good, arg, bad, {arg}, id=f"{fn.__name__}-{arg}-{label}")


CASES = list(_cases())


def _public_functions():
    for package in (kalman_course.chapters, kalman_course.plotting, kalman_course.symbolic):
        for info in pkgutil.iter_modules(package.__path__):
            module = importlib.import_module(f"{package.__name__}.{info.name}")
            names = getattr(module, "__all__", None)
            if names is None:
                names = [n for n, o in vars(module).items() if not n.startswith("_") and inspect.isfunction(o)
                         and o.__module__ == module.__name__]
            for name in names:
                obj = getattr(module, name)
                if callable(obj) and not isinstance(obj, type):
                    yield module.__name__, name, obj


def test_every_public_function_has_cases():
    listed = {getattr(fn, "wrapped", fn) for fn, *_ in SPECS}
    missing = [f"{module}.{name}" for module, name, obj in _public_functions()
               if obj not in listed and name not in EXEMPT and module not in EXEMPT_MODULES]
    assert not missing, f"public functions without bad-input cases (add a SPECS entry or an exemption): {missing}"
    assert len(CASES) >= 1000


@pytest.mark.filterwarnings("error::numpy.exceptions.ComplexWarning")   # complex refused, not cast
@pytest.mark.parametrize("fn, good, arg, bad, names", CASES)
def test_bad_argument_is_a_value_error_naming_it(fn, good, arg, bad, names):
    assert_refused(fn, dict(good, **{arg: bad}), names)


@pytest.mark.parametrize("fn, good", [(fn, good) for fn, good, *_ in SPECS], ids=[fn.__name__ for fn, *_ in SPECS])
def test_the_good_arguments_are_good(fn, good):
    with np.errstate(all="raise", under="ignore"):
        fn(**good)


# ---------------------------------------------------------------------------------------
# functions whose good call is a whole run: each bad argument is refused before the work
# ---------------------------------------------------------------------------------------

def _cv_runs():
    from kalman_course.data import cv_target
    return [cv_target(30, 0.1, 1.0, 0.5, seed=s, dim=1) for s in (0, 1)]


def corridor_model():
    return wrong_models.CorridorModel((True, False, False, True, False), 0.9, 0.1, ((1, 0.8), (2, 0.2)))


_RUN = _cv_runs()[0]
# x0, P0, F, G, Q, R of innovation_tuning, for the 1-D CV runs above
CV_MODEL = (np.zeros(2), np.eye(2) * 10.0, _RUN.F, _RUN.H, _RUN.Q, _RUN.R)


HEAVY = [
    (lambda: beacons.run_beacon_filter(None), "scenario"),
    (lambda: beacons.run_beacon_filter(beacons.kitti_beacons("turns", 0), max_iter=0), "max_iter"),
    (lambda: beacons.run_beacon_filter(beacons.kitti_beacons("turns", 0), max_iter=2.5), "max_iter"),
    (lambda: beacons.run_beacon_filter(beacons.kitti_beacons("turns", 0), tol="1e-6"), "tol"),
    (lambda: beacons.run_beacon_filter(beacons.kitti_beacons("turns", 0), tol=-1.0), "tol"),
    (lambda: beacons.runs_over_seeds([0, -1]), r"seeds\[1\]"),
    (lambda: beacons.runs_over_seeds(None), "seeds"),
    (lambda: beacons.runs_over_seeds([True]), r"seeds\[0\]"),
    (lambda: lidar_radar.fuse_lidar_radar("scenario"), "scenario"),
    (lambda: lidar_radar.fuse_lidar_radar(lidar_radar.ctrv_lidar_radar(seed=0), max_iter=None), "max_iter"),
    (lambda: lidar_radar.position_nees(None), "result"),
    (lambda: lidar_radar.kitti_acceleration(3), "excerpt"),
    (lambda: wrong_models.corridor_trials(None, None, [0]), "filter_model"),
    (lambda: wrong_models.corridor_trials(corridor_model(), "truth", [0]), "truth"),
    (lambda: wrong_models.corridor_trials(corridor_model(), corridor_model(), [1.5]), r"seeds\[0\]"),
    (lambda: gnss.truth_at("turns", [1.0]), r"t must lie inside the truth of 'turns'"),
    (lambda: gnss.truth_at("turns", "abc"), "t"),
    (lambda: kf_tuning.innovation_tuning(None, *CV_MODEL), "runs"),
    (lambda: kf_tuning.innovation_tuning(["abc"], *CV_MODEL), r"runs\[0\]"),
    (lambda: kf_tuning.innovation_tuning(_cv_runs(), *CV_MODEL, skip=True), "skip"),
    (lambda: kf_tuning.innovation_tuning(_cv_runs(), *CV_MODEL[:5], "abc"), "R"),
    (lambda: kf_tuning.innovation_tuning(_cv_runs(), *CV_MODEL[:4], np.eye(2) + 0j, CV_MODEL[5]), "Q"),
    (lambda: kf_tuning.sigma_for_unit_nis(_cv_runs(), *CV_MODEL[:5], lo="0.1"), "lo"),
    (lambda: kf_tuning.sigma_for_unit_nis(_cv_runs(), *CV_MODEL[:5], hi=np.inf), "hi"),
    (lambda: kf_tuning.sigma_for_unit_nis(_cv_runs(), *CV_MODEL[:5], iterations=0), "iterations"),
    (lambda: motion.predicted_paths("turns", np.nan, 3.0), "t0"),
    (lambda: motion.predicted_paths("turns", 320.0, 3.0, n=2.0), "n"),
    (lambda: motion.predicted_paths("turns", 320.0, 3.0, causal="False"), "causal"),
    (lambda: motion.kitti_model_states("turns", "cv", causal=1), "causal"),
    (lambda: bias_models.earth_rotation("49"), "latitude_deg"),
    (lambda: bias_models.earth_rotation(True), "latitude_deg"),
]


@pytest.mark.parametrize("call, name", HEAVY, ids=[f"heavy-{i}" for i in range(len(HEAVY))])
def test_a_run_refuses_a_bad_argument_by_name(call, name):
    with pytest.raises(Exception) as info:
        call()
    assert type(info.value) is ValueError, f"{type(info.value).__name__}: {info.value}"
    assert re.search(name, str(info.value)), str(info.value)
