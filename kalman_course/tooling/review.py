"""Reasons to look at a graded submission by hand, found by reading its code.

Grading runs the learner's notebook, so code that passes a check without doing the work
can earn the points: importing the function the exercise asks for (the course ships its
reference implementations), changing the grading code or the libraries it uses from an
earlier cell, or reaching into the code that calls the learner's function. None of this
can be prevented inside the kernel, but all of it is visible in the source.
:func:`review_flags` reads the syntax tree of every code cell but the one taken as each
grader (:mod:`kalman_course.tooling.identify`; a cell that only carries a grader's id is
read) that differs from the released cell it was written into, as IPython runs it: after
IPython's own input transformations (magics, shell escapes, and for a one-line cell the
automagic and autocall that IPython's prefilter applies), with the Python that magics run
(``%time``, ``%timeit``, ``%%capture``, ``%%writefile``, the aliases ``%alias_magic`` makes),
what ``{...}`` in a magic's line or a shell command evaluates, here-documents, and the files
the notebook writes that ``%run``, ``%load_ext`` or an import run, read as well; and reports

- an import of a function the learner must write (one defined in a released cell with a
  ``# fix this`` line), or a binding or call of such a function through a module
  attribute (``histogram_update = bayes.histogram_update``), through ``getattr``,
  ``operator.attrgetter`` or a write into ``globals()``; and such a function whose whole
  body returns one call of a course function (the reference under another name);
- an import of the grading machinery (``kalman_course.checks``, ``kalman_course.tooling.grading``,
  nbval) that the release does not make, an assignment to an attribute of it, or
  ``setattr`` on it;
- an import of ``importlib`` or ``builtins``, or use of ``__builtins__`` or ``sys.modules``;
- a module-level rebinding (assignment, ``def``, ``class``, ``for``, ``with``, walrus,
  ``del``, ``except ... as``, another import) of a name the release binds by an import
  (``checks``, ``np``, ...), a ``global`` declaration of such a name, and a write into
  the namespace of anything imported (``vars(m)[...] = ...``, ``m.__dict__.update(...)``,
  ``setattr(m, ...)``);
- code that runs or builds code the review cannot read: ``exec``, ``eval``, ``compile``,
  ``__import__``, ``runpy``, ``types.FunctionType``/``CodeType``, ``marshal`` or
  ``pickle`` loads, and assignments to ``__code__``, ``__globals__``, ``__class__`` and
  similar internals of an object;
- reading source code: ``inspect.getsource`` and its relatives, ``__file__``/``__path__``
  of a course module, and string constants naming a path under ``solutions/`` or inside
  the ``kalman_course`` package;
- any use of the IPython shell object (``get_ipython()``: ``set_custom_exc``, input and
  AST transformers, events, ``user_ns``, ...) other than the calls IPython itself writes
  for magics and shell escapes, and IPython or kernel internals;
- frame and interpreter hooks: ``sys._getframe``, ``sys.settrace``/``setprofile``,
  ``threading.settrace``, ``inspect.currentframe``/``stack``, ``f_back``/``f_locals``/
  ``f_globals``/``tb_frame``, ``gc.get_referrers``/``get_objects``, ``ctypes``,
  ``sys.meta_path``/``path_hooks``/``addaudithook``, and ``os.kill`` of another process;
- an assignment to (or deletion of) an attribute of anything imported: numpy
  (``np.allclose = ...``, ``np.ndarray.__eq__ = ...``), builtins, a class of an imported
  module;
- a star-import the release does not make, and ``getattr``, ``vars`` or dunder access on a
  ``kalman_course`` module or on a module imported at run time;
- what changes how IPython reads later cells (``%autocall``, ``%automagic``, ``%alias_magic``,
  ``%alias``, ``%rehashx``, ``%macro``, ``%config`` of the shell's reading), and what IPython
  runs that the review cannot read: ``%run``, ``%load`` or ``%load_ext`` of a file or module
  whose code is not in the notebook (an extension written in it too: it is handed the shell),
  ``%store -r``, a cell magic it does not know, a shell (``!``, ``%%bash``, ``%sx``,
  ``subprocess``, ...) that runs Python, writes a Python file or installs from a path or URL,
  Python that writes a Python file with text it cannot read (or any file under a computed
  name), an import of a module that is neither installed nor written in the notebook, a magic
  call with computed arguments, the shell's runners (``run_cell``, ``ex``, ...) reached under any
  name (``globals()["get_ipython"]``, ``builtins.get_ipython``, ``getattr``, ``methodcaller``,
  a namespace's values), and a source encoding declaration other than UTF-8 or ASCII (the
  decoded text is read too).

Names are resolved through the notebook's imports and simple aliases (``import numpy as n``,
``s = sys``, ``from sys import _getframe as g``), scope by scope, so a function's own local
``np = 3`` or a parameter named like a module is not mistaken for the module.

The flags never change points or status: they are shown to the instructor (and to a
learner grading themselves) next to the grade.
"""

from __future__ import annotations

import ast
import builtins
import codecs
import functools
import importlib.util
import io
import keyword
import os
import re
import shlex
import sys
import tokenize
from dataclasses import dataclass, field

from kalman_course.tooling.cells import FIX_THIS, grader_info
from kalman_course.tooling.identify import identify_cells, same_code

__all__ = ["review_flags", "MACHINERY"]

#: Modules whose import by learner code is flagged: they run or report the checks.
MACHINERY = ("kalman_course.checks", "kalman_course.tooling.grading", "kalman_course.tooling.kernel_session", "nbval")
_ESCAPES = ("importlib", "builtins", "__builtins__")

#: What IPython's TransformerManager turns magics and shell escapes into: ``get_ipython().<method>(...)``.
_MAGIC_METHODS = frozenset({"run_line_magic", "run_cell_magic", "system", "getoutput"})
#: Magics whose argument (line) or body (cell) IPython runs or writes as Python.
_PYTHON_LINE_MAGICS = frozenset({"time", "timeit", "prun", "debug"})
_PYTHON_CELL_MAGICS = frozenset({"time", "timeit", "prun", "debug", "capture", "writefile", "file",
                                 "python", "python2", "python3", "pypy"})

_TOO_DEEP = "nests code too deeply for the review to read it"
_RUNS = "which runs code the review cannot read"
_BUILDS = "which builds a function from a code object"
_LOADS = "which loads objects or code from bytes"
_SOURCE = "which reads the source code of other modules"
_FRAMES = "which reaches into running code's frames and objects"
_HOOKS = "which hooks into the interpreter"
_SHELL = "which reaches into the IPython shell or kernel"
_MODULES = "which reaches the loaded modules"
_BY_NAME = "which gets a module's contents by name"

#: Dotted paths (and everything under them) whose use is flagged, with the reason.
_RISKY = {
    "builtins.exec": _RUNS, "builtins.eval": _RUNS, "builtins.compile": _RUNS,
    "builtins.__import__": "which imports a module named at run time",
    "runpy": _RUNS, "site.addsitedir": _RUNS, "site.addpackage": _RUNS, "site.main": _RUNS,  # run .pth lines
    "code.InteractiveInterpreter": _RUNS, "code.InteractiveConsole": _RUNS,
    "types.FunctionType": _BUILDS, "types.LambdaType": _BUILDS, "types.CodeType": _BUILDS,
    "marshal.load": _LOADS, "marshal.loads": _LOADS, "pickle.load": _LOADS, "pickle.loads": _LOADS,
    "pickle.Unpickler": _LOADS, "_pickle": _LOADS, "dill.load": _LOADS, "dill.loads": _LOADS,
    "cloudpickle.load": _LOADS, "cloudpickle.loads": _LOADS,
    "inspect.getsource": _SOURCE, "inspect.getsourcelines": _SOURCE, "inspect.getsourcefile": _SOURCE,
    "inspect.getfile": _SOURCE, "inspect.findsource": _SOURCE, "inspect.getmembers": _BY_NAME,
    "linecache": _SOURCE, "pkgutil.get_data": _SOURCE,
    "sys._getframe": _FRAMES, "sys._current_frames": _FRAMES, "sys.settrace": _FRAMES, "sys.setprofile": _FRAMES,
    "threading.settrace": _FRAMES, "threading.setprofile": _FRAMES, "threading.settrace_all_threads": _FRAMES,
    "threading.setprofile_all_threads": _FRAMES, "inspect.currentframe": _FRAMES, "inspect.stack": _FRAMES,
    "inspect.trace": _FRAMES, "inspect.getouterframes": _FRAMES, "inspect.getinnerframes": _FRAMES,
    "traceback.walk_stack": _FRAMES, "traceback.walk_tb": _FRAMES, "gc.get_referrers": _FRAMES,
    "gc.get_referents": _FRAMES, "gc.get_objects": _FRAMES, "ctypes": _FRAMES, "_ctypes": _FRAMES,
    "sys.meta_path": _HOOKS, "sys.path_hooks": _HOOKS, "sys.path_importer_cache": _HOOKS,
    "sys.addaudithook": _HOOKS, "sys.excepthook": _HOOKS, "sys.displayhook": _HOOKS, "sys.monitoring": _HOOKS,
    "sys.modules": _MODULES,
    "os.kill": "which signals other processes", "os.killpg": "which signals other processes",
    "ipykernel": _SHELL, "jupyter_client": _SHELL, "zmq": _SHELL,
}
#: The parts of IPython that only display things; the rest of ``IPython.*`` reaches the shell.
_IPYTHON_DISPLAY = ("IPython.display", "IPython.core.display", "IPython.core.display_functions", "IPython.lib.display")
#: While a cell runs, IPython puts ``get_ipython`` in the builtins and the user namespace (``__main__``) too.
_GET_IPYTHON = frozenset({"IPython.get_ipython", "IPython.core.getipython.get_ipython", "builtins.get_ipython",
                          "__main__.get_ipython"})
#: What the shell object runs code with: reached on any object (the shell under another name), by
#: ``getattr`` or ``operator.methodcaller``, they are the shell's own way to run unread code.
_SHELL_METHODS = frozenset({"run_cell", "run_cell_async", "run_line_magic", "run_cell_magic", "safe_execfile",
                            "safe_execfile_ipy", "safe_run_module", "runcode", "run_code", "run_ast_nodes",
                            "transform_cell", "transform_ast", "define_macro", "find_magic", "find_line_magic",
                            "find_cell_magic", "register_magics", "magics_manager", "prefilter_manager",
                            "alias_manager", "extension_manager", "system_piped", "system_raw", "_ip"})
#: Shell methods whose names are too common to flag on any object; on the shell they are flagged anyway.
_SHELL_METHODS_BY_NAME = _SHELL_METHODS | {"ex", "ev", "system", "getoutput", "push", "magic", "kernel"}

#: Attribute names that honest course code never touches, on whatever object.
_RISKY_ATTRIBUTES = {
    **dict.fromkeys(("f_back", "f_locals", "f_globals", "f_builtins", "f_code", "f_trace", "tb_frame",
                     "gi_frame", "cr_frame", "ag_frame", "_getframe", "settrace", "setprofile"), _FRAMES),
    "addaudithook": _HOOKS,
    **dict.fromkeys(("getsource", "getsourcelines", "getsourcefile", "findsource"), _SOURCE),
    **dict.fromkeys(("set_custom_exc", "input_transformers_cleanup", "input_transformers_post",
                     "input_transformer_manager", "ast_transformers", "register_magic_function",
                     "user_ns", "user_global_ns"), _SHELL),
    **dict.fromkeys(_SHELL_METHODS, _SHELL),
    **dict.fromkeys(("__globals__", "__code__", "__closure__", "__subclasses__"),
                    "which reaches into the internals of functions and classes"),
}
#: Attributes whose assignment swaps what an object is or does.
_INTERNALS = frozenset({"__code__", "__globals__", "__class__", "__dict__", "__defaults__", "__kwdefaults__",
                        "__closure__", "__bases__"})
