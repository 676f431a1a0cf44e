"""Bad input at every public boundary, part 2: the modules test_validation.py does not cover.

Issue 27, items 3 and 5. The same table-driven scheme as ``tests/test_validation.py``
(whose bad-value kinds, :func:`assert_names` and numpy phrases are imported, not copied):
each public function of core.angles, core.imu, core.linalg, core.observations,
filters.ekf, filters.nominal_ekf, filters.eskf_config, evaluation.consistency,
evaluation.drift, evaluation.spread, data.kitti, data.synthetic, data.mems_imu,
data.observation_errors and the Udacity log reader is listed once with good arguments
and the kind of each argument; every argument is then replaced, one at a time, by each
bad value of its kind. Each call must raise exactly ``ValueError`` naming the argument
(or the file and line or field). Then what the generic table cannot express: bad row
selections, configuration mappings with a wrong type at every key, and broken files
written in ``tmp_path`` (a missing file is the one ``FileNotFoundError``, as the
loaders document; it names the file too).
"""

from __future__ import annotations

import copy
import json
import math
import shutil
from types import SimpleNamespace

import numpy as np
import pytest
import yaml

from test_data_kitti import _rewrite
from test_validation import KINDS, NUMPY_PHRASES, assert_names, assert_refused, bad_matrices, bad_vectors

from kalman_course.chapters import lidar_radar
from kalman_course.core import angles, imu, linalg, observations
from kalman_course.core.imu import NavState
from kalman_course.core.observations import PoseObservations, PositionObservations
from kalman_course.data import kitti, mems_imu, observation_errors, synthetic
from kalman_course.data.observation_errors import GaussMarkovErrors, MapMatchingFailures, WhiteErrors
from kalman_course.evaluation import consistency, drift, spread
from kalman_course.filters import ekf, eskf_config, nominal_ekf

# ---------------------------------------------------------------------------------------
# good values shared by the specs
# ---------------------------------------------------------------------------------------

I2, I3 = np.eye(2), np.eye(3)
Z2, Z3 = np.zeros(2), np.zeros(3)
F2 = np.array([[1.0, 0.1], [0.0, 1.0]])
G12 = np.array([[1.0, 0.0]])
R1 = np.array([[0.5]])
GRAVITY = np.array([0.0, 0.0, -9.8092])
FORCE = np.array([0.1, 0.0, 9.8092])
RATE = np.array([0.0, 0.0, 0.1])
Q_UNIT = np.array([1.0, 0.0, 0.0, 0.0])
X16 = np.concatenate([Z3, [1.0, 0.0, 0.0], Q_UNIT, np.zeros(6)])
NAV = NavState(Z3, np.array([1.0, 0.0, 0.0]), I3)

SCENARIO = synthetic.imu_trajectory(0, duration=1.0)            # 101 IMU samples at 100 Hz
IMU = SimpleNamespace(t=SCENARIO.imu.t, specific_force=SCENARIO.imu.specific_force,
                      angular_rate=SCENARIO.imu.angular_rate)
LIDAR = PoseObservations(SCENARIO.t[10::20], SCENARIO.position[10::20], SCENARIO.rotation[10::20])

T6 = np.linspace(0.0, 0.5, 6)
P6 = np.column_stack([T6, np.zeros(6), np.zeros(6)])
R6 = np.tile(I3, (6, 1, 1))
POSE = PoseObservations(T6, P6, R6)

ROUTE = np.column_stack([np.arange(12.0), np.zeros(12), np.zeros(12)])   # 12 frames, 1 m apart
ROUTE_R = np.tile(I3, (12, 1, 1))

# a small excerpt-like record: 2 s of 100 Hz IMU times, 10 Hz truth moving along x
_T_TRUTH = np.arange(0.0, 2.01, 0.1)
TRUTH = SimpleNamespace(t=_T_TRUTH, position=np.column_stack([3.0 * _T_TRUTH, np.zeros((len(_T_TRUTH), 2))]),
                        rotation=np.tile(I3, (len(_T_TRUTH), 1, 1)))
EXCERPT = SimpleNamespace(imu=SimpleNamespace(t=np.arange(0.0, 2.001, 0.01)), truth=TRUTH, gravity=GRAVITY)
GNSS = SimpleNamespace(t=np.arange(5.0), position_true=np.zeros((5, 3)))

T_GM = np.linspace(0.0, 1.0, 5)
NORMALS = np.zeros((4, 3))
INNOVATIONS = np.random.default_rng(0).standard_normal((8, 2))
S_STACK = np.tile(I2, (8, 1, 1))


def _rows(K: int, tail: tuple = ()):
    return np.arange(1.0, K * int(np.prod(tail, dtype=int)) + 1).reshape(K, *tail)


# ---------------------------------------------------------------------------------------
# bad values of the kinds test_validation.py does not have. Entries: (label, value,
# dimension_error), as there.
# ---------------------------------------------------------------------------------------

def bad_rows(K: int, tail: tuple = ()):
    """A record of K samples, each of shape ``tail`` (times, positions, normals)."""
    good = _rows(K, tail)
    with_nan, with_inf = good.copy(), good.copy()
    with_nan.flat[-1], with_inf.flat[0] = np.nan, np.inf
    cases = [("wrong count", _rows(K + 1, tail), True), ("NaN", with_nan, False), ("inf", with_inf, False),
             ("string", "abc", False), ("None", None, False), ("complex", good + 1j, False),
             ("ragged", [[1.0], [1.0, 2.0]], False), ("3-D", good.reshape(1, *good.shape), False)]
    if tail:
        cases.append(("wrong tail", np.ones((K, tail[0] + 1)), False))
    return cases


def bad_times(K: int):
    """Strictly increasing times (K,)."""
    good = _rows(K)
    backwards, repeated = good[::-1].copy(), good.copy()
    repeated[1] = repeated[0]
    return bad_rows(K) + [("decreasing", backwards, False), ("repeated", repeated, False)]


def bad_rotation_stacks(K: int):
    good = np.tile(I3, (K, 1, 1))
    with_nan, scaled, reflected = good.copy(), good.copy(), good.copy()
    with_nan[-1, 0, 0] = np.nan
    scaled[0] *= 1.1
    reflected[-1] = np.diag([1.0, 1.0, -1.0])
    return [("wrong count", np.tile(I3, (K + 1, 1, 1)), True), ("(K, 9)", good.reshape(K, 9), False),
            ("one matrix", I3, False), ("NaN", with_nan, False), ("scaled", scaled, False),
            ("reflection", reflected, False), ("string", "abc", False), ("None", None, False),
            ("complex", good + 1j, False)]


def bad_covariance_stacks(N: int, m: int):
    good = np.tile(np.eye(m), (N, 1, 1))
    asym, indefinite, with_nan = good.copy(), good.copy(), good.copy()
    asym[2, 0, 1] = 0.5
    indefinite[3] = 2.0 * np.ones((m, m)) - np.eye(m)
    with_nan[1, 0, 0] = np.nan
    return [("wrong count", np.tile(np.eye(m), (N + 1, 1, 1)), True), ("one matrix", np.eye(m), False),
            ("non-square", np.ones((N, m, m + 1)), False), ("non-symmetric", asym, False),
            ("indefinite", indefinite, False), ("NaN", with_nan, False), ("string", "abc", False),
            ("None", None, False)]


def bad_nonnegative_scalars():
    return [("negative", -1.0, False), ("NaN", math.nan, False), ("inf", math.inf, False),
            ("string", "2", False), ("None", None, False), ("bool", True, False), ("list", [1.0, 2.0], False)]


