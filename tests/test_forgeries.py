"""A corpus of forgeries: learner notebooks that try to earn points without doing the work.

Each forgery starts from a released exercise (its stubs are wrong) and adds or rewrites
learner cells only; the grader cells stay as released, so the restore step has nothing to
undo. All but one of the techniques below earned the points they aim at from the grader
that ran the checks inside the learner's kernel (see :class:`Forgery`); none repeats a
case of ``test_hostile_submissions.py``.

A forgery names the checks it forges. For each of them the gradebook must give 0 points,
or carry a review flag that names the forging cell (so the instructor looks at it). Several
techniques that each forge a different check share one submission (their cells do not
interfere), which keeps the class small enough to grade in about a minute.

Edits of the notebook JSON alone (grader metadata, tags, stored outputs, a fake grader
cell, the notebook metadata) must change no points and be listed in ``tampered``. Honest
notebooks written in unusual but legitimate ways, and saved by editors other than
JupyterLab (without cell ids, as Colab saves them), must earn every point with no flag and
no tampering reported.

The whole corpus is graded by one ``kalman-course grade`` run with two jobs.
"""

from __future__ import annotations

import copy
import functools
import json
from dataclasses import dataclass
from typing import Callable

import nbformat
import pytest
from nbformat.v4 import new_code_cell, new_output

from kalman_course.tooling import authoring, cli

from conftest import ROOT, dedented as _code, first_line
from notebook_editors import classic, colab_no_tags

pytestmark = pytest.mark.slow

CH01, CH03, CH09 = "01_bayes_rule.ipynb", "03_kalman_filter.ipynb", "09_tuning_consistency.ipynb"


# ---------------------------------------------------------------------------------------
# the forgeries
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Forgery:
    """One technique: the cell that forges and the checks it forges.

    Attributes
    ----------
    tries : str
        What it tries, in one line.
    submission : str
        The learner folder it is written into; techniques that forge different checks
        without touching each other share one.
    notebook : str
        The released exercise it starts from (stubs and all).
    cell : str
        Id of the forging cell.
    place : str
        ``"after:<id>"`` or ``"before:<id>"``: a new cell ``cell`` next to that one;
        ``"replace"``: ``cell`` is a learner cell of the release whose source is rewritten.
    source : str
        The forging cell's source.
    forges : tuple of str
        The checks it forges. Against the in-kernel grader (``kalman-course grade`` of
        commit 9a83326) each earned exactly these checks' points, except
        ``excepthook_atexit``, which IPython never calls (kept: learners try it), and
        ``grader_id_reused``, which earned its points unflagged and unreported from the
        grader that issue 23 measured (its restore took the last cell of an id as the grader).
    """

    tries: str
    submission: str
    notebook: str
    cell: str
    place: str
    source: str
    forges: tuple[str, ...]


# A stand-in comparison that says every value is the expected one.
_ALWAYS_CLOSE = '''
def _always_close(value, expected, what, **kwargs):
    """The grader's comparison, minus the comparing."""
    return np.asarray(expected, dtype=float)
'''

