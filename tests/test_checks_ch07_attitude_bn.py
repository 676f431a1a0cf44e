"""Chapter 07's attitude checks for the two storages of the attitude: ``attitude_step_bn`` (the
step of C = R_bn = R_nbᵀ, which the exercise asks the learner to derive) and ``attitude_step``
(R_nb, built from it). The conventions' mistakes are named, the cases and the sweep are the
R_nb step's seen through the transpose, a wrong ``attitude_step_bn`` is blamed upstream of the
R_nb step, and the exercise's self-check motions tell every convention mistake apart.

The checks run in-process on small functions written below (no kernel starts)."""

import numpy as np
import pytest

from kalman_course import checks, so3
from kalman_course.checks import CheckFailed, cases, hints, imu as imu_checks


@pytest.fixture(params=[None, 20261202], ids=["fixed", "drawn"])
def run_seed(request):
    cases.set_run_seed(request.param)
    yield request.param
    cases.set_run_seed(None)


def _phi(w0, w1, b_w, dt):
    return (0.5 * (w0 + w1) - b_w) * dt


def _bn(step):
    """An attitude_step_bn(C, w0, w1, b_w, dt) from ``step(C, φ)``."""
    def attitude_step_bn(C, w0, w1, b_w, dt):
        return step(C, _phi(w0, w1, b_w, dt))
    return attitude_step_bn


def _failure(check, fn) -> str:
    with pytest.raises(CheckFailed) as failed:
        check.judge(fn)
    return str(failed.value)


@pytest.mark.parametrize("step", [
    lambda C, phi: so3.Exp(-phi) @ C,
    lambda C, phi: so3.Exp(phi).T @ C,
    lambda C, phi: (C.T @ so3.Exp(phi)).T,                     # the lecture's step of R = Cᵀ, transposed back
    lambda C, phi: so3.quat_to_matrix(so3.quat_multiply(so3.quat_exp(-phi), so3.matrix_to_quat(C))),
], ids=["Exp(-phi) C", "Exp(phi)^T C", "(C^T Exp(phi))^T", "quaternion"])
def test_every_form_of_the_derived_step_passes(step, run_seed):
    checks.attitude_step_bn.judge(_bn(step))


@pytest.mark.parametrize("step, named", [
    (lambda C, phi: C @ so3.Exp(phi), "lecture 07's step for R = R_nb, applied to C"),
    (lambda C, phi: so3.Exp(phi) @ C, "must be transposed too"),
    (lambda C, phi: C @ so3.Exp(-phi), "reverses the order of its factors"),
    (lambda C, phi: C.T @ so3.Exp(phi), "returns the new R_nb"),
    (lambda C, phi: so3.Exp(-phi) @ C.T, "do not transpose C"),
    (lambda C, phi: C.copy(), "did not change"),
], ids=["C Exp(phi)", "Exp(phi) C", "C Exp(-phi)", "C^T Exp(phi)", "Exp(-phi) C^T", "C unchanged"])
def test_each_convention_mistake_is_named_without_the_formula_at_tier_one(step, named, run_seed):
    text = _failure(checks.attitude_step_bn, _bn(step))
    assert named in text and "C_next is wrong" in text
    assert "Exp(−φ) C" not in text and text.endswith(f"({hints.IN_NOTEBOOK})")


def test_tier_two_gives_the_derived_step():
    hints.set_tier(2, escalate=False)
    try:
        text = _failure(checks.attitude_step_bn, _bn(lambda C, phi: C @ so3.Exp(phi)))
    finally:
        hints.set_tier(1, escalate=False)
    assert "C_next = Exp(φ)ᵀ C = Exp(−ω̄ T) C" in text


def test_the_learner_is_handed_c_and_its_result_is_read_as_c():
    seen = []

    def attitude_step_bn(C, w0, w1, b_w, dt):
        seen.append(np.array(C))
        return so3.Exp(-_phi(w0, w1, b_w, dt)) @ C

    checks.attitude_step_bn.judge(attitude_step_bn)
    first = imu_checks._attitude_cases()[0]
    assert np.allclose(seen[0], first["R"].T) and not np.allclose(seen[0], first["R"])