def bad_reals():
    """Any finite real number (an initial state x0)."""
    return [("NaN", math.nan, False), ("inf", -math.inf, False), ("string", "abc", False),
            ("None", None, False), ("complex", 1 + 1j, False), ("list", [1.0, 2.0], False), ("bool", True, False)]


def bad_probabilities():
    return [("zero", 0.0, False), ("one", 1.0, False), ("above one", 1.5, False), ("NaN", math.nan, False),
            ("string", "0.9", False), ("None", None, False), ("bool", True, False)]


def bad_counts():
    """A positive integer (a number of steps, dof, a lag)."""
    return [("zero", 0, False), ("negative", -2, False), ("float", 2.5, False), ("whole float", 2.0, False),
            ("string", "3", False), ("bool", True, False), ("None", None, False)]


def bad_seeds():
    return [("negative", -1, False), ("float", 1.5, False), ("string", "1", False), ("None", None, False),
            ("bool", True, False)]


def bad_indices():
    """A slice bound: an integer, or None where the default is None."""
    return [("float", 1.5, False), ("string", "1", False), ("bool", True, False), ("list", [1], False)]


def bad_times_of_day():
    """An optional time in s (t_end)."""
    return [("NaN", math.nan, False), ("inf", math.inf, False), ("string", "1.0", False), ("bool", True, False),
            ("list", [1.0], False)]


def bad_callables():
    return [("None", None, False), ("number", 3, False), ("string", "f", False)]


def bad_names():
    return [("None", None, False), ("number", 3, False), ("empty", "", False)]


def bad_nav_states():
    return [("None", None, False), ("no fields", object(), False),
            ("no rotation", SimpleNamespace(position=Z3, velocity=Z3), False),
            ("position NaN", NavState(np.array([0.0, np.nan, 0.0]), Z3, I3), False),
            ("velocity (2,)", NavState(Z3, Z2, I3), False),
            ("rotation scaled", NavState(Z3, Z3, 2.0 * I3), False),
            ("rotation reflection", NavState(Z3, Z3, np.diag([1.0, 1.0, -1.0])), False),
            ("rotation string", NavState(Z3, Z3, "I"), False)]


def bad_imus(record):
    """An IMU record: t (N,), specific_force (N, 3), angular_rate (N, 3)."""
    t, f, w = record.t, record.specific_force, record.angular_rate
    t_nan, t_back, f_nan = t.copy(), t.copy(), f.copy()
    t_nan[5] = np.nan
    t_back[7] = t_back[6]
    f_nan[9, 1] = np.inf

    def imu_with(**change):
        return SimpleNamespace(**dict(dict(t=t, specific_force=f, angular_rate=w), **change))

    return [("None", None, False), ("no fields", object(), False),
            ("no angular_rate", SimpleNamespace(t=t, specific_force=f), False),
            ("t string", imu_with(t="abc"), False), ("t scalar", imu_with(t=1.0), False),
            ("t 2-D", imu_with(t=t[:, None]), False), ("t NaN", imu_with(t=t_nan), False),
            ("t not increasing", imu_with(t=t_back), False), ("force inf", imu_with(specific_force=f_nan), False),
            ("force (N, 2)", imu_with(specific_force=f[:, :2]), False),
            ("rate short", imu_with(angular_rate=w[:-3]), False), ("rate None", imu_with(angular_rate=None), False)]


def bad_lidar_records():
    half = SimpleNamespace(t=LIDAR.t, position=LIDAR.position)
    nan = LIDAR.position.copy()
    nan[1, 2] = np.nan
    late = PoseObservations(LIDAR.t + 100.0, LIDAR.position, LIDAR.rotation)
    return [("None", None, False), ("no fields", object(), False), ("no rotation", half, False),
            ("positions only", PositionObservations(LIDAR.t, LIDAR.position), False),
            ("NaN position", SimpleNamespace(t=LIDAR.t, position=nan, rotation=LIDAR.rotation), False),
            ("empty", PoseObservations([], np.zeros((0, 3)), np.zeros((0, 3, 3))), False),
            ("all after the IMU", late, False), ("string", "lidar", False)]


def bad_configs():
    return [("None", None, False), ("number", 3, False), ("list", ["kitti_lidar"], False),
            ("empty mapping", {}, False), ("mapping of junk", {"prior": 1}, False)]


def bad_truth_records():
    t, p, R = TRUTH.t, TRUTH.position, TRUTH.rotation
    K = len(t)
    back = t.copy()
    back[3] = back[2]
    R_bad = R.copy()
    R_bad[4] = 2.0 * I3

    def truth_with(**change):
        return SimpleNamespace(**dict(dict(t=t, position=p, rotation=R), **change))

    return [("None", None, False), ("no fields", object(), False),
            ("no attitude", SimpleNamespace(t=t, position=p), False), ("t string", truth_with(t="abc"), False),
            ("t not increasing", truth_with(t=back), False), ("t NaN", truth_with(t=np.full(K, np.nan)), False),
            ("position (K, 2)", truth_with(position=p[:, :2]), False),
            ("position short", truth_with(position=p[:-1]), False),
            ("position string", truth_with(position="abc"), False),
            ("rotation scaled", truth_with(rotation=R_bad), False),
            ("rotation (K, 9)", truth_with(rotation=R.reshape(K, 9)), False),
            ("quaternion (K, 3)", SimpleNamespace(t=t, position=p, quaternion=np.zeros((K, 3))), False)]


def bad_gnss_records():
    t, p = GNSS.t, GNSS.position_true
    return [("None", None, False), ("no fields", object(), False),
            ("t string", SimpleNamespace(t="abc", position_true=p), False),
            ("t 2-D", SimpleNamespace(t=t[:, None], position_true=p), False),
            ("position (M, 2)", SimpleNamespace(t=t, position_true=p[:, :2]), False),
            ("position NaN", SimpleNamespace(t=t, position_true=np.full((5, 3), np.nan)), False),
            ("position string", SimpleNamespace(t=t, position_true="abc"), False)]


def bad_excerpts():
    def excerpt_with(imu_t=EXCERPT.imu.t, gravity=GRAVITY, **truth_change):
        truth = SimpleNamespace(**dict(vars(TRUTH), **truth_change))
        return SimpleNamespace(imu=SimpleNamespace(t=imu_t), truth=truth, gravity=gravity)

    R_bad = TRUTH.rotation.copy()
    R_bad[2] = np.diag([1.0, 1.0, -1.0])
    return [("None", None, False), ("no fields", object(), False),
            ("imu.t string", excerpt_with(imu_t="abc"), False),
            ("imu.t outside", excerpt_with(imu_t=np.arange(10.0, 12.0, 0.01)), False),
            ("truth.t decreasing", excerpt_with(t=TRUTH.t[::-1].copy()), False),
            ("truth.position short", excerpt_with(position=TRUTH.position[:-1]), False),
            ("truth.rotation reflection", excerpt_with(rotation=R_bad), False),
            ("truth.rotation None", excerpt_with(rotation=None), False),
            ("gravity (2,)", excerpt_with(gravity=Z2), False)]


def bad_specs():
    return [("None", None, False), ("name", "consumer MEMS", False), ("mapping", {"name": "x"}, False)]


def bad_error_models():
    return [("number", 3, False), ("string", "white", False), ("class", WhiteErrors, False)]


def bad_generators():
    return [("None", None, False), ("seed", 0, False), ("legacy", np.random.RandomState(0), False)]


def bad_dims():
    return [("zero", 0, False), ("four", 4, False), ("whole float", 2.0, False), ("bool", True, False),
            ("string", "2", False), ("None", None, False)]


def bad_excerpt_names():
    return [("unknown", "highway", False), ("None", None, False), ("number", 3, False),
            ("list", ["turns"], False), ("path", "kalman_course/data/kitti/turns.npz", False)]


