"""Chapters 01–03's checks teach in tiers and sweep the CV model's time step.

Tier 1 of a hint names the concept and the lecture section without the formula; the
sections it names exist in the lecture; the sweep of ``cv_process_noise`` reaches very short
and very long steps, on both sides of σ_a = 1, also when drawn under a run seed. Exercise 02's
linear map is derived for a noise correlated with x: its reference is checked against the
blocks of the joint covariance and against samples, and its cases make the lecture's
independent-noise formulas fail. Exercise 03's row 0 is decided by the learner: each wrong
decision about the belief at t[0] gets a hint that names it.
"""

from __future__ import annotations

import re
from pathlib import Path

import nbformat
import numpy as np
import pytest

from kalman_course import checks
from kalman_course.checks import CheckFailed, bayes, cases, gaussians, hints, kf

ROOT = Path(__file__).resolve().parent.parent
MODULES = {"01": bayes, "02": gaussians, "03": kf}


def _sections(chapter: str) -> set[str]:
    """The numbers of the lecture's ``## k · ...`` headings."""
    notebook = nbformat.read(next((ROOT / "notebooks").glob(f"{chapter}_*.ipynb")), as_version=4)
    return {found[1] for cell in notebook.cells if cell.cell_type == "markdown"
            for found in re.finditer(r"^## (\d+) ·", cell.source, re.M)}


@pytest.mark.parametrize("chapter", sorted(MODULES))
def test_every_section_a_hint_names_is_a_heading_of_its_lecture(chapter):
    source = Path(MODULES[chapter].__file__).read_text(encoding="utf-8")
    named = re.findall(rf"lecture {chapter} §(\d+)((?: and §\d+)*)", source)
    # a hint built by a module's _about(why, section, formula) names its section as an argument
    named += [(section, "") for section in re.findall(r'_about\([^()]*?"(\d+)(?: and §\d+)?", ', source, re.S)]
    numbers = {n for first, more in named for n in (first, *re.findall(r"\d+", more))}
    assert numbers, f"no hint of chapter {chapter} names a lecture section"
    assert numbers <= _sections(chapter), f"sections that lecture {chapter} does not have: {numbers - _sections(chapter)}"


def _message(check, fn) -> str:
    with pytest.raises(CheckFailed) as failed:
        check.judge(fn)
    return str(failed.value)


def _prior_without_q(x_hat, P_hat, F, Q):
    return F @ x_hat, F @ P_hat @ F.T


def _q_of_the_state(T, sigma_a, dim=3):
    I = np.eye(dim)
    return np.block([[I, T * I], [np.zeros((dim, dim)), I]]), sigma_a**2 * np.eye(2 * dim)


@pytest.mark.parametrize("check, fn, concept, formula", [
    (checks.kf_predict, _prior_without_q, "the process noise is missing: the step adds its uncertainty (lecture 03 §2)", "P̌ = F P̂ Fᵀ + Q"),
    (checks.cv_process_noise, _q_of_the_state, "process-noise Jacobian B", "Q = B (σ_a² I) Bᵀ"),
])
def test_tier_one_names_the_concept_and_section_and_tier_two_adds_the_formula(check, fn, concept, formula):
    first = _message(check, fn)
    assert concept in first and "lecture 03 §" in first
    assert formula not in first and first.endswith(f"({hints.IN_NOTEBOOK})")
    try:
        hints.set_tier(2, escalate=False)
        assert formula in _message(check, fn)
    finally:
        hints.set_tier(1, escalate=False)


def _cv_with_a_cut_off(T, sigma_a, dim=3):
    """The reference CV model, with no process noise below 1 ms (a learner's special case)."""
    F, Q = kf.cv_matrices_reference(T, sigma_a, dim)
    return F, (Q if T >= 1e-3 else np.zeros_like(Q))


def test_the_sweep_finds_a_cut_off_for_short_steps_the_three_cases_miss():
    # the three cases' steps are 0.1 s and longer: only the sweep reaches below 1 ms
    assert min(T for T, _ in kf.CV_CASES) > 1e-3
    message = _message(checks.cv_process_noise, _cv_with_a_cut_off)
    assert "very short and very long" in message and "T=1e-06" in message


@pytest.fixture
def run_seed():
    yield cases.set_run_seed
    cases.set_run_seed(None)


@pytest.mark.parametrize("seed", (20261202, 7))
def test_a_drawn_sweep_keeps_the_fixed_ones_decades_and_sides_of_one(seed, run_seed):
    run_seed(seed)
    drawn = kf._cv_sweep()
    assert drawn != kf.CV_SWEEP and len(drawn) == len(kf.CV_SWEEP)
    for (T, sigma), (T_fixed, sigma_fixed) in zip(drawn, kf.CV_SWEEP):
        assert T_fixed / 3.01 <= T <= T_fixed * 3.01
        assert (sigma < 1.0) == (sigma_fixed < 1.0) and abs(np.log(sigma)) >= np.log(1.1)
    checks.cv_process_noise.judge(kf.cv_matrices_reference)  # the reference passes the drawn sweep


