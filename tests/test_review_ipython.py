"""The review reads what IPython runs (issue 24, item 3): each forging cell below runs code that
the cell's Python text does not show (magics under new names, automagic, autocall, files written
and then run or imported, shells, the IPython shell reached under another name, a source
encoding declaration), and must carry a flag naming it; the honest cells must carry none."""

import base64
import copy
import functools

import nbformat
import pytest
from nbformat.v4 import new_code_cell

from kalman_course.tooling import authoring
from kalman_course.tooling.review import review_flags

from conftest import ROOT

CH03 = "03_kalman_filter.ipynb"
REFERENCE = "from kalman_course.filters.kf import kf_update"
PAYLOAD = base64.b64encode(REFERENCE.encode()).decode()


@functools.lru_cache(maxsize=None)
def _read(folder, chapter):
    return nbformat.read(ROOT / folder / chapter, as_version=4)


def _solved(chapter=CH03):
    """The released exercise with the solution's code in every non-grader cell."""
    exercise = copy.deepcopy(_read("exercises", chapter))
    solution = authoring.render(_read("solutions", chapter), set())
    sources = {c["id"]: c.source for c in solution.cells}
    for cell in exercise.cells:
        if authoring.grader_info(cell) is None and cell["id"] in sources:
            cell.source = sources[cell["id"]]
    return exercise


def _flags(*sources):
    """The review of the solved chapter 03 with ``sources`` appended as cells a0, a1, ..."""
    nb = _solved()
    for k, source in enumerate(sources):
        cell = new_code_cell(source)
        cell["id"] = f"a{k}"
        nb.cells.append(cell)
    return review_flags(nb, copy.deepcopy(_read("exercises", CH03)))


def _names(flags, cell):
    return [f for f in flags if f.startswith(f"cell {cell}: ")]


READS_LATER = "which changes how IPython reads later cells"