def bad_which():
    return [("out of range", [0, 6], False), ("negative out of range", [-7], False), ("float", [0.0, 1.0], False),
            ("float scalar", 1.5, False), ("bool mask too short", np.ones(4, dtype=bool), False),
            ("bool mask too long", np.ones(7, dtype=bool), False), ("string", "abc", False),
            ("list of strings", ["0", "1"], False), ("None", None, False), ("2-D", [[0, 1]], False),
            ("ragged", [[0], [0, 1]], False), ("reversed", [3, 1], False), ("repeated", [1, 1], False),
            ("slice backwards", slice(None, None, -1), False), ("slice of floats", slice(0.5, 3), False),
            ("slice step zero", slice(0, 3, 0), False), ("dict", {0: 1}, False), ("complex", [1j], False)]


LOCAL_KINDS = {
    "rows": bad_rows, "times": bad_times, "rotations": bad_rotation_stacks, "covs": bad_covariance_stacks,
    "nonneg": bad_nonnegative_scalars, "any_real": bad_reals, "prob": bad_probabilities, "count": bad_counts,
    "seed": bad_seeds, "index": bad_indices, "time": bad_times_of_day, "callable": bad_callables,
    "name": bad_names, "navstate": bad_nav_states, "imu": bad_imus, "lidar": bad_lidar_records,
    "config": bad_configs, "truth": bad_truth_records, "gnss": bad_gnss_records, "excerpt": bad_excerpts,
    "spec": bad_specs, "errors": bad_error_models, "rng": bad_generators, "dim": bad_dims,
    "excerpt_name": bad_excerpt_names, "which": bad_which,
}
ALL_KINDS = {**KINDS, **LOCAL_KINDS}
assert not set(KINDS) & set(LOCAL_KINDS)


# ---------------------------------------------------------------------------------------
# the public functions (and the constructors of the validated records)
# ---------------------------------------------------------------------------------------

def select(which):
    """PoseObservations.select on a 6-row record."""
    return POSE.select(which)


def white_draw(t, rng):
    """WhiteErrors.draw."""
    return WhiteErrors(0.2, 0.3).draw(t, rng)


def gauss_markov_draw(t, rng):
    """GaussMarkovErrors.draw."""
    return GaussMarkovErrors(0.2, 0.3, 1.0).draw(t, rng)


def failures_draw(t, rng):
    """MapMatchingFailures.draw."""
    return MapMatchingFailures(WhiteErrors(0.2, 0.3), 0.1, 1.0, 1.0, 1.0, 0.1, 5.0, 5.0).draw(t, rng)


def count_above(bar):
    """Spread.count_above."""
    return spread.spread([1.0, 2.0, 3.0]).count_above(bar)


def bias_at(times):
    """MemsImuData.bias_at."""
    return MEMS.bias_at(times)


def mems_spec(gyro_arw_deg_rth):
    """MemsSpec's constructor, one datasheet value."""
    return mems_imu.MemsSpec("test", gyro_arw_deg_rth, 20.0, 100.0, 360.0, 150.0, 0.1, 100.0, 5.0)


MEMS = mems_imu.simulate_mems_imu(EXCERPT, seed=0)
LOG = "<a valid Udacity log in tmp_path>"
GOOD_LOG_LINES = ["L 1.0 2.0 1477010443000000 1.1 2.1 5.0 0.5",
                  "R 2.2 0.4 1.0 1477010443050000 1.3 2.1 5.0 0.5",
                  "L 1.6 2.2 1477010443100000 1.6 2.2 5.0 0.5"]

G_OF = (lambda x: G12 @ x)
F_OF = (lambda x: F2 @ x)

