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
kernel starts, so the learner's code cannot raise them. When the grader runs as root, each
kernel runs as an unprivileged user of its own, and ``pids`` and ``memory`` control groups
of the sandbox's own bound its processes and its whole memory.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import shutil
import signal
import subprocess
import sys
import time
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
    command = [bwrap, *_namespaces(), *_system_binds(), "--proc", "/proc", "--", "true"]
    if os.geteuid() == 0:  # as each kernel will be started: as a user of its own
        command = _as_user_launcher([], _unprivileged_uid()) + command
    try:
        out = subprocess.run(command, capture_output=True, text=True, timeout=30)
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


def _matplotlib_font_cache() -> list[tuple[str, str]]:
    """(here, in the sandbox) of matplotlib's font list, read-only in the kernel's config
    folder: without it each kernel would spend seconds scanning the fonts again."""
    try:
        import matplotlib

        cache = Path(matplotlib.get_cachedir())
    except Exception:  # no matplotlib or no cache folder: the kernel builds its own
        return []
    return [(str(path), f"{SANDBOX_HOME}/.config/matplotlib/{path.name}")
            for path in sorted(cache.glob("fontlist-*.json"))]


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


class ControlGroups:
    """The control groups that hold one sandbox when the grader is root: ``pids`` (every process
    and thread of the sandbox together) and ``memory`` (the whole sandbox's memory, its
    in-memory folders included, where ``RLIMIT_AS`` bounds each process alone). :meth:`remove`
    ends what is left in them."""

    PREFIX = "kalman-course-"

    def __init__(self, roots: dict[str, Path], limits: Limits):
        self.paths = []
        name = f"{self.PREFIX}{uuid.uuid4().hex[:12]}"
        for controller, root in roots.items():
            path = root / name
            if path not in self.paths:  # cgroup v2: one group for every controller
                path.mkdir()
                self.paths.append(path)
            for setting, value in _CGROUP_SETTINGS[(controller, (root / "cgroup.controllers").exists())](limits):
                (path / setting).write_text(str(value))

    @staticmethod
    def available_roots() -> dict[str, Path]:
        """Writable hierarchies by controller (cgroup v1, or a v2 root with the controller on)."""
        if os.geteuid() != 0:
            return {}
        roots = {}
        unified = Path("/sys/fs/cgroup")
        enabled = (unified / "cgroup.subtree_control")
        for controller in ("pids", "memory"):
            v1 = unified / controller
            if (v1 / "cgroup.procs").exists() and os.access(v1, os.W_OK):
                roots[controller] = v1
            elif enabled.exists() and controller in enabled.read_text().split() and os.access(unified, os.W_OK):
                roots[controller] = unified
        return roots

    @classmethod
    def remove_stale(cls, roots: dict[str, Path]) -> None:
        """Remove the empty groups an earlier run left (a group still in use is not empty)."""
        for root in set(roots.values()):
            for path in root.glob(f"{cls.PREFIX}*"):
                with contextlib.suppress(OSError):
                    path.rmdir()

    def enter_prefix(self) -> list[str]:
        """A command prefix that moves itself into the groups and then becomes the command
        (everything it starts stays in them)."""
        moves = " && ".join(f'echo 0 > "${i}"' for i in range(len(self.paths)))
        return ["/bin/sh", "-c", f'{moves} && shift {len(self.paths) - 1} && exec "$@"',
                *(str(path / "cgroup.procs") for path in self.paths)]

    def remove(self, seconds: float = 2.0) -> None:
        """Kill whatever is still in the groups, then remove them."""
        end = time.monotonic() + seconds
        for path in self.paths:
            while path.exists():
                with contextlib.suppress(OSError, ValueError):
                    for pid in (path / "cgroup.procs").read_text().split():
                        with contextlib.suppress(ProcessLookupError):
                            os.kill(int(pid), signal.SIGKILL)
                try:
                    path.rmdir()
                except OSError:  # its last processes are still exiting
                    if time.monotonic() > end:
                        break
                    time.sleep(0.02)


#: What each controller's group is told, in cgroup v1 (False) and v2 (True).
_CGROUP_SETTINGS = {
    ("pids", False): lambda limits: [("pids.max", limits.processes)],
    ("pids", True): lambda limits: [("pids.max", limits.processes)],
    ("memory", False): lambda limits: [("memory.limit_in_bytes", limits.memory)],
    ("memory", True): lambda limits: [("memory.max", limits.memory)],
}


@dataclass
class PreparedKernel:
    """How to start one sandboxed kernel, and what to undo once it is gone."""

    argv: list[str]
    channels: str
    cgroups: ControlGroups | None = None

    def started(self) -> None:
        """The kernel has made its sockets: as root, make the channels folder read-only to the
        kernel (which could otherwise fill the disk with files there)."""
        if os.geteuid() == 0:
            os.chown(self.channels, 0, 0)
            os.chmod(self.channels, 0o755)

    def remove(self) -> None:
        if self.cgroups is not None:
            self.cgroups.remove()