#: Attributes that locate a module's files.
_LOCATIONS = frozenset({"__file__", "__path__", "__loader__", "__spec__", "__cached__"})
#: Dunders of a course module that say nothing about its code.
_HARMLESS_DUNDERS = frozenset({"__name__", "__doc__", "__version__"})
#: Methods that change a dict (a namespace) in place.
_MUTATORS = frozenset({"update", "setdefault", "pop", "popitem", "clear", "__setitem__", "__delitem__", "__ior__"})
#: Modules on which ``getattr`` with a computed name can reach anything of the above.
_SENSITIVE_ROOTS = frozenset({"sys", "builtins", "inspect", "gc", "threading", "importlib", "types", "marshal",
                              "pickle", "ctypes", "runpy", "IPython", "get_ipython()", "operator"})
#: Modules that other modules import and so expose as attributes (``os.sys``, ``numpy.core.sys``).
_REEXPORTED = frozenset({"sys", "builtins", "inspect", "gc", "threading", "types", "marshal", "pickle", "ctypes",
                         "runpy", "traceback", "linecache"})
_BUILTIN_NAMES = frozenset(dir(builtins))
_SOLUTIONS_PATH = re.compile(r"(?:^|[/\\])solutions(?:[/\\]|$)")
_PACKAGE_PATH = re.compile(r"(?:^|[/\\])kalman_course(?:[/\\]|$)")
#: Stand-in path of a module imported by a name computed at run time.
_RUNTIME_MODULE = "?"


# --- what IPython runs ------------------------------------------------------------------------
#
# The kernel does not run a cell's text but what IPython makes of it: its static transforms
# (``%``, ``!``, ``?``, ``%%``) apply to every cell, and a cell that is one line after them is
# "prefiltered", where automagic (on by default) runs ``time x`` as ``%time x`` and autocall
# (off unless the notebook turns it on) runs ``f x`` as ``f(x)``. Magics then run more Python
# (``%time``, ``%%capture``), files (``%run``, ``%load_ext``) and shells (``!``, ``%%bash``), and
# aliases (``%alias_magic``, ``%alias``) rename all of that. The review reads each of these as
# the kernel would, and flags what it cannot read.

#: Line magics of IPython and ipykernel, the default system aliases and the magics of the
#: extensions a kernel loads (``storemagic``) or that learners load (``autoreload``): a one-line
#: cell whose first word is one of them runs as that magic (automagic).
_LINE_MAGICS = frozenset("""
    aimport alias alias_magic autoawait autocall automagic autoreload autosave bookmark cat cd clear colors conda
    config connect_info cp debug dhist dirs doctest_mode ed edit env gui hist history killbgscripts ldir less lf lk
    ll load load_ext loadpy logoff logon logstart logstate logstop ls lsmagic lx macro magic man matplotlib mkdir
    more mv notebook page pastebin pdb pdef pdoc pfile pinfo pinfo2 pip popd pprint precision prun psearch psource
    pushd pwd pycat pylab qtconsole quickref recall rehashx reload_ext rep rerun reset reset_selective rm rmdir run
    save sc set_env store subshell sx system tb time timeit unalias unload_ext who who_ls whos xdel xmode
    """.split())
_CELL_MAGICS = frozenset("""
    ! HTML SVG bash capture debug file html javascript js latex markdown perl prun pypy python python2 python3
    ruby script sh svg sx system time timeit writefile
    """.split())
#: Magics that IPython hands their line as written (``@no_var_expand``); the others see
#: ``{expression}`` and ``$name`` evaluated first, which runs that Python.
_NO_VAR_EXPAND = frozenset({"time", "timeit", "prun", "debug"})
#: The system aliases every IPython defines (``%cp a b`` runs ``cp a b``).
_DEFAULT_ALIASES = frozenset({"cat", "cp", "ldir", "lf", "lk", "ll", "ls", "lx", "mkdir", "mv", "rm", "rmdir"})
#: Cell magics whose body is a shell (or another interpreter's) script.
_SHELL_CELL_MAGICS = frozenset({"bash", "sh", "sx", "system", "!", "perl", "ruby"})
#: Magics after which IPython reads (or may read) later cells differently.
_READING_MAGICS = frozenset({"autocall", "automagic", "alias_magic", "alias", "rehashx", "config", "macro",
                             "autoawait"})
#: ``%config`` settings that change how output looks, not how input is read.
_HONEST_CONFIG_CLASSES = frozenset({"InlineBackend", "IPCompleter", "Completer", "PlainTextFormatter",
                                    "HistoryManager"})
_HONEST_SHELL_TRAITS = frozenset({"ast_node_interactivity", "colors", "xmode", "pdb", "separate_in", "separate_out",
                                  "separate_out2", "show_rewritten_input", "autoindent", "cache_size",
                                  "sphinxify_docstring", "enable_html_pager"})
_SHELL_CLASSES = frozenset({"InteractiveShell", "ZMQInteractiveShell", "TerminalInteractiveShell"})
_HONEST_AWAIT = frozenset({"", "on", "off", "true", "false", "1", "0", "asyncio", "curio", "trio"})
#: IPython extensions that only add timing, profiling and reloading magics.
_HONEST_EXTENSIONS = frozenset({"autoreload", "storemagic", "line_profiler", "memory_profiler", "snakeviz",
                                "watermark"})
#: Names in every IPython user namespace: like the notebook's own names, they shadow a magic
#: of the same name for automagic.
_USER_NS = frozenset({"In", "Out", "get_ipython", "exit", "quit", "_ih", "_oh", "_dh", "_", "__", "___", "_i",
                      "_ii", "_iii"})
#: What IPython's prefilter asks of a line before autocall rewrites it (``re_fun_name``,
#: ``re_exclude_auto`` and the operators of ``PythonOpsChecker``).
_AUTOCALL_NAME = re.compile(r"[^\W\d]([\w.]*) *$")
_NO_AUTOCALL = re.compile(r"^[,&^|*/+-]|^is |^not |^in |^and |^or |^[!=()<>,+*/%^&|]")
_PYTHON_FILE = re.compile(r"\.(?:py|pyw|pyc|pyo|pth|ipy|so|pyd)$")
#: Compiled Python (``__pycache__/m.cpython-311.pyc`` runs instead of ``m.py``): never readable.
_COMPILED_FILE = re.compile(r"\.(?:pyc|pyo|so|pyd)$")
#: A matplotlib backend named as a module (``%matplotlib module://m``, ``matplotlib.use(...)``): imported.
_BACKEND_MODULE = re.compile(r"^module://([A-Za-z_][\w.]*)$")
_PYTHON_EXE = r"(?<![\w.-])(?:[\w.~/-]*/)?(?:i?python[\d.]*|pypy[\d.]*|jupyter(?:-[\w-]+)?|papermill)(?![\w.-])"
_RUNS_PYTHON = re.compile(_PYTHON_EXE)
#: ``python -m pip ...`` is pip, judged by what it installs.
_PYTHON_PIP = re.compile(_PYTHON_EXE + r"\s+-m\s+pip\b")
#: A pip argument that installs code from somewhere other than the package index.
_LOCAL_PACKAGE = re.compile(r"^(?:\.|/|~|file:|git\+|hg\+|svn\+|https?:|-e$|--editable|-r$|--requirement|-i$|"
                            r"--index-url|--extra-index-url|-f$|--find-links)|\.(?:whl|zip|tar\.gz|tgz)$")
#: Shell commands that read files but write none (a redirect writes, and is read on its own).
_READ_ONLY_COMMANDS = frozenset({"ls", "ll", "cat", "head", "tail", "wc", "grep", "egrep", "fgrep", "rg", "less",
                                 "more", "file", "stat", "du", "df", "diff", "cmp", "md5sum", "sha1sum", "sha256sum",
                                 "echo", "printf", "find", "which", "type", "pwd", "nl", "od", "xxd", "hexdump",
                                 "realpath", "readlink", "basename", "dirname", "test", "[", "rm", "rmdir", "tree",
                                 "pygmentize", "pip", "pip3", "conda"})
_COMMAND_PREFIXES = frozenset({"sudo", "env", "command", "exec", "nohup", "time", "nice", "builtin"})
_REDIRECT = re.compile(r"(?:\d?>>?|&>>?|>\|)\s*(['\"]?)([^\s'\";&|<>()]+)\1")
_TEE = re.compile(r"\btee\b(?:\s+-\S+)*\s+(['\"]?)([^\s'\";&|<>()]+)\1")
_HEREDOC = re.compile(r"(?<!<)<<(?!<)(-?)[ \t]*(['\"]?)([^\s'\"<>;&|()]+)\2")
#: Python that starts another process, and the argument that names the command.
_PROCESSES = frozenset({"os.system", "os.popen", "subprocess.run", "subprocess.call", "subprocess.check_call",
                        "subprocess.check_output", "subprocess.Popen", "subprocess.getoutput",
                        "subprocess.getstatusoutput", "os.execv", "os.execve", "os.execl", "os.execle", "os.execvp",
                        "os.execvpe", "os.execlp", "os.execlpe", "os.spawnv", "os.spawnve", "os.spawnl",
                        "os.spawnle", "os.spawnvp", "os.spawnlp", "os.posix_spawn", "os.posix_spawnp", "pty.spawn",
                        "asyncio.create_subprocess_exec", "asyncio.create_subprocess_shell"})
_OPENERS = frozenset({"builtins.open", "io.open", "codecs.open", "os.open", "io.FileIO", "_io.open"})
_PATHS = frozenset({"pathlib.Path", "pathlib.PosixPath", "pathlib.PurePath", "pathlib.PurePosixPath",
                    "pathlib.WindowsPath"})
_COPIES = frozenset({"shutil.copy", "shutil.copy2", "shutil.copyfile", "shutil.copytree", "shutil.move", "os.rename",
                     "os.replace", "os.link", "os.symlink"})

_READS_LATER = "which changes how IPython reads later cells"
_UNREADABLE = "code the review cannot read"


def _python(text: str) -> ast.Module | None:
    """``text`` parsed as Python, or None (RecursionError is left to the caller)."""
    try:
        return ast.parse(text)
    except (SyntaxError, ValueError):
        return None


@dataclass
class _Shell:
    """IPython's state as the notebook sets it, as far as reading cells goes. The review does
    not run the cells, so what any cell sets counts for every cell."""

    #: ``%alias_magic`` name -> (the magic it runs, the parameters it adds), for line and cell magics
    line_aliases: dict[str, tuple[str, str]] = field(default_factory=dict)
    cell_aliases: dict[str, tuple[str, str]] = field(default_factory=dict)
    #: ``%alias`` name -> the shell command it runs
    system_aliases: dict[str, str] = field(default_factory=dict)
    autocall: bool = False
    #: ``%rehashx`` makes every program on the PATH a magic
    rehashx: bool = False
    #: module-level names the notebook binds (they shadow a magic of the same name)
    bound: frozenset[str] = frozenset()
    #: path (normalised) -> every text the notebook writes there, in cell order (a later write
    #: does not hide an earlier one: the review does not know which one a run reads)
    files: dict[str, list[str]] = field(default_factory=dict)

    def is_line_magic(self, name: str) -> bool:
        return (name in _LINE_MAGICS or name in self.line_aliases or name in self.system_aliases
                or (self.rehashx and re.fullmatch(r"[\w+-][\w.+-]*", name) is not None))

    def file(self, path: str) -> list[str]:
        """The texts the notebook writes at ``path`` (or ``path.py``, as ``%run`` tries)."""
        return [text for candidate in (path, path + ".py") for text in self.files.get(_normalised(candidate), [])]

    def module(self, name: str) -> list[str]:
        """The texts of module ``name`` that the notebook writes (``m.py``, ``pkg/__init__.py``)."""
        return [text for path, texts in self.files.items() if name in _module_names(path) for text in texts]