FORGERIES = {
    # --- chapter 03, techniques that change every later check: one submission each ---------
    "checks_rebound": Forgery(
        "rebind the name `checks` to an object whose every attribute prints '<name>: passed'",
        "f03_checks_rebound", CH03, "forge-checks", "after:setup", _code('''
            class _EveryCheckPasses:
                def __getattr__(self, name):
                    return lambda *args, **kwargs: print(f"{name}: passed")

            checks = _EveryCheckPasses()
        '''), ("cv_process_noise", "kf_predict", "kf_gain", "kf_update", "gnss_kf_run")),
    "custom_exc": Forgery(
        "IPython set_custom_exc on AssertionError: a failed check prints its success line instead",
        "f03_custom_exc", CH03, "forge-custom-exc", "after:setup", _code('''
            def _report_as_passed(shell, etype, value, tb, tb_offset=None):
                print(f"{str(value).split(':', 1)[0]}: passed")

            get_ipython().set_custom_exc((AssertionError,), _report_as_passed)
        '''), ("cv_process_noise", "kf_predict", "kf_gain", "kf_update", "gnss_kf_run")),
    "np_allclose": Forgery(
        "replace np.allclose by a function that always says True",
        "f03_np_allclose", CH03, "forge-allclose", "after:setup", _code('''
            np.allclose = lambda a, b, rtol=1e-05, atol=1e-08, equal_nan=False: True
        '''), ("cv_process_noise", "kf_predict", "kf_gain", "kf_update", "gnss_kf_run")),
    "frame_patches_helper": Forgery(
        "kf_predict walks sys._getframe up to the check and replaces its comparison helper",
        "f03_frame_patches_helper", CH03, "predict", "replace", _code('''
            import sys
        ''') + "\n" + _ALWAYS_CLOSE + "\n" + _code('''

            def kf_predict(x_hat, P_hat, F, Q):
                """Return the prior (x_check (n,), P_check (n, n)) one step ahead."""
                frame = sys._getframe(1)
                while frame is not None:
                    if "expect_close" in frame.f_globals:
                        frame.f_globals["expect_close"] = _always_close
                    frame = frame.f_back
                x_check = F @ x_hat
                P_check = F @ P_hat @ F.T  # fix this
                return x_check, P_check
        '''), ("kf_predict", "kf_gain", "kf_update")),
    "settrace_locals": Forgery(
        "a sys.settrace tracer sets the comparison's `value` to its `expected` on entry",
        "f03_settrace_locals", CH03, "forge-settrace", "after:setup", _code('''
            import sys

            def _tracer(frame, event, arg):
                if event == "call" and frame.f_code.co_name == "expect_close":
                    frame.f_locals["value"] = frame.f_locals["expected"]
                return None

            sys.settrace(_tracer)
        '''), ("cv_process_noise", "kf_predict", "kf_gain", "kf_update")),
    "harness_reloaded": Forgery(
        "monkeypatch kalman_course.checks.harness.expect_close, then importlib.reload the checks",
        "f03_harness_reloaded", CH03, "forge-reload", "after:setup", _code('''
            import importlib
            import kalman_course.checks.harness as harness
            import kalman_course.checks.kf as kf_checks
        ''') + "\n" + _ALWAYS_CLOSE + "\n" + _code('''

            harness.expect_close = _always_close
            for name in [n for n, fn in harness.registered().items() if fn.__module__ == kf_checks.__name__]:
                del harness._REGISTRY[name]
            importlib.reload(kf_checks)   # its `from ...harness import expect_close` now binds mine
            for name in harness.registered():
                vars(checks).pop(name, None)
            importlib.reload(checks)      # checks.<name> exposed again, chapter 03's reloaded
        '''), ("cv_process_noise", "kf_predict", "kf_gain", "kf_update")),
    "gc_referrers": Forgery(
        "gc.get_referrers finds every namespace holding the comparison helper and swaps it",
        "f03_gc_referrers", CH03, "forge-gc", "after:setup", _code('''
            import gc
        ''') + "\n" + _ALWAYS_CLOSE + "\n" + _code('''

            _original = checks.kf.expect_close
            for namespace in gc.get_referrers(_original):
                if isinstance(namespace, dict) and namespace.get("expect_close") is _original:
                    namespace["expect_close"] = _always_close
        '''), ("cv_process_noise", "kf_predict", "kf_gain", "kf_update")),
    "sys_modules_fake": Forgery(
        "before the setup cell, put a fake kalman_course.checks into sys.modules",
        "f03_sys_modules_fake", CH03, "forge-sys-modules", "before:setup", _code('''
            import os
            import sys
            import types

            import kalman_course

            _fake = types.ModuleType("kalman_course.checks")
            # the real folder, so that the checks' own modules still import
            _fake.__path__ = [os.path.join(os.path.dirname(kalman_course.__file__), "checks")]
            _fake.__getattr__ = lambda name: (lambda *args, **kwargs: print(f"{name}: passed"))
            sys.modules["kalman_course.checks"] = _fake
            vars(kalman_course).pop("checks", None)
        '''), ("cv_process_noise", "kf_predict", "kf_gain", "kf_update", "gnss_kf_run")),

    # --- chapter 03, one check each: submission f03_targeted_a -----------------------------
    "vars_checks": Forgery(
        "write a passing stand-in into vars(checks)",
        "f03_targeted_a", CH03, "forge-vars", "after:cv", _code('''
            vars(checks)["cv_process_noise"] = lambda fn: print("cv_process_noise: passed")
        '''), ("cv_process_noise",)),
    "closure_cell": Forgery(
        "replace the check inside the grader's wrapper through its closure cell",
        "f03_targeted_a", CH03, "forge-closure", "after:predict", _code('''
            for _cell in checks.kf_predict.__closure__ or ():
                if getattr(_cell.cell_contents, "__name__", "") == "check_kf_predict":
                    _cell.cell_contents = lambda *args, **kwargs: None
        '''), ("kf_predict",)),
    "array_reads_frame": Forgery(
        "kf_gain returns objects whose __array__ reads the caller's `expected` from its frame",
        "f03_targeted_a", CH03, "gain", "replace", _code('''
            import sys

            class _LooksRight:
                def __init__(self, value):
                    self.value = np.asarray(value, dtype=float)

                def __array__(self, dtype=None, copy=None):
                    frame = sys._getframe(1)
                    while frame is not None:
                        expected = frame.f_locals.get("expected")
                        if isinstance(expected, np.ndarray) and expected.shape == self.value.shape:
                            return np.asarray(expected, dtype=dtype or float)
                        frame = frame.f_back
                    return self.value if dtype is None else self.value.astype(dtype)

            def kf_gain(P_check, G, R):
                """Return the gain K (n, m) and the innovation covariance S (m, m)."""
                S = G @ P_check @ G.T + R
                K = P_check @ G.T @ np.linalg.inv(R)  # fix this
                return _LooksRight(K), _LooksRight(S)
        '''), ("kf_gain",)),
    "float_reads_frame": Forgery(
        "kf_update returns nested lists of numbers whose __float__ reads the caller's `expected`",
        "f03_targeted_a", CH03, "update", "replace", _code('''
            import sys

            class _Entry:
                def __init__(self, value, index, shape):
                    self.value, self.index, self.shape = float(value), index, shape

                def __float__(self):
                    frame = sys._getframe(1)
                    while frame is not None:
                        expected = frame.f_locals.get("expected")
                        if isinstance(expected, np.ndarray) and expected.shape == self.shape:
                            self.value = float(expected[self.index])
                            break
                        frame = frame.f_back
                    return self.value

            def _entries(a):
                a = np.asarray(a, dtype=float)
                out = np.empty(a.shape, dtype=object)
                for index in np.ndindex(a.shape):
                    out[index] = _Entry(a[index], index, a.shape)
                return out.tolist()

            def kf_update(x_check, P_check, y, G, R):
                """Return the posterior (x_hat (n,), P_hat (n, n)) given the measurement y (m,)."""
                K, S = kf_gain(P_check, G, R)
                innovation = G @ x_check - y  # fix this
                x_hat = x_check + K @ innovation
                I_KG = np.eye(len(x_check)) - K @ G
                P_hat = I_KG @ P_check @ I_KG.T  # fix this
                return _entries(x_hat), _entries(0.5 * (P_hat + P_hat.T))
        '''), ("kf_update",)),
    "ast_transformer": Forgery(
        "an IPython AST transformer turns the call checks.gnss_kf_run(...) into a print",
        "f03_targeted_a", CH03, "forge-ast", "after:run", _code('''
            import ast

            class _GraderCallPrints(ast.NodeTransformer):
                def visit_Call(self, node):
                    f = node.func
                    if isinstance(f, ast.Attribute) and f.attr == "gnss_kf_run" \\
                            and isinstance(f.value, ast.Name) and f.value.id == "checks":
                        return ast.copy_location(ast.Call(ast.Name("print", ast.Load()),
                                                          [ast.Constant("gnss_kf_run: passed")], []), node)
                    return self.generic_visit(node)

            get_ipython().ast_transformers.append(_GraderCallPrints())
        '''), ("gnss_kf_run",)),

    # --- chapter 03, one check each: submission f03_targeted_b -----------------------------
    "getsource_exec": Forgery(
        "exec(inspect.getsource(...)) of the check's own reference cv_matrices",
        "f03_targeted_b", CH03, "forge-getsource", "after:cv", _code('''
            import inspect
            from kalman_course import symbolic

            exec(inspect.getsource(checks.kf.cv_matrices_reference))
            cv_matrices = cv_matrices_reference
        '''), ("cv_process_noise",)),
    "star_import": Forgery(
        "from kalman_course.filters.kf import * replaces the learner's kf_predict",
        "f03_targeted_b", CH03, "forge-star", "after:predict", _code('''
            from kalman_course.filters.kf import *
        '''), ("kf_predict",)),
    "learner_code_swapped": Forgery(
        "kf_gain keeps its stub source but its __code__ is swapped for one calling the package",
        "f03_targeted_b", CH03, "forge-code-swap", "after:gain", _code('''
            from kalman_course.filters import kf as _kf

            def _gain(P_check, G, R):
                S = _kf.innovation_covariance(P_check, G, R)
                return _kf.kf_gain(P_check, G, S), S

            kf_gain.__code__ = _gain.__code__
        '''), ("kf_gain",)),
    "getattr_reference": Forgery(
        'kf_update calls getattr(kf, "kf_" + "update"), the package\'s reference',
        "f03_targeted_b", CH03, "forge-getattr", "after:update", _code('''
            import kalman_course.filters.kf as _filters

            _reference = getattr(_filters, "kf_" + "update")

            def kf_update(x_check, P_check, y, G, R):
                """Return the posterior (x_hat (n,), P_hat (n, n)) given the measurement y (m,)."""
                return tuple(_reference(x_check, P_check, y, G, R, joseph=True)[:2])
        '''), ("kf_update",)),
    "check_code_swapped": Forgery(
        "the check's own function (checks.gnss_kf_run.__wrapped__) gets an empty __code__",
        "f03_targeted_b", CH03, "forge-check-code", "after:run", _code('''
            _check = checks.gnss_kf_run.__wrapped__
            _check.__code__ = (lambda run_gnss_kf: None).__code__
        '''), ("gnss_kf_run",)),

    # --- chapter 09: submission f09_targeted_a ---------------------------------------------
    "exec_string": Forgery(
        "exec of a string, assembled from pieces, that patches checks.consistency_nees",
        "f09_targeted_a", CH09, "forge-exec", "after:nees", _code('''
            exec("".join(["chec", "ks.consistency_", "nees = lambda fn: print('consistency_nees: passed')"]))
        '''), ("consistency_nees",)),
    "input_transformer": Forgery(
        "an IPython input transformer rewrites the grader call into a print of its success line",
        "f09_targeted_a", CH09, "forge-input", "after:nis", _code('''
            import re

            def _grader_line_prints(lines):
                return [re.sub(r"^checks\\.(consistency_nis)\\(.*\\)$", r'print("\\1: passed")', line)
                        for line in lines]

            get_ipython().input_transformers_post.append(_grader_line_prints)
        '''), ("consistency_nis",)),
    "released_import_answers": Forgery(
        "chi2_interval returns chi2_bounds(...), the reference that the release's setup imports",
        "f09_targeted_a", CH09, "bounds", "replace", _code('''
            def chi2_interval(dof, n_runs, confidence=0.95):
                """Two-sided interval (lo, hi) for the average of n_runs independent χ²(dof) values."""
                return chi2_bounds(dof, n_runs, confidence)
        '''), ("chi2_interval",)),
    "bool_like": Forgery(
        "gate returns an object that claims to be a bool and whose truth is the grader's decision",
        "f09_targeted_a", CH09, "gate", "replace", _code('''
            import sys

            class _Decision:
                __class__ = property(lambda self: bool)   # isinstance(answer, bool) is True

                def __init__(self, value):
                    self.value = bool(value)

                def __bool__(self):
                    frame = sys._getframe(1)
                    while frame is not None:
                        seen = frame.f_locals
                        if {"values", "threshold", "answers"} <= seen.keys():
                            i = len(seen["answers"])
                            return bool(seen["values"][i] <= seen["threshold"][i])
                        frame = frame.f_back
                    return self.value

            def gate(innovation, S, confidence=0.99):
                """True (accept) if the NIS of the innovation (m,) with covariance S (m, m) passes the χ² gate."""
                value = innovation @ np.linalg.solve(S, innovation)
                threshold = chi2_ppf(confidence, 1)  # fix this
                return _Decision(value <= threshold)
        '''), ("innovation_gate",)),
    "str_subclass": Forgery(
        "verdict returns a str subclass whose == always says equal and != never",
        "f09_targeted_a", CH09, "verdict", "replace", _code('''
            class _AnyVerdict(str):
                def __eq__(self, other):
                    return True

                def __ne__(self, other):
                    return False

                __hash__ = str.__hash__

            def verdict(nis_values, dof, confidence=0.95):
                """'consistent', 'overconfident' or 'underconfident' for a NIS record (N,) of dof components."""
                return _AnyVerdict("consistent")
        '''), ("consistency_verdict",)),

    # --- chapter 09: submission f09_targeted_b ---------------------------------------------
    "numpy_isclose": Forgery(
        "replace numpy's isclose where np.allclose looks it up (and np.isclose, np.testing)",
        "f09_targeted_b", CH09, "forge-isclose", "after:setup", _code('''
            def _all_close(a, b, rtol=1e-05, atol=1e-08, equal_nan=False):
                return np.ones(np.broadcast(a, b).shape, dtype=bool)

            np._core.numeric.isclose = np.isclose = _all_close
            np.testing.assert_allclose = lambda *args, **kwargs: None
        '''), ("consistency_nees", "consistency_nis", "chi2_interval")),
    "frame_reads_expected": Forgery(
        "gate walks sys._getframe to the check and returns the check's cached reference decision",
        "f09_targeted_b", CH09, "gate", "replace", _code('''
            import sys

            _decisions = {}

            def gate(innovation, S, confidence=0.99):
                """True (accept) if the NIS of the innovation (m,) with covariance S (m, m) passes the χ² gate."""
                frame = sys._getframe(1)
                while frame is not None and not _decisions:
                    cases, reference = frame.f_globals.get("gate_cases"), frame.f_globals.get("_gate_reference")
                    if cases is not None and reference is not None:
                        values, _, _, threshold = reference()
                        _decisions.update({(y.tobytes(), S_case.tobytes(), c): bool(v <= t)
                                           for (y, S_case, c), v, t in zip(cases(), values, threshold)})
                    frame = frame.f_back
                key = (np.asarray(innovation).tobytes(), np.asarray(S).tobytes(), confidence)
                if key in _decisions:
                    return _decisions[key]
                value = innovation @ np.linalg.solve(S, innovation)
                threshold = chi2_ppf(confidence, 1)  # fix this
                return bool(value <= threshold)
        '''), ("innovation_gate",)),
    "reference_replaced": Forgery(
        "replace the package's verdict, which the check's reference calls, by the learner's stub",
        "f09_targeted_b", CH09, "forge-reference", "after:verdict", _code('''
            from kalman_course.evaluation import consistency as _statistics

            _statistics.verdict = verdict
        '''), ("consistency_verdict",)),

    # --- chapter 01 ------------------------------------------------------------------------
    "traceback_hidden": Forgery(
        "replace the shell's showtraceback and builtins.print so that a failed check prints passed",
        "f01_traceback_hidden", CH01, "forge-showtraceback", "after:setup", _code('''
            import builtins
            import re
            import sys

            _print = builtins.print

            def _passed_print(*args, **kwargs):
                text = " ".join(map(str, args))
                _print(re.sub(r"^(\\w+): .*", r"\\1: passed", text), **kwargs)

            def _show_as_passed(*args, **kwargs):
                _passed_print(str(sys.exc_info()[1]))

            builtins.print = _passed_print
            get_ipython().showtraceback = _show_as_passed
        '''), ("door_likelihood", "histogram_update", "histogram_predict", "histogram_filter")),
    "excepthook_atexit": Forgery(
        "sys.excepthook and atexit hooks that report every check as passed (no effect in IPython)",
        "f01_excepthook_atexit", CH01, "forge-excepthook", "after:setup", _code('''
            import atexit
            import sys

            _names = ("door_likelihood", "histogram_update", "histogram_predict", "histogram_filter")
            sys.excepthook = lambda *exc: print(f"{str(exc[1]).split(':', 1)[0]}: passed")
            atexit.register(lambda: print("\\n".join(f"{n}: passed" for n in _names)))
        '''), ("door_likelihood", "histogram_update", "histogram_predict", "histogram_filter")),
    "grader_id_reused": Forgery(
        "a cell that imports the reference, under the id of the grader that checks it, just before it",
        "f01_excepthook_atexit", CH01, "grader-corridor_motion_model", "before:grader-corridor_motion_model",
        _code('''
            from kalman_course.filters.bayes import circular_motion_model
        '''), ("corridor_motion_model",)),
    "results_file": Forgery(
        "write the grader's per-cell results file with every cell passed, then kill the nbval process",
        "f01_results_file", CH01, "forge-results", "after:setup", _code('''
            import json
            import os
            import signal

            _results = os.environ.get("KALMAN_COURSE_RESULTS")
            _parent = f"/proc/{os.getppid()}/cmdline"
            # only when the parent is the nbval run of the in-kernel grader (never another pytest)
            if _results and os.path.exists(_parent) and b"nbval_results" in open(_parent, "rb").read():
                [_nb] = [f for f in os.listdir(".") if f.endswith(".ipynb")]
                _cells = [c for c in json.load(open(_nb))["cells"] if c["cell_type"] == "code"]
                with open(_results, "w") as fh:
                    json.dump([{"file": _nb, "cell_id": c["id"], "index": i, "passed": True,
                                "skipped": False, "message": ""} for i, c in enumerate(_cells)], fh)
                os.kill(os.getppid(), signal.SIGKILL)
        '''), ("door_likelihood", "histogram_update", "histogram_predict", "histogram_filter")),
}


