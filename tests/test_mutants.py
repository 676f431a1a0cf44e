"""Every plausible mistake in the catalogues fails the check it targets, with a hint that
names it; every correct variant passes; every exercise stub is one of the mistakes. See
``tests/mutation_harness.py``."""

import ast

import nbformat
import pytest

from kalman_course.checks import cases
from kalman_course.tooling import authoring
from mutation_harness import SOLUTIONS, catalogues, solution

CATALOGUES = catalogues()


#: Run seeds of a graded run (kalman_course.checks.cases): each edit is also tried on the
#: inputs drawn from one of them (edit k from seed k mod 3), so that the catalogue as a whole
#: meets three draws besides the self-check's fixed cases.
DRAWN_SEEDS = (20261202, 7, 2**62 + 11)


def _cases(kind: str):
    # fixed cases first, then one group per seed: the checks' cached cases are drawn once per group
    for seed in (None, *DRAWN_SEEDS):
        for stem, module in CATALOGUES.items():
            for k, edit in enumerate(getattr(module, kind, ())):
                if seed is None or DRAWN_SEEDS[k % len(DRAWN_SEEDS)] == seed:
                    tag = "fixed" if seed is None else f"seed{DRAWN_SEEDS.index(seed)}"
                    yield pytest.param(module.NOTEBOOK, edit, seed, id=f"{stem}-{edit.check}-{k}-{tag}")


@pytest.fixture
def run_seed():
    """Set the run seed a test asks for; back to the fixed cases afterwards."""
    def use(seed):
        cases.set_run_seed(seed)
    yield use
    cases.set_run_seed(None)


@pytest.mark.parametrize("notebook, mutant, seed", list(_cases("MUTANTS")))
def test_mutant_fails_its_check_with_a_hint_that_names_it(notebook, mutant, seed, run_seed):
    run_seed(seed)
    outcome = solution(notebook).grade(mutant)
    assert not outcome.passed, f"{mutant.check} passes a mutant: {mutant.mistake}"
    assert not {"\x02", "\x03"} & set(outcome.message), f"a hint's tier marks reached the learner: {outcome.message!r}"
    assert mutant.keyword.lower() in outcome.message.lower(), (
        f"{mutant.check} rejects '{mutant.mistake}' but its message does not name it "
        f"(keyword {mutant.keyword!r}): {outcome.message}")


@pytest.mark.parametrize("notebook, variant, seed", list(_cases("EQUIVALENTS")))
def test_correct_variant_passes(notebook, variant, seed, run_seed):
    run_seed(seed)
    outcome = solution(notebook).grade(variant)
    assert outcome.passed, f"{variant.check} rejects a correct variant ({variant.mistake}): {outcome.message}"


@pytest.mark.parametrize("notebook, edit, seed", list(_cases("EQUIVALENT_MUTANTS")))
def test_listed_equivalent_mutant_is_really_equivalent(notebook, edit, seed, run_seed):
    run_seed(seed)
    # an edit listed as unable to change any result must indeed pass; if a check starts
    # rejecting it, it was not equivalent and belongs in MUTANTS
    outcome = solution(notebook).grade(edit)
    assert outcome.passed, f"{edit.check}: listed as equivalent ({edit.reason}) but rejected: {outcome.message}"


def test_every_graded_check_has_mutants():
    graded = {(module.NOTEBOOK, check) for module in CATALOGUES.values()
              for check in solution(module.NOTEBOOK).grader_call}
    covered = {(module.NOTEBOOK, edit.check) for module in CATALOGUES.values() for edit in module.MUTANTS}
    assert sorted(graded - covered) == []


def _code(source: str) -> str:
    """A cell's code as Python sees it: comments and layout do not count."""
    return ast.dump(ast.parse(source))


def _rendered_code(source: str) -> str | None:
    """The code of an edited solution cell as the exercise would have it, or None when the
    edit crossed a region's markers (a mutant of a neighbouring line, not this stub)."""
    try:
        return _code(authoring.render_source(source, set()))
    except authoring.AuthoringError:
        return None


STUBS = [(module.NOTEBOOK, stub) for module in CATALOGUES.values()
         for stub in authoring.list_stubs(nbformat.read(SOLUTIONS / f"{module.NOTEBOOK}.ipynb", as_version=4))]


@pytest.mark.parametrize("notebook, stub", STUBS, ids=[f"{nb}-{s.check}-{s.stub_id}" for nb, s in STUBS])
def test_every_stub_is_a_catalogued_mutant(notebook, stub):
    # the exercise's own stub is the first mistake a learner meets: its hint must name it,
    # which the catalogue's mutant tests check; here, that the catalogue holds it
    sol = solution(notebook)
    cell_id, _, number = stub.stub_id.rpartition(":")
    cell = next(c for c in sol.code if c.id == cell_id)
    wanted = _code(authoring.render_source(cell.source, {int(number)}))
    module = next(m for m in CATALOGUES.values() if m.NOTEBOOK == notebook)
    found = [edit.mistake for edit in module.MUTANTS if edit.check == stub.check and sol.cell_of(edit) is cell
             and _rendered_code(sol.edited_source(edit)) == wanted]
    assert found, (f"the stub {stub.stub.strip()!r} of {notebook} ({stub.check}) is not a mutant in "
                   f"its catalogue: add Edit({stub.check!r}, <reference lines>, <stub lines>, keyword=...)")
