"""Chapters 09–10's graders beyond the mutation catalogues: the verdict taken from single values
is named, the tiers of their hints, the sweeps of the singular regimes (T/τ, turns near 0 and
near π) and the summary of how many cases are wrong."""

import numpy as np
import pytest

from kalman_course import checks
from kalman_course.checks import cases, consistency, hints, real_sensors
from kalman_course.checks.harness import known_mistake
from kalman_course.core import so3


@pytest.fixture
def run_seed():
    """Set a run seed for one test; back to the fixed cases afterwards."""
    yield cases.set_run_seed
    cases.set_run_seed(None)


@pytest.fixture
def tier_two():
    """Render hints at tier 2 for one test; back to tier 1 (tests/conftest.py) afterwards."""
    hints.set_tier(2, escalate=False)
    yield
    hints.set_tier(1, escalate=False)


def _chi2_interval(dof, n_runs, confidence=0.95):
    from kalman_course.evaluation.metrics import chi2_ppf
    return (chi2_ppf((1 - confidence) / 2, dof * n_runs) / n_runs,
            chi2_ppf((1 + confidence) / 2, dof * n_runs) / n_runs)


def share_verdict(nis_values, dof, confidence=0.95):
    """The mistake of issue 25: the share of single values inside the one-step interval."""
    lo, hi = _chi2_interval(dof, 1, confidence)
    if np.mean((nis_values >= lo) & (nis_values <= hi)) >= confidence:
        return "consistent"
    return "overconfident" if np.median(nis_values) > dof else "underconfident"


def _message(check, fn) -> str:
    with pytest.raises(checks.CheckFailed) as failed:
        check.judge(fn)
    return str(failed.value)


def test_a_verdict_from_the_share_of_single_values_is_named_without_the_formula():
    message = _message(checks.consistency_verdict, share_verdict)
    assert "share of single NIS values" in message
    assert "lecture 09 §1" in message.lower() and "interval of a mean of N" in message
    assert "χ²(N · dof)" not in message and hints.IN_NOTEBOOK in message


def test_the_share_verdict_hint_gives_the_interval_of_the_mean_at_tier_two(tier_two):
    message = _message(checks.consistency_verdict, share_verdict)
    assert "N · NIS̄ ~ χ²(N · dof)" in message and hints.IN_NOTEBOOK not in message


@pytest.mark.parametrize("seed", [None, 7, 20261202])
def test_the_share_rule_is_told_apart_from_every_listed_rule(seed, run_seed):
    run_seed(seed)
    records = consistency.verdict_cases()
    answers = [share_verdict(*r[1:]) for r in records]
    assert answers != list(consistency._expected_verdicts())
    why = known_mistake(answers, records, consistency._verdict_mistakes(),
                        lambda a, w, k: w is not None and consistency._allows(a, w),
                        evaluate=lambda rule, record: rule(*record[1:]))
    assert why == consistency._SHARE_HINT


def test_the_nees_hint_leaves_the_formula_for_tier_two():
    def nees(error, P):
        return float(error @ P @ error)

    message = _message(checks.consistency_nees, nees)
    assert "INVERSE covariance" in message and "lecture 09 §1" in message
    assert "eᵀ P⁻¹ e" not in message


def test_a_nees_in_single_precision_is_told_so():
    def nees(error, P):
        Pf, ef = P.astype(np.float32), error.astype(np.float32)
        return float(np.linalg.solve(Pf, ef) @ ef)

    assert "single precision" in _message(checks.consistency_nees, nees)


@pytest.mark.parametrize("seed", [None, 7, 2**62 + 11])
def test_the_gauss_markov_sweep_spans_short_and_long_steps(seed, run_seed):
    run_seed(seed)
    sweep = real_sensors.gm_sweep()
    ratios = np.array([T / tau for _, T, tau in sweep])
    steps = np.array([T for _, T, _ in sweep])
    sigma = np.concatenate([s for s, _, _ in sweep])
    assert ratios.min() <= 3e-6 and ratios.max() >= 3e2
    # no gap wider than a decade between neighbouring ratios
    assert np.max(np.diff(np.log10(np.sort(ratios)))) <= 1.0
    assert steps.min() < 1e-5 and steps.max() > 1e3
    assert sigma.min() < 0.1 and sigma.max() > 10.0
    augmented = np.array([T / tau for _, _, _, T, tau in real_sensors.augmented_cases()])
    assert augmented.min() < 1e-5 and augmented.max() > 1e2


def test_a_cut_off_for_long_steps_is_caught_by_the_sweep():
    def gauss_markov_blocks(sigma, T, tau):
        phi = 0.0 if T > 20 * tau else np.exp(-T / tau)
        return phi * np.eye(6), np.diag(sigma ** 2 * (1.0 - phi ** 2))

    message = _message(checks.gauss_markov_blocks, gauss_markov_blocks)
    assert "sweep" in message and "T/τ = 22" in message


@pytest.mark.parametrize("seed", [None, 7, 2**62 + 11])
def test_the_turn_sweep_reaches_the_identity_and_the_half_turn_both_ways(seed, run_seed):
    run_seed(seed)
    increments = [so3.log(R0.T @ R1) for _, _, R0, _, R1 in real_sensors.turn_sweep_pairs()]
    angles = np.array([np.linalg.norm(v) for v in increments])
    assert angles.min() < 1e-7 and np.pi - angles.max() < 1e-5
    # every angle about an axis and about its opposite
    for first, second in zip(increments[0::2], increments[1::2]):
        if np.linalg.norm(first) < 3.0:
            np.testing.assert_allclose(first, -second, atol=1e-12)
    assert any(np.pi - angle < 1e-5 for angle in angles[1::2])
    labels = [label for label, *_ in real_sensors.jacobian_cases()]
    assert sum("turned by" in label for label in labels) == 2


def test_a_relative_motion_mistake_says_how_many_cases_are_wrong():
    def relative_motion(p0, R0, p1, R1):
        return R0.T @ (p1 - p0), R1 @ R0.T

    message = _message(checks.relative_motion, relative_motion)
    total = len(real_sensors.pose_pairs()) + len(real_sensors.turn_sweep_pairs())
    assert "NAVIGATION frame" in message and f"of {total} cases wrong" in message


def test_a_relative_motion_into_the_callers_pose_is_named():
    def relative_motion(p0, R0, p1, R1):
        R1[:] = R0.T @ R1
        return R0.T @ (p1 - p0), R1

    assert "changed its argument R1 in place" in _message(checks.relative_motion, relative_motion)