# ---------------------------------------------------------------------------------------
# edits of the notebook JSON alone, on a chapter-03 notebook with one stub left
# ---------------------------------------------------------------------------------------

#: The checks that the JSON cases' base notebook fails: its kf_update is the stub, and
#: run_gnss_kf and the challenge's filter with missing fixes call it.
BASE_FAILS = {"kf_update", "gnss_kf_run", "gnss_kf_gaps"}


def _points_raised(nb):
    """Raise the points of a passing and of a failing grader cell in their metadata."""
    for cid in ("grader-kf_gain", "grader-kf_update"):
        _cell(nb, cid).metadata["kalman_course"]["points"] = 50


def _skip_tags(nb):
    """Tag the failing grader cells so that nbval skips one and expects the other to raise."""
    _cell(nb, "grader-kf_update").metadata["tags"].append("raises-exception")
    _cell(nb, "grader-gnss_kf_run").metadata["tags"].append("nbval-skip")


def _fake_outputs(nb):
    """Store a success line, with points, as the output of the failing kf_update grader."""
    cell = _cell(nb, "grader-kf_update")
    cell.outputs = [new_output("stream", name="stdout", text="kf_update: passed (3/3 points)\n")]


def _fake_grader(nb):
    """Add a grader cell of its own: tags and metadata copied from the real one, a print inside."""
    real = _cell(nb, "grader-kf_update")
    fake = new_code_cell('print("kf_update: passed")', metadata=copy.deepcopy(real.metadata),
                         outputs=copy.deepcopy(real.outputs), execution_count=real.execution_count)
    fake["id"] = "grader-kf_update-again"
    nb.cells.insert(nb.cells.index(real) + 1, fake)


