"""A bubblewrap sandbox for one learner kernel: what the kernel can see, reach and use.

``kalman-course grade`` starts each learner's kernel inside `bubblewrap
<https://github.com/containers/bubblewrap>`_ (``bwrap``, packaged by Debian, Ubuntu,
Fedora and Arch; the tool Flatpak sandboxes its applications with). Inside, the kernel
sees:

- the Python installation and the ``kalman_course`` package, read-only (no other folder
  of the checkout: not ``solutions/``, not the class folder);
- the released exercise and this learner's notebook, read-only copies;
- a private, size-limited, writable HOME (its working folder) and ``/tmp``;
- the folder of its own channels to the grading process (Jupyter's ``ipc`` transport:
  Unix sockets in a folder bound into the sandbox, since a TCP port on 127.0.0.1 would be
  the kernel's own loopback in its network namespace);
- and nothing else: no network, its own PID namespace (``/proc`` lists only its own
  processes, and every process it starts dies with it), its own user namespace with no
  capabilities, a new terminal session.

Limits (:class:`Limits`) are set as hard resource limits inside the sandbox before the
kernel starts, so the learner's code cannot raise them. The kernel exempts root from
``RLIMIT_NPROC``: when the grader runs as root, the number of processes is bounded by a
``pids`` control group of the sandbox's own instead.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import uuid
from dataclasses import dataclass
from pathlib import Path

#: Where the kernel's HOME (and working folder) is, inside the sandbox.
SANDBOX_HOME = "/home/learner"


class SandboxUnavailable(RuntimeError):
    """bubblewrap is not installed or cannot create its namespaces on this machine."""


@dataclass(frozen=True)
class Limits:
    """Resource limits of one learner kernel (each a hard limit the learner cannot raise).

    Attributes
    ----------
    memory : int
        Bytes of address space per process (``RLIMIT_AS``).
    processes : int
        Processes and threads the sandbox may hold at once.
    cpu_seconds : int
        CPU seconds per process (``RLIMIT_CPU``; the kernel is killed past it).
    file_size : int
        Bytes of the largest file a process may write (``RLIMIT_FSIZE``).
    tmp_size : int
        Bytes of each of the two writable folders (HOME and ``/tmp``, both in memory).
    """

    memory: int = 4 * 2**30
    processes: int = 128
    cpu_seconds: int = 1800
    file_size: int = 64 * 2**20
    tmp_size: int = 256 * 2**20

    def describe(self) -> str:
        """One line for README, the CLI and the gradebook."""
        return (f"{self.memory / 2**30:g} GiB address space per process, {self.processes} processes, "
                f"{self.cpu_seconds} CPU s per process, files up to {self.file_size // 2**20} MiB, "
                f"HOME and /tmp {self.tmp_size // 2**20} MiB each")


def find_bwrap() -> str | None:
    """The path of the ``bwrap`` executable, or None."""
    return shutil.which("bwrap")


def bwrap_version(bwrap: str) -> str:
    """``"bubblewrap 0.8.0"``: what ``bwrap --version`` prints."""
    out = subprocess.run([bwrap, "--version"], capture_output=True, text=True, timeout=10)
    return out.stdout.strip() or "bubblewrap (unknown version)"


def probe(bwrap: str) -> None:
    """Raise :class:`SandboxUnavailable` unless ``bwrap`` can build the sandbox here (some
    containers forbid user namespaces)."""
    try:
        out = subprocess.run([bwrap, *_namespaces(), "--ro-bind", "/", "/", "--proc", "/proc", "--", "true"],
                             capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise SandboxUnavailable(f"bubblewrap did not run ({exc})") from None
    if out.returncode != 0:
        raise SandboxUnavailable(f"bubblewrap cannot create its namespaces here: {out.stderr.strip()}")


def _namespaces() -> list[str]:
    # every namespace bubblewrap supports; uid/gid 1000 inside, no capabilities
    return ["--unshare-all", "--unshare-user", "--uid", "1000", "--gid", "1000", "--cap-drop", "ALL",
            "--die-with-parent", "--new-session", "--hostname", "sandbox"]


def _python_roots() -> list[str]:
    """The folders the kernel's Python needs: its installation (and a virtual environment's)."""
    roots = {os.path.realpath(p) for p in (sys.base_prefix, sys.prefix, sys.exec_prefix)}
    return sorted(roots)


def _package_dir() -> str:
    """The ``kalman_course`` package folder alone (in an editable install its checkout holds
    ``solutions/``, which must stay out)."""
    return os.path.realpath(Path(__file__).parents[1])


#: System files a Python kernel reads, bound read-only when present (the rest of /etc stays out).
_ETC = ("ld.so.cache", "ld.so.conf", "ld.so.conf.d", "localtime", "fonts", "nsswitch.conf", "passwd",
        "group", "mime.types")


def _system_binds() -> list[str]:
    args = []
    for top in ("/usr", "/bin", "/lib", "/lib32", "/lib64", "/sbin"):
        if os.path.islink(top):
            args += ["--symlink", os.readlink(top), top]
        elif os.path.isdir(top):
            args += ["--ro-bind", top, top]
    for name in _ETC:
        path = os.path.join("/etc", name)
        if os.path.exists(path):
            args += ["--ro-bind", path, path]
    return args


def _matplotlib_font_cache() -> list[str]:
    """matplotlib's font list, read-only in the kernel's config folder: without it each
    kernel would spend seconds scanning the fonts again."""
    try:
        import matplotlib

        cache = Path(matplotlib.get_cachedir())
    except Exception:  # no matplotlib or no cache folder: the kernel builds its own
        return []
    return [arg for path in sorted(cache.glob("fontlist-*.json"))
            for arg in ("--ro-bind", str(path), f"{SANDBOX_HOME}/.config/matplotlib/{path.name}")]


def _limits_launcher(limits: Limits) -> list[str]:
    """A command prefix that sets the hard limits and then becomes the kernel."""
    code = ("import os, resource, sys\n"
            f"for name, value in (('RLIMIT_AS', {limits.memory}), ('RLIMIT_NPROC', {limits.processes}), "
            f"('RLIMIT_CPU', {limits.cpu_seconds}), ('RLIMIT_FSIZE', {limits.file_size}), ('RLIMIT_CORE', 0)):\n"
            "    resource.setrlimit(getattr(resource, name), (value, value))\n"
            "os.execv(sys.argv[1], sys.argv[1:])\n")
    return [sys.executable, "-I", "-S", "-c", code]


def _environment(extra: dict[str, str]) -> list[str]:
    """The kernel's whole environment: nothing of the grader's (no key, no paths of its own)."""
    env = {"HOME": SANDBOX_HOME, "PATH": os.pathsep.join([os.path.dirname(sys.executable), "/usr/bin", "/bin"]),
           "LANG": "C.UTF-8", "TMPDIR": "/tmp", "PYTHONNOUSERSITE": "1", "PYTHONDONTWRITEBYTECODE": "1",
           "MPLCONFIGDIR": f"{SANDBOX_HOME}/.config/matplotlib", "IPYTHONDIR": f"{SANDBOX_HOME}/.ipython"}
    for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        if name in os.environ:
            env[name] = os.environ[name]
    env.update(extra)
    args = ["--clearenv"]
    for name, value in sorted(env.items()):
        args += ["--setenv", name, value]
    return args


class ProcessGroupCgroup:
    """A ``pids`` control group holding one sandbox (used when the grader is root, whom
    ``RLIMIT_NPROC`` does not bind), removed by :meth:`remove`."""

    def __init__(self, root: Path, limit: int):
        self.path = root / f"kalman-course-{uuid.uuid4().hex[:12]}"
        self.path.mkdir()
        (self.path / "pids.max").write_text(str(limit))

    @staticmethod
    def available_root() -> Path | None:
        """The writable ``pids`` hierarchy (cgroup v1, or v2 with the controller on), or None."""
        if os.geteuid() != 0:
            return None
        for root in (Path("/sys/fs/cgroup/pids"), Path("/sys/fs/cgroup")):
            if (root / "cgroup.procs").exists() and os.access(root, os.W_OK):
                controllers = root / "cgroup.subtree_control"
                if root.name == "pids" or (controllers.exists() and "pids" in controllers.read_text().split()):
                    return root
        return None

    def enter_prefix(self) -> list[str]:
        """A command prefix that moves itself into the group and then becomes the command
        (everything it starts stays in the group)."""
        return ["/bin/sh", "-c", 'echo 0 > "$0" && exec "$@"', str(self.path / "cgroup.procs")]

    def remove(self) -> None:
        try:
            self.path.rmdir()
        except OSError:  # still has a process for an instant after the kill
            pass


class Sandbox:
    """How to start one learner kernel inside bubblewrap.

    Parameters
    ----------
    bwrap : str
        The ``bwrap`` executable.
    limits : Limits
        The kernel's resource limits.
    """

    def __init__(self, bwrap: str, limits: Limits = Limits()):
        self.bwrap, self.limits = bwrap, limits
        self.version = bwrap_version(bwrap)
        self._cgroup_root = ProcessGroupCgroup.available_root()

    def describe(self) -> str:
        return f"{self.version} ({self.limits.describe()})"

    def kernel_argv(self, kernel_argv: list[str], *, channels: str, files: dict[str, str],
                    env: dict[str, str]) -> tuple[list[str], ProcessGroupCgroup | None]:
        """The command that runs ``kernel_argv`` in a new sandbox.

        Parameters
        ----------
        kernel_argv : list of str
            The kernel's own command (its connection file inside ``channels``).
        channels : str
            The folder of the connection file and the ``ipc`` sockets, bound read-write at
            the same path.
        files : dict
            Files to show read-only in the kernel's HOME: name there → path here.
        env : dict
            Environment variables the kernel needs beyond the sandbox's own.

        Returns
        -------
        argv : list of str
        cgroup : ProcessGroupCgroup or None
            The control group to remove once the kernel is gone (root only).
        """
        args = [self.bwrap, *_namespaces(), *_system_binds()]
        for root in [*_python_roots(), _package_dir()]:
            args += ["--ro-bind", root, root]
        args += ["--dev", "/dev", "--proc", "/proc",
                 "--size", str(self.limits.tmp_size), "--tmpfs", "/tmp",
                 "--size", str(self.limits.tmp_size), "--tmpfs", SANDBOX_HOME,
                 "--bind", channels, channels]
        for name, path in sorted(files.items()):
            args += ["--ro-bind", path, f"{SANDBOX_HOME}/{name}"]
        args += _matplotlib_font_cache()
        args += ["--chdir", SANDBOX_HOME, *_environment(env), "--"]
        args += _limits_launcher(self.limits) + kernel_argv
        cgroup = ProcessGroupCgroup(self._cgroup_root, self.limits.processes) if self._cgroup_root else None
        return (cgroup.enter_prefix() + args if cgroup else args), cgroup


def open_sandbox(limits: Limits = Limits()) -> Sandbox:
    """A working :class:`Sandbox`, or :class:`SandboxUnavailable` saying what to install."""
    bwrap = find_bwrap()
    if bwrap is None:
        raise SandboxUnavailable("bubblewrap (bwrap) is not installed: `apt-get install bubblewrap` "
                                 "(Debian, Ubuntu), `dnf install bubblewrap` (Fedora), `pacman -S bubblewrap` (Arch)")
    probe(bwrap)
    return Sandbox(bwrap, limits)
