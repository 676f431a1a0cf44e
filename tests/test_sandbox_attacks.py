"""Attacks on the grading sandbox, graded for real: learner cells that try to get out.

Each attack is a learner cell of a released exercise (its stubs left wrong, so an honest
grade is 0 on every check), written the way a learner who wants the points, or wants to harm
a classmate, would write it. The whole corpus is one class, graded by one ``kalman-course
grade`` run with two jobs, each kernel in the real bubblewrap sandbox (no mock). Two honest
classmates, the solutions themselves, are graded in the same run: one of them is the notebook
an attacker tries to read and rewrite.

Most attacks end by raising ``Held`` (the defence stopped them: the cell's error in the
gradebook says how) or ``Escaped`` (they did what they tried: the error says what); what an
attack writes outside the sandbox is looked for where it would land, after the run. The
gradebook files are read right after the run and again at the end of this module, more than
five seconds later (an attack's process sleeps three seconds and then rewrites them).

Beside the class run: the worker-death handling alone, Ctrl-C of a class run in a terminal,
the shell's ``kalman-course grade`` (which re-runs itself sealed), a sealed process whose
``sys.modules`` must not grow while it grades, and the ``--no-sandbox`` note.
"""

from __future__ import annotations

import contextlib
import csv
import glob
import hashlib
import importlib.util
import io
import json
import os
import random
import re
import shutil
import signal
import site
import socket
import subprocess
import sys
import sysconfig
import tempfile
import threading
import time
import uuid
from dataclasses import dataclass
from pathlib import Path

import nbformat
import pytest
from nbformat.v4 import new_code_cell, new_notebook

from kalman_course.tooling.cells import BEGIN_RE, END_RE, STUB_RE
from kalman_course.tooling import cli, grading
from kalman_course.tooling.gradebook import KEY_VARIABLE

from conftest import ROOT, dedented as _code

pytestmark = pytest.mark.slow

if shutil.which("bwrap") is None:
    if os.environ.get("KALMAN_COURSE_REQUIRE_SANDBOX"):
        pytest.fail("KALMAN_COURSE_REQUIRE_SANDBOX is set but bubblewrap (bwrap) is not installed: "
                    "`apt-get install bubblewrap`", pytrace=False)
    pytest.skip("bubblewrap (bwrap) is not installed: these attacks need the real sandbox",
                allow_module_level=True)

CH01, CH03 = "01_bayes_rule.ipynb", "03_kalman_filter.ipynb"
TIMEOUT = 10  # --timeout of the class run: the output flood must be stopped by it
INTERRUPT_GRACE = 5  # seconds an interrupted kernel gets to stop (kernel_session.INTERRUPT_GRACE)
#: In the command line of every long-lived process an attack starts (found with pgrep afterwards).
MARK = "kcattack" + uuid.uuid4().hex[:12]
#: The fork bomb's `sleep` argument: a number only this module's sleepers carry.
SLEEP = f"30.{random.randrange(10**8, 10**9)}"
MiB = 2**20


# ---------------------------------------------------------------------------------------
# the attacks
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Attack:
    """One attack: a learner cell and what the defence must make of it.

    Attributes
    ----------
    case : str
        The case of issue 23 it belongs to.
    tries : str
        What it tries, in one line.
    submission : str
        The learner folder (attacks that cannot interfere share one notebook).
    notebook : str
        The released exercise it starts from.
    cell : str
        The attacking cell's id.
    place : str
        ``"after:<id>"``: a new cell after that one; ``"replace"``: the release's learner
        cell ``cell`` rewritten.
    source : str
        The cell; ``@@NAME@@`` is replaced by the Python literal of a path or number of
        this run (the learner wrote it in by hand, or learned it from an earlier run).
    error : str
        The start of the error the cell must end with (``"Held"``: the defence stopped it;
        ``"MemoryError"``, ...); empty when the cell must run without error.
    """

    case: str
    tries: str
    submission: str
    notebook: str
    cell: str
    place: str
    source: str
    error: str


_HELD = '''
class Held(Exception):
    """The defence stopped this attack (the message says how)."""


class Escaped(Exception):
    """The attack did what it tried (the message says what)."""
'''

# the longest notebooks first (learners are graded in sorted order): the run ends sooner
FLOOD, PROCESSES, INTRUDER = "a_flood", "b_processes", "c_intruder"
CLASSMATE_01, CLASSMATE_03 = "y_classmate", "z_classmate"