def _normalised(path: str) -> str:
    return os.path.normpath(path.strip().strip("'\"")) if path.strip() else ""


def _module_names(path: str) -> set[str]:
    """The names ``import`` finds the Python file at ``path`` under (the notebook's folder and
    the file's own folder on ``sys.path``)."""
    stem, suffix = os.path.splitext(path)
    if suffix not in (".py", ".pyc", ".so", ".pyd"):
        return set()
    parts = [p for p in stem.replace("\\", "/").split("/") if p not in ("", ".")]
    if parts and parts[-1] == "__init__":
        parts = parts[:-1]
    names = {parts[-1]} if parts else set()
    if parts and not os.path.isabs(path) and ".." not in parts:
        names.add(".".join(parts))
    return names


@dataclass(frozen=True)
class _Invocation:
    """One magic or shell escape a cell runs, as IPython runs it (aliases followed)."""

    kind: str  # "line", "cell" or "shell"
    name: str  # the magic that runs ('' for a shell escape)
    written: str  # the name the cell calls it by
    line: str  # the magic's line (for a shell: its command)
    body: str = ""  # a cell magic's body

    def shown(self) -> str:
        written = {"line": f"%{self.written} {self.line}", "cell": f"%%{self.written} {self.line}"}.get(
            self.kind, f"{self.written}{self.line}" if self.written == "!" else f"%{self.written} {self.line}")
        return _shortened(written.strip())


def _shortened(text: str, width: int = 60) -> str:
    text = " ".join(text.split())
    return text if len(text) <= width else text[:width - 3] + "..."


def _walk(tree: ast.Module) -> list[ast.AST]:
    """The nodes of ``tree``; once it is read to the end (``complete``) the list is kept, as
    every check walks it."""
    if not getattr(tree, "complete", False):
        return list(ast.walk(tree))
    if not hasattr(tree, "walked"):
        tree.walked = list(ast.walk(tree))
    return tree.walked


def _constant_args(node: ast.Call) -> list[str] | None:
    """The arguments of a magic call if they are what IPython writes (positional string
    constants), else None."""
    args = [_str(a) for a in node.args]
    return None if node.keywords or None in args else args


def _invocations(tree: ast.Module, shell: _Shell):
    """The magics and shell escapes in ``tree`` (those written as IPython writes them)."""
    if not getattr(tree, "has_magics", True):  # most cells have none: no need to walk them
        return
    for node in _walk(tree):
        if not _is_magic_call(node) or (args := _constant_args(node)) is None:
            continue
        method = node.func.attr
        if method in ("system", "getoutput") and args:
            yield _Invocation("shell", "", "!", args[0])
        elif method == "run_line_magic" and len(args) >= 2:
            yield _line_invocation(args[0], args[1], shell)
        elif method == "run_cell_magic" and len(args) >= 3:
            name, line = _follow_aliases(args[0], args[1], shell.cell_aliases)
            yield _Invocation("cell", name, args[0], line, args[2])


def _follow_aliases(name: str, line: str, aliases: dict[str, tuple[str, str]]) -> tuple[str, str]:
    """The magic an ``%alias_magic`` name runs and the line it gets (each alias puts its
    parameters in front)."""
    for _ in range(8):  # IPython refuses an alias that calls itself; eight is deeper than anyone aliases
        if name not in aliases:
            break
        name, params = aliases[name]
        line = f"{params} {line}" if params else line
    return name, line


def _line_invocation(written: str, line: str, shell: _Shell) -> _Invocation:
    name, line = _follow_aliases(written, line, shell.line_aliases)
    # IPython refuses an %alias named like a magic, but lets one redefine its own system aliases
    if name in shell.system_aliases and (name in _DEFAULT_ALIASES or name not in _LINE_MAGICS):
        return _Invocation("shell", name, written, f"{shell.system_aliases[name]} {line}")
    if name in _DEFAULT_ALIASES or (shell.rehashx and name not in _LINE_MAGICS):
        return _Invocation("shell", name, written, f"{name} {line}")
    if name in ("sx", "system"):
        return _Invocation("shell", name, written, line)
    if name in ("pip", "conda"):  # they run `python -m pip` / `conda` with the line
        return _Invocation("shell", name, written, f"{name} {line}")
    return _Invocation("line", name, written, line)


def _words(text: str) -> list[str]:
    """``text`` split as a shell (and IPython's magics) would, or on blanks if it does not split."""
    try:
        return shlex.split(text)
    except ValueError:
        return text.split()


def _script_interpreter(line: str) -> str:
    """The program ``%%script`` runs its body with (its first argument that is not an option)."""
    words, i = _words(line), 0
    while i < len(words) and words[i].startswith("-"):
        i += 2 if words[i] in ("--out", "--err", "--proc") else 1
    return words[i] if i < len(words) else ""


def _shell_text(inv: _Invocation) -> str | None:
    """The script a shell runs for ``inv``, or None if it runs no shell."""
    if inv.kind == "shell":
        return inv.line
    if inv.kind == "cell" and inv.name in _SHELL_CELL_MAGICS:
        return inv.body
    if inv.kind == "cell" and inv.name == "script" and not _RUNS_PYTHON.fullmatch(_script_interpreter(inv.line)):
        return f"{_script_interpreter(inv.line)}\n{inv.body}"
    return None


def _expanded(line: str) -> list[str]:
    """The Python IPython evaluates in a magic's line or a shell command (``{expression}``,
    ``$name``) before running it."""
    from IPython.utils.text import DollarFormatter

    fields = []
    try:
        for _, name, spec, _ in DollarFormatter().parse(line):
            if name is not None:
                fields.append(f"{name}:{spec}" if spec else name)  # IPython's own reading of `{a[1:2]}`
    except ValueError:  # IPython gives up here too, but has evaluated the fields before
        pass
    return fields


def _heredocs(text: str) -> list[tuple[str | None, str, bool]]:
    """The here-documents in a shell script: (the file the line writes them to or None, the
    text, whether the shell expands ``$`` and backquotes in it)."""
    lines, found, i = text.split("\n"), [], 0
    while i < len(lines):
        j = i + 1
        for match in _HEREDOC.finditer(lines[i]):
            tabs, quoted, end = match.group(1) == "-", bool(match.group(2)), match.group(3)
            body = []
            while j < len(lines) and (lines[j].lstrip("\t") if tabs else lines[j]) != end:
                body.append(lines[j].lstrip("\t") if tabs else lines[j])
                j += 1
            j += 1
            targets = [m.group(2) for m in (*_REDIRECT.finditer(lines[i]), *_TEE.finditer(lines[i]))]
            found.append((targets[0] if targets else None, "\n".join(body) + "\n", not quoted))
        i = j
    return found


def _run_target(line: str) -> tuple[str, str]:
    """What ``%run`` runs: ("module", name) for ``-m``, else ("file", path) ('' if none)."""
    words = _words(line)
    for i, word in enumerate(words):
        if not word.startswith("-") or word == "-":
            return "file", word
        for k, option in enumerate(word[1:]):
            if option in "Nbm":  # options that take a value, attached or as the next word
                value = word[k + 2:] or (words[i + 1] if i + 1 < len(words) else "")
                if option == "m":
                    return "module", value
                break
    return "file", ""


def _load_target(line: str) -> str:
    """The file, URL or object ``%load`` puts in the cell (its options -r, -s, -n take a value)."""
    words, i, target = _words(line), 0, ""
    while i < len(words):
        if words[i] in ("-r", "-s", "-n"):
            i += 2
            continue
        if not words[i].startswith("-"):
            target = words[i]
        i += 1
    return target


def _also_runs(tree: ast.Module, shell: _Shell):
    """For each piece of code that ``tree`` makes IPython run besides itself, the candidate
    sources of it (the first that parses is it): the Python of magics, what ``{...}`` in a
    magic's line or a shell command evaluates, here-documents, and the files the notebook
    writes that ``%run``, ``%load_ext`` or an import run."""
    for inv in _invocations(tree, shell):
        if inv.kind == "line" and inv.name in _PYTHON_LINE_MAGICS and inv.line:
            yield _after_options(inv.line)
        if inv.kind == "cell" and (inv.name in _PYTHON_CELL_MAGICS or inv.name not in _CELL_MAGICS
                                   or (inv.name == "script"
                                       and _RUNS_PYTHON.fullmatch(_script_interpreter(inv.line)))):
            yield [inv.body]  # a cell magic the review does not know is read too, if its body is Python
        if inv.kind == "cell" and inv.name == "timeit" and inv.line:  # the line of %%timeit is setup code
            yield _after_options(inv.line)
        if inv.name not in _NO_VAR_EXPAND:
            yield from ([field] for field in _expanded(inv.line))
        if (script := _shell_text(inv)) is not None:
            yield from ([body] for _, body, _ in _heredocs(script))
        yield from ([text] for text in _target_texts(inv, shell))
    for node in _walk(tree) if shell.files else ():
        for name in _imported_modules(node):
            yield from ([text] for text in shell.module(name))


def _target_texts(inv: _Invocation, shell: _Shell) -> list[str]:
    """The texts of the file (written in the notebook) that ``%run`` or ``%load_ext`` runs."""
    if inv.kind != "line":
        return []
    if inv.name == "run":
        kind, target = _run_target(inv.line)
        return shell.file(target) if kind == "file" else shell.module(target)
    if inv.name in ("load_ext", "reload_ext") and (words := _words(inv.line)):
        return shell.module(words[0])
    return []


def _imported_modules(node: ast.AST) -> list[str]:
    """The absolute module names an import statement (or a ``module://`` backend) imports."""
    if (text := _str(node)) is not None and (match := _BACKEND_MODULE.match(text.strip())):
        return [match.group(1)]
    if isinstance(node, ast.Import):
        return [a.name for a in node.names]
    if isinstance(node, ast.ImportFrom) and not node.level and node.module:
        return [node.module, *(f"{node.module}.{a.name}" for a in node.names if a.name != "*")]
    return []


def _one_line_readings(transformed: str, shell: _Shell) -> list[str]:
    """What IPython's prefilter makes of a cell that is one line after the static transforms,
    besides the line itself: the magic automagic runs, or the call autocall writes.

    Automagic runs ``name rest`` as ``%name rest`` when ``name`` is a line magic that nothing
    in the user's namespace shadows. The review does not run the cells, so it reads a line
    that is not Python as the magic (else it is a syntax error), and a line that is Python as
    the magic too unless the notebook binds the name somewhere or it is a builtin.
    """
    from IPython.core.splitinput import LineInfo

    lines = transformed.splitlines()
    if len(lines) != 1:
        return []
    info = LineInfo(lines[0])
    if info.esc or not info.ifun or info.the_rest[:1] in ("=", ","):  # an assignment is always Python
        return []
    python = _python(lines[0]) is not None
    head = info.ifun.split(".", 1)[0]
    shadowed = head in shell.bound or head in _BUILTIN_NAMES or keyword.iskeyword(head) or head in _USER_NS
    if shell.is_line_magic(info.ifun) and not (python and shadowed):
        name, _, line = f"{info.ifun} {info.the_rest}".partition(" ")  # as IPython's MagicHandler splits it
        return [f"get_ipython().run_line_magic({name.lstrip('%')!r}, {line!r})"]
    if shell.autocall and not python and _AUTOCALL_NAME.match(info.ifun) and not _NO_AUTOCALL.match(info.the_rest):
        return [f"{info.ifun}({info.the_rest})"]
    return []


def _declared_encoding(source: str) -> str | None:
    """The encoding a PEP 263 declaration in the first two lines names, if it is not UTF-8 or
    ASCII: Python decodes a file (a module the notebook writes) with it, so its code is not the
    text the review reads."""
    try:
        codec, _ = tokenize.detect_encoding(io.BytesIO(source.encode("utf-8", "surrogatepass")).readline)
    except SyntaxError:  # a codec Python does not know: the declaration as written
        match = re.search(r"coding[:=][ \t]*([-\w.]+)", "\n".join(source.splitlines()[:2]))
        return match.group(1) if match else "unknown"
    except UnicodeError:
        return None
    try:
        codec = codecs.lookup(codec).name
    except LookupError:
        return codec
    return None if codec in ("utf-8", "utf-8-sig", "ascii") else codec


