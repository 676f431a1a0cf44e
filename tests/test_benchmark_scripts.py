"""The benchmark scripts run from the repository (they import the package, never the reverse)."""

import subprocess
import sys

import pytest


@pytest.mark.slow
def test_eskf_speed_ab_times_two_trees_and_cleans_up(root):
    def worktrees():
        return subprocess.run(["git", "worktree", "list"], cwd=root, capture_output=True, text=True).stdout

    before = worktrees()
    out = subprocess.run([sys.executable, "benchmarks/eskf_speed_ab.py", "HEAD", "--pairs", "1", "--runs", "1"],
                         cwd=root, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert "pair 1: old" in out.stdout and "median ratio new/old" in out.stdout
    assert worktrees() == before                    # its temporary checkout is gone


def test_eskf_speed_ab_rejects_zero_pairs(root):
    out = subprocess.run([sys.executable, "benchmarks/eskf_speed_ab.py", "HEAD", "--pairs", "0"],
                         cwd=root, capture_output=True, text=True, timeout=60)
    assert out.returncode == 2 and "--pairs and --runs must be at least 1" in out.stderr


@pytest.mark.slow
def test_check_times_lists_every_check_of_this_checkout(root):
    from kalman_course import checks

    out = subprocess.run([sys.executable, "benchmarks/check_times.py", "--repeats", "1"],
                         cwd=root, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    rows = [line.split("|")[1].strip() for line in out.stdout.splitlines()[2:] if line.startswith("|")]
    assert sorted(rows) == sorted(checks.registered())


def test_check_times_rejects_zero_repeats(root):
    out = subprocess.run([sys.executable, "benchmarks/check_times.py", "--repeats", "0"],
                         cwd=root, capture_output=True, text=True, timeout=60)
    assert out.returncode == 2 and "must be at least 1" in out.stderr


def test_class_throughput_builds_the_class_and_finds_each_trees_command(root, tmp_path):
    sys.path.insert(0, str(root / "benchmarks"))
    try:
        import class_throughput
    finally:
        sys.path.remove(str(root / "benchmarks"))
    count = class_throughput.make_class(root, tmp_path / "class")
    per_learner = len(list((root / "exercises").glob("[0-9][0-9]_*.ipynb"))) + \
        len(list((root / "solutions").glob("[0-9][0-9]_*.ipynb")))
    assert count == 2 * per_learner == len(list((tmp_path / "class").rglob("*.ipynb")))
    assert class_throughput._entry_point(root) == ("kalman_course.tooling.cli", "main")
    old = tmp_path / "old"
    old.mkdir()
    (old / "pyproject.toml").write_text('[project.scripts]\nkalman-course = "kalman_course.cli:main"\n')
    assert class_throughput._entry_point(old) == ("kalman_course.cli", "main")


def test_class_throughput_rejects_zero_pairs(root):
    out = subprocess.run([sys.executable, "benchmarks/class_throughput.py", "HEAD", "--pairs", "0"],
                         cwd=root, capture_output=True, text=True, timeout=60)
    assert out.returncode == 2 and "--pairs and --jobs must be at least 1" in out.stderr
