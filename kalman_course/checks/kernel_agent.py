"""The grading process's hand inside the learner's kernel: run learner code on plain data.

``kalman-course grade`` runs the learner's cells in their own kernel and the checks in the
grading process. When a check calls a learner function, the grading process sends the
call as a comm message (:func:`listen` registered the target before the learner's cells
ran): this module decodes the arguments (:mod:`plain_data`), calls the function exactly as
a grader cell would (prints and warnings silenced, floating-point warnings off, arguments
fresh copies), and sends back the result as plain data, or the exception it raised.

Nothing here knows an expected value, and nothing the kernel sends back is trusted beyond
being data: a learner who replaces this module only changes what their own functions
appear to return.
"""

from __future__ import annotations

import contextlib
import copy
import functools
import inspect
import io
import types
import warnings

import numpy as np

from kalman_course.checks import plain_data
from kalman_course.core import withheld

#: The largest answer a check accepts, in characters of JSON (a whole ESKF run is ~5 MB).
MAX_ANSWER = 16 * 2**20

#: Dataclass instances received whole earlier in this kernel, by handle (see plain_data.encode).
_HANDLES: dict[int, object] = {}


def global_names(code: types.CodeType) -> set[str]:
    """Global names a function's code refers to, including its comprehensions and lambdas."""
    names = set(code.co_names)
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            names |= global_names(const)
    return names


def to_plain(value):
    """Replace a learner's result that is not plain data by the nearest plain value.

    Subclasses of ``str``, ``int``, ``float``, ``list``, ``tuple`` and ``dict`` become the
    builtin (their value, not their methods, crosses); an array-like (a SymPy matrix, an
    ``np.matrix``) becomes an array; anything else is reported by its type's name only.
    """
    for base in (bool, str, int, float, complex):
        if isinstance(value, base):
            return base.__new__(base, value) if base is not bool else bool(value)
    if isinstance(value, np.ndarray):
        return np.array(value, subok=False)
    if isinstance(value, np.generic):
        return value.item()
    for container in (list, tuple, dict):
        if isinstance(value, container):
            return container(value)
    if hasattr(value, "__array__"):
        try:
            arr = np.asarray(value)
            if arr.dtype == object:
                arr = arr.astype(float)
            return np.array(arr, subok=False)
        except Exception:  # an array-like that is not numeric
            pass
    return plain_data.Opaque(type(value).__name__)


def _lookup(namespace: dict):
    def learner_object(name: str):
        if name not in namespace:
            raise NameError(f"name '{name}' is not defined")
        return namespace[name]
    return learner_object


def _describe(namespace: dict, name: str) -> dict:
    """Whether ``name`` is defined and callable, and the global names its code refers to."""
    obj = namespace.get(name)
    code = getattr(obj, "__code__", None)
    return {"defined": name in namespace, "callable": callable(obj), "type": type(obj).__name__,
            "globals": sorted(global_names(code)) if isinstance(code, types.CodeType) else None}


def call_watched(fn, args: tuple, repeat: bool = True):
    """``fn(*args)`` as the checks call learner code, and how the call behaved besides its result.

    The call runs on fresh copies of the arguments, its prints and warnings silenced and
    floating-point warnings off (a grader cell and this agent both call learner functions
    this way). With ``repeat`` (a check asks for it on its first call of each function, see
    :func:`harness.call`), a function of the notebook is called a second time on the same
    inputs.

    Returns
    -------
    result
        What ``fn`` returned.
    behaviour : list of [str, str] or [str, str, str]
        ``[kind, detail]`` for each property of well-behaved code the call broke (``[kind,
        detail, name]`` when a notebook function that ``fn`` drove broke it), in the
        order of :data:`BEHAVIOUR`: ``changed`` (an argument modified in place; detail: its
        name), ``aliased`` (a returned array shares memory with an argument: its name),
        ``precision`` (a floating result narrower than float64: where and which type),
        ``unrepeatable`` (a second call on the same inputs returned something else; tried
        for functions of the notebook only, whose calls are cheap).
    """
    with _quiet():
        return _watched_call(fn, args, repeat)


def _watched_call(fn, args: tuple, repeat: bool):
    given = _copies(args)  # the learner's code never sees ``args`` themselves: they stay as they were
    inner: list = []  # what the notebook's functions that a package function drives did
    result = fn(*(given if _of_the_notebook(fn) else _watching(given, inner)))
    names = _parameter_names(fn, len(args))
    behaviour = [["changed", names[i]] for i, (old, new) in enumerate(zip(args, given))
                 if not _same(old, new)]
    behaviour += inner
    given_arrays = [(names[i], a) for i, arg in enumerate(given) for a in _arrays(arg)]
    behaviour += [["aliased", name] for name in dict.fromkeys(
        name for r in _arrays(result) for name, a in given_arrays
        if np.may_share_memory(r, a) and np.shares_memory(r, a))]  # the first test is cheap, the second exact
    behaviour += [["precision", what] for what in _narrow_floats(result)]
    if repeat and not behaviour and _of_the_notebook(fn):
        try:
            again = fn(*_copies(args))
        except (Exception, SystemExit):
            again = _RAISED
        if not _same(result, again):
            behaviour.append(["unrepeatable", ""])
    return result, behaviour


