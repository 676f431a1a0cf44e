"""Pose evaluation (APE, RPE, pose NEES): the moved ``evaluate`` scores an ESKF run as before."""

import numpy as np
import pytest

from kalman_course.core import so3
from kalman_course.data import load_kitti
from kalman_course.evaluation.pose import evaluate
from kalman_course.filters import eskf


def reference_evaluate(t, p, R, truth, P, rpe_delta=1.0):
    """The formulas as ``filters/eskf.py`` wrote them before the move: the oracle."""
    k = np.searchsorted(truth.t, t - 1e-6)
    pt, Rt = truth.position[k], truth.rotation[k]
    ep = p - pt
    dR = np.swapaxes(Rt, -1, -2) @ R
    eth = so3.log(dR)

    def angle(M):
        c = 0.5 * (np.trace(M, axis1=-2, axis2=-1) - 1.0)
        s = 0.5 * np.linalg.norm(np.stack([M[..., 2, 1] - M[..., 1, 2], M[..., 0, 2] - M[..., 2, 0],
                                           M[..., 1, 0] - M[..., 0, 1]], -1), axis=-1)
        return np.arctan2(s, c)

    j = np.searchsorted(t, t + rpe_delta - 1e-3)
    ok = j < len(t)
    i, j = np.nonzero(ok)[0], j[ok]
    rel_t_p = np.einsum("kji,kj->ki", Rt[i], pt[j] - pt[i])
    rel_e_p = np.einsum("kji,kj->ki", R[i], p[j] - p[i])
    rel_t_R = np.swapaxes(Rt[i], -1, -2) @ Rt[j]
    rel_e_R = np.swapaxes(R[i], -1, -2) @ R[j]
    idx = [0, 1, 2, 6, 7, 8]
    Pp = P[:, idx][:, :, idx]
    e6 = np.concatenate([ep, eth], axis=1)
    nees = np.einsum("ki,ki->k", e6, np.linalg.solve(Pp, e6[..., None])[..., 0])
    return {
        "ape_position": np.sqrt(np.mean(np.sum(ep ** 2, axis=1))),
        "ape_attitude_deg": np.rad2deg(np.sqrt(np.mean(angle(dR) ** 2))),
        "rpe_position": np.sqrt(np.mean(np.sum((rel_e_p - rel_t_p) ** 2, axis=1))),
        "rpe_attitude_deg": np.rad2deg(np.sqrt(np.mean(
            angle(np.swapaxes(rel_t_R, -1, -2) @ rel_e_R) ** 2))),
        "position_error": ep, "attitude_error": eth, "nees": nees, "nees_pose": np.mean(nees),
    }


@pytest.fixture(scope="module")
def cruise():
    return load_kitti("cruise")


@pytest.fixture(scope="module", params=["lidar", "gnss"])
def run(request, cruise):
    k0, s0 = cruise.initial_state()
    if request.param == "lidar":
        return eskf.run(cruise.imu, s0, "kitti_lidar", cruise.gravity, lidar=cruise.lidar, start=k0)
    res = eskf.run(cruise.imu, s0, "kitti_gnss", cruise.gravity, gnss=cruise.gnss.observations(),
                   start=k0, output_times=cruise.truth.t, clip_output_times=True)
    return res.at(cruise.truth.t)              # rows at the truth's times only


def test_an_eskf_run_scores_as_before_the_move(run, cruise):
    got = evaluate(run.t, run.position, run.rotation, cruise.truth, run.P)
    ref = reference_evaluate(run.t, run.position, run.rotation, cruise.truth, run.P)
    assert set(got) == set(ref) | {"nees_position", "nees_attitude"}     # the blocks came later
    for key in ("position_error", "attitude_error", "ape_attitude_deg", "rpe_attitude_deg"):
        np.testing.assert_array_equal(got[key], ref[key], err_msg=key)
    # the shared kernels sum in another order (ATE as the norm of per-axis RMSEs) and take
    # the NEES by a Cholesky factor instead of LU: equal to round-off
    for key in ("ape_position", "rpe_position", "nees", "nees_pose"):
        np.testing.assert_allclose(got[key], ref[key], rtol=1e-13, atol=0, err_msg=key)
    assert 0.0 < got["ape_position"] < 2.0 and np.isfinite(got["nees"]).all()


def test_the_truth_itself_has_no_error(cruise):
    tr = cruise.truth
    m = evaluate(tr.t, tr.position, tr.rotation, tr, np.broadcast_to(np.eye(6), (len(tr), 6, 6)))
    for key in ("ape_position", "ape_attitude_deg", "rpe_position", "rpe_attitude_deg", "nees_pose"):
        assert m[key] == 0.0, key