def _decoded(source: str, codec: str) -> str | None:
    """The text Python reads from the UTF-8 bytes of ``source`` under ``codec``, or None."""
    try:
        return source.encode("utf-8").decode(codec)
    except (LookupError, UnicodeError):
        return None


@functools.lru_cache(maxsize=4096)
def _transformed(source: str) -> str:
    """IPython's static transforms of a cell (the same whatever the notebook sets; a review
    reads each cell several times, and a class's notebooks share most of their cells)."""
    from IPython.core.inputtransformer2 import TransformerManager

    return TransformerManager().transform_cell(source)


def _read_cell(source: str, shell: _Shell) -> ast.Module | None:
    """The Python a cell is read as: IPython's static transforms, then the prefilter's readings
    of a one-line cell, all of them in one module (None if none is Python)."""
    try:
        transformed = _transformed(source)
        readings = [transformed, *_one_line_readings(transformed, shell)]
        trees = [t for r in readings if (t := _python(r)) is not None]
    except (SyntaxError, ValueError):
        return None  # the learner's own error; the run reports it
    except RecursionError:  # nested too deeply for the parser (how deep depends on the stack)
        tree = ast.Module(body=[], type_ignores=[])
        tree.too_deep = True
        return tree
    if not trees:
        return None
    for other in trees[1:]:
        trees[0].body.extend(other.body)
    trees[0].has_magics = any("get_ipython" in r for r in readings)
    return trees[0]


def _parser(shell: _Shell | None = None):
    """A function source -> AST of what IPython runs for it (see :func:`_read_cell`; the Python
    that magics, files and shells run appended at module level; None if none of it is Python),
    parsing each distinct source once. Each tree carries ``notes``: flags found while reading."""
    trees, shell = {}, shell or _Shell()

    def parse(source: str, depth: int = 0) -> ast.Module | None:
        if source in trees:
            return trees[source]
        trees[source] = None  # a file that imports or runs itself is read once
        tree, notes = _read_cell(source, shell), set()
        if (codec := _declared_encoding(source)) is not None:
            notes.add(f"declares the source encoding `{codec}`, so the Python that runs may not be "
                      "the text the review reads")
            decoded = _decoded(source, codec)
            if decoded not in (None, source) and (inner := parse(decoded, depth + 1)) is not None:
                tree = tree or ast.Module(body=[], type_ignores=[])
                tree.body.extend(inner.body)
                notes |= inner.notes
                tree.has_magics = getattr(tree, "has_magics", True) or getattr(inner, "has_magics", True)
        if tree is not None and depth < 3 and not getattr(tree, "too_deep", False):
            # code run by code run by ... a cell is read too, not endlessly
            for candidates in list(_also_runs(tree, shell)):
                inner = next((t for c in candidates if (t := parse(c, depth + 1)) is not None), None)
                if inner is not None:
                    tree.body.extend(inner.body)
                    notes |= inner.notes
                    tree.has_magics = getattr(tree, "has_magics", True) or getattr(inner, "has_magics", True)
        if tree is None and notes:
            tree = ast.Module(body=[], type_ignores=[])
        if tree is not None:
            tree.notes, tree.complete = notes, True
        trees[source] = tree
        return tree

    return parse


def _str(node: ast.AST | None) -> str | None:
    """The value of a string constant, else None."""
    return node.value if isinstance(node, ast.Constant) and isinstance(node.value, str) else None


def _is_magic_call(node: ast.AST) -> bool:
    """``get_ipython().run_line_magic(...)`` and the other calls IPython writes for magics."""
    return (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr in _MAGIC_METHODS
            and isinstance(node.func.value, ast.Call) and not node.func.value.args
            and isinstance(node.func.value.func, ast.Name) and node.func.value.func.id == "get_ipython")


def _after_options(text: str) -> list[str]:
    """``text`` and its suffixes after each leading word, so ``-n 1 -r 3 stmt`` yields ``stmt``."""
    return [text[m.start():] for m in re.finditer(r"\S+", text)][:8]


def _is_machinery(module: str) -> bool:
    return any(module == m or module.startswith(m + ".") for m in MACHINERY)


def _dotted(node: ast.AST) -> str:
    """``a.b.c`` for a chain of attributes on a name, else ''."""
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if isinstance(node, ast.Name):
        return ".".join([node.id, *reversed(parts)])
    return ""


def _root(node: ast.AST) -> str:
    return _dotted(node).split(".", 1)[0]


def _under(path: str, prefix: str) -> bool:
    return path == prefix or path.startswith(prefix + ".")


def _risk(path: str) -> str | None:
    """Why using the object at dotted ``path`` is flagged, or None."""
    parts = path.split(".")
    # a module re-exported by another (``os.sys``) is itself: check from each such part on
    starts = [0, *(i for i, part in enumerate(parts) if i and part in _REEXPORTED)]
    for start in starts:
        for end in range(len(parts), start, -1):
            if (reason := _RISKY.get(".".join(parts[start:end]))) is not None:
                return reason
    if path.startswith("IPython.") and not any(_under(path, p) for p in _IPYTHON_DISPLAY):
        return _SHELL
    return None


def _text(node: ast.AST) -> str:
    """The source of ``node`` on one line, shortened."""
    text = " ".join(ast.unparse(node).split())
    return text if len(text) <= 60 else text[:57] + "..."


def _via(written: str, path: str) -> str:
    """`` (`numpy.allclose`)`` when the code wrote an alias of ``path``."""
    return f" (`{path}`)" if path and path != written and not path.startswith(_RUNTIME_MODULE) else ""


def _machinery_names(tree: ast.Module) -> set[str]:
    """Names that a cell binds to the grading machinery (``from kalman_course import checks``)."""
    names = set()
    for node in _walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if _is_machinery(a.name):
                    names.add(a.asname or a.name.split(".", 1)[0])
        elif isinstance(node, ast.ImportFrom) and node.module:
            for a in node.names:
                if _is_machinery(node.module) or _is_machinery(f"{node.module}.{a.name}"):
                    names.add(a.asname or a.name)
    return names


# --- names and what they are bound to -------------------------------------------------------

_NEW_SCOPES = (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda, ast.ClassDef)


def _same_scope_nodes(node: ast.AST):
    """``node`` and what it contains, in source order, without entering nested functions,
    lambdas and classes (whose own names are in their own scope)."""
    stack = [node]
    while stack:
        node = stack.pop()
        yield node
        if not isinstance(node, _NEW_SCOPES):
            stack.extend(reversed(list(ast.iter_child_nodes(node))))


def _pairs(target: ast.AST, value: ast.AST | None):
    """(name, value expression or None) for each name an assignment target binds."""
    if isinstance(target, ast.Name):
        yield target.id, value
    elif isinstance(target, (ast.Tuple, ast.List)):
        values = value.elts if isinstance(value, (ast.Tuple, ast.List)) and len(value.elts) == len(target.elts) \
            and not any(isinstance(e, ast.Starred) for e in [*value.elts, *target.elts]) else [None] * len(target.elts)
        for t, v in zip(target.elts, values):
            yield from _pairs(t, v)
    elif isinstance(target, ast.Starred):
        yield from _pairs(target.value, None)


def _stored_names(target: ast.AST):
    for t in ast.walk(target):
        if isinstance(t, ast.Name) and isinstance(t.ctx, (ast.Store, ast.Del)):
            yield t.id


def _bindings(node: ast.AST):
    """(name, how, what) for each name that ``node`` binds by itself (not through the
    statements it contains) in its scope: how is ``import`` (what: the imported dotted
    path), ``assign`` (what: the value expression or None), ``define`` (``def``, ``class``),
    ``delete`` or ``other``; and
    ``("*", "star", module)`` for a star-import."""
    if isinstance(node, ast.Import):
        for a in node.names:
            yield (a.asname, "import", a.name) if a.asname else (a.name.split(".")[0], "import", a.name.split(".")[0])
    elif isinstance(node, ast.ImportFrom):
        module = "." * node.level + (node.module or "")
        for a in node.names:
            yield ("*", "star", module) if a.name == "*" else (a.asname or a.name, "import", f"{module}.{a.name}")
    elif isinstance(node, ast.Assign):
        for target in node.targets:
            for name, value in _pairs(target, node.value):
                yield name, "assign", value
    elif isinstance(node, (ast.AugAssign, ast.AnnAssign)):
        if isinstance(node.target, ast.Name) and (isinstance(node, ast.AugAssign) or node.value is not None):
            yield node.target.id, "assign", None
    elif isinstance(node, (ast.For, ast.AsyncFor)):
        for name in _stored_names(node.target):
            yield name, "other", None
    elif isinstance(node, (ast.With, ast.AsyncWith)):
        for item in node.items:
            for name in _stored_names(item.optional_vars) if item.optional_vars else ():
                yield name, "other", None
    elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
        yield node.name, "define", None
    elif isinstance(node, ast.Delete):
        for target in node.targets:
            for name in _stored_names(target):
                yield name, "delete", None
    elif isinstance(node, ast.ExceptHandler) and node.name:
        yield node.name, "other", None
    elif isinstance(node, ast.match_case):
        for p in ast.walk(node.pattern):
            for name in (getattr(p, "name", None), getattr(p, "rest", None)):
                if name:
                    yield name, "other", None
    elif isinstance(node, ast.NamedExpr):  # binds in the enclosing scope, even inside a comprehension
        yield node.target.id, "assign", node.value


_BINDERS = (ast.Import, ast.ImportFrom, ast.Assign, ast.AugAssign, ast.AnnAssign, ast.For, ast.AsyncFor, ast.With,
            ast.AsyncWith, ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef, ast.Delete, ast.ExceptHandler,
            ast.match_case, ast.NamedExpr)
def _scope_names(body: list[ast.stmt], cache: dict[int, tuple]) -> tuple[list[tuple[str, str, object]], set[str]]:
    """The bindings (see :func:`_bindings`) of one scope's body, and the names it declares
    ``global`` or ``nonlocal``; ``cache`` keeps them by body for the trees of one review."""
    if id(body) not in cache:
        bindings, declared = [], set()
        for stmt in body:
            for node in _same_scope_nodes(stmt):
                if isinstance(node, _BINDERS):
                    bindings += _bindings(node)
                elif isinstance(node, (ast.Global, ast.Nonlocal)):
                    declared.update(node.names)
        cache[id(body)] = (body, bindings, declared)  # the body is kept so that its id stays its own
    return cache[id(body)][1:]


@dataclass
class _Notebook:
    """What the review of one submission knows about the whole notebook."""

    to_write: set[str]
    machinery: set[str]
    #: what learner code may use of ``kalman_course.checks``: the release's checks, CheckFailed, SUCCESS
    check_api: set[str] = field(default_factory=set)
    #: function to write -> the course functions its released version calls
    released_calls: dict[str, set[str]] = field(default_factory=dict)
    #: module-level name -> dotted path of what it is bound to by an import or an alias
    imported: dict[str, str] = field(default_factory=dict)
    #: module-level names of the notebook's own functions and classes (they hide builtins)
    own: set[str] = field(default_factory=set)
    #: names the release binds by a module-level import -> the imported path
    released_imports: dict[str, str] = field(default_factory=dict)
    released_stars: set[str] = field(default_factory=set)
    #: body id -> its scope's names (see :func:`_scope_names`)
    scopes: dict[int, tuple] = field(default_factory=dict)
    #: IPython's state as the notebook sets it (aliases, autocall, files written)
    shell: _Shell = field(default_factory=_Shell)
    #: top-level modules the release imports, and the IPython flags its own cells raise
    released_modules: set[str] = field(default_factory=set)
    released_ipython: set[str] = field(default_factory=set)

    def scope_names(self, body: list[ast.stmt]):
        return _scope_names(body, self.scopes)