ATTACKS = [
    # --- c_intruder, chapter 01: files of the grading machine, the solution, classmates -----------
    Attack("1 forged modules", "a %%bash cell writes a .pyc for a module a check imports, one for "
           "tooling/grading.py (headers matching the sources), a .pth in site-packages, and modules in "
           "solutions/ and tooling/; exit status = the writes refused",
           INTRUDER, CH01, "attack-forge", "after:setup", _code('''
            %%bash
            python - <<'EOF'
            import importlib.util, os, site, sys
            from importlib._bootstrap_external import _code_to_timestamp_pyc

            import kalman_course

            package = os.path.dirname(kalman_course.__file__)
            mark = @@MARK@@


            def forged_pyc(module_file):
                """The .pyc Python trusts for module_file: its header says the source's mtime and size."""
                with open(module_file) as fh:
                    source = fh.read()
                code = compile(source + f"\\n_forged_by = {mark!r}\\n", module_file, "exec")
                st = os.stat(module_file)
                return _code_to_timestamp_pyc(code, int(st.st_mtime), st.st_size)


            writes = []
            for rel in ("filters/bayes.py", "tooling/grading.py"):
                module = os.path.join(package, rel)
                # (a graded kernel's package has no tooling/: the write is refused all the same)
                data = forged_pyc(module) if os.path.exists(module) else b"forged"
                writes.append((importlib.util.cache_from_source(module), data))
            writes.append((os.path.join(site.getsitepackages()[0], f"zz_{mark}.pth"),
                           f"import sys; sys.modules.setdefault({mark!r}, sys)\\n".encode()))
            repo = os.path.dirname(package)
            writes.append((os.path.join(repo, "solutions", f"{mark}.py"), b"ANSWERS = {}\\n"))
            writes.append((os.path.join(package, "tooling", f"{mark}.py"), b"FORGED = True\\n"))
            refused = 0
            for path, data in writes:
                try:
                    with open(path, "wb") as fh:
                        fh.write(data)
                    print("wrote", path)
                except OSError as exc:
                    refused += 1
                    print("refused", path, exc.strerror)
            sys.exit(refused)
            EOF
        '''), "CalledProcessError"),
    Attack("2 reading the solution", "%run the repository's solutions/01_bayes_rule.ipynb by a path "
           "built at run time from the package's own location",
           INTRUDER, CH01, "likelihood", "replace", _HELD + "\n" + _code('''
            import os

            import kalman_course

            # the checkout the grader runs from is the package's parent folder
            _repo = os.path.dirname(os.path.dirname(kalman_course.__file__))
            _solution = os.path.join(_repo, "solu" + "tions", "01_bayes" + "_rule.ipynb")
            if not os.path.exists(_solution):
                raise Held(f"{_solution}: no such file in the sandbox")
            get_ipython().run_line_magic("run", _solution)  # every function of the solution, defined here
        '''), "Held"),
    Attack("3 finding classmates", "list /proc: the grader's command line names the class folder; "
           "then list that folder",
           INTRUDER, CH01, "attack-proc", "after:attack-forge", _HELD + "\n" + _code('''
            import os

            _seen = {}
            for _pid in os.listdir("/proc"):
                if _pid.isdigit():
                    try:
                        with open(f"/proc/{_pid}/cmdline", "rb") as fh:
                            _seen[int(_pid)] = fh.read().replace(b"\\0", b" ").decode(errors="replace")
                    except OSError:
                        pass
            _grader = {pid: cmd for pid, cmd in _seen.items()
                       if any(word in cmd for word in ("kalman_course.tooling", "kalman-course", "pytest",
                                                       "multiprocessing", @@CLASS@@))}
            try:
                _classmates = os.listdir(@@CLASS@@)
            except OSError as exc:
                _classmates = None
                _why = exc.strerror
            if _grader or _classmates is not None or len(_seen) > 10:
                raise Escaped(f"{len(_seen)} processes visible, grader {_grader}, class folder {_classmates}")
            raise Held(f"{len(_seen)} processes visible (pids {sorted(_seen)}), none of the grader's; "
                       f"the class folder: {_why}")
        '''), "Held"),
    Attack("3 rewriting a classmate", "rewrite a classmate's notebook in the class folder before it is "
           "graded: their histogram_update becomes `return belief`",
           INTRUDER, CH01, "attack-rewrite", "after:attack-proc", _HELD + "\n" + _code('''
            import json

            _target = @@CLASSMATE@@
            try:
                with open(_target, encoding="utf-8") as fh:
                    _nb = json.load(fh)
            except OSError as exc:
                raise Held(f"{_target}: {exc.strerror}")
            for _cell in _nb["cells"]:
                if _cell.get("id") == "update":
                    _cell["source"] = "def histogram_update(belief, likelihood):\\n    return belief\\n"
            with open(_target, "w", encoding="utf-8") as fh:
                json.dump(_nb, fh)
            raise Escaped(f"rewrote {_target}")
        '''), "Held"),
    Attack("3 copying a classmate", "run the classmate's own histogram_update cell, read from their "
           "notebook in the class folder",
           INTRUDER, CH01, "update", "replace", _HELD + "\n" + _code('''
            import json

            try:
                with open(@@CLASSMATE@@, encoding="utf-8") as fh:
                    _theirs = json.load(fh)
            except OSError as exc:
                raise Held(f"the classmate's notebook: {exc.strerror}")
            for _cell in _theirs["cells"]:
                if _cell.get("id") == "update":
                    exec("".join(_cell["source"]))
        '''), "Held"),
    Attack("1 the machine's kernel settings", "as root on the grading machine, kernel.core_pattern "
           "'|/a/program' runs that program as root outside every namespace at the next crash: "
           "write it (with its own value, which changes nothing)",
           INTRUDER, CH01, "attack-sysctl", "after:attack-rewrite", _HELD + "\n" + _code('''
            _pattern = "/proc/sys/kernel/core_pattern"
            try:
                with open(_pattern) as fh:
                    _now = fh.read()
                with open(_pattern, "w") as fh:
                    fh.write(_now)  # the same value: proves the write, changes nothing
            except OSError as exc:
                raise Held(f"{_pattern}: {exc.strerror}")
            raise Escaped(f"{_pattern} of the grading machine is writable from the sandbox "
                          f"(it is {_now.strip()!r}; '|/path/to/program' would run that program as root)")
        '''), "Held"),
    Attack("3 the grader's secrets", "look for the gradebook key in the environment and every "
           "process's /proc/PID/environ, read /etc/shadow, root's ssh key and the checkout's .git",
           INTRUDER, CH01, "attack-secrets", "after:attack-sysctl", _HELD + "\n" + _code('''
            import glob
            import os

            import kalman_course

            _found = [f"${name}" for name in os.environ if "KEY" in name or "GRADEBOOK" in name]
            for _path in glob.glob("/proc/*/environ"):
                try:
                    with open(_path, "rb") as fh:
                        if b"GRADEBOOK_KEY" in fh.read():
                            _found.append(_path)
                except OSError:
                    pass
            _repo = os.path.dirname(os.path.dirname(kalman_course.__file__))
            _refused = []
            for _path in ("/etc/shadow", "/root/.ssh/id_rsa", "/root/.ssh/authorized_keys",
                          os.path.join(_repo, ".git", "config")):
                try:
                    with open(_path, "rb") as fh:
                        fh.read(1)
                    _found.append(_path)
                except OSError as exc:
                    _refused.append(f"{_path}: {exc.strerror}")
            if _found:
                raise Escaped(f"read {_found}")
            raise Held("; ".join(_refused))
        '''), "Held"),
    Attack("6 memory outside the limits", "fill the sandbox's in-memory folders past the 256 MiB "
           "a kernel's folders may hold: /dev/shm and / are memory too",
           INTRUDER, CH01, "attack-shm", "after:attack-secrets", _HELD + "\n" + _code('''
            _written = {}
            for _folder in ("/dev/shm", "/"):
                _written[_folder] = 0
                try:
                    for _i in range(6):
                        with open(f"{_folder.rstrip('/')}/fill-{_i}", "wb") as fh:
                            fh.write(bytes(60 * 2**20))
                        _written[_folder] += 60
                except OSError as exc:
                    _written[_folder] = f"{_written[_folder]} MiB, then {exc.strerror}"
            _past = {f: n for f, n in _written.items() if n == 360}
            if _past:
                raise Escaped(f"wrote 360 MiB of the machine's memory into {sorted(_past)}, past the "
                              "256 MiB limit of the sandbox's folders")
            raise Held(f"{_written}")
        '''), "Held"),
    Attack("6 the machine's disk", "fill the grading machine's disk through the folder of the "
           "kernel's connection file, the one folder of the machine the sandbox can write",
           INTRUDER, CH01, "attack-disk", "after:attack-shm", _HELD + "\n" + _code('''
            import os

            from ipykernel import get_connection_file

            _folder = os.path.dirname(get_connection_file())
            _written = 0
            try:
                for _i in range(6):
                    with open(os.path.join(_folder, f"fill-{_i}"), "wb") as fh:
                        fh.write(bytes(60 * 2**20))
                    _written += 60
            except OSError as exc:
                raise Held(f"{_folder}: refused after {_written} MiB ({exc.strerror})")
            _st = os.statvfs(_folder)
            raise Escaped(f"wrote {_written} MiB on the grading machine's disk in {_folder} "
                          f"(a {_st.f_blocks * _st.f_frsize / 2**30:.0f} GiB file system, "
                          f"{_st.f_bavail * _st.f_frsize / 2**30:.0f} GiB free)")
        '''), "Held"),

    Attack("10 a flood of maximal messages", "publish 24 messages of 18 MiB (each under the grader's "
           "20 MiB bound) while the grader waits for this cell: its unread messages pile up in the worker "
           "(the kernel holds as much: in a notebook whose kernel needs no more memory)",
           INTRUDER, CH01, "attack-pileup", "after:attack-disk", _code('''
            import time

            _kernel = get_ipython().kernel
            _chunk = bytes(18 * 2**20)
            for _ in range(24):
                _kernel.session.send(_kernel.iopub_socket, "stream", {"name": "stdout", "text": ""},
                                     parent=_kernel.get_parent(), buffers=[_chunk])
            del _chunk
            time.sleep(2)
        '''), ""),

    # --- b_processes, chapter 03: processes, the network, memory, answers ----------------------------
    Attack("5 network", "connect to a port the grading machine listens on (127.0.0.1), to its "
           "abstract Unix socket, and to the internet",
           PROCESSES, CH03, "attack-network", "after:setup", _HELD + "\n" + _code('''
            import socket

            _reached, _refused = [], []
            for _family, _address in ((socket.AF_INET, ("127.0.0.1", @@PORT@@)),
                                      (socket.AF_UNIX, "\\0" + @@MARK@@),
                                      (socket.AF_INET, ("1.1.1.1", 53))):
                _s = socket.socket(_family, socket.SOCK_STREAM)
                _s.settimeout(3)
                try:
                    _s.connect(_address)
                    _reached.append(repr(_address))
                except OSError as exc:
                    _refused.append(f"{_address!r}: {exc.strerror or exc}")
                finally:
                    _s.close()
            if _reached:
                raise Escaped(f"connected to {_reached}")
            raise Held("; ".join(_refused))
        '''), "Held"),
    Attack("7 memory", "allocate 8 GiB at once",
           PROCESSES, CH03, "attack-memory", "after:attack-network", _code('''
            _hoard = bytearray(8 * 2**30)
        '''), "MemoryError"),
    Attack("9 killing the grading worker", "SIGKILL the kernel's parent, its process group and "
           "anything in /proc that looks like the grader",
           PROCESSES, CH03, "attack-kill", "after:attack-memory", _HELD + "\n" + _code('''
            import os
            import signal

            _tried = []


            def _attempt(what, kill):
                try:
                    kill()
                    _tried.append(f"{what}: sent")
                except OSError as exc:
                    _tried.append(f"{what}: {exc.strerror}")


            _parent = os.getppid()
            _attempt(f"kill({_parent}) (my parent)", lambda: os.kill(_parent, signal.SIGKILL))
            _group = os.getpgid(_parent)
            if _group not in (0, os.getpgid(0)):
                _attempt(f"killpg({_group}) (my parent's group)", lambda: os.killpg(_group, signal.SIGKILL))
            for _pid in os.listdir("/proc"):
                if _pid.isdigit() and int(_pid) not in (os.getpid(), _parent):
                    try:
                        with open(f"/proc/{_pid}/cmdline", "rb") as fh:
                            _cmd = fh.read()
                    except OSError:
                        continue
                    if any(word in _cmd for word in (b"multiprocessing", b"kalman_course.tooling", b"pytest")):
                        _attempt(f"kill({_pid})", lambda: os.kill(int(_pid), signal.SIGKILL))
            raise Held("; ".join(_tried) + " (and the grading went on)")
        '''), "Held"),
    Attack("4 rewriting the gradebook later", "a process in a session of its own waits 3 s, then "
           "rewrites the gradebook's JSON, CSV and feedback (absolute paths) every half second for a "
           "minute, SIGKILLs the grader's processes it can find, and its new parent once its kernel is gone",
           PROCESSES, CH03, "attack-daemon", "after:attack-kill", _code('''
            import subprocess
            import sys

            _daemon = """
            import json, os, signal, sys, time
            kernel = os.getppid()
            time.sleep(3)
            forged = {
                @@JSON@@: json.dumps([{"learner": "b_processes", "points": 12, "possible": 12}]),
                @@CSV@@: "learner,points,possible\\\\nb_processes,12,12\\\\n",
                @@FEEDBACK@@: "# Feedback for b_processes\\\\n\\\\n12/12 points\\\\n",
            }
            for _ in range(120):
                for path, text in forged.items():
                    try:
                        with open(path, "w") as fh:
                            fh.write(text)
                    except OSError:
                        pass
                for pid in os.listdir("/proc"):
                    try:
                        cmd = open(f"/proc/{pid}/cmdline", "rb").read()
                    except OSError:
                        continue
                    if b"kalman_course.tooling" in cmd or b"multiprocessing" in cmd:
                        try:
                            os.kill(int(pid), signal.SIGKILL)
                        except OSError:
                            pass
                if os.getppid() != kernel:  # my kernel is gone: kill whoever adopted me (the grader)
                    try:
                        os.kill(os.getppid(), signal.SIGKILL)
                    except OSError:
                        pass
                time.sleep(0.5)
            """
            subprocess.Popen([sys.executable, "-c", _daemon, @@MARK@@], start_new_session=True,
                             stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        '''), ""),
    Attack("6 fork bomb", "start 1000 `sleep 30` processes, catch the failure, leave them running",
           PROCESSES, CH03, "attack-forkbomb", "after:attack-daemon", _HELD + "\n" + _code('''
            import subprocess

            _sleepers = []
            try:
                for _ in range(1000):
                    _sleepers.append(subprocess.Popen(["sleep", @@SLEEP@@]))
            except OSError as exc:
                raise Held(f"{len(_sleepers)} started, then {exc.strerror}")
            raise Escaped(f"{len(_sleepers)} processes started")
        '''), "Held"),
    Attack("10 a huge answer", "kf_predict returns a 200 MB string (to its first caller, the check)",
           PROCESSES, CH03, "predict", "replace", _code('''
            _calls = []


            def kf_predict(x_hat, P_hat, F, Q):
                """Return the prior (x_check (n,), P_check (n, n)) one step ahead."""
                _calls.append(1)
                if len(_calls) == 1:
                    return "x" * (200 * 2**20), P_hat
                return F @ x_hat, F @ P_hat @ F.T  # fix this
        '''), ""),
    Attack("10 a huge raw answer", "run_gnss_kf_gaps (the last check) sends the grader a 120 MB "
           "answer on the grading comm itself, past the kernel agent's own size check",
           PROCESSES, CH03, "gaps", "replace", _code('''
            def run_gnss_kf_gaps(t, y, sigma_a, sigma_gnss, sigma_v0=15.0):
                """Like run_gnss_kf; a row of y that is all NaN is a missing fix."""
                for comm in list(get_ipython().kernel.comm_manager.comms.values()):
                    comm.send({"answer": "x" * (120 * 2**20)})
                return np.zeros((len(t), 6)), np.zeros((len(t), 6, 6))
        '''), ""),

    # --- a_flood, chapter 01: a hang under a stream of output -------------------------------------
    Attack("8 output flood", "a thread displays something every 20 ms for ever",
           FLOOD, CH01, "attack-chatter", "after:setup", _code('''
            import threading
            import time

            from IPython.display import display


            def _keep_talking():
                while True:
                    display({"text/plain": "still thinking " * 40}, raw=True)
                    time.sleep(0.02)


            threading.Thread(target=_keep_talking, daemon=True).start()
        '''), ""),
    Attack("8 output flood", "... while circular_motion_model (called by the last check only) "
           "sleeps for ever",
           FLOOD, CH01, "challenge", "replace", _code('''
            import time


            def circular_motion_model(n, step_probs):
                """Return the transition matrix of a circular corridor of n cells."""
                time.sleep(10**6)
        '''), ""),
]


