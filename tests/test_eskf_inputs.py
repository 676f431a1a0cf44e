"""Bad inputs to the ESKF, the nominal-state EKF and SO(3): each raises a ValueError that
names the argument (issue 11, items 7 and 8), never a numpy-internal message or a NaN result."""

from __future__ import annotations

import types

import numpy as np
import pytest

from kalman_course.core import so3
from kalman_course.data import load_kitti
from kalman_course.filters import eskf, nominal_ekf
from kalman_course.filters.eskf import NominalState
from kalman_course.filters.eskf_config import load_config

G = np.array([0.0, 0.0, -9.8092])
NAN3 = np.array([0.0, np.nan, 0.0])
R_GOOD = so3.exp(np.array([0.1, -0.2, 0.3]))
R_SHEARED = R_GOOD + np.array([[0.0, 0.05, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
R_REFLECTION = R_GOOD @ np.diag([1.0, 1.0, -1.0])
P_GOOD = np.diag(np.arange(1.0, 16.0)) * 1e-2
P_ASYMMETRIC = P_GOOD.copy()
P_ASYMMETRIC[0, 1] = 0.3
# symmetric, non-negative diagonal, but indefinite: a variance-covariance pair no Gaussian has
P_INDEFINITE = P_GOOD.copy()
P_INDEFINITE[0, 1] = P_INDEFINITE[1, 0] = 2.0 * np.sqrt(P_GOOD[0, 0] * P_GOOD[1, 1])
X = NominalState(np.zeros(3), np.ones(3), R_GOOD)
X_NAN = NominalState(NAN3, np.ones(3), R_GOOD)
X_SHEARED = NominalState(np.zeros(3), np.ones(3), R_SHEARED)
Q16 = np.r_[np.zeros(6), so3.matrix_to_quat(R_GOOD), np.zeros(6)]


def _filter():
    return eskf.ESKF("kitti_lidar", X, G)


# (label, call, message the ValueError must match)
CASES = [
    # the step-by-step ESKF
    ("predict dt = 0", lambda: _filter().predict(np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3), 0.0), r"^dt "),
    ("predict dt < 0", lambda: _filter().predict(np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3), -0.01), r"^dt "),
    ("predict dt NaN",
     lambda: _filter().predict(np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3), np.nan),
     r"^dt "),
    ("predict NaN reading", lambda: _filter().predict(NAN3, np.zeros(3), np.zeros(3), np.zeros(3), 0.01), r"^f0 "),
    ("predict short reading",
     lambda: _filter().predict(np.zeros(3), np.zeros(2), np.zeros(3), np.zeros(3), 0.01),
     r"^w0 "),
    ("predict interpolated not a bool",
     lambda: _filter().predict(*[np.zeros(3)] * 4, 0.01, interpolated="yes"),
     r"^interpolated "),
    ("ESKF non-symmetric P0", lambda: eskf.ESKF("kitti_lidar", X, G, P0=P_ASYMMETRIC), r"^P0 must be symmetric"),
    ("ESKF indefinite P0", lambda: eskf.ESKF("kitti_lidar", X, G, P0=P_INDEFINITE),
     r"^P0 must be positive semi-definite"),
    ("ESKF P0 wrong shape", lambda: eskf.ESKF("kitti_lidar", X, G, P0=np.eye(6)), r"^P0 "),
    ("ESKF NaN initial state", lambda: eskf.ESKF("kitti_lidar", X_NAN, G), r"^initial.position "),
    ("ESKF initial rotation not a rotation",
     lambda: eskf.ESKF("kitti_lidar", X_SHEARED, G),
     r"^initial.rotation must be a rotation"),
    ("ESKF initial without a rotation",
     lambda: eskf.ESKF("kitti_lidar", object(), G),
     r"^initial must be a NominalState"),
    ("ESKF NaN gravity", lambda: eskf.ESKF("kitti_lidar", X, NAN3), r"^gravity\[1\] is NaN"),
    ("ESKF config of the wrong type", lambda: eskf.ESKF(3.0, X, G), r"^config must be"),
    ("update_pose non-orthonormal rotation",
     lambda: _filter().update_pose(np.zeros(3), R_SHEARED),
     r"^R_meas must be a rotation"),
    ("update_pose reflection",
     lambda: _filter().update_pose(np.zeros(3), R_REFLECTION),
     r"^R_meas must be a rotation"),
    ("update_pose NaN position", lambda: _filter().update_pose(NAN3, R_GOOD), r"^p_meas "),
    ("update_position NaN", lambda: _filter().update_position(NAN3), r"^p_meas "),
    # the building blocks
    ("error_dynamics R not a rotation",
     lambda: eskf.error_dynamics(R_SHEARED, np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3)),
     r"^R must be a rotation"),
    ("error_dynamics NaN force",
     lambda: eskf.error_dynamics(R_GOOD, NAN3, np.zeros(3), np.zeros(3), np.zeros(3)),
     r"^specific_force "),
    ("error_dynamics bias shape",
     lambda: eskf.error_dynamics(R_GOOD, np.zeros(3), np.zeros(3), np.zeros(4), np.zeros(3)),
     r"^accel_bias "),
    ("noise_jacobian unknown bias model", lambda: eskf.noise_jacobian(R_GOOD, "brownian"), r"^bias_model "),
    ("noise_jacobian R shape", lambda: eskf.noise_jacobian(np.eye(4)), r"^R "),
    ("discretise T = 0", lambda: eskf.discretise(np.zeros((15, 15)), np.zeros((15, 12)), 0.0), r"^T "),
    ("discretise F_t shape", lambda: eskf.discretise(np.zeros((15, 14)), np.zeros((15, 12)), 0.01), r"^F_t "),
    ("discretise B_t columns", lambda: eskf.discretise(np.zeros((15, 15)), np.zeros((15, 7)), 0.01), r"^B_t "),
    ("process_noise negative density", lambda: eskf.process_noise([0.1, -1.0, 0.0, 0.0], 0.01), r"^density "),
    ("process_noise density length", lambda: eskf.process_noise([0.1, 0.1, 0.1], 0.01), r"^density "),
    ("process_noise T < 0", lambda: eskf.process_noise([0.1] * 4, -0.01), r"^T "),
    ("process_noise unknown bias model", lambda: eskf.process_noise([0.1] * 4, 0.01, "white"), r"^bias_model "),
    ("propagate_covariance non-symmetric P",
     lambda: eskf.propagate_covariance(P_ASYMMETRIC, np.eye(15), np.zeros((15, 12)), np.eye(12)),
     r"^P must be symmetric"),
    ("propagate_covariance Q shape",
     lambda: eskf.propagate_covariance(P_GOOD, np.eye(15), np.zeros((15, 12)), np.eye(6)),
     r"^Q "),
    ("propagate_covariance NaN F",
     lambda: eskf.propagate_covariance(P_GOOD, np.full((15, 15), np.nan), np.zeros((15, 12)), np.eye(12)),
     r"^F "),
    ("pose_residual non-orthonormal R_meas",
     lambda: eskf.pose_residual(np.zeros(3), R_GOOD, np.zeros(3), R_SHEARED),
     r"^R_meas must be a rotation"),
    ("pose_residual R_check shape",
     lambda: eskf.pose_residual(np.zeros(3), np.eye(2), np.zeros(3), R_GOOD),
     r"^R_check "),
    ("position_residual shape", lambda: eskf.position_residual(np.zeros(3), np.zeros(2)), r"^p_meas "),
    ("kalman_gain non-symmetric P",
     lambda: eskf.kalman_gain(P_ASYMMETRIC, eskf.POSE_G, np.eye(6)),
     r"^P must be symmetric"),
    ("kalman_gain G columns", lambda: eskf.kalman_gain(P_GOOD, np.zeros((6, 14)), np.eye(6)), r"^G "),
    ("kalman_gain singular R",
     lambda: eskf.kalman_gain(P_GOOD, eskf.POSE_G, np.zeros((6, 6))),
     r"^R must be positive definite"),
    ("kalman_gain R shape", lambda: eskf.kalman_gain(P_GOOD, eskf.POSE_G, np.eye(3)), r"^R "),
    ("update_covariance K shape",
     lambda: eskf.update_covariance(P_GOOD, np.zeros((15, 3)), eskf.POSE_G, np.eye(6)),
     r"^K "),
    ("inject dx length", lambda: eskf.inject(X, np.zeros(14)), r"^dx "),
    ("inject NaN dx", lambda: eskf.inject(X, np.full(15, np.nan)), r"^dx "),
    ("inject NaN nominal", lambda: eskf.inject(X_NAN, np.zeros(15)), r"^nominal.position "),
    ("reset_jacobian dx length", lambda: eskf.reset_jacobian(np.zeros(9)), r"^dx "),
    ("reset_covariance non-symmetric P",
     lambda: eskf.reset_covariance(P_ASYMMETRIC, np.zeros(15)),
     r"^P must be symmetric"),
    ("reset_covariance exact not a bool",
     lambda: eskf.reset_covariance(P_GOOD, np.zeros(15), exact="no"),
     r"^exact "),
    ("nominal_step dt = 0", lambda: eskf.nominal_step(X, *[np.zeros(3)] * 4, 0.0, G), r"^dt "),
    ("nominal_step NaN gravity",
     lambda: eskf.nominal_step(X, *[np.zeros(3)] * 4, 0.01, NAN3),
     r"^gravity\[1\] is NaN"),
    ("nominal_step rotation not a rotation",
     lambda: eskf.nominal_step(X_SHEARED, *[np.zeros(3)] * 4, 0.01, G),
     r"^nominal.rotation must be a rotation"),
    ("NominalState.from_nav NaN",
     lambda: NominalState.from_nav(types.SimpleNamespace(position=NAN3, velocity=np.zeros(3), rotation=R_GOOD)),
     r"^nav.position "),
    ("initial_covariance not a config", lambda: eskf.initial_covariance(None), r"^config must be"),
    ("EskfResult.at NaN times", lambda: _short_run().at([np.nan]), r"^times "),
    # the nominal-state EKF
    ("nominal_ekf.propagate dt = 0", lambda: nominal_ekf.propagate(Q16, *[np.zeros(3)] * 4, 0.0, G), r"^dt "),
    ("nominal_ekf.propagate zero quaternion",
     lambda: nominal_ekf.propagate(np.zeros(16), *[np.zeros(3)] * 4, 0.01, G),
     r"^x\[6:10\] must be a non-zero quaternion"),
    ("nominal_ekf.propagate state length",
     lambda: nominal_ekf.propagate(np.zeros(15), *[np.zeros(3)] * 4, 0.01, G),
     r"^x "),
    ("nominal_ekf.continuous_jacobian NaN q",
     lambda: nominal_ekf.continuous_jacobian([1.0, np.nan, 0, 0], *[np.zeros(3)] * 4),
     r"^q "),
    ("nominal_ekf.nominal_noise_jacobian q length", lambda: nominal_ekf.nominal_noise_jacobian(np.ones(3)), r"^q "),
    ("nominal_ekf.rotate_jacobian a length",
     lambda: nominal_ekf.rotate_jacobian([1.0, 0, 0, 0], np.zeros(2)),
     r"^a "),
    ("nominal_ekf.quat_xi q length", lambda: nominal_ekf.quat_xi(np.ones(5)), r"^q "),
    ("nominal_ekf.quat_omega v length", lambda: nominal_ekf.quat_omega(np.ones(4)), r"^v "),
    # SO(3)
    ("so3.exp NaN", lambda: so3.exp(NAN3), r"^phi must be finite"),
    ("so3.exp of a string", lambda: so3.exp("abc"), r"^phi must be a numeric array"),
    ("so3.log NaN", lambda: so3.log(np.full((3, 3), np.nan)), r"^R must be finite"),
    ("so3.log shape", lambda: so3.log(np.eye(2)), r"^R must have shape"),
    ("so3.left_jacobian shape", lambda: so3.left_jacobian(np.zeros(4)), r"^phi must have shape"),
    ("so3.right_jacobian_inv beyond π",
     lambda: so3.right_jacobian_inv(np.array([0.0, 0.0, 3.5])),
     r"^phi must have norm"),
    ("so3.interpolate NaN alpha", lambda: so3.interpolate(R_GOOD, R_GOOD, np.nan), r"^alpha must be finite"),
    ("so3.interpolate R1 shape", lambda: so3.interpolate(R_GOOD, np.eye(2), 0.5), r"^R1 must have shape"),
    ("so3.is_rotation negative tol", lambda: so3.is_rotation(R_GOOD, tol=-1.0), r"^tol "),
    ("so3.quat_to_matrix zero", lambda: so3.quat_to_matrix(np.zeros(4)), r"^q must be non-zero"),
    ("so3.quat_multiply p shape", lambda: so3.quat_multiply(np.ones(3), np.ones(4)), r"^p must have shape"),
    ("so3.quat_exp NaN", lambda: so3.quat_exp(NAN3), r"^phi must be finite"),
    ("so3.matrix_to_quat shape", lambda: so3.matrix_to_quat(np.ones(3)), r"^R must have shape"),
]