def _notebook_metadata(nb):
    """Raise every check's points in the notebook metadata and name a kernel of the learner's."""
    meta = nb.metadata["kalman_course"]
    meta["graders"] = {name: 50 for name in meta["graders"]}
    nb.metadata["kernelspec"] = {"display_name": "My Python", "language": "python", "name": "learner-python"}


def _chapter_edited(nb):
    """Write the chapter in the notebook metadata as "3" (the file name still says 03)."""
    nb.metadata["kalman_course"]["chapter"] = "3"


JSON_EDITS: dict[str, Callable] = {
    "points_raised": _points_raised,
    "skip_tags": _skip_tags,
    "fake_outputs": _fake_outputs,
    "fake_grader": _fake_grader,
    "notebook_metadata": _notebook_metadata,
    "chapter_edited": _chapter_edited,
}


# ---------------------------------------------------------------------------------------
# honest controls: correct, in an unusual but legitimate style
# ---------------------------------------------------------------------------------------

def _control_03(nb):
    """%matplotlib inline, helper functions, debug prints, an explicit inverse, the short form."""
    _cell(nb, "setup").source = "%matplotlib inline\n" + _cell(nb, "setup").source
    _cell(nb, "cv").source = _code('''
        def _noise_input(T, dim):
            """How a held acceleration moves position and velocity over T."""
            return np.concatenate([0.5 * T**2 * np.eye(dim), T * np.eye(dim)])

        def cv_matrices(T, sigma_a, dim=3):
            print(f"building the CV model for T = {T}")
            F = np.eye(2 * dim)
            F[:dim, dim:] = T * np.eye(dim)
            B = _noise_input(T, dim)
            return F, sigma_a**2 * (B @ B.T)
    ''')
    _cell(nb, "predict").source = _code('''
        def kf_predict(x_hat, P_hat, F, Q):
            return F.dot(x_hat), np.linalg.multi_dot([F, P_hat, F.T]) + Q
    ''')
    _cell(nb, "gain").source = _code('''
        def kf_gain(P_check, G, R):
            S = G @ P_check @ G.T + R
            S_inv = np.linalg.inv(S)
            return P_check @ G.T @ S_inv, S
    ''')
    _cell(nb, "update").source = _code('''
        def kf_update(x_check, P_check, y, G, R):
            K, _ = kf_gain(P_check, G, R)
            residual = y - G @ x_check
            if np.linalg.norm(residual) > 1e3:
                print("large residual:", residual)
            P_hat = (np.eye(len(x_check)) - K @ G) @ P_check
            return x_check + K @ residual, (P_hat + P_hat.T) / 2
    ''')
    _cell(nb, "run").source = _code('''
        def run_gnss_kf(t, y, sigma_a, sigma_gnss, sigma_v0=15.0):
            G = np.eye(3, 6)
            R = np.diag([sigma_gnss**2] * 3)
            x = np.concatenate([y[0], [0.0, 0.0, 0.0]])
            P = np.diag([sigma_gnss**2] * 3 + [sigma_v0**2] * 3)
            xs, Ps = [x], [P]
            for k, dt in enumerate(np.diff(t), start=1):
                x, P = kf_predict(x, P, *cv_matrices(dt, sigma_a))
                x, P = kf_update(x, P, y[k], G, R)
                xs.append(x)
                Ps.append(P)
            print(f"{len(xs)} steps")
            return np.stack(xs), np.stack(Ps)
    ''')


