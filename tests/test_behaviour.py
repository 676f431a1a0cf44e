"""Graders judge behaviour as well as values: a learner function that changes its arguments in
place, returns an argument's memory, computes in single precision or answers the same question
two ways fails its check, with a hint that names what it did, in the learner's kernel and
through the plain-data protocol alike; correct code passes. An alias or a second answer is
judged after the values (a wrong value keeps its own hint); an argument changed in place or
single precision is named even when a value is wrong, as the likelier cause."""

import numpy as np
import pytest

from kalman_course.checks import CheckFailed, harness
from kalman_course.checks.remote import LearnerFunction, LocalSession
from kalman_course.core.numdiff import numerical_jacobian

P = np.array([[2.0, 0.3], [0.3, 1.5]])
F = np.array([[1.0, 0.1], [0.0, 1.0]])
Q = np.array([[0.01, 0.02], [0.02, 0.3]])
EXPECTED = F @ P @ F.T + Q

#: name -> (source of a learner's predict(P, F, Q), the words its failure must contain, or None)
LEARNERS = {
    "correct": ("def predict(P, F, Q):\n    return F @ P @ F.T + Q\n", None),
    "a copy, then in place": ("def predict(P, F, Q):\n    P = P.copy()\n    P[:] = F @ P @ F.T\n"
                              "    P += Q\n    return P\n", None),
    "in place": ("def predict(P, F, Q):\n    P[:] = F @ P @ F.T + Q\n    return P\n",
                 "predict changed its argument P in place"),
    "in place, fresh result": ("def predict(P, F, Q):\n    out = F @ P @ F.T + Q\n    Q *= 0\n    return out\n",
                               "predict changed its argument Q in place"),
    "returns an argument": ("def predict(P, F, Q):\n    Q[:] = F @ P @ F.T + Q\n    return Q\n",
                            "changed its argument Q in place"),
    "float32": ("def predict(P, F, Q):\n    return (F @ P @ F.T + Q).astype(np.float32)\n",
                "computes in single precision: the result is float32"),
    "float32 in a tuple": ("def predict(P, F, Q):\n    return [np.float32(1.0), F @ P @ F.T + Q][1:] + "
                           "[np.float16(0)]\n", "item 1 is float16"),
    "unrepeatable": ("_calls = [0]\n"
                     "def predict(P, F, Q):\n    _calls[0] += 1\n    return F @ P @ F.T + Q + 1e-3 * (_calls[0] % 2 == 0)\n",
                     "gave different results for the same inputs"),
    # a wrong value after an argument changed in place: the change is named, it is the likelier cause
    "wrong and in place": ("def predict(P, F, Q):\n    P[:] = F @ P @ F + Q\n    return P\n",
                           "predict changed its argument P in place"),
    # a wrong value and a returned argument: the value's own message (the alias explains nothing)
    "wrong and aliased": ("def predict(P, F, Q):\n    return P\n", "differs from the reference"),
}


@pytest.fixture
def predict_check():
    """A registered check of predict(P, F, Q), removed afterwards."""
    @harness.check
    def check_behaviour_predict(predict):
        got = harness.call(predict, P, F, Q)
        harness.expect_close(got if not isinstance(got, list) else got[0], EXPECTED, "P_check")
    yield check_behaviour_predict
    harness._REGISTRY.pop("behaviour_predict", None)


def _learner(source: str, remote: bool):
    namespace = {"np": np, "__name__": "__main__"}
    exec(source, namespace)
    return LearnerFunction(LocalSession(namespace), "predict") if remote else namespace["predict"]


@pytest.mark.parametrize("remote", [False, True], ids=["in the kernel", "through the protocol"])
@pytest.mark.parametrize("name", list(LEARNERS))
def test_behaviour_is_judged_after_the_values(predict_check, name, remote):
    source, words = LEARNERS[name]
    learner = _learner(source, remote)
    if words is None:
        predict_check.judge(learner)
        return
    with pytest.raises(CheckFailed) as failed:
        predict_check.judge(learner)
    assert words in str(failed.value), str(failed.value)
    assert name == "wrong and aliased" or " Hint: " in str(failed.value)


def test_the_hint_names_the_argument_by_its_parameter_name(predict_check):
    source = ("def predict(cov, trans, noise):\n    out = trans @ cov @ trans.T + noise\n    cov[0, 0] = -1\n"
              "    return out\n")
    with pytest.raises(CheckFailed, match="changed its argument cov in place"):
        predict_check.judge(_learner(source, remote=True))


def test_an_alias_of_an_argument_is_reported_when_values_are_right():
    @harness.check
    def check_behaviour_identity(fn):
        x = np.arange(3.0)
        harness.expect_close(harness.call(fn, x), x, "x")
    try:
        for source, words in [("def f(x):\n    return x\n", "returns its argument x itself"),
                              ("def f(x):\n    return x[:]\n", "returns its argument x itself, or a view"),
                              ("def f(x):\n    return x.copy()\n", None),
                              ("def f(x):\n    return np.array(x)\n", None)]:
            for remote in (False, True):
                namespace = {"np": np, "__name__": "__main__"}
                exec(source, namespace)
                fn = LearnerFunction(LocalSession(namespace), "f") if remote else namespace["f"]
                if words is None:
                    check_behaviour_identity.judge(fn)
                else:
                    with pytest.raises(CheckFailed, match=words):
                        check_behaviour_identity.judge(fn)
    finally:
        harness._REGISTRY.pop("behaviour_identity", None)