def test_a_constant_offset_is_absolute_not_relative_error(cruise):
    tr = cruise.truth
    offset = np.array([3.0, -4.0, 12.0])                      # |offset| = 13 m
    phi = np.deg2rad([0.0, 0.0, 2.0])
    m = evaluate(tr.t, tr.position + offset, tr.rotation @ so3.exp(phi), tr)
    assert m["ape_position"] == pytest.approx(13.0, rel=1e-12)
    assert m["ape_attitude_deg"] == pytest.approx(2.0, rel=1e-9)
    np.testing.assert_allclose(m["attitude_error"], np.broadcast_to(phi, (len(tr), 3)), atol=1e-12)
    # the translation between two poses does not see a constant position offset
    tr_only = evaluate(tr.t, tr.position + offset, tr.rotation, tr)
    assert tr_only["rpe_position"] < 1e-12 and tr_only["rpe_attitude_deg"] < 1e-9
    assert np.isnan(m["nees_pose"]) and np.isnan(m["nees"]).all()


def test_nees_uses_only_the_pose_block_of_a_15_state_covariance(cruise):
    tr = cruise.truth
    e_p, e_th = np.array([0.3, 0.0, -0.4]), np.deg2rad([0.0, 1.0, 0.0])
    sigma_p, sigma_th = 0.5, np.deg2rad(2.0)
    P = np.diag(np.r_[[sigma_p ** 2] * 3, [7.0] * 3, [sigma_th ** 2] * 3, [1e-6] * 6])
    m = evaluate(tr.t, tr.position + e_p, tr.rotation @ so3.exp(e_th), tr,
                 np.broadcast_to(P, (len(tr), 15, 15)))
    expected = (0.5 / sigma_p) ** 2 + (np.deg2rad(1.0) / sigma_th) ** 2     # 1 + 0.25
    np.testing.assert_allclose(m["nees"], expected, rtol=1e-9)



def test_block_nees_use_their_own_blocks_of_a_correlated_covariance(cruise):
    # the position and attitude NEES each invert their own 3×3 block, not the pose inverse's blocks:
    # with position–attitude correlation the two differ, and their sum is not the pose NEES
    tr = cruise.truth
    e_p, e_th = np.array([0.3, -0.1, -0.4]), np.deg2rad([0.5, 1.0, -0.3])
    A = np.array([[0.4, 0.0, 0.0, 0.0, 0.0, 0.0], [0.1, 0.3, 0.0, 0.0, 0.0, 0.0], [0.0, 0.05, 0.5, 0.0, 0.0, 0.0],
                  [0.01, 0.0, 0.0, 0.02, 0.0, 0.0], [0.0, 0.01, 0.0, 0.003, 0.03, 0.0],
                  [0.0, 0.0, 0.005, 0.0, 0.002, 0.025]])
    P_pose = A @ A.T                                       # symmetric positive definite, correlated blocks
    m = evaluate(tr.t[:5], tr.position[:5] + e_p, tr.rotation[:5] @ so3.exp(e_th), tr,
                 np.broadcast_to(P_pose, (5, 6, 6)))
    e_th_measured = so3.log(np.swapaxes(tr.rotation[0], -1, -2) @ tr.rotation[0] @ so3.exp(e_th))
    np.testing.assert_allclose(m["nees_position"], e_p @ np.linalg.solve(P_pose[:3, :3], e_p), rtol=1e-9)
    np.testing.assert_allclose(m["nees_attitude"], e_th_measured @ np.linalg.solve(P_pose[3:, 3:], e_th_measured),
                               rtol=1e-9)
    assert not np.allclose(m["nees_position"] + m["nees_attitude"], m["nees"])
    assert np.isnan(evaluate(tr.t[:5], tr.position[:5], tr.rotation[:5], tr)["nees_attitude"]).all()

def test_rpe_is_nan_when_no_two_times_are_rpe_delta_apart(cruise):
    tr = cruise.truth
    m = evaluate(tr.t[:3], tr.position[:3], tr.rotation[:3], tr, rpe_delta=5.0)
    assert np.isnan(m["rpe_position"]) and np.isnan(m["rpe_attitude_deg"])
    assert m["ape_position"] == 0.0


def _bad(cruise, **change):
    tr = cruise.truth
    args = dict(t=tr.t[:20], position=tr.position[:20], rotation=tr.rotation[:20], truth=tr, P=None)
    args.update(change)
    return args


