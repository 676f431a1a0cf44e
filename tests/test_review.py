"""Tests for kalman_course.tooling.review: what gets flagged, and that honest work never is."""

import copy
import functools

import nbformat
import pytest
from nbformat.v4 import new_code_cell

from kalman_course.tooling import authoring
from kalman_course.tooling.review import review_flags

from conftest import ROOT

CHAPTERS = sorted(p.name for p in (ROOT / "exercises").glob("[0-9]*.ipynb"))


@functools.lru_cache(maxsize=None)
def _read(folder, chapter):
    return nbformat.read(ROOT / folder / chapter, as_version=4)


def _release(chapter):
    return copy.deepcopy(_read("exercises", chapter))


def _solved(chapter):
    """The released exercise with the solution's code in every non-grader cell."""
    exercise = _release(chapter)
    solution = authoring.render(_read("solutions", chapter), set())
    sources = {c["id"]: c.source for c in solution.cells}
    for cell in exercise.cells:
        if authoring.grader_info(cell) is None and cell["id"] in sources:
            cell.source = sources[cell["id"]]
    return exercise


@pytest.mark.parametrize("chapter", CHAPTERS)
def test_honest_notebooks_are_not_flagged(chapter):
    """The release, the solved exercise and the solution notebook itself raise no flag."""
    release = _release(chapter)
    assert review_flags(release, release) == []
    assert review_flags(_solved(chapter), release) == []
    assert review_flags(_read("solutions", chapter), release) == []


CH01 = "01_bayes_rule.ipynb"


def _with_update_cell(source):
    nb = _solved(CH01)
    next(c for c in nb.cells if c["id"] == "update").source = source
    return nb


def _with_extra_cell(source):
    nb = _solved(CH01)
    cell = new_code_cell(source)
    cell["id"] = "extra"
    nb.cells.insert(1, cell)
    return nb


CASES = [
    (_with_update_cell("from kalman_course.filters.bayes import histogram_update"),
     "cell update: imports `histogram_update` from `kalman_course.filters.bayes` instead of writing it"),
    (_with_update_cell("from kalman_course.filters.bayes import histogram_update as ref\n"
                       "def histogram_update(b, l):\n    return ref(b, l)"),
     "cell update: imports `histogram_update` from `kalman_course.filters.bayes` instead of writing it"),
    (_with_update_cell("import kalman_course.filters.bayes as kb\nhistogram_update = kb.histogram_update"),
     "cell update: binds `histogram_update` to `kb.histogram_update` instead of writing it"),
    (_with_update_cell("import kalman_course.filters.bayes\n"
                       "def histogram_update(belief, likelihood):\n"
                       "    return kalman_course.filters.bayes.histogram_update(belief, likelihood)"),
     "cell update: `histogram_update` calls `kalman_course.filters.bayes.histogram_update` instead of doing the work"),
    (_with_extra_cell("checks.histogram_update = lambda f: print('histogram_update: passed')"),
     "cell extra: assigns to `checks.histogram_update`, part of the grading code"),
    (_with_extra_cell("from kalman_course.checks import harness\nharness.call = lambda fn, *a, **k: None"),
     "cell extra: assigns to `harness.call`, part of the grading code"),
    (_with_extra_cell("from kalman_course.checks import harness\nharness.call = lambda fn, *a, **k: None"),
     "cell extra: imports `harness` from `kalman_course.checks`"),
    (_with_extra_cell("import kalman_course.checks.bayes as cb\nsetattr(cb, 'CORRIDOR', None)"),
     "cell extra: calls `setattr` on `cb`, part of the grading code"),
    (_with_extra_cell("import sys\nsys.modules['kalman_course.checks'].door_likelihood = print"),
     "cell extra: uses `sys.modules`"),
    (_with_extra_cell("import importlib\n%matplotlib inline\n!echo hi"), "cell extra: imports `importlib`"),
    (_with_extra_cell("__builtins__.print = None"), "cell extra: uses `__builtins__`"),
]