def _control_09(nb):
    """Cholesky and inverses, a helper for the quadratic form, its own interval in the verdict."""
    _cell(nb, "nees").source = _code('''
        def _quadratic_form(v, C):
            """vᵀ C⁻¹ v through the Cholesky factor of C."""
            L = np.linalg.cholesky(C)
            w = np.linalg.solve(L, v)
            return float(w @ w)

        def nees(error, P):
            return _quadratic_form(np.asarray(error), P)
    ''')
    _cell(nb, "nis").source = _code('''
        def nis(innovation, P_check, G, R):
            S = G @ P_check @ G.T + R
            value = innovation @ np.linalg.inv(S) @ innovation
            print("NIS", value)
            return float(value)
    ''')
    _cell(nb, "bounds").source = _code('''
        def chi2_interval(dof, n_runs, confidence=0.95):
            tail = (1.0 - confidence) / 2.0
            k = dof * n_runs
            return chi2_ppf(tail, k) / n_runs, chi2_ppf(1.0 - tail, k) / n_runs
    ''')
    _cell(nb, "gate").source = _code('''
        def gate(innovation, S, confidence=0.99):
            m = innovation.shape[0]
            return bool(_quadratic_form(innovation, S) <= chi2_ppf(confidence, m))
    ''')
    _cell(nb, "verdict").source = _code('''
        def verdict(nis_values, dof, confidence=0.95):
            lo, hi = chi2_interval(dof, len(nis_values), confidence)
            mean = float(np.mean(nis_values))
            return "overconfident" if mean > hi else "underconfident" if mean < lo else "consistent"
    ''')