class _Watched:
    """A notebook function handed to a package function (a whole filter run from the learner's
    steps): its first calls run on copies and are watched like a direct call, so that a step
    that changes its arguments in place is named, not the run it spoils."""

    WATCHED_CALLS = 2

    def __init__(self, fn, found: list):
        self.fn, self.found, self.calls = fn, found, 0
        functools.update_wrapper(self, fn)

    def __call__(self, *args, **kwargs):
        if kwargs or self.calls >= self.WATCHED_CALLS:
            return self.fn(*args, **kwargs)
        self.calls += 1
        given = copy.deepcopy(args)  # the package's own arrays are not handed over while watched
        result = self.fn(*given)
        names = _parameter_names(self.fn, len(args))
        who = getattr(self.fn, "__name__", "a function of yours")
        changed = [["changed", names[i], who] for i, (old, new) in enumerate(zip(args, given)) if not _same(old, new)]
        narrow = [["precision", what, who] for what in _narrow_floats(result)]
        for item in changed + narrow:
            if item not in self.found:
                self.found.append(item)
        return result


def _watching(args: tuple, found: list) -> tuple:
    """``args`` with each notebook function among them (or in a list, tuple or dict among
    them) watched by a :class:`_Watched`."""
    def watched(value):
        return _Watched(value, found) if _of_the_notebook(value) else value

    out = []
    for arg in args:
        if isinstance(arg, dict):
            arg = type(arg)({k: watched(v) for k, v in arg.items()}) if type(arg) is dict else arg
        elif type(arg) in (list, tuple):
            arg = type(arg)(watched(v) for v in arg)
        out.append(watched(arg))
    return tuple(out)


#: The properties :func:`call_watched` reports, in the order it reports them.
BEHAVIOUR = ("changed", "aliased", "precision", "unrepeatable")

_RAISED = object()  # what a second call that raised is compared as


def _copies(args: tuple) -> tuple:
    """A fresh copy of each argument, each on its own: two arguments that were one array become
    two, as they do when they cross from the grading process as plain data."""
    return tuple(arg.copy() if type(arg) is np.ndarray and arg.dtype != object
                 else arg if type(arg) in (float, int, bool, str, type(None))
                 else copy.deepcopy(arg) for arg in args)


@contextlib.contextmanager
def _quiet():
    """Prints and warnings silenced, floating-point warnings off."""
    sink = io.StringIO()
    with contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink), \
            warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        yield


def _parameter_names(fn, count: int) -> list[str]:
    """The names of ``fn``'s first ``count`` positional parameters ("argument 3" where unknown)."""
    code = getattr(fn, "__code__", None)
    if isinstance(fn, types.FunctionType) and isinstance(code, types.CodeType):
        # a plain function's names are in its code (inspect.signature costs ~50x more)
        params = list(code.co_varnames[:code.co_argcount])
    else:
        try:
            params = [p.name for p in inspect.signature(fn).parameters.values()
                      if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
        except (TypeError, ValueError):
            params = []
    return [params[i] if i < len(params) else f"argument {i + 1}" for i in range(count)]


def _of_the_notebook(fn) -> bool:
    """Whether ``fn`` is a plain function defined in the notebook (not one of this package)."""
    return isinstance(fn, types.FunctionType) and not str(getattr(fn, "__module__", "")).startswith("kalman_course")


def _same(a, b, depth: int = 0) -> bool:
    """Whether two values are equal as data (arrays element by element, NaN equal to NaN)."""
    if depth > 20 or a is b:
        return True
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        if not (isinstance(a, np.ndarray) and isinstance(b, np.ndarray)) or a.shape != b.shape \
                or a.dtype != b.dtype:
            return False
        if a.dtype.kind in "biufc":  # bit for bit: NaN equals NaN, and it is fast
            return np.ascontiguousarray(a).tobytes() == np.ascontiguousarray(b).tobytes()
        return all(_same(x, y, depth + 1) for x, y in zip(a.flat, b.flat))
    if type(a) is not type(b):
        return False
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y, depth + 1) for x, y in zip(a, b))
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k], depth + 1) for k in a)
    if isinstance(a, (float, np.floating)) and a != a and b != b:  # NaN
        return True
    if callable(a):  # a function handed in: not data
        return True
    if hasattr(a, "__dict__") and not isinstance(a, type):
        return _same(vars(a), vars(b), depth + 1)
    try:
        return bool(a == b)
    except Exception:  # a value that cannot be compared is taken as unchanged
        return True