# (function, good keyword arguments, {argument: (kind, kind parameters)}, sized_by)
SPECS = [
    # core.angles
    (angles.wrap_angle, dict(angle=0.5), {"angle": ("real", ())}, {}),
    # core.imu
    (imu.midpoint_step, dict(state=NAV, f0=FORCE, w0=RATE, f1=FORCE, w1=RATE, dt=0.01, gravity=GRAVITY,
                             accel_bias=Z3, gyro_bias=Z3),
     {"state": ("navstate", ()), "f0": ("vector", (3,)), "w0": ("vector", (3,)), "f1": ("vector", (3,)),
      "w1": ("vector", (3,)), "dt": ("scalar", ()), "gravity": ("vector", (3,)),
      "accel_bias": ("vector", (3,)), "gyro_bias": ("vector", (3,))}, {}),
    (imu.dead_reckon, dict(imu=IMU, initial_state=NAV, gravity=GRAVITY, accel_bias=Z3, gyro_bias=Z3, start=0,
                           stop=None),
     {"imu": ("imu", (IMU,)), "initial_state": ("navstate", ()), "gravity": ("vector", (3,)),
      "accel_bias": ("vector", (3,)), "gyro_bias": ("vector", (3,)), "start": ("index", ()),
      "stop": ("index", ())}, {}),
    # core.linalg
    (linalg.expm, dict(A=F2), {"A": ("matrix", (2, 2))}, {}),
    # core.observations
    (PositionObservations, dict(t=T6, position=P6), {"t": ("times", (6,)), "position": ("rows", (6, (3,)))},
     {"t": "position", "position": "t"}),
    (PoseObservations, dict(t=T6, position=P6, rotation=R6),
     {"t": ("times", (6,)), "position": ("rows", (6, (3,))), "rotation": ("rotations", (6,))},
     {"t": "position", "position": "t", "rotation": "t"}),
    (select, dict(which=[0, 2]), {"which": ("which", ())}, {}),
    # filters.ekf
    (ekf.ekf_predict, dict(x_hat=Z2, P_hat=I2, f=F_OF, F=F2, Q=0.1 * I2, B=None),
     {"x_hat": ("vector", (2,)), "P_hat": ("psd", (2,)), "f": ("callable", ()), "F": ("matrix", (2, 2)),
      "Q": ("psd", (2,)), "B": ("matrix", (2, 2))}, {"x_hat": "P_hat", "B": "Q"}),
    (ekf.ekf_update, dict(x_check=Z2, P_check=I2, y=np.zeros(1), g=G_OF, G=G12, R=R1, C=None, residual=None,
                          joseph=True),
     {"x_check": ("vector", (2,)), "P_check": ("psd", (2,)), "y": ("vector", (1,)), "g": ("callable", ()),
      "G": ("matrix", (1, 2)), "R": ("pd", (1,)), "C": ("matrix", (1, 1)), "residual": ("callable", ()),
      "joseph": ("flag", ())}, {"x_check": "P_check", "y": "R", "C": "R"}),
    (ekf.iekf_update, dict(x_check=Z2, P_check=I2, y=np.zeros(1), g=G_OF, G=lambda x: G12, R=R1, C=None,
                           residual=None, tol=1e-9, max_iter=5, joseph=True),
     {"x_check": ("vector", (2,)), "P_check": ("psd", (2,)), "y": ("vector", (1,)), "g": ("callable", ()),
      "G": ("callable", ()), "R": ("pd", (1,)), "residual": ("callable", ()), "tol": ("nonneg", ()),
      "max_iter": ("count", ()), "joseph": ("flag", ())}, {"x_check": "P_check", "y": "R"}),
    (ekf.radar_residual, dict(y=[1.0, 0.1, 0.2], y_pred=[1.0, 0.0, 0.0]),
     {"y": ("vector", (3,)), "y_pred": ("vector", (3,))}, {}),
    (ekf.lidar_observation, dict(x=np.zeros(5)), {"x": ("vector", (5,))}, {}),
    (ekf.lidar_jacobian, dict(x=np.zeros(5)), {"x": ("vector", (5,))}, {}),
    # filters.nominal_ekf
    (nominal_ekf.rotate_jacobian, dict(q=Q_UNIT, a=FORCE), {"q": ("vector", (4,)), "a": ("vector", (3,))}, {}),
    (nominal_ekf.quat_xi, dict(q=Q_UNIT), {"q": ("vector", (4,))}, {}),
    (nominal_ekf.quat_omega, dict(v=RATE), {"v": ("vector", (3,))}, {}),
    (nominal_ekf.continuous_jacobian, dict(q=Q_UNIT, f=FORCE, w=RATE, b_a=Z3, b_w=Z3),
     {"q": ("vector", (4,)), "f": ("vector", (3,)), "w": ("vector", (3,)), "b_a": ("vector", (3,)),
      "b_w": ("vector", (3,))}, {}),
    (nominal_ekf.nominal_noise_jacobian, dict(q=Q_UNIT), {"q": ("vector", (4,))}, {}),
    (nominal_ekf.propagate, dict(x=X16, f0=FORCE, w0=RATE, f1=FORCE, w1=RATE, dt=0.01, g=GRAVITY),
     {"x": ("vector", (16,)), "f0": ("vector", (3,)), "w0": ("vector", (3,)), "f1": ("vector", (3,)),
      "w1": ("vector", (3,)), "dt": ("scalar", ()), "g": ("vector", (3,))}, {}),
    (nominal_ekf.run_nominal_ekf, dict(imu=IMU, initial=SCENARIO.state(0), config="kitti_lidar", gravity=GRAVITY,
                                       lidar=LIDAR, start=0, t_end=None, jacobian=None, covariance_update=None),
     {"imu": ("imu", (IMU,)), "initial": ("navstate", ()), "config": ("config", ()),
      "gravity": ("vector", (3,)), "lidar": ("lidar", ()), "start": ("int", ((0, 100),)),
      "t_end": ("time", ()), "jacobian": ("callable", ()), "covariance_update": ("callable", ())}, {}),
    # filters.eskf_config (the files: FILE_CASES below)
    (eskf_config.config_from_dict, dict(data=yaml.safe_load((eskf_config.config_dir() / "kitti_lidar.yaml")
                                                            .read_text(encoding="utf-8")), name="dict"),
     {"data": ("config", ()), "name": ("name", ())}, {}),
    # evaluation.consistency
    (consistency.summarise, dict(values=[1.0, 2.0, 3.0], dof=2, n_runs=1, confidence=0.95),
     {"values": ("real", ()), "dof": ("count", ()), "n_runs": ("count", ()), "confidence": ("prob", ())}, {}),
    (consistency.verdict, dict(values=[1.0, 2.0, 3.0], dof=2, confidence=0.95),
     {"values": ("real", ()), "dof": ("count", ()), "confidence": ("prob", ())}, {}),
    (consistency.gate_threshold, dict(dof=2, confidence=0.99), {"dof": ("count", ()), "confidence": ("prob", ())},
     {}),
    (consistency.gate, dict(innovation=[0.1, 0.2], S=I2, confidence=0.99),
     {"innovation": ("vector", (2,)), "S": ("pd", (2,)), "confidence": ("prob", ())}, {"innovation": "S"}),
    (consistency.correlation_time, dict(values=[1.0, 2.0, 1.5, 0.5]), {"values": ("real", ())}, {}),
    (consistency.average_band, dict(values=[1.0, 2.0, 1.5, 0.5], dof=1, confidence=0.95),
     {"values": ("real", ()), "dof": ("count", ()), "confidence": ("prob", ())}, {}),
    (consistency.innovation_whiteness, dict(innovation=INNOVATIONS, S=S_STACK, max_lag=2, confidence=0.95),
     {"innovation": ("rows", (8, (2,))), "S": ("covs", (8, 2)), "max_lag": ("count", ()),
      "confidence": ("prob", ())}, {"innovation": "S", "S": "innovation"}),
    # evaluation.drift
    (drift.path_distance, dict(position=ROUTE), {"position": ("matrix", (12, 3))}, {}),
    (drift.segments, dict(distance=np.arange(12.0), lengths=[2.0, 4.0], step=2),
     {"distance": ("vector", (12,)), "lengths": ("vector", (2,)), "step": ("count", ())}, {}),
    (drift.drift, dict(position=ROUTE, rotation=ROUTE_R, true_position=ROUTE, true_rotation=ROUTE_R,
                       lengths=[2.0, 4.0], step=2),
     {"position": ("matrix", (12, 3)), "rotation": ("rotations", (12,)), "true_position": ("matrix", (12, 3)),
      "true_rotation": ("rotations", (12,)), "lengths": ("vector", (2,)), "step": ("count", ())},
     {"true_position": "position", "rotation": "position", "true_rotation": "position"}),
    # evaluation.spread
    (spread.spread, dict(values=[1.0, 2.0, 3.0], name="values"), {"values": ("vector", (3,)), "name": ("name", ())},
     {}),
    (count_above, dict(bar=1.5), {"bar": ("any_real", ())}, {}),
    # data.kitti (the files: FILE_CASES below)
    (kitti.load_kitti, dict(name="cruise"), {"name": ("excerpt_name", ())}, {}),
    (kitti.simulate_lidar_poses, dict(truth=TRUTH, seed=1, sigma_position=0.2, sigma_attitude_deg=0.3, errors=None),
     {"truth": ("truth", ()), "seed": ("seed", ()), "sigma_position": ("nonneg", ()),
      "sigma_attitude_deg": ("nonneg", ()), "errors": ("errors", ())}, {}),
    (kitti.simulate_gnss, dict(gnss=GNSS, seed=1, sigma=1.0),
     {"gnss": ("gnss", ()), "seed": ("seed", ()), "sigma": ("nonneg", ())}, {}),
    # data.synthetic
    (synthetic.random_walk_1d, dict(n_steps=5, q=0.1, r=0.2, seed=0, x0=0.0),
     {"n_steps": ("count", ()), "q": ("nonneg", ()), "r": ("nonneg", ()), "seed": ("seed", ()),
      "x0": ("any_real", ())}, {}),
    (synthetic.cv_target, dict(n_steps=5, dt=0.1, sigma_a=1.0, sigma_meas=0.5, seed=0, dim=2, x0=None),
     {"n_steps": ("count", ()), "dt": ("scalar", ()), "sigma_a": ("nonneg", ()), "sigma_meas": ("nonneg", ()),
      "seed": ("seed", ()), "dim": ("dim", ()), "x0": ("vector", (4,))}, {}),
    (synthetic.imu_trajectory, dict(seed=0, duration=0.5, rate=20.0),
     {"seed": ("seed", ()), "duration": ("scalar", ()), "rate": ("scalar", ()),
      "accel_noise_density": ("nonneg", ()), "gyro_noise_density": ("nonneg", ()),
      "accel_bias_density": ("nonneg", ()), "gyro_bias_density": ("nonneg", ()),
      "accel_bias0": ("vector", (3,)), "gyro_bias0": ("vector", (3,)), "gravity": ("vector", (3,))}, {}),
    # data.mems_imu
    (mems_imu.reference_imu, dict(excerpt=EXCERPT, knot_spacing=0.3),
     {"excerpt": ("excerpt", ()), "knot_spacing": ("scalar", ())}, {}),
    (mems_imu.gauss_markov_drift, dict(t=T_GM, sigma=0.1, time_constant=10.0, normals=NORMALS),
     {"t": ("times", (5,)), "sigma": ("scalar", ()), "time_constant": ("scalar", ()),
      "normals": ("rows", (4, (3,)))}, {"t": "normals", "normals": "t"}),
    (mems_imu.simulate_mems_imu, dict(source=EXCERPT, spec=mems_imu.CONSUMER_MEMS, seed=0, knot_spacing=0.3),
     {"source": ("excerpt", ()), "spec": ("spec", ()), "seed": ("seed", ()), "knot_spacing": ("scalar", ())}, {}),
    (mems_spec, dict(gyro_arw_deg_rth=0.3), {"gyro_arw_deg_rth": ("scalar", ())}, {}),
    (bias_at, dict(times=[0.5, 1.0]), {"times": ("real", ())}, {}),
    # data.observation_errors
    (WhiteErrors, dict(sigma_position=0.2, sigma_attitude_deg=0.3),
     {"sigma_position": ("nonneg", ()), "sigma_attitude_deg": ("nonneg", ())}, {}),
    (GaussMarkovErrors, dict(sigma_position=0.2, sigma_attitude_deg=0.3, time_constant=1.0),
     {"sigma_position": ("nonneg", ()), "sigma_attitude_deg": ("nonneg", ()), "time_constant": ("scalar", ())}, {}),
    (MapMatchingFailures, dict(base=WhiteErrors(0.2, 0.3), jump_rate=0.1, jump_position=1.0, jump_duration=1.0,
                               outlier_rate=0.1, outlier_position=5.0),
     {"base": ("errors", ()), "jump_rate": ("nonneg", ()), "jump_position": ("nonneg", ()),
      "jump_attitude_deg": ("nonneg", ()), "jump_duration": ("nonneg", ()), "outlier_rate": ("nonneg", ()),
      "outlier_position": ("nonneg", ()), "outlier_attitude_deg": ("nonneg", ())}, {}),
    (white_draw, dict(t=T6, rng=np.random.default_rng(0)), {"t": ("times", (6,)), "rng": ("rng", ())}, {}),
    (gauss_markov_draw, dict(t=T6, rng=np.random.default_rng(0)), {"t": ("times", (6,)), "rng": ("rng", ())}, {}),
    (failures_draw, dict(t=T6, rng=np.random.default_rng(0)), {"t": ("times", (6,)), "rng": ("rng", ())}, {}),
    # the Udacity log reader (the files: FILE_CASES below)
    (lidar_radar.read_udacity_log, dict(path=LOG, R_lidar=0.0225 * I2, R_radar=np.diag([0.09, 9e-4, 0.09]),
                                        sigma_a=3.0, sigma_yaw_acc=0.3),
     {"R_lidar": ("pd", (2,)), "R_radar": ("pd", (3,)), "sigma_a": ("nonneg", ()),
      "sigma_yaw_acc": ("nonneg", ())}, {}),
]

