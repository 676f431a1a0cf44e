"""Chapters 04–06's checks: the dense sweep of the CTRV singular regime and its reference, the
radar model's conventions (a bearing off by whole turns, single precision, ρ → 0), a coarse
finite-difference Jacobian named as such, hints in tiers, and the choice of the mistake that
explains every case (``ekf._judge`` on ``harness.known_mistake``).

Every test here runs the checks in-process on small learner functions written below; none
starts a kernel.
"""

import mpmath
import numpy as np
import pytest

from kalman_course import symbolic
from kalman_course.checks import CheckFailed, cases, ekf, hints, motion
from kalman_course.core.angles import wrap_angle


@pytest.fixture(params=[None, 20261202], ids=["fixed", "drawn"])
def run_seed(request):
    """The checks' fixed cases, then those of one run seed; back to the fixed ones afterwards."""
    cases.set_run_seed(request.param)
    yield request.param
    cases.set_run_seed(None)


def _exact_increment(x, T):
    """f(x) − x of the CTRV step's position, by the closed form in 40 significant digits (exact
    where the double-precision closed form cancels)."""
    with mpmath.workdps(40):
        px, py, v, psi, om = (mpmath.mpf(float(c)) for c in x)
        T = mpmath.mpf(float(T))
        if om == 0:
            return np.array([float(v * T * mpmath.cos(psi)), float(v * T * mpmath.sin(psi))])
        return np.array([float(v / om * (mpmath.sin(psi + om * T) - mpmath.sin(psi))),
                         float(v / om * (mpmath.cos(psi) - mpmath.cos(psi + om * T)))])


def test_the_sweep_reaches_every_regime(run_seed):
    sweep = motion.kitti_ctrv_cases()
    rates = np.array([x[4] for x, *_ in sweep])
    steps = np.array([T for _, T, *_ in sweep])
    assert steps.min() <= 2e-5 and steps.max() >= 1.5          # a tiny step and the exercise's horizon
    for k in motion.SWEEP_DECADES:
        for sign in (1.0, -1.0):
            # in every decade, a rate just above the round cut-off 10^k, of either sign
            above = sign * rates / 10.0**k
            assert np.any((above > 1.0) & (above < 1.11)), (k, sign)
    # right turns at |ω T| > 1 at the longest step, where the lecture's series is far off
    assert np.any((rates * steps < -1.0) & (steps >= 1.5))
    # the Jacobian's subset: a rate just above every round cut-off, at the tiny step and at 0.1 s
    jacobian = motion.jacobian_cases()
    # (at the tiny step up to 1e-3 rad/s, above which the closed form is exact there)
    for T_max, decades in ((2e-5, range(-13, -2)), (0.3, range(-13, 0))):
        near = [abs(x[4]) for x, T, *_ in jacobian if T <= T_max and x[4] != 0.0]
        for k in decades:
            assert any(1.0 < rate / 10.0**k < 1.11 for rate in near), (T_max, k)
    assert any(x[4] * T < -1.0 for x, T, *_ in jacobian)


def test_the_step_reference_is_exact_over_the_sweep(run_seed):
    # the tolerance is 1e-6 of v T: the reference must be far better than that everywhere,
    # also where the double-precision closed form would lose every digit
    for x, T, expected, _ in motion.kitti_ctrv_cases():
        error = np.abs((expected[:2] - x[:2]) - _exact_increment(x, T))
        # 1e-13 of v T, and the round-off of subtracting KITTI coordinates (~400 m) back out
        assert np.all(error <= 1e-13 * abs(x[2]) * T + 2e-13), (x, T, error)


def _closed_form_above(cut_off, on_rate_times_step=False):
    """A learner's ctrv_step: the closed form above the cut-off, the lecture's series below it."""
    def ctrv_step(x, T):
        px, py, v, psi, omega = x
        size = abs(omega * T) if on_rate_times_step else abs(omega)
        if size > cut_off:
            px_new = px + v / omega * (np.sin(psi + omega * T) - np.sin(psi))
            py_new = py + v / omega * (np.cos(psi) - np.cos(psi + omega * T))
        else:
            K = np.arange(8)
            c = v * T * (omega * T) ** K / np.cumprod(K + 1)
            px_new, py_new = px + c @ np.cos(psi + K * np.pi / 2), py + c @ np.sin(psi + K * np.pi / 2)
        return np.array([px_new, py_new, v, psi + omega * T, omega])
    return ctrv_step


