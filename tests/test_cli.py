"""The command line as a user meets it: plain help, checked options, one-line errors."""

import subprocess
import sys

import pytest

from kalman_course.tooling import cli, gradebook, grading

from conftest import ROOT

SUBCOMMANDS = [[], ["execute"], ["build"], ["grade"], ["merge"], ["export"], ["bench"], ["data"], ["data", "build"]]


@pytest.mark.parametrize("words", SUBCOMMANDS, ids=lambda w: " ".join(w) or "top")
def test_help_texts_have_no_markup(words, capsys):
    with pytest.raises(SystemExit) as done:
        cli.main([*words, "--help"])
    assert done.value.code == 0
    text = capsys.readouterr().out
    assert "usage: kalman-course" in text and "`" not in text and "``" not in text


@pytest.mark.parametrize("argv, message", [
    (["grade", "--jobs", "0"], "argument --jobs: expected a number greater than 0, got '0'"),
    (["grade", "--timeout", "-1"], "argument --timeout: expected a number greater than 0, got '-1'"),
    (["grade", "--timeout", "soon"], "argument --timeout: expected a number greater than 0, got 'soon'"),
    (["grade", "--shard", "3/2"], "argument --shard: expected K/N with 1 <= K <= N, got '3/2'"),
    (["grade", "--shard", "half"], "argument --shard: expected K/N (shard K of N), got 'half'"),
    (["execute", "x.ipynb", "--timeout", "0"], "argument --timeout: expected a number greater than 0, got '0'"),
    (["grade", "--seed", "-3"], "argument --seed: expected an integer in [0, 2**63), got '-3'"),
    (["grade", "--seed", str(2**63)], "argument --seed: expected an integer in [0, 2**63)"),
    (["grade", "--seed", "0x10"], "argument --seed: expected an integer, got '0x10'"),
])
def test_option_values_are_checked_with_a_clear_message(argv, message, capsys):
    with pytest.raises(SystemExit) as done:
        cli.main(argv)
    assert done.value.code == 2 and message in capsys.readouterr().err


def test_a_shard_without_a_seed_is_refused_with_one_to_use(tmp_path, capsys):
    (tmp_path / "class").mkdir()
    assert cli.main(["grade", str(tmp_path / "class"), "--release", str(ROOT / "exercises"), "--shard", "1/2",
                     "--no-sandbox"]) == 2
    err = capsys.readouterr().err
    assert "pass every shard the same --seed (for instance --seed " in err


def test_outside_the_repository_errors_are_one_line_not_tracebacks(tmp_path):
    out = subprocess.run([sys.executable, "-m", "kalman_course.tooling.cli", "build", "--check"],
                         cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert out.returncode == 2 and "Traceback" not in out.stderr
    assert out.stderr.startswith("error: ") and "solutions" in out.stderr


def test_a_missing_file_is_named_and_grading_yourself_writes_feedback_md(tmp_path, capsys):
    missing = tmp_path / "03_kalman_filter.ipynb"
    code = cli.main(["grade", str(missing), "--feedback", str(tmp_path / "fb")])
    out = capsys.readouterr().out
    assert code == 1 and f"no such file: {missing}" in out
    said = [line for line in out.splitlines() if not line.startswith("note: ")]  # the sandbox's note may come first
    assert said[0].startswith("grading 1 notebook(s)")      # said before any work
    assert [p.name for p in (tmp_path / "fb").iterdir()] == ["feedback.md"]


def test_grading_in_process_leaves_the_run_seed_and_the_hint_tier_as_they_were(tmp_path, capsys):
    # a grade draws the checks' inputs from its run seed at tier 1 (or 2 with --all-hints); a
    # test or a notebook that calls cli.main and goes on must find the fixed cases again
    from kalman_course.checks import cases, hints
    before = (cases.run_seed(), hints.settings())
    for extra in ([], ["--all-hints"]):
        cli.main(["grade", str(tmp_path / "03_kalman_filter.ipynb"), "--seed", "12345", *extra])
        assert (cases.run_seed(), hints.settings()) == before
    capsys.readouterr()


def test_every_hint_can_be_listed_under_the_table():
    checks = [grading.CheckResult("kf_predict", "g1", 0, 2, "CheckFailed: kf_predict: P is wrong. Hint: add Q\nmore"),
              grading.CheckResult("kf_gain", "g2", 2, 2),
              grading.CheckResult("kf_update", "g3", 0, 3, "CheckFailed: kf_update: x is wrong")]
    result = grading.NotebookResult("a/03_kalman_filter.ipynb", "alice", "03", checks=checks)
    short, full = gradebook.format_table([result]), gradebook.format_table([result], every_hint=True)
    assert "kf_update: x is wrong" not in short
    assert full.endswith("03_kalman_filter.ipynb (alice):\n  kf_predict: P is wrong. Hint: add Q\n"
                         "  kf_update: x is wrong")