#: name -> (the cells appended, the cells that must carry a flag)
ATTACKS = {
    # magics under a new name, and settings that change how later cells are read
    "alias-magic-of-capture": (["%alias_magic c capture", f"%%c\n{REFERENCE}"], ["a0", "a1"]),
    "alias-magic-cell-only-with-params": (["%alias_magic --cell -p '-q' quiet capture",
                                           f"%%quiet\nimport kalman_course.filters.kf as k\nkf_update = k.kf_update"],
                                          ["a0", "a1"]),
    "alias-magic-line-of-time": (["%alias_magic t time", f"%t {REFERENCE}"], ["a0", "a1"]),
    "alias-magic-by-automagic": (["alias_magic c capture", f"%%c\n{REFERENCE}"], ["a0", "a1"]),
    "autocall-then-exec": (["%autocall 1", f'exec "{REFERENCE}"'], ["a0", "a1"]),
    "autocall-by-config": (["%config InteractiveShell.autocall = 2", f'exec "{REFERENCE}"'], ["a0", "a1"]),
    "alias-magic-of-an-alias": (["%alias_magic a capture\n%alias_magic b a", f"%%b\n{REFERENCE}"], ["a0", "a1"]),
    "alias-magic-by-the-call-ipython-writes": (["get_ipython().run_line_magic('alias_magic', 'c capture')",
                                                f"%%c\n{REFERENCE}"], ["a0", "a1"]),
    "autocall-by-kernel-config": (["%config ZMQInteractiveShell.autocall=1"], ["a0"]),
    "automagic-off": (["%automagic off"], ["a0"]),
    "system-alias-runs-python": (["%alias go python m.py", "%go"], ["a0", "a1"]),
    "rehashx-then-a-program": (["%rehashx", "python3 m.py"], ["a0", "a1"]),
    "macro": (["code = 'x = 1'\n%macro m code"], ["a0"]),
    "store-restores": (["%store -r kf_update"], ["a0"]),
    # automagic: a first word that names a line magic, no `%`
    "automagic-time": ([f"time {REFERENCE}"], ["a0"]),
    "automagic-timeit": (["timeit -n1 -r1 checks.kf_update = print"], ["a0"]),
    "automagic-run": (["run -i helper.py"], ["a0"]),
    "automagic-inside-capture": ([f"%%capture\ntime {REFERENCE}"], ["a0"]),
    # files written, then run, loaded or imported
    "writefile-then-run": (["%%writefile m.py\nimport kalman_course.filters.kf as k\nkf_update = k.kf_update",
                            "%run -i m.py"], ["a0", "a1"]),
    "writefile-appended-then-imported": (["%%writefile m.py\nx = '''", f"%%writefile -a m.py\n'''\n{REFERENCE}",
                                          "from m import *"], ["a2"]),
    "writefile-then-load": ([f"%%writefile m.py\n{REFERENCE}", "%load m.py"], ["a0"]),
    "writefile-extension": (["%%writefile ext.py\ndef load_ipython_extension(ip):\n    ip.push({'x': 1})",
                             "%load_ext ext"], ["a1"]),
    "run-of-an-unknown-file": (["%run -i helper.py"], ["a0"]),
    "run-of-a-course-module": (["%run -m kalman_course.filters.kf"], ["a0"]),
    "load-of-an-unknown-file": (["%load helper.py"], ["a0"]),
    "load-ext-of-an-unknown-module": (["%load_ext helper"], ["a0"]),
    "python-write-then-import": ([f"open('m.py', 'w').write({REFERENCE!r})", "import m"], ["a1"]),
    "python-write-in-a-with": ([f"with open('m.py', 'w') as f:\n    f.write({REFERENCE!r})", "from m import kf_update"],
                               ["a1"]),
    "python-write-of-computed-text": ([f"import base64\n"
                                       f"open('m.py', 'w').write(base64.b64decode('{PAYLOAD}').decode())",
                                       "import m"], ["a0", "a1"]),
    "pathlib-write-of-computed-name": (["from pathlib import Path\nPath('m' + '.py').write_text(code)", "import m"],
                                       ["a0", "a1"]),
    "bash-heredoc-then-import": ([f"%%bash\ncat > m.py <<'EOF'\n{REFERENCE}\nEOF", "import m"], ["a0", "a1"]),
    "sh-heredoc-expanded": ([f"%%sh\ncat <<EOF > m.py\n{REFERENCE} $X\nEOF", "import m"], ["a0", "a1"]),
    "shell-line-writes-a-module": ([f"!echo '{REFERENCE}' > m.py", "import m"], ["a0", "a1"]),
    "shell-copies-a-module": (["!cp /tmp/elsewhere/kf.py .", "import kf"], ["a0", "a1"]),
    "shell-tee-heredoc": ([f"%%bash\ntee m.py <<'EOF' > /dev/null\n{REFERENCE}\nEOF"], ["a0"]),
    "shell-downloads-a-module": (["!curl -s -o m.py https://example.org/m.py", "import m"], ["a0", "a1"]),
    "shell-clones-a-package": (["!git clone https://example.org/helpers.git", "import helpers"], ["a1"]),
    "python-downloads-a-module": (["import urllib.request\nurllib.request.urlretrieve('https://example.org/x', 'm.py')",
                                   "import m"], ["a1"]),
    "site-runs-pth-files": (["import site\nsite.addsitedir('.')"], ["a0"]),
    "vars-of-exit-holds-the-shell": (["vars(exit)['_ip'].ex('x = 1')"], ["a0"]),
    "python2-cell-magic-is-read": (["%%python2\nimport kalman_course.checks as c\nc.kf_update = print"], ["a0"]),
    "matplotlib-backend-module": (["%matplotlib module://mybackend"], ["a0"]),
    "matplotlib-backend-written": ([f"%%writefile mybackend.py\n{REFERENCE}", "import matplotlib\n"
                                    "matplotlib.use('module://mybackend')"], ["a0", "a1"]),
    "compiled-module-written": (["open('__pycache__/m.cpython-311.pyc', 'wb').write(b'\\x00')", "import m"],
                                ["a0", "a1"]),
    "rerun-of-edited-history": (["In[-1] = 'x = 1'\n%rerun -l 1"], ["a0"]),
    "alias-named-like-a-magic-does-not-hide-it": (["%alias time echo", f"%time {REFERENCE}"], ["a0", "a1"]),
    "later-write-does-not-hide-an-earlier-one": ([f"open('m.py', 'w').write({REFERENCE!r})", "import m",
                                                  "open('m.py', 'w').write('x = 1')"], ["a1"]),
    "shell-runs-python": (["!python -c 'print(1)'"], ["a0"]),
    "shell-runs-sys-executable": (["import sys\n!{sys.executable} m.py"], ["a0"]),
    "sx-runs-python": (["%sx python3 m.py"], ["a0"]),
    "script-bash-runs-python": (["%%script bash\npython3 - <<EOF\nprint(1)\nEOF"], ["a0"]),
    "pip-install-of-a-path": (["!pip install ./helpers"], ["a0"]),
    "subprocess-runs-python": (["import subprocess, sys\nsubprocess.run([sys.executable, 'm.py'])"], ["a0"]),
    "os-system-computed": (["import os\ncmd = 'py' + 'thon m.py'\nos.system(cmd)"], ["a0"]),
    "unknown-module": (["import kf_helpers"], ["a0"]),
    "script-python-body-is-read": ([f"%%script python3\n{REFERENCE}"], ["a0"]),
    "unknown-cell-magic": (["%%mystery\nanything"], ["a0"]),
    # the shell's own runners, reached under any name
    "globals-get-ipython-run-cell": ([f"import base64\nglobals()['get_ipython']().run_cell("
                                      f"base64.b64decode('{PAYLOAD}').decode())"], ["a0"]),
    "vars-get-ipython": (["vars()['get_ipython']().ex('x = 1')"], ["a0"]),
    "globals-get": (["globals().get('get_ipython')().ev('1')"], ["a0"]),
    "alias-of-get-ipython": ([f"g = get_ipython\ng().run_line_magic('time', {REFERENCE!r})"], ["a0"]),
    "builtins-get-ipython": (["import builtins\nbuiltins.get_ipython().run_cell('x = 1')"], ["a0"]),
    "main-get-ipython": (["import __main__\ngetattr(__main__, 'get_ipython')().safe_execfile('m.py')"], ["a0"]),
    "getattr-with-a-built-name": (["shell = globals()['get_' + 'ipython']()\ngetattr(shell, 'run_' + 'cell')('x')"],
                                  ["a0"]),
    "methodcaller": (["import operator\noperator.methodcaller('run_cell', 'x = 1')(None)"], ["a0"]),
    "every-global-value": (["[v for k, v in globals().items() if k.endswith('ipython')][0]().run_cell('x')"],
                           ["a0"]),
    "exit-holds-the-shell": (["exit._ip.run_cell('x = 1')"], ["a0"]),
    "magic-with-computed-arguments": ([f"code = {REFERENCE!r}\nget_ipython().run_line_magic('time', code)"], ["a0"]),
    "expansion-in-a-shell-line": (["!echo {exec('x = 1')}"], ["a0"]),
    "expansion-in-a-magic-line": (["%matplotlib {exec('x = 1')}"], ["a0"]),
    # the source encoding: the text the review parses is not the code Python decodes
    "utf-7-cell": (["# coding: utf-7\nx = '+AGEA-'"], ["a0"]),
    "utf-7-module": (["%%writefile m.py\n# -*- coding: utf-7 -*-\nx = 1 +AAo-from kalman_course.filters.kf import "
                      "kf+AF8-update\n", "from m import kf_update"], ["a0", "a1"]),
    "latin-1-second-line": (["#!/usr/bin/env python\n# vim: set fileencoding=latin-1 :\nx = 1"], ["a0"]),
}