# ---------------------------------------------------------------------------------------
# building the class
# ---------------------------------------------------------------------------------------

def _cell(nb, cid):
    return next(c for c in nb.cells if c.get("id") == cid)


def _exercise(notebook: str):
    return nbformat.read(ROOT / "exercises" / notebook, as_version=4)


def _fill(source: str, targets: dict) -> str:
    for name, value in targets.items():
        source = source.replace(f"@@{name}@@", repr(value))
    assert "@@" not in source, source
    return source


def _apply(nb, attack: Attack, targets: dict) -> None:
    source = _fill(attack.source, targets)
    if attack.place == "replace":
        _cell(nb, attack.cell).source = source
        return
    where, anchor = attack.place.split(":")
    cell = new_code_cell(source)
    cell["id"] = attack.cell
    nb.cells.insert(nb.cells.index(_cell(nb, anchor)) + 1, cell)


def _class(targets: dict) -> dict[str, tuple[str, bytes]]:
    """Learner folder -> (notebook file name, the file's bytes)."""
    notebooks = {}
    for attack in ATTACKS:
        _, nb = notebooks.setdefault(attack.submission, (attack.notebook, _exercise(attack.notebook)))
        _apply(nb, attack, targets)
    out = {learner: (name, nbformat.writes(nb).encode()) for learner, (name, nb) in notebooks.items()}
    # the honest classmates hand in the solutions' code in their own words: without the region
    # markers, and with a comment of their own on each line they wrote (a copy, character for
    # character, of a chapter with many solution lines is flagged: tests/test_copied.py)
    out[CLASSMATE_01] = (CH01, _solved(CH01))
    out[CLASSMATE_03] = (CH03, _solved(CH03))
    return out


