"""Generated mutants (``tests/mutation_generator.py``) of every graded function: each fails its
check with a message that names its class, or is listed as unable to change any result.

A mutant of the classes that the harness reports by a property of the call (``in_place``,
``float32``, ``reshape``) must fail with the property's words ("in place", "single precision",
"shape"); a mutant of the other classes must fail with a hint (its message contains
"Hint:"), not merely an exception or a bare mismatch. A mutant listed in
``tests/mutants/generated_equivalents.py`` must pass instead (so an entry that stops being
equivalent fails), and every entry there must still be generated.

Cost: one mutant costs one run of its check, twice (in the kernel and through the plain-data
protocol; see ``tests/mutation_harness.py``), and a check that rejects a mutant often costs more
than one that passes it (it looks for the known mistake that explains the failure): about
10 ms to 0.3 s for most, seconds for the checks in :data:`SLOW_CHECKS`. Finding the mutants costs
one run of each graded check (which values are 1-D floats), about 15 s of CPU. The full set
(about 780 mutants) takes about 6 minutes of CPU; by default a deterministic subset runs
(about 250 mutants, under 1.5 minutes of CPU with the collection): for every (operator class, graded
check) pair its first :data:`PER_PAIR` mutants in source order, one for the checks in
:data:`SLOW_CHECKS` (named there, with their run time), and every listed equivalent. Set
``KALMAN_COURSE_ALL_MUTANTS=1`` to run them all. Mutants are graded on the fixed cases; with
``KALMAN_COURSE_ALL_MUTANTS=1`` a listed equivalent is also graded on one drawn run seed.

``python tests/test_generated_mutants.py`` grades the full set and prints, per chapter and
operator class, how many were generated, caught with a hint that names them, caught with a
generic message, listed equivalent and missed, then every mutant that did not meet its test.
"""

from __future__ import annotations

import collections
import functools
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

import mutation_generator as generator  # noqa: E402
from kalman_course import checks  # noqa: E402
from kalman_course.checks import cases  # noqa: E402
from mutation_harness import SOLUTIONS, CATALOGUES, Edit, Outcome, _verdict, catalogue, solution  # noqa: E402

ALL_MUTANTS = os.environ.get("KALMAN_COURSE_ALL_MUTANTS") == "1"

#: Mutants per (operator class, graded check) in the default subset.
PER_PAIR = 1

#: Checks that take about a second or more to run, or to reject a mutant (measured on the fixed
#: cases): only their first mutant of each class runs, even with KALMAN_COURSE_ALL_MUTANTS=1
#: (``python tests/test_generated_mutants.py`` grades all of theirs too).
SLOW_CHECKS = {
    "monte_carlo_nees": "a Monte-Carlo run of many filters, about 4 s",
    "nis_rescaled_std": "filter runs over a whole drive, about 3 s",
    "innovation_gate": "sweeps of gated runs, about 1.5 s",
    "consistency_verdict": "filter runs under several tunings, about 0.7 s",
    "eskf_run": "a failing run is replayed step by step to find the step at fault: 5 to 15 s a mutant",
    "mechanisation_run": "a failing run is replayed to find the step at fault: about 2 s a mutant",
}

#: A run seed of a graded run (kalman_course.checks.cases) for the second grading of a listed
#: equivalent (in the full run only).
DRAWN_SEED = 20261202

EQUIVALENTS = catalogue(CATALOGUES / "generated_equivalents.py").EQUIVALENTS


@dataclass(frozen=True)
class Generated:
    """A generated mutant: where it comes from and the edit that writes it."""

    notebook: str
    operator: str
    edit: Edit

    @property
    def key(self) -> tuple:
        return (self.edit.check, self.edit.cell, self.edit.old, self.edit.new)

    @property
    def listing(self) -> tuple:
        """How generated_equivalents.py names it: (check, mistake)."""
        return (self.edit.check, self.edit.mistake)

    @property
    def chapter(self) -> str:
        return self.notebook[:2]


