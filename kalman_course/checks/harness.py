"""What every check shares: running learner code quietly, comparing, failing with a hint.

A check is a function ``check_<name>`` decorated with :func:`check`, which registers it
under ``<name>`` (the name is written once, in the ``def`` line); ``kalman_course.checks``
exposes every registered check as ``checks.<name>``. A check receives the learner's
objects (usually functions), runs them through :func:`call` next to the reference
implementation, and compares with :func:`expect_close` and friends. On success it prints
one constant line, ``<name>: passed``; on failure it raises :class:`CheckFailed`, whose
message says what is wrong and, where the mistake is a known one, why.
"""

from __future__ import annotations

import contextvars
import functools
import re
import types
from typing import Callable, Iterable

import numpy as np

from kalman_course.checks import hints
from kalman_course.core import linalg
from kalman_course.checks.kernel_agent import call_watched, global_names
from kalman_course.checks.plain_data import Opaque
from kalman_course.checks.remote import LearnerFunction, LearnerNamespace, session_of

SUCCESS = "{name}: passed"

#: What a graded kernel's guard raises where a reference is withheld (kalman_course.core.withheld).
WITHHELD = "ReferenceWithheld"


class CheckFailed(AssertionError):
    """A learner's code gave a wrong answer. The message names the problem and a hint."""

    def _render_traceback_(self) -> list[str]:
        """What IPython shows for a failed check (JupyterLab, nbval): the hint first, then
        what the check saw, and none of the grader's own frames (they are not the learner's
        to read). ``str(exc)``, which gradebooks record, is unchanged."""
        name, _, rest = hints.strip(str(self)).partition(": ")
        if not rest:  # a message without the "<check>: " prefix
            name, rest = "check", str(self)
        saw, _, hint = rest.partition(" Hint: ")
        red, bold, reset = "\x1b[31m", "\x1b[1m", "\x1b[0m"
        lines = [f"{red}{bold}{name}: not passed yet{reset}"]
        if hint:
            lines += [f"{bold}Hint:{reset} {hint}", f"What the check saw: {saw}"]
        else:
            lines.append(saw)
        return lines


#: Prefix of every check function's name; the rest of the name is the check's name.
CHECK_PREFIX = "check_"

# name -> the wrapped check, in registration order (the order of the chapters' imports)
_REGISTRY: dict[str, Callable] = {}


def check(fn: Callable | None = None, *, uses: tuple[str, ...] | dict[str, str] = ()) -> Callable:
    """Decorate ``check_<name>`` as the grader check ``<name>`` and register it.

    The wrapped check prints the constant line ``<name>: passed`` on success and prefixes
    every :class:`CheckFailed` message with ``<name>: ``. Written ``@check``, or
    ``@check(uses=("kf_gain",))`` for a check whose learner function calls other graded
    learner functions.

    Parameters
    ----------
    fn : callable
        The check; its ``__name__`` must be ``check_<name>`` with a non-empty ``<name>``.
    uses : tuple of str, or dict of str to str
        The graded learner functions that the learner's function may call: their names,
        when each is also the name of the check that grades it (``("kf_gain",)``), or a
        mapping from the learner function's name to its check's name
        (``{"kalman_gain": "eskf_gain"}``). When this check fails, each one found in the
        learner's namespace (the ``__globals__`` of the function handed in) is run through
        its own check first; if that fails, the message says to fix it first, instead of
        blaming the function under test for a mistake made upstream.

    Returns
    -------
    callable
        The wrapped check, with attributes ``check_name`` = ``<name>``, ``uses`` and
        ``judge``: the same check without the printed line (it returns on success), which
        the grading tool calls.

    Raises
    ------
    ValueError
        If ``fn``'s name does not start with ``check_``, or a check is already registered
        under ``<name>`` (a second module defining the same check, or a module imported
        twice under two names: either way, ``checks.<name>`` would be ambiguous).
    """
    uses = dict(uses) if isinstance(uses, dict) else {name: name for name in uses}
    if fn is None:
        return functools.partial(check, uses=uses)
    if not callable(fn) or not getattr(fn, "__name__", "").startswith(CHECK_PREFIX) \
            or fn.__name__ == CHECK_PREFIX:
        raise ValueError(f"@check decorates a function named {CHECK_PREFIX}<name>, "
                         f"got {getattr(fn, '__name__', fn)!r}")
    name = fn.__name__[len(CHECK_PREFIX):]

    def judge(*args, **kwargs):
        token, repeated = _MISBEHAVED.set([]), _REPEATED.set(set())
        try:
            fn(*args, **kwargs)
            _raise_first_misbehaviour(_MISBEHAVED.get())
        except CheckFailed as exc:
            upstream = _upstream_of(uses, args[0]) if args else None
            # an argument changed in place or single precision explains a wrong value that follows it
            cause = _misbehaviour_message(_MISBEHAVED.get(), kinds=("changed", "precision"))
            message = upstream or cause or _with_error_hint(_undefined_name(str(exc)))
            raise CheckFailed(_rendered(name, f"{name}: {message}")) from None
        else:
            _LAST_FAILURE.pop(name, None)
        finally:
            _MISBEHAVED.reset(token)
            _REPEATED.reset(repeated)

    @functools.wraps(fn)
    def run(*args, **kwargs):
        judge(*args, **kwargs)
        print(SUCCESS.format(name=name))

    run.check_name = name
    run.uses = dict(uses)
    run.judge = judge  # the verdict alone: returns, or raises CheckFailed; prints nothing
    _register(name, run)
    return run