@pytest.mark.parametrize("nb,expected", CASES, ids=[f"case{i}" for i in range(len(CASES))])
def test_shortcuts_are_flagged(nb, expected):
    assert expected in review_flags(nb, _release(CH01))


def test_release_imports_are_not_flagged_but_new_ones_are():
    """The setup cell imports kalman_course.checks in the release; a learner's extra import is new."""
    nb = _solved(CH01)
    setup = next(c for c in nb.cells if c["id"] == "setup")
    setup.source += "\nfrom kalman_course.checks.harness import CheckFailed"
    flags = review_flags(nb, _release(CH01))
    assert flags == ["cell setup: imports `CheckFailed` from `kalman_course.checks.harness`"]


def test_unparsable_cells_and_magics_are_not_flags():
    for source in ("def broken(:\n    pass", "%%bash\necho hi", "x = 1?"):
        assert review_flags(_with_extra_cell(source), _release(CH01)) == []


def test_grader_cells_are_skipped_and_nothing_is_modified():
    """Grading restores grader cells, so what a learner put there is not reported twice."""
    nb = _solved(CH01)
    next(c for c in nb.cells if c["id"] == "grader-door_likelihood").source = "import importlib"
    before = copy.deepcopy(nb)
    assert review_flags(nb, _release(CH01)) == []
    assert nb == before


# --- what learners used to forge grades (issue 13), each in an extra cell of a solved chapter 01 ---

def _extra_flags(source):
    return review_flags(_with_extra_cell(source), _release(CH01))


IMPORTS = "a name the exercise imports"
RUNS = "which runs code the review cannot read"
INTERNALS = "which reaches into the internals of functions and classes"
SOURCE = "which reads the source code of other modules"
SHELL = "which reaches into the IPython shell or kernel"
FRAMES = "which reaches into running code's frames and objects"
HOOKS = "which hooks into the interpreter"
PATCHES = "patching something imported"
CHANGES = "changing something imported"
REFERENCE = "where the reference code is"
LOADS = "which loads objects or code from bytes"