@pytest.mark.parametrize("cut_off", [1e-12, 1e-9, 1e-6])
def test_a_cut_off_on_the_rate_alone_fails_with_the_cancellation_named(run_seed, cut_off):
    with pytest.raises(CheckFailed, match="cancellation"):
        motion.check_ctrv_step.judge(_closed_form_above(cut_off))


def test_a_cut_off_where_the_closed_form_is_exact_passes(run_seed):
    motion.check_ctrv_step.judge(_closed_form_above(1e-7, on_rate_times_step=True))
    motion.check_ctrv_step.judge(_closed_form_above(motion.THRESHOLD, on_rate_times_step=True))


def _forward_difference_jacobian(h):
    def ctrv_jacobian(x, T):
        x = np.asarray(x, dtype=float)
        f0 = symbolic.ctrv_step(x, T)
        return np.column_stack([(symbolic.ctrv_step(x + h * e, T) - f0) / h for e in np.eye(5)])
    return ctrv_jacobian


def test_a_coarse_finite_difference_jacobian_is_named_as_such():
    with pytest.raises(CheckFailed, match="too coarse") as failed:
        motion.check_ctrv_jacobian.judge(_forward_difference_jacobian(1e-2))
    assert "h = 0.01" in str(failed.value)
    motion.check_ctrv_jacobian.judge(_forward_difference_jacobian(1e-6))


def _radar_h(bearing_range=None, dtype=float):
    def radar_h(x):
        px, py, v, psi, _ = x
        rho = np.hypot(px, py)
        phi = np.arctan2(py, px)
        if bearing_range == "[0, 2π)":
            phi = phi % (2 * np.pi)
        return np.array([rho, phi, (px * v * np.cos(psi) + py * v * np.sin(psi)) / rho], dtype=dtype)
    return radar_h


def test_a_bearing_in_zero_to_two_pi_is_the_same_bearing(run_seed):
    ekf.check_radar_h.judge(_radar_h("[0, 2π)"))
    # some case must have a bearing that [0, 2π) moves, or the test proves nothing
    assert any(h[1] < 0 for _, h in ekf._radar_h_references())


def test_an_unwrapped_residual_is_still_rejected():
    def radar_residual(y, y_pred):
        return np.asarray(y, dtype=float) - np.asarray(y_pred, dtype=float)
    with pytest.raises(CheckFailed, match="must be wrapped"):
        ekf.check_radar_residual.judge(radar_residual)


def test_single_precision_is_named():
    with pytest.raises(CheckFailed, match="single precision"):
        ekf.check_radar_h.judge(_radar_h(dtype=np.float32))


def test_the_radar_model_is_graded_next_to_the_radar(run_seed):
    ranges = [np.hypot(x[0], x[1]) for x, _ in ekf._radar_h_references()]
    assert min(ranges) <= 1e-2

    def guarded(x):                       # a guard that changes h where it is defined
        out = _radar_h()(x)
        out[2] = out[2] * out[0] / max(out[0], 0.01)
        return out
    with pytest.raises(CheckFailed, match="range rate"):
        ekf.check_radar_h.judge(guarded)


def _noise_without_cross_terms(x, T, sigma_a, sigma_yaw):
    B = symbolic.ctrv_noise_jacobian(x, T)
    return np.diag(np.diag(B @ np.diag([sigma_a**2, sigma_yaw**2]) @ B.T))


def test_tier_one_names_the_concept_and_section_without_the_formula():
    with pytest.raises(CheckFailed) as failed:
        motion.check_ctrv_process_noise.judge(_noise_without_cross_terms)
    text = str(failed.value)
    assert "cross terms" in text and "lecture 04 §4b" in text
    assert "B diag(σ_a², σ_ψ̈²) Bᵀ" not in text and text.endswith(f"({hints.IN_NOTEBOOK})")


