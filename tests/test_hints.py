"""Hints in tiers: the concept and the section first, the formula when the learner asks for it
(a second identical failure in the notebook, ``checks.more_hints()``, ``grade --all-hints``),
and the tier recorded in the gradebook."""

import pytest

from kalman_course import checks
from kalman_course.checks import CheckFailed, harness, hints
from kalman_course.tooling import gradebook

MARKED = ("P̌ is wrong. Hint: the prior carries P̂ through the motion model and adds the process noise "
          "(lecture 03 §2: " + hints.formula("P̌ = F P̂ Fᵀ + Q") + ")")


@pytest.fixture
def tier_restored():
    yield
    hints.set_tier(1, escalate=False)


def test_tier_one_leaves_the_formula_out_and_says_how_to_see_it():
    text = hints.render(MARKED, 1)
    assert "F P̂ Fᵀ" not in text and "\x02" not in text and "\x03" not in text
    assert text.startswith("P̌ is wrong. Hint: the prior carries P̂ through the motion model and adds the "
                           "process noise (lecture 03 §2)")
    assert text.endswith(f"({hints.IN_NOTEBOOK})")


def test_tier_two_shows_everything_without_marks():
    assert hints.render(MARKED, 2) == MARKED.replace("\x02", "").replace("\x03", "")
    assert hints.render("plain text", 1) == "plain text"  # nothing left out: no note added


@pytest.mark.parametrize("marked, tier1", [
    ("Hint: use the gain. " + hints.formula("K = P Gᵀ S⁻¹."), "Hint: use the gain."),
    ("Hint: the gain (" + hints.formula("K = P Gᵀ S⁻¹") + ") weighs the residual",
     "Hint: the gain weighs the residual"),
    ("Hint: the gain, " + hints.formula("K = P Gᵀ S⁻¹") + ", weighs it", "Hint: the gain, weighs it"),
])
def test_what_is_left_reads_cleanly(marked, tier1):
    assert hints.render(marked, 1) == f"{tier1} ({hints.IN_NOTEBOOK})"


def test_a_bad_tier_is_refused():
    for bad in (0, 3, True, "2"):
        with pytest.raises(ValueError, match="level must be one of"):
            hints.set_tier(bad)


def _wrong_check():
    @harness.check
    def check_hint_tiers(value):
        if value != 1:
            raise CheckFailed(f"value is {value}. Hint: it counts one thing (lecture 01 §1). "
                              + hints.formula("value = 1"))
    return check_hint_tiers


def test_a_grader_cell_run_again_with_the_same_failure_shows_the_formula(tier_restored):
    hints.set_tier(1, escalate=True)
    check = _wrong_check()
    try:
        messages = []
        for value in (2, 2, 3, 2):
            with pytest.raises(CheckFailed) as failed:
                check.judge(value)
            messages.append(str(failed.value))
        assert "value = 1" not in messages[0] and "checks.more_hints()" in messages[0]
        assert messages[1].endswith("value = 1")        # the same failure again: tier 2
        assert "value = 1" not in messages[2]           # another failure: tier 1 again
        check.judge(1)                                  # passing forgets the failure
        with pytest.raises(CheckFailed) as failed:
            check.judge(2)
        assert "value = 1" not in str(failed.value)
    finally:
        harness._REGISTRY.pop("hint_tiers", None)


def test_without_escalation_a_check_says_the_same_every_time(tier_restored):
    hints.set_tier(1, escalate=False, more=hints.WHEN_GRADED)
    check = _wrong_check()
    try:
        seen = set()
        for _ in range(3):
            with pytest.raises(CheckFailed) as failed:
                check.judge(2)
            seen.add(str(failed.value))
        assert len(seen) == 1 and "--all-hints" in seen.pop()
        checks.more_hints()
        with pytest.raises(CheckFailed, match="value = 1$"):
            check.judge(2)
    finally:
        harness._REGISTRY.pop("hint_tiers", None)


def test_a_marked_message_is_never_shown_with_its_marks():
    exc = CheckFailed("kf_gain: K is wrong. Hint: the gain " + hints.formula("K = P Gᵀ S⁻¹"))
    assert not any("\x02" in line or "\x03" in line for line in exc._render_traceback_())


def test_the_gradebook_records_the_tier():
    run = gradebook.run_record([("a", "a.ipynb")], sandbox="none", seed=3, hint_tier=2)
    assert run["hint_tier"] == 2 and gradebook._run_problem(run) == ""
    older = {k: v for k, v in run.items() if k != "hint_tier"}  # written before tiers: tier 1
    assert gradebook._run_problem(older) == ""
    assert "not 1 or 2" in gradebook._run_problem({**run, "hint_tier": 3})
    assert "hint_tier is of type str" in gradebook._run_problem({**run, "hint_tier": "2"})
