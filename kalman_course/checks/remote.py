"""Learner functions that live in another process: what a check holds when it grades out of
the learner's kernel.

In a grader cell, ``checks.kf_update(kf_update)`` hands the check the learner's function
itself. When ``kalman-course grade`` grades, the check runs in the grading process instead
and is handed a :class:`LearnerFunction`: calling it sends the arguments to the learner's
kernel as plain data (:mod:`plain_data`), runs the learner's function there
(:mod:`kernel_agent`) and decodes its result. The reference values and the comparisons
stay in the grading process, so nothing the learner's cells do to their kernel can reach
them.

A :class:`Session` is the link to one kernel; the grading tool provides one that talks to
a Jupyter kernel, and :class:`LocalSession` runs the agent in this process (for tests of the
protocol itself).
"""

from __future__ import annotations

from kalman_course.checks import kernel_agent, plain_data


class KernelLost(BaseException):
    """The learner's kernel died or did not answer in time: the notebook cannot be graded on.

    A ``BaseException``, so that no check's ``except Exception`` mistakes it for a wrong
    answer of the learner's code.
    """

    def __init__(self, status: str, detail: str):
        super().__init__(detail)
        self.status, self.detail = status, detail


class LearnerRaised(Exception):
    """The learner's function raised; ``type_name`` and ``message`` are what it raised."""

    def __init__(self, type_name: str, message: str):
        super().__init__(f"{type_name}: {message}")
        self.type_name, self.message = type_name, message


class Session:
    """The link to one learner kernel. Subclasses implement :meth:`exchange`."""

    #: Largest answer accepted from the kernel, in characters.
    MAX_ANSWER = kernel_agent.MAX_ANSWER

    def __init__(self):
        self._memo: dict = {}  # dataclass instances sent whole, by id (see plain_data.encode)

    def exchange(self, request: str) -> str:
        """Send one request to the kernel's agent and return its answer (JSON text)."""
        raise NotImplementedError

    def _ask(self, request: dict) -> dict:
        text = plain_data.encode(request, towards_kernel=True, convert=_as_learner_name, memo=self._memo)
        answer = self.exchange(text)
        if len(answer) > self.MAX_ANSWER:
            return {"result": plain_data.Opaque(f"answer of {len(answer)} characters")}
        try:
            decoded = plain_data.decode(answer, from_kernel=True)
        except plain_data.NotPlainData as exc:
            return {"raised": plain_data.Raised("NotPlainData", f"the kernel's answer was not plain data: {exc}")}
        if type(decoded) is not dict or not decoded.keys() & {"result", "raised", "not_callable", "defined"}:
            return {"raised": plain_data.Raised("NotPlainData", "the kernel's answer was malformed")}
        return decoded

    def call(self, callee, args: tuple, repeat: bool = True) -> dict:
        """Run ``callee(*args)`` in the kernel: ``{"result": value}``, ``{"raised": Raised}``
        or ``{"not_callable": type name}``. Without ``repeat`` the kernel does not call it a
        second time to see that the answer is the same."""
        request = {"op": "call", "callee": callee, "args": tuple(args)}
        if not repeat:
            request["repeat"] = False
        return self._ask(request)

    def withheld_calls(self) -> list[tuple[str, int, str, str]]:
        """(file of the calling code, line, function, the exercise function it stands for) of
        each call of a reference withheld while grading (:mod:`kalman_course.core.withheld`),
        as far as the kernel says."""
        answer = self._ask({"op": "withheld"})
        calls = answer.get("result")
        if not isinstance(calls, list):
            return []
        return [tuple(c) for c in calls if isinstance(c, list) and len(c) == 4 and type(c[1]) is int
                and all(isinstance(c[k], str) for k in (0, 2, 3))]

    def describe(self, name: str) -> dict:
        """``{"defined", "callable", "type", "globals"}`` of a name in the learner's notebook."""
        answer = self._ask({"op": "describe", "name": name})
        return answer if "defined" in answer else {"defined": False, "callable": False, "type": "?",
                                                   "globals": None}


def _as_learner_name(value):
    if isinstance(value, LearnerFunction):
        return plain_data.LearnerName(value.name)
    raise plain_data.NotPlainData(f"a {type(value).__name__} cannot be sent to the learner's kernel")


class LearnerFunction:
    """A function of the learner's notebook, called through a :class:`Session`."""

    def __init__(self, session: Session, name: str):
        self.session, self.name = session, name
        self.__name__ = name

    def __repr__(self) -> str:
        return f"<the learner's {self.name}>"

    def __call__(self, *args):
        answer = self.session.call(self, args)
        if "not_callable" in answer:
            raise LearnerRaised("TypeError", f"'{answer['not_callable']}' object is not callable")
        if "raised" in answer:
            raise LearnerRaised(answer["raised"].type_name, answer["raised"].message)
        return answer["result"]

    def referenced_names(self) -> set[str]:
        """The global names the function's code refers to (empty if it has no code)."""
        return set(self.session.describe(self.name).get("globals") or ())


class LearnerNamespace:
    """The learner notebook's globals, as far as a check asks for them: ``get(name)`` is a
    :class:`LearnerFunction` when ``name`` is a callable there, else ``default``."""

    def __init__(self, session: Session):
        self.session = session

    def get(self, name: str, default=None):
        described = self.session.describe(name)
        return LearnerFunction(self.session, name) if described.get("callable") else default


def session_of(*values) -> Session | None:
    """The session of the first :class:`LearnerFunction` among ``values`` (searched through
    tuples, lists, dict values and partial applications), or None: a call that involves
    one runs in the learner's kernel."""
    stack = list(values)
    while stack:
        value = stack.pop()
        if isinstance(value, LearnerFunction):
            return value.session
        if isinstance(value, (tuple, list)):
            stack.extend(value)
        elif isinstance(value, dict):
            stack.extend(value.values())
        elif hasattr(value, "func") and hasattr(value, "args") and hasattr(value, "keywords"):
            stack.extend((value.func, *value.args, *value.keywords.values()))
    return None


class LocalSession(Session):
    """A session whose "kernel" is a namespace in this process (tests of the protocol)."""

    def __init__(self, namespace: dict):
        super().__init__()
        self.namespace, self.handles = namespace, {}

    def exchange(self, request: str) -> str:
        return kernel_agent.answer(self.namespace, request, self.handles)