def _solved(notebook: str) -> bytes:
    nb = nbformat.read(ROOT / "solutions" / notebook, as_version=4)
    for cell in nb.cells:
        lines, in_solution = [], False
        for line in cell.source.splitlines():
            if BEGIN_RE.match(line) or STUB_RE.match(line):
                in_solution = bool(BEGIN_RE.match(line))
            elif END_RE.match(line):
                in_solution = False
            elif in_solution and line.strip() and not line.rstrip().endswith("\\"):
                lines.append(f"{line}  # my own line")
            elif not in_solution or line.strip():
                lines.append(line)
        cell.source = "\n".join(lines)
    return nbformat.writes(nb).encode()


# ---------------------------------------------------------------------------------------
# what is on the machine, before and after
# ---------------------------------------------------------------------------------------

def _pgrep(pattern: str) -> list[str]:
    out = subprocess.run(["pgrep", "-af", pattern], capture_output=True, text=True)
    return [line for line in out.stdout.splitlines() if str(os.getpid()) != line.split()[0]]


def _children(pid: int) -> set[int]:
    found = set()
    for path in glob.glob(f"/proc/{pid}/task/*/children"):
        with contextlib.suppress(OSError):
            found.update(int(p) for p in Path(path).read_text().split())
    return found


def _process_table() -> dict[int, tuple[int, str]]:
    """pid -> (parent pid, start time) of every process."""
    table = {}
    for stat in glob.glob("/proc/[0-9]*/stat"):
        try:
            text = Path(stat).read_text()
        except OSError:
            continue
        fields = text[text.rindex(")") + 2:].split()
        table[int(stat.split("/")[2])] = (int(fields[1]), fields[19])
    return table


def _descendants(pid: int) -> dict[int, str]:
    """pid -> start time of every process under ``pid``."""
    table = _process_table()
    found, todo = {}, [pid]
    while todo:
        parent = todo.pop()
        for child, (ppid, start) in table.items():
            if ppid == parent and child not in found:
                found[child] = start
                todo.append(child)
    return found


def _alive(processes: dict[int, str]) -> dict[int, str]:
    """The processes of ``processes`` still running (same pid, same start time)."""
    table = _process_table()
    alive = {}
    for pid, start in processes.items():
        if pid in table and table[pid][1] == start:
            with contextlib.suppress(OSError):
                alive[pid] = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode()[:200]
    return alive


def _git_status() -> set[str]:
    out = subprocess.run(["git", "status", "--porcelain", "--ignored", "kalman_course", "solutions"],
                         cwd=ROOT, capture_output=True, text=True)
    return set(out.stdout.splitlines())


def _leftovers() -> dict[str, set[str]]:
    """Kernel folders and control groups that outlive their kernel."""
    return {"kernel folders": set(glob.glob(os.path.join(tempfile.gettempdir(), "kalman-grade-*"))),
            "pids control groups": set(glob.glob("/sys/fs/cgroup/pids/kalman-course-*")
                                       + glob.glob("/sys/fs/cgroup/kalman-course-*"))}


def _core_pattern() -> str:
    try:
        return Path("/proc/sys/kernel/core_pattern").read_text()
    except OSError:
        return ""


def _forged_files() -> dict[str, Path]:
    """Where the attacks write outside the sandbox (what must not exist, or not hold MARK)."""
    package = ROOT / "kalman_course"
    return {
        "forged filters/bayes .pyc": Path(importlib.util.cache_from_source(str(package / "filters" / "bayes.py"))),
        "forged tooling/grading .pyc": Path(importlib.util.cache_from_source(str(package / "tooling" / "grading.py"))),
        "site-packages .pth": Path(site.getsitepackages()[0]) / f"zz_{MARK}.pth",
        "module in solutions/": ROOT / "solutions" / f"{MARK}.py",
        "module in tooling/": package / "tooling" / f"{MARK}.py",
    }


def _forged(path: Path) -> bool:
    try:
        return MARK.encode() in path.read_bytes()
    except OSError:
        return False