_NAME_ERROR = re.compile(r"(\w+) raised NameError: name '(\w+)' is not defined")


def _undefined_name(message: str) -> str:
    """A failure caused by a name the learner's code uses and never defined, told as such
    (whatever hint the check would add about shapes or formulas), else ``message``."""
    found = _NAME_ERROR.search(message)
    if found is None:
        return message
    fn, name = found.groups()
    return (f"{fn} uses {name}, which is not defined. Hint: run the cell that defines {name} first; "
            "if that cell raised an error, fix it, then run it again")


#: check name -> the tier-1 text of its last failure in this process (a grader cell run again)
_LAST_FAILURE: dict[str, str] = {}


def _rendered(name: str, marked: str) -> str:
    """The failure message at the tier the learner is at: tier 2 when this check failed the
    same way the last time it ran here and hints escalate (see :mod:`hints`)."""
    first = hints.render(marked, 1)
    again = hints.escalates() and _LAST_FAILURE.get(name) == first
    _LAST_FAILURE[name] = first
    return hints.render(marked, 2) if again or hints.tier() >= 2 else first


def referenced_names(learner_fn) -> set[str]:
    """The global names a learner function's code refers to (empty for a non-function)."""
    if isinstance(learner_fn, LearnerFunction):
        return learner_fn.referenced_names()
    code = getattr(learner_fn, "__code__", None)
    return global_names(code) if isinstance(code, types.CodeType) else set()


def learner_namespace(learner_fn):
    """Where the learner's other functions live: the notebook's globals (a dict in the
    kernel, a :class:`LearnerNamespace` when grading from outside), or None. Both answer
    ``.get(name)``."""
    if isinstance(learner_fn, LearnerFunction):
        return LearnerNamespace(learner_fn.session)
    namespace = getattr(learner_fn, "__globals__", None)
    return namespace if isinstance(namespace, dict) else None


def _upstream_of(uses: dict[str, str], learner_fn) -> str | None:
    """:func:`upstream_failure` for the used functions that ``learner_fn``'s code refers to
    (a learner's ``nis`` that does not call ``nees`` is not blamed on a ``nees`` stub)."""
    if not uses:
        return None
    refers = referenced_names(learner_fn)
    return upstream_failure({name: check_name for name, check_name in uses.items() if name in refers},
                            learner_namespace(learner_fn))


_UPSTREAM = re.compile(r"^this function calls your (\w+), which (.*)$", re.S)


