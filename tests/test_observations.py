"""Observation records: validation of bad input, read-only storage, subsets."""

import re

import numpy as np
import pytest

from kalman_course.core import so3
from kalman_course.core.observations import PoseObservations, PositionObservations
from kalman_course.core.validation import ROTATION_TOL, as_rotation

K = 6
T = np.arange(K) * 0.1
P = np.arange(3 * K, dtype=float).reshape(K, 3)
R = so3.exp(np.linspace(-1.0, 1.0, 3 * K).reshape(K, 3))


def _with(arr, index, value):
    out = np.array(arr, dtype=float)
    out[index] = value
    return out


def _scaled_rotation(k, factor):
    out = R.copy()
    out[k] = factor * out[k]
    return out


# (case id, t, position, rotation (None: a PositionObservations), message regex)
BAD = [
    ("t 2-D", T[:, None], P, None, r"t must be a 1-D array of shape \(K,\), got shape \(6, 1\)"),
    ("t NaN", _with(T, 3, np.nan), P, None, r"^t\[3\] is NaN$"),
    ("t inf", _with(T, 0, np.inf), P, None, r"^t\[0\] is inf$"),
    ("t repeated", _with(T, 4, T[3]), P, None,
     r"^t must be strictly increasing: t\[4\] = 0\.3 <= t\[3\] = 0\.3$"),
    ("t decreasing", T[::-1], P, None, r"t must be strictly increasing: t\[1\] = 0\.4 <= t\[0\] = 0\.5"),
    ("t not numbers", ["a", "b"], P[:2], None, r"t must be a 1-D array"),
    ("position short", T, P[:-1], None, r"position must have shape \(K=6, 3\).*got shape \(5, 3\)"),
    ("position 2 columns", T, P[:, :2], None, r"position must have shape \(K=6, 3\).*got shape \(6, 2\)"),
    ("position NaN", T, _with(P, (4, 1), np.nan), None, r"^position\[4\] is NaN$"),
    ("position -inf", T, _with(P, (2, 2), -np.inf), None, r"^position\[2\] is inf$"),
    ("position not numbers", T, [["x"] * 3] * K, None, r"position must be a numeric array"),
    ("rotation missing row", T, P, R[:-1], r"rotation must have shape \(K=6, 3, 3\).*got shape \(5, 3, 3\)"),
    ("rotation NaN", T, P, _with(R, (5, 0, 0), np.nan), r"^rotation\[5\] is NaN$"),
    ("rotation scaled", T, P, _scaled_rotation(3, 1.1),
     r"^rotation\[3\] is not a rotation matrix \(\|RᵀR − I\| = 0\.21,"),
    ("rotation sheared", T, P, _with(R, (1, 0, 1), R[1, 0, 1] + 1e-3), r"^rotation\[1\] is not a rotation matrix"),
    ("rotation reflection", T, P, _scaled_rotation(2, -1.0), r"^rotation\[2\] is a reflection.*det = -1"),
]


@pytest.mark.parametrize("t, position, rotation, message", [case[1:] for case in BAD],
                         ids=[case[0] for case in BAD])
def test_bad_input_names_the_field_and_the_first_bad_row(t, position, rotation, message):
    with pytest.raises(ValueError, match=message):
        if rotation is None:
            PositionObservations(t, position)
        else:
            PoseObservations(t, position, rotation)


def test_the_first_bad_row_is_named_when_several_are_bad():
    position = _with(_with(P, 4, np.nan), 1, np.inf)
    with pytest.raises(ValueError, match=re.escape("position[1] is inf")):
        PositionObservations(T, position)


def test_rotation_within_the_tolerance_is_accepted_and_just_outside_is_rejected():
    # a symmetric stretch of size e changes RᵀR − I by about 2e
    inside = R.copy()
    inside[0] = R[0] @ np.diag([1.0 + 0.4 * ROTATION_TOL, 1.0, 1.0])
    PoseObservations(T, P, inside)
    outside = R.copy()
    outside[0] = R[0] @ np.diag([1.0 + 0.6 * ROTATION_TOL, 1.0, 1.0])
    with pytest.raises(ValueError, match=r"rotation\[0\] is not a rotation matrix"):
        PoseObservations(T, P, outside)


