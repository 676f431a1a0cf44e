"""One learner notebook's own Jupyter kernel, driven by the grading process.

The kernel runs the learner's cells one by one, as JupyterLab would, and answers the
checks' calls of learner functions (:class:`kalman_course.checks.remote.Session`): each
call is a comm message of plain data that the kernel's agent answers with another.
A cell that runs past its time is interrupted; a kernel that dies is noticed within
:data:`POLL` seconds.
"""

from __future__ import annotations

import os
import queue
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import uuid
from dataclasses import dataclass

import zmq
from zmq.utils.monitor import recv_monitor_message
from jupyter_client.kernelspec import KernelSpec, KernelSpecManager
from jupyter_client.manager import KernelManager

from kalman_course.checks.kernel_agent import COMM_TARGET, MAX_ANSWER
from kalman_course.checks.plain_data import Raised, encode
from kalman_course.checks.remote import KernelLost, Session

#: Seconds between two looks at whether the kernel is still alive while waiting for it.
POLL = 0.25
#: Seconds an interrupted cell gets to stop before the kernel is given up.
INTERRUPT_GRACE = 5.0
#: What a channel reader's judge returns while the message it waits for has not come.
_PENDING = object()
#: What a channel reader gets for a message ZeroMQ cut off (over the bound) or that cannot be read.
_CUT_OFF = object()
#: Statuses a lost kernel reports (the same words as the gradebook's).
TIMED_OUT, KERNEL_DIED = "timed out", "kernel died"
#: Messages the grading process's sockets hold from a kernel before ZeroMQ drops more: with
#: :data:`MAX_MESSAGE`, what a flooding kernel can make this process hold.
QUEUED_MESSAGES = 16

#: Run once in a fresh kernel, before the learner's cells: the agent starts listening.
_AGENT_LISTEN = "__import__('kalman_course.checks.kernel_agent', fromlist=['listen']).listen(get_ipython(), globals())"


#: The kernel's command: the Python that runs the grader (the environment the course is installed in).
_KERNEL_ARGV = [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}",
                "--log-level=ERROR",  # no start-up notices on the grader's stderr
                "--HistoryManager.enabled=False"]  # no history database shared between learners' kernels

#: The largest message the grading process accepts from a kernel, in bytes: larger ones are
#: refused by ZeroMQ as they arrive (the peer is cut off), before they take any memory here.
#: An honest kernel's agent refuses a larger answer itself, with a message.
MAX_MESSAGE = MAX_ANSWER + 4 * 2**20


class _Spec(KernelSpecManager):
    """One kernel command (plain, or inside the sandbox) and how to interrupt it."""

    def __init__(self, argv: list[str], interrupt_mode: str):
        super().__init__()
        self._argv, self._interrupt_mode = argv, interrupt_mode

    def get_kernel_spec(self, kernel_name):
        return KernelSpec(argv=self._argv, display_name="Python 3", language="python", name=kernel_name,
                          interrupt_mode=self._interrupt_mode)


#: The sessions of this process whose kernel may still run (see :func:`close_every_session`).
_LIVE: set = set()


def close_every_session() -> None:
    """End every kernel this process started (a worker told to stop, Ctrl-C)."""
    for session in list(_LIVE):
        session.close()


@dataclass
class CellOutcome:
    """What running one cell gave: ``status`` is "ok", "error" or TIMED_OUT."""

    status: str
    error: str = ""      # "Name: message" of the exception, if any
    stdout: str = ""     # only when asked for


