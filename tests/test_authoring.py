"""The exercise builder: fix-region parsing, deterministic builds, sync with solutions/,
and what a released exercise must (its first screen, a whole step to write) and must not
(the reference's outputs) contain."""

import hashlib
import re
import shutil

import nbformat
import pytest
from nbformat.v4 import new_code_cell, new_notebook

from kalman_course.tooling import authoring
from kalman_course.tooling.authoring import AuthoringError

from conftest import ROOT

SOLUTIONS = sorted((ROOT / "solutions").glob("[0-9][0-9]_*.ipynb"))
EXERCISES = sorted((ROOT / "exercises").glob("[0-9][0-9]_*.ipynb"))

REGION = """def f(x):
    # BEGIN SOLUTION f_check
    y = x + 1
    # STUB
    # y = x - 1  # fix this
    # END SOLUTION
    return y"""


def _grader(check="f_check", points=2, **extra):
    cell = new_code_cell(f"checks.{check}(f)")
    cell.metadata["tags"] = ["grader"]
    cell.metadata["kalman_course"] = {"check": check, "points": points, **extra}
    return cell


def _solution(tmp_path, source=REGION, graders=None, name="07_demo.ipynb"):
    nb = new_notebook(cells=[new_code_cell(source), *(graders if graders is not None else [_grader()])])
    for i, c in enumerate(nb.cells):
        c["id"] = f"cell{i}"
    path = tmp_path / name
    nbformat.write(nb, path)
    return path


def test_render_replaces_region_with_uncommented_stub(tmp_path):
    nb = nbformat.read(_solution(tmp_path), as_version=4)
    assert authoring.render(nb).cells[0].source == (
        "def f(x):\n    y = x - 1  # fix this\n    return y")
    assert authoring.render(nb, set()).cells[0].source == "def f(x):\n    y = x + 1\n    return y"
    [stub] = authoring.list_stubs(nb)
    assert (stub.stub_id, stub.check) == ("cell0:0", "f_check")


def test_a_multi_line_region_becomes_a_multi_line_stub(tmp_path):
    source = """def step(x, P):
    # BEGIN SOLUTION f_check
    x = 2 * x
    P = 4 * P
    return x, P
    # STUB
    # # fix this: the whole step, mean and covariance
    # return x, P
    # END SOLUTION"""
    ex = authoring.build_exercise(_solution(tmp_path, source))
    assert ex.cells[0].source == "def step(x, P):\n    # fix this: the whole step, mean and covariance\n    return x, P"


def test_exercise_gets_grader_ids_tags_and_chapter(tmp_path):
    ex = authoring.build_exercise(_solution(tmp_path))
    code, grader = ex.cells
    assert grader["id"] == "grader-f_check"
    assert "nbval-check-output" in grader.metadata["tags"]
    assert code.metadata["tags"] == ["nbval-ignore-output"]
    assert ex.metadata["kalman_course"]["chapter"] == "07"
    assert ex.metadata["kalman_course"]["graders"] == {"f_check": 2}
    assert ex.metadata["kalman_course"]["challenges"] == []


def test_the_builder_drops_the_references_outputs(tmp_path):
    path = _solution(tmp_path)
    nb = nbformat.read(path, as_version=4)
    nb.cells[0].outputs = [nbformat.v4.new_output("stream", name="stdout", text="answer 42\n")]
    nb.cells[0].execution_count = 1
    nb.cells[1].outputs = [nbformat.v4.new_output("stream", name="stdout", text="f_check: passed\n")]
    nb.cells[1].execution_count = 2
    nbformat.write(nb, path)
    ex = authoring.build_exercise(path)
    assert [(c.outputs, c.execution_count) for c in ex.cells] == [([], None), ([], None)]


def test_a_challenge_is_named_in_the_release(tmp_path):
    two = REGION + "\n\n" + REGION.replace("f_check", "bonus").replace("def f", "def g")
    ex = authoring.build_exercise(_solution(tmp_path, two, graders=[_grader(), _grader("bonus", 3, challenge=True)]))
    assert ex.metadata["kalman_course"]["graders"] == {"f_check": 2, "bonus": 3}
    assert ex.metadata["kalman_course"]["challenges"] == ["bonus"]
    with pytest.raises(AuthoringError, match="challenge"):
        authoring.build_exercise(_solution(tmp_path, graders=[_grader(challenge="yes")]))


