"""The grading run's own machinery, without kernels: the worker pool, the sealed process's
fingerprint and orphan reaper, the refusal to grade a class unsandboxed."""

import os
import signal
import subprocess
import sys
import time

import pytest

from kalman_course.tooling import cli, sandbox, sealed
from kalman_course.tooling.workers import WorkerPool


def _work(item):
    if item == "die":
        os.kill(os.getpid(), signal.SIGKILL)
    if item == "exit":
        os._exit(3)
    return item.upper()


def test_a_worker_that_dies_costs_only_its_own_item():
    items = ["a", "die", "b", "exit", "c", "d"]
    with WorkerPool(2, _work, lambda: None, lambda: None) as pool:
        got = dict(pool.map(items, died=lambda item, why: f"died: {item} ({why})"))
    assert got == {0: "A", 1: "died: die (killed by signal 9)", 2: "B", 3: "died: exit (exit status 3)",
                   4: "C", 5: "D"}


def test_every_worker_is_stopped_and_runs_its_stop_hook(tmp_path):
    marks = tmp_path / "stopped"
    marks.mkdir()

    def stop():
        (marks / str(os.getpid())).touch()

    with WorkerPool(2, _work, lambda: None, stop) as pool:
        workers = []
        for _ in pool.map(["a", "b", "c"], died=None):
            workers = [w.process for w in pool._workers]
    assert len(list(marks.iterdir())) == 2
    assert all(not p.is_alive() for p in workers)


def _slow(item):
    time.sleep(60)


def test_an_interrupted_pool_ends_its_workers_within_two_seconds(tmp_path):
    marks = tmp_path / "stopped"
    marks.mkdir()
    pool = WorkerPool(2, _slow, lambda: None, lambda: (marks / str(os.getpid())).touch())
    results = pool.map(["a", "b", "c"], died=None)
    # the first item is handed out, then Ctrl-C arrives while the parent waits
    signal.setitimer(signal.ITIMER_REAL, 0.5)
    previous = signal.signal(signal.SIGALRM, lambda *a: (_ for _ in ()).throw(KeyboardInterrupt()))
    start = time.monotonic()
    try:
        with pytest.raises(KeyboardInterrupt), pool:
            next(results)
    finally:
        signal.signal(signal.SIGALRM, previous)
    assert time.monotonic() - start < 2.5
    assert pool._workers == []
    assert len(list(marks.iterdir())) == 2  # each worker ran its stop hook (its kernels ended)


def test_the_fingerprint_names_added_changed_and_removed_files(tmp_path, monkeypatch):
    files = {name: tmp_path / name for name in ("a.py", "b.pth", "c.pyc")}
    for path in files.values():
        path.write_text("x")
    monkeypatch.setattr(sealed, "_watched_files", lambda: sorted(str(p) for p in tmp_path.iterdir()))
    fingerprint = sealed.Fingerprint()
    assert fingerprint.changes() == []
    files["b.pth"].write_text("import evil")
    files["c.pyc"].unlink()
    (tmp_path / "d.pth").write_text("import evil")
    assert fingerprint.changes() == [f"added: {tmp_path / 'd.pth'}", f"changed: {files['b.pth']}",
                                     f"removed: {files['c.pyc']}"]


def test_the_fingerprint_watches_the_package_and_the_start_up_files():
    watched = sealed._watched_files()
    assert str(sealed.PACKAGE / "tooling" / "grading.py") in watched
    assert any(path.endswith(".pth") for path in watched)  # the editable install's own, at least


def test_the_reaper_ends_a_process_that_left_its_session():
    with sealed.OrphanReaper() as reaper:
        # a child that starts a grandchild in a session of its own and exits: the grandchild is adopted
        subprocess.run([sys.executable, "-c", "import subprocess, sys; subprocess.Popen([sys.executable, '-c', "
                        "'import time; time.sleep(60)'], start_new_session=True)"], check=True)
        time.sleep(0.2)
        assert len(sealed._children() - reaper._before) == 1
        assert reaper.end_adopted() == 1
        assert sealed._children() - reaper._before == set()


