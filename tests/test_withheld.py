"""While grading, the course's own versions of the chapter's exercise functions are withheld.

The routes are those that earned full points before the guard (issue 24): the reference
reached through a module, an object, an alias, a decorator, a name built at run time, the
loaded modules, the garbage collector, a class's globals, the agent's own call replaced,
its source read and run. Each submission is the solution with ``kf_update`` redefined
through one route: every other check still passes, ``kf_update`` earns nothing, its hint
says the reference is not available, and where the guard was reached the flag names the
cell. Every solution is graded on its chapter's guarded build elsewhere
(``tests/test_exercises.py``); here also the build itself, and that the twins table knows
every package function that passes a check under another name.
"""

from __future__ import annotations

import contextlib
import copy
import inspect
import io
import importlib
import pkgutil
import shutil
import signal
import warnings

import nbformat
import numpy as np
import pytest

import kalman_course
from kalman_course import checks
from kalman_course.core.withheld import ReferenceWithheld
from kalman_course.tooling import grading, withheld
from kalman_course.tooling.cells import grader_info

from conftest import ROOT, dedented
from mutation_harness import catalogues, solution

CH03 = "03_kalman_filter"

#: route → the cell code appended to the solution's kf_update cell (redefining kf_update).
ROUTES = {
    "list_subscript": """
        import kalman_course.filters.kf as _kf_module
        kf_update = [_kf_module][0].kf_update
    """,
    "partial": """
        import functools
        from kalman_course.filters import kf as _kf
        kf_update = functools.partial(_kf.kf_update)
    """,
    "callable_instance": """
        from kalman_course.filters import kf as _kf
        class _Update:
            def __call__(self, *args):
                return _kf.kf_update(*args)
        kf_update = _Update()
    """,
    "decorator": """
        from kalman_course.filters import kf as _kf
        @lambda stub: _kf.kf_update
        def kf_update(x_check, P_check, y, G, R):
            raise NotImplementedError
    """,
    "resolve_name": """
        import pkgutil
        kf_update = pkgutil.resolve_name(".".join(["kalman_course", "filters", "kf"]) + ":kf_" + "update")
    """,
    "sys_modules_scan": """
        import sys
        import kalman_course.filters.kf
        kf_update = next(getattr(m, "kf_update") for name, m in list(vars(sys)["modules"].items())
                         if name.endswith("filters.kf"))
    """,
    "gc_scan": """
        import gc, types
        import kalman_course.filters.kf
        kf_update = next(o for o in gc.get_objects() if isinstance(o, types.FunctionType)
                         and o.__name__ == "kf_update" and o.__module__ == "kalman_course.filters.kf")
    """,
    "subclasses_globals": """
        import kalman_course.filters.kf
        def _walk(cls):
            for sub in type.__subclasses__(cls):
                yield sub
                yield from _walk(sub)
        kf_update = next(c.__init__.__globals__["kf_update"] for c in _walk(object)
                         if c.__module__ == "kalman_course.filters.kf" and hasattr(c, "__dataclass_fields__"))
    """,
    "reduce_getattr": """
        import functools, kalman_course
        import kalman_course.filters.kf
        kf_update = functools.reduce(getattr, ["filters", "kf", "kf_update"], kalman_course)
    """,
    "renamed_helper": """
        from kalman_course.filters.kf import kf_update as _a_helper_of_mine
        kf_update = _a_helper_of_mine
    """,
    "source_read_and_run": """
        import kalman_course.filters.kf as _kf
        _namespace = {"__name__": "copied"}
        exec(open(_kf.__file__).read(), _namespace)
        kf_update = _namespace["kf_update"]
    """,
    "agent_call_replaced": """
        import kalman_course.checks.kernel_agent as _agent
        from kalman_course.filters import kf as _kf
        _real_call = _agent.call_watched
        def _forged(fn, args, *rest, **options):
            if getattr(fn, "__name__", "") == "kf_update":
                return _kf.kf_update(*args), []
            return _real_call(fn, args, *rest, **options)
        _agent.call_watched = _forged
        def kf_update(x_check, P_check, y, G, R):
            raise NotImplementedError
    """,
}
#: Routes whose code calls the guard in a cell of the notebook (the flag names that cell).
CALL_THE_GUARD = set(ROUTES) - {"source_read_and_run"}


def _forged(route: str) -> nbformat.NotebookNode:
    nb = nbformat.read(ROOT / "solutions" / f"{CH03}.ipynb", as_version=4)
    cell = next(c for c in nb.cells if c.cell_type == "code" and "def kf_update(" in c.source)
    cell.source += "\n" + dedented(ROUTES[route])
    return nb


@pytest.fixture(scope="module")
def graded():
    """Every route graded in one class run (its own kernels, the sandbox when there is one)."""
    try:
        from kalman_course.tooling.sandbox import open_sandbox
        sandbox = open_sandbox() if shutil.which("bwrap") else None
    except Exception:
        sandbox = None
    release = grading.load_release(ROOT / "exercises")
    submissions = [((f"{route}__{CH03}.ipynb", _forged(route)), route) for route in ROUTES]
    results = grading.grade_many(submissions, release, timeout=60, jobs=2, sandbox=sandbox)
    return dict(zip(ROUTES, results))


