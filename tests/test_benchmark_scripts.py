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