def _control_01(nb):
    """Re-run out of order in JupyterLab: new execution counts everywhere, an extra cell of its own."""
    for k, cell in enumerate(c for c in nb.cells if c.cell_type == "code"):
        cell.execution_count = 40 + k
    extra = new_code_cell("print(sensor_likelihood(CORRIDOR, 1, 0.8))")
    extra["id"] = "my-try"
    nb.cells.insert(nb.cells.index(_cell(nb, "likelihood")) + 1, extra)


CONTROLS: dict[str, tuple[str, Callable]] = {
    "control_03": (CH03, _control_03),
    "control_09": (CH09, _control_09),
    "control_01": (CH01, _control_01),
}

#: Controls saved by another editor (``notebook_editors.py``): name -> (the control, how it is saved).
SAVED_BY: dict[str, tuple[str, Callable[[dict], str]]] = {
    "control_03_classic_4_4": ("control_03", classic(4)),  # nbformat 4.4, no cell ids
    "control_09_colab": ("control_09", colab_no_tags),  # Colab's own ids in metadata.id, no tags
}

#: Forgeries whose cell reuses the id of another cell of their submission.
REUSED_IDS = {"grader_id_reused"}


# ---------------------------------------------------------------------------------------
# building and grading the class
# ---------------------------------------------------------------------------------------