@pytest.mark.parametrize("source, message", [
    (REGION.replace("  # fix this", ""), "has no '# fix this'"),
    (REGION.replace("    # STUB\n", ""), "no '# STUB'"),
    (REGION.replace("    # END SOLUTION\n", ""), "is '# END SOLUTION' missing"),
    (REGION.replace("    # END SOLUTION\n    return y", ""), "no '# END SOLUTION'"),
    (REGION.replace("    # y = x - 1", "    y = x - 1"), "stub lines must be commented"),
    ("x = 1\n# END SOLUTION", "without '# BEGIN SOLUTION'"),
])
def test_malformed_regions_are_reported(tmp_path, source, message):
    with pytest.raises(AuthoringError, match=message):
        authoring.build_exercise(_solution(tmp_path, source))


def test_stub_without_grader_and_grader_without_stub_are_errors(tmp_path):
    with pytest.raises(AuthoringError, match="has no grader cell"):
        authoring.build_exercise(_solution(tmp_path, graders=[]))
    with pytest.raises(AuthoringError, match="have no stub"):
        authoring.build_exercise(_solution(tmp_path, graders=[_grader(), _grader("other")]))
    with pytest.raises(AuthoringError, match="points"):
        authoring.build_exercise(_solution(tmp_path, graders=[_grader(points=0)]))


def test_notebook_names_need_a_chapter(tmp_path):
    with pytest.raises(AuthoringError, match="two-digit chapter"):
        authoring.build_exercise(_solution(tmp_path, name="demo.ipynb"))


def test_build_is_deterministic_and_check_detects_drift(tmp_path):
    sol, ex = tmp_path / "solutions", tmp_path / "exercises"
    shutil.copytree(ROOT / "solutions", sol)
    assert authoring.build_all(sol, ex)  # first build writes everything
    digest = {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in ex.iterdir()}
    assert authoring.build_all(sol, ex) == []  # second build changes nothing
    assert digest == {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in ex.iterdir()}
    target = sorted(ex.iterdir())[0]
    target.write_text(target.read_text().replace("# fix this", "# fixed"))
    assert authoring.build_all(sol, ex, check=True) == [target]
    (ex / "99_stray.ipynb").write_text("{}")
    assert ex / "99_stray.ipynb" in authoring.build_all(sol, ex, check=True)


def _one_chapter(tmp_path):
    """A solutions folder with one real chapter, built once; (solutions, exercises, the exercise)."""
    sol, ex = tmp_path / "solutions", tmp_path / "exercises"
    sol.mkdir()
    shutil.copy(ROOT / "solutions" / "03_kalman_filter.ipynb", sol)
    assert authoring.build_all(sol, ex) == [ex / "03_kalman_filter.ipynb"]
    return sol, ex, ex / "03_kalman_filter.ipynb"


def test_a_build_never_overwrites_a_learners_work_without_force(tmp_path):
    sol, ex, target = _one_chapter(tmp_path)
    built = target.read_text()
    assert authoring.written_by_build(built)
    # the learner fixes a stub and saves; then the instructor's solution changes and build runs
    mine = built.replace("# fix this", "# fixed by me", 1)
    target.write_text(mine)
    assert not authoring.written_by_build(mine)
    solution = sol / "03_kalman_filter.ipynb"
    solution.write_text(solution.read_text().replace("Exercise 03", "Exercise 03 (revised)", 1))
    with pytest.raises(authoring.BuildRefused) as refused:
        authoring.build_all(sol, ex)
    assert refused.value.refused == [target] and refused.value.written == []
    assert target.read_text() == mine and not list(ex.glob("*.bak*"))       # untouched, nothing else written
    # --force: the new exercise is written, the learner's file kept beside it, twice without loss
    assert authoring.build_all(sol, ex, force=True) == [target]
    assert (ex / "03_kalman_filter.ipynb.bak").read_text() == mine
    assert authoring.written_by_build(target.read_text()) and "(revised)" in target.read_text()
    target.write_text(mine + " ")                                        # not even valid JSON now
    assert authoring.build_all(sol, ex, force=True) == [target]
    assert (ex / "03_kalman_filter.ipynb.bak2").read_text() == mine + " "
    assert (ex / "03_kalman_filter.ipynb.bak").read_text() == mine
    assert authoring.build_all(sol, ex, check=True) == []                # backups are not exercises