def test_a_call_outside_a_check_fails_at_once():
    def in_place(P):
        P += 1
        return P * 2
    with pytest.raises(CheckFailed, match="in_place changed its argument P in place"):
        harness.call(in_place, np.eye(2))


def test_the_callers_arrays_are_never_touched():
    # the learner's function works on copies: the check's own cases stay as they were
    P0 = P.copy()

    def in_place(P, F, Q):
        P *= 100
        return P
    with pytest.raises(CheckFailed):
        harness.call(in_place, P0, F, Q)
    np.testing.assert_array_equal(P0, P)



@pytest.mark.parametrize("remote", [False, True], ids=["in the kernel", "through the protocol"])
def test_only_a_checks_first_call_of_a_function_is_repeated(remote):
    # a whole run called once costs two runs; a sweep of many calls costs one more call, not twice as many
    source = "calls = []\ndef predict(P, F, Q):\n    calls.append(1)\n    return F @ P @ F.T + Q\n"
    namespace = {"np": np, "__name__": "__main__"}
    exec(source, namespace)
    learner = LearnerFunction(LocalSession(namespace), "predict") if remote else namespace["predict"]

    @harness.check
    def check_behaviour_thrice(predict):
        for _ in range(3):
            harness.expect_close(harness.call(predict, P, F, Q), EXPECTED, "P_check")
    try:
        check_behaviour_thrice.judge(learner)
        assert len(namespace["calls"]) == 4
        check_behaviour_thrice.judge(learner)  # the next check run repeats its first call again
        assert len(namespace["calls"]) == 8
    finally:
        harness._REGISTRY.pop("behaviour_thrice", None)

#: learner functions f(x) handed to a package function (numerical_jacobian) that calls them
DRIVEN = {
    "correct": ("def f(x):\n    return np.array([x[0] * x[1], np.sin(x[0])])\n", None),
    "in place": ("def f(x):\n    x[1] = x[1] * 1.0\n    x[0] += 0.0\n    y = np.array([x[0] * x[1], np.sin(x[0])])\n"
                 "    x *= 2\n    return y\n", "f changed its argument x in place"),
}


@pytest.mark.parametrize("remote", [False, True], ids=["in the kernel", "through the protocol"])
@pytest.mark.parametrize("name", list(DRIVEN))
def test_a_function_driven_by_a_package_function_is_named(remote, name):
    @harness.check
    def check_behaviour_driven(f):
        x = np.array([0.3, -1.2])
        got = harness.call(numerical_jacobian, f, x)
        harness.expect_close(got, [[x[1], x[0]], [np.cos(x[0]), 0.0]], "the Jacobian", rtol=1e-3, atol=1e-3)
    source, words = DRIVEN[name]
    try:
        namespace = {"np": np, "__name__": "__main__"}
        exec(source, namespace)
        f = LearnerFunction(LocalSession(namespace), "f") if remote else namespace["f"]
        if words is None:
            check_behaviour_driven.judge(f)
        else:
            with pytest.raises(CheckFailed, match=words):
                check_behaviour_driven.judge(f)
    finally:
        harness._REGISTRY.pop("behaviour_driven", None)


@pytest.mark.parametrize("remote", [False, True], ids=["in the kernel", "through the protocol"])
def test_a_name_never_defined_is_told_as_such(remote, predict_check):
    namespace = {"np": np, "__name__": "__main__"}
    exec("def predict(P, F, Q):\n    return propagate(P, F) + Q\n", namespace)
    learner = LearnerFunction(LocalSession(namespace), "predict") if remote else namespace["predict"]
    with pytest.raises(CheckFailed) as failed:
        predict_check.judge(learner)
    assert str(failed.value) == ("behaviour_predict: predict uses propagate, which is not defined. Hint: run the "
                                 "cell that defines propagate first; if that cell raised an error, fix it, then "
                                 "run it again")


@pytest.mark.parametrize("source, hint", [
    ("def predict(P, F, Q):\n    return F[:, :1] @ P @ F.T + Q\n", "shapes do not fit together"),
    ("def predict(P, F, Q):\n    return F @ P @ F.T + Q[2]\n", "an index is past the end"),
    ("def predict(P, F, Q):\n    return F @ np.linalg.inv(P - P) @ F.T + Q\n", "singular"),
    ("def predict(P, F, Q):\n    return F @ P @ F.T + Q + len()\n", "called with the wrong arguments"),
])
def test_an_exception_without_a_hint_gets_one_by_its_kind(predict_check, source, hint):
    with pytest.raises(CheckFailed) as failed:
        predict_check.judge(_learner(source, remote=True))
    message = str(failed.value)
    assert " raised " in message and hint in message.split(" Hint: ", 1)[1], message