@pytest.mark.parametrize("name", ATTACKS)
def test_code_ipython_runs_unread_is_flagged_on_its_cell(name):
    sources, forging = ATTACKS[name]
    flags = _flags(*sources)
    for cell in forging:
        assert _names(flags, cell), f"{name}: no flag names cell {cell}: {flags}"


def test_the_flags_say_what_they_saw():
    assert f"cell a0: uses `%alias_magic c capture`, {READS_LATER}" in _flags("%alias_magic c capture")
    assert f"cell a0: uses `%autocall 1`, {READS_LATER}" in _flags("%autocall 1")
    assert ("cell a0: imports `kf_update` from `kalman_course.filters.kf` instead of writing it"
            in _flags(f"time {REFERENCE}"))
    assert ("cell a0: uses `globals()['get_ipython']().run_cell` (`get_ipython().run_cell`), which reaches into "
            "the IPython shell or kernel" in _flags("globals()['get_ipython']().run_cell('x')"))
    assert ("cell a0: declares the source encoding `utf-7`, so the Python that runs may not be the text the "
            "review reads" in _flags("# coding: utf-7\nx = 1"))
    assert ("cell a0: runs `helper.py` (`%run -i helper.py`), whose code is not in the notebook"
            in _flags("%run -i helper.py"))
    assert ("cell a0: imports `kf_helpers`, a module that is not installed and whose code is not in the notebook"
            in _flags("import kf_helpers"))