def _listing(entry) -> tuple:
    return (entry.check, entry.mutant)


@functools.cache
def _returned_shapes(notebook: str, check: str, function_name: str) -> dict:
    """What the function returns, position by position (see
    :func:`mutation_generator.returned_shapes`), while its check runs on the unedited solution;
    once per function, however many regions it holds."""
    sol = solution(notebook)
    call = sol.grader_call[check]
    argument = call[call.index("(") + 1:call.rindex(")")]

    def run_check():
        cases.set_run_seed(None)
        _verdict(getattr(checks, check), eval(argument, sol.namespace))

    return generator.returned_shapes(run_check, sol.namespace, function_name)


def _returned(notebook: str, region):
    """``(one_dimensional, floating)`` for the reshape and float32 operators of ``region``:
    whether the value at a position of what its function returns is a 1-D array (of numbers or
    booleans), and whether it holds floats."""
    if region.function is None:
        return (lambda position: False), (lambda position: False)
    shapes = _returned_shapes(notebook, region.check, region.function.name)
    return ((lambda position: shapes.get(position, (None, None))[0] == 1),
            (lambda position: shapes.get(position, (None, None))[1] == "f"))


@functools.cache
def generated() -> tuple[Generated, ...]:
    """Every generated mutant of every solution, in notebook, cell and source order; the same
    edit found from two regions of one function (its ``return`` mutants) is kept once."""
    found, seen = [], set()
    for path in sorted(SOLUTIONS.glob("*.ipynb")):
        sol = solution(path.stem)
        for cell in sol.code:
            for region in generator.regions(cell.id, cell.source):
                if region.check not in sol.grader_call:
                    raise LookupError(f"{path.name}:{cell.id}: a region of {region.check!r}, which no grader cell calls")
                for mutation in generator.mutations(region, *_returned(path.stem, region)):
                    item = Generated(path.stem, mutation.operator, generator.as_edit(region, mutation))
                    if item.key not in seen:
                        seen.add(item.key)
                        found.append(item)
    return tuple(found)


def selected(everything: tuple[Generated, ...], run_all: bool, limit_slow: bool = True) -> list[Generated]:
    """The mutants a run grades: all (``run_all``) or the default subset (module docstring);
    one per class for the checks in :data:`SLOW_CHECKS` unless not ``limit_slow``, and every
    listed equivalent."""
    listed = {_listing(e) for e in EQUIVALENTS}
    taken: collections.Counter = collections.Counter()
    chosen = []
    for item in everything:
        pair = (item.edit.check, item.operator)
        limit = 1 if limit_slow and item.edit.check in SLOW_CHECKS else (None if run_all else PER_PAIR)
        if item.listing in listed or limit is None or taken[pair] < limit:
            chosen.append(item)
        if item.listing not in listed:
            taken[pair] += 1
    return chosen


def _label(items) -> list[str]:
    numbers: collections.Counter = collections.Counter()
    labels = []
    for item in items:
        pair = (item.notebook[:2], item.edit.check, item.operator)
        labels.append("-".join((*pair, str(numbers[pair]))))
        numbers[pair] += 1
    return labels


EVERY = generated()
_LABELS = dict(zip((item.key for item in EVERY), _label(EVERY)))
SELECTED = selected(EVERY, ALL_MUTANTS)


def caught_with_its_name(item: Generated, outcome: Outcome) -> bool:
    """Whether a failing mutant's message names its class (or, for the classes without a
    generic name, gives a hint)."""
    return item.edit.keyword.lower() in outcome.message.lower()


@pytest.fixture
def fixed_cases_afterwards():
    yield
    cases.set_run_seed(None)


