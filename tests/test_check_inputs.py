"""A graded run's check inputs are drawn from its seed: no table made beforehand can know them.

Every check is run on the solution's function through the plain-data protocol (as
``kalman-course grade`` runs it), and every request it sends to the learner's "kernel" is
recorded: under the self-check's fixed cases, under a run seed (twice), and under another
run seed. The solution passes under each; the same seed sends the same requests; and no
call under a run seed carries the arguments of a fixed-case call, so a submission holding
the reference's outputs for the public inputs has nothing to look up.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json

import nbformat
import pytest

from kalman_course import checks
from kalman_course.checks import cases
from kalman_course.checks.remote import LearnerFunction, LocalSession
from kalman_course.tooling import withheld
from conftest import ROOT
from mutation_harness import catalogues, solution

SEEDS = (20261202, 99)

GRADED = [(module.NOTEBOOK, name) for module in catalogues().values()
          for name in solution(module.NOTEBOOK).grader_call]


class RecordingSession(LocalSession):
    """A session in this process that keeps a digest of every call it sends."""

    def __init__(self, namespace: dict):
        super().__init__(namespace)
        self.calls: list[str] = []
        self.functions: set[str] = set()  # the package functions sent by name

    def exchange(self, request: str) -> str:
        if '["op","call"]' in request:
            self.calls.append(hashlib.sha256(request.encode()).hexdigest())
        self.functions.update(_function_refs(json.loads(request)))
        return super().exchange(request)


def _function_refs(value):
    if isinstance(value, dict):
        if value.get("~") == "function":
            yield value.get("ref")
        for item in value.values():
            yield from _function_refs(item)
    elif isinstance(value, list):
        for item in value:
            yield from _function_refs(item)


def _session(notebook: str, check_name: str, seed) -> RecordingSession:
    cases.set_run_seed(seed)
    sol = solution(notebook)
    call = sol.grader_call[check_name]
    argument = call[call.index("(") + 1:call.rindex(")")]
    session = RecordingSession(dict(sol.namespace))
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            getattr(checks, check_name).judge(LearnerFunction(session, argument))
    except checks.CheckFailed as exc:
        pytest.fail(f"the solution fails {check_name} under run seed {seed}: {exc}")
    finally:
        cases.set_run_seed(None)
    assert session.calls, f"{check_name} never called the learner's function"
    return session


def _requests(notebook: str, check_name: str, seed) -> list[str]:
    return _session(notebook, check_name, seed).calls


@pytest.mark.parametrize("notebook, check_name", GRADED, ids=[f"{nb}-{c}" for nb, c in GRADED])
def test_a_run_seed_draws_inputs_no_fixed_case_has(notebook, check_name):
    fixed = _requests(notebook, check_name, None)
    drawn = _requests(notebook, check_name, SEEDS[0])
    assert _requests(notebook, check_name, SEEDS[0]) == drawn, "the same run seed must send the same inputs"
    other = _requests(notebook, check_name, SEEDS[1])
    assert other != drawn, "two run seeds sent the same inputs"
    shared = set(fixed) & set(drawn)
    assert not shared, (f"{check_name}: {len(shared)} of its {len(drawn)} calls under a run seed carry a "
                        "fixed case's arguments (a lookup table would know them)")


@pytest.mark.parametrize("notebook, check_name", GRADED, ids=[f"{nb}-{c}" for nb, c in GRADED])
def test_a_graded_run_sends_no_function_its_kernel_lacks(notebook, check_name):
    """A graded kernel runs on the chapter's guarded build: no kalman_course.checks (but the
    agent), and no reference of what the chapter's learner writes."""
    release = nbformat.read(ROOT / "exercises" / f"{notebook}.ipynb", as_version=4)
    guarded = withheld.withheld_functions(withheld.functions_to_write(release), list(solution(notebook).grader_call))
    sent = _session(notebook, check_name, SEEDS[0]).functions
    missing = sorted(ref for ref in sent if ref.startswith("kalman_course.checks.")
                     or ref.replace(":", ".") in guarded)
    assert not missing, f"{check_name} sends functions a graded kernel does not have: {missing}"


def test_run_seed_is_validated():
    for bad in (-1, 2**63, 1.5, "7", True):
        with pytest.raises(ValueError, match="seed"):
            cases.set_run_seed(bad)
    assert cases.run_seed() is None