class _WorkerMemory:
    """The peak resident memory (VmHWM) of this process's children (the grading workers)."""

    def __init__(self):
        self.peak: dict[int, int] = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._sample, daemon=True)

    @staticmethod
    def rss(pid: int, field: str = "VmRSS") -> int:
        try:
            for line in Path(f"/proc/{pid}/status").read_text().splitlines():
                if line.startswith(field + ":"):
                    return int(line.split()[1]) * 1024
        except OSError:
            pass
        return 0

    def _sample(self):
        while not self._stop.wait(0.1):
            for pid in _children(os.getpid()):
                self.peak[pid] = max(self.peak.get(pid, 0), self.rss(pid, "VmHWM"))

    def __enter__(self):
        self.start = self.rss(os.getpid())
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()


def _results(path: Path) -> dict[str, dict]:
    data = json.loads(path.read_text(encoding="utf-8"))
    records = data["results"] if isinstance(data, dict) else data
    return {r["learner"]: r for r in records}


def _snapshot(out: Path) -> dict[str, bytes]:
    return {str(p.relative_to(out)): p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()}


@dataclass
class Run:
    code: int
    seconds: float
    console: str
    errors: str
    results: dict
    files: dict
    ended: float
    digests: dict
    before: dict
    after: dict
    survivors: dict
    memory: _WorkerMemory
    listeners: tuple
    root: Path
    out: Path


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """Grade the whole corpus with one `kalman-course grade --jobs 2` run, in the sandbox."""
    root, out = tmp_path_factory.mktemp("class"), tmp_path_factory.mktemp("out")
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen(8)
    listener.setblocking(False)
    abstract = socket.socket(socket.AF_UNIX)
    abstract.bind("\0" + MARK)
    abstract.listen(8)
    abstract.setblocking(False)
    targets = {"MARK": MARK, "SLEEP": SLEEP, "PORT": listener.getsockname()[1], "CLASS": str(root),
               "CLASSMATE": str(root / CLASSMATE_01 / CH01), "JSON": str(out / "g.json"),
               "CSV": str(out / "g.csv"), "FEEDBACK": str(out / "fb" / f"{PROCESSES}.md")}
    for learner, (name, data) in _class(targets).items():
        (root / learner).mkdir()
        (root / learner / name).write_bytes(data)
    digests = {p: hashlib.sha256(p.read_bytes()).hexdigest() for p in root.rglob("*.ipynb")}
    before = {"git": _git_status(), "site-packages": set(os.listdir(site.getsitepackages()[0])),
              "core_pattern": _core_pattern()}
    children = _children(os.getpid())
    console, errors = io.StringIO(), io.StringIO()
    start = time.monotonic()
    key = os.environ.get(KEY_VARIABLE)
    os.environ[KEY_VARIABLE] = f"key-{MARK}"  # the instructor's signing key, as the Actions recipe sets it
    try:
        with _WorkerMemory() as memory, contextlib.redirect_stdout(console), contextlib.redirect_stderr(errors):
            code = cli.main(["grade", str(root), "--release", str(ROOT / "exercises"), "--jobs", "2",
                             "--timeout", str(TIMEOUT), "--json", str(out / "g.json"), "--csv", str(out / "g.csv"),
                             "--feedback", str(out / "fb")])
        seconds = time.monotonic() - start
        if key is None:
            os.environ.pop(KEY_VARIABLE, None)
        else:
            os.environ[KEY_VARIABLE] = key
        ended = time.monotonic()
        survivors = {"attack processes": _pgrep(MARK), "sleepers": _pgrep(SLEEP.replace(".", r"\.")),
                     "children of the grader": sorted(_children(os.getpid()) - children)}
        files = _snapshot(out)
        after = {"git": _git_status(), "site-packages": set(os.listdir(site.getsitepackages()[0])),
                 "core_pattern": _core_pattern()}
        results = _results(out / "g.json") if (out / "g.json").exists() else {}
        yield Run(code, seconds, console.getvalue(), errors.getvalue(), results, files, ended, digests,
                  before, after, survivors, memory, (listener, abstract), root, out)
    finally:
        if os.environ.get(KEY_VARIABLE) == f"key-{MARK}":  # cli.main raised
            os.environ.pop(KEY_VARIABLE)
        listener.close()
        abstract.close()
        for path in _forged_files().values():  # an attack that got out leaves nothing for the next run
            if path.exists() and (MARK in path.name or _forged(path)):
                path.unlink()
        for pid in _pgrep(MARK) + _pgrep(SLEEP.replace(".", r"\.")):
            with contextlib.suppress(OSError, ValueError):
                os.kill(int(pid.split()[0]), signal.SIGKILL)


def _errors_of(result: dict, cell: str) -> list[str]:
    """The learner errors of one cell (each error line starts with the cell's label, which names its id)."""
    return [e for e in result["learner_errors"] if e.startswith(f"cell {cell}: ") or f"(id {cell}," in e]


def _by_check(result: dict) -> dict[str, int]:
    return {c["check"]: c["points"] for c in result["checks"]}


def _message(result: dict, check: str) -> str:
    return next(c["message"] for c in result["checks"] if c["check"] == check)


def _attack(cell: str, submission: str) -> Attack:
    return next(a for a in ATTACKS if a.cell == cell and a.submission == submission)


# ---------------------------------------------------------------------------------------
# the class run
# ---------------------------------------------------------------------------------------

def test_the_corpus_is_well_formed():
    """Every attacking cell is where its notebook runs it; every submission's cell ids are unique."""
    names = {}
    for learner, (name, data) in _class({k: "x" if k != "PORT" else 1 for k in
                                         ("MARK", "SLEEP", "PORT", "CLASS", "CLASSMATE", "JSON", "CSV",
                                          "FEEDBACK")}).items():
        nb = nbformat.reads(data.decode(), as_version=4)
        ids = [c["id"] for c in nb.cells]
        assert len(ids) == len(set(ids)), learner
        last_grader = max(i for i, c in enumerate(nb.cells) if c.get("id", "").startswith("grader-"))
        names[learner] = ids[:last_grader]  # cells after the last grader cell are never run
    for attack in ATTACKS:
        assert attack.cell in names[attack.submission], attack.tries


def test_every_notebook_is_graded_in_one_run_that_ends_in_time(run):
    assert run.results, f"no gradebook was written (exit {run.code}):\n{run.errors}\n{run.console[-3000:]}"
    assert set(run.results) == {a.submission for a in ATTACKS} | {CLASSMATE_01, CLASSMATE_03}
    assert run.seconds < 90, f"the class run took {run.seconds:.0f} s"
    assert run.code == 1, "the flood notebook timed out: the exit status must say a notebook did not run to the end"


@pytest.mark.parametrize("attack", [a for a in ATTACKS if a.error], ids=lambda a: f"{a.submission}-{a.cell}")
def test_each_attack_cell_ends_as_the_defence_makes_it(run, attack):
    """Held: the cell's own error says what stopped it (an Escaped says what it achieved)."""
    errors = _errors_of(run.results[attack.submission], attack.cell)
    assert errors and all(f"{attack.error}:" in e for e in errors), (
        f"{attack.tries}: expected a {attack.error} error, got {errors or 'none'}")