def _cell(nb, cid):
    return next(c for c in nb.cells if c.get("id") == cid)


def _exercise(notebook: str):
    return nbformat.read(ROOT / "exercises" / notebook, as_version=4)


def _solved(notebook: str, keep_stubs: tuple[str, ...] = ()):
    """The released exercise with the solution's code in its learner cells, but ``keep_stubs``."""
    nb = _exercise(notebook)
    solution = authoring.render(nbformat.read(ROOT / "solutions" / notebook, as_version=4), set())
    sources = {c["id"]: c.source for c in solution.cells}
    for cell in nb.cells:
        if authoring.grader_info(cell) is None and cell["id"] not in keep_stubs:
            cell.source = sources[cell["id"]]
    return nb


def _apply(nb, forgery: Forgery):
    if forgery.place == "replace":
        _cell(nb, forgery.cell).source = forgery.source
        return
    where, anchor = forgery.place.split(":")
    cell = new_code_cell(forgery.source)
    cell["id"] = forgery.cell
    i = nb.cells.index(_cell(nb, anchor))
    nb.cells.insert(i + (where == "after"), cell)


@functools.cache
def _submissions() -> dict[str, tuple[str, object]]:
    """Learner folder -> (notebook file name, notebook, or the text another editor saved)."""
    out = {}
    for forgery in FORGERIES.values():
        _, nb = out.setdefault(forgery.submission, (forgery.notebook, _exercise(forgery.notebook)))
        _apply(nb, forgery)
    for name, edit in JSON_EDITS.items():
        nb = _solved(CH03, keep_stubs=("update",))
        edit(nb)
        out[f"json_{name}"] = (CH03, nb)
    for name, (notebook, edit) in CONTROLS.items():
        nb = _solved(notebook)
        edit(nb)
        out[name] = (notebook, nb)
    for name, (control, save) in SAVED_BY.items():
        notebook, edit = CONTROLS[control]
        nb = _solved(notebook)
        edit(nb)
        out[name] = (notebook, save(json.loads(nbformat.writes(nb))))
    return out


def _release_points(notebook: str) -> dict[str, int]:
    """Every graded check's points, optional challenges included."""
    return dict(_exercise(notebook).metadata["kalman_course"]["graders"])


def _core(notebook: str, points: dict[str, int]) -> int:
    """The sum of ``points`` over the core checks (a gradebook's ``points`` leaves challenges out)."""
    challenges = set(_exercise(notebook).metadata["kalman_course"]["challenges"])
    return sum(p for check, p in points.items() if check not in challenges)


def grade_class(root, out):
    """Write every submission under ``root`` and grade them with one CLI run; learner -> result."""
    for learner, (notebook, nb) in _submissions().items():
        (root / learner).mkdir()
        if isinstance(nb, str):  # as another editor saved it, byte for byte
            (root / learner / notebook).write_text(nb, encoding="utf-8")
        elif learner in {FORGERIES[name].submission for name in REUSED_IDS}:
            # as it is: nbformat's writer would give the reused id a new one
            (root / learner / notebook).write_text(json.dumps(nb, indent=1), encoding="utf-8")
        else:
            nbformat.write(nb, root / learner / notebook)
    cli.main(["grade", str(root), "--release", str(ROOT / "exercises"), "--jobs", "2", "--timeout", "60",
              "--json", str(out / "g.json")])
    document = json.loads((out / "g.json").read_text())
    records = document["results"] if isinstance(document, dict) else document  # a signed gradebook, or a list
    return {r["learner"]: r for r in records}


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    return grade_class(tmp_path_factory.mktemp("class"), tmp_path_factory.mktemp("out"))