def _arrays(value, depth: int = 0):
    """The NumPy arrays inside ``value`` (through tuples, lists, dict values, object fields)."""
    if depth > 5:
        return
    if isinstance(value, np.ndarray):
        if value.dtype != object:
            yield value
    elif isinstance(value, (list, tuple)):
        for item in value:
            yield from _arrays(item, depth + 1)
    elif isinstance(value, dict):
        for item in value.values():
            yield from _arrays(item, depth + 1)
    elif hasattr(value, "__dict__") and not isinstance(value, type) and not callable(value):
        for item in vars(value).values():
            yield from _arrays(item, depth + 1)


def _narrow_floats(result) -> list[str]:
    """Where a result holds floating values narrower than float64 (float32, float16, complex64)."""
    found = []

    def visit(value, where: str, depth: int) -> None:
        if depth > 5:
            return
        dtype = getattr(value, "dtype", None)
        if isinstance(value, (np.ndarray, np.generic)) and dtype.kind in "fc" and \
                dtype.itemsize < (8 if dtype.kind == "f" else 16):
            found.append(f"{where} is {dtype.name}")
        elif isinstance(value, (list, tuple)):
            for i, item in enumerate(value):
                visit(item, f"item {i} of {where}" if where != "the result" else f"item {i}", depth + 1)
        elif isinstance(value, dict):
            for key, item in value.items():
                visit(item, f"{key!r} of {where}", depth + 1)
        elif hasattr(value, "__dict__") and not isinstance(value, type) and not callable(value):
            for key, item in vars(value).items():
                visit(item, f".{key} of {where}", depth + 1)

    visit(result, "the result", 0)
    return found


def _call(namespace: dict, request: dict):
    fn = request["callee"]
    if not callable(fn):
        return {"not_callable": type(fn).__name__}
    try:
        result, behaviour = call_watched(fn, request["args"], repeat=request.get("repeat", True) is not False)
    except (Exception, SystemExit) as exc:  # the learner's code may raise anything
        return {"raised": plain_data.Raised(type(exc).__name__, str(exc))}
    return {"result": result, "behaviour": behaviour} if behaviour else {"result": result}


def answer(namespace: dict, request: str, handles: dict | None = None) -> str:
    """The plain-data answer to one request of the grading process (JSON text in and out).

    Parameters
    ----------
    namespace : dict
        The notebook's globals, where the learner's functions live.
    request : str
        The request: a call of a function on arguments, or a question about a name.
    handles : dict, optional
        Where dataclass instances sent whole are kept for later requests (default: this
        module's store, one per kernel).
    """
    try:
        decoded = plain_data.decode(request, from_kernel=False, learner_lookup=_lookup(namespace),
                                    handles=_HANDLES if handles is None else handles)
        if decoded["op"] == "describe":
            reply = _describe(namespace, decoded["name"])
        elif decoded["op"] == "withheld":  # the calls of withheld references (a graded kernel's guard)
            reply = {"result": [list(call) for call in withheld.calls()]}
        else:
            reply = _call(namespace, decoded)
    except NameError as exc:  # a learner function handed to another one is not defined
        reply = {"raised": plain_data.Raised("NameError", str(exc))}
    except Exception as exc:  # a malformed request: only if something replaced the grader's
        reply = {"raised": plain_data.Raised(type(exc).__name__, f"the request could not be read: {exc}")}
    try:
        text = plain_data.encode(reply, towards_kernel=False, convert=to_plain)
    except (plain_data.NotPlainData, RecursionError, ValueError, TypeError):
        result = reply.get("result")
        return plain_data.encode({"result": plain_data.Opaque(type(result).__name__)}, towards_kernel=False)
    if len(text) > MAX_ANSWER:  # said here, where it is cheap; the grading process refuses more anyway
        why = (f"your function's result is {len(text) / 2**20:.0f} MiB as data, more than the "
               f"{MAX_ANSWER // 2**20} MiB a check accepts: does it return what the exercise asks for?")
        return plain_data.encode({"raised": plain_data.Raised("ValueError", why)}, towards_kernel=False)
    return text


#: The Jupyter comm target on which the grading process sends its requests.
COMM_TARGET = "kalman_course.grading"


def listen(shell, namespace: dict) -> None:
    """Answer the grading process's requests that arrive on a comm (see :data:`COMM_TARGET`).

    The grading process runs this in a fresh kernel before any learner cell. A comm message
    reaches the kernel without passing through IPython's cell machinery, so a request costs
    about a millisecond; each one is a JSON text in ``data["request"]``, answered in
    ``data["answer"]``.

    Parameters
    ----------
    shell : IPython shell
        ``get_ipython()`` of the kernel.
    namespace : dict
        The notebook's globals.
    """
    def opened(comm, open_msg):
        @comm.on_msg
        def on_request(msg):
            comm.send({"answer": answer(namespace, msg["content"]["data"]["request"])})

    shell.kernel.comm_manager.register_target(COMM_TARGET, opened)