@pytest.mark.parametrize("attack", [a for a in ATTACKS if not a.error], ids=lambda a: f"{a.submission}-{a.cell}")
def test_attack_cells_that_must_run_without_error(run, attack):
    """These attacks only start something (a process, a flood): the start itself must work, or the
    tests that judge what it did prove nothing."""
    if attack.submission == FLOOD and attack.cell == "challenge":
        return  # defines the sleeping function: nothing to run
    assert not _errors_of(run.results[attack.submission], attack.cell), attack.tries


def test_attackers_earn_no_point(run):
    for learner in (INTRUDER, PROCESSES, FLOOD):
        r = run.results[learner]
        assert (r["points"], r["challenge_points"]) == (0, 0), (learner, _by_check(r))


def test_forged_files_do_not_exist(run):
    """Case 1: the .pyc files, the .pth, the modules in solutions/ and tooling/ were refused."""
    errors = _errors_of(run.results[INTRUDER], "attack-forge")
    assert any("exit status 5" in e for e in errors), f"not every write was refused: {errors}"
    for what, path in _forged_files().items():
        assert not (path.exists() and (MARK in path.name or _forged(path))), f"{what} written: {path}"


def test_the_package_tree_and_site_packages_are_unchanged(run):
    new = run.after["git"] - run.before["git"]
    assert not [line for line in new if MARK in line or "__pycache__" in line or "solutions" in line], new
    assert run.after["site-packages"] == run.before["site-packages"]


def test_the_solution_is_out_of_reach(run):
    """Case 2: the solution notebook is no file in the sandbox; its check gets 0."""
    assert _by_check(run.results[INTRUDER])["door_likelihood"] == 0


def test_classmates_are_out_of_sight_and_out_of_reach(run):
    """Case 3: no process of the grader in /proc, no class folder; the classmate's file unchanged
    byte for byte and graded in full."""
    assert _by_check(run.results[INTRUDER])["histogram_update"] == 0
    assert {p: hashlib.sha256(p.read_bytes()).hexdigest() for p in run.digests} == run.digests
    mate = run.results[CLASSMATE_01]
    assert (mate["points"], mate["possible"]) == (8, 8), [c["message"] for c in mate["checks"]]


def test_no_process_an_attack_started_outlives_the_run(run):
    """Cases 4 and 6: the daemon in a session of its own and the fork bomb's sleepers are gone
    when the run returns, and so is every process the run started here."""
    assert run.survivors == {"attack processes": [], "sleepers": [], "children of the grader": []}


def test_nobody_connected_to_the_grading_machine(run):
    """Case 5: the test's listening sockets (TCP on 127.0.0.1, an abstract Unix socket) were never reached."""
    for sock in run.listeners:
        with pytest.raises(BlockingIOError):
            sock.accept()


def _core_checks_ran(result: dict) -> dict[str, str]:
    """The core checks that did not run (a dead kernel or channel would leave them "not run")."""
    return {c["check"]: c["message"] for c in result["checks"] if not c["challenge"] and c["message"] == "not run"}


def test_the_fork_bomb_is_bounded_and_grading_goes_on(run):
    """Case 6: far fewer than 1000 processes started; the notebook's later checks still ran."""
    [error] = _errors_of(run.results[PROCESSES], "attack-forkbomb")
    started = int(re.search(r"Held: (\d+) started", error).group(1))
    assert started < 200, error
    assert _core_checks_ran(run.results[PROCESSES]) == {}


def test_memory_is_bounded_and_the_error_reported(run):
    """Case 7: the 8 GiB allocation raised MemoryError in the kernel; the notebook was graded on."""
    r = run.results[PROCESSES]
    assert _errors_of(r, "attack-memory")
    assert _core_checks_ran(r) == {}


def test_an_output_flood_does_not_stop_the_deadline(run):
    """Case 8: a function that sleeps for ever while a thread displays every 20 ms times out
    within the check's deadline (and the interrupt's grace); the checks before it are graded."""
    r = run.results[FLOOD]
    assert r["status"] == grading.TIMED_OUT, (r["status"], r.get("detail"))
    assert "TimeoutError" in _message(r, "corridor_motion_model"), _message(r, "corridor_motion_model")
    assert _core_checks_ran(r) == {}
    line = next(line for line in run.console.splitlines() if f"] {FLOOD}:" in line)
    seconds = float(re.search(r"\(([\d.]+) s\)$", line).group(1))
    assert seconds < TIMEOUT + INTERRUPT_GRACE + 5, line


def test_killing_the_worker_from_the_kernel_reaches_nothing(run):
    """Case 9: the kernel's kill attempts hit nothing of the grader: no notebook's worker died,
    the attacker's notebook kept its kernel to the end."""
    statuses = {learner: r["status"] for learner, r in run.results.items()}
    assert grading.WORKER_DIED not in statuses.values(), statuses
    assert statuses[PROCESSES] != grading.KERNEL_DIED
    assert _core_checks_ran(run.results[PROCESSES]) == {}


def test_huge_answers_fail_their_check_with_a_clear_message(run):
    """Case 10: a 200 MB answer, returned or sent raw on the comm, fails its check with a message
    that says why (in MiB), and the notebook is graded to the end."""
    r = run.results[PROCESSES]
    for check in ("kf_predict", "gnss_kf_gaps"):
        assert _by_check(r)[check] == 0
        assert "MiB" in _message(r, check), (check, _message(r, check))
    assert r["status"] == grading.GRADED, (r["status"], r.get("detail"))


def test_the_grading_worker_does_not_balloon(run):
    """Case 10: answers are bounded while they stream in, so no worker grows by much more than
    the largest answer accepted (80 MiB): not by the 1.5 GB of messages a kernel publishes at once."""
    growth = {pid: peak - run.memory.start for pid, peak in run.memory.peak.items()}
    assert growth, "no grading worker was seen"
    assert max(growth.values()) < 512 * MiB, {pid: f"{g / MiB:+.0f} MiB" for pid, g in growth.items()}


def test_the_machine_kernel_settings_are_unchanged(run):
    """The attack on kernel.core_pattern (see its Held/Escaped above) left the machine's value as it was."""
    assert run.after["core_pattern"] == run.before["core_pattern"]


def test_honest_classmates_get_every_point_unflagged(run):
    """Case 14: the solutions, handed in as they are, earn every point, core and challenge."""
    for learner, notebook in ((CLASSMATE_01, CH01), (CLASSMATE_03, CH03)):
        r = run.results[learner]
        graders = _exercise(notebook).metadata["kalman_course"]["graders"]
        assert r["status"] == grading.GRADED, (learner, r.get("detail"))
        assert (r["points"] + r["challenge_points"], r["possible"] + r["challenge_possible"]) == (
            sum(graders.values()), sum(graders.values())), [c["message"] for c in r["checks"]]
        assert (r["flags"], r["tampered"], r["readded"], r["learner_errors"]) == ([], [], [], []), learner