def test_tier_two_shows_the_formula():
    hints.set_tier(2, escalate=False)
    try:
        with pytest.raises(CheckFailed) as failed:
            motion.check_ctrv_process_noise.judge(_noise_without_cross_terms)
    finally:
        hints.set_tier(1, escalate=False)
    assert "Q = B diag(σ_a², σ_ψ̈²) Bᵀ" in str(failed.value)


def _case(value, expected, mistakes):
    return (np.asarray(value, dtype=float), np.asarray(expected, dtype=float), "v", lambda: mistakes)


def test_the_mistake_named_is_the_one_that_explains_every_case():
    # "one way" coincides with the learner on the failing case only; "both" also on the case
    # the learner got right, where it coincides with the right answer: "both" explains all
    results = [_case([1.0], [0.0], [([1.0], "one way"), ([1.0], "both")]),
               _case([2.0], [2.0], [([5.0], "one way"), ([2.0], "both")])]
    with pytest.raises(CheckFailed, match="Hint: both"):
        ekf._judge(results, close=ekf._allclose(1e-9, 1e-12), hint="none")


def test_a_mistake_without_a_value_on_a_case_is_not_held_against_it():
    results = [_case([1.0], [0.0], [([1.0], "first"), ([1.0], "second")]),
               _case([3.0], [0.0], [([7.0], "first"), ([3.0], "second")]),
               _case([2.0], [2.0], [([np.nan], "second")])]   # no usable value: undefined there
    with pytest.raises(CheckFailed, match="Hint: second"):
        ekf._judge(results, close=ekf._allclose(1e-9, 1e-12), hint="none")


def test_without_a_known_mistake_the_fallback_hint_is_given():
    results = [_case([1.0], [0.0], [([4.0], "first")])]
    with pytest.raises(CheckFailed, match="differs from the reference.*Hint: none"):
        ekf._judge(results, close=ekf._allclose(1e-9, 1e-12), hint="none")


def test_a_heading_wrapped_into_minus_pi_pi_passes():
    def ctrv_step(x, T):
        out = symbolic.ctrv_step(x, T)
        out[3] = wrap_angle(out[3])
        return out
    motion.check_ctrv_step.judge(ctrv_step)


# ---- ekf_update: entries of y that were not measured (NaN) ------------------------------------

def _update_measured(x_check, P_check, y, g, G, R, residual):
    """The EKF update of the measured entries, written in information form (another formula
    than the check's reference, which is the library's gain form on the reduced case)."""
    measured = np.isfinite(y)
    if not measured.any():
        return np.array(x_check, dtype=float), np.array(P_check, dtype=float)
    y_pred = np.asarray(g(x_check), dtype=float)
    r = np.asarray(residual(np.where(measured, y, y_pred), y_pred), dtype=float)[measured]
    Gm = np.asarray(G(x_check), dtype=float)[measured]
    R_inv = np.linalg.inv(np.asarray(R, dtype=float)[np.ix_(measured, measured)])
    P_hat = np.linalg.inv(np.linalg.inv(P_check) + Gm.T @ R_inv @ Gm)
    return x_check + P_hat @ Gm.T @ R_inv @ r, P_hat


def test_the_missing_cases_cover_every_role(run_seed):
    found = ekf.missing_update_cases()
    counts = [int((~measured).sum()) for _, measured in found]
    sizes = [len(measured) for _, measured in found]
    assert 0 in [m - c for m, c in zip(sizes, counts)]                # one with nothing measured
    assert 1 in counts                                                 # one with a single entry missing
    assert any(1 < c < m for c, m in zip(counts, sizes))               # several missing, some measured
    for case, measured in found:
        y, R = case[2], case[5]
        assert np.array_equal(np.isnan(y), ~measured)
        # a case whose R correlates a missing entry with a measured one tells R's block from
        # G's rows zeroed
    assert any(np.abs(case[5][np.ix_(~measured, measured)]).max(initial=0.0) > 0 for case, measured in found
               if measured.any())