FORGERIES = {
    # 1. rebinding a name the release imports, writing into an imported namespace
    "rebind-by-assignment": ("class Fake:\n    def __getattr__(self, name):\n"
                             "        return lambda fn: print(name + ': passed')\nchecks = Fake()",
                             f"rebinds `checks`, {IMPORTS}"),
    "rebind-by-def": ("def np():\n    pass", f"rebinds `np`, {IMPORTS}"),
    "rebind-by-class": ("class plt:\n    pass", f"rebinds `plt`, {IMPORTS}"),
    "rebind-by-augmented-assignment": ("CORRIDOR += 0", f"rebinds `CORRIDOR`, {IMPORTS}"),
    "rebind-by-annotated-assignment": ("checks: object = None", f"rebinds `checks`, {IMPORTS}"),
    "rebind-by-for": ("for checks in [None]:\n    pass", f"rebinds `checks`, {IMPORTS}"),
    "rebind-by-with": ("import contextlib\nwith contextlib.nullcontext() as np:\n    pass", f"rebinds `np`, {IMPORTS}"),
    "rebind-by-walrus-in-comprehension": ("[(checks := f) for f in [print]]", f"rebinds `checks`, {IMPORTS}"),
    "rebind-by-except": ("try:\n    pass\nexcept Exception as np:\n    pass", f"rebinds `np`, {IMPORTS}"),
    "rebind-in-if-block": ("if True:\n    corridor_scenario = print", f"rebinds `corridor_scenario`, {IMPORTS}"),
    "rebind-by-import": ("from kalman_course import plotting as checks",
                         f"rebinds `checks`, {IMPORTS}, to `kalman_course.plotting`"),
    "delete": ("del checks", f"deletes `checks`, {IMPORTS}"),
    "global-declaration": ("def patch():\n    global checks\n    checks = None",
                           f"declares `global checks`, so that a function can rebind {IMPORTS}"),
    "vars-of-module-written": ("vars(checks)['histogram_update'] = lambda fn: print('histogram_update: passed')",
                               f"writes into the namespace of `vars(checks)` (`kalman_course.checks`), {CHANGES}"),
    "module-dict-written": ("np.__dict__['allclose'] = lambda *a, **k: True",
                            f"writes into the namespace of `np.__dict__` (`numpy`), {CHANGES}"),
    "vars-of-module-updated": ("import numpy\nvars(numpy).update(allclose=lambda *a, **k: True)",
                               f"writes into the namespace of `vars(numpy)` (`numpy`), {CHANGES}"),
    "setattr-on-module": ("setattr(np, 'allclose', lambda *a, **k: True)",
                          f"calls `setattr` on `np` (`numpy`), {CHANGES}"),
    "object-setattr-on-module": ("object.__setattr__(np, 'isclose', print)",
                                 f"calls `__setattr__` on `np` (`numpy`), {CHANGES}"),
    # 2. running or building code the review cannot read
    "exec": ('exec("checks.histogram_update = print")', f"uses `exec` (`builtins.exec`), {RUNS}"),
    "exec-through-an-alias": ("run = exec\nrun('x = 1')", f"uses `run` (`builtins.exec`), {RUNS}"),
    "exec-through-builtins": ("__builtins__.exec('x = 1')", f"uses `__builtins__.exec` (`builtins.exec`), {RUNS}"),
    "eval": ('eval("print")', f"uses `eval` (`builtins.eval`), {RUNS}"),
    "compile": ('code = compile("x = 1", "<learner>", "exec")', f"uses `compile` (`builtins.compile`), {RUNS}"),
    "dunder-import": ('bayes = __import__("kalman_course.filters.bayes")',
                      "uses `__import__` (`builtins.__import__`), which imports a module named at run time"),
    "runpy": ("import runpy", f"imports `runpy`, {RUNS}"),
    "function-type": ("import types\nf = types.FunctionType(sensor_likelihood.__code__, {})",
                      "uses `types.FunctionType`, which builds a function from a code object"),
    "code-type": ("from types import CodeType\nc = CodeType",
                  "imports `types.CodeType`, which builds a function from a code object"),
    "code-assigned": ("def mine():\n    pass\nmine.__code__ = sensor_likelihood.__code__",
                      "assigns to `mine.__code__`, swapping the internals of an object"),
    "class-assigned": ("x = np.float64(1.0)\nx.__class__ = float",
                       "assigns to `x.__class__`, swapping the internals of an object"),
    "globals-of-a-function": ("(lambda: 0).__globals__['checks'] = None",
                              f"uses `(lambda: 0).__globals__`, {INTERNALS}"),
    "pickle-loads": ("import pickle\nf = pickle.loads(b'')", f"uses `pickle.loads`, {LOADS}"),
    "marshal-loads": ("import marshal\nf = marshal.loads(b'')", f"uses `marshal.loads`, {LOADS}"),
    # 3. reading source code
    "getsource": ("import inspect\nfrom kalman_course.filters import bayes\nexec(inspect.getsource(bayes))",
                  f"uses `inspect.getsource`, {SOURCE}"),
    "getsourcelines-aliased": ("from inspect import getsourcelines as lines\nlines(print)",
                               f"uses `lines` (`inspect.getsourcelines`), {SOURCE}"),
    "getfile": ("import inspect\npath = inspect.getfile(checks)", f"uses `inspect.getfile`, {SOURCE}"),
    "package-file": ("import kalman_course, os\n"
                     "text = open(os.path.join(os.path.dirname(kalman_course.__file__), 'filters', 'bayes.py')).read()",
                     "reads `kalman_course.__file__`, which locates the source files of the course's code"),
    "solutions-path": ("text = open('../solutions/01_bayes_rule.ipynb').read()",
                       f"names a path under `solutions/` ('../solutions/01_bayes_rule.ipynb'), {REFERENCE}"),
    "solutions-run-by-a-magic": ("%run ../solutions/01_bayes_rule.ipynb",
                                 f"names a path under `solutions/` ('../solutions/01_bayes_rule.ipynb'), {REFERENCE}"),
    "package-path": ("text = open('/venv/kalman_course/filters/bayes.py').read()",
                     "names a path inside the `kalman_course` package ('/venv/kalman_course/filters/bayes.py'), "
                     + REFERENCE),
    # 4. IPython hooks
    "shell-in-a-variable": ("ip = get_ipython()", f"gets the IPython shell (`get_ipython()`) outside a magic, {SHELL}"),
    "set-custom-exc": ("ip = get_ipython()\nip.set_custom_exc((AssertionError,), lambda *a, **k: print('passed'))",
                       f"uses `ip.set_custom_exc` (`get_ipython().set_custom_exc`), {SHELL}"),
    "input-transformer": ("get_ipython().input_transformers_cleanup.append(lambda lines: lines)",
                          f"uses `get_ipython().input_transformers_cleanup.append`, {SHELL}"),
    "ast-transformer": ("import IPython\nIPython.get_ipython().ast_transformers.append(None)",
                        "uses `IPython.get_ipython().ast_transformers.append` "
                        f"(`get_ipython().ast_transformers.append`), {SHELL}"),
    "events": ("get_ipython().events.register('post_run_cell', print)",
               f"uses `get_ipython().events.register`, {SHELL}"),
    "register-magic": ("get_ipython().register_magic_function(print)",
                       f"uses `get_ipython().register_magic_function`, {SHELL}"),
    "display-formatter": ("get_ipython().display_formatter.formatters.clear()",
                          f"uses `get_ipython().display_formatter.formatters.clear`, {SHELL}"),
    "showtraceback-replaced": ("get_ipython().showtraceback = lambda *a, **k: None",
                               f"uses `get_ipython().showtraceback`, {SHELL}"),
    "run-cell-overridden": ("get_ipython().run_cell = print", f"uses `get_ipython().run_cell`, {SHELL}"),
    "user-ns": ("get_ipython().user_ns['checks'] = None", f"uses `get_ipython().user_ns`, {SHELL}"),
    "shell-class": ("from IPython.core.interactiveshell import InteractiveShell\nshell = InteractiveShell.instance()",
                    f"imports `IPython.core.interactiveshell.InteractiveShell`, {SHELL}"),
    "ipython-flag": ("running_in_ipython = __IPYTHON__", f"uses `__IPYTHON__`, {SHELL}"),
    # 5. frames and interpreter hooks
    "getframe-in-the-learner-function": ("import sys\ndef sensor_likelihood(world, z, p_correct):\n"
                                         "    caller = sys._getframe(1)\n    return world",
                                         f"uses `sys._getframe`, {FRAMES}"),
    "getframe-imported-under-another-name": ("from sys import _getframe as g\nframe = g()",
                                             f"uses `g` (`sys._getframe`), {FRAMES}"),
    "settrace-through-an-alias": ("import sys\ns = sys\ns.settrace(None)",
                                  f"uses `s.settrace` (`sys.settrace`), {FRAMES}"),
    "settrace-through-a-default": ("import sys\ndef install(s=sys):\n    s.settrace(None)",
                                   f"uses `s.settrace` (`sys.settrace`), {FRAMES}"),
    "sys-reexported-by-os": ("import os\nos.sys.settrace(None)", f"uses `os.sys.settrace`, {FRAMES}"),
    "setprofile": ("import sys\nsys.setprofile(None)", f"uses `sys.setprofile`, {FRAMES}"),
    "threading-settrace": ("import threading\nthreading.settrace(print)", f"uses `threading.settrace`, {FRAMES}"),
    "currentframe": ("import inspect\nframe = inspect.currentframe()", f"uses `inspect.currentframe`, {FRAMES}"),
    "stack": ("import inspect\nframes = inspect.stack()", f"uses `inspect.stack`, {FRAMES}"),
    "getouterframes": ("from inspect import getouterframes\ngetouterframes(None)",
                       f"imports `inspect.getouterframes`, {FRAMES}"),
    "f-back-f-locals": ("def spy(frame):\n    return frame.f_back.f_locals", f"uses `frame.f_back.f_locals`, {FRAMES}"),
    "f-globals": ("def spy(frame):\n    frame.f_globals['checks'] = None", f"uses `frame.f_globals`, {FRAMES}"),
    "tb-frame": ("try:\n    1 / 0\nexcept ZeroDivisionError as error:\n    frame = error.__traceback__.tb_frame",
                 f"uses `error.__traceback__.tb_frame`, {FRAMES}"),
    "gc-get-referrers": ("import gc\nholders = gc.get_referrers(np.allclose)", f"uses `gc.get_referrers`, {FRAMES}"),
    "gc-get-objects": ("import gc\nobjects = gc.get_objects()", f"uses `gc.get_objects`, {FRAMES}"),
    "ctypes": ("import ctypes", f"imports `ctypes`, {FRAMES}"),
    "meta-path": ("import sys\nsys.meta_path.insert(0, None)", f"uses `sys.meta_path.insert`, {HOOKS}"),
    "path-hooks": ("import sys\nsys.path_hooks.append(print)", f"uses `sys.path_hooks.append`, {HOOKS}"),
    "audit-hook": ("import sys\nsys.addaudithook(print)", f"uses `sys.addaudithook`, {HOOKS}"),
    # 6. patching numpy, builtins, classes of imported modules
    "np-allclose": ("np.allclose = lambda *a, **k: True", f"assigns to `np.allclose` (`numpy.allclose`), {PATCHES}"),
    "numpy-aliased": ("import numpy as n\nn.isclose = lambda *a, **k: True",
                      f"assigns to `n.isclose` (`numpy.isclose`), {PATCHES}"),
    "numpy-testing": ("import numpy.testing\nnumpy.testing.assert_allclose = print",
                      f"assigns to `numpy.testing.assert_allclose`, {PATCHES}"),
    "np-linalg": ("np.linalg.solve = print", f"assigns to `np.linalg.solve` (`numpy.linalg.solve`), {PATCHES}"),
    "ndarray-eq": ("np.ndarray.__eq__ = lambda a, b: True",
                   f"assigns to `np.ndarray.__eq__` (`numpy.ndarray.__eq__`), {PATCHES}"),
    "np-deleted-attribute": ("del np.isclose", f"deletes `np.isclose` (`numpy.isclose`), {PATCHES}"),
    "builtins-print": ("import builtins\nbuiltins.print = lambda *a, **k: None",
                       "assigns to `builtins.print`, patching a builtin"),
    "dunder-builtins-attribute": ("__builtins__.len = lambda x: 0",
                                  "assigns to `__builtins__.len` (`builtins.len`), patching a builtin"),
    "class-of-an-imported-module": ("from collections import OrderedDict\nOrderedDict.__eq__ = lambda a, b: True",
                                    f"assigns to `OrderedDict.__eq__` (`collections.OrderedDict.__eq__`), {PATCHES}"),
    "main-module": ("import __main__\n__main__.checks = None", f"assigns to `__main__.checks`, {PATCHES}"),
    # 7. star-imports, getattr on course modules, globals() writes
    "star-import": ("from kalman_course.filters.bayes import *",
                    "star-imports `kalman_course.filters.bayes` (`from kalman_course.filters.bayes import *`), "
                    "which the exercise does not"),
    "getattr-of-the-function-to-write": ("import kalman_course.filters.bayes as kb\n"
                                         "histogram_update = getattr(kb, 'histogram_update')",
                                         "gets `histogram_update` by name (`getattr`) instead of writing it"),
    "getattr-on-a-course-module": ("import kalman_course.filters.bayes as kb\nname = 'histogram' + '_update'\n"
                                   "f = getattr(kb, name)",
                                   "calls `getattr` on `kb` (`kalman_course.filters.bayes`), a course module"),
    "getattr-on-a-course-module-imported-at-run-time": (
        "import importlib\n"
        "f = getattr(importlib.import_module('kalman_course.filters.bayes'), 'histogram' + '_update')",
        "calls `getattr` on `importlib.import_module('kalman_course.filters.bayes')` "
        "(`kalman_course.filters.bayes`), a course module"),
    "getattr-on-a-module-named-at-run-time": ("import importlib\nm = importlib.import_module('kalman' + '_course')\n"
                                              "f = getattr(m, 'x')",
                                              "calls `getattr` on a module imported at run time"),
    "getattr-on-sys-with-a-computed-name": ("import sys\nspy = getattr(sys, '_get' + 'frame')",
                                            "calls `getattr` on `sys` with a computed name"),
    "getattr-of-a-frame-function": ("import sys\nspy = getattr(sys, '_getframe')",
                                    f"uses `getattr(sys, '_getframe')` (`sys._getframe`), {FRAMES}"),
    "attrgetter": ("import operator\nfrom kalman_course.filters import bayes\n"
                   "f = operator.attrgetter('histogram_update')(bayes)",
                   "gets `histogram_update` by name (`operator.attrgetter`) instead of writing it"),
    "attrgetter-on-a-course-module": ("import operator\nfrom kalman_course.filters import bayes\n"
                                      "f = operator.attrgetter('x')(bayes)",
                                      "applies `operator.attrgetter('x')` to a course module"),
    "vars-of-a-course-module-read": ("from kalman_course.filters import bayes\nf = vars(bayes)['histogram_update']",
                                     "reads the namespace of a course module (`vars(bayes)`)"),
    "globals-binds-the-function": ("from kalman_course.filters import bayes\n"
                                   "globals()['histogram_update'] = bayes.histogram_update",
                                   "binds `histogram_update` through `globals()` instead of writing it"),
    "globals-update-rebinds": ("globals().update({'checks': None})",
                               f"rebinds `checks`, {IMPORTS}, through `globals()`"),
    "globals-computed-name": ("name = 'histogram' + '_update'\nglobals()[name] = print",
                              "writes into `globals()` under a computed name"),
    "locals-binds-the-function": ("locals().setdefault('histogram_predict', print)",
                                  "binds `histogram_predict` through `locals()` instead of writing it"),
    "vars-binds-the-function": ("vars()['sensor_likelihood'] = print",
                                "binds `sensor_likelihood` through `vars()` instead of writing it"),
    # a function to write that only hands its work to a course function under another name
    "delegation-to-a-course-function": ("from kalman_course.filters.bayes import normalise\n"
                                        "def histogram_predict(belief, transition):\n"
                                        "    \"\"\"Docstring.\"\"\"\n"
                                        "    return normalise(belief)",
                                        "`histogram_predict` only returns what `normalise` "
                                        "(`kalman_course.filters.bayes.normalise`) returns, "
                                        "a course function, instead of doing the work"),
    # a function to write that calls a course function its solution does not (the reference of a
    # graded answer under another name, in more than one line)
    "course-function-the-solution-does-not-call": ("from kalman_course.filters.bayes import normalise\n"
                                                   "def histogram_predict(belief, transition):\n"
                                                   "    predicted = normalise(transition @ belief)\n"
                                                   "    return predicted",
                                                   "`histogram_predict` calls `normalise` "
                                                   "(`kalman_course.filters.bayes.normalise`), a course "
                                                   "function that the exercise's version of it does not use"),
    # signalling the process that runs the grading
    "kill": ("import os, signal\nos.kill(os.getppid(), signal.SIGKILL)",
             "uses `os.kill`, which signals other processes"),
    # the graders' own code computes the expected values: reaching past the checks is flagged
    "graders-internals": ("cases = checks.bayes._update_cases()",
                          "uses `checks.bayes._update_cases` (`kalman_course.checks.bayes._update_cases`), "
                          "the graders' own code (it computes the expected values)"),
    "graders-submodule": ("h = checks.harness", "uses `checks.harness` (`kalman_course.checks.harness`), "
                          "the graders' own code (it computes the expected values)"),
    "graders-by-full-path": ("import kalman_course\nref = kalman_course.checks.bayes",
                             "uses `kalman_course.checks.bayes`, the graders' own code (it computes the "
                             "expected values)"),
    "private-course-name": ("from kalman_course.filters import bayes as b\nf = b._normalised",
                            "uses `b._normalised` (`kalman_course.filters.bayes._normalised`), a private "
                            "name of the course's code"),
    "private-course-import": ("from kalman_course.filters.bayes import _normalised",
                              "imports `_normalised` from `kalman_course.filters.bayes`, a private name of the "
                              "course's code"),
    # the Python that magics run is read as well
    "hidden-in-capture": ("%%capture\nchecks = None", f"rebinds `checks`, {IMPORTS}"),
    "hidden-in-timeit": ("%timeit -n1 -r1 np.allclose = print",
                         f"assigns to `np.allclose` (`numpy.allclose`), {PATCHES}"),
    "hidden-in-writefile": ("%%writefile helper.py\nimport sys\nsys.settrace(None)", f"uses `sys.settrace`, {FRAMES}"),
}