def _notebook(release_trees: list[ast.Module], submission_trees: list[ast.Module], to_write, machinery,
              check_api=frozenset(), shell: _Shell | None = None) -> _Notebook:
    nb = _Notebook(to_write, machinery, set(check_api), shell=shell or _Shell())
    for tree in release_trees:
        for node in _walk(tree):
            nb.released_modules |= {name.split(".", 1)[0] for name in _imported_modules(node)}
        for name, how, what in nb.scope_names(tree.body)[0]:
            if how == "import":
                nb.released_imports[name] = what
            elif how == "star":
                nb.released_stars.add(what)
    bindings = [b for tree in [*release_trees, *submission_trees] for b in nb.scope_names(tree.body)[0]]
    deleted = {name for name, how, _ in bindings if how == "delete"}
    for name, how, what in bindings:
        if how == "import":
            nb.imported.setdefault(name, what)
        elif how == "define" and name not in deleted:  # only a def or class surely makes a name the learner's own
            nb.own.add(name)
    reader = _Reader(nb, shadow_builtins=False)  # `exec = exec` is an alias of the builtin, not a new name
    for _ in range(2):  # twice, so that an alias of an alias resolves
        for name, how, what in bindings:
            if how == "assign" and what is not None and name not in nb.imported and (path := reader.resolve(what)):
                nb.imported[name] = path
    for tree in release_trees:
        for node in tree.body:
            if isinstance(node, ast.FunctionDef) and node.name in to_write:
                nb.released_calls.setdefault(node.name, set()).update(reader.course_calls(node))
    return nb


# --- reading one cell ------------------------------------------------------------------------

