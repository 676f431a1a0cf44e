"""Gradebooks an instructor can trust, without a kernel: results are built directly.

Shards are signed and merge only when honest (every forgery is refused, naming the file and
the learner, with nothing written); honest shards merge into exactly the files one run writes;
learner text is escaped where it lands (CSV formulas, terminal escapes, Markdown and HTML);
learners the gradebooks could not tell apart, and outputs that would overwrite a submission or
land in the release, are refused before grading; a failed write leaves the old file whole.
"""

import csv
import io
import json
import os
import re
import stat

import mistune
import pytest

from kalman_course.tooling import cli, gradebook, grading

KEY = "the instructor's key"
SANDBOX = "bubblewrap 0.8.0"
SEED = 20261202
#: Five learners (alice with two notebooks); three shards deal them as alice+dave, bob+erin, carol.
ROSTER = [("alice", "class/alice/01_bayes.ipynb"), ("alice", "class/alice/02_gauss.ipynb"),
          ("bob", "class/bob/01_bayes.ipynb"), ("carol", "class/carol/01_bayes.ipynb"),
          ("dave", "class/dave/01_bayes.ipynb"), ("erin", "class/erin/01_bayes.ipynb")]


@pytest.fixture(autouse=True)
def key(monkeypatch):
    monkeypatch.setenv(gradebook.KEY_VARIABLE, KEY)


def _result(i, learner, path, **fields):
    passed = i in (0, 3, 4)  # alice's second notebook, bob and erin fail kf_predict
    checks = [grading.CheckResult("kf_predict", "g1", 2 if passed else 0, 2,
                                  "" if passed else "CheckFailed: kf_predict: P is wrong.\nHint: add Q"),
              grading.CheckResult("kf_gain", "g2", 3, 3),
              grading.CheckResult("kf_tune", "g3", 0, 4, "not done", challenge=True)]
    chapter = path.rsplit("/", 1)[-1][:2]
    return grading.NotebookResult(path, learner, chapter, checks=checks, order=i, class_size=len(ROSTER), **fields)


def _results():
    return [_result(i, learner, path) for i, (learner, path) in enumerate(ROSTER)]


def _run(shard=None, roster=ROSTER):
    return gradebook.run_record(roster, sandbox=SANDBOX, seed=SEED, shard=shard)


def _shards(folder, n=3, key=KEY.encode()):
    """Write the class as ``n`` signed shards, as ``grade --shard K/N --json`` does."""
    submissions = [(path, learner) for learner, path in ROSTER]
    results, paths = _results(), []
    for k in range(1, n + 1):
        path = folder / f"shard-{k}.json"
        mine = [results[i] for i in grading.shard_of(submissions, k, n)]
        gradebook.write_gradebooks(mine, _run((k, n)), key, json_path=path)
        paths.append(path)
    return paths


def _edit(path, change, key=KEY):
    """Change a shard's JSON; with ``key``, sign it again (a forger holding the key, or a buggy grader)."""
    document = json.loads(path.read_text())
    change(document)
    if key:
        document["signature"] = gradebook.signature(document, key.encode())
    path.write_text(json.dumps(document, indent=1) + "\n")


def _outputs(folder):
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


# --- honest shards ---------------------------------------------------------------------------

def test_honest_shards_merge_into_exactly_the_files_one_run_writes(tmp_path, capsys):
    one = tmp_path / "one"
    gradebook.write_gradebooks(_results(), _run(), KEY.encode(), csv_path=one / "grades.csv",
                               json_path=one / "grades.json", feedback_dir=one / "feedback")
    merged = tmp_path / "merged"
    code = cli.main(["merge", *map(str, _shards(tmp_path)), "--csv", str(merged / "grades.csv"),
                     "--json", str(merged / "grades.json"), "--feedback", str(merged / "feedback")])
    assert code == 0, capsys.readouterr().err
    expected = _outputs(one)
    assert len(expected) == 2 + 5 and _outputs(merged) == expected
    document = json.loads(expected["grades.json"])
    assert (document["format"], document["version"], document["run"]["shard"]) == ("kalman-course gradebook", 2, None)
    assert document["run"]["class"] == [list(entry) for entry in ROSTER] and document["run"]["sandbox"] == SANDBOX
    assert document["signature"] == gradebook.signature(document, KEY.encode())