# ---------------------------------------------------------------------------------------
# exercise 02: the moments of y = G x + n for a noise correlated with x (a derivation)
# ---------------------------------------------------------------------------------------

def _correlated_case(n=3, m=2, seed=5):
    """(mu_x, Sigma_xx, G, R, Sigma_xn): dense Σ_xx and R of scales ≠ 1, and Σ_xn = Σ_xx^½ K R^½
    with ‖K‖₂ = 0.8, a strong correlation that keeps Cov([x; n]) positive definite."""
    rng = np.random.default_rng(seed)
    A, B = rng.normal(size=(n, n)) * 1.7, rng.normal(size=(m, m)) * 1.3
    Sxx, R = A @ A.T + 0.2 * np.eye(n), B @ B.T + 0.2 * np.eye(m)
    K = rng.normal(size=(n, m))
    Sxn = gaussians._sqrtm(Sxx) @ (0.8 / np.linalg.norm(K, 2) * K) @ gaussians._sqrtm(R)
    return rng.normal(size=n), Sxx, 0.5 * rng.normal(size=(m, n)), R, Sxn


def test_the_correlated_reference_is_the_blocks_of_the_joint_covariance():
    # lecture 02 §5's compact form, [x; y] = T [x; n] with T = [[I, 0], [G, I]], applied to a
    # full Cov([x; n]): an independent computation of all three moments
    mu_x, Sxx, G, R, Sxn = _correlated_case()
    n, m = len(mu_x), len(R)
    mu_y, Syy, Sxy = gaussians.linear_map_moments_reference(mu_x, Sxx, G, R, Sxn)
    T = np.block([[np.eye(n), np.zeros((n, m))], [G, np.eye(m)]])
    joint = T @ np.block([[Sxx, Sxn], [Sxn.T, R]]) @ T.T
    assert np.allclose(mu_y, G @ mu_x, rtol=1e-12)
    assert np.allclose(Syy, joint[n:, n:], rtol=1e-12) and np.allclose(Sxy, joint[:n, n:], rtol=1e-12)
    assert np.array_equal(Syy, Syy.T)
    # and the lecture's moments again when the noise is independent of x
    independent = gaussians.linear_map_moments_reference(mu_x, Sxx, G, R, np.zeros((n, m)))
    for got, want in zip(independent, gaussians.gaussians.linear_map(mu_x, Sxx, G, R)):
        assert np.allclose(got, want, rtol=1e-12)


def test_the_correlated_reference_agrees_with_samples():
    mu_x, Sxx, G, R, Sxn = _correlated_case(seed=8)
    n = len(mu_x)
    joint = np.block([[Sxx, Sxn], [Sxn.T, R]])
    draws = np.random.default_rng(3).multivariate_normal(np.zeros(len(joint)), joint, size=400_000,
                                                         method="cholesky")
    xs, ns = mu_x + draws[:, :n], draws[:, n:]
    ys = xs @ G.T + ns
    mu_y, Syy, Sxy = gaussians.linear_map_moments_reference(mu_x, Sxx, G, R, Sxn)
    cross = (xs - xs.mean(axis=0)).T @ (ys - ys.mean(axis=0)) / len(ys)
    gap_yy, gap_xy = np.max(np.abs(np.cov(ys.T) - Syy)), np.max(np.abs(cross - Sxy))
    assert gap_yy < 0.02 * np.max(np.abs(Syy)) and gap_xy < 0.02 * np.max(np.abs(Sxy))
    # the independent-noise formulas are off by far more than the sampling noise
    assert np.max(np.abs(np.cov(ys.T) - (G @ Sxx @ G.T + R))) > 10 * gap_yy
    assert np.max(np.abs(cross - Sxx @ G.T)) > 10 * gap_xy


def test_the_correlated_reference_names_a_misshapen_cross_covariance():
    mu_x, Sxx, G, R, Sxn = _correlated_case()
    with pytest.raises(ValueError, match="Sigma_xn must have shape"):
        gaussians.linear_map_moments_reference(mu_x, Sxx, G, R, Sxn.T)


@pytest.mark.parametrize("seed", (None, 20261202, 7))
def test_every_linear_case_correlates_x_and_the_noise_so_that_the_lecture_formulas_fail(seed, run_seed):
    run_seed(seed)
    gaussians._linear_cases.cache_clear()
    try:
        for (mu_x, Sxx, G, R, Sxn), (mu_y, Syy, Sxy), _ in gaussians._linear_cases():
            assert np.linalg.eigvalsh(np.block([[Sxx, Sxn], [Sxn.T, R]]))[0] > 1e-3   # a covariance of [x; n]
            cross = G @ Sxn
            if len(R) > 1:   # G Σ_xn not symmetric: one cross term, or 2 G Σ_xn, is another Σ_yy
                assert np.max(np.abs(cross - cross.T)) > 0.05 * np.max(np.abs(cross))
            assert np.max(np.abs(G @ Sxx @ G.T + R - Syy)) > 1e-2 * np.max(np.abs(Syy))
            assert np.max(np.abs(Sxx @ G.T - Sxy)) > 1e-2 * np.max(np.abs(Sxy))
    finally:
        gaussians._linear_cases.cache_clear()