def upstream_failure(uses: dict[str, str], namespace) -> str | None:
    """The message for the first used learner function that fails its own check, or None.

    Parameters
    ----------
    uses : dict of str to str
        Learner function name -> the name of the check that grades it.
    namespace : dict, LearnerNamespace or None
        Where the learner's functions live (:func:`learner_namespace` of the function under
        test), so the check sees exactly the ``kf_gain`` that the learner's ``kf_update``
        calls. None means there is nothing to ask.
    """
    if not uses or namespace is None:
        return None
    for dependency, check_name in uses.items():
        learner_fn = namespace.get(dependency)
        dependency_check = _REGISTRY.get(check_name)
        if not callable(learner_fn) or dependency_check is None:
            continue
        try:
            dependency_check.judge(learner_fn)
        except CheckFailed as exc:
            # what the other check saw, without its name and hint (its own grader cell gives those)
            text = hints.strip(str(exc)).split("\n")[0].removeprefix(f"{check_name}: ")
            chained = _UPSTREAM.match(text)
            if chained:  # the dependency's own failure is upstream of it: name the root
                return f"this function calls your {dependency}, which calls your {chained[1]}, which {chained[2]}"
            saw = text.split(" Hint: ")[0].rstrip(".")
            return (f"this function calls your {dependency}, which does not pass its own check yet: "
                    f"{saw}. Hint: fix {dependency} first; its grader cell's hint says how")
    return None


def _register(name: str, wrapped: Callable) -> None:
    """Add ``wrapped`` to the registry; a second check of the same name is an error."""
    previous = _REGISTRY.get(name)
    if previous is not None:
        raise ValueError(f"check name {name!r} is registered twice: by "
                         f"{previous.__module__}.{previous.__qualname__} and "
                         f"{wrapped.__module__}.{wrapped.__qualname__}")
    _REGISTRY[name] = wrapped


def registered() -> dict[str, Callable]:
    """Every registered check, ``{name: check}``, in registration order (a copy)."""
    return dict(_REGISTRY)


def call(fn: Callable, *args, label: str | None = None):
    """Call learner code with copies of ``args``, its prints and warnings silenced.

    An exception inside the learner's code becomes a ``CheckFailed`` naming the function
    and the exception, so the grader cell shows the learner's bug, not the harness.

    When ``fn`` or an argument is a :class:`LearnerFunction` (grading from outside the
    learner's kernel), the call runs in the learner's kernel: ``fn`` is the learner's
    function, or a function of this package driving learner functions handed to it (a
    whole filter built from the learner's steps); only plain data crosses.
    """
    label = label or getattr(fn, "__name__", "your function")
    repeat = _first_call(fn)
    session = session_of(fn, args)
    if session is not None:
        answer = session.call(fn, args, repeat=repeat)
        if "not_callable" in answer:
            raise CheckFailed(f"expected a function, got {answer['not_callable']}")
        if "raised" in answer:
            raised = answer["raised"]
            if raised.type_name == WITHHELD:
                raise CheckFailed(f"{label} calls a reference implementation of the course. Hint: the "
                                  f"reference is not available while grading ({raised.message}); write the "
                                  "computation yourself")
            raise CheckFailed(f"{label} raised {raised.type_name}: {raised.message}")
        behaviour = answer.get("behaviour")
        _note_misbehaviour(label, behaviour if isinstance(behaviour, list) else [])
        return answer["result"]
    if not callable(fn):
        raise CheckFailed(f"expected a function, got {type(fn).__name__}")
    try:
        result, behaviour = call_watched(fn, args, repeat=repeat)
    except CheckFailed:
        raise
    except Exception as exc:  # the learner's code may raise anything
        raise CheckFailed(f"{label} raised {type(exc).__name__}: {exc}") from None
    _note_misbehaviour(label, behaviour)
    return result


#: The functions the running check has called so far: only a function's first call in a
#: check is repeated to see that it gives the same answer (a whole filter run would otherwise
#: cost twice its time, and state kept between calls shows on the first repeat).
_REPEATED: contextvars.ContextVar[set | None] = contextvars.ContextVar("repeated", default=None)


def _first_call(fn) -> bool:
    """Whether this is the running check's first call of ``fn`` (always, outside a check)."""
    called = _REPEATED.get()
    if called is None:
        return True
    try:
        first = fn not in called
        called.add(fn)
    except TypeError:  # not hashable: not a function, and the call will say so
        return True
    return first


#: The properties of well-behaved code that the learner's calls broke during the running check:
#: (function label, kind, detail). Judged after the check's values (a wrong value's hint names
#: the mistake better), so a check fails on them only when every value was right.
_MISBEHAVED: contextvars.ContextVar[list | None] = contextvars.ContextVar("misbehaved", default=None)