def test_the_gradebook_files_say_what_the_grade_computed(run):
    """The console's progress lines, the JSON, the CSV and the feedback agree, learner by learner."""
    graded = {learner: (r["status"], r["points"], r["possible"]) for learner, r in run.results.items()}
    progress = {}
    for line in run.console.splitlines():
        m = re.match(r"^\[\d+/\d+\] (\S+): .*: (.+), (\d+)/(\d+)(?: \+\d+/\d+)? points \([\d.]+ s\)$", line)
        if m:
            progress[m.group(1)] = (m.group(2), int(m.group(3)), int(m.group(4)))
    assert progress == graded
    rows = {row["learner"]: row for row in csv.DictReader(io.StringIO(run.files["g.csv"].decode()))}
    assert {learner: (row["status"], int(row["points"]), int(row["possible"])) for learner, row in rows.items()} \
        == graded
    feedback = {name: text.decode() for name, text in run.files.items() if name.startswith("fb/")}
    assert len(feedback) == len(graded), sorted(feedback)
    mine = [text for text in feedback.values() if "b\\_processes" in text or PROCESSES in text]
    assert len(mine) == 1 and "0/12 points" in mine[0] and "12/12" not in mine[0], mine


def _kernel_folders_holding(text: str) -> list[str]:
    """Kernel folders (of any run) whose files hold ``text``: left behind by the run that wrote it."""
    found = []
    for folder in glob.glob(os.path.join(tempfile.gettempdir(), "kalman-grade-*")):
        for path in Path(folder).rglob("*"):
            with contextlib.suppress(OSError):
                if path.is_file() and text.encode() in path.read_bytes():
                    found.append(folder)
                    break
    return found


def test_no_kernel_folder_of_the_run_is_left_behind(run):
    """Every kernel's folder (its channels, the learner's notebook copy) goes with its kernel."""
    assert _kernel_folders_holding(MARK) == []


def test_a_closed_kernel_leaves_no_folder_and_no_control_group():
    """One sandboxed kernel, started and closed: its folder and (as root) its pids control group
    are gone (a class run makes one of each per notebook, and one per worker's spare kernel)."""
    from kalman_course.tooling.kernel_session import KernelSession
    from kalman_course.tooling.sandbox import open_sandbox

    session = KernelSession(10, open_sandbox())
    try:
        session.wait_until_ready()
    finally:
        session.close()
    group = getattr(getattr(session, "_cgroup", None), "path", None)
    assert not os.path.exists(session.folder)
    assert group is None or not group.exists(), f"{group} left behind (pids.current " \
        f"{(group / 'pids.current').read_text().strip()}, {len(_leftovers()['pids control groups'])} such groups)"


# ---------------------------------------------------------------------------------------
# beside the class run
# ---------------------------------------------------------------------------------------

def _kill_own_worker(item):
    """``_grade_one`` of a worker that dies (SIGKILL) on the notebook named die.ipynb."""
    (source, learner) = item[0]
    if str(source).endswith("die.ipynb"):
        os.kill(os.getpid(), signal.SIGKILL)
    return grading.NotebookResult(str(source), learner, status=grading.GRADED)


def test_a_worker_that_dies_costs_only_its_notebook(monkeypatch, tmp_path):
    """Case 9: a worker killed while it grades one notebook makes that notebook "grading worker
    died"; the others are graded and the results come back (the workers fork after the patch)."""
    monkeypatch.setattr(grading, "_grade_one", _kill_own_worker)
    monkeypatch.setattr(grading, "_worker_start", lambda sandbox: None)  # no kernel started ahead
    submissions = [(tmp_path / "a.ipynb", "ann"), (tmp_path / "die.ipynb", "ben"), (tmp_path / "c.ipynb", "cat")]
    results = grading.grade_many(submissions, {}, jobs=2)
    assert [(r.learner, r.status) for r in results] == [
        ("ann", grading.GRADED), ("ben", grading.WORKER_DIED), ("cat", grading.GRADED)]
    assert "signal 9" in results[1].detail, results[1].detail


def test_no_sandbox_is_said_on_the_console(tmp_path, capsys):
    """Case 13: --no-sandbox prints its note (a notebook of no released chapter: no kernel starts)."""
    (tmp_path / "cls" / "eve").mkdir(parents=True)
    nbformat.write(new_notebook(cells=[new_code_cell("x = 1")]), tmp_path / "cls" / "eve" / "99_mystery.ipynb")
    code = cli.main(["grade", str(tmp_path / "cls"), "--release", str(ROOT / "exercises"), "--no-sandbox",
                     "--jobs", "1", "--json", str(tmp_path / "g.json")])
    out = capsys.readouterr().out
    assert "note: --no-sandbox" in out and "not sandboxed" in out, out
    assert code == 1  # the notebook has no release: it did not run to the end
    assert json.loads((tmp_path / "g.json").read_text())["run"]["sandbox"] == "none (--no-sandbox)"


def test_the_gradebook_says_which_sandbox_graded(run):
    sandbox = json.loads((run.out / "g.json").read_text())["run"]["sandbox"]
    assert sandbox.startswith("bubblewrap ") and "128 processes" in sandbox, sandbox


def test_a_class_is_not_graded_without_bubblewrap(tmp_path, monkeypatch, capsys):
    """Without bwrap a class run refuses to start (no gradebook), while a learner grading their
    own notebook is told in one line that it runs unsandboxed."""
    (tmp_path / "cls" / "eve").mkdir(parents=True)
    nbformat.write(new_notebook(cells=[new_code_cell("x = 1")]), tmp_path / "cls" / "eve" / "99_mystery.ipynb")
    nbformat.write(new_notebook(cells=[new_code_cell("x = 1")]), tmp_path / "99_mine.ipynb")
    (tmp_path / "bin").mkdir()
    monkeypatch.setenv("PATH", str(tmp_path / "bin"))  # a machine without bubblewrap
    code = cli.main(["grade", str(tmp_path / "cls"), "--release", str(ROOT / "exercises"), "--jobs", "1",
                     "--json", str(tmp_path / "g.json")])
    said = capsys.readouterr()
    assert code == 2 and "needs the sandbox" in said.err, (code, said.err)
    assert not (tmp_path / "g.json").exists()
    cli.main(["grade", str(tmp_path / "99_mine.ipynb"), "--release", str(ROOT / "exercises")])
    notes = [line for line in capsys.readouterr().out.splitlines() if "without a sandbox" in line]
    assert len(notes) == 1 and notes[0].startswith("note:"), notes


_SEALED = '''
import json, sys
from kalman_course.tooling import cli, sealed

sealed.preload()
cli.build_parser()  # what `kalman-course` does before grading starts
before = set(sys.modules)
code = cli.main(sys.argv[1:])
print("NEW-MODULES " + json.dumps(sorted(set(sys.modules) - before)))
sys.exit(code)
'''