def test_fields_are_read_only_float_copies():
    t_in, p_in = T.astype(np.float32), P.copy()
    obs = PositionObservations(t_in, p_in)
    assert obs.t.dtype == obs.position.dtype == np.float64
    p_in[0, 0] = 99.0                                   # the caller's array stays theirs
    assert obs.position[0, 0] == 0.0
    with pytest.raises(ValueError, match="read-only"):
        obs.position[0, 0] = 1.0
    with pytest.raises(AttributeError):
        obs.position = P                                # frozen
    pose = PoseObservations(T, P, R)
    with pytest.raises(ValueError, match="read-only"):
        pose.rotation[0] = np.eye(3)


def test_len_and_lists_are_accepted():
    obs = PositionObservations(T.tolist(), P.tolist())
    assert len(obs) == K
    np.testing.assert_array_equal(obs.position, P)
    assert len(PositionObservations([], np.zeros((0, 3)))) == 0
    assert len(PoseObservations([], np.zeros((0, 3)), np.zeros((0, 3, 3)))) == 0


def test_a_pose_record_is_a_position_record():
    assert isinstance(PoseObservations(T, P, R), PositionObservations)


@pytest.mark.parametrize("which, rows", [
    (slice(1, 4), [1, 2, 3]),
    (np.array([True, False, True, False, False, True]), [0, 2, 5]),
    ([0, 4], [0, 4]),
    (slice(None, None, 2), [0, 2, 4]),
])
def test_select_keeps_the_chosen_rows_and_the_type(which, rows):
    pose = PoseObservations(T, P, R).select(which)
    assert type(pose) is PoseObservations
    np.testing.assert_array_equal(pose.t, T[rows])
    np.testing.assert_array_equal(pose.position, P[rows])
    np.testing.assert_array_equal(pose.rotation, R[rows])
    positions = PositionObservations(T, P).select(which)
    assert type(positions) is PositionObservations
    np.testing.assert_array_equal(positions.position, P[rows])


def test_select_an_outage_drops_the_fixes_inside_it():
    obs = PositionObservations(T, P)
    kept = obs.select((obs.t < 0.15) | (obs.t > 0.35))
    np.testing.assert_array_equal(kept.t, T[[0, 1, 4, 5]])


def test_select_rejects_a_mask_of_the_wrong_length_and_reordering_indices():
    obs = PositionObservations(T, P)
    with pytest.raises(ValueError, match=r"which must be a boolean mask of shape \(6,\)"):
        obs.select(np.ones(4, dtype=bool))
    with pytest.raises(ValueError, match="t must be strictly increasing"):
        obs.select([3, 1])


def test_repr_is_short():
    assert repr(PositionObservations(T, P)) == "PositionObservations(K=6, t=[0 … 0.5] s)"
    assert repr(PoseObservations([], np.zeros((0, 3)), np.zeros((0, 3, 3)))) == "PoseObservations(K=0)"


@pytest.mark.parametrize("value, message", [
    (np.eye(3) * 1.1, r"^R_obs must be a rotation matrix .* max \|RᵀR − I\| = 0\.21,"),
    (-np.eye(3), r"^R_obs must be a rotation matrix .* det = -1"),
    (np.eye(4), r"R_obs must have shape \(3, 3\), got \(4, 4\)"),
    (np.full((3, 3), np.nan), r"R_obs must be finite"),
    ("x", r"R_obs must be a 2-D matrix of shape \(3, 3\)"),
], ids=["scaled", "reflection", "4x4", "NaN", "text"])
def test_as_rotation_rejects_what_is_not_a_rotation(value, message):
    with pytest.raises(ValueError, match=message):
        as_rotation(value, "R_obs")


def test_as_rotation_returns_a_proper_rotation_unchanged():
    np.testing.assert_array_equal(as_rotation(R[2].tolist(), "R_obs"), R[2])