class _Reader:
    """Walks one cell's syntax tree, resolving names scope by scope, and collects its flags."""

    def __init__(self, nb: _Notebook, shadow_builtins: bool = True):
        self.nb = nb
        self.shadow_builtins = shadow_builtins
        #: function, class and comprehension scopes, innermost last: (name -> path or '', is a class)
        self.scopes: list[tuple[dict[str, str], bool]] = []
        self.flags: set[str] = set()
        self.reported: set[int] = set()  # ids of nodes already flagged, so that one thing gives one flag

    # resolution

    def lookup(self, name: str) -> str:
        for depth, (table, is_class) in enumerate(reversed(self.scopes)):
            if is_class and depth > 0:  # a class body's names are not visible in its methods
                continue
            if name in table:
                return table[name]
        if name in self.nb.imported:
            return self.nb.imported[name]
        if self.shadow_builtins and name in self.nb.own:
            return ""
        if name == "__builtins__":
            return "builtins"
        if name == "get_ipython":
            return "IPython.get_ipython"
        return f"builtins.{name}" if name in _BUILTIN_NAMES else ""

    def module_lookup(self, name: str) -> str:
        """What ``name`` is at module level (``globals()[name]``), wherever the code is."""
        scopes, self.scopes = self.scopes, []
        try:
            return self.lookup(name)
        finally:
            self.scopes = scopes

    def resolve(self, node: ast.AST | None) -> str:
        """The dotted path of what ``node`` evaluates to (``numpy.linalg``), '' if unknown; the
        IPython shell's ``get_ipython`` is ``IPython.get_ipython`` whichever way it is reached."""
        path = self._resolve(node)
        return "IPython.get_ipython" if path in _GET_IPYTHON else path

    def _resolve(self, node: ast.AST | None) -> str:
        """The dotted path of what ``node`` evaluates to (``numpy.linalg``), '' if unknown."""
        if isinstance(node, ast.Name):
            return self.lookup(node.id)
        if isinstance(node, ast.Attribute):
            base = self.resolve(node.value)
            return f"{base}.{node.attr}" if base else ""
        if isinstance(node, ast.Call):
            return self._resolve_call(node)
        if isinstance(node, ast.Subscript):
            base, key = self.resolve(node.value), _str(node.slice)
            if not base or key is None:
                return ""
            if base == "sys.modules":
                return key
            if base == "globals()":  # `globals()["get_ipython"]` is the module-level name
                return self.module_lookup(key)
            if base.endswith(".__dict__"):
                return f"{base[:-len('.__dict__')]}.{key}"
            return f"builtins.{key}" if base == "builtins" else ""
        if isinstance(node, ast.NamedExpr):
            return self.resolve(node.value)
        return ""

    def _resolve_call(self, node: ast.Call) -> str:
        func = self.resolve(node.func)
        if func == "IPython.get_ipython":
            return "get_ipython()"
        if func in ("builtins.globals", "builtins.locals") or (func == "builtins.vars" and not node.args):
            return "globals()"
        if func == "builtins.vars" and len(node.args) == 1:
            base = self.resolve(node.args[0])
            return f"{base}.__dict__" if base else ""
        if func in ("importlib.import_module", "builtins.__import__") and node.args:
            return _str(node.args[0]) or _RUNTIME_MODULE
        if func == "builtins.getattr" and len(node.args) >= 2:
            base, key = self.resolve(node.args[0]), _str(node.args[1])
            return f"{base}.{key}" if base and key else ""
        if func == "globals().get" and node.args and (key := _str(node.args[0])) is not None:
            return self.module_lookup(key)
        if func.endswith(".__dict__.get") and node.args and (key := _str(node.args[0])) is not None:
            return f"{func[:-len('.__dict__.get')]}.{key}"
        return ""

    # scopes

    def _push(self, body: list[ast.stmt], table: dict[str, str], is_class: bool = False):
        bindings, declared = self.nb.scope_names(body)
        bindings = [b for b in bindings if b[0] not in declared]
        for name, how, what in bindings:
            table.setdefault(name, "")
            if how == "import":
                table[name] = what
        self.scopes.append((table, is_class))
        for name, how, what in bindings:
            if how == "assign" and what is not None and (path := self.resolve(what)):
                table[name] = path

    def visit_FunctionDef(self, node):
        for child in [*node.decorator_list, node.args, node.returns]:
            if child is not None:
                self.visit(child)
        self._enter_function(node.args, node.body)
        if node.name in self.nb.to_write and len(self.scopes) == 1 and not self._check_delegation(node):
            for path, written in self.course_calls(node, entered=True).items():
                if path not in self.nb.released_calls.get(node.name, ()):
                    self.flag(node, f"`{node.name}` calls `{written}`{_via(written, path)}, a course function "
                                    "that the exercise's version of it does not use")
        for stmt in node.body:
            self.visit(stmt)
        self.scopes.pop()

    visit_AsyncFunctionDef = visit_FunctionDef

    def _check_delegation(self, node: ast.FunctionDef) -> bool:
        """A function the learner must write whose whole work is one call of a course function
        (``return chi2_bounds(dof, n, confidence)``): the reference, under another name."""
        body = node.body[1:] if _str(getattr(node.body[0], "value", None)) is not None else node.body  # docstring
        if len(body) == 1 and isinstance(body[0], ast.Return) and isinstance(body[0].value, ast.Call):
            callee = self.resolve(body[0].value.func)
            if callee.startswith("kalman_course."):
                written = _text(body[0].value.func)
                self.flag(node, f"`{node.name}` only returns what `{written}`{_via(written, callee)} returns, "
                                "a course function, instead of doing the work")
                return True
        return False

    def course_calls(self, node: ast.FunctionDef, entered: bool = False) -> dict[str, str]:
        """The course functions ``node``'s body calls: resolved path -> as written.

        ``entered``: the function's scope is already on the stack (while visiting it).
        """
        if not entered:
            self._enter_function(node.args, node.body)
        try:
            return {path: _text(call.func) for stmt in node.body for call in ast.walk(stmt)
                    if isinstance(call, ast.Call) and (path := self.resolve(call.func)).startswith("kalman_course.")}
        finally:
            if not entered:
                self.scopes.pop()

    def visit_Lambda(self, node):
        self.visit(node.args)
        self._enter_function(node.args, [ast.Expr(node.body)])
        self.visit(node.body)
        self.scopes.pop()

    def _enter_function(self, args: ast.arguments, body: list[ast.stmt]):
        positional = [*args.posonlyargs, *args.args]
        defaults = [None] * (len(positional) - len(args.defaults)) + list(args.defaults)
        table = {}
        for arg, default in [*zip(positional, defaults), *zip(args.kwonlyargs, args.kw_defaults)]:
            table[arg.arg] = self.resolve(default) if default is not None else ""  # def f(s=sys) is an alias
        for arg in (args.vararg, args.kwarg):
            if arg is not None:
                table[arg.arg] = ""
        self._push(body, table)

    def visit_ClassDef(self, node):
        for child in [*node.decorator_list, *node.bases, *node.keywords]:
            self.visit(child)
        self._push(node.body, {}, is_class=True)
        for stmt in node.body:
            self.visit(stmt)
        self.scopes.pop()

    def visit_ListComp(self, node):
        self.visit(node.generators[0].iter)  # evaluated in the enclosing scope
        self.scopes.append(({name: "" for g in node.generators for name in _stored_names(g.target)}, False))
        for i, g in enumerate(node.generators):
            self._check_targets([g.target], "assigns to")
            for child in ([] if i == 0 else [g.iter]) + g.ifs:
                self.visit(child)
        for child in (node.key, node.value) if isinstance(node, ast.DictComp) else (node.elt,):
            self.visit(child)
        self.scopes.pop()

    visit_SetComp = visit_GeneratorExp = visit_DictComp = visit_ListComp

    # the walk

    def visit(self, node: ast.AST):
        method = getattr(self, f"visit_{type(node).__name__}", None)
        if method is not None:
            method(node)
        else:
            self.generic_visit(node)

    def generic_visit(self, node: ast.AST):
        for child in ast.iter_child_nodes(node):
            self.visit(child)

    def flag(self, node: ast.AST | None, message: str):
        self.flags.add(message)
        if node is not None:
            self.reported.add(id(node))

    def flag_use(self, node: ast.AST, path: str, reason: str):
        written = _text(node)
        self.flag(node, f"uses `{written}`{_via(written, path)}, {reason}")

    def visit_Import(self, node):
        for a in node.names:
            if isinstance(node, ast.ImportFrom):
                module = "." * node.level + (node.module or "")
                if a.name == "*":
                    if module not in self.nb.released_stars:
                        self.flag(node, f"star-imports `{module}` (`from {module} import *`), "
                                        "which the exercise does not")
                    continue
                path = f"{module}.{a.name}"
            else:
                path = a.name
            if path.split(".", 1)[0] not in _ESCAPES and (reason := _risk(path)):  # escapes are flagged already
                self.flag(node, f"imports `{path}`, {reason}")

    visit_ImportFrom = visit_Import

    def visit_Name(self, node):
        if not isinstance(node.ctx, ast.Load):
            return
        if node.id == "__IPYTHON__":
            self.flag(node, "uses `__IPYTHON__`, " + _SHELL)
        path = self.resolve(node)
        if path in _GET_IPYTHON:
            self.flag(node, f"uses `{node.id}` without calling it for a magic, {_SHELL}")
        elif path and (reason := _risk(path)):
            self.flag_use(node, path, reason)

    def visit_Constant(self, node):
        if isinstance(node.value, str):
            shown = repr(node.value) if len(node.value) <= 50 else repr(node.value[:47] + "...")
            if _SOLUTIONS_PATH.search(node.value):
                self.flag(node, f"names a path under `solutions/` ({shown}), where the reference code is")
            if _PACKAGE_PATH.search(node.value):
                self.flag(node, f"names a path inside the `kalman_course` package ({shown}), "
                                "where the reference code is")

    def visit_Attribute(self, node):
        chain, base = [], node
        while isinstance(base, ast.Attribute):
            chain.append(base)
            base = base.value
        written, path = _text(node), self.resolve(node)
        risky_attr = next((a.attr for a in reversed(chain) if a.attr in _RISKY_ATTRIBUTES), None)
        if not isinstance(node.ctx, ast.Load) and node.attr in _INTERNALS:
            risky_attr = None  # `f.__code__ = ...` is reported as the assignment it is
        literal_sys_modules = any(_dotted(a) == "sys.modules" for a in chain)  # flagged as such already
        if (reason := self._course_internals(path)) is not None:
            self.flag(node, f"uses `{written}`{_via(written, path)}, {reason}")
        elif path.startswith("get_ipython()"):
            self.flag(node, f"uses `{written}`{_via(written, path)}, {_SHELL}")
        elif path in _GET_IPYTHON:
            self.flag(node, f"uses `{written}` without calling it for a magic, {_SHELL}")
        elif path and (reason := _risk(path)) and not (literal_sys_modules and _under(path, "sys.modules")):
            self.flag_use(node, path, reason)
        elif risky_attr is not None:
            self.flag(node, f"uses `{written}`, {_RISKY_ATTRIBUTES[risky_attr]}")
        for a in chain:
            owner = self.resolve(a.value)
            if a.attr in _LOCATIONS and (not owner or owner.startswith(("kalman_course", _RUNTIME_MODULE))):
                self.flag(node, f"reads `{_text(a)}`{_via(_text(a), f'{owner}.{a.attr}' if owner else '')}, "
                                "which locates the source files of the course's code")
            elif (a.attr.startswith("__") and a.attr not in _HARMLESS_DUNDERS | _LOCATIONS
                  and id(a) not in self.reported and owner.startswith(("kalman_course", _RUNTIME_MODULE))):
                self.flag(node, f"uses `{_text(a)}`{_via(_text(a), f'{owner}.{a.attr}')}, "
                                "the inside of a course module or one imported at run time")
        if isinstance(base, ast.Call) and self.resolve(base) == "get_ipython()":
            self.visit_Call(base, shell_base=True)  # reported above as part of the chain
        elif not isinstance(base, ast.Name):
            self.visit(base)

    def _course_internals(self, path: str) -> str | None:
        """Why using the course object at ``path`` is flagged: the graders' own code beyond
        the checks the release calls (it computes the expected values), or a private name."""
        parts = path.split(".")
        if parts[:2] == ["kalman_course", "checks"] and len(parts) > 2 \
                and (len(parts) > 3 or parts[2] not in self.nb.check_api):
            return "the graders' own code (it computes the expected values)"
        if parts[0] == "kalman_course" and any(p.startswith("_") and not p.startswith("__") for p in parts):
            return "a private name of the course's code"
        return None

    def visit_Call(self, node, shell_base: bool = False):
        func = node.func
        arguments = [*node.args, *node.keywords]
        if _is_magic_call(node):  # only the exact call IPython writes: under another name it is the shell
            if _constant_args(node) is None:
                self.flag(node, f"calls `{_text(node.func)}` with arguments computed at run time, {_UNREADABLE}")
            for child in arguments:  # a magic is no flag, but what it names may be
                self.visit(child)
            return
        callee = self.resolve(func)
        if callee in _GET_IPYTHON:
            if not shell_base:
                self.flag(node, f"gets the IPython shell (`{_text(node)}`) outside a magic, {_SHELL}")
            for child in arguments:
                self.visit(child)
            return
        self._check_setattr(node, callee)
        self._check_namespace_call(node)
        self._check_by_name(node, callee)
        self._check_namespace_read(node)
        path = self.resolve(node)
        if path and path not in ("get_ipython()", "globals()") and id(node) not in self.reported:
            if path.endswith(".__dict__") and path.startswith(("kalman_course", _RUNTIME_MODULE)):
                self.flag(node, f"reads the namespace of a course module (`{_text(node)}`)")
            elif callee == "builtins.getattr" and (reason := _risk(path)):
                self.flag_use(node, path, reason)
        self.visit(func)
        for child in arguments:
            self.visit(child)

    def _check_setattr(self, node: ast.Call, callee: str):
        """``setattr(np, ...)``, ``object.__setattr__(np, ...)``, ``np.__setattr__(...)``."""
        target = None
        if callee in ("builtins.setattr", "builtins.delattr") and node.args:
            target, verb = node.args[0], callee.split(".")[-1]
            if _root(target) in self.nb.machinery:
                return  # flagged as a change of the grading code already
        elif callee.endswith(("__setattr__", "__delattr__")):
            verb = callee.rsplit(".", 1)[-1]
            if callee.startswith(("builtins.object.", "builtins.type.")) and node.args:
                target = node.args[0]
            elif isinstance(node.func, ast.Attribute):
                target = node.func.value
        elif isinstance(node.func, ast.Attribute) and node.func.attr in ("__setattr__", "__delattr__"):
            target, verb = node.func.value, node.func.attr
        if target is not None and (owner := self.resolve(target)):
            what = "a builtin" if owner.split(".")[0] == "builtins" else "something imported"
            self.flag(node, f"calls `{verb}` on `{_text(target)}`{_via(_text(target), owner)}, changing {what}")

    def _check_namespace_call(self, node: ast.Call):
        """``vars(m).update(...)``, ``m.__dict__.setdefault(...)``, ``globals().update(...)``."""
        if not (isinstance(node.func, ast.Attribute) and node.func.attr in _MUTATORS):
            return
        namespace = node.func.value
        owner = self.resolve(namespace)
        if owner.endswith(".__dict__"):
            self._namespace_write(namespace, owner)
        elif owner == "globals()":
            if node.func.attr == "update":
                keys = [k for a in node.args for k in (a.keys if isinstance(a, ast.Dict) else [None])]
                keys += [ast.Constant(k.arg) if k.arg else None for k in node.keywords]
            else:
                keys = node.args[:1] or [None]
            for key in keys:
                self._globals_write(namespace, key)

    def _namespace_write(self, namespace: ast.AST, owner: str):
        module = owner[: -len(".__dict__")]
        self.flag(namespace, f"writes into the namespace of `{_text(namespace)}`{_via(_text(namespace), module)}, "
                             "changing something imported")

    def _globals_write(self, namespace: ast.AST, key_node: ast.AST | None):
        key, where = _str(key_node), _text(namespace)
        if key is None:
            self.flag(namespace, f"writes into `{where}` under a computed name")
        elif key in self.nb.to_write:
            self.flag(namespace, f"binds `{key}` through `{where}` instead of writing it")
        elif key in self.nb.released_imports:
            self.flag(namespace, f"rebinds `{key}`, a name the exercise imports, through `{where}`")

    def _check_by_name(self, node: ast.Call, callee: str):
        """``getattr`` and ``operator.attrgetter`` of what the learner must write, or on course modules."""
        if callee == "builtins.getattr" and len(node.args) >= 2:
            owner, key = self.resolve(node.args[0]), _str(node.args[1])
            shown = _text(node.args[0])
            if key in self.nb.to_write:
                self.flag(node, f"gets `{key}` by name (`getattr`) instead of writing it")
            elif owner.startswith(_RUNTIME_MODULE):
                self.flag(node, "calls `getattr` on a module imported at run time")
            elif owner.startswith("kalman_course"):
                self.flag(node, f"calls `getattr` on `{shown}`{_via(shown, owner)}, a course module")
            elif key is None and owner and owner.split(".")[0] in _SENSITIVE_ROOTS:
                self.flag(node, f"calls `getattr` on `{shown}`{_via(shown, owner)} with a computed name")
            elif key in _SHELL_METHODS_BY_NAME:
                self.flag(node, f"gets `{key}` by name (`getattr`), {_SHELL}")
        elif callee in ("operator.attrgetter", "operator.methodcaller"):
            names = {part for a in node.args[:1 if callee.endswith("methodcaller") else None]
                     if (s := _str(a)) for part in s.split(".")}
            for name in sorted(names & self.nb.to_write):
                self.flag(node, f"gets `{name}` by name (`{callee}`) instead of writing it")
            for name in sorted(names & _SHELL_METHODS_BY_NAME):
                self.flag(node, f"gets `{name}` by name (`{callee}`), {_SHELL}")
        elif (isinstance(node.func, ast.Call) and node.args
              and self.resolve(node.func.func) in ("operator.attrgetter", "operator.methodcaller")):
            owner = self.resolve(node.args[0])
            if owner.startswith(("kalman_course", _RUNTIME_MODULE)):
                self.flag(node, f"applies `{_text(node.func)}` to a course module")

    def _check_namespace_read(self, node: ast.Call):
        """``globals().values()``, ``vars(builtins).items()``: every value of a namespace, the
        IPython shell's ``get_ipython`` among them, without naming it."""
        if isinstance(node.func, ast.Attribute) and node.func.attr in ("values", "items"):
            owner = self.resolve(node.func.value)
            if owner == "globals()" or owner in ("builtins.__dict__", "__main__.__dict__"):
                self.flag(node, f"reads every value of `{_text(node.func.value)}`, {_SHELL}")

    def visit_Subscript(self, node):
        """``globals()[name]`` under a computed name reaches any name, ``get_ipython`` among them."""
        key = _str(node.slice)
        if isinstance(node.ctx, ast.Load) and key is None:
            owner = self.resolve(node.value)
            if owner == "globals()" or owner in ("builtins", "builtins.__dict__", "__main__.__dict__"):
                self.flag(node, f"reads `{_text(node.value)}` under a computed name, {_SHELL}")
        elif key in _SHELL_METHODS and self.resolve(node.value).endswith(".__dict__"):  # vars(exit)["_ip"]
            self.flag(node, f"uses `{_text(node)}`, {_SHELL}")
        self.generic_visit(node)

    # assignments

    def _check_targets(self, targets: list[ast.AST], verb: str, kinds=(ast.Attribute, ast.Subscript)):
        for target in targets:
            for t in ast.walk(target):
                if (not isinstance(getattr(t, "ctx", None), (ast.Store, ast.Del)) or id(t) in self.reported
                        or not isinstance(t, kinds)):
                    continue
                if isinstance(t, ast.Attribute):
                    if t.attr in _INTERNALS:
                        self.flag(t, f"{verb} `{_text(t)}`, swapping the internals of an object")
                        continue
                    owner = self.resolve(t.value)
                    if (not owner or _root(t) in self.nb.machinery  # the grading code: flagged as such already
                            or owner.startswith("get_ipython()") or owner == "globals()"):
                        continue
                    what = "patching a builtin" if owner.split(".")[0] == "builtins" else "patching something imported"
                    self.flag(t, f"{verb} `{_text(t)}`{_via(_text(t), f'{owner}.{t.attr}')}, {what}")
                elif isinstance(t, ast.Subscript):
                    owner = self.resolve(t.value)
                    if owner.endswith(".__dict__"):
                        self._namespace_write(t.value, owner)
                    elif owner == "globals()":
                        self._globals_write(t.value, t.slice)

    def _visit_assignment(self, node, targets: list[ast.AST], verb: str = "assigns to"):
        # a write into a namespace is reported as such, not also as a read of it; an attribute
        # whose use is flagged (``sys.excepthook = ...``) is not reported again as an assignment
        self._check_targets(targets, verb, kinds=ast.Subscript)
        self.generic_visit(node)
        self._check_targets(targets, verb, kinds=ast.Attribute)

    def visit_Assign(self, node):
        self._visit_assignment(node, node.targets)

    def visit_AugAssign(self, node):
        self._visit_assignment(node, [node.target])

    visit_AnnAssign = visit_AugAssign

    def visit_Delete(self, node):
        self._visit_assignment(node, node.targets, "deletes")

    def visit_For(self, node):
        self._visit_assignment(node, [node.target])

    visit_AsyncFor = visit_For

    def visit_With(self, node):
        self._visit_assignment(node, [i.optional_vars for i in node.items if i.optional_vars is not None])

    visit_AsyncWith = visit_With