def test_unsigned_shards_merge_only_when_asked_and_say_so(tmp_path, capsys):
    paths = _shards(tmp_path, key=None)
    assert cli.main(["merge", *map(str, paths), "--json", str(tmp_path / "out" / "g.json")]) == 2
    err = capsys.readouterr().err
    assert "shard-1.json is unsigned" in err and not (tmp_path / "out").exists()
    assert cli.main(["merge", *map(str, paths), "--unsigned", "--json", str(tmp_path / "out" / "g.json")]) == 0
    err = capsys.readouterr().err
    assert err.count("is unsigned: its points were not verified (--unsigned)") == 3
    assert json.loads((tmp_path / "out" / "g.json").read_text())["signature"] is None  # never laundered


def test_a_forgery_is_refused_even_when_unsigned_shards_are_allowed(tmp_path, capsys):
    paths = _shards(tmp_path, key=None)
    _edit(paths[1], lambda d: d["results"][0]["checks"][0].update(points=999), key=None)
    assert cli.main(["merge", *map(str, paths), "--unsigned", "--csv", str(tmp_path / "g.csv")]) == 2
    assert "learner 'bob'" in capsys.readouterr().err and not (tmp_path / "g.csv").exists()


# --- forged shards ----------------------------------------------------------------------------

def _points(document, learner, points):
    record = next(r for r in document["results"] if r["learner"] == learner)
    record["checks"][0]["points"] = points
    return record


def _drop(document, learner):
    document["results"] = [r for r in document["results"] if r["learner"] != learner]


def _steal(paths):
    """Copy erin's result (shard 2) into shard 1, signed."""
    erin = next(r for r in json.loads(paths[1].read_text())["results"] if r["learner"] == "erin")
    _edit(paths[0], lambda d: d["results"].append(erin))


def _forget_erin(document):
    document["run"]["class"] = [entry for entry in document["run"]["class"] if entry[0] != "erin"]
    document["run"]["class_size"] = len(document["run"]["class"])
    _drop(document, "erin")


# name -> (shard to change (0-based), change, sign again, what stderr must say)
FORGERIES = {
    "points edited": (1, lambda d: _points(d, "bob", 2), False, r"shard-2\.json: its signature does not verify"),
    "message edited": (0, lambda d: d["results"][0]["checks"][1].update(message="well done"), False,
                       r"shard-1\.json: its signature does not verify.*'alice'"),
    "learner renamed": (2, lambda d: d["results"][0].update(learner="mallory"), False,
                        r"shard-3\.json: its signature does not verify"),
    "signature removed": (0, lambda d: d.update(signature=None), False, r"shard-1\.json is unsigned"),
    "999 of 2 points": (1, lambda d: _points(d, "bob", 999), True,
                        r"learner 'bob' \('class/bob/01_bayes\.ipynb'\): check 'kf_predict' records 999/2 points, "
                        "more than the check is worth"),
    "negative points": (1, lambda d: _points(d, "bob", -2), True, r"learner 'bob'.*-2/2 points, which is negative"),
    "half a check": (1, lambda d: _points(d, "bob", 1), True, r"learner 'bob'.*1/2 points; a check gives 0 or all"),
    "total inflated": (1, lambda d: d["results"][0].update(points=5), True,
                       r"learner 'bob'.*its points reads 5, but its checks make it 3"),
    "hint forged": (1, lambda d: d["results"][0].update(hint=""), True, r"learner 'bob'.*its hint reads ''"),
    "same number twice": (2, lambda d: d["run"].update(shard="2/3"), True,
                          r"shard-2\.json and .*shard-3\.json all say they are shard 2/3.*\n.*shard 3/3 is missing"),
    "numbers of parts differ": (2, lambda d: d["run"].update(shard="3/4"), True, r"disagree on how many parts"),
    "renumbered as 1/1": (1, lambda d: d["run"].update(shard="1/1"), True,
                          r"disagree on how many parts.*shard-2\.json says 1/1"),
    "renumbered as the whole class": (1, lambda d: d["run"].update(shard=None), True,
                                      r"shard-2\.json is a whole class's gradebook"),
    "a learner disappears": (1, lambda d: _drop(d, "bob"), True,
                             r"shard-2\.json \(shard 2/3\) lacks learner 'bob' \('class/bob/01_bayes\.ipynb'\)"),
    "an unknown learner": (0, lambda d: d["results"][0].update(learner="mallory"), True,
                           r"shard-1\.json \(shard 1/3\) holds learner 'mallory'.*not in the class roster"),
    "a roster edited": (1, _forget_erin, True, r"shard-2\.json is of another class than .*shard-1\.json: "
                                               r"'erin' \('class/erin/01_bayes\.ipynb'\) only in .*shard-1\.json"),
    "interrupted": (2, lambda d: d["run"].update(interrupted=True), True, r"shard-3\.json: the run .* was interrupted"),
    "another sandbox": (2, lambda d: d["run"].update(sandbox="none (--no-sandbox)"), True,
                        r"shard-3\.json was graded with sandbox 'none \(--no-sandbox\)'"),
    "another run seed": (1, lambda d: d["run"].update(seed=SEED + 1), True,
                         rf"shard-2\.json was graded with seed {SEED + 1}, .*shard-1\.json with {SEED}"),
}


