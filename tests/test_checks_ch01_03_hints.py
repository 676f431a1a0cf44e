"""Chapters 01–03's checks teach in tiers and sweep the CV model's time step.

Tier 1 of a hint names the concept and the lecture section without the formula; the
sections it names exist in the lecture; the sweep of ``cv_process_noise`` reaches very short
and very long steps, on both sides of σ_a = 1, also when drawn under a run seed.
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