# --- IPython's state, as the notebook sets it ----------------------------------------------------

def _survey(sources: list[str]) -> _Shell:
    """IPython's state as the cells set it (aliases, autocall, the files they write), read
    twice: the first reading finds the aliases and files that the second one reads with."""
    shell = _Shell()
    for _ in range(2):
        parse = _parser(shell)
        shell = _settings([t for s in sources if (t := parse(s)) is not None], shell)
        if not (shell.line_aliases or shell.cell_aliases or shell.system_aliases or shell.autocall
                or shell.rehashx or shell.files):
            break  # nothing read differently a second time (the names bound are read with in the end)
    return shell


def _settings(trees: list[ast.Module], shell: _Shell) -> _Shell:
    """The state that ``trees`` set, their magics read with the aliases of ``shell``."""
    new, bound = _Shell(), set()
    try:
        resolve = _Reader(_notebook([], trees, set(), set())).resolve  # `o = open` is open too
    except RecursionError:  # nested too deeply to resolve aliases; the review proper reports it
        resolve = _Reader(_Notebook(set(), set())).resolve
    for tree in trees:
        bound |= {name for name, _, _ in _scope_names(tree.body, {})[0]}
        for inv in _invocations(tree, shell):
            _apply_setting(inv, new)
        try:
            writes = _python_writes(tree, resolve)
        except RecursionError:  # nested too deeply to resolve: the cell's own review says so
            writes = []
        for name_node, text, append, _ in writes:
            if (path := _str(name_node)) is not None and text is not None:
                _write(new, path, text, append)
    new.bound = frozenset(bound)
    return new


def _write(shell: _Shell, path: str, text: str, append: bool):
    key = _normalised(path)
    versions = shell.files.setdefault(key, [])
    versions.append((versions[-1] if append and versions else "") + text)


def _apply_setting(inv: _Invocation, shell: _Shell):
    """What one magic changes in ``shell``: an alias, autocall, a file written."""
    if inv.kind == "line" and inv.name == "alias_magic":
        _add_magic_alias(inv.line, shell)
    elif inv.kind == "line" and inv.name == "alias" and len(parts := inv.line.strip().split(None, 1)) == 2:
        shell.system_aliases[parts[0]] = parts[1]
    elif inv.kind == "line" and (inv.name == "autocall" or (inv.name == "config" and "autocall" in inv.line)):
        shell.autocall = True
    elif inv.kind == "line" and inv.name == "rehashx":
        shell.rehashx = True
    elif inv.kind == "cell" and inv.name in ("writefile", "file"):
        words = _words(inv.line)
        if paths := [w for w in words if not w.startswith("-")]:
            _write(shell, paths[-1], inv.body, append=any(w in ("-a", "--append") for w in words))
    if (script := _shell_text(inv)) is not None:
        for path, body, expands in _heredocs(script):
            if path and not (expands and re.search(r"[$`\\]", body)):  # else the shell writes other text
                _write(shell, path, body, append=False)


def _add_magic_alias(line: str, shell: _Shell):
    """``%alias_magic [-l] [-c] [-p PARAMS] name target``: neither -l nor -c makes both."""
    words, kinds, params, names, i = _words(line), set(), "", [], 0
    while i < len(words):
        if words[i] in ("-l", "--line", "-c", "--cell"):
            kinds.add(words[i].lstrip("-")[0])
        elif words[i] in ("-p", "--params"):
            params, i = (words[i + 1] if i + 1 < len(words) else ""), i + 1
        elif words[i].startswith("--params="):
            params = words[i].split("=", 1)[1]
        else:
            names.append(words[i].lstrip("%"))
        i += 1
    if len(names) >= 2:
        for kind, aliases in (("l", shell.line_aliases), ("c", shell.cell_aliases)):
            if not kinds or kind in kinds:
                aliases[names[0]] = (names[1], params.strip("'\""))


# --- flags about what IPython runs ---------------------------------------------------------------

def _ipython_flags(tree: ast.Module, nb: _Notebook) -> set[str]:
    """The magics and shell escapes of ``tree`` that change how IPython reads later cells or
    run code the review cannot read (less what the release's own cells do)."""
    flags = set()
    for inv in _invocations(tree, nb.shell):
        if (script := _shell_text(inv)) is not None:
            flags |= _shell_flags(script)
        if inv.kind == "line":
            flags |= _line_magic_flags(inv, nb.shell)
        elif inv.kind == "cell" and inv.name in ("writefile", "file") and _COMPILED_FILE.search(inv.line.strip()):
            flags.add(f"writes `{inv.line.strip()}`, compiled Python the review cannot read")
        elif inv.kind == "cell" and inv.name not in _CELL_MAGICS:
            flags.add(f"runs `%%{inv.written}`, a cell magic the review does not know, so it cannot tell what runs")
    return flags - nb.released_ipython


def _changes_reading(name: str, line: str) -> bool:
    """Whether ``%name line`` changes how IPython reads later cells (``%config`` of how output
    looks, ``%alias`` that only lists, ``%autoawait`` with asyncio do not)."""
    if name == "config":
        match = re.match(r"\s*(\w+)\.(\w+)\s*=", line)
        return match is not None and not (match.group(1) in _HONEST_CONFIG_CLASSES or (
            match.group(1) in _SHELL_CLASSES and match.group(2) in _HONEST_SHELL_TRAITS))
    if name == "alias":
        return bool(line.strip())
    if name == "autoawait":
        return line.strip().lower() not in _HONEST_AWAIT
    return True


def _line_magic_flags(inv: _Invocation, shell: _Shell) -> set[str]:
    shown, name, line = inv.shown(), inv.name, inv.line
    if name in _READING_MAGICS and _changes_reading(name, line):
        return {f"uses `{shown}`, {_READS_LATER}"}
    if name == "run":
        kind, target = _run_target(line)
        if target and not (shell.file(target) if kind == "file" else shell.module(target)):
            what = f"the module `{target}`" if kind == "module" else f"`{target}`"
            return {f"runs {what} (`{shown}`), whose code is not in the notebook"}
    if name in ("load", "loadpy") and (target := _load_target(line)) and not shell.file(target):
        return {f"loads `{target}` into the cell (`{shown}`), {_UNREADABLE}"}
    if name in ("load_ext", "reload_ext") and (words := _words(line)):
        if shell.module(words[0]):
            return {f"loads `{words[0]}`, an IPython extension written in the notebook (`{shown}`), "
                    "which is handed the IPython shell"}
        if words[0].split(".")[0] not in _HONEST_EXTENSIONS:
            return {f"loads the IPython extension `{words[0]}` (`{shown}`), which is handed the IPython shell"}
    if name == "rerun":  # the history it reruns is a list any cell can change (`In[3] = ...`)
        return {f"reruns input from IPython's history (`{shown}`), {_UNREADABLE}"}
    if name == "store" and "-r" in _words(line):
        return {f"restores variables with `{shown}`, objects the review cannot read"}
    return set()


def _shell_flags(script: str) -> set[str]:
    """A shell script that runs Python, writes a Python file or installs a package from a path
    or URL: code the review cannot read (``ls``, ``pip list``, ``pip install numpy`` are none)."""
    flags = set()
    text = re.sub(r"\{[^{}]*\bexecutable\b[^{}]*\}|\$\{?sys\.executable\}?", "python", script)  # {sys.executable}
    text = _PYTHON_PIP.sub("pip", text)
    text = re.sub(r"(?m)(^|\s)#.*$", r"\1", text)  # comments (`# then run python`) run nothing
    for segment in re.split(r"\n|;|&&|\|\||\||&|\$\(|`", text):  # commands, and those in $(...) and `...`
        words = [w.strip("'\"()") for w in segment.split()]
        while words and (words[0] in _COMMAND_PREFIXES or re.match(r"\w+=", words[0])):
            words.pop(0)  # `env X=1 sudo python ...` runs python
        if not words:
            continue
        shown, command = _shortened(segment), os.path.basename(words[0])
        if _RUNS_PYTHON.search(segment) and command not in _READ_ONLY_COMMANDS - {"rm", "rmdir", "pip", "pip3"}:
            flags.add(f"runs Python in another process (`{shown}`), {_UNREADABLE}")
            continue
        if (command in ("pip", "pip3", "conda", "mamba", "uv") and "install" in words
                and any(_LOCAL_PACKAGE.search(w) for w in words[words.index("install") + 1:])):
            flags.add(f"installs a package from a path or URL (`{shown}`), {_UNREADABLE}")
        targets = [m.group(2) for m in (*_REDIRECT.finditer(segment), *_TEE.finditer(segment))]
        if any(_PYTHON_FILE.search(t) for t in targets) or (
                command not in _READ_ONLY_COMMANDS and any(_PYTHON_FILE.search(w) for w in words[1:])):
            flags.add(f"writes a Python file from a shell (`{shown}`), {_UNREADABLE}")
    return flags


@functools.lru_cache(maxsize=None)
def _installed(top: str) -> bool:
    """Whether a module of that name can be imported where the review runs (the kernel's
    environment) without the notebook writing it."""
    if top in sys.stdlib_module_names or top in sys.builtin_module_names or top in sys.modules:
        return True
    try:
        return importlib.util.find_spec(top) is not None
    except (ImportError, ValueError):
        return False


def _import_flags(tree: ast.Module, nb: _Notebook) -> set[str]:
    """Imports of a module that is neither installed nor written in the notebook: something
    the review cannot read (a shell, a computed file name) put it where the kernel looks."""
    flags = set()
    for node in _walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            names = [node.module]
        elif (text := _str(node)) is not None and (match := _BACKEND_MODULE.match(text.strip())):
            names = [match.group(1)]
        else:
            continue
        for name in names:
            top = name.split(".", 1)[0]
            if not (top in nb.released_modules or _installed(top)
                    or nb.shell.module(name) or nb.shell.module(top)):
                flags.add(f"imports `{name}`, a module that is not installed and whose code is not in the notebook")
    return flags


def _open_call(node: ast.AST, resolve) -> tuple[ast.AST, bool, bool] | None:
    """For a call that opens a file: (the node naming the file, whether it writes, whether it
    appends); else None."""
    if not isinstance(node, ast.Call):
        return None
    callee = resolve(node.func)
    if callee in _OPENERS and node.args:
        name, mode = node.args[0], (node.args[1:2] or [k.value for k in node.keywords if k.arg in ("mode", "flags")])
    elif (isinstance(node.func, ast.Attribute) and node.func.attr == "open"
          and (name := _path_name(node.func.value, resolve)) is not None):
        mode = node.args[:1] or [k.value for k in node.keywords if k.arg == "mode"]
    else:
        return None
    if callee == "os.open":
        return name, not (mode and resolve(mode[0]) == "os.O_RDONLY"), False
    text = _str(mode[0]) if mode else "r"
    return name, text is None or bool(set(text) & set("wax+")), text is not None and "a" in text


def _path_name(node: ast.AST, resolve) -> ast.AST | None:
    """The node naming the file of ``Path(name)``, else None."""
    if isinstance(node, ast.Call) and resolve(node.func) in _PATHS and len(node.args) == 1:
        return node.args[0]
    return None


def _written_text(call: ast.Call) -> str | None:
    """What ``f.write(...)``, ``f.writelines([...])`` or ``p.write_text(...)`` writes, if constant."""
    values = call.args[0].elts if (call.func.attr == "writelines" and call.args
                                   and isinstance(call.args[0], (ast.List, ast.Tuple))) else call.args[:1]
    texts = [v.value for v in values if isinstance(v, ast.Constant) and isinstance(v.value, (str, bytes))]
    if len(call.args) != 1 or len(texts) != len(values):
        return None
    return "".join(t if isinstance(t, str) else t.decode("utf-8", "replace") for t in texts)