def _moments_of_an_independent_noise(mu_x, Sigma_xx, G, R, Sigma_xn):
    """Lecture 02 §5's formulas, with the cross-covariance ignored (the copied formula)."""
    return G @ mu_x, G @ Sigma_xx @ G.T + R, Sigma_xx @ G.T


def _one_cross_term(mu_x, Sigma_xx, G, R, Sigma_xn):
    return G @ mu_x, G @ Sigma_xx @ G.T + G @ Sigma_xn + R, Sigma_xx @ G.T + Sigma_xn


@pytest.mark.parametrize("fn, concept", [
    (_moments_of_an_independent_noise, "the noise is correlated with x"),
    (_one_cross_term, "only one of the two cross terms"),
])
def test_the_linear_map_hints_name_the_derivation_and_keep_its_result_for_tier_two(fn, concept):
    first = _message(checks.linear_map_moments, fn)
    assert concept in first and "lecture 02 §5" in first
    assert "G Σ_xn + Σ_xnᵀ Gᵀ" not in first and first.endswith(f"({hints.IN_NOTEBOOK})")
    try:
        hints.set_tier(2, escalate=False)
        assert "Σ_yy = G Σ_xx Gᵀ + G Σ_xn + Σ_xnᵀ Gᵀ + R" in _message(checks.linear_map_moments, fn)
    finally:
        hints.set_tier(1, escalate=False)


# ---------------------------------------------------------------------------------------
# exercise 03: row 0 of run_gnss_kf is the learner's decision (the belief at t[0])
# ---------------------------------------------------------------------------------------

SIGMA_GNSS, SIGMA_V0 = 1.6, 15.0       # both ≠ 1, so that σ and σ² differ
Y0, Y1, STEP = np.array([10.0, -4.0, 2.0]), np.array([21.0, -9.0, 2.5]), 1.001


def _row_zero(position=None, velocity=None, pos_var=SIGMA_GNSS**2, vel_var=SIGMA_V0**2):
    x0 = np.r_[Y0 if position is None else position, np.zeros(3) if velocity is None else velocity]
    return x0, np.diag(np.r_[np.full(3, pos_var), np.full(3, vel_var)])


def _coupled(block):
    x0, P0 = _row_zero()
    P0 = P0.copy()
    if block == "position-velocity":
        P0[:3, 3:] = P0[3:, :3] = 0.4 * SIGMA_GNSS * SIGMA_V0 * np.eye(3)
    else:
        P0[0, 1] = P0[1, 0] = 0.5 * SIGMA_GNSS**2
    return x0, P0


@pytest.mark.parametrize("row, words", [
    ((np.zeros(6), np.eye(6)), "placeholder"),
    (_row_zero(vel_var=1e-4), "near zero"),
    (_row_zero(vel_var=0.0), "near zero"),
    (_row_zero(vel_var=SIGMA_V0), "standard deviation σ = 15"),
    (_row_zero(vel_var=SIGMA_GNSS**2), "not the fix's error"),
    (_row_zero(pos_var=SIGMA_GNSS), "position variance must be σ²"),
    (_row_zero(pos_var=0.0), "exact"),
    (_row_zero(pos_var=1.0), "as if σ_gnss were 1"),
    (_row_zero(pos_var=SIGMA_V0**2), "throws away"),
    (_coupled("position-velocity"), "couples the position and velocity"),
    (_coupled("position"), "three axes are independent"),
    (_row_zero(position=np.zeros(3)), "origin"),
    (_row_zero(velocity=(Y1 - Y0) / STEP), "second fix"),
    (_row_zero(velocity=np.full(3, 2.0)), "direction of travel"),
])
def test_each_wrong_decision_about_row_zero_is_named_and_the_matrix_kept_for_tier_two(row, words):
    hint = kf._initial_state_hint(*row, Y0, SIGMA_GNSS, SIGMA_V0, second=(STEP, Y1))
    assert hint is not None and words in hint
    first = hints.render(hint, 1)
    assert words in first and "lecture 03 §9" in first and "P₀ = diag" not in first
    assert "P₀ = diag(σ_gnss² I, σ_v0² I)" in hints.render(hint, 2) or "x₀ = [y[0], 0]" in hints.render(hint, 2)


def test_the_right_row_zero_has_no_hint_and_a_later_fix_never_enters_it():
    assert kf._initial_state_hint(*_row_zero(), Y0, SIGMA_GNSS, SIGMA_V0, second=(STEP, Y1)) is None
    # a velocity that is not the two fixes' difference is not blamed on the second fix
    hint = kf._initial_state_hint(*_row_zero(velocity=(Y1 - Y0) / (2 * STEP)), Y0, SIGMA_GNSS, SIGMA_V0,
                                  second=(STEP, Y1))
    assert "second fix" not in hint and "direction of travel" in hint