def test_a_cut_off_in_the_derived_step_is_named_by_the_sweep():
    def step(C, phi):
        return C.copy() if np.linalg.norm(phi) < 1e-8 else so3.Exp(-phi) @ C
    text = _failure(checks.attitude_step_bn, _bn(step))
    assert "small rotations" in text and "returns C unchanged" in text


def test_a_rate_mistake_keeps_its_hint_through_the_transpose():
    def attitude_step_bn(C, w0, w1, b_w, dt):
        return so3.Exp(-0.5 * (w0 + w1) * dt) @ C        # the bias left in
    assert "subtract the gyro bias" in _failure(checks.attitude_step_bn, attitude_step_bn)


# ---- attitude_step built from attitude_step_bn -------------------------------------------

def _namespace_with(bn_step):
    """A learner namespace whose attitude_step_bn is ``bn_step`` and an attitude_step in it."""
    namespace = {"attitude_step_bn": _bn(bn_step)}
    exec("def attitude_step(R, w0, w1, b_w, dt):\n"
         "    return attitude_step_bn(R.T, w0, w1, b_w, dt).T\n", namespace)
    return namespace


def test_a_wrong_attitude_step_bn_is_blamed_upstream():
    namespace = _namespace_with(lambda C, phi: C @ so3.Exp(phi))
    text = _failure(checks.attitude_step, namespace["attitude_step"])
    assert "calls your attitude_step_bn" in text and "fix attitude_step_bn first" in text


def test_a_right_attitude_step_bn_through_the_conversions_passes(run_seed):
    checks.attitude_step.judge(_namespace_with(lambda C, phi: so3.Exp(-phi) @ C)["attitude_step"])


@pytest.mark.parametrize("body, named", [
    ("attitude_step_bn(R, w0, w1, b_w, dt)", "hand it the transpose of R, and transpose what it returns"),
    ("attitude_step_bn(R.T, w0, w1, b_w, dt)", "transpose it back"),
    ("attitude_step_bn(R, w0, w1, b_w, dt).T", "not R itself"),
])
def test_the_conversions_forgotten_are_named(body, named):
    namespace = {"attitude_step_bn": _bn(lambda C, phi: so3.Exp(-phi) @ C)}
    exec(f"def attitude_step(R, w0, w1, b_w, dt):\n    return {body}\n", namespace)
    assert named in _failure(checks.attitude_step, namespace["attitude_step"])


def test_an_r_step_that_does_not_call_attitude_step_bn_gets_no_conversion_hint():
    def attitude_step(R, w0, w1, b_w, dt):
        return R.T @ so3.Exp(_phi(w0, w1, b_w, dt))
    text = _failure(checks.attitude_step, attitude_step)
    assert "do not transpose R" in text and "attitude_step_bn" not in text


# ---- the exercise's self-check motions ---------------------------------------------------

def _motions():
    """The two motions of the exercise's self-check: (C0, gyro reading, nose, left side) after
    one step of 1 s, expected from the picture (a level car turning left from east; a level
    car heading north rolling a quarter turn about its nose)."""
    quarter = np.pi / 2
    north = so3.Exp(np.array([0.0, 0.0, quarter])).T
    return [(np.eye(3), np.array([0.0, 0.0, quarter]), [0, 1, 0], [-1, 0, 0]),
            (north, np.array([quarter, 0.0, 0.0]), [0, 1, 0], [0, 0, 1])]


def _as_expected(step) -> list[bool]:
    out = []
    for C0, w, nose, left in _motions():
        C1 = step(C0, w * 1.0)
        out.append(bool(np.allclose(C1.T @ [1, 0, 0], nose) and np.allclose(C1.T @ [0, 1, 0], left)))
    return out


def test_the_self_check_motions_agree_with_the_reference_step():
    # the expectations come from the picture; the R_nb reference step, transposed, must meet them
    assert _as_expected(lambda C, phi: imu_checks.reference_attitude_step(C.T, phi, phi, np.zeros(3), 1.0).T) \
        == [True, True]


@pytest.mark.parametrize("step", [lambda C, phi: C @ so3.Exp(phi), lambda C, phi: so3.Exp(phi) @ C,
                                  lambda C, phi: C @ so3.Exp(-phi), lambda C, phi: C.copy()],
                         ids=["C Exp(phi)", "Exp(phi) C", "C Exp(-phi)", "C unchanged"])
def test_the_self_check_motions_catch_every_convention_mistake(step):
    assert not all(_as_expected(step))