@pytest.mark.parametrize("name", sorted(FORGERIES))
def test_a_forged_shard_is_refused_naming_what_is_wrong(name, tmp_path, capsys):
    shard, change, sign, message = FORGERIES[name]
    paths = _shards(tmp_path)
    _edit(paths[shard], change, key=KEY if sign else None)
    out = tmp_path / "out"
    code = cli.main(["merge", *map(str, paths), "--csv", str(out / "g.csv"), "--json", str(out / "g.json"),
                     "--feedback", str(out / "fb")])
    err = capsys.readouterr().err
    assert code == 2 and re.search(message, err), err
    assert not out.exists()


def test_a_shard_signed_with_another_key_or_left_out_is_refused(tmp_path, capsys):
    paths = _shards(tmp_path)
    assert cli.main(["merge", str(paths[0]), str(paths[2])]) == 2
    assert "shard 2/3 is missing" in capsys.readouterr().err
    _edit(paths[1], lambda d: None, key="a student's guess")
    assert cli.main(["merge", *map(str, paths)]) == 2
    assert "shard-2.json: its signature does not verify" in capsys.readouterr().err


def test_a_signed_shard_needs_a_key_to_be_checked(tmp_path, monkeypatch, capsys):
    paths = _shards(tmp_path)
    monkeypatch.delenv(gradebook.KEY_VARIABLE)
    assert cli.main(["merge", *map(str, paths)]) == 2
    assert "is signed, but no key was given" in capsys.readouterr().err


@pytest.mark.parametrize("text, problem", [
    ("[1, 2]", "a list of results: a gradebook of an earlier version"),
    ('[{"learner": "alice"}]', "a list of results"),
    ("{ not json", "JSONDecodeError"),
    ('{"format": "something else"}', "its format is not 'kalman-course gradebook'"),
    ('{"format": "kalman-course gradebook", "version": 1}', "version 1; this course reads version 2"),
    ('{"format": "kalman-course gradebook", "format": "kalman-course gradebook"}', "a key appears twice"),
])
def test_read_json_says_what_is_not_a_gradebook(text, problem, tmp_path):
    path = tmp_path / "g.json"
    path.write_text(text)
    with pytest.raises(ValueError, match="not a gradebook written by") as refused:
        gradebook.read_json(path)
    assert str(path) in str(refused.value) and problem in str(refused.value)


def test_read_json_checks_every_field_type(tmp_path):
    path = _shards(tmp_path)[0]
    _edit(path, lambda d: d["results"][1]["checks"][0].update(points="2"))
    with pytest.raises(ValueError, match=r"results\[1\]\.checks\[0\]\.points is of type str, not int"):
        gradebook.read_json(path)
    _edit(path, lambda d: d["results"][1].update(extra=1))
    with pytest.raises(ValueError, match=r"results\[1\] has unknown fields extra"):
        gradebook.read_json(path)


# --- learner text where it lands ----------------------------------------------------------------

HOSTILE = [
    ("=HYPERLINK(\"http://evil.example\",\"click\")", "class/x/01_bayes.ipynb", "01", "CheckFailed: f: wrong"),
    ("alice", "class/alice/01_bayes.ipynb", "=1+2", "+cmd|' /C calc'!A0"),
    ("bob", "@SUM(A1)/01_bayes.ipynb", "01", "-2+3"),
    ("\tcarol", "class/carol/01_bayes.ipynb", "01", "\r=1+1"),
    ("  =dave", "class/dave/01_bayes.ipynb", "01", "fine"),
]