def _note_misbehaviour(label: str, behaviour: list) -> None:
    noted = _MISBEHAVED.get()
    for item in behaviour:
        if isinstance(item, list) and len(item) in (2, 3) and all(isinstance(x, str) for x in item):
            # [kind, detail] of the call itself, [kind, detail, name] of a learner function it drove
            who = item[2] if len(item) == 3 else label
            if noted is None:  # a call outside a check (a test, a notebook helper): fail at once
                _raise_first_misbehaviour([(who, *item[:2])])
            noted.append((who, *item[:2]))


#: What each broken property is told as, most telling first ({who}: the function, {detail}: what).
_MISBEHAVIOUR = {
    "changed": "{who} changed its argument {detail} in place. Hint: work on a copy (P = P + Q, not P += Q; "
               "or {detail} = {detail}.copy() first): the caller's arrays must be as they were after the call",
    "precision": "{who} computes in single precision: {detail}. Hint: keep NumPy's default float64; float32 "
                 "keeps about 7 digits, and a filter's covariance loses more than that in a few steps",
    "aliased": "{who} returns its argument {detail} itself, or a view of it. Hint: return a new array "
               "({detail}.copy()): a caller who changes the result would change their own input",
    "unrepeatable": "{who} gave different results for the same inputs. Hint: it depends on something "
                    "besides its arguments: unseeded randomness, a global it changes, or a default "
                    "argument it modifies",
}


def _misbehaviour_message(noted, kinds=tuple(_MISBEHAVIOUR)) -> str | None:
    """The message for the most telling broken property among ``noted`` of ``kinds``, or None."""
    for kind in kinds:
        for who, noted_kind, detail in noted or ():
            if noted_kind == kind:
                return _MISBEHAVIOUR[kind].format(who=who, detail=detail)
    return None


def _raise_first_misbehaviour(noted: list) -> None:
    """Fail on the most telling property of well-behaved code that a call broke (see
    :func:`kernel_agent.call_watched`): the caller's arguments left as they were, float64
    precision, results that are new arrays, the same answer to the same question."""
    message = _misbehaviour_message(noted)
    if message:
        raise CheckFailed(message)


#: A hint for an exception the learner's code raised, by what its message says, where the
#: check gave none (first match wins).
_ERROR_HINTS = (
    (re.compile(r"raised (ValueError|LinAlgError): .*(broadcast|shape|align|dimension|matmul|size)", re.S | re.I),
     "two arrays' shapes do not fit together: check which rows and columns each slice or block takes, "
     "each matrix's orientation (a transpose?), and the order of the arguments you pass"),
    (re.compile(r"raised IndexError: "),
     "an index is past the end of an array: check the state's layout (which entries are which) in the "
     "lecture, and that slices start and stop where the blocks do"),
    (re.compile(r"raised LinAlgError: .*singular", re.I),
     "a matrix your code inverts is singular: check that it is the one the lecture inverts (with its "
     "noise term) and that no block of it was left at zero"),
    (re.compile(r"raised TypeError: .*(argument|positional|unexpected keyword)", re.I),
     "a function was called with the wrong arguments: check each call against its signature, in order"),
    (re.compile(r"raised TypeError: "),
     "a value has the wrong type for what is done to it: check the types of the arguments and results"),
    (re.compile(r"raised (ZeroDivisionError|FloatingPointError): "),
     "a division by zero: check the denominator, and whether the case needs its own limit"),
    (re.compile(r"raised (\w+): "),
     "the error is in your code: its message says what went wrong; the traceback, when you run the "
     "function yourself on the check's inputs, says where"),
)


def _with_error_hint(message: str) -> str:
    """``message``, with a hint added when it reports an exception of the learner's code and
    the check gave no hint."""
    if " Hint: " in message:
        return message
    for pattern, hint in _ERROR_HINTS:
        if pattern.search(message):
            return f"{message}. Hint: {hint}"
    return message


def type_name(value) -> str:
    """The name of a learner result's type (also of one that could not cross as plain data)."""
    return value.type_name if isinstance(value, Opaque) else type(value).__name__