def test_a_decoded_module_is_read_as_python_decodes_it():
    """In UTF-7, ``+AAo-`` is a newline: the module imports the reference on a line of its own."""
    flags = _flags("%%writefile m.py\n# coding: utf-7\nx = 1 +AAo-from kalman_course.filters.kf import kf+AF8-update\n")
    assert "cell a0: imports `kf_update` from `kalman_course.filters.kf` instead of writing it" in flags


HONEST = {
    "timeit": "%timeit kf_predict(np.zeros(6), np.eye(6), np.eye(6), np.eye(6))",
    "timeit-cell": "%%timeit -n1 -r1 x = np.zeros(6)\nkf_predict(x, np.eye(6), np.eye(6), np.eye(6))",
    "time-cell": "%%time\nx = np.linalg.solve(np.eye(2), np.ones(2))",
    "matplotlib": "%matplotlib inline",
    "ls": "!ls",
    "ls-captured": "files = !ls\nprint(files)",
    "ls-python-files": "!ls *.py\n!cat README.md | head -n 3",
    "pip-list": "!pip list\n!pip install numpy",
    "python-m-pip-list": "import sys\n!{sys.executable} -m pip list",
    "capture": "%%capture output\nprint('hidden')",
    "autoreload": "%load_ext autoreload\n%autoreload 2",
    "config-output": ("%config InlineBackend.figure_format = 'retina'\n"
                      "%config InteractiveShell.ast_node_interactivity = 'all'"),
    "bash": "%%bash\necho hi\nls -l | wc -l\n# python is not run here\necho 'python'",
    "expansion-of-a-name": "path = '.'\n!ls {path}\n!echo $path",
    "magics-that-inspect": "%who\n%whos\n%pwd\n%precision 3\nnp.allclose?",
    "one-line-python": "print(kf_predict)",
    "one-line-assignment-named-like-a-magic": "time = 3.0",
    "one-line-call-of-a-bound-name-like-a-magic": "def run(x):\n    return x",
    "writefile-of-notes": "%%writefile notes.txt\nthe gain shrinks as P does",
    "python-writes-data": ("with open('out.txt', 'w') as f:\n    f.write(str(np.eye(2)))\n"
                           "for k in range(2):\n    open(f'run_{k}.csv', 'w').write('x')\n"
                           "np.save('belief.npy', np.ones(3))"),
    "utf-8-declaration": "# -*- coding: utf-8 -*-\nx = 1",
    "imports-of-installed-modules": "import scipy.linalg\nimport json, os.path\nfrom kalman_course import so3",
    "autoawait": "%autoawait asyncio",
    "matplotlib-inline-backend-by-name": ("import matplotlib\n"
                                          "matplotlib.use('module://matplotlib_inline.backend_inline')"),
    "writefile-of-a-helper-then-imported": ("%%writefile helper_math.py\nimport numpy as np\n\n"
                                            "def sym(P):\n    return (P + P.T) / 2"),
}


@pytest.mark.parametrize("name", HONEST)
def test_honest_ipython_is_not_flagged(name):
    assert _flags(HONEST[name]) == []


def test_a_one_line_cell_after_a_binding_of_a_magic_name_is_python():
    """`run(3)` calls the notebook's own `run` (IPython's automagic sees the name is bound)."""
    assert _flags("def run(x):\n    return x", "run (3)") == []
    assert _names(_flags("run (m.py)"), "a0"), "unbound, `run (m.py)` is `%run (m.py)`"


def test_a_helper_module_written_in_the_notebook_and_imported_is_read_not_flagged():
    helper = "%%writefile helper_math.py\nimport numpy as np\n\ndef sym(P):\n    return (P + P.T) / 2"
    assert _flags(helper, "from helper_math import sym\nprint(sym(np.eye(2)))\n%run -i helper_math.py") == []