# Bad values that are right for some arguments.
ALLOWED = {
    ("wrap_angle", "angle", "empty"),                      # an empty array wraps to an empty array
    ("midpoint_step", "accel_bias", "None"), ("midpoint_step", "gyro_bias", "None"),     # None: no bias
    ("dead_reckon", "accel_bias", "None"), ("dead_reckon", "gyro_bias", "None"),
    ("ekf_predict", "B", "None"), ("ekf_update", "C", "None"), ("ekf_update", "residual", "None"),
    ("iekf_update", "residual", "None"), ("iekf_update", "tol", "inf"),     # tol = inf: stop after one step
    ("run_nominal_ekf", "jacobian", "None"), ("run_nominal_ekf", "covariance_update", "None"),
    ("cv_target", "x0", "None"), ("simulate_lidar_poses", "errors", "None"),
    # any number of rows or values where the argument itself fixes it
    ("PositionObservations", "t", "wrong count"), ("PoseObservations", "t", "wrong count"),
    ("path_distance", "position", "wrong rows"), ("drift", "position", "wrong rows"),
    ("segments", "distance", "wrong length"), ("segments", "lengths", "wrong length"),
    ("drift", "lengths", "wrong length"), ("spread", "values", "wrong length"),
    ("innovation_whiteness", "innovation", "wrong count"), ("gauss_markov_draw", "t", "wrong count"),
    ("white_draw", "t", "wrong count"), ("failures_draw", "t", "wrong count"),
    ("gauss_markov_drift", "normals", "wrong tail"),        # m, the number of drifting columns, is free
    ("gauss_markov_drift", "t", "wrong count"),
    ("bias_at", "times", "empty"),                          # no times, no biases
}


# Names a message may use instead of the argument's: the configuration names itself
# (``config dict: missing prior.position``).
ALSO = {("config_from_dict", "data"): {"config"}}


def _cases():
    for fn, good, kinds, sized_by in SPECS:
        for arg, (kind, params) in kinds.items():
            for label, bad, size_only in ALL_KINDS[kind](*params):
                if (fn.__name__, arg, label) in ALLOWED:
                    continue
                expected = {arg, sized_by.get(arg, arg)} if size_only else {arg}
                expected |= ALSO.get((fn.__name__, arg), set())
                yield pytest.param(fn, good, arg, bad, expected, id=f"{fn.__name__}-{arg}-{label}")


CASES = list(_cases())


def _write_log(tmp_path, lines, name="log.txt"):
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def _resolve(kwargs: dict, tmp_path) -> dict:
    """The placeholder of a file argument replaced by a valid file written in tmp_path."""
    return {k: (_write_log(tmp_path, GOOD_LOG_LINES) if isinstance(v, str) and v == LOG else v)
            for k, v in kwargs.items()}


@pytest.mark.parametrize("fn, good, arg, bad, names", CASES)
def test_bad_argument_is_a_value_error_naming_it(fn, good, arg, bad, names, tmp_path):
    assert_refused(fn, _resolve(dict(good, **{arg: bad}), tmp_path), names)


@pytest.mark.parametrize("fn, good", [(fn, good) for fn, good, *_ in SPECS],
                         ids=[fn.__name__ for fn, *_ in SPECS])
def test_the_good_arguments_are_good(fn, good, tmp_path):
    with np.errstate(all="raise"):
        fn(**_resolve(good, tmp_path))


# ---------------------------------------------------------------------------------------
# select: what the rows are (the generic table tried the bad ones)
# ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("which, rows", [([-1], [5]), ([0, -1], [0, 5]), ([], []), (np.array([], dtype=int), []),
                                         (np.int64(2) * np.ones(1, dtype=int), [2]), (slice(4, 100), [4, 5])])
def test_select_accepts_negative_indices_and_empty_selections(which, rows):
    out = POSE.select(which)
    np.testing.assert_array_equal(out.t, T6[rows])
    assert type(out) is PoseObservations


def test_select_messages_name_which_and_the_rule():
    with pytest.raises(ValueError, match=r"^which must hold row indices in \[-6, 6\), got 6"):
        POSE.select([0, 6])
    with pytest.raises(ValueError, match=r"^which must be a slice, a boolean mask of shape \(6,\) or integer row "
                                         r"indices, got .*float64"):
        POSE.select([0.0, 1.0])
    with pytest.raises(ValueError, match=r"^which must pick rows in increasing order \(t must be strictly "
                                         r"increasing\): row 1 after row 3"):
        POSE.select([3, 1])


# ---------------------------------------------------------------------------------------
# cases the generic table cannot express
# ---------------------------------------------------------------------------------------

