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


def call_quietly(fn, args: tuple):
    """``fn(*args)`` as the checks call learner code: on fresh copies of the arguments, its
    prints and warnings silenced, floating-point warnings off (a grader cell and this agent
    both call learner functions this way)."""
    sink = io.StringIO()
    with contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink), \
            warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        return fn(*copy.deepcopy(args))


def _call(namespace: dict, request: dict):
    fn = request["callee"]
    if not callable(fn):
        return {"not_callable": type(fn).__name__}
    try:
        result = call_quietly(fn, request["args"])
    except (Exception, SystemExit) as exc:  # the learner's code may raise anything
        return {"raised": plain_data.Raised(type(exc).__name__, str(exc))}
    return {"result": result}


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