@pytest.mark.parametrize("item", SELECTED, ids=[_LABELS[item.key] for item in SELECTED])
def test_generated_mutant_fails_naming_its_class_or_is_listed_equivalent(item, fixed_cases_afterwards):
    listed = {_listing(e): e for e in EQUIVALENTS}
    outcome = solution(item.notebook).grade(item.edit)
    if item.listing in listed:
        reason = listed[item.listing].reason
        assert outcome.passed, f"{item.edit.check}: listed as equivalent ({reason}) but rejected: {outcome.message}"
        if not ALL_MUTANTS:
            return
        cases.set_run_seed(DRAWN_SEED)
        again = solution(item.notebook).grade(item.edit)
        assert again.passed, (f"{item.edit.check}: listed as equivalent ({reason}) but rejected under run seed "
                              f"{DRAWN_SEED}: {again.message}")
        return
    assert not outcome.passed, f"{item.edit.check} passes a generated mutant ({item.edit.mistake})"
    assert caught_with_its_name(item, outcome), (
        f"{item.edit.check} rejects the generated mutant ({item.edit.mistake}) but its message does not "
        f"contain {item.edit.keyword!r}: {outcome.message}")


def test_every_listed_equivalent_is_still_generated():
    generated_now = {item.listing for item in EVERY}
    stale = [f"{e.check}: {e.mutant}" for e in EQUIVALENTS if _listing(e) not in generated_now]
    assert stale == [], "entries of generated_equivalents.py that the generator no longer makes (remove them)"


def test_every_listed_equivalent_gives_a_reason():
    assert [e for e in EQUIVALENTS if len(e.reason.split()) < 4] == []


def test_the_default_subset_covers_every_class_of_every_check():
    every_pair = {(item.edit.check, item.operator) for item in EVERY}
    chosen = {(item.edit.check, item.operator) for item in selected(EVERY, run_all=False)}
    assert every_pair - chosen == set()


def test_every_graded_check_has_generated_mutants():
    graded = {check for path in sorted(SOLUTIONS.glob("*.ipynb")) for check in solution(path.stem).grader_call}
    mutated = {item.edit.check for item in EVERY}
    assert graded - mutated == set()


def summary() -> None:
    """Grade every generated mutant; print counts per chapter and class, then the failures."""
    from kalman_course.checks import hints

    hints.set_tier(1, escalate=False)  # as tests/conftest.py has it
    listed = {_listing(e) for e in EQUIVALENTS}
    table: dict = collections.defaultdict(collections.Counter)
    unmet = []
    seconds: collections.Counter = collections.Counter()
    for item in selected(EVERY, run_all=True, limit_slow=False):
        cases.set_run_seed(None)
        started = time.perf_counter()
        try:
            outcome = solution(item.notebook).grade(item.edit)
        except AssertionError as exc:  # judged differently in the kernel and from outside
            outcome = Outcome(False, f"HARNESS: {exc}")
        seconds[item.edit.check] += time.perf_counter() - started
        row = table[(item.chapter, item.operator)]
        row["generated"] += 1
        if item.listing in listed:
            row["equivalent"] += 1
            if not outcome.passed:
                unmet.append(("listed but rejected", item, outcome))
        elif outcome.passed:
            row["missed"] += 1
            unmet.append(("missed", item, outcome))
        elif caught_with_its_name(item, outcome):
            row["named"] += 1
        else:
            row["generic"] += 1
            unmet.append(("generic", item, outcome))
    columns = ("generated", "named", "generic", "equivalent", "missed")
    print(f"{'chapter':8s}{'class':11s}" + "".join(f"{c:>11s}" for c in columns))
    for (chapter, operator), row in sorted(table.items()):
        print(f"{chapter:8s}{operator:11s}" + "".join(f"{row[c]:11d}" for c in columns))
    total = sum(table.values(), collections.Counter())
    print(f"{'all':19s}" + "".join(f"{total[c]:11d}" for c in columns))
    print("seconds of grading per check:", ", ".join(f"{c} {t:.1f}" for c, t in seconds.most_common()))
    for kind, item, outcome in unmet:
        print(f"\n[{kind}] {_LABELS[item.key]}: {item.edit.mistake}\n    {outcome.message[:400]}", flush=True)


if __name__ == "__main__":
    summary()
