"""Checks graded from outside the learner's kernel: the plain-data protocol and its guarantees.

The protocol runs here without a kernel (:class:`LocalSession` runs the kernel's agent in
this process, so attacks on the grading process's frames are not tested here);
``tests/test_exercises.py`` and the mutation harness run it against real notebooks, and
``tests/test_forgeries.py`` against forged ones in real kernels.
"""

import functools
import json

import numpy as np
import pytest

from kalman_course import checks
from kalman_course.checks import harness, kernel_agent, plain_data
from kalman_course.checks.remote import LearnerFunction, LearnerNamespace, LocalSession
from kalman_course.core.numdiff import numerical_jacobian
from kalman_course.filters.eskf import NominalState


def _round_trip(value, towards_kernel=False):
    text = plain_data.encode(value, towards_kernel=towards_kernel)
    return plain_data.decode(text, from_kernel=not towards_kernel)


def test_plain_data_crosses_exactly_with_its_types():
    value = (1, -0.0, 2.5e-300, float("nan"), float("-inf"), "σ²", None, True,
             [np.arange(6.0).reshape(2, 3).T, np.float64(0.1), np.bool_(False), np.int8(-3)],
             {"k": (1, 2), (0, "a"): [], 3: np.array([1 + 2j])})
    back = _round_trip(value)
    assert type(back) is tuple and type(back[8]) is list and type(back[9]) is dict
    assert back[1] == 0.0 and str(back[1]) == "-0.0" and back[2] == 2.5e-300 and np.isnan(back[3])
    arr = back[8][0]
    assert type(arr) is np.ndarray and arr.shape == (3, 2) and np.array_equal(arr, value[8][0])
    assert arr.flags.writeable and arr.flags.c_contiguous
    assert type(back[8][1]) is np.float64 and back[8][1] == 0.1
    assert type(back[8][2]) is np.bool_ and type(back[8][3]) is np.int8
    assert back[9][(0, "a")] == [] and back[9][3].dtype == np.complex128


def test_course_dataclasses_cross_whole_and_then_by_handle():
    state = NominalState(position=np.array([1.0, 2.0, 3.0]), velocity=np.zeros(3), rotation=np.eye(3))
    memo, handles = {}, {}
    first = plain_data.encode(state, towards_kernel=True, memo=memo)
    again = plain_data.encode(state, towards_kernel=True, memo=memo)
    assert len(again) < 40 < len(first)
    rebuilt = plain_data.decode(first, from_kernel=False, handles=handles)
    assert plain_data.decode(again, from_kernel=False, handles=handles) is rebuilt
    assert np.array_equal(rebuilt.position, state.position)


@pytest.mark.parametrize("record, why", [
    ({"~": "function", "ref": "kalman_course.filters.kf:kf_update"}, "not accepted here"),
    ({"~": "learner", "name": "kf_update"}, "not accepted here"),
    ({"~": "dataclass", "type": "os:environ", "fields": {}}, "not in the kalman_course package"),
    ({"~": "dataclass", "type": "kalman_course.filters.kf:kf_update", "fields": {}}, "not a dataclass"),
    ({"~": "array", "dtype": "|O", "shape": [1], "data": ""}, "dtype"),
    ({"~": "array", "dtype": "<f8", "shape": [2], "data": "AAAAAAAA8D8="}, "does not match its shape"),
    ({"~": "array", "dtype": "<f8", "shape": [-1], "data": ""}, "non-negative"),
    ({"~": "float", "repr": "1e5"}, "nan, inf or -inf"),
    ({"~": "pickle", "data": "gASV"}, "not accepted"),
    ({"a": 1}, "not accepted"),
    ({"~": "dict", "items": [[[1], 2]]}, "hashable"),
])
def test_the_grading_side_accepts_only_plain_data(record, why):
    with pytest.raises(plain_data.NotPlainData, match=why):
        plain_data.decode(json.dumps(record), from_kernel=True)


def test_deep_nesting_and_non_json_are_rejected():
    deep = "[" * 40 + "]" * 40
    with pytest.raises(plain_data.NotPlainData, match="deeper"):
        plain_data.decode(deep, from_kernel=True)
    with pytest.raises(plain_data.NotPlainData, match="not JSON"):
        plain_data.decode("{'a': 1}", from_kernel=True)


class _LyingText(str):
    """A learner's verdict that claims to equal every label."""

    def __eq__(self, other):
        return True

    def __ne__(self, other):
        return False

    __hash__ = str.__hash__


class _ArraySubclass(np.ndarray):
    pass


def test_results_are_converted_to_exact_plain_values_in_the_kernel():
    text = kernel_agent.to_plain(_LyingText("consistent"))
    assert type(text) is str and text == "consistent" and text != "overconfident"
    assert type(kernel_agent.to_plain(np.eye(2).view(_ArraySubclass))) is np.ndarray
    assert kernel_agent.to_plain(object()) == plain_data.Opaque("object")
    assert type(kernel_agent.to_plain(True)) is bool


def _session(**functions):
    return LocalSession(dict(functions))


def test_a_lying_string_cannot_pass_a_verdict_check_from_outside():
    session = _session(verdict=lambda values, dof, confidence: _LyingText("consistent"))
    with pytest.raises(checks.CheckFailed, match="consistency_verdict"):
        checks.consistency_verdict.judge(LearnerFunction(session, "verdict"))


def test_learner_errors_read_the_same_from_outside_as_inside():
    def kf_gain(P, G, R):
        raise ValueError("shapes do not match")

    inside = outside = None
    with pytest.raises(checks.CheckFailed) as inside:
        checks.kf_gain.judge(kf_gain)
    with pytest.raises(checks.CheckFailed) as outside:
        checks.kf_gain.judge(LearnerFunction(_session(kf_gain=kf_gain), "kf_gain"))
    assert str(inside.value) == str(outside.value) and "raised ValueError: shapes do not match" in str(inside.value)
    with pytest.raises(checks.CheckFailed, match="expected a function, got int"):
        harness.call(LearnerFunction(_session(kf_gain=3), "kf_gain"))
    with pytest.raises(checks.CheckFailed, match="raised NameError: name 'kf_gian' is not defined"):
        harness.call(LearnerFunction(_session(), "kf_gian"))


def test_package_drivers_run_the_learners_functions_in_the_kernel():
    calls = []

    def scaled_square(k, x):
        calls.append(k)
        return k * x**2

    session = _session(scaled_square=scaled_square)
    learner_fn = LearnerFunction(session, "scaled_square")
    # a package function handed a learner function (here in a partial) runs in the kernel
    J = harness.call(numerical_jacobian, functools.partial(learner_fn, 2.0), np.array([1.0, 2.0]))
    assert np.allclose(J, np.diag([4.0, 8.0]), atol=1e-6) and calls and set(calls) == {2.0}
    assert LearnerNamespace(session).get("scaled_square") is not None
    assert LearnerNamespace(session).get("nope") is None
    exec("def doubled(x):\n    return scaled_square(1.0, x) * 2", session.namespace)
    assert harness.referenced_names(LearnerFunction(session, "doubled")) == {"scaled_square"}


def test_a_result_that_is_not_plain_data_is_named_by_its_type():
    session = _session(kf_gain=lambda P, G, R: {1, 2})
    with pytest.raises(checks.CheckFailed, match="must return a tuple .K, S., got set"):
        checks.kf_gain.judge(LearnerFunction(session, "kf_gain"))