def test_a_sealed_grading_process_imports_nothing_once_kernels_run(tmp_path):
    """Case 12: after preload, grading a class (sandboxed, one job: all in this process) imports
    no module: what a learner could have written is never read by the grader."""
    (tmp_path / "cls" / "dan").mkdir(parents=True)
    (tmp_path / "cls" / "eve").mkdir(parents=True)
    shutil.copy(ROOT / "exercises" / CH03, tmp_path / "cls" / "dan" / CH03)
    for solution in sorted((ROOT / "solutions").glob("[0-9][0-9]_*.ipynb")):  # every chapter's checks
        shutil.copy(solution, tmp_path / "cls" / "eve" / solution.name)
    (tmp_path / "pyc").mkdir()
    out = subprocess.run(
        [sys.executable, "-I", "-B", "-X", f"pycache_prefix={tmp_path / 'pyc'}", "-c", _SEALED, "grade",
         str(tmp_path / "cls"), "--release", str(ROOT / "exercises"), "--jobs", "1", "--timeout", "60",
         "--json", str(tmp_path / "g.json"), "--csv", str(tmp_path / "g.csv"), "--feedback", str(tmp_path / "fb")],
        capture_output=True, text=True, timeout=300, cwd=tmp_path)
    line = next((line for line in out.stdout.splitlines() if line.startswith("NEW-MODULES ")), None)
    assert line is not None, out.stderr[-3000:]
    assert _results(tmp_path / "g.json")["dan"]["status"] == grading.GRADED
    new = json.loads(line.removeprefix("NEW-MODULES "))
    roots = sorted({name.split(".")[0] for name in new})
    assert not new, f"{len(new)} modules imported while grading (top-level: {roots}): {new[:40]}"
    assert not list((tmp_path / "pyc").rglob("*")), "bytecode was written"


_SITECUSTOMIZE = '''
import atexit, os, sys
with open(os.environ["KC_START_LOG"], "a") as fh:
    fh.write(f"start {os.getpid()} isolated={sys.flags.isolated}\\n")
atexit.register(lambda: open(os.environ["KC_START_LOG"], "a").write(f"exit {os.getpid()}\\n"))
'''


def _script() -> str:
    script = Path(sysconfig.get_path("scripts")) / "kalman-course"
    return str(script) if script.exists() else shutil.which("kalman-course")


def test_the_shell_command_grades_in_a_sealed_interpreter(tmp_path):
    """From the shell, `kalman-course grade` re-runs itself with -I -B: a sitecustomize on
    PYTHONPATH runs in the first interpreter only, which never exits on its own (it became the
    sealed one); the class is graded and its gradebook written; no bytecode folder is left."""
    (tmp_path / "cls" / "fay").mkdir(parents=True)
    shutil.copy(ROOT / "solutions" / CH01, tmp_path / "cls" / "fay" / CH01)
    (tmp_path / "hook").mkdir()
    (tmp_path / "hook" / "sitecustomize.py").write_text(_SITECUSTOMIZE)
    log = tmp_path / "start.log"
    prefixes = set(glob.glob(os.path.join(tempfile.gettempdir(), "kalman-course-pyc-*")))
    env = {**os.environ, "PYTHONPATH": str(tmp_path / "hook"), "KC_START_LOG": str(log)}
    out = subprocess.run([_script(), "grade", str(tmp_path / "cls"), "--release", str(ROOT / "exercises"),
                          "--jobs", "1", "--json", str(tmp_path / "g.json")],
                         capture_output=True, text=True, timeout=300, cwd=tmp_path, env=env)
    assert out.returncode == 0, out.stderr[-3000:]
    r = _results(tmp_path / "g.json")["fay"]
    assert (r["status"], r["points"], r["possible"]) == (grading.GRADED, 8, 8)
    lines = log.read_text().splitlines()
    assert len(lines) == 1 and lines[0].endswith("isolated=0"), lines
    assert set(glob.glob(os.path.join(tempfile.gettempdir(), "kalman-course-pyc-*"))) == prefixes


def test_ctrl_c_stops_a_class_run_within_two_seconds(tmp_path):
    """Case 11: SIGINT to the run's process group (a terminal's Ctrl-C) while its kernels grade:
    exit 130 within 2 s, "interrupted" said, no gradebook, no process of the run left, and no
    kernel folder (each holds a copy of a learner's notebook)."""
    mark = f"{MARK}-ctrl-c"
    for name in ("ann", "ben", "cat", "dan"):
        (tmp_path / "cls" / name).mkdir(parents=True)
        nb = _exercise(CH01)
        extra = new_code_cell(f"# {mark}: my notes\nimport time\ntime.sleep(1)")
        extra["id"] = "my-notes"
        nb.cells.insert(1, extra)
        nbformat.write(nb, tmp_path / "cls" / name / CH01)
    stderr = (tmp_path / "stderr.txt").open("w+")
    proc = subprocess.Popen([_script(), "grade", str(tmp_path / "cls"), "--release", str(ROOT / "exercises"),
                             "--jobs", "2", "--timeout", "60", "--json", str(tmp_path / "g.json")],
                            stdout=subprocess.PIPE, stderr=stderr, text=True, start_new_session=True,
                            cwd=tmp_path)
    watchdog = threading.Timer(120, lambda: os.killpg(proc.pid, signal.SIGKILL))
    watchdog.start()
    try:
        seen = []
        for line in proc.stdout:
            seen.append(line)
            if line.startswith("grading "):
                break
        assert seen and seen[-1].startswith("grading "), "".join(seen)
        time.sleep(3)  # the workers' kernels start and run the first notebooks' cells
        processes = _descendants(proc.pid)
        assert len(processes) >= 4, f"the run has no workers and kernels to end: {processes}"
        sent = time.monotonic()
        os.killpg(proc.pid, signal.SIGINT)
        rest = proc.stdout.read()
        code = proc.wait(timeout=30)
        took = time.monotonic() - sent
    finally:
        watchdog.cancel()
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        stderr.seek(0)
        said = stderr.read()
        stderr.close()
    assert code == 130, (code, said[-2000:], rest[-2000:])
    assert took < 2.0, f"it took {took:.1f} s to stop"
    assert "interrupted" in said, said[-2000:]
    assert not (tmp_path / "g.json").exists()
    time.sleep(0.5)
    assert _alive(processes) == {}
    assert _kernel_folders_holding(mark) == []


def test_the_gradebook_is_never_rewritten_after_the_run(run):
    """Case 4: more than five seconds after the run (the daemon sleeps three), every gradebook
    file is byte for byte what the run wrote, and no attack process is alive."""
    time.sleep(max(0.0, run.ended + 5.5 - time.monotonic()))
    assert _snapshot(run.out) == run.files
    assert _pgrep(MARK) == [] and _pgrep(SLEEP.replace(".", r"\.")) == []