def _with_text(body: list[ast.stmt], name: str) -> str | None:
    """What a ``with open(...) as name:`` body writes, if every use of ``name`` writes a constant."""
    module, texts, uses = ast.Module(body=body, type_ignores=[]), [], 0
    for node in ast.walk(module):
        if isinstance(node, ast.Name) and node.id == name:
            uses += 1
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                and node.func.attr in ("write", "writelines")
                and isinstance(node.func.value, ast.Name) and node.func.value.id == name):
            texts.append(_written_text(node))
    return "".join(texts) if texts and None not in texts and uses == len(texts) else None


_WRITES = ("write", "writelines", "write_text", "write_bytes")


def _python_writes(tree: ast.Module, resolve) -> list[tuple[ast.AST | None, str | None, bool, ast.AST]]:
    """The files Python code in ``tree`` writes: (the node naming the file or None, the text if
    constant, whether it appends, the node that writes)."""
    writes, handled = [], set()
    for node in _walk(tree):
        if isinstance(node, (ast.With, ast.AsyncWith)):
            for item in node.items:
                opened = _open_call(item.context_expr, resolve)
                if opened and opened[1] and isinstance(item.optional_vars, ast.Name):
                    handled.add(id(item.context_expr))
                    text = _with_text(node.body, item.optional_vars.id)
                    writes.append((opened[0], text, opened[2], item.context_expr))
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr in _WRITES:
            base, text = node.func.value, _written_text(node)
            if node.func.attr in ("write_text", "write_bytes"):
                writes.append((_path_name(base, resolve), text, False, node))
            elif (opened := _open_call(base, resolve)) and opened[1]:
                handled.add(id(base))
                writes.append((opened[0], text, opened[2], node))
        elif isinstance(node, ast.Call) and resolve(node.func) in _COPIES and len(node.args) >= 2:
            python = [a for a in node.args[:2] if _str(a) and _PYTHON_FILE.search(_str(a))]
            writes.append(((python or node.args[1:2])[0], None, False, node))
    for node in _walk(tree):
        if id(node) not in handled and (opened := _open_call(node, resolve)) and opened[1]:
            writes.append((opened[0], None, opened[2], node))
    return writes


def _names_another_file(node: ast.AST) -> bool:
    """Whether a computed file name visibly ends in a suffix that is not Python's
    (``f"run_{k}.csv"``, ``os.path.join(folder, "belief.npy")``)."""
    last = (node.values[-1] if isinstance(node, ast.JoinedStr) and node.values else node.right
            if isinstance(node, ast.BinOp) else node.args[-1] if isinstance(node, ast.Call) and node.args else node)
    text = _str(last)
    return text is not None and re.search(r"\.\w+$", text) is not None and not _PYTHON_FILE.search(text)


def _command_text(node: ast.AST, resolve) -> str | None:
    """The command an argument of ``subprocess.run`` and the like names, if constant
    (``sys.executable`` reads as python)."""
    if (text := _str(node)) is not None:
        return text
    if isinstance(node, (ast.List, ast.Tuple)):
        parts = [_command_text(e, resolve) for e in node.elts]
        return None if None in parts else " ".join(parts)
    if resolve(node) == "sys.executable":
        return "python"
    return None


def _write_flags(tree: ast.Module, nb: _Notebook) -> set[str]:
    """Python that writes a Python file the review cannot read (or a file whose name it cannot
    read), or starts a process that runs Python or writes such a file."""
    flags, resolve = set(), _Reader(nb).resolve
    for name_node, text, _, node in _python_writes(tree, resolve):
        path = _str(name_node) if name_node is not None else None
        if path is not None and _COMPILED_FILE.search(path):
            flags.add(f"writes `{path}`, compiled Python the review cannot read")
        elif path is not None and text is None and _PYTHON_FILE.search(path):
            flags.add(f"writes `{path}`, a Python file, with text the review cannot read")
        elif path is None and not (name_node is not None and _names_another_file(name_node)):
            flags.add(f"writes a file whose name the review cannot read (`{_text(node)}`)")
    for node in _walk(tree):
        if isinstance(node, ast.Call) and resolve(node.func) in _PROCESSES:
            arguments = [*node.args, *(k.value for k in node.keywords if k.arg in ("args", "cmd"))]
            parts = [_command_text(a, resolve) for a in arguments]
            if all(p is None for p in parts):
                flags.add(f"runs a command the review cannot read (`{_text(node)}`)")
            else:
                flags |= _shell_flags(" ".join(p or "?" for p in parts))
    return flags


def _rebinding_flags(tree: ast.Module, nb: _Notebook) -> set[str]:
    """Module-level rebinding of the names the release imports, and ``global`` declarations of them."""
    flags = set()
    for name, how, what in nb.scope_names(tree.body)[0]:
        if name not in nb.released_imports:
            continue
        if how == "import":
            if what != nb.released_imports[name]:
                flags.add(f"rebinds `{name}`, a name the exercise imports, to `{what}`")
        elif how == "delete":
            flags.add(f"deletes `{name}`, a name the exercise imports")
        else:
            flags.add(f"rebinds `{name}`, a name the exercise imports")
    for node in _walk(tree):
        if isinstance(node, ast.Global):
            for name in node.names:
                if name in nb.released_imports:
                    flags.add(f"declares `global {name}`, so that a function can rebind a name the exercise imports")
    return flags


def _cell_flags(tree: ast.Module, nb: _Notebook) -> set[str]:
    """The flags of one cell, without its id (so that they can be compared with the release)."""
    if getattr(tree, "too_deep", False):
        return {_TOO_DEEP}
    to_write, machinery = nb.to_write, nb.machinery
    flags = set()
    for node in _walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if _is_machinery(a.name) or a.name.split(".", 1)[0] in _ESCAPES:
                    flags.add(f"imports `{a.name}`")
        elif isinstance(node, ast.ImportFrom):
            module = node.module or ""
            for a in node.names:
                if a.name in to_write or (a.asname or "") in to_write:
                    flags.add(f"imports `{a.name}` from `{module}` instead of writing it")
                elif _is_machinery(module) or _is_machinery(f"{module}.{a.name}"):
                    flags.add(f"imports `{a.name}` from `{module}`")
                elif module.startswith("kalman_course") and a.name.startswith("_"):
                    flags.add(f"imports `{a.name}` from `{module}`, a private name of the course's code")
                elif module.split(".", 1)[0] in _ESCAPES:
                    flags.add(f"imports from `{module}`")
        elif isinstance(node, (ast.Assign, ast.AugAssign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for target in targets:
                for t in ast.walk(target):
                    if isinstance(t, ast.Attribute) and _root(t) in machinery:
                        flags.add(f"assigns to `{_dotted(t)}`, part of the grading code")
                    elif isinstance(t, ast.Name) and t.id in to_write and _dotted(node.value).count("."):
                        flags.add(f"binds `{t.id}` to `{_dotted(node.value)}` instead of writing it")
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ("setattr", "delattr"):
            if node.args and _root(node.args[0]) in machinery:
                flags.add(f"calls `{node.func.id}` on `{_dotted(node.args[0])}`, part of the grading code")
        elif isinstance(node, ast.Attribute) and _dotted(node) == "sys.modules":
            flags.add("uses `sys.modules`")
        elif isinstance(node, ast.Name) and node.id == "__builtins__":
            flags.add("uses `__builtins__`")
        if isinstance(node, ast.FunctionDef) and node.name in to_write:
            for inner in ast.walk(node):
                if isinstance(inner, ast.Attribute) and inner.attr == node.name and _dotted(inner):
                    flags.add(f"`{node.name}` calls `{_dotted(inner)}` instead of doing the work")
    reader, ipython = _Reader(nb), set(getattr(tree, "notes", ()))
    try:
        reader.visit(tree)
        # what IPython makes the cell run beyond its Python: magics, shells, files, unknown modules
        ipython |= _ipython_flags(tree, nb) | _import_flags(tree, nb) | _write_flags(tree, nb)
    except RecursionError:  # the walk recurses; code nested this deeply is worth reading by hand anyway
        reader.flags.add(_TOO_DEEP)
    return flags | reader.flags | _rebinding_flags(tree, nb) | ipython


def _functions_to_write(release, parse) -> set[str]:
    names = set()
    for cell in release.cells:
        if cell.cell_type == "code" and FIX_THIS in cell.source and (tree := parse(cell.source)):
            names |= {n.name for n in ast.walk(tree) if isinstance(n, ast.FunctionDef)}
    return names


def solution_course_calls(solution, exercise) -> dict[str, list[str]]:
    """For each function the exercise asks for, the course functions its solution calls.

    Parameters
    ----------
    solution, exercise : NotebookNode
        A solution notebook and the exercise built from it (which names the functions to
        write: those with a ``# fix this`` line).

    Returns
    -------
    dict of str to list of str
        Function name -> sorted dotted paths (``kalman_course.so3.Exp``); stored in the
        exercise's metadata, where :func:`review_flags` reads it.
    """
    parse = _parser()
    to_write = _functions_to_write(exercise, parse)
    trees = [t for c in solution.cells if c.cell_type == "code" and not grader_info(c) and (t := parse(c.source))]
    nb = _notebook(trees, [], to_write, set())
    return {name: sorted(paths) for name, paths in sorted(nb.released_calls.items())}


def review_flags(submission, release) -> list[str]:
    """Reasons to review ``submission`` by hand, one line each (empty when there are none).

    Parameters
    ----------
    submission : nbformat.NotebookNode
        The learner's notebook as written. The one cell taken as each grader (see
        :mod:`kalman_course.tooling.identify`) is skipped: grading restores it. Every other
        code cell is read, whatever id it carries.
    release : nbformat.NotebookNode
        The released exercise of the same chapter.

    Returns
    -------
    list of str
        ``"<cell>: <what the code does>"``, in cell order, the cell named as
        :attr:`Identified.labels <kalman_course.tooling.identify.Identified>` names it
        (``cell update``, ``cell 7 (no id)``); flags that the released cell it was written
        into raises too are left out.
    """
    cells = identify_cells(submission, release)
    released = [c for c in release.cells if c.cell_type == "code"]
    learner_cells = [(i, c) for i, c in enumerate(submission.cells)
                     if c.get("cell_type") == "code" and i not in cells.graders]
    # IPython's state (aliases, autocall, files written) as the cells that run set it
    shell = _survey([*(c.source for _, c in learner_cells), *(c.source for c in released)])
    parse = _parser(shell)
    to_write = _functions_to_write(release, parse)
    release_trees = [t for c in released if (t := parse(c.source))]
    learner_trees = [t for _, c in learner_cells if (t := parse(c.source))]
    machinery = set()
    # the cells that run: what a grader cell holds in the submission is replaced before the run
    all_trees = [*release_trees, *learner_trees]
    for tree in {id(t): t for t in all_trees}.values():  # a cell the learner left as released is read once
        machinery |= _machinery_names(tree)
    check_api = {"CheckFailed", "SUCCESS", *(grader_info(c)[0] for c in released if grader_info(c))}
    nb = _notebook(release_trees, learner_trees, to_write, machinery, check_api, shell)
    nb.released_ipython = {flag for tree in release_trees for flag in _ipython_flags(tree, nb)}
    solution_calls = release.metadata.get("kalman_course", {}).get("course_calls", {})
    for name, paths in solution_calls.items():
        nb.released_calls.setdefault(name, set()).update(paths)

    out = []
    for i, cell in learner_cells:
        r = cells.originals.get(i)
        original = release.cells[r] if r is not None else None
        if original is not None and same_code(original.source, cell.source):
            continue
        tree = parse(cell.source)
        if tree is None:
            continue
        flags = _cell_flags(tree, nb)
        if flags and original is not None and (original_tree := parse(original.source)):
            flags -= _cell_flags(original_tree, nb)
        out += [f"{cells.labels[i]}: {flag}" for flag in sorted(flags)]
    return out