@pytest.mark.parametrize("name", FORGERIES)
def test_forgery_techniques_are_flagged(name):
    source, expected = FORGERIES[name]
    assert f"cell extra: {expected}" in _extra_flags(source)


HONEST = {
    "allclose-called": "ok = np.allclose(np.ones(2), np.ones(2)) and np.isclose(1.0, 1.0)",
    "getattr-on-an-array": "a = np.zeros((2, 3))\nprint(getattr(a, 'shape'), getattr(a, 'ndim', 0))",
    "loop-variable": "for k in range(3):\n    print(k)",
    "own-helper-named-like-numpy": ("def allclose(a, b):\n    return np.all(np.abs(a - b) < 1e-9)\n"
                                    "allclose(np.ones(1), np.ones(1))"),
    "own-function-named-like-a-builtin": "def compile(parts):\n    return list(parts)\ncompile('ab')",
    "plots": ("fig, ax = plt.subplots()\nax.plot([1, 2])\nax.set_title('belief')\n"
              "plt.rcParams['figure.figsize'] = (8, 4)\nplt.show()"),
    "local-shadowing": "def f():\n    np = 3\n    checks = 4\n    return np + checks",
    "parameter-named-like-a-module": "def scale(np, plt):\n    np.factor = 2\n    plt.title = 'x'\n    return np",
    "comprehension-variable-named-like-a-module": "squares = [np * np for np in range(3)]",
    "lambda-parameter-named-like-a-module": "total = lambda np: np.sum()",
    "local-import-in-a-function": "def f():\n    import numpy as np\n    return np.eye(2)",
    "magics": "%matplotlib inline\n%load_ext autoreload\n%autoreload 2\n!ls\nfiles = !ls",
    "timeit-of-honest-code": "%timeit -n1 -r1 np.allclose(np.ones(2), np.ones(2))",
    "time-of-honest-code": "%%time\nx = np.linalg.solve(np.eye(2), np.ones(2))",
    "help": "help(np.allclose)\nnp.allclose?",
    "reimports": "import numpy as np\nimport matplotlib.pyplot as plt\nfrom kalman_course.plotting import plot_belief",
    "other-libraries": "import re\nimport scipy.linalg as sla\npattern = re.compile('a')\nL = sla.cholesky(np.eye(2))",
    "display": "from IPython.display import display, Markdown\ndisplay(Markdown('**belief**'))",
    "numpy-state": "np.random.seed(0)\nnp.set_printoptions(precision=3)",
    "own-class": ("import dataclasses\n@dataclasses.dataclass(frozen=True)\nclass Pose:\n    x: float\n"
                  "    def __post_init__(self):\n        object.__setattr__(self, 'x', float(self.x))\n"
                  "    def __eq__(self, other):\n        return self.x == other.x"),
    "own-object-attributes": "class State:\n    pass\ns = State()\ns.x = np.zeros(2)\ns.__dict__.update(P=np.eye(2))",
    "in-place-array-updates": "belief = np.full(5, 0.2)\nbelief /= belief.sum()\nbelief[0] = 1.0",
    "exceptions": "try:\n    1 / 0\nexcept ZeroDivisionError as error:\n    print(error)",
    "globals-read": "print(sorted(globals())[:3])",
    "exits": "import os\nif False:\n    os._exit(1)",
    "own-check-runs": ("try:\n    checks.histogram_update(lambda p, l: p)\nexcept checks.CheckFailed as error:\n"
                       "    print(error)"),
}