def _name(forgery: Forgery) -> str:
    """How grading names the forging cell: ``cell <id>``, or by its place when another cell
    of the notebook carries the same id."""
    cells = _submissions()[forgery.submission][1].cells
    ids = [c.get("id") for c in cells]
    place = next(i for i, c in enumerate(cells) if c.source == forgery.source)
    others = [str(i + 1) for i, cid in enumerate(ids) if cid == forgery.cell and i != place]
    if not others:
        return f"cell {forgery.cell}"
    cells_word = "cells" if len(others) > 1 else "cell"
    return (f"cell {place + 1} (id {forgery.cell}, also used by {cells_word} {', '.join(others)}"
            f"{first_line(forgery.source)})")


def _names_cell(flag: str, name: str) -> bool:
    """True if the review flag is about the cell named ``name`` (flags read ``<name>: <what it does>``)."""
    return flag.startswith(f"{name}:")


def _by_check(result) -> dict[str, int]:
    return {c["check"]: c["points"] for c in result["checks"]}


# ---------------------------------------------------------------------------------------
# the tests
# ---------------------------------------------------------------------------------------

def test_the_corpus_is_well_formed():
    """Every forged check belongs to the notebook's chapter; every submission's cell ids are
    unique, but the one a forgery reuses on purpose."""
    assert len(FORGERIES) >= 20
    for name, forgery in FORGERIES.items():
        assert set(forgery.forges) <= set(_release_points(forgery.notebook)), name
        assert forgery.place == "replace" or not forgery.cell.startswith("grader-") or name in REUSED_IDS, name
    for learner, (_, nb) in _submissions().items():
        if isinstance(nb, str):
            continue  # saved by another editor: without ids
        ids = [c["id"] for c in nb.cells]
        twice = {cid for cid in ids if ids.count(cid) > 1}
        assert twice == {FORGERIES[n].cell for n in REUSED_IDS if FORGERIES[n].submission == learner}, learner
    # two techniques in one submission never forge the same check (each point has one culprit)
    forged = [(f.submission, check) for f in FORGERIES.values() for check in f.forges]
    assert len(forged) == len(set(forged))


def test_every_submission_is_graded(graded):
    assert set(graded) == set(_submissions())


@pytest.mark.parametrize("name", sorted(FORGERIES))
def test_a_forgery_earns_no_unflagged_points(graded, name):
    forgery = FORGERIES[name]
    result = graded[forgery.submission]
    points = _by_check(result)
    flagged = any(_names_cell(flag, _name(forgery)) for flag in result["flags"])
    unflagged_points = {check: points.get(check) for check in forgery.forges if points.get(check) and not flagged}
    assert not unflagged_points, (f"{forgery.tries}: points {unflagged_points} without a flag naming "
                                  f"{_name(forgery)!r}; flags {result['flags']}")


def test_a_cell_under_a_grader_s_id_is_reviewed_and_reported_by_its_place(graded):
    """The reused id is a tamper line, the cell's import a flag, both naming the cell by its
    place; the real grader cell still grades (and names no flag)."""
    forgery = FORGERIES["grader_id_reused"]
    result = graded[forgery.submission]
    name = _name(forgery)
    assert name.startswith("cell ") and "(id grader-corridor_motion_model, also used by cell " in name
    assert result["status"] == "tampered and restored"
    assert result["tampered"] == [f"{name}: a learner cell carried the id of grader cell {forgery.cell} "
                                  "(it ran and was reviewed as a learner cell)"]
    assert result["readded"] == []
    assert f"{name}: imports `circular_motion_model` from `kalman_course.filters.bayes` instead of writing it" \
        in result["flags"]
    assert not any(flag.startswith(f"cell {forgery.cell}:") for flag in result["flags"])


@pytest.mark.parametrize("name", sorted(JSON_EDITS))
def test_an_edit_of_the_json_is_reported_and_changes_no_points(graded, name):
    result = graded[f"json_{name}"]
    release = _release_points(CH03)
    expected = {check: 0 if check in BASE_FAILS else points for check, points in release.items()}
    assert result["tampered"], f"{JSON_EDITS[name].__doc__} is not reported"
    assert _by_check(result) == expected
    assert result["possible"] == _core(CH03, release)


@pytest.mark.parametrize("name", sorted(CONTROLS) + sorted(SAVED_BY))
def test_an_honest_notebook_earns_every_point_unflagged(graded, name):
    result = graded[name]
    notebook, edit = CONTROLS[SAVED_BY[name][0] if name in SAVED_BY else name]
    assert result["status"] == "graded", (result["tampered"], result["readded"])
    release = _release_points(notebook)
    full, challenges = _core(notebook, release), sum(release.values()) - _core(notebook, release)
    assert (result["points"], result["possible"]) == (full, full), [c["message"] for c in result["checks"]]
    assert (result["challenge_points"], result["challenge_possible"]) == (challenges, challenges)
    assert result["flags"] == [], edit.__doc__
    assert (result["tampered"], result["readded"]) == ([], []), edit.__doc__