class Sandbox:
    """How to start one learner kernel inside bubblewrap.

    When the grader runs as root, each kernel runs as an unprivileged user of its own (a
    user id no account has), so that no file of root's, ``/proc/sys`` among them, is
    writable from inside; the folders it needs are bound first where that user can reach
    them, in a mount namespace that dies with the sandbox.

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
        self._cgroup_roots = ControlGroups.available_roots()
        ControlGroups.remove_stale(self._cgroup_roots)

    def describe(self) -> str:
        return f"{self.version} ({self.limits.describe()})"

    def prepare(self, kernel_argv: list[str], *, channels: str, files: dict[str, str],
                env: dict[str, str], package: str | None = None) -> PreparedKernel:
        """The command that runs ``kernel_argv`` in a new sandbox.

        Parameters
        ----------
        kernel_argv : list of str
            The kernel's own command (its connection file inside ``channels``).
        channels : str
            The folder of the connection file and the ``ipc`` sockets, bound read-write at
            the same path.
        files : dict
            Folders to show read-only in the kernel's HOME: name there → path here.
        env : dict
            Environment variables the kernel needs beyond the sandbox's own.
        package : str, optional
            A build of the package shown where the package is instead of the package itself
            (:mod:`kalman_course.tooling.withheld`: the chapter's references withheld).
        """
        as_root = os.geteuid() == 0
        uid = _unprivileged_uid() if as_root else os.geteuid()
        # the package after the Python installation: it hides an installed copy of itself there
        read_only = [(root, root) for root in _python_roots()] + [(package or _package_dir(), _package_dir())]
        read_only += [(path, f"{SANDBOX_HOME}/{name}") for name, path in sorted(files.items())]
        read_only += _matplotlib_font_cache()
        staged = []
        if as_root:
            # the kernel's own user may not pass through root's folders (a Python under /root):
            # each is bound, in a mount namespace of the sandbox's own, where that user reaches it
            stage = Path(channels).parent / "stage"
            stage.mkdir(mode=0o711)
            os.chmod(stage.parent, 0o711)
            for i, (source, dest) in enumerate(read_only):
                target = stage / str(i)
                target.mkdir() if os.path.isdir(source) else target.touch()
                staged.append((source, str(target)))
                read_only[i] = (str(target), dest)
            os.chown(channels, uid, uid)  # until the kernel has made its sockets (see PreparedKernel.started)
        args = [self.bwrap, *_namespaces(), *_system_binds(),
                "--dev", "/dev", "--size", str(self.limits.tmp_size // 4), "--tmpfs", "/dev/shm",
                "--proc", "/proc",
                "--size", str(self.limits.tmp_size), "--tmpfs", "/tmp",
                "--size", str(self.limits.tmp_size), "--tmpfs", SANDBOX_HOME,
                "--bind", channels, channels]
        for source, dest in read_only:  # after HOME's folder, which some are shown in
            args += ["--ro-bind", source, dest]
        # nothing but the folders above is writable: not the sandbox's root, not /dev
        args += ["--remount-ro", "/dev", "--remount-ro", "/"]
        args += ["--chdir", SANDBOX_HOME, *_environment(env), "--"]
        args += _limits_launcher(self.limits) + kernel_argv
        if as_root:
            args = _as_user_launcher(staged, uid) + args
        cgroups = ControlGroups(self._cgroup_roots, self.limits) if self._cgroup_roots else None
        return PreparedKernel((cgroups.enter_prefix() + args) if cgroups else args, channels, cgroups)


def _as_user_launcher(binds: list[tuple[str, str]], uid: int) -> list[str]:
    """A command prefix, run as root, that binds ``binds`` (source, target) in a mount
    namespace of its own and then becomes the command as user and group ``uid``."""
    code = ("import ctypes, os, sys\n"
            "libc = ctypes.CDLL(None, use_errno=True)\n"
            "def call(result, what):\n"
            "    if result != 0:\n"
            "        raise OSError(ctypes.get_errno(), what)\n"
            "call(libc.unshare(0x20000), 'unshare the mount namespace')\n"  # CLONE_NEWNS
            "call(libc.mount(b'none', b'/', None, 0x44000, None), 'make the mounts private')\n"  # MS_REC | MS_PRIVATE
            "n, uid = int(sys.argv[1]), int(sys.argv[2])\n"
            "for source, target in zip(sys.argv[3:3 + n], sys.argv[3 + n:3 + 2 * n]):\n"
            "    call(libc.mount(source.encode(), target.encode(), None, 0x5000, None), 'bind ' + source)\n"  # MS_BIND | MS_REC
            "os.setgroups([])\n"
            "os.setgid(uid)\n"
            "os.setuid(uid)\n"
            "os.execv(sys.argv[3 + 2 * n], sys.argv[3 + 2 * n:])\n")
    return [sys.executable, "-I", "-S", "-c", code, str(len(binds)), str(uid),
            *(source for source, _ in binds), *(target for _, target in binds)]


def _unprivileged_uid() -> int:
    """A user id of its own for one kernel, far above every account's (and below 2**31)."""
    return 2**30 + secrets.randbelow(2**29)


def open_sandbox(limits: Limits = Limits()) -> Sandbox:
    """A working :class:`Sandbox`, or :class:`SandboxUnavailable` saying what to install."""
    bwrap = find_bwrap()
    if bwrap is None:
        raise SandboxUnavailable("bubblewrap (bwrap) is not installed: `apt-get install bubblewrap` "
                                 "(Debian, Ubuntu), `dnf install bubblewrap` (Fedora), `pacman -S bubblewrap` (Arch)")
    probe(bwrap)
    return Sandbox(bwrap, limits)