def test_csv_cells_that_a_spreadsheet_would_run_are_neutralised(tmp_path):
    results = [grading.NotebookResult(path, learner, chapter, order=i, class_size=len(HOSTILE), flags=["@flag"],
                                      checks=[grading.CheckResult("f", "g", 0, 2, hint)])
               for i, (learner, path, chapter, hint) in enumerate(HOSTILE)]
    gradebook.write_gradebooks(results, _run(), csv_path=tmp_path / "g.csv")
    raw = (tmp_path / "g.csv").read_text(encoding="utf-8")
    header, *rows = list(csv.reader(io.StringIO(raw)))
    columns = [dict(zip(header, row)) for row in rows]
    assert [c["learner"] for c in columns] == ["'=HYPERLINK(\"http://evil.example\",\"click\")", "alice", "bob",
                                               "'\tcarol", "'  =dave"]
    assert columns[1]["chapter"] == "'=1+2" and columns[2]["notebook"] == "'@SUM(A1)/01_bayes.ipynb"
    assert [c["hint"] for c in columns] == ["CheckFailed: f: wrong", "'+cmd|' /C calc'!A0", "'-2+3", "'\n=1+1", "fine"]
    assert all(c["flags"] == "'@flag" for c in columns)
    for row in rows:  # no cell left that starts a formula
        assert not any(cell.lstrip().startswith(("=", "+", "-", "@")) or cell.startswith(("\t", "\r")) for cell in row)
    # numbers written bare (a spreadsheet reads them as numbers), every text cell quoted
    numbers = list(csv.reader(io.StringIO(raw.split("\n", 1)[1]), quoting=csv.QUOTE_NONNUMERIC))
    assert [row[4:8] for row in numbers] == [[0.0, 2.0, 0.0, 0.0]] * len(HOSTILE)
    assert all(isinstance(row[0], str) for row in numbers)


ANSI = "\x1b[2K\r"  # erase the row and go back to its start


def _hostile_console_result():
    message = f"CheckFailed: kf_predict: wrong{ANSI}kf_predict: passed 12/12\x1b]0;owned\x07\x08\x07"
    return grading.NotebookResult(f"class/{ANSI}mallory/03_kf\x1b[8m.ipynb", f"{ANSI}mallory\u202e", f"\x1b[31m03\n",
                                  checks=[grading.CheckResult("kf_predict", "g1", 0, 2, message)],
                                  flags=[f"cell c:\x9b2J imports `f`{ANSI}"], tampered=[f"cell {ANSI}: source edited"],
                                  learner_errors=["cell x: E: \x1b[1A\x1b[2Kup"])


def _controls(text):
    return sorted({hex(ord(ch)) for ch in text if ch != "\n" and (ord(ch) < 0x20 or 0x7f <= ord(ch) <= 0x9f
                                                                 or ch in "\u200e\u200f\u202a\u202b\u202c\u202d\u202e")})


def test_the_console_gets_no_control_character_or_escape_sequence():
    hostile, honest = _hostile_console_result(), _results()[0]
    table = gradebook.format_table([hostile, honest], every_hint=True)
    summary = gradebook.format_summary([hostile, honest])
    progress = gradebook.progress_line(1, 2, hostile)
    assert _controls(table) == [] and _controls(summary) == [] and _controls(progress) == []
    lines = table.splitlines()
    # header, rule, two rows, total, the challenges' note, restored cells, review; two notebooks' hints
    assert len(lines) == 2 + 2 + 1 + 1 + 1 + 1 + 2 * 2
    assert lines[2].startswith("mallory  03 ") and lines[2].endswith("  kf_predict: wrong")
    assert "\n" not in progress and progress.startswith("[1/2] mallory: class/ mallory/03_kf.ipynb: graded")
    assert "chapter 03: 1 graded" in summary