def test_a_class_is_not_graded_without_the_sandbox_unless_asked(tmp_path, monkeypatch, capsys):
    from conftest import ROOT

    monkeypatch.setattr(sandbox, "find_bwrap", lambda: None)
    folder = tmp_path / "class" / "alice"
    folder.mkdir(parents=True)
    (folder / "01_bayes_rule.ipynb").write_bytes((ROOT / "exercises" / "01_bayes_rule.ipynb").read_bytes())
    code = cli.main(["grade", str(tmp_path / "class"), "--release", str(ROOT / "exercises"),
                     "--json", str(tmp_path / "g.json")])
    err = capsys.readouterr().err
    assert code == 2 and "grading a class needs the sandbox" in err and "apt-get install bubblewrap" in err
    assert not (tmp_path / "g.json").exists()


def test_a_learner_grading_alone_is_told_there_is_no_sandbox(monkeypatch, capsys):
    monkeypatch.setattr(sandbox, "find_bwrap", lambda: None)

    class Args:
        no_sandbox = False

    assert cli._open_sandbox(Args(), grading_a_class=False) is None
    out = capsys.readouterr().out
    assert out.count("\n") == 1 and out.startswith("note: grading your own notebook without a sandbox")


def test_the_limits_are_described_as_readme_states_them():
    from conftest import ROOT

    text = sandbox.Limits().describe()
    assert text.startswith("4 GiB address space per process, 128 processes, 1800 CPU s per process")
    readme = " ".join((ROOT / "README.md").read_text().split())
    assert "4 GiB of address space per process, 128 processes" in readme
    assert "1800 CPU seconds per process, files up to 64 MiB, a 256 MiB HOME and a 256 MiB `/tmp`" in readme


def test_a_link_to_a_classmates_notebook_or_folder_is_not_graded_as_ones_own(tmp_path):
    from conftest import ROOT

    from kalman_course.tooling import grading

    (tmp_path / "alice").mkdir()
    (tmp_path / "alice" / "01_bayes_rule.ipynb").write_bytes((ROOT / "solutions" / "01_bayes_rule.ipynb").read_bytes())
    (tmp_path / "bob").mkdir()
    (tmp_path / "bob" / "01_bayes_rule.ipynb").symlink_to(tmp_path / "alice" / "01_bayes_rule.ipynb")
    (tmp_path / "carol").symlink_to(tmp_path / "alice", target_is_directory=True)
    found = cli._expand_notebooks([str(tmp_path)], recursive=True)
    assert found == [tmp_path / "alice" / "01_bayes_rule.ipynb", tmp_path / "bob" / "01_bayes_rule.ipynb"]
    result = grading.grade_notebook(found[1], {}, learner="bob")
    assert result.status == grading.NOT_A_NOTEBOOK and "symbolic link" in result.detail


def test_a_notebook_too_large_to_read_is_refused_unread(tmp_path, monkeypatch):
    from kalman_course.tooling import grading

    path = tmp_path / "01_bayes_rule.ipynb"
    with open(path, "wb") as fh:
        fh.truncate(grading.MAX_NOTEBOOK + 1)  # sparse: no disk used
    monkeypatch.setattr(grading, "read_notebook", lambda path: pytest.fail("the notebook was read"))
    result = grading.grade_notebook(path, {})
    assert result.status == grading.NOT_A_NOTEBOOK and "more than the 100 MiB" in result.detail


def test_control_groups_of_a_unified_hierarchy_are_one_group(tmp_path):
    # cgroup v2: both controllers in one hierarchy, one group holds the sandbox
    (tmp_path / "cgroup.controllers").write_text("pids memory\n")
    groups = sandbox.ControlGroups({"pids": tmp_path, "memory": tmp_path}, sandbox.Limits())
    [path] = groups.paths
    assert (path / "pids.max").read_text() == "128" and (path / "memory.max").read_text() == str(4 * 2**30)
    prefix = groups.enter_prefix()
    assert prefix[3:] == [str(path / "cgroup.procs")] and "shift 0" in prefix[2]
    for name in ("pids.max", "memory.max"):
        (path / name).unlink()  # a real group's files go with it
    groups.remove()
    assert not path.exists()
