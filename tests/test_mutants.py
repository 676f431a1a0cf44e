"""Every plausible mistake in the catalogues fails the check it targets, with a hint that
names it; every correct variant passes; every exercise stub is one of the mistakes. See
``tests/mutation_harness.py``."""

import ast

import nbformat
import pytest

from kalman_course.tooling import authoring
from mutation_harness import SOLUTIONS, catalogues, solution

CATALOGUES = catalogues()


def _cases(kind: str):
    for stem, module in CATALOGUES.items():
        for k, edit in enumerate(getattr(module, kind, ())):
            yield pytest.param(module.NOTEBOOK, edit, id=f"{stem}-{edit.check}-{k}")


@pytest.mark.parametrize("notebook, mutant", list(_cases("MUTANTS")))
def test_mutant_fails_its_check_with_a_hint_that_names_it(notebook, mutant):
    outcome = solution(notebook).grade(mutant)
    assert not outcome.passed, f"{mutant.check} passes a mutant: {mutant.mistake}"
    assert mutant.keyword.lower() in outcome.message.lower(), (
        f"{mutant.check} rejects '{mutant.mistake}' but its message does not name it "
        f"(keyword {mutant.keyword!r}): {outcome.message}")


@pytest.mark.parametrize("notebook, variant", list(_cases("EQUIVALENTS")))
def test_correct_variant_passes(notebook, variant):
    outcome = solution(notebook).grade(variant)
    assert outcome.passed, f"{variant.check} rejects a correct variant ({variant.mistake}): {outcome.message}"


@pytest.mark.parametrize("notebook, edit", list(_cases("EQUIVALENT_MUTANTS")))
def test_listed_equivalent_mutant_is_really_equivalent(notebook, edit):
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