def test_feedback_markdown_shows_learner_text_as_text(tmp_path):
    evil = ("CheckFailed: kf_predict: <img src=x onerror=alert(1)> wrong\n- **kf_predict** (2/2): passed\n"
            "# Chapter 03: full marks\n```\n</pre><script>alert(2)</script>")
    r = grading.NotebookResult("class/x/03_<b>kf<b>`x`.ipynb", "<i>eve</i>_*", "[03](javascript:alert(3))",
                               checks=[grading.CheckResult("kf_predict", "g1", 0, 2, evil),
                                       grading.CheckResult("kf_gain", "g2", 3, 3)],
                               flags=["cell c: imports `f` from `m` <a href=x>"],
                               learner_errors=["cell d: ValueError: <svg onload=alert(4)>\n- **kf_gain** (3/3): passed"])
    written = gradebook.write_gradebooks([r], _run(), feedback_dir=tmp_path / "fb")
    assert written == [f"wrote 1 feedback file(s) to {tmp_path / 'fb'}"]
    [path] = (tmp_path / "fb").iterdir()
    text = path.read_text()
    html = mistune.create_markdown(escape=False)(text)  # raw HTML would pass through: escaping is ours
    assert not re.search(r"<(img|script|svg|a|b|i)\b", html), html
    assert "&lt;img src=x onerror=alert(1)&gt;" in html and "&lt;i&gt;eve&lt;/i&gt;_*" in html
    assert 'href="javascript' not in html and "[03](javascript:alert(3))" in html
    assert re.findall(r"<li>", html) == ["<li>"] * 4  # the flag, the error, two checks: nothing faked
    assert "<strong>kf_predict</strong> (0/2): failed" in html and "(2/2): passed" not in html.replace(
        "<pre><code>- **kf_predict** (2/2): passed", "")
    assert "<h2>Chapter 03: full marks" not in html and html.count("<h2>") == 1
    assert "<code>03_&lt;b&gt;kf&lt;b&gt;`x`.ipynb</code>" in html


def test_feedback_of_a_self_grade_is_titled_feedback(tmp_path):
    r = _results()[0]
    r.learner = "-"
    gradebook.write_gradebooks([r], _run(), feedback_dir=tmp_path)
    assert (tmp_path / "feedback.md").read_text().splitlines()[0] == "# Feedback"


# --- who is who, where the gradebooks go ---------------------------------------------------------

@pytest.mark.parametrize("submissions, named", [
    ([("c/a b/01_x.ipynb", "a b"), ("c/a_b/01_x.ipynb", "a_b")], r"learners 'a b' and 'a_b' would share one "
                                                                 r"feedback file, a_b\.md"),
    ([("c/Alice/01_x.ipynb", "Alice"), ("c/alice/01_x.ipynb", "alice")], r"'Alice' and 'alice'"),
    ([("c/alice/01_x.ipynb", "alice"), ("c/alice__02_y.ipynb", "alice")],
     r"learner 'alice' is in both layouts: 'c/alice/01_x\.ipynb' .* and 'c/alice__02_y\.ipynb'"),
])
def test_learners_the_gradebooks_could_not_tell_apart_are_refused(submissions, named):
    with pytest.raises(ValueError, match=named):
        gradebook.refuse_clashing_learners(submissions, roots=["c"])
    gradebook.refuse_clashing_learners(submissions[:1], roots=["c"])  # either one alone is fine


def test_a_flat_layout_under_a_folder_named_like_the_learner_is_one_layout():
    home = [("/home/alice/class/alice__01_x.ipynb", "alice"), ("/home/alice/class/alice__02_y.ipynb", "alice")]
    gradebook.refuse_clashing_learners(home, roots=["/home/alice/class"])


