"""The grading process, sealed before the first learner kernel starts.

A learner's kernel that is not sandboxed (``--no-sandbox``, or a learner grading their
own notebook without bubblewrap) runs with the grader's permissions. This module keeps
what it can write from reaching the grading process or the gradebook:

- :func:`preload` imports every module grading can need before any kernel starts, so
  that no Python file (or a ``.pyc`` forged beside it) is read afterwards;
- :func:`seal_argv` is the command line the ``grade`` command re-runs itself with:
  ``-I`` (no user site, no ``PYTHON*`` variables, no current folder on the path), ``-B``
  (no bytecode written) and a fresh ``pycache_prefix`` (no ``.pyc`` of anyone's read:
  every module is compiled from its source);
- :class:`Fingerprint` records digests of the package's files and of every ``.pth`` file
  Python runs at start-up; :meth:`Fingerprint.changes` lists what changed during the run,
  and no gradebook is written when anything did;
- :class:`OrphanReaper` makes this process the "subreaper" of everything it starts, so
  that a process a kernel starts in a session of its own (which survives the kernel's
  process group) is adopted here and ended before any gradebook is written.
"""

from __future__ import annotations

import ctypes
import glob
import hashlib
import importlib
import os
import pkgutil
import signal
import site
import sys
import tempfile
import time
from pathlib import Path

#: The ``kalman_course`` package folder.
PACKAGE = Path(__file__).resolve().parents[1]

#: Modules of the course that grading never runs (and that import what grading does not need).
_NOT_FOR_GRADING = ("kalman_course.data.build", "kalman_course.tooling.bench", "kalman_course.tooling.export")

#: Standard-library and third-party modules that grading imports lazily, inside functions.
_LAZY = ("csv", "hmac", "concurrent.futures", "multiprocessing.connection", "multiprocessing.util",
         "jupyter_client.manager", "jupyter_client.blocking.client", "jupyter_client.provisioning.local_provisioner",
         "jupyter_client.launcher", "jupyter_client.channels", "jupyter_client.session", "zmq")


def preload() -> list[str]:
    """Import every module grading can need; return their names (for the tests)."""
    names = []
    for info in pkgutil.walk_packages([str(PACKAGE)], "kalman_course."):
        if not info.name.startswith(_NOT_FOR_GRADING):
            importlib.import_module(info.name)
            names.append(info.name)
    for name in _LAZY:
        importlib.import_module(name)
    from kalman_course.checks import registered

    registered()  # the checks' own set-up (SymPy models, the excerpts)
    from jupyter_client.provisioning.factory import KernelProvisionerFactory

    # jupyter_client finds its provisioners through entry points: resolve them now
    KernelProvisionerFactory.instance().get_provisioner_entries()
    return names


def is_sealed() -> bool:
    """Whether this interpreter runs as :func:`seal_argv` starts it."""
    return bool(sys.flags.isolated and sys.flags.dont_write_bytecode and sys.pycache_prefix)


def seal_argv(argv: list[str]) -> list[str]:
    """The command that runs ``kalman-course ARGV`` in a sealed interpreter."""
    prefix = tempfile.mkdtemp(prefix="kalman-course-pyc-")
    return [sys.executable, "-I", "-B", "-X", f"pycache_prefix={prefix}", "-m", "kalman_course.tooling.cli",
            *argv]


def _digest(path: str) -> str:
    try:
        with open(path, "rb") as fh:
            return hashlib.sha256(fh.read()).hexdigest()
    except OSError as exc:
        return f"unreadable ({exc.strerror})"


def _watched_files() -> list[str]:
    """The package's files (``.pyc`` included) and the start-up files of every site folder."""
    files = [str(p) for p in PACKAGE.rglob("*") if p.is_file()]
    folders = [*site.getsitepackages(), site.getusersitepackages()]
    for folder in folders:
        files += glob.glob(os.path.join(folder, "*.pth"))
        files += glob.glob(os.path.join(folder, "sitecustomize.py")) + glob.glob(os.path.join(folder, "usercustomize.py"))
    return sorted(set(files))


class Fingerprint:
    """Digests of the files that decide what the grading process runs."""

    def __init__(self):
        self.files = {path: _digest(path) for path in _watched_files()}

    def changes(self) -> list[str]:
        """``"added: PATH"``, ``"changed: PATH"``, ``"removed: PATH"`` since the fingerprint was taken."""
        now = {path: _digest(path) for path in _watched_files()}
        out = [f"added: {p}" for p in sorted(now.keys() - self.files.keys())]
        out += [f"changed: {p}" for p in sorted(now.keys() & self.files.keys()) if now[p] != self.files[p]]
        out += [f"removed: {p}" for p in sorted(self.files.keys() - now.keys())]
        return out


_PR_SET_CHILD_SUBREAPER = 36


def _children() -> set[int]:
    pids = set()
    for path in glob.glob(f"/proc/{os.getpid()}/task/*/children"):
        try:
            pids.update(int(p) for p in Path(path).read_text().split())
        except OSError:  # the thread ended meanwhile
            pass
    return pids


class OrphanReaper:
    """Adopt every process the run's kernels leave behind, and end them (Linux).

    Use as a context manager around a class run; :meth:`end_adopted` kills and reaps every
    child process that was not there when the run started (the run's own workers have been
    joined by then), until none is left.
    """

    def __init__(self):
        self._libc = None
        self._before: set[int] = set()

    def __enter__(self):
        self._before = _children()
        try:
            self._libc = ctypes.CDLL(None, use_errno=True)
            self._libc.prctl(_PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0)
        except (OSError, AttributeError):  # not Linux: processes in sessions of their own stay alive
            self._libc = None
        return self

    def end_adopted(self, seconds: float = 5.0) -> int:
        """Kill every adopted process; return how many there were."""
        ended = 0
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            strays = _children() - self._before
            if not strays:
                break
            for pid in strays:
                try:
                    os.kill(pid, signal.SIGKILL)
                    os.waitpid(pid, 0)
                    ended += 1
                except (ProcessLookupError, ChildProcessError):
                    pass
        return ended

    def __exit__(self, *exc):
        self.end_adopted()
        if self._libc is not None:
            self._libc.prctl(_PR_SET_CHILD_SUBREAPER, 0, 0, 0, 0)
        return False