@pytest.mark.parametrize("name", HONEST)
def test_honest_code_is_not_flagged(name):
    assert _extra_flags(HONEST[name]) == []


@pytest.mark.parametrize("chapter", CHAPTERS)
def test_every_chapter_knows_what_its_release_imports(chapter):
    """Whatever a chapter's setup cell imports, rebinding `checks` or patching numpy is seen."""
    nb = _solved(chapter)
    cell = new_code_cell("checks = None\nnp.allclose = lambda *a, **k: True")
    cell["id"] = "extra"
    nb.cells.insert(1, cell)
    assert review_flags(nb, _release(chapter)) == [
        "cell extra: assigns to `np.allclose` (`numpy.allclose`), patching something imported",
        "cell extra: rebinds `checks`, a name the exercise imports"]


def test_an_edited_setup_cell_may_repeat_its_imports_but_not_change_them():
    nb = _solved(CH01)
    setup = next(c for c in nb.cells if c["id"] == "setup")
    setup.source += "\nimport numpy as np\nfrom kalman_course import checks"
    assert review_flags(nb, _release(CH01)) == []
    edited = setup.source
    setup.source = edited + "\nimport jax.numpy as np"
    assert review_flags(nb, _release(CH01)) == [  # jax is not installed: the import would fail, or run code unread
        "cell setup: imports `jax.numpy`, a module that is not installed and whose code is not in the notebook",
        "cell setup: rebinds `np`, a name the exercise imports, to `jax.numpy`"]
    setup.source = edited + "\nnp.allclose = print"  # the released cell's own flags are no cover for new ones
    assert review_flags(nb, _release(CH01)) == [
        "cell setup: assigns to `np.allclose` (`numpy.allclose`), patching something imported"]


def test_only_module_level_rebinding_counts():
    """A function's own `checks` is local; the same assignment at module level is not."""
    inside = "def helper():\n    checks = None\n    return checks"
    assert _extra_flags(inside) == []
    assert _extra_flags(inside + "\nchecks = helper()") == ["cell extra: rebinds `checks`, a name the exercise imports"]


def test_code_nested_too_deeply_to_walk_is_a_flag_not_a_failure():
    assert _extra_flags("x = " + " + ".join(["1"] * 200)) == []
    assert _extra_flags("x = " + " + ".join(["1"] * 3000)) == [
        "cell extra: nests code too deeply for the review to read it"]
    # deeper still, the parser itself gives up (where exactly depends on the stack left)
    assert _extra_flags("x = " + " + ".join(["1"] * 30000)) == [
        "cell extra: nests code too deeply for the review to read it"]