BAD = [
    ("time between truth poses", dict(t=lambda tr: tr.t[:20] + np.r_[np.zeros(7), 0.05, np.zeros(12)]),
     r"t\[7\] = .* s is not one of truth\.t"),
    ("time NaN", dict(t=lambda tr: np.r_[tr.t[:19], np.nan]), r"t must be finite"),
    ("times unsorted", dict(t=lambda tr: tr.t[:20][::-1]), r"t must be strictly increasing"),
    ("empty", dict(t=lambda tr: tr.t[:0]), r"t must not be empty"),
    ("position short", dict(position=lambda tr: tr.position[:19]), r"position must have shape \(20, 3\)"),
    ("position NaN", dict(position=lambda tr: np.where(np.arange(20)[:, None] == 3, np.nan, tr.position[:20])),
     r"position must be finite"),
    ("rotation flat", dict(rotation=lambda tr: tr.rotation[:20].reshape(20, 9)),
     r"rotation must have shape \(20, 3, 3\)"),
    ("P wrong size", dict(P=lambda tr: np.broadcast_to(np.eye(9), (20, 9, 9))),
     r"P must have shape \(20, 15, 15\) or \(20, 6, 6\)"),
    ("P indefinite", dict(P=lambda tr: np.broadcast_to(np.diag([1.0, 1, 1, 1, 1, -1]), (20, 6, 6))),
     r"P must be positive definite"),
    ("rpe_delta zero", dict(rpe_delta=lambda tr: 0.0), r"rpe_delta must be a finite positive number"),
    ("truth without rotation", dict(truth=lambda tr: type("T", (), {"t": tr.t, "position": tr.position})),
     r"truth must have t, position and rotation; missing 'rotation'"),
]


@pytest.mark.parametrize("change, message", [c[1:] for c in BAD], ids=[c[0] for c in BAD])
def test_bad_input_names_the_argument(cruise, change, message):
    args = _bad(cruise, **{key: make(cruise.truth) for key, make in change.items()})
    with pytest.raises(ValueError, match=message):
        evaluate(**args)


# ---------------------------------------------------------------------------------------
# what is not a rotation is refused, in the estimate and in the truth (issue 27)
# ---------------------------------------------------------------------------------------

from types import SimpleNamespace                                        # noqa: E402

from kalman_course.evaluation.attitude import heading_tilt_error         # noqa: E402


def _small_truth(K=6):
    rng = np.random.default_rng(3)
    t = 0.1 * np.arange(K)
    rotation = so3.exp(rng.normal(0.0, 0.5, (K, 3)))
    return SimpleNamespace(t=t, position=rng.normal(0.0, 5.0, (K, 3)), rotation=rotation)


BROKEN = [
    ("reflection", lambda R: R @ np.diag([1.0, 1.0, -1.0]), "is a reflection, not a rotation"),
    ("scaled", lambda R: 1.05 * R, r"is not a rotation matrix \(\|RᵀR − I\| = 0.1"),
    ("sheared", lambda R: R @ np.array([[1.0, 0.3, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]),
     "is not a rotation matrix"),
]


@pytest.mark.parametrize("label, broken, message", BROKEN, ids=[b[0] for b in BROKEN])
def test_evaluate_refuses_an_estimate_that_is_not_a_rotation(label, broken, message):
    truth = _small_truth()
    rotation = truth.rotation.copy()
    rotation[3] = broken(rotation[3])
    with pytest.raises(ValueError, match=rf"^rotation\[3\] {message}"):
        evaluate(truth.t, truth.position, rotation, truth)


@pytest.mark.parametrize("label, broken, message", BROKEN, ids=[b[0] for b in BROKEN])
def test_evaluate_refuses_a_truth_that_is_not_a_rotation(label, broken, message):
    truth = _small_truth()
    estimate = truth.rotation.copy()
    truth.rotation[2] = broken(truth.rotation[2])
    with pytest.raises(ValueError, match=rf"^truth.rotation\[2\] {message}"):
        evaluate(truth.t, truth.position, estimate, truth)


def test_evaluate_accepts_rotations_printed_with_seven_digits():
    # products of two matrices each ~1e-7 off SO(3) are not re-checked against the tolerance
    truth = _small_truth()
    printed = np.vectorize(lambda v: float(f"{v:.6e}"))(truth.rotation)
    out = evaluate(truth.t, truth.position, printed, truth)
    assert out["ape_attitude_deg"] < 1e-4


@pytest.mark.parametrize("label, broken, message", BROKEN, ids=[b[0] for b in BROKEN])
def test_heading_tilt_error_refuses_what_is_not_a_rotation(label, broken, message):
    truth = _small_truth()
    bad = truth.rotation.copy()
    bad[4] = broken(bad[4])
    with pytest.raises(ValueError, match=rf"^rotation\[4\] {message}"):
        heading_tilt_error(bad, truth.rotation)
    with pytest.raises(ValueError, match=rf"^rotation_true\[4\] {message}"):
        heading_tilt_error(truth.rotation, bad)
    with pytest.raises(ValueError, match=rf"^rotation_true {message}"):
        heading_tilt_error(truth.rotation[0], bad[4])


def test_heading_tilt_error_still_splits_a_turn():
    R_true = so3.from_rpy(0.1, -0.2, 1.0)
    heading, tilt = heading_tilt_error(so3.exp([0.0, 0.0, np.deg2rad(2.0)]) @ R_true, R_true)
    assert np.isclose(heading, 2.0) and np.isclose(tilt, 0.0, atol=1e-12)