@pytest.mark.slow
@pytest.mark.parametrize("route", ROUTES)
def test_a_route_to_the_reference_earns_nothing(graded, route):
    result = graded[route]
    assert result.status in grading.RAN_TO_THE_END, result.detail
    by_check = {c.check: c for c in result.checks}
    update = by_check.pop("kf_update")
    assert update.points == 0, f"{route} earned kf_update's points"
    # a check whose function uses kf_update fails too, blaming kf_update rather than itself
    downstream = {name for name in by_check if "kf_update" in getattr(checks, name).uses.values()}
    lost = [(c.check, c.message) for c in by_check.values() if c.points < c.possible
            and not (c.check in downstream and "calls your kf_update, which does not pass its own check" in c.message)]
    assert not lost, f"{route}: another check lost its points: {lost}"
    if route in CALL_THE_GUARD:
        assert "not available while grading" in update.message, update.message
        assert any("calls kalman_course.filters.kf.kf_update" in flag and flag.startswith("cell update")
                   for flag in result.flags), result.flags


def test_a_guarded_function_keeps_its_signature_and_loses_its_body(tmp_path):
    release = nbformat.read(ROOT / "exercises" / f"{CH03}.ipynb", as_version=4)
    names = [info[0] for cell in release.cells if (info := grader_info(cell))]
    functions = withheld.withheld_functions(withheld.functions_to_write(release), names)
    assert functions["kalman_course.filters.kf.kf_update"] == "kf_update"
    build = withheld.build_guarded(tmp_path, functions, "03")
    guarded = (build / "filters" / "kf.py").read_text()
    original = (withheld.PACKAGE / "filters" / "kf.py").read_text()
    body = inspect.getsource(kalman_course.filters.kf.kf_update).splitlines()[-1].strip()
    assert body in original and body not in guarded
    assert len(guarded.splitlines()) <= len(original.splitlines())
    # the agent alone of the checks; none of the grading tool; nothing compiled from the real package
    assert sorted(p.name for p in (build / "checks").glob("*.py")) == ["__init__.py", "kernel_agent.py",
                                                                        "plain_data.py"]
    assert not (build / "tooling").exists()
    namespace = {}
    exec(compile(guarded, str(build / "filters" / "kf.py"), "exec"), namespace)
    with pytest.raises(ReferenceWithheld, match="chapter 03's exercise asks you to write kf_update"):
        namespace["kf_update"](np.zeros(2), np.eye(2), np.zeros(1), np.ones((1, 2)), np.eye(1))
    assert list(inspect.signature(namespace["kf_update"]).parameters) == \
        list(inspect.signature(kalman_course.filters.kf.kf_update).parameters)
    with pytest.raises(FileExistsError):
        withheld.build_guarded(tmp_path, functions, "03")


def test_an_outdated_twins_table_is_an_error(tmp_path):
    with pytest.raises(ValueError, match="TWINS is out of date"):
        withheld.build_guarded(tmp_path, {"kalman_course.filters.kf.no_such_function": "kf_update"}, "03")


# ---------------------------------------------------------------------------------------
# every twin is known: a package function that passes a check is withheld for its chapter
# ---------------------------------------------------------------------------------------

def _package_functions():
    skip = ("kalman_course.checks", "kalman_course.tooling", "kalman_course.data.build")
    for info in pkgutil.walk_packages(kalman_course.__path__, "kalman_course."):
        if info.name.startswith(skip):
            continue
        module = importlib.import_module(info.name)
        for name, value in vars(module).items():
            if inspect.isfunction(value) and value.__module__ == module.__name__:
                yield f"{module.__name__}.{name}", value


class _TooLong(BaseException):
    pass


@contextlib.contextmanager
def _quiet_within(seconds: float):
    """No output, no warnings, and :class:`_TooLong` once ``seconds`` have passed."""
    def stop(*_):
        raise _TooLong
    previous = signal.signal(signal.SIGALRM, stop)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        with contextlib.redirect_stdout(io.StringIO()), warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def _same(a, b) -> bool:
    """Whether two results agree (arrays to 1e-6, containers element by element)."""
    if isinstance(a, (tuple, list)) and isinstance(b, (tuple, list)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    try:
        a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    except (TypeError, ValueError):
        return bool(a == b) if type(a) is type(b) else False
    return a.shape == b.shape and bool(np.allclose(a, b, rtol=1e-6, atol=1e-9, equal_nan=True))


def _first_call(check, learner):
    """(args, result) of the check's first call of the solution's function."""
    seen = []

    def spy(*args):
        result = learner(*copy.deepcopy(args))
        seen.append((copy.deepcopy(args), result))
        return result
    spy.__name__ = spy.__qualname__ = learner.__name__
    with _quiet_within(60):
        check.judge(spy)
    return seen[0]


def _passes(check, candidate, first_call) -> bool:
    """Whether ``candidate`` passes ``check``: it must first give the solution's result on
    the check's first call (cheap), then pass the check itself."""
    args, expected = first_call
    try:
        with _quiet_within(0.2):
            if not _same(candidate(*copy.deepcopy(args)), expected):
                return False
        with _quiet_within(2.0):
            check.judge(candidate)
        return True
    except (Exception, _TooLong):
        return False


def test_every_package_function_that_passes_a_check_is_withheld_for_its_chapter():
    candidates = list(_package_functions())
    unknown = []
    for module in catalogues().values():
        sol = solution(module.NOTEBOOK)
        release = nbformat.read(ROOT / "exercises" / f"{module.NOTEBOOK}.ipynb", as_version=4)
        names = list(sol.grader_call)
        known = withheld.withheld_functions(withheld.functions_to_write(release), names)
        for check_name in names:
            check = getattr(checks, check_name)
            call = sol.grader_call[check_name]
            learner = sol.namespace[call[call.index("(") + 1:call.rindex(")")]]
            first_call = _first_call(check, learner)
            for dotted, fn in candidates:
                try:
                    inspect.signature(fn).bind(*first_call[0])
                except TypeError:
                    continue
                if dotted not in known and _passes(check, fn, first_call):
                    unknown.append(f"{dotted} passes {check_name}")
    assert not unknown, "add to withheld.TWINS: " + "; ".join(unknown)