def test_a_build_overwrites_its_own_output_even_resaved_by_another_editor(tmp_path):
    sol, ex, target = _one_chapter(tmp_path)
    nb = nbformat.read(target, as_version=4)
    target.write_text(nbformat.writes(nb, version=4).replace("\n ", "\n  "))     # another indentation, same content
    assert authoring.written_by_build(target.read_text())
    solution = sol / "03_kalman_filter.ipynb"
    solution.write_text(solution.read_text().replace("Exercise 03", "Exercise 03 (revised)", 1))
    assert authoring.build_all(sol, ex) == [target] and not list(ex.glob("*.bak*"))
    # an exercise of a build before the digests is the build's too, when it is what that build wrote
    plain = nbformat.read(target, as_version=4)
    del plain.metadata["kalman_course"][authoring.BUILD_DIGEST]
    target.write_text(authoring.notebook_text(plain))
    assert authoring.build_all(sol, ex) == [target] and not list(ex.glob("*.bak*"))


def test_the_build_command_names_the_files_it_left_and_the_way_out(tmp_path, capsys):
    from kalman_course.tooling import cli

    sol, ex, target = _one_chapter(tmp_path)
    target.write_text(target.read_text().replace("# fix this", "# fixed by me", 1))
    solution = sol / "03_kalman_filter.ipynb"
    solution.write_text(solution.read_text().replace("Exercise 03", "Exercise 03 (revised)", 1))
    assert cli.main(["build", "--solutions", str(sol), "--exercises", str(ex)]) == 1
    err = capsys.readouterr().err
    assert str(target) in err and "--force" in err and ".bak" in err
    assert cli.main(["build", "--solutions", str(sol), "--exercises", str(ex), "--force"]) == 0
    assert (ex / "03_kalman_filter.ipynb.bak").exists()


def test_exercises_folder_is_in_sync_with_solutions():
    assert authoring.build_all(ROOT / "solutions", ROOT / "exercises", check=True) == [], \
        "exercises/ is out of date: run `kalman-course build`"


@pytest.mark.parametrize("path", SOLUTIONS, ids=lambda p: p.stem)
def test_every_solution_has_at_least_three_stubs(path):
    stubs = authoring.list_stubs(nbformat.read(path, as_version=4))
    assert len(stubs) >= 3
    assert all("# fix this" in s.stub for s in stubs)


@pytest.mark.parametrize("path", EXERCISES, ids=lambda p: p.stem)
def test_no_exercise_contains_an_output_of_the_reference(path):
    nb = nbformat.read(path, as_version=4)
    shipped = [(c["id"], len(c.outputs), c.execution_count) for c in nb.cells
               if c.cell_type == "code" and (c.outputs or c.execution_count is not None)]
    assert shipped == [], f"{path.name} ships outputs (cell, outputs, execution count): {shipped}"
    # no figure or result pasted into the text either
    assert not [c["id"] for c in nb.cells if c.cell_type == "markdown" and c.get("attachments")]


@pytest.mark.parametrize("path", EXERCISES, ids=lambda p: p.stem)
def test_every_exercise_opens_with_what_when_and_how(path):
    first = nbformat.read(path, as_version=4).cells[0]
    assert first.cell_type == "markdown"
    lines = first.source.splitlines()
    chapter = path.name[:2]
    assert re.match(rf"^# Exercise {chapter} — \S", lines[0]), lines[0]
    for label in ("**You build:**", "**Time:**", "**Read first:**", "**Check yourself:**"):
        assert label in first.source, f"{path.name}: the first screen has no {label}"
    assert re.search(r"\*\*Time:\*\* about \d+ minutes", first.source), "the time, in minutes"
    assert re.search(rf"\*\*Read first:\*\* lecture {chapter} §\d", first.source), "the lecture sections"
    assert f"pytest --nbval exercises/{path.name}" in first.source
    assert f"kalman-course grade exercises/{path.name}" in first.source
    assert len(lines) <= 22, f"{path.name}: the first screen has {len(lines)} lines"


@pytest.mark.parametrize("path", SOLUTIONS, ids=lambda p: p.stem)
def test_every_exercise_has_a_whole_step_to_write(path):
    stubs = authoring.list_stubs(nbformat.read(path, as_version=4))
    longest = max(len([line for line in s.solution.splitlines() if line.strip() and not line.strip().startswith("#")])
                  for s in stubs)
    assert longest >= 3, f"{path.name}: no fix section replaces a step of three or more lines"