def _no_grading(monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("grading started")
    monkeypatch.setattr(grading, "grade_many", refuse)
    monkeypatch.setattr(grading, "load_release", refuse)


@pytest.mark.parametrize("layout, named", [
    ({"a b/01_x.ipynb", "a_b/01_x.ipynb"}, "'a b' and 'a_b'"),
    ({"alice/01_x.ipynb", "alice__02_y.ipynb"}, "learner 'alice' is in both layouts"),
])
def test_grade_refuses_such_a_class_before_grading(layout, named, tmp_path, monkeypatch, capsys):
    _no_grading(monkeypatch)
    for name in layout:
        (tmp_path / "class" / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / "class" / name).write_text("{}")
    code = cli.main(["grade", str(tmp_path / "class"), "--feedback", str(tmp_path / "fb")])
    assert code == 2 and named in capsys.readouterr().err and not (tmp_path / "fb").exists()


def test_an_output_that_is_a_submission_or_in_the_release_is_refused(tmp_path, monkeypatch, capsys):
    _no_grading(monkeypatch)
    submission = tmp_path / "03_kf.ipynb"
    submission.write_text('{"the learner": "work"}')
    release = tmp_path / "release"
    release.mkdir()
    for option, target in [("--json", submission), ("--csv", submission), ("--feedback", tmp_path / "release"),
                           ("--csv", release / "grades.csv"), ("--json", tmp_path / "." / "03_kf.ipynb")]:
        code = cli.main(["grade", str(submission), "--release", str(release), option, str(target)])
        err = capsys.readouterr().err
        assert code == 2 and option in err and "refusing to write the gradebooks" in err, (option, target, err)
    assert submission.read_text() == '{"the learner": "work"}' and list(release.iterdir()) == []
    # a feedback file that would be the submission itself
    (tmp_path / "feedback.md").write_text("a submission")
    assert cli.main(["grade", str(tmp_path / "feedback.md"), "--feedback", str(tmp_path)]) == 2
    assert "feedback.md" in capsys.readouterr().err and (tmp_path / "feedback.md").read_text() == "a submission"


def test_merge_never_overwrites_a_shard_it_reads(tmp_path, capsys):
    paths = _shards(tmp_path)
    before = paths[0].read_bytes()
    assert cli.main(["merge", *map(str, paths), "--json", str(paths[0])]) == 2
    assert "is one of the files being read" in capsys.readouterr().err and paths[0].read_bytes() == before


# --- keys ------------------------------------------------------------------------------------------

def test_a_key_file_signs_like_the_variable_and_must_be_private(tmp_path, monkeypatch, capsys):
    paths = _shards(tmp_path)
    monkeypatch.delenv(gradebook.KEY_VARIABLE)
    key_file = tmp_path / "key"
    key_file.write_text(KEY + "\n")
    key_file.chmod(0o644)
    assert cli.main(["merge", *map(str, paths), "--key-file", str(key_file)]) == 2
    assert "chmod 600" in capsys.readouterr().err
    key_file.chmod(0o600)
    assert cli.main(["merge", *map(str, paths), "--key-file", str(key_file), "--json", str(tmp_path / "g.json")]) == 0
    document = json.loads((tmp_path / "g.json").read_text())
    assert document["signature"] == gradebook.signature(document, KEY.encode())
    assert cli.main(["merge", *map(str, paths), "--key-file", str(tmp_path / "nowhere")]) == 2
    assert "cannot read it" in capsys.readouterr().err


def test_unsigned_is_an_option_of_merge_only():
    parser = cli.build_parser()
    assert parser.parse_args(["merge", "a.json", "--unsigned"]).unsigned is True
    with pytest.raises(SystemExit):
        parser.parse_args(["grade", "--unsigned"])


# --- atomic writes -------------------------------------------------------------------------------

def test_a_failed_write_leaves_the_old_file_whole_and_no_leftovers(tmp_path, monkeypatch):
    path = tmp_path / "g.json"
    gradebook.write_gradebooks(_results()[:1], _run(), json_path=path)
    before = path.read_bytes()

    def full_disk(src, dst):
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(gradebook.os, "replace", full_disk)
    with pytest.raises(OSError, match="No space left"):
        gradebook.write_gradebooks(_results(), _run(), json_path=path)
    assert path.read_bytes() == before and os.listdir(tmp_path) == ["g.json"]


def test_nothing_is_written_when_making_a_gradebook_fails(tmp_path, monkeypatch):
    def broken(*args, **kwargs):
        raise RuntimeError("serialiser broke")
    monkeypatch.setattr(gradebook.json, "dumps", broken)
    with pytest.raises(RuntimeError):
        gradebook.write_gradebooks(_results(), _run(), csv_path=tmp_path / "g.csv", json_path=tmp_path / "g.json",
                                   feedback_dir=tmp_path / "fb")
    assert os.listdir(tmp_path) == []


def test_a_new_gradebook_has_the_usual_permissions(tmp_path):
    umask = os.umask(0o022)
    try:
        gradebook.write_gradebooks(_results(), _run(), csv_path=tmp_path / "g.csv")
    finally:
        os.umask(umask)
    assert stat.S_IMODE((tmp_path / "g.csv").stat().st_mode) == 0o644
