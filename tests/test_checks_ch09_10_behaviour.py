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


# ---- the augmented matrices with correlated components, one τ each (exercise 10 §2) --------

@pytest.mark.parametrize("seed", [None, 7, 2**62 + 11])
def test_the_augmented_cases_have_correlated_components_and_their_own_time_constants(seed, run_seed):
    run_seed(seed)
    for F, BQBt, Sigma, T, tau in real_sensors.augmented_cases():
        assert np.allclose(Sigma, Sigma.T, rtol=0.0, atol=0.0) and np.linalg.eigvalsh(Sigma).min() > 0.0
        d = np.sqrt(np.diag(Sigma))
        assert np.abs(Sigma / np.outer(d, d) - np.eye(6)).max() > 0.25          # correlated components
        assert tau.shape == (6,) and len(set(np.round(tau / tau.min(), 6))) == 6   # no two τ alike
        Q_e = real_sensors._stationary_noise(Sigma, T, tau)
        assert np.linalg.eigvalsh(Q_e).min() > -1e-14 * np.abs(Sigma).max()    # a covariance for every step


def test_the_stationary_covariance_is_kept_by_steps_of_any_length_and_composes():
    sigma, tau = np.array([0.3, 0.1, 0.5, 0.004, 0.006, 0.02]), np.array([2.0, 0.5, 4.0, 0.3, 0.7, 0.1])
    Sigma = real_sensors.stationary_covariance(sigma, tau, real_sensors.AUG_DRIVE_CORRELATION)
    np.testing.assert_allclose(np.sqrt(np.diag(Sigma)), sigma, rtol=1e-14)
    for T in (1e-6, 0.01, 1.0, 50.0):
        Phi = np.diag(real_sensors._decays(T, tau))
        np.testing.assert_allclose(Phi @ Sigma @ Phi.T + real_sensors._stationary_noise(Sigma, T, tau), Sigma,
                                   rtol=1e-12, atol=1e-18)
    # two steps T1 and T2 compose to one step T1 + T2, from a covariance that is not stationary
    P, (T1, T2) = 0.3 * Sigma, (0.04, 0.27)
    for T in (T1, T2):
        Phi = np.diag(real_sensors._decays(T, tau))
        P = Phi @ P @ Phi.T + real_sensors._stationary_noise(Sigma, T, tau)
    Phi = np.diag(real_sensors._decays(T1 + T2, tau))
    np.testing.assert_allclose(P, Phi @ (0.3 * Sigma) @ Phi.T + real_sensors._stationary_noise(Sigma, T1 + T2, tau),
                               rtol=1e-12, atol=1e-18)
    # continuous time: A Σ + Σ A is the drives' (positive definite) density
    A = np.diag(1.0 / tau)
    assert np.linalg.eigvalsh(A @ Sigma + Sigma @ A).min() > 0.0


def test_the_lectures_per_component_blocks_are_named_for_dropping_the_correlations():
    def augmented_matrices(F, BQBt, Sigma, T, tau):
        phi = np.exp(-T / tau)
        F_aug, Q_aug = np.zeros((21, 21)), np.zeros((21, 21))
        F_aug[:15, :15], F_aug[15:, 15:] = F, np.diag(phi)
        Q_aug[:15, :15], Q_aug[15:, 15:] = BQBt, np.diag(np.diag(Sigma) * (1.0 - phi ** 2))
        return F_aug, Q_aug

    message = _message(checks.augmented_matrices, augmented_matrices)
    assert "correlations between the components are dropped" in message
    assert "F_e Σ F_eᵀ + Q_e = Σ" not in message


def test_one_time_constant_for_all_components_is_named():
    def augmented_matrices(F, BQBt, Sigma, T, tau):
        phi = np.exp(-T / np.mean(tau))
        F_aug, Q_aug = np.zeros((21, 21)), np.zeros((21, 21))
        F_aug[:15, :15], F_aug[15:, 15:] = F, phi * np.eye(6)
        Q_aug[:15, :15], Q_aug[15:, 15:] = BQBt, (1.0 - phi ** 2) * Sigma
        return F_aug, Q_aug

    assert "one time constant" in _message(checks.augmented_matrices, augmented_matrices)


# ---- the camera's lever arm in the relative pose (exercise 10 §3) -------------------------

def test_kittis_camera_lever_arm_comes_from_the_calibration():
    kitti, other = real_sensors.camera_lever_arms()
    np.testing.assert_allclose(kitti, [1.102, -0.319, 0.746], atol=1e-3)     # ahead, right, above the IMU
    assert np.all(np.abs(other) >= 0.4) and np.all(np.sign(other[:2]) != np.sign(kitti[:2]))


@pytest.mark.parametrize("seed", [None, 7, 2**62 + 11])
def test_the_lever_arm_jacobian_agrees_with_central_differences_and_every_listed_block_is_far(seed, run_seed):
    run_seed(seed)
    rows = {"y_p": slice(0, 3), "y_θ": slice(3, 6)}
    cols = {name: slice(a, b) for name, a, b in real_sensors._G_COLS}
    lever_cases = 0
    farthest = {}
    for label, Rc, dp, dR, t, G_fd in real_sensors.jacobian_cases():
        ref = real_sensors._reference_jacobian(Rc, dp, dR, t)
        np.testing.assert_allclose(ref, G_fd, atol=1e-8, rtol=0.0)
        lever_cases += bool(np.any(t))
        for (r, c), alternatives in real_sensors._g_alternatives(Rc, dp, dR, t).items():
            for wrong, why in alternatives:
                key = (r, c, why)
                farthest[key] = max(farthest.get(key, 0.0), np.abs(wrong - ref[rows[r], cols[c]]).max())
    assert lever_cases == 2 * len(real_sensors.POSE_PAIRS)
    assert min(farthest.values()) > 0.9     # every listed mistake errs by more than 0.9 on some case


def test_the_lectures_jacobian_is_named_on_a_cameras_increments():
    def relative_pose_jacobian(R_clone, dp_check, dR_check, lever_arm=np.zeros(3)):
        G = np.zeros((6, 21))
        G[0:3, 0:3], G[3:6, 6:9] = R_clone.T, np.eye(3)
        G[0:3, 15:18], G[0:3, 18:21], G[3:6, 18:21] = -R_clone.T, so3.hat(dp_check), -dR_check.T
        return G

    message = _message(checks.relative_pose_jacobian, relative_pose_jacobian)
    assert "lever arm" in message and "swings the camera" in message and "−ΔŘ [t]×" not in message


def test_a_residual_that_ignores_the_lever_arm_is_named():
    def relative_pose_residual(p_clone, R_clone, p_check, R_check, dp_meas, dR_meas, lever_arm=np.zeros(3)):
        dp, dR = R_clone.T @ (p_check - p_clone), R_clone.T @ R_check
        return np.concatenate([dp - dp_meas, so3.log(dR_meas.T @ dR)])

    assert "lever arm is ignored" in _message(checks.relative_pose_residual, relative_pose_residual)