SPECIAL = [
    # core.angles: an angle of inf has no direction (NaN stays NaN: a missing value)
    (lambda: angles.wrap_angle(np.inf), {"angle"}),
    (lambda: angles.wrap_angle([0.0, -np.inf]), {"angle"}),
    # core.imu: a stop past the end, a start at the end
    (lambda: imu.dead_reckon(IMU, NAV, GRAVITY, start=101), {"start"}),
    (lambda: imu.dead_reckon(IMU, NAV, GRAVITY, start=50, stop=10), {"start", "stop"}),
    # filters.ekf: what the callables return
    (lambda: ekf.ekf_predict(Z2, I2, F_OF, lambda x: np.ones(3), 0.1 * I2), {"F(x_hat)"}),
    (lambda: ekf.ekf_predict(Z2, I2, lambda x: "x", F2, 0.1 * I2), {"f(x_hat)"}),
    (lambda: ekf.ekf_update(Z2, I2, [0.0], lambda x: [1.0, 2.0], G12, R1), {"g(x_check)"}),
    (lambda: ekf.ekf_update(Z2, I2, [0.0], G_OF, G12, R1, residual=lambda y, p: None),
     {"residual(y, g(x_check))"}),
    (lambda: ekf.iekf_update(Z2, I2, [0.0], G_OF, G12, R1), {"G"}),
    (lambda: ekf.iekf_update(Z2, I2, [0.0], G_OF, lambda x: np.ones((2, 2)), R1), {"G(x_op)"}),
    # filters.nominal_ekf: a zero quaternion; the learner's callables return the wrong thing
    (lambda: nominal_ekf.rotate_jacobian(np.zeros(4), FORCE), {"q"}),
    (lambda: nominal_ekf.propagate(np.zeros(16), FORCE, RATE, FORCE, RATE, 0.01, GRAVITY), {"x[6:10]"}),
    (lambda: nominal_ekf.run_nominal_ekf(IMU, SCENARIO.state(0), gravity=-GRAVITY, lidar=LIDAR), {"gravity"}),
    (lambda: nominal_ekf.run_nominal_ekf(IMU, SCENARIO.state(0), lidar=LIDAR, t_end=0.05), {"lidar", "t_end"}),
    (lambda: nominal_ekf.run_nominal_ekf(IMU, SCENARIO.state(0), lidar=LIDAR, jacobian=lambda *a: np.eye(15)),
     {"jacobian"}),
    (lambda: nominal_ekf.run_nominal_ekf(IMU, SCENARIO.state(0), lidar=LIDAR,
                                         covariance_update=lambda P, K, G, R: None), {"covariance_update"}),
    (lambda: nominal_ekf.run_nominal_ekf(IMU, SCENARIO.state(0), LIDAR), {"config", "lidar"}),
    (lambda: nominal_ekf.run_nominal_ekf(IMU, SCENARIO.state(0)), {"lidar"}),
    # evaluation.consistency: inf values; S not positive definite at one step; too large a lag
    (lambda: consistency.summarise([1.0, np.inf], 2), {"values"}),
    (lambda: consistency.summarise([np.nan, np.nan], 2), {"values"}),
    (lambda: consistency.correlation_time(np.ones((2, 2, 2))), {"values"}),
    (lambda: consistency.innovation_whiteness(INNOVATIONS, S_STACK, max_lag=8), {"max_lag"}),
    (lambda: consistency.innovation_whiteness(INNOVATIONS, S_STACK * np.r_[1.0, 1, 1, 0, 1, 1, 1, 1][:, None, None],
                                              max_lag=2), {"S"}),
    (lambda: consistency.innovation_whiteness(np.ones((8, 2)), S_STACK, max_lag=2), {"innovation"}),
    # evaluation.drift: distance going backwards, negative lengths
    (lambda: drift.segments([0.0, 2.0, 1.0]), {"distance"}),
    (lambda: drift.segments(np.arange(5.0), [-1.0]), {"lengths"}),
    # data.kitti: contradicting σ's; a record with fields of another length
    (lambda: kitti.simulate_lidar_poses(TRUTH, 1, 0.5, errors=WhiteErrors(0.2, 0.3)), {"sigma_position"}),
    # data.synthetic: too many samples for a float
    (lambda: synthetic.imu_trajectory(0, duration=1e300, rate=1e300), {"duration", "rate"}),
    # data.mems_imu: too small a knot spacing; times outside the record
    (lambda: mems_imu.reference_imu(EXCERPT, knot_spacing=0.1), {"knot_spacing"}),
    (lambda: MEMS.bias_at([100.0]), {"times"}),
    (lambda: MEMS.bias_at([[0.5]]), {"times"}),
    (lambda: mems_imu.MemsSpec("", 1, 1, 1, 1, 1, 1, 1, 1), {"name"}),
    (lambda: mems_imu.MemsSpec(None, 1, 1, 1, 1, 1, 1, 1, 1), {"name"}),
    # data.observation_errors: failures that change nothing; a base that is no base
    (lambda: MapMatchingFailures(WhiteErrors(0.2, 0.3), outlier_rate=1.5, outlier_position=1.0), {"outlier_rate"}),
    (lambda: MapMatchingFailures(WhiteErrors(0.2, 0.3), jump_rate=0.1, jump_position=1.0), {"jump_duration"}),
    (lambda: MapMatchingFailures(MapMatchingFailures(WhiteErrors(0.2, 0.3))), {"base"}),
]


@pytest.mark.parametrize("call, names", SPECIAL, ids=[f"special-{i}" for i in range(len(SPECIAL))])
def test_special_bad_input_is_a_value_error_naming_it(call, names):
    with np.errstate(all="raise"):
        with pytest.raises(Exception) as info:
            call()
    assert_names(info.value, names)


# ---------------------------------------------------------------------------------------
# ESKF configuration mappings: a wrong type at every key
# ---------------------------------------------------------------------------------------

RAW_CONFIG = yaml.safe_load((eskf_config.config_dir() / "kitti_lidar.yaml").read_text(encoding="utf-8"))
WRONG_TYPES = [("None", None), ("list", [1.0]), ("mapping", {"a": 1}), ("bool", True), ("text", "abc"),
               ("NaN", math.nan), ("negative", -1.0)]


def _config_cases():
    top = {"bias_model": WRONG_TYPES[:5] + [("unknown", "gauss_markov"), ("number", 1)],
           "exact_reset": WRONG_TYPES[:3] + [("text", "true"), ("number", 1)],
           "imu_rate_hz": WRONG_TYPES}
    for key, values in top.items():
        for label, value in values:
            yield pytest.param((key,), value, {key}, id=f"{key}-{label}")
    for section, entries in eskf_config.SECTIONS.items():
        yield pytest.param((section,), [1, 2], {section}, id=f"{section}-list")
        for entry in entries:
            key = f"{section}.{entry}"
            if entry not in RAW_CONFIG.get(section, {}):
                continue
            yield pytest.param((section, entry), [1.0], {key}, id=f"{key}-list")
            for label, value in WRONG_TYPES:
                yield pytest.param((section, entry, "value"), value, {key}, id=f"{key}.value-{label}")
            for field in ("unit", "kind", "meaning"):
                for label, value in [("None", None), ("list", ["m"]), ("mapping", {"m": 1}), ("number", 1.0),
                                     ("bool", False)]:
                    yield pytest.param((section, entry, field), value, {key}, id=f"{key}.{field}-{label}")
    # keys of another type than a string, at the top and inside a section
    yield pytest.param((1,), 2, {"1"}, id="top-int-key")
    yield pytest.param(("process", 7), {"value": 1}, {"process.7"}, id="process-int-key")


CONFIG_CASES = list(_config_cases())


@pytest.mark.parametrize("where, value, names", CONFIG_CASES)
def test_a_wrong_type_at_each_configuration_key_is_named(where, value, names):
    data = copy.deepcopy(RAW_CONFIG)
    target = data
    for key in where[:-1]:
        target = target[key]
    target[where[-1]] = value
    with pytest.raises(Exception) as info:
        eskf_config.config_from_dict(data, name="test")
    assert_names(info.value, names)


