"""Reasons to look at a graded submission by hand, found by reading its code.

Grading runs the learner's notebook, so code that passes a check without doing the work
can earn the points: importing the function the exercise asks for (the course ships its
reference implementations), changing the grading code or the libraries it uses from an
earlier cell, or reaching into the code that calls the learner's function. None of this
can be prevented inside the kernel, but all of it is visible in the source.
:func:`review_flags` reads the syntax tree of every code cell but the one taken as each
grader (:mod:`kalman_course.tooling.identify`; a cell that only carries a grader's id is
read) that differs from the released cell it was written into (IPython magics translated,
and the Python that ``%time``, ``%timeit``, ``%%capture``, ``%%writefile`` and the like
run read as well) and reports

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
  ``kalman_course`` module or on a module imported at run time.

Names are resolved through the notebook's imports and simple aliases (``import numpy as n``,
``s = sys``, ``from sys import _getframe as g``), scope by scope, so a function's own local
``np = 3`` or a parameter named like a module is not mistaken for the module.

The flags never change points or status: they are shown to the instructor (and to a
learner grading themselves) next to the grade.
"""

from __future__ import annotations

import ast
import builtins
import re
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
                                 "python", "python3", "pypy"})

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
    "runpy": _RUNS, "code.InteractiveInterpreter": _RUNS, "code.InteractiveConsole": _RUNS,
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
_GET_IPYTHON = frozenset({"IPython.get_ipython", "IPython.core.getipython.get_ipython"})

#: Attribute names that honest course code never touches, on whatever object.
_RISKY_ATTRIBUTES = {
    **dict.fromkeys(("f_back", "f_locals", "f_globals", "f_builtins", "f_code", "f_trace", "tb_frame",
                     "gi_frame", "cr_frame", "ag_frame", "_getframe", "settrace", "setprofile"), _FRAMES),
    "addaudithook": _HOOKS,
    **dict.fromkeys(("getsource", "getsourcelines", "getsourcefile", "findsource"), _SOURCE),
    **dict.fromkeys(("set_custom_exc", "input_transformers_cleanup", "input_transformers_post",
                     "input_transformer_manager", "ast_transformers", "register_magic_function",
                     "user_ns", "user_global_ns"), _SHELL),
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


def _parser():
    """A function source -> AST (IPython magics and shell escapes translated, the Python that
    magics run appended at module level; None if the cell is not valid Python), parsing each
    distinct source once."""
    from IPython.core.inputtransformer2 import TransformerManager

    transformer, trees = TransformerManager(), {}

    def parse(source: str, depth: int = 0) -> ast.Module | None:
        if source not in trees:
            try:
                transformed = transformer.transform_cell(source)
                tree = ast.parse(transformed)
            except (SyntaxError, ValueError):
                tree, transformed = None, ""  # the learner's own error; the run reports it
            except RecursionError:  # nested too deeply for the parser (how deep depends on the stack)
                tree, transformed = ast.Module(body=[], type_ignores=[]), ""
                tree.too_deep = True
            # only magics (``get_ipython().run_line_magic(...)``) run Python of their own; a magic
            # inside a magic's body is read too, not endlessly
            if tree is not None and depth < 3 and "get_ipython" in transformed:
                for candidates in _magic_python(tree):
                    inner = next((t for c in candidates if (t := parse(c, depth + 1)) is not None), None)
                    if inner is not None:
                        tree.body.extend(inner.body)
            trees[source] = tree
        return trees[source]

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


def _magic_python(tree: ast.Module):
    """For each magic in ``tree`` that runs Python, the candidate sources of that Python (the
    first that parses is it)."""
    for node in ast.walk(tree):
        if not _is_magic_call(node):
            continue
        args = [_str(a) for a in node.args]
        if node.func.attr == "run_line_magic" and len(args) == 2 and args[0] in _PYTHON_LINE_MAGICS and args[1]:
            yield _after_options(args[1])
        elif node.func.attr == "run_cell_magic" and len(args) == 3 and args[0] and args[2] is not None:
            name, line, body = args
            if name in _PYTHON_CELL_MAGICS or (name == "script" and (line or "").startswith("python")):
                yield [body]
            if name == "timeit" and line:  # the line of %%timeit is setup code
                yield _after_options(line)


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
    for node in ast.walk(tree):
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

    def scope_names(self, body: list[ast.stmt]):
        return _scope_names(body, self.scopes)


def _notebook(release_trees: list[ast.Module], submission_trees: list[ast.Module], to_write, machinery,
              check_api=frozenset()) -> _Notebook:
    nb = _Notebook(to_write, machinery, set(check_api))
    for tree in release_trees:
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

    def resolve(self, node: ast.AST | None) -> str:
        """The dotted path of what ``node`` evaluates to (``numpy.linalg``), '' if unknown."""
        if isinstance(node, ast.Name):
            return self.lookup(node.id)
        if isinstance(node, ast.Attribute):
            base = self.resolve(node.value)
            path = f"{base}.{node.attr}" if base else ""
            return "IPython.get_ipython" if path in _GET_IPYTHON else path
        if isinstance(node, ast.Call):
            return self._resolve_call(node)
        if isinstance(node, ast.Subscript):
            base, key = self.resolve(node.value), _str(node.slice)
            if not base or key is None:
                return ""
            if base == "sys.modules":
                return key
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
        if _is_magic_call(node) or (isinstance(func, ast.Attribute) and func.attr in _MAGIC_METHODS
                                    and self.resolve(func.value) == "get_ipython()"
                                    and isinstance(func.value, ast.Call) and not func.value.args):
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
        elif callee in ("operator.attrgetter", "operator.methodcaller"):
            names = {part for a in node.args if (s := _str(a)) for part in s.split(".")}
            for name in sorted(names & self.nb.to_write):
                self.flag(node, f"gets `{name}` by name (`{callee}`) instead of writing it")
        elif (isinstance(node.func, ast.Call) and node.args
              and self.resolve(node.func.func) in ("operator.attrgetter", "operator.methodcaller")):
            owner = self.resolve(node.args[0])
            if owner.startswith(("kalman_course", _RUNTIME_MODULE)):
                self.flag(node, f"applies `{_text(node.func)}` to a course module")

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
    for node in ast.walk(tree):
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
    for node in ast.walk(tree):
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
    reader = _Reader(nb)
    try:
        reader.visit(tree)
    except RecursionError:  # the walk recurses; code nested this deeply is worth reading by hand anyway
        reader.flags.add(_TOO_DEEP)
    return flags | reader.flags | _rebinding_flags(tree, nb)


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
    parse = _parser()
    to_write = _functions_to_write(release, parse)
    release_trees = [t for c in released if (t := parse(c.source))]
    learner_cells = [(i, c) for i, c in enumerate(submission.cells)
                     if c.get("cell_type") == "code" and i not in cells.graders]
    learner_trees = [t for _, c in learner_cells if (t := parse(c.source))]
    machinery = set()
    # the cells that run: what a grader cell holds in the submission is replaced before the run
    all_trees = [*release_trees, *learner_trees]
    for tree in {id(t): t for t in all_trees}.values():  # a cell the learner left as released is read once
        machinery |= _machinery_names(tree)
    check_api = {"CheckFailed", "SUCCESS", *(grader_info(c)[0] for c in released if grader_info(c))}
    nb = _notebook(release_trees, learner_trees, to_write, machinery, check_api)
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
