"""Chapter 06 (kalman_course.chapters.beacons): the KITTI beacon scenario, its observation
model, and the EKF against the IEKF."""

import numpy as np
import pytest

from kalman_course.chapters import beacons
from kalman_course.core.angles import wrap_angle


def test_beacon_observation_is_range_and_bearing_and_its_jacobian_matches_finite_differences():
    positions = np.array([[3.0, 4.0], [-2.0, 1.0]])
    x = np.array([0.5, -1.0, 2.0, 0.3])
    g, G = beacons.beacon_observation(positions), beacons.beacon_jacobian(positions)
    for i, b in enumerate(positions):
        d = x[:2] - b
        np.testing.assert_allclose(g(x)[2 * i:2 * i + 2], [np.hypot(*d), np.arctan2(d[1], d[0])])
    h = 1e-6
    numeric = np.column_stack([(g(x + h * e) - g(x - h * e)) / (2 * h) for e in np.eye(4)])
    np.testing.assert_allclose(G(x), numeric, rtol=1e-6, atol=1e-9)
    assert G(x).shape == (4, 4) and not G(x)[:, 2:].any()          # velocity is not observed


def test_bearings_residual_wraps_every_bearing_and_no_range():
    y = np.array([5.0, -np.pi + 0.01, 7.0, 0.2])
    y_pred = np.array([4.0, np.pi - 0.01, 6.5, 0.1])
    np.testing.assert_allclose(beacons.bearings_residual(y, y_pred), [1.0, 0.02, 0.5, 0.1], atol=1e-12)
    far = np.array([8.0, 0.0, 1.0, 0.0])
    assert beacons.bearings_residual(far, np.zeros(4))[0] == 8.0       # ranges are never wrapped


@pytest.mark.parametrize("call, message", [
    (lambda: beacons.bearings_residual([1.0, 0.1, 2.0], [1.0, 0.1, 2.0]), r"y must hold \[range, bearing\] pairs"),
    (lambda: beacons.bearings_residual([1.0, 0.1], [1.0, np.nan]), r"y_pred must be finite"),
    (lambda: beacons.bearings_residual([1.0, 0.1], [1.0, 0.1, 0.0, 0.0]), r"y_pred must have shape \(2,\)"),
    (lambda: beacons.beacon_observation(np.zeros((2, 3))), r"beacons must have shape \(m, 2\)"),
    (lambda: beacons.beacon_observation([[0.0, 1.0]])(np.zeros(3)), r"x must have shape \(4,\)"),
    (lambda: beacons.beacon_jacobian([[0.0, 1.0]])([0.0, np.nan, 0.0, 0.0]), r"x must be finite"),
    (lambda: beacons.kitti_beacons(seed=-1), r"seed must be a non-negative integer"),
    (lambda: beacons.kitti_beacons(n_beacons=0), r"n_beacons must be a positive integer"),
    (lambda: beacons.kitti_beacons(offset=-4.0), r"offset must be a finite positive number"),
], ids=["odd length", "NaN prediction", "lengths differ", "beacons not planar", "state of the wrong length",
        "NaN state", "negative seed", "no beacons", "negative offset"])
def test_bad_inputs_raise_a_value_error_naming_the_argument(call, message):
    with pytest.raises(ValueError, match=message):
        call()


def test_scenario_is_seeded_and_measures_the_nearest_beacons():
    sc = beacons.kitti_beacons("turns", 1)
    again = beacons.kitti_beacons("turns", 1)
    np.testing.assert_array_equal(sc.z, again.z)
    assert not np.array_equal(beacons.kitti_beacons("turns", 2).z, sc.z)
    distance = np.linalg.norm(sc.beacons[None, :, :] - sc.truth[:, None, :2], axis=2)
    np.testing.assert_array_equal(np.sort(distance, axis=1)[:, :2],
                                  np.take_along_axis(distance, sc.nearest, axis=1))
    noise = sc.z - np.array([beacons.beacon_observation(sc.beacons[i])(x) for x, i in zip(sc.truth, sc.nearest)])
    noise[:, 1::2] = wrap_angle(noise[:, 1::2])
    assert np.abs(noise[:, 0::2]).max() < 5 * 0.05 and np.abs(noise[:, 1::2]).max() < 5 * np.deg2rad(0.5)


def test_iekf_beats_the_ekf_on_precise_beacons_and_ties_on_far_ones():
    sc = beacons.kitti_beacons("turns", 1)
    e, i = beacons.run_beacon_filter(sc), beacons.run_beacon_filter(sc, iterated=True)
    assert i.position_rmse < 0.5 * e.position_rmse
    assert 2.0 < i.mean_nees < 6.0 < e.mean_nees
    assert (e.iterations == 1).all() and i.iterations.mean() > 2
    far = beacons.kitti_beacons("turns", 1, offset=100.0, sigma_range=0.5)
    e, i = beacons.run_beacon_filter(far), beacons.run_beacon_filter(far, iterated=True)
    assert abs(i.position_rmse - e.position_rmse) < 0.02 * e.position_rmse


def test_runs_over_seeds_are_the_single_runs_of_each_seed():
    # the notebook's spread over seeds is built from the same step functions as one run
    runs = beacons.runs_over_seeds([3, 4], iterated=True, sigma_a=1.0, offset=50.0)
    for seed, run in zip([3, 4], runs):
        alone = beacons.run_beacon_filter(beacons.kitti_beacons("turns", seed, offset=50.0), iterated=True,
                                          sigma_a=1.0)
        np.testing.assert_array_equal(run.nees, alone.nees)
    assert not np.array_equal(runs[0].nees, runs[1].nees)
    with pytest.raises(ValueError, match="seeds"):
        beacons.runs_over_seeds([])


def test_iterated_given_as_text_is_refused():
    sc = beacons.kitti_beacons("turns", 1)
    with pytest.raises(ValueError, match="iterated must be True or False"):
        beacons.run_beacon_filter(sc, iterated="no")