# ---------------------------------------------------------------------------------------
# files: the loaders on broken files written in tmp_path (never the shipped data)
# ---------------------------------------------------------------------------------------

def _excerpt_copy(tmp_path):
    src = kitti.kitti_dir()
    shutil.copy(src / "cruise.npz", tmp_path / "cruise.npz")
    shutil.copy(src / "MANIFEST.json", tmp_path / "MANIFEST.json")
    return tmp_path / "cruise.npz"


def _meta_change(**changes):
    def change(arrays):
        meta = json.loads(str(arrays["meta"]))
        for dotted, value in changes.items():
            target = meta
            *parents, last = dotted.split("__")
            for p in parents:
                target = target[p]
            if value is _DELETE:
                del target[last]
            else:
                target[last] = value
        arrays["meta"] = np.array(json.dumps(meta))
    return change


_DELETE = object()


def _excerpt_with(change):
    def build(tmp_path):
        path = _excerpt_copy(tmp_path)
        _rewrite(path, change)
        return lambda: kitti.load_excerpt_file(path)
    return build


def _bytes_file(name, data: bytes):
    def write(tmp_path):
        path = tmp_path / name
        path.write_bytes(data)
        return path
    return write


def _manifest_case(text_or_obj, parsed=False):
    def build(tmp_path):
        path = _excerpt_copy(tmp_path)
        if parsed:
            return lambda: kitti.load_excerpt_file(path, manifest=text_or_obj)
        (tmp_path / "MANIFEST.json").write_text(text_or_obj if isinstance(text_or_obj, str)
                                                else json.dumps(text_or_obj), encoding="utf-8")
        return lambda: kitti.load_excerpt_file(path, manifest=tmp_path / "MANIFEST.json")
    return build


def _good_manifest():
    return json.loads((kitti.kitti_dir() / "MANIFEST.json").read_text(encoding="utf-8"))


def _manifest_entry(**change):
    manifest = _good_manifest()
    manifest["files"]["cruise.npz"].update(change)
    return manifest


def _npy_file(tmp_path):
    path = tmp_path / "array.npz"
    with open(path, "wb") as fh:
        np.save(fh, np.zeros(3))
    return lambda: kitti.load_excerpt_file(path)


def _log_case(lines=None, data=None, name="log.txt"):
    def build(tmp_path):
        path = tmp_path / name
        if data is not None:
            path.write_bytes(data)
        elif lines is not None:
            path.write_text("\n".join(lines) + "\n", encoding="utf-8")
        return lambda: lidar_radar.read_udacity_log(path)
    return build


def _config_file(text=None, data=None, name="bad.yaml"):
    def build(tmp_path):
        path = tmp_path / name
        if data is not None:
            path.write_bytes(data)
        elif text is not None:
            path.write_text(text, encoding="utf-8")
        return lambda: eskf_config.load_config(path)
    return build


GOOD_L = GOOD_LOG_LINES[0]
NOT_FOUND = FileNotFoundError

# (id, build(tmp_path) -> call, names, expected exception type)
FILE_CASES = [
    # data.kitti.load_excerpt_file
    ("excerpt-missing", lambda p: (lambda: kitti.load_excerpt_file(p / "nothere.npz")), {"nothere.npz"}, NOT_FOUND),
    ("excerpt-directory", lambda p: (lambda: kitti.load_excerpt_file(p)), {"directory"}, ValueError),
    ("excerpt-empty", lambda p: (lambda: kitti.load_excerpt_file(_bytes_file("e.npz", b"")(p))), {"e.npz"},
     ValueError),
    ("excerpt-text", lambda p: (lambda: kitti.load_excerpt_file(_bytes_file("t.npz", b"hello")(p))), {"t.npz"},
     ValueError),
    ("excerpt-npy", _npy_file, {"array.npz"}, ValueError),
    ("excerpt-truncated", lambda p: (lambda: kitti.load_excerpt_file(
        _bytes_file("cut.npz", (kitti.kitti_dir() / "cruise.npz").read_bytes()[:5000])(p))), {"cut.npz"}, ValueError),
    ("excerpt-missing-key", _excerpt_with(lambda a: a.pop("imu/angular_rate")), {"cruise.npz"}, ValueError),
    ("excerpt-wrong-shape", _excerpt_with(lambda a: a.update({"gravity": np.zeros(2)})), {"cruise.npz"}, ValueError),
    ("excerpt-wrong-dtype", _excerpt_with(lambda a: a.update({"imu/interpolated": a["imu/t"]})), {"cruise.npz"},
     ValueError),
    ("excerpt-meta-not-text", _excerpt_with(lambda a: a.update({"meta": np.zeros(3)})), {"cruise.npz"}, ValueError),
    ("excerpt-meta-list", _excerpt_with(lambda a: a.update({"meta": np.array("[1, 2]")})), {"cruise.npz"},
     ValueError),
    ("excerpt-meta-no-gnss-seed", _excerpt_with(_meta_change(gnss__seed=_DELETE)), {"cruise.npz"}, ValueError),
    ("excerpt-meta-seed-text", _excerpt_with(_meta_change(lidar__seed="abc")), {"cruise.npz"}, ValueError),
    ("excerpt-meta-seed-negative", _excerpt_with(_meta_change(lidar__seed=-1)), {"cruise.npz"}, ValueError),
    ("excerpt-meta-gnss-not-object", _excerpt_with(_meta_change(gnss=3)), {"cruise.npz"}, ValueError),
    ("excerpt-meta-tau-range-number", _excerpt_with(_meta_change(tau_range=3)), {"cruise.npz"}, ValueError),
    ("excerpt-meta-tau-range-short", _excerpt_with(_meta_change(tau_range=[1.0])), {"cruise.npz"}, ValueError),
    ("excerpt-meta-tau-range-text", _excerpt_with(_meta_change(tau_range=["a", "b"])), {"cruise.npz"}, ValueError),
    ("excerpt-meta-name-number", _excerpt_with(_meta_change(name=3)), {"cruise.npz"}, ValueError),
    ("excerpt-meta-schema-text", _excerpt_with(_meta_change(schema_version="1")), {"cruise.npz"}, ValueError),
    ("excerpt-meta-provenance-list", _excerpt_with(_meta_change(provenance=[1])), {"cruise.npz"}, ValueError),
    ("excerpt-quaternion-zero", _excerpt_with(lambda a: a.update({"lidar/quaternion": np.zeros_like(
        a["lidar/quaternion"])})), {"cruise.npz"}, ValueError),
    ("excerpt-frames-not-rotation", _excerpt_with(lambda a: a.update({"frames/R_cam_imu": 2.0 * np.eye(3)})),
     {"cruise.npz"}, ValueError),
    ("excerpt-path-none", lambda p: (lambda: kitti.load_excerpt_file(None)), {"path"}, ValueError),
    ("excerpt-path-number", lambda p: (lambda: kitti.load_excerpt_file(3)), {"path"}, ValueError),
    # ... and its manifest
    ("manifest-missing", lambda p: (lambda: kitti.load_excerpt_file(_excerpt_copy(p), manifest=p / "nope.json")),
     {"nope.json"}, NOT_FOUND),
    ("manifest-list", _manifest_case("[1, 2]"), {"MANIFEST.json"}, ValueError),
    ("manifest-no-files", _manifest_case({"schema_version": 1}), {"MANIFEST.json"}, ValueError),
    ("manifest-size-text", _manifest_case(_manifest_entry(size="big")), {"MANIFEST.json"}, ValueError),
    ("manifest-sha-number", _manifest_case(_manifest_entry(sha256=3)), {"MANIFEST.json"}, ValueError),
    ("manifest-schema-text", _manifest_case(_manifest_entry(schema_version="1")), {"MANIFEST.json"}, ValueError),
    ("manifest-not-utf8", lambda p: (lambda: kitti.load_excerpt_file(
        _excerpt_copy(p), manifest=_bytes_file("m.json", b"\xff\xfe{")(p))), {"m.json"}, ValueError),
    ("manifest-parsed-no-files", _manifest_case({"schema": 1}, parsed=True), {"manifest"}, ValueError),
    ("manifest-parsed-entry-text", _manifest_case({"files": {"cruise.npz": "x"}}, parsed=True), {"manifest"},
     ValueError),
    ("manifest-number", _manifest_case(3, parsed=True), {"manifest"}, ValueError),
    ("manifest-directory", lambda p: (lambda: kitti.read_manifest(p)), {"directory"}, ValueError),
    # data.kitti.file_sha256
    ("sha256-missing", lambda p: (lambda: kitti.file_sha256(p / "none.bin")), {"none.bin"}, NOT_FOUND),
    ("sha256-directory", lambda p: (lambda: kitti.file_sha256(p)), {"directory"}, ValueError),
    ("sha256-none", lambda p: (lambda: kitti.file_sha256(None)), {"path"}, ValueError),
    # filters.eskf_config.load_config
    ("config-missing", lambda p: (lambda: eskf_config.load_config(p / "none.yaml")), {"none.yaml"}, NOT_FOUND),
    ("config-directory", lambda p: (lambda: eskf_config.load_config(p)), {"directory"}, ValueError),
    ("config-not-utf8", _config_file(data=b"prior:\n  position: \xff\xfe\n"), {"bad.yaml"}, ValueError),
    ("config-bad-yaml", _config_file(text="prior: [1, 2\n"), {"bad.yaml"}, ValueError),
    ("config-tabs", _config_file(text="prior:\n\t- 1\n"), {"bad.yaml"}, ValueError),
    ("config-empty", _config_file(text=""), {"bad"}, ValueError),
    ("config-list", _config_file(text="- 1\n- 2\n"), {"bad"}, ValueError),
    ("config-binary", _config_file(data=bytes(range(256))), {"bad.yaml"}, ValueError),
    ("config-none", lambda p: (lambda: eskf_config.load_config(None)), {"source"}, ValueError),
    ("config-number", lambda p: (lambda: eskf_config.load_config(3.5)), {"source"}, ValueError),
    # the Udacity log reader
    ("log-missing", lambda p: (lambda: lidar_radar.read_udacity_log(p / "none.txt")), {"none.txt"}, NOT_FOUND),
    ("log-directory", lambda p: (lambda: lidar_radar.read_udacity_log(p)), {"directory"}, ValueError),
    ("log-none", lambda p: (lambda: lidar_radar.read_udacity_log(None)), {"path"}, ValueError),
    ("log-binary", _log_case(data=b"L 1 2 \xff\xfe 3\n", name="log.bin"), {"log.bin"}, ValueError),
    ("log-letter", _log_case(["X 1 2 3 4 5 6 7"]), {"line 1"}, ValueError),
    ("log-short", _log_case([GOOD_L, "L 1 2 3"]), {"line 2"}, ValueError),
    ("log-text-number", _log_case([GOOD_L, GOOD_L.replace("2.0", "two", 1)]), {"line 2"}, ValueError),
    ("log-nan", _log_case([GOOD_L.replace("1.0", "nan", 1)]), {"line 1"}, ValueError),
    ("log-float-stamp", _log_case(["L 1.0 2.0 1.5e15 1 2 3 4"]), {"line 1"}, ValueError),
    ("log-huge-stamp", _log_case(["L 1.0 2.0 99999999999999999999999 1 2 3 4"]), {"line 1"}, ValueError),
    ("log-negative-stamp", _log_case(["L 1.0 2.0 -5 1 2 3 4"]), {"line 1"}, ValueError),
    ("log-bearing-degrees", _log_case(["R 2.0 45.0 1.0 1477010443050000 1 2 3 4"]), {"line 1"}, ValueError),
    ("log-empty", _log_case(["", "   "]), {"log.txt"}, ValueError),
    ("log-mixed-format", _log_case([GOOD_L + " 0.1 0.2", GOOD_L]), {"line 2"}, ValueError),
]