def as_array(value, what: str) -> np.ndarray:
    """Convert a learner's result to a float array or fail saying what came back."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise CheckFailed(f"{what} should be a numeric array, got {type_name(value)}") from None
    return arr


def expect_shape(value, shape: tuple, what: str) -> np.ndarray:
    """Fail unless ``value`` is an array of exactly ``shape``."""
    arr = as_array(value, what)
    if arr.shape != tuple(shape):
        hint = ""
        if arr.size == int(np.prod(shape)) and arr.ndim != len(shape):
            hint = " (a column vector where a 1-D vector was expected? use shape (n,))"
        raise CheckFailed(f"{what} has shape {arr.shape}, expected {tuple(shape)}{hint}")
    if not np.all(np.isfinite(arr)):
        raise CheckFailed(f"{what} contains NaN or inf")
    return arr


def expect_close(value, expected, what: str, *, rtol: float = 1e-7, atol: float = 1e-9,
                 mistakes: Iterable[tuple[object, str]] = (), hint: str = "") -> np.ndarray:
    """Fail unless ``value`` matches ``expected``.

    Parameters
    ----------
    value, expected : array_like
        The learner's result and the reference.
    what : str
        Name of the quantity, used in the message.
    mistakes : iterable of (array_like, str)
        Results of known wrong formulas with the hint to give when the learner's value
        matches one of them.
    hint : str
        The hint given when no known mistake matches.
    """
    expected = np.asarray(expected, dtype=float)
    arr = expect_shape(value, expected.shape, what)
    if np.allclose(arr, expected, rtol=rtol, atol=atol):
        return arr
    for wrong, why in mistakes:
        wrong = np.asarray(wrong, dtype=float)
        if wrong.shape == arr.shape and np.allclose(arr, wrong, rtol=rtol, atol=atol):
            raise CheckFailed(f"{what} is wrong. Hint: {why}")
    err = np.max(np.abs(arr - expected))
    raise CheckFailed(f"{what} differs from the reference (max abs error {err:.3g})."
                      + (f" Hint: {hint}" if hint else ""))


def expect_symmetric(value, what: str) -> np.ndarray:
    """Fail unless ``value`` is a symmetric matrix (to round-off)."""
    arr = as_array(value, what)
    if arr.ndim != 2 or arr.shape[0] != arr.shape[1]:
        raise CheckFailed(f"{what} should be a square matrix, got shape {arr.shape}")
    scale = max(np.max(np.abs(arr)), 1e-300)
    if np.max(np.abs(arr - arr.T)) > 1e-9 * scale:
        raise CheckFailed(f"{what} is not symmetric. Hint: a covariance is always symmetric; "
                          "check the order of the products (A @ P @ A.T, not A @ P @ A)")
    return arr


def with_symmetrised(mistakes):
    """Each known wrong value, then its symmetrised form with the same hint (a learner's last
    line often symmetrises whatever the formula gave), as a list."""
    out = []
    for wrong, why in mistakes:
        wrong = np.asarray(wrong, dtype=float)
        out.append((wrong, why))
        if wrong.ndim == 2 and wrong.shape[0] == wrong.shape[1]:
            out.append((linalg.symmetrise(wrong), why))
    return out


def known_mistake(got, cases, mistakes, close, *, evaluate=None, case: int | None = None) -> str | None:
    """Which known mistake explains a learner's results over a check's cases, or None.

    The one place every check asks "which plausible wrong formula gives exactly what the
    learner's code gave?".

    Parameters
    ----------
    got : sequence
        The learner's result on each case.
    cases : sequence
        The check's cases, as the mistakes' formulas take them.
    mistakes : iterable of (callable, str)
        ``(formula, hint)``: ``evaluate(formula, case)`` is the wrong result on a case.
    close : callable
        ``close(learner_result, wrong_result, k)``: whether they agree on case ``k``. A wrong
        result that could not be evaluated is passed as None.
    evaluate : callable, optional
        How a formula is applied to a case (default ``formula(case)``); an exception counts
        as "could not be evaluated".
    case : int, optional
        When no mistake explains every case: the hint of the first that agrees on this case
        alone (the first case the learner got wrong), else None.

    Returns
    -------
    str or None
        The hint of the first mistake that reproduces the learner's result on every case.
    """
    evaluate = evaluate or (lambda formula, c: formula(c))

    def wrong_on(formula, c):
        try:
            return evaluate(formula, c)
        except Exception:  # a wrong formula may not apply to a case (a shape, a singular matrix)
            return None

    tried = []
    for formula, why in mistakes:
        wrong = [wrong_on(formula, c) for c in cases]
        if all(close(g, w, k) for k, (g, w) in enumerate(zip(got, wrong))):
            return why
        tried.append((why, wrong))
    if case is not None:
        return next((why for why, wrong in tried if close(got[case], wrong[case], case)), None)
    return None