@pytest.mark.parametrize("call,message", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_input_raises_a_value_error_naming_the_argument(call, message):
    with np.errstate(all="raise"):          # and no NaN reaches the result on the way
        with pytest.raises(ValueError, match=message):
            call()


# ---------------------------------------------------------------------------------------
# eskf.run and run_nominal_ekf: bad samples and bad observations
# ---------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def turns():
    ex = load_kitti("turns")
    k0, s0 = ex.initial_state()
    return ex, k0, s0


def _short_run():
    ex = load_kitti("turns")
    k0, s0 = ex.initial_state()
    return eskf.run(ex.imu, s0, "kitti_lidar", ex.gravity, lidar=ex.lidar, start=k0, t_end=ex.imu.t[k0] + 0.5)


def _imu_with(imu, field, row, value):
    data = {f: np.array(getattr(imu, f)) for f in ("t", "specific_force", "angular_rate", "interpolated")}
    data[field][row] = value
    return types.SimpleNamespace(**data)


def _gnss_with(gnss, row, value):
    position = np.array(gnss.position_noisy)
    position[row] = value
    return types.SimpleNamespace(t=gnss.t, position=position)


def _lidar_with(lidar, field, row, value):
    data = {f: np.array(getattr(lidar, f)) for f in ("t", "position", "rotation")}
    data[field][row] = value
    return types.SimpleNamespace(**data)


RUN_CASES = [
    ("NaN lidar position",
     lambda ex: {"lidar": _lidar_with(ex.lidar, "position", 40, np.nan)},
     r"^lidar: position\[40\] is NaN"),
    ("lidar rotation not orthonormal",
     lambda ex: {"lidar": _lidar_with(ex.lidar, "rotation", 7, R_SHEARED)},
     r"^lidar: rotation\[7\] is not a rotation"),
    ("lidar times not increasing",
     lambda ex: {"lidar": _lidar_with(ex.lidar, "t", 5, 0.0)},
     r"^lidar: t must be strictly increasing"),
    ("lidar without rotations",
     lambda ex: {"lidar": types.SimpleNamespace(t=ex.lidar.t, position=ex.lidar.position)},
     r"^lidar must be a PoseObservations"),
    ("inf GNSS position",
     lambda ex: {"gnss": _gnss_with(ex.gnss, 3, np.inf)},
     r"^gnss: position\[3\] is inf"),
    ("NaN IMU angular rate",
     lambda ex: {"imu": _imu_with(ex.imu, "angular_rate", 1234, np.nan)},
     r"^imu.angular_rate\[1234\] is NaN"),
    ("inf IMU specific force",
     lambda ex: {"imu": _imu_with(ex.imu, "specific_force", 999, np.inf)},
     r"^imu.specific_force\[999\] is inf"),
    ("NaN IMU time", lambda ex: {"imu": _imu_with(ex.imu, "t", 1500, np.nan)}, r"^imu.t\[1500\] is NaN"),
    ("IMU time going back",
     lambda ex: {"imu": _imu_with(ex.imu, "t", 1500, 0.0)},
     r"^imu.t must be strictly increasing: imu.t\[1500\]"),
    ("NaN gravity", lambda ex: {"gravity": np.array([0.0, 0.0, np.nan])}, r"^gravity\[2\] is NaN"),
    ("gravity shape", lambda ex: {"gravity": np.zeros(2)}, r"^gravity must have shape \(3,\)"),
    ("non-symmetric P0", lambda ex: {"P0": P_ASYMMETRIC}, r"^P0 must be symmetric"),
    ("indefinite P0", lambda ex: {"P0": P_INDEFINITE}, r"^P0 must be positive semi-definite"),
    ("start out of range", lambda ex: {"start": 10 ** 6}, r"^start must be"),
    ("start not an integer", lambda ex: {"start": 1.5}, r"^start must be"),
    ("NaN t_end", lambda ex: {"t_end": np.nan}, r"^t_end must be a finite time"),
    ("t_end before the start", lambda ex: {"t_end": 0.0}, r"at least two IMU samples"),
    ("gap_factor zero", lambda ex: {"gap_factor": 0.0}, r"^gap_factor "),
    ("NaN output time", lambda ex: {"output_times": [np.nan]}, r"^output_times "),
    ("use_interpolation_flags not a bool",
     lambda ex: {"use_interpolation_flags": "yes"},
     r"^use_interpolation_flags "),
    ("initial rotation not a rotation", lambda ex: {"initial": X_SHEARED}, r"^initial.rotation must be a rotation"),
]


@pytest.mark.parametrize("change,message", [c[1:] for c in RUN_CASES], ids=[c[0] for c in RUN_CASES])
def test_run_rejects_bad_samples_and_observations(turns, change, message):
    ex, k0, s0 = turns
    args = {"imu": ex.imu, "initial": s0, "gravity": ex.gravity, "lidar": ex.lidar, "start": k0}
    args.update(change(ex))
    with pytest.raises(ValueError, match=message):
        eskf.run(config="kitti_lidar", **args)


NOMINAL_EKF_CASES = ("NaN lidar position", "lidar rotation not orthonormal", "NaN IMU angular rate",
                     "NaN gravity", "start out of range", "initial rotation not a rotation")


@pytest.mark.parametrize("change,message", [c[1:] for c in RUN_CASES if c[0] in NOMINAL_EKF_CASES],
                         ids=[c[0] for c in RUN_CASES if c[0] in NOMINAL_EKF_CASES])
def test_run_nominal_ekf_rejects_them_too(turns, change, message):
    ex, k0, s0 = turns
    args = {"imu": ex.imu, "initial": s0, "gravity": ex.gravity, "lidar": ex.lidar, "start": k0}
    args.update(change(ex))
    with pytest.raises(ValueError, match=message):
        nominal_ekf.run_nominal_ekf(config=load_config("kitti_lidar"), **args)


def test_a_nan_observation_no_longer_poisons_the_run_silently(turns):
    """The issue's case: before, one NaN lidar position turned every later output into NaN."""
    ex, k0, s0 = turns
    bad = _lidar_with(ex.lidar, "position", 40, np.nan)
    with pytest.raises(ValueError, match=r"position\[40\] is NaN"):
        eskf.run(ex.imu, s0, "kitti_lidar", ex.gravity, lidar=bad, start=k0)
    good = eskf.run(ex.imu, s0, "kitti_lidar", ex.gravity, lidar=ex.lidar, start=k0, t_end=ex.imu.t[k0] + 5.0)
    assert np.isfinite(good.position).all() and np.isfinite(good.P).all()


def test_an_indefinite_process_or_observation_noise_is_refused():
    # symmetric, positive diagonal, one negative eigenvalue: it would make P indefinite
    P, F, B = np.eye(15), np.eye(15), np.eye(15)[:, :6]
    Q = np.eye(6)
    Q[0, 1] = Q[1, 0] = 2.0
    with pytest.raises(ValueError, match="Q must be positive semi-definite"):
        eskf.propagate_covariance(P, F, B, Q)
    G, K = np.eye(15)[:3], np.zeros((15, 3))
    R = np.eye(3)
    R[0, 2] = R[2, 0] = 1.5
    with pytest.raises(ValueError, match="R must be positive semi-definite"):
        eskf.update_covariance(P, K, G, R)
    # a singular R (a component known exactly) and Q are fine
    assert np.isfinite(eskf.update_covariance(P, K, G, np.diag([1.0, 0.0, 1.0]))).all()
    assert np.isfinite(eskf.propagate_covariance(P, F, B, np.zeros((6, 6)))).all()


@pytest.mark.parametrize("which", ["eskf", "relative", "augmented", "nominal"])
def test_gravity_of_the_wrong_sign_or_in_g_is_refused_by_every_filter(turns, which):
    from kalman_course.filters import eskf_augmented, eskf_relative
    ex, k0, s0 = turns
    t_end = ex.imu.t[k0] + 2.0
    runs = {"eskf": lambda g: eskf.run(ex.imu, s0, "kitti_lidar", g, lidar=ex.lidar, start=k0, t_end=t_end),
            "relative": lambda g: eskf_relative.run_relative(ex.imu, s0, "kitti_lidar", g, vo=ex.lidar,
                                                             relative_std=(0.01, 1e-3), start=k0, t_end=t_end),
            "augmented": lambda g: eskf_augmented.run(ex.imu, s0, "kitti_lidar", g, lidar=ex.lidar, time_constant=1.0,
                                                      start=k0, t_end=t_end),
            "nominal": lambda g: nominal_ekf.run_nominal_ekf(ex.imu, s0, "kitti_lidar", g, lidar=ex.lidar, start=k0,
                                                             t_end=t_end)}
    run = runs[which]
    with pytest.raises(ValueError, match="gravity points along the specific force"):
        run(-ex.gravity)                                   # +9.81 "up" in the z-up navigation frame
    with pytest.raises(ValueError, match=r"given in g\?"):
        run(ex.gravity / 9.80665)
    with pytest.raises(ValueError, match=r"\|g\| between 9.7 and 9.9"):
        run(ex.gravity * 3.0)
    assert np.isfinite(run(ex.gravity).position).all()     # the right one runs


def test_at_finds_the_rows_of_unsorted_times(turns):
    ex, k0, s0 = turns
    res = eskf.run(ex.imu, s0, "kitti_lidar", ex.gravity, lidar=ex.lidar, start=k0, t_end=ex.imu.t[k0] + 5.0,
                   output_times=ex.lidar.t[(ex.lidar.t > ex.imu.t[k0]) & (ex.lidar.t <= ex.imu.t[k0] + 5.0)])
    times = res.t[::2]
    shuffled = np.random.default_rng(0).permutation(times)
    assert np.array_equal(res.at(shuffled).t, times) and np.array_equal(res.at(times).t, times)