def test_a_range_is_missing_next_to_the_cut_in_the_fixed_cases():
    # the entries left, [φ, ρ̇], are not where the residual looks for the bearing
    radar = [(case, measured) for case, measured in ekf.missing_update_cases() if len(measured) == 3]
    assert any(not measured[0] and measured[1] and abs(case[2][1]) > 3.0 for case, measured in radar)


def test_the_missing_references_agree_with_the_information_form(run_seed):
    start = len(ekf.ekf_update_cases())
    for k, (case, _) in enumerate(ekf.missing_update_cases()):
        x_ref, P_ref = ekf._ekf_reference(start + k)
        x_info, P_info = _update_measured(*case)
        assert np.allclose(x_ref, x_info, rtol=1e-8, atol=1e-9)
        assert np.allclose(P_ref, P_info, rtol=1e-7, atol=1e-11)


def test_the_information_form_with_missing_entries_passes(run_seed):
    ekf.check_ekf_update.judge(_update_measured)


def test_a_huge_variance_for_the_missing_entries_is_accepted():
    def ekf_update(x_check, P_check, y, g, G, R, residual):
        measured = np.isfinite(y)
        y_pred = g(x_check)
        r = residual(np.where(measured, y, y_pred), y_pred)
        Gm = G(x_check)
        Rm = np.array(R, dtype=float)
        Rm[~measured, :] = Rm[:, ~measured] = 0.0
        Rm[~measured, ~measured] = 1e12
        K = P_check @ Gm.T @ np.linalg.inv(Gm @ P_check @ Gm.T + Rm)
        return x_check + K @ r, (np.eye(len(x_check)) - K @ Gm) @ P_check
    ekf.check_ekf_update.judge(ekf_update)


def _missing_failure(ekf_update) -> str:
    with pytest.raises(CheckFailed) as failed:
        ekf.check_ekf_update.judge(ekf_update)
    return str(failed.value)


def test_zeroed_rows_of_g_with_the_whole_r_are_named():
    def ekf_update(x_check, P_check, y, g, G, R, residual):
        measured = np.isfinite(y)
        y_pred = g(x_check)
        r = residual(np.where(measured, y, y_pred), y_pred)
        Gm = G(x_check) * measured[:, None]
        K = P_check @ Gm.T @ np.linalg.inv(Gm @ P_check @ Gm.T + R)
        return x_check + K @ r, (np.eye(len(x_check)) - K @ Gm) @ P_check
    text = _missing_failure(ekf_update)
    assert "correlations" in text and "missing (NaN)" in text and "np.ix_" not in text   # tier 1


def test_nan_reaching_the_result_is_named():
    def ekf_update(x_check, P_check, y, g, G, R, residual):
        Gm = G(x_check)
        K = P_check @ Gm.T @ np.linalg.inv(Gm @ P_check @ Gm.T + R)
        y_pred = g(x_check)
        r = residual(np.where(np.isfinite(y), y, y_pred), y_pred)
        r[~np.isfinite(y)] = np.nan                 # the missing entries carried along as NaN
        return x_check + K @ r, (np.eye(len(x_check)) - K @ Gm) @ P_check
    assert "reached the result" in _missing_failure(ekf_update)


def test_a_failure_with_nothing_measured_is_named():
    def ekf_update(x_check, P_check, y, g, G, R, residual):
        if np.isnan(y).all():
            raise RuntimeError("nothing to update with")
        return _update_measured(x_check, P_check, y, g, G, R, residual)
    text = _missing_failure(ekf_update)
    assert "RuntimeError" in text and "nothing was measured" in text


def test_the_lectures_equations_as_they_stand_are_told_what_nan_means(run_seed):
    def ekf_update(x_check, P_check, y, g, G, R, residual):
        Gm = G(x_check)
        K = P_check @ Gm.T @ np.linalg.inv(Gm @ P_check @ Gm.T + R)
        return x_check + K @ residual(y, g(x_check)), (np.eye(len(x_check)) - K @ Gm) @ P_check
    text = _missing_failure(ekf_update)
    assert "must be finite" in text and "full-length vectors of numbers" in text