@pytest.mark.parametrize("build, names, kind", [c[1:] for c in FILE_CASES], ids=[c[0] for c in FILE_CASES])
def test_a_broken_file_is_named(build, names, kind, tmp_path):
    call = build(tmp_path)
    with pytest.raises(Exception) as info:
        call()
    exc = info.value
    if kind is FileNotFoundError:
        assert type(exc) is FileNotFoundError, f"{type(exc).__name__}: {exc}"
        assert any(name in str(exc) for name in names), str(exc)
        assert "Errno" not in str(exc), str(exc)           # the loader's own sentence, not open()'s
        return
    if names == {"directory"}:                             # the folder is named by its path
        names = {tmp_path.name}
        assert "directory" in str(exc), str(exc)
    assert_names(exc, names)


# ---------------------------------------------------------------------------------------
# the table covers every public function of the modules
# ---------------------------------------------------------------------------------------

MODULES = (angles, imu, linalg, observations, ekf, nominal_ekf, eskf_config, consistency, drift, spread, kitti,
           synthetic, mems_imu, observation_errors)

#: Public callables deliberately without bad-input cases, and why.
EXEMPT = {
    # core.linalg's kernels are documented as unvalidated: filters validate at their public
    # boundary and then call them inside their loops, where every check would cost time
    linalg.symmetrise: "unvalidated kernel", linalg.predict_covariance: "unvalidated kernel",
    linalg.innovation_covariance: "unvalidated kernel", linalg.gain: "unvalidated kernel",
    linalg.whitened_gain: "unvalidated kernel", linalg.joseph_form: "unvalidated kernel",
    linalg.joseph_update: "unvalidated kernel", linalg.short_update: "unvalidated kernel",
    linalg.whitened_update: "unvalidated kernel",
    imu.integrate_midpoint: "unvalidated kernel (midpoint_step, dead_reckon and the ESKF validate first)",
    # no arguments
    kitti.kitti_dir: "no arguments", eskf_config.config_dir: "no arguments",
}

#: Covered by the special, configuration and file tables rather than by SPECS.
COVERED_ELSEWHERE = {eskf_config.load_config, kitti.read_manifest, kitti.load_excerpt_file, kitti.file_sha256}


def _is_function(obj) -> bool:
    return callable(obj) and not isinstance(obj, type)


def test_the_table_is_large_and_covers_every_public_function():
    covered = {fn for fn, *_ in SPECS} | COVERED_ELSEWHERE
    for module in MODULES:
        for name in module.__all__:
            obj = getattr(module, name)
            if _is_function(obj) and obj not in EXEMPT:
                assert obj in covered, f"{module.__name__}.{name} has no bad-input cases"
    assert lidar_radar.read_udacity_log in covered
    # the kernels say in their module that they are unvalidated
    assert "Unvalidated kernels" in linalg.__doc__ and "unvalidated" in imu.integrate_midpoint.__doc__
    total = len(CASES) + len(SPECIAL) + len(CONFIG_CASES) + len(FILE_CASES)
    assert len(CASES) >= 700 and total >= 1000, (len(CASES), total)


def test_numpy_phrases_are_the_shared_ones():
    # the phrases and kinds come from test_validation.py, so both tables apply one rule
    assert "out of bounds" in NUMPY_PHRASES and KINDS["vector"] is bad_vectors and KINDS["matrix"] is bad_matrices
