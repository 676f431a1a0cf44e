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
- :class:`Fingerprint` records signatures of the package's files, of every ``.pth`` file
  Python runs at start-up and of every module loaded; :meth:`Fingerprint.changes` lists what
  changed during the run, and no gradebook is written when anything did;
- :class:`OrphanReaper` makes this process the "subreaper" of everything it starts, so
  that a process a kernel starts in a session of its own (which survives the kernel's
  process group) is adopted here and ended before any gradebook is written.
"""

from __future__ import annotations

import ctypes
import glob
import importlib
import inspect
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
         "jupyter_client.launcher", "jupyter_client.channels", "jupyter_client.session", "zmq",
         "zmq.utils.garbage", "zmq.utils.monitor", "matplotlib", "numpy.random", "IPython.core.inputtransformer2",
         # the cell files of a kernel (who called a withheld reference); what SymPy loads for the
         # drawn cases' models (sympy.physics.units, sympy.physics.matrices)
         "ipykernel.compiler", "sympy.physics.units", "sympy.physics.matrices")


def preload(check_names=None) -> list[str]:
    """Import every module grading can need and compute what the checks compute once.

    Parameters
    ----------
    check_names : iterable of str, optional
        The checks the run will use (default: all): their modules' cached reference values
        (``functools.cache``) are computed now, which imports whatever SymPy and numpy load
        on first use, and is then inherited by every worker instead of computed by each.

    Returns
    -------
    list of str
        The course's modules imported (for the tests).
    """
    names = []
    for info in pkgutil.walk_packages([str(PACKAGE)], "kalman_course."):
        if not info.name.startswith(_NOT_FOR_GRADING):
            importlib.import_module(info.name)
            names.append(info.name)
    for name in _LAZY:
        importlib.import_module(name)
    from IPython.core.inputtransformer2 import TransformerManager
    from jupyter_client.provisioning.factory import KernelProvisionerFactory

    TransformerManager().transform_cell("%time x = 1\n!true\n")  # the review reads cells as IPython does
    # jupyter_client finds its provisioners through entry points: resolve them now
    KernelProvisionerFactory.instance().get_provisioner_entries()
    from kalman_course.checks import registered

    checks = registered()
    wanted = checks if check_names is None else {n: checks[n] for n in check_names if n in checks}
    for module in sorted({check.__module__ for check in wanted.values()}):
        _compute_cached_values(sys.modules[module])
    return names


def _compute_cached_values(module) -> None:
    """Call every cached function of ``module`` that takes no argument (the checks' cases)."""
    for value in list(vars(module).values()):
        if not (callable(value) and hasattr(value, "cache_info") and value.__module__ == module.__name__):
            continue
        try:
            parameters = inspect.signature(value).parameters.values()
        except (TypeError, ValueError):
            continue
        if all(p.default is not p.empty or p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD) for p in parameters):
            value()


def is_sealed() -> bool:
    """Whether this interpreter runs as :func:`seal_argv` starts it."""
    return bool(sys.flags.isolated and sys.flags.dont_write_bytecode and sys.pycache_prefix)


def seal_argv(argv: list[str]) -> list[str]:
    """The command that runs ``kalman-course ARGV`` in a sealed interpreter."""
    prefix = tempfile.mkdtemp(prefix="kalman-course-pyc-")
    return [sys.executable, "-I", "-B", "-X", f"pycache_prefix={prefix}", "-m", "kalman_course.tooling.cli",
            *argv]


def _signature(path: str) -> str:
    """What changes whenever a file is written, renamed over or has its times set (the inode
    change time cannot be set back by its owner)."""
    try:
        st = os.stat(path)
    except OSError as exc:
        return f"unreadable ({exc.strerror})"
    return f"{st.st_ino}:{st.st_size}:{st.st_mtime_ns}:{st.st_ctime_ns}"


def _watched_files() -> list[str]:
    """The package's files (``.pyc`` included), the start-up files of every site folder (``.pth``,
    ``sitecustomize``, editable installs' finders) and the file of every module loaded."""
    files = [str(p) for p in PACKAGE.rglob("*") if p.is_file()]
    for folder in [*site.getsitepackages(), site.getusersitepackages()]:
        for pattern in ("*.pth", "sitecustomize.py", "usercustomize.py", "__editable__*"):
            files += glob.glob(os.path.join(folder, pattern))
    files += [path for module in list(sys.modules.values())
              if isinstance(path := getattr(module, "__file__", None), str) and os.path.isfile(path)]
    return sorted(set(files))


class Fingerprint:
    """Signatures of the files that decide what the grading process (and the next one) runs."""

    def __init__(self):
        self.taken = time.time_ns()
        self.files = {path: _signature(path) for path in _watched_files()}

    def changes(self) -> list[str]:
        """``"added: PATH"``, ``"changed: PATH"``, ``"removed: PATH"`` since the fingerprint was
        taken (a module first loaded since is compared by whether its file changed after then)."""
        now = {path: _signature(path) for path in _watched_files()}
        out = [f"added: {p}" for p in sorted(now.keys() - self.files.keys()) if self._new_since(p)]
        out += [f"changed: {p}" for p in sorted(now.keys() & self.files.keys()) if now[p] != self.files[p]]
        out += [f"removed: {p}" for p in sorted(self.files.keys() - now.keys())]
        return out

    def _new_since(self, path: str) -> bool:
        try:
            return os.stat(path).st_ctime_ns >= self.taken
        except OSError:
            return True


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