class KernelSession(Session):
    """A fresh kernel for one notebook.

    The kernel starts at once, in a new temporary folder of its own (its working folder,
    removed by :meth:`close`); :meth:`wait_until_ready` waits for it.

    Parameters
    ----------
    timeout : float
        Seconds each cell (and each check, over all its calls) may take.
    sandbox : kalman_course.tooling.sandbox.Sandbox, optional
        Where the kernel runs (None: as a plain process).
    package : str, optional
        A build of the package the kernel imports instead of the package itself
        (:func:`kalman_course.tooling.withheld.build_guarded`).
    """

    def __init__(self, timeout: float, sandbox=None, package: str | None = None):
        super().__init__()
        self.timeout = float(timeout)
        self.deadline = None  # set by the grader for the check that is running
        self.timed_out = ""  # what ran out of time and was interrupted ("a cell", "a learner function")
        self.folder = tempfile.mkdtemp(prefix="kalman-grade-")
        self._comm_id = None
        channels = os.path.join(self.folder, "channels")
        self.files = os.path.join(self.folder, "files")  # what the kernel sees of the notebook (read-only)
        os.mkdir(channels)
        os.mkdir(self.files)
        env = dict(os.environ)
        env.pop("KALMAN_COURSE_GRADEBOOK_KEY", None)  # the instructor's signing key is not the learner's
        env["MPLBACKEND"] = "Agg"  # plots are not graded: draw them nowhere (no PNG rendering)
        env["PYDEVD_DISABLE_FILE_VALIDATION"] = "1"  # no debugger warning on stderr
        env["IPYTHONDIR"] = os.path.join(self.folder, ".ipython")  # a profile of its own: no shared start-up files
        argv, interrupt_mode = _KERNEL_ARGV, "signal"
        self.package = package
        if package is not None:  # first on the path: before the installed package
            env["PYTHONPATH"] = os.pathsep.join(filter(None, [os.path.dirname(package), env.get("PYTHONPATH")]))
        self._sandboxed = None
        if sandbox is not None:
            self._sandboxed = sandbox.prepare(_KERNEL_ARGV, channels=channels, files={"notebooks": self.files},
                                              env={"MPLBACKEND": "Agg", "PYDEVD_DISABLE_FILE_VALIDATION": "1"},
                                              package=package)
            argv = self._sandboxed.argv
            interrupt_mode = "message"  # a signal would reach bubblewrap, not the kernel inside
            env = {"PATH": os.environ.get("PATH", "/usr/bin:/bin")}  # bubblewrap sets the kernel's own
        # ipc: Unix sockets in the kernel's own folder (a TCP port would be the sandbox's own loopback)
        self.km = KernelManager(kernel_spec_manager=_Spec(argv, interrupt_mode), kernel_name="python3",
                                transport="ipc", ip=os.path.join(channels, "kernel"))
        self.km.connection_file = os.path.join(channels, "kernel.json")
        self.km.write_connection_file()
        os.chmod(self.km.connection_file, 0o644)  # the kernel may run as a user of its own
        self.kc = None
        _LIVE.add(self)
        # its own log (a KeyboardInterrupt after a timeout, ...) is not the grader's output
        self.km.start_kernel(cwd=self.folder if sandbox is None else None, env=env,
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)

    def show_notebooks(self, notebooks: dict[str, str]) -> None:
        """Put read-only copies of ``notebooks`` (file name → JSON text) where the kernel
        sees them (``~/notebooks`` in the sandbox, ``files/`` of its folder without one)."""
        for name, text in notebooks.items():
            # a learner's file name, made a plain name in this folder
            path = os.path.join(self.files, re.sub(r"[^\w.-]", "_", os.path.basename(name)).lstrip(".") or "_")
            with open(path, "w", encoding="utf-8") as fh:
                fh.write(text)
            os.chmod(path, 0o444)

    def _connect(self) -> None:
        if self.kc is None:
            context = zmq.Context()
            context.setsockopt(zmq.MAXMSGSIZE, MAX_MESSAGE)  # every socket of this client: bounded
            context.setsockopt(zmq.RCVHWM, QUEUED_MESSAGES)
            self.kc = self.km.client(context=context)
            self.kc.start_channels()
            # ZeroMQ cuts off a kernel whose message is over the bound: said on this monitor
            self._cut_offs = self.kc.iopub_channel.socket.get_monitor_socket(zmq.EVENT_DISCONNECTED)

    def wait_until_ready(self, timeout: float = 60.0) -> None:
        """Block until the kernel answers and its agent listens (start it first; overlap other
        work with this)."""
        self._connect()
        try:
            self.kc.wait_for_ready(timeout=timeout)
        except RuntimeError as exc:
            raise KernelLost(KERNEL_DIED, f"the kernel did not start ({exc})") from None
        if self._sandboxed is not None:
            self._sandboxed.started()
        outcome = self.run_cell(_AGENT_LISTEN, silent=True, timeout=timeout)
        if outcome.status != "ok":
            raise KernelLost(KERNEL_DIED, f"the grading agent did not start in the kernel ({outcome.error})")
        self._comm_id = uuid.uuid4().hex
        self.kc.shell_channel.send(self.kc.session.msg(
            "comm_open", content={"comm_id": self._comm_id, "target_name": COMM_TARGET, "data": {}}))

    def close(self) -> None:
        """Stop the kernel and remove the request files (again: nothing)."""
        if self not in _LIVE:
            return
        _LIVE.discard(self)
        if self.kc is not None:
            self.kc.stop_channels()
        process = getattr(getattr(self.km, "provisioner", None), "process", None)
        try:
            if process is not None and os.name == "posix":
                # SIGKILL to the kernel's process group (what it started too), then reap it: the
                # same end as shutdown_kernel(now=True) without its 0.1 s polling
                group = os.getpgid(process.pid)
                if group != os.getpgid(0):
                    os.killpg(group, signal.SIGKILL)
                else:
                    process.kill()
                process.wait(timeout=10)
                self.km.cleanup_resources()
            else:
                self.km.shutdown_kernel(now=True)
        except (OSError, subprocess.TimeoutExpired):  # already gone
            pass
        if self.kc is not None:
            self._cut_offs.close(linger=0)
            self.kc.context.destroy(linger=0)
        if self._sandboxed is not None:
            self._sandboxed.remove()
        shutil.rmtree(self.folder, ignore_errors=True)

    # -- cells -------------------------------------------------------------------------

    def run_cell(self, source: str, *, capture: bool = False, silent: bool = False,
                 timeout: float | None = None) -> CellOutcome:
        """Run ``source`` in the kernel and wait for it (``capture``: also collect stdout)."""
        msg_id = self.kc.execute(source, silent=silent, store_history=not silent, allow_stdin=False,
                                 stop_on_error=False)
        reply = self._reply(msg_id, self.timeout if timeout is None else timeout, keep_output=capture)
        stdout = self._stdout(msg_id) if capture else ""
        self._drain()
        if reply is None:
            return CellOutcome(TIMED_OUT, "the cell ran out of time", stdout)
        content = reply["content"]
        if content.get("status") == "ok":
            return CellOutcome("ok", "", stdout)
        return CellOutcome("error", f"{content.get('ename', 'Error')}: {content.get('evalue', '')}", stdout)

    def _reply(self, msg_id: str, timeout: float, keep_output: bool = False):
        """The execute reply to ``msg_id``, or None after interrupting a cell that ran out of time
        (``keep_output``: leave what the cell publishes to be read; else it is dropped as it comes)."""
        def judge(msg, interrupted):
            if msg is _CUT_OFF or msg["parent_header"].get("msg_id") != msg_id:
                return _PENDING
            return None if interrupted else msg

        def get_msg(timeout):
            if not keep_output:
                self._discard_published()
            return self.kc.get_shell_msg(timeout=min(timeout, 0.05 if not keep_output else timeout))
        return self._wait(get_msg, judge, timeout, "a cell")

    def _discard_published(self) -> None:
        """Drop what the kernel has published so far, unread (a flood of outputs costs nothing)."""
        socket = self.kc.iopub_channel.socket
        while socket.poll(0):
            socket.recv_multipart(copy=False)

    def _wait(self, get_msg, judge, timeout: float, what: str):
        """Read a channel until ``judge(msg, interrupted)`` gives something else than _PENDING.

        A dead kernel is noticed within :data:`POLL` seconds; past ``timeout`` the kernel is
        interrupted once, and given up :data:`INTERRUPT_GRACE` seconds later.
        """
        end = time.monotonic() + timeout
        interrupted = False
        alive_checked = time.monotonic()
        while True:
            now = time.monotonic()
            # the deadline and the kernel's life are looked at however busy the channel is
            if now > end:
                if interrupted:
                    raise KernelLost(TIMED_OUT, f"{what} ran longer than {timeout:g} s and did not stop")
                self.km.interrupt_kernel()
                self.timed_out, interrupted = what, True
                end = time.monotonic() + INTERRUPT_GRACE
            if now - alive_checked > POLL:
                alive_checked = now
                if not self.km.is_alive():
                    raise KernelLost(KERNEL_DIED, "the kernel died (os._exit, a crash, or out of memory)")
            try:
                msg = get_msg(timeout=min(POLL, max(end - now, 0.01)))
            except queue.Empty:
                if not self.km.is_alive():
                    raise KernelLost(KERNEL_DIED, "the kernel died (os._exit, a crash, or out of memory)")
                continue
            except ValueError:  # not signed with the session's key, or a part over the bound cut off
                msg = _CUT_OFF
            outcome = judge(msg, interrupted)
            if outcome is not _PENDING:
                return outcome

    def _stdout(self, msg_id: str) -> str:
        """Everything the cell ``msg_id`` printed to stdout (read until the kernel is idle)."""
        text = []
        end = time.monotonic() + 10.0
        while time.monotonic() < end:
            try:
                msg = self.kc.get_iopub_msg(timeout=POLL)
            except (queue.Empty, ValueError):  # ValueError: a message that cannot be read is no output
                continue
            if msg["parent_header"].get("msg_id") != msg_id:
                continue
            if msg["msg_type"] == "stream" and msg["content"].get("name") == "stdout":
                text.append(msg["content"]["text"])
            if msg["msg_type"] == "status" and msg["content"].get("execution_state") == "idle":
                break
        return "".join(text)

    def _drain(self) -> None:
        """Drop the published messages nobody asked for (outputs, status), unread."""
        self._discard_published()

    # -- the checks' calls -------------------------------------------------------------

    def exchange(self, request: str) -> str:
        while self._cut_offs.poll(0):  # a cut-off during a cell is not this call's
            recv_monitor_message(self._cut_offs)
        msg = self.kc.session.msg("comm_msg", content={"comm_id": self._comm_id, "data": {"request": request}})
        self.kc.shell_channel.send(msg)
        left = self.timeout if self.deadline is None else max(self.deadline - time.monotonic(), 0.5)
        reply = self._comm_reply(msg["header"]["msg_id"], left)
        if reply is None:
            why = f"your function ran longer than the {self.timeout:g} s a check may take"
            return encode({"raised": Raised("TimeoutError", why)}, towards_kernel=False)
        if reply.get("cut_off"):
            why = (f"your function's answer was cut off: the grader receives no message over "
                   f"{MAX_MESSAGE // 2**20} MiB, nor one it cannot read (does it return what the exercise asks for?)")
            return encode({"raised": Raised("ValueError", why)}, towards_kernel=False)
        answer = reply.get("answer") if isinstance(reply, dict) else None
        if not isinstance(answer, str):
            why = ("the notebook did not answer the grader (an answer over "
                   f"{MAX_MESSAGE // 2**20} MiB, or its kernel's comms were changed)")
            return encode({"raised": Raised("RuntimeError", why)}, towards_kernel=False)
        return answer  # Session._ask bounds its size and decodes it

    def _comm_reply(self, msg_id: str, timeout: float):
        """The data of the agent's reply to ``msg_id``; {} if the kernel went idle without one;
        None after interrupting a call that ran out of time."""
        def judge(msg, interrupted):
            if msg is _CUT_OFF:
                return {"cut_off": True}
            if msg["parent_header"].get("msg_id") != msg_id:
                return _PENDING
            if msg["msg_type"] == "comm_msg" and not interrupted:
                return msg["content"].get("data", {})
            if msg["msg_type"] == "status" and msg["content"].get("execution_state") == "idle":
                return None if interrupted else {}
            return _PENDING

        def get_msg(timeout):
            if self._cut_offs.poll(0):
                recv_monitor_message(self._cut_offs)
                return _CUT_OFF
            return self.kc.get_iopub_msg(timeout=min(timeout, 0.05))
        return self._wait(get_msg, judge, timeout, "a learner function")
