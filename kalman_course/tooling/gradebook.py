"""Gradebooks: the points table, the CSV, the signed JSON and the feedback files.

Grading (:mod:`kalman_course.tooling.grading`) produces :class:`NotebookResult` objects; this
module puts them where an instructor or a learner reads them. Much of what a result holds came
from a learner (folder and file names, chapter metadata, cell ids, check messages that carry
their exceptions, review flags, their cells' errors), so every string is escaped for the place
it lands: a CSV cell never starts a formula, a console line carries no control character or
escape sequence and stays one line, and feedback Markdown shows learner text as text.

Each file is written beside its final name and then renamed over it, so that a reader (or a
crash) finds the old file or the new one, never part of one. The JSON gradebook records its run
(the whole class's roster, the shard, the sandbox) and is signed with an HMAC-SHA256 whose key
the instructor holds; :func:`merge_results` refuses any shard whose signature, numbering,
learners or points do not verify, naming the file and the learner.
"""

from __future__ import annotations

import csv
import hashlib
import hmac
import io
import json
import os
import re
import secrets
import textwrap
from collections import Counter, defaultdict
from dataclasses import asdict, dataclass
from pathlib import Path

from kalman_course.tooling.grading import NOT_A_NOTEBOOK, RAN_TO_THE_END, CheckResult, NotebookResult, shard_of
from kalman_course.tooling.notebooks import InputError, blocking_file, read_text

#: What a JSON gradebook says it is; version 2 added the run record and the signature.
FORMAT, VERSION = "kalman-course gradebook", 2
#: The environment variable that holds the signing key (``--key-file`` is the other way to give it).
KEY_VARIABLE = "KALMAN_COURSE_GRADEBOOK_KEY"
_SIGNATURE_PREFIX = "hmac-sha256:"


# --- learner text, made harmless where it lands -------------------------------------------

#: Terminal escape sequences: CSI (colours, cursor moves, erasing a line), OSC (window titles,
#: hyperlinks; up to BEL or ST, or to the end when unterminated, as a terminal would swallow
#: it), DCS/SOS/PM/APC strings, the two-byte escapes, and the 8-bit CSI.
_ESCAPE_SEQUENCE = re.compile(r"\x1b\[[0-?]*[ -/]*[@-~]|\x1b\][^\x07\x1b]*(?:\x07|\x1b\\)?"
                              r"|\x1b[PX^_][^\x1b]*(?:\x1b\\)?|\x1b[ -/]*[0-~]|\x9b[0-?]*[ -/]*[@-~]")
#: Every line break ``str.splitlines`` knows: a bare carriage return rewinds a terminal line.
_LINE_BREAK = re.compile("\r\n|[\n\r\x0b\x0c\x1c-\x1e\x85\u2028\u2029]")
#: C0 controls but the tab, C1 controls and DEL, and the Unicode marks that reorder what a line displays.
_CONTROL = re.compile("[\x00-\x08\x0a-\x1f\x7f-\x9f\u200e\u200f\u202a-\u202e\u2066-\u2069]")


def _lines(text) -> list[str]:
    """The lines of learner text, without escape sequences or control characters (tabs kept)."""
    text = _ESCAPE_SEQUENCE.sub("", str(text))
    return [_CONTROL.sub("", line) for line in _LINE_BREAK.split(text)]


def console_text(text) -> str:
    """Learner text for one line of a terminal: no escape sequence or control character left
    (one could erase the row, print a fake score or hide the lines after it), line breaks and
    tabs as spaces, none around it."""
    return " ".join(_lines(text)).replace("\t", " ").strip()


def _first_line(text) -> str:
    return console_text(_lines(text)[0])


#: A spreadsheet reads a cell that starts with one of these as a formula (OWASP, CSV injection).
_FORMULA_START = ("=", "+", "-", "@", "\t", "\r")


def csv_cell(value):
    """``value`` for a CSV cell: text that a spreadsheet would read as a formula gets a leading
    single quote (OWASP's rule; also when spaces come first, which some spreadsheets skip), and
    loses its escape sequences and control characters but line breaks (a CSV is also read in a
    terminal). Numbers stay numbers."""
    if not isinstance(value, str):
        return value
    if value.startswith(_FORMULA_START) or value.lstrip().startswith(_FORMULA_START):
        value = "'" + value
    return "\n".join(_lines(value))


#: Characters that mean something inside a Markdown line: escapes, code, emphasis, links and
#: images, tables, strike-through, maths.
_MARKDOWN_SPECIAL = re.compile(r"[\\`*\[\]|~$]")


def _escape_underscores(match: re.Match) -> str:
    """A run of underscores between two letters or digits is never emphasis (``03_kalman_filter``
    reads as written); any other is escaped."""
    text, start, end = match.string, match.start(), match.end()
    inside_a_word = start > 0 and end < len(text) and text[start - 1].isalnum() and text[end].isalnum()
    return match.group() if inside_a_word else "\\_" * (end - start)


def markdown_text(text) -> str:
    """Learner text as inline Markdown that renders as itself: one line, ``&``, ``<`` and ``>``
    as HTML entities (a tag is shown, never made), Markdown's special characters escaped."""
    text = console_text(text).replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
    text = _MARKDOWN_SPECIAL.sub(lambda m: "\\" + m.group(), text)
    return re.sub(r"_+", _escape_underscores, text)


def markdown_code(text) -> str:
    """Learner text as a Markdown code span, shown as typed: its fence is longer than any run of
    backticks in the text, so the text cannot close it."""
    text = console_text(text)
    if not text:
        return ""
    fence = "`" * (max(map(len, re.findall(r"`+", text)), default=0) + 1)
    pad = " " if text.startswith(("`", " ")) or text.endswith(("`", " ")) else ""  # Markdown strips one each side
    return f"{fence}{pad}{text}{pad}{fence}"


def _markdown_block(lines: list[str], indent: str) -> list[str]:
    """``lines`` as a fenced code block (its fence longer than any run of backticks in them, so
    no line can close it), each line indented to stay inside the list item above it."""
    longest = max((len(run) for line in lines for run in re.findall(r"`+", line)), default=0)
    fence = "`" * max(3, longest + 1)
    return [indent + fence, *((indent + line).rstrip() for line in lines), indent + fence]


def _markdown_lines(text, indent: str = "  ") -> tuple[str, list[str]]:
    """Learner text in Markdown: its first line inline and escaped, the lines after it (if any)
    as a fenced block, where a line such as ``- **kf_predict** (2/2): passed`` is only text."""
    first, *rest = _lines(text)
    while rest and not rest[-1].strip():
        rest.pop()
    return markdown_text(first), (_markdown_block(rest, indent) if rest else [])


def _quoted(text) -> str:
    """Learner text inside an error message: quoted, every control character spelled out."""
    return repr(str(text))


def _who(r: NotebookResult) -> str:
    return f"learner {_quoted(r.learner)} ({_quoted(r.path)})"


# --- the console ------------------------------------------------------------------------------

def progress_line(done: int, total: int, r: NotebookResult) -> str:
    """The line printed as each notebook is graded: ``[3/30] alice: PATH: graded, 12/12 points (4.1 s)``."""
    who = f"{console_text(r.learner)}: " if r.learner != "-" else ""
    return (f"[{done}/{total}] {who}{console_text(r.path)}: {console_text(r.status)}, {r.points_text} points "
            f"({r.seconds:.1f} s)")


#: Width the hints are wrapped to when a learner grades their own notebooks.
CONSOLE_WIDTH = 100


def grading_yourself(results: list[NotebookResult]) -> bool:
    """True when no result has a learner: ``kalman-course grade`` on one's own notebooks."""
    return all((r.learner or "-") == "-" for r in results)


def _subject(r: NotebookResult) -> str:
    """Whom a console line is about: the notebook's name when grading yourself, else the
    learner and their file (every learner's notebook has the same name)."""
    if (r.learner or "-") == "-":
        return console_text(Path(r.path).name)
    return f"{console_text(r.learner)} ({console_text(r.path)})"


def _first_failed(r: NotebookResult):
    return next((c for c in r.checks if c.points < c.possible and not c.challenge), None)


def _wrapped(text: str, indent: str = "  ") -> str:
    return textwrap.fill(text, CONSOLE_WIDTH, initial_indent=indent, subsequent_indent=indent,
                         break_long_words=False, break_on_hyphens=False)


def format_table(results: list[NotebookResult], every_hint: bool = False) -> str:
    """Return the points table printed by ``kalman-course grade`` (``every_hint``: also every
    failed check with the first line of its message, notebook by notebook).

    Grading yourself, the table names each notebook's first failing check and its hint follows
    the table, wrapped to :data:`CONSOLE_WIDTH` columns; for a class the hint is in the table."""
    yourself = grading_yourself(results)
    rows = [("learner", "chapter", "notebook", "points", "status",
             "first failing check" if yourself else "first hint")]
    for r in results:
        failed = _first_failed(r)
        first = ((failed.check if failed else "") if yourself
                 else _first_line(r.hint).removeprefix("CheckFailed: "))
        rows.append((console_text(r.learner or "-"), console_text(r.chapter) or "?", console_text(Path(r.path).name),
                     r.points_text, console_text(r.status), console_text(first)))
    if yourself:
        rows = [row[1:] for row in rows]  # grading yourself: no learner column
    ncol = len(rows[0]) - 1
    widths = [max(len(row[i]) for row in rows) for i in range(ncol)]
    lines = ["  ".join(cell.ljust(w) for cell, w in zip(row[:ncol], widths)) + "  " + row[ncol] for row in rows]
    lines.insert(1, "-" * min(sum(widths) + 2 * ncol + 10, 120))
    total, possible = sum(r.points for r in results), sum(r.possible for r in results)
    lines.append(f"total {total}/{possible} points")
    if any(r.challenge_possible for r in results):
        lines.append("(+a/b: the optional challenges' points, counted apart from the core)")
    for r in results:
        name = _subject(r)
        if r.tampered or r.readded:
            lines.append(f"note: {name}: grader cells restored "
                         f"(edited: {', '.join(map(console_text, r.tampered)) or 'none'}; "
                         f"re-added: {', '.join(map(console_text, r.readded)) or 'none'})")
        lines += [f"review: {name}: {console_text(flag)}" for flag in r.flags]
    if every_hint:
        lines += _every_hint(results, wrap=yourself)
    elif yourself:
        lines += _first_hints(results)
    return "\n".join(lines)


def _first_hints(results: list[NotebookResult]) -> list[str]:
    """Each notebook's first failing check and its hint, wrapped (grading yourself)."""
    lines = []
    for r in results:
        failed = _first_failed(r)
        if failed is None and not r.hint:
            continue
        text = _first_line(failed.message if failed else r.hint).removeprefix("CheckFailed: ")
        head = f"{console_text(Path(r.path).name)}, {console_text(failed.check)}:" if failed else \
            f"{console_text(Path(r.path).name)}:"
        lines += ["", head, _wrapped(console_text(text).removeprefix(f"{failed.check}: " if failed else ""))]
    return lines


def next_step(results: list[NotebookResult], all_hints: bool) -> str:
    """What to do next, for a learner grading their own notebooks (instead of class statistics)."""
    todo = [r for r in results if r.points < r.possible or r.status not in RAN_TO_THE_END]
    if not todo:
        return "next: every core check passes" + (
            "; the optional challenges are there when you want more" if any(
                r.challenge_points < r.challenge_possible for r in results) else "")
    r = todo[0]
    failed = _first_failed(r)
    where = console_text(r.path)
    if failed is None:
        return textwrap.fill(f"next: {where} was not graded ({console_text(r.status)}: see above); put that "
                             "right, then grade it again", CONSOLE_WIDTH, subsequent_indent="      ",
                             break_long_words=False, break_on_hyphens=False)
    more = "" if all_hints else "; --all-hints lists every failing check and shows the formulas"
    return textwrap.fill(f"next: in {where}, fix {console_text(failed.check)} (its hint is above), run its "
                         f"grader cell again, then this command{more}", CONSOLE_WIDTH, subsequent_indent="      ",
                         break_long_words=False, break_on_hyphens=False)


def _every_hint(results: list[NotebookResult], wrap: bool = False) -> list[str]:
    lines = []
    for r in results:
        failed = [c for c in r.checks if c.points < c.possible]
        if not failed:
            continue
        who = f" ({console_text(r.learner)})" if r.learner != "-" else ""
        lines.append(f"{console_text(Path(r.path).name)}{who}:")
        for c in failed:
            text, check = _first_line(c.message).removeprefix("CheckFailed: "), console_text(c.check)
            line = text if text.startswith(f"{check}:") else f"{check}: {text}"
            lines.append(_wrapped(line) if wrap else f"  {line}")
    return lines


def format_summary(results: list[NotebookResult]) -> str:
    """Counts per status and the mean points per chapter."""
    counts = Counter(console_text(r.status) for r in results)
    lines = ["submissions: " + ", ".join(f"{n} {status}" for status, n in sorted(counts.items()))]
    flagged = sum(1 for r in results if r.flags)
    if flagged:
        lines.append(f"flagged for review: {flagged} (the 'review:' lines, the gradebook's flags column)")
    by_chapter = defaultdict(list)
    for r in results:
        if r.status in RAN_TO_THE_END:
            by_chapter[console_text(r.chapter)].append(r)
    for chapter, rs in sorted(by_chapter.items()):
        mean = sum(r.points for r in rs) / len(rs)
        line = f"chapter {chapter}: {len(rs)} graded, mean {mean:.1f}/{rs[0].possible} points"
        if rs[0].challenge_possible:
            done = sum(r.challenge_points == r.challenge_possible for r in rs)
            line += f"; optional challenge done by {done} of {len(rs)}"
        lines.append(line)
    return "\n".join(lines)


def ungraded_lines(results: list[NotebookResult]) -> list[str]:
    """One console line per file that could not be read as a notebook, naming it and why (the
    error lines a grading run ends with)."""
    return [console_text(f"{r.path} was not graded: {r.detail}; expected a Jupyter notebook")
            for r in results if r.status == NOT_A_NOTEBOOK]


# --- who is who, and where the gradebooks may go ----------------------------------------------

def feedback_name(learner: str) -> str:
    """A learner's feedback file name, without ``.md``: ``feedback`` when grading yourself
    (``"-"``); otherwise anything but letters, digits, ``.``, ``-`` and ``_`` becomes ``_``."""
    return "feedback" if learner in ("-", "") else (re.sub(r"[^\w.-]", "_", learner) or "_")


def _layout(path, roots) -> str:
    """How a class folder names this notebook's learner: by a folder of their own, or by file name."""
    for root in roots:
        try:
            parts = Path(path).relative_to(root).parts
        except ValueError:
            continue
        return "folder" if len(parts) > 1 else "file name"
    return "file name"  # a notebook given on its own


def refuse_clashing_learners(submissions: list[tuple], roots=()) -> None:
    """Refuse a class whose learners its gradebooks could not tell apart.

    ``submissions``: (path, learner) pairs; ``roots``: the class folders they were found in.

    Raises
    ------
    ValueError
        Naming both, if two learners share a feedback file name (``a b`` and ``a_b``; letter
        case counts as the same, since feedback folders travel to case-insensitive disks), or
        if one learner has notebooks in both layouts (``SUBMISSIONS/alice/...`` and
        ``SUBMISSIONS/alice__03_x.ipynb``), which would give them two rows for one chapter.
    """
    problems = []
    by_file = defaultdict(set)
    for _, learner in submissions:
        by_file[feedback_name(learner).casefold()].add(learner)
    for learners in by_file.values():
        if len(learners) > 1:
            names = sorted(learners)
            problems.append(f"learners {' and '.join(map(_quoted, names))} would share one feedback file, "
                            f"{feedback_name(names[0])}.md: rename one of them")
    layouts = defaultdict(dict)
    for path, learner in submissions:
        if learner != "-":
            layouts[learner].setdefault(_layout(path, roots), path)
    for learner, found in sorted(layouts.items()):
        if len(found) > 1:
            problems.append(f"learner {_quoted(learner)} is in both layouts: {_quoted(found['folder'])} "
                            f"(a folder of their own) and {_quoted(found['file name'])} (named by learner): "
                            "keep one")
    if problems:
        raise ValueError("learners the gradebooks could not tell apart (nothing written):\n"
                         + "\n".join(f"  {p}" for p in problems))


def _identity(path: Path):
    """What tells two paths apart: the resolved path, and the file's device and inode when it exists."""
    try:
        stat = path.stat()
    except OSError:
        return path.resolve(), None
    return path.resolve(), (stat.st_dev, stat.st_ino)


def refuse_unsafe_outputs(csv_path=None, json_path=None, feedback_dir=None, *, learners=(), protected=(),
                          release=None) -> None:
    """Refuse gradebook outputs that would overwrite what they must not.

    ``learners``: whose feedback files ``feedback_dir`` will get; ``protected``: files never to
    be overwritten (the submissions being graded, the shards being merged); ``release``: the
    released exercises' folder, where nothing is written.

    Raises
    ------
    ValueError
        Naming each output that is one of the protected files, lies inside the release folder,
        is an existing folder where a file goes (or a file where the folder goes), would be made
        in a folder that is a file, or is given to both ``--csv`` and ``--json``.
    """
    files = [(option, Path(p)) for option, p in (("--csv", csv_path), ("--json", json_path)) if p]
    problems = [f"{option} {path} is a folder" for option, path in files if path.is_dir()]
    if len(files) == 2 and files[0][1].resolve() == files[1][1].resolve():
        problems.append(f"--csv and --json name the same file, {files[0][1]}")
    places = list(files)  # everything written or made: the files, and the feedback folder itself
    if feedback_dir:
        folder = Path(feedback_dir)
        if folder.exists() and not folder.is_dir():
            problems.append(f"--feedback {folder} is a file, not a folder")
        places.append(("--feedback", folder))
        files += [("--feedback", folder / f"{feedback_name(learner)}.md") for learner in sorted(set(learners))]
    problems += [f"{option} {path}: {blocked} is a file, not a folder" for option, path in places
                 if (blocked := blocking_file(path)) is not None]
    kept = [_identity(Path(p)) for p in protected]
    kept_paths, kept_files = {p for p, _ in kept}, {f for _, f in kept if f}
    for option, path in files:
        resolved, file = _identity(path)
        if resolved in kept_paths or (file and file in kept_files):
            problems.append(f"{option} {_quoted(path)} is one of the files being read (a submission or a "
                            "shard): it would be overwritten")
    if release:
        release = Path(release).resolve()
        problems += [f"{option} {path} is inside the release folder {release}"
                     for option, path in places if path.resolve().is_relative_to(release)]
    if problems:
        raise ValueError("refusing to write the gradebooks (nothing written):\n"
                         + "\n".join(f"  {p}" for p in dict.fromkeys(problems)))


# --- the CSV, the JSON and the feedback, as text ----------------------------------------------

_CSV_HEADER = ["learner", "notebook", "chapter", "status", "points", "possible", "challenge_points",
               "challenge_possible", "checks", "tampered", "readded", "flags", "hint"]


def csv_text(results: list[NotebookResult]) -> str:
    """One row per notebook: learner, chapter, status, points, each check's points, restored
    cells, review flags, the first hint. Every text cell is quoted (a separator inside it
    cannot start a cell, whatever separator a spreadsheet expects) and neutralised by
    :func:`csv_cell`; numbers are written bare."""
    buffer = io.StringIO()
    csv.writer(buffer).writerow(_CSV_HEADER)  # our own words: no quotes needed
    rows = csv.writer(buffer, quoting=csv.QUOTE_NONNUMERIC)
    for r in results:
        rows.writerow([csv_cell(cell) for cell in (
            r.learner, r.path, r.chapter, r.status, r.points, r.possible, r.challenge_points, r.challenge_possible,
            ";".join(f"{c.check}={c.points}/{c.possible}" for c in r.checks),
            ";".join(r.tampered), ";".join(r.readded), " | ".join(r.flags), r.hint)])
    return buffer.getvalue()


def run_record(roster, *, sandbox: str, seed: int, shard: tuple[int, int] | None = None,
               interrupted: bool = False, hint_tier: int = 1) -> dict:
    """What a JSON gradebook says about the run that wrote it.

    Parameters
    ----------
    roster : list of (str, str)
        (learner, notebook path) of the *whole* class, in the class's order (a result's
        ``order`` is its place here); a shard's gradebook carries it, so that merging can
        tell which learners each shard must hold.
    sandbox : str
        What the learners' kernels ran in, as the caller states it (``"none (--no-sandbox)"``).
    seed : int
        The run seed the checks drew their inputs from (:mod:`kalman_course.checks.cases`):
        grading again with it gives every check the same inputs.
    shard : (int, int), optional
        (K, N) when the run graded shard K of N.
    interrupted : bool
        Whether the run was stopped before every notebook was graded.
    hint_tier : int
        How much the hints say (:data:`kalman_course.checks.hints.TIERS`): 1, the concept and
        the lecture section; 2, the formulas too (``--all-hints``).
    """
    return {"sandbox": str(sandbox), "seed": int(seed), "shard": f"{shard[0]}/{shard[1]}" if shard else None,
            "class_size": len(roster), "class": [[str(learner), str(path)] for learner, path in roster],
            "interrupted": bool(interrupted), "hint_tier": int(hint_tier)}


def _record(r: NotebookResult) -> dict:
    record = dict(asdict(r), points=r.points, possible=r.possible, challenge_points=r.challenge_points,
                  challenge_possible=r.challenge_possible, hint=r.hint)
    del record["seconds"]  # it would differ between two runs
    for c in record["checks"]:
        if c["in_kernel"] is None:
            del c["in_kernel"]
    return record


def signature(document: dict, key: bytes) -> str:
    """The HMAC-SHA256, with ``key``, of everything in ``document`` but its signature, serialised
    canonically (sorted keys, no spaces, ASCII), so that reading and writing again changes nothing."""
    signed = {name: value for name, value in document.items() if name != "signature"}
    canonical = json.dumps(signed, sort_keys=True, separators=(",", ":"), ensure_ascii=True, allow_nan=False)
    return _SIGNATURE_PREFIX + hmac.new(key, canonical.encode("ascii"), hashlib.sha256).hexdigest()


def json_text(results: list[NotebookResult], run: dict, key: bytes | None = None) -> str:
    """The JSON gradebook: ``{"format", "version", "run", "results", "signature"}``, every check's
    message included; signed with ``key`` (``"signature": null`` without one)."""
    document = {"format": FORMAT, "version": VERSION, "run": run, "results": [_record(r) for r in results]}
    document["signature"] = signature(document, key) if key else None
    return json.dumps(document, indent=1) + "\n"


def feedback_files(results: list[NotebookResult]) -> dict[str, str]:
    """File name -> Markdown: one feedback file per learner with every failed check's message."""
    per_learner = defaultdict(list)
    for r in results:
        per_learner[r.learner or "-"].append(r)
    files = {}
    for learner, rs in sorted(per_learner.items()):
        name = f"{feedback_name(learner)}.md"
        if name in files:  # refused before grading; never let one learner's file replace another's
            raise ValueError(f"two learners would share the feedback file {name}: rename one of them")
        files[name] = _feedback(learner, rs)
    return files


def _feedback(learner: str, results: list[NotebookResult]) -> str:
    lines = ["# Feedback" if learner == "-" else f"# Feedback for {markdown_text(learner)}", ""]
    for r in sorted(results, key=lambda r: (r.chapter, r.path)):
        lines += _feedback_section(r)
    return "\n".join(lines)


def _item(head: str, text, joiner: str) -> list[str]:
    """A list item: ``head`` (our Markdown), then the learner's ``text`` (escaped; its lines after
    the first in a fenced block inside the item)."""
    first, block = _markdown_lines(text)
    return [f"- {head}{joiner + first if first else ''}", *block]


def _feedback_section(r: NotebookResult) -> list[str]:
    lines = [f"## Chapter {markdown_text(r.chapter) or '?'}: {markdown_code(Path(r.path).name)}", "",
             f"{r.points}/{r.possible} points — {markdown_text(r.status)}", ""]
    if r.challenge_possible:
        lines += [f"Optional challenge: {r.challenge_points}/{r.challenge_possible} points "
                  "(counted apart from the points above).", ""]
    if r.status not in RAN_TO_THE_END:
        first, block = _markdown_lines(r.detail, indent="")
        lines += [f"The notebook could not be graded to the end: {first}.", *block, ""]
    if r.tampered or r.readded:
        lines += ["Grader cells were restored from the released exercise before grading "
                  f"(edited: {', '.join(map(markdown_text, r.tampered)) or 'none'}; "
                  f"missing: {', '.join(map(markdown_text, r.readded)) or 'none'}).", ""]
    if r.flags:
        lines += ["Flagged for review by hand (the points above are what the checks gave):", ""]
        lines += [line for flag in r.flags for line in _item("", flag, "")] + [""]
    lines += [line for error in r.learner_errors for line in _item("your", error, " ")]
    if r.learner_errors:
        lines.append("")
    for c in r.checks:
        mark = "passed" if c.points == c.possible else ("not done" if c.challenge else "failed")
        label = "optional challenge " if c.challenge else ""
        lines += _item(f"**{markdown_text(c.check)}** ({label}{c.points}/{c.possible}): {mark}", c.message, " — ")
    lines.append("")
    return lines


# --- writing ----------------------------------------------------------------------------------

def write_file(path, text: str) -> None:
    """Write ``text`` to ``path`` atomically: into a new file beside it, flushed to the disk, then
    renamed over it. A reader, or a crash, finds the old file or the new one, never a part; a
    symlink planted at ``path`` is replaced, not followed."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    temporary = path.with_name(f".{path.name}.{secrets.token_hex(8)}.tmp")
    # O_EXCL: never a file or link that is already there; 0o666 less the umask, as for any new file
    fd = os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(text.encode("utf-8"))
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(temporary, path)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise


def write_gradebooks(results: list[NotebookResult], run: dict, key: bytes | None = None, *,
                     csv_path=None, json_path=None, feedback_dir=None) -> list[str]:
    """Write the gradebooks asked for, each file atomically; return a line per output written.

    Every text is made before the first file is touched, so a failure while making them writes
    nothing. ``run`` and ``key``: see :func:`run_record` and :func:`json_text`.
    """
    texts, said = {}, []
    if csv_path:
        texts[Path(csv_path)] = csv_text(results)
        said.append(f"wrote {csv_path}")
    if json_path:
        texts[Path(json_path)] = json_text(results, run, key)
        said.append(f"wrote {json_path}")
    if feedback_dir:
        files = feedback_files(results)
        texts.update({Path(feedback_dir) / name: text for name, text in files.items()})
        said.append(f"wrote {len(files)} feedback file(s) to {feedback_dir}")
        Path(feedback_dir).mkdir(parents=True, exist_ok=True)  # even for an empty class
    for path, text in texts.items():
        write_file(path, text)
    return said


# --- the key ------------------------------------------------------------------------------------

def load_key(key_file=None, environ=None) -> bytes | None:
    """The instructor's signing key: the contents of ``key_file`` (surrounding whitespace
    stripped), else the environment variable :data:`KEY_VARIABLE`; ``None`` if neither is set.

    Raises
    ------
    ValueError
        If ``key_file`` cannot be read, is empty, or (on POSIX) can be read or written by anyone
        but its owner: a key others can read signs nothing.
    """
    if key_file:
        path = Path(key_file)
        try:
            mode, key = path.stat().st_mode, path.read_bytes().strip()
        except OSError as exc:
            raise ValueError(f"--key-file {key_file}: cannot read it ({exc.strerror or exc})") from None
        if os.name == "posix" and mode & 0o077:
            raise ValueError(f"--key-file {key_file} can be read or written by others than its owner "
                             f"(mode {mode & 0o777:o}): chmod 600 {key_file}")
        if not key:
            raise ValueError(f"--key-file {key_file} is empty")
        return key
    value = (os.environ if environ is None else environ).get(KEY_VARIABLE, "")
    return value.encode("utf-8") or None  # an empty variable (an undefined CI secret) is no key


# --- reading ------------------------------------------------------------------------------------

@dataclass
class Gradebook:
    """A JSON gradebook as read (:func:`read_json`)."""

    path: str
    run: dict
    results: list[NotebookResult]
    records: list[dict]  # the results as written, with the totals they state
    document: dict  # everything the signature covers, as read
    signature: str | None


#: Types of the fields a record holds (a field added to the dataclasses later is read unchecked).
_TYPES = {"path": str, "learner": str, "chapter": str, "status": str, "checks": list, "tampered": list,
          "readded": list, "learner_errors": list, "flags": list, "detail": str, "order": int, "class_size": int,
          "points": int, "possible": int, "challenge_points": int, "challenge_possible": int, "hint": str}
_CHECK_TYPES = {"check": str, "cell_id": str, "points": int, "possible": int, "message": str, "challenge": bool,
                "in_kernel": bool}
_TOTALS = ("points", "possible", "challenge_points", "challenge_possible", "hint")
_RESULT_FIELDS = [name for name in NotebookResult.__dataclass_fields__ if name != "seconds"]
_CHECK_FIELDS = list(CheckResult.__dataclass_fields__)


def _unique_keys(pairs):
    """A JSON object, refusing a repeated key (a reader would see one value, the parser another)."""
    keys = [k for k, _ in pairs]
    if len(set(keys)) < len(keys):
        raise ValueError(f"a key appears twice in one object: {sorted(k for k in keys if keys.count(k) > 1)[0]!r}")
    return dict(pairs)


def _no_constant(name):
    raise ValueError(f"{name} is not a number a gradebook holds")


def _fields_problem(record, types: dict, required, optional, where: str) -> str:
    if not isinstance(record, dict):
        return f"{where} is not an object"
    missing = [name for name in required if name not in record]
    extra = sorted(set(record) - set(required) - set(optional))
    if missing or extra:
        return f"{where} " + ("lacks " + ", ".join(missing) if missing else "has unknown fields " + ", ".join(extra))
    for name, value in record.items():
        if name in types and type(value) is not types[name]:
            return f"{where}.{name} is of type {type(value).__name__}, not {types[name].__name__}"
    return ""


def _run_problem(run) -> str:
    types = {"sandbox": str, "seed": int, "class_size": int, "class": list, "interrupted": bool}
    if not isinstance(run, dict):
        return "run is not an object"
    # hint_tier is newer than the format: a gradebook without it was graded at tier 1
    problem = _fields_problem(run, {**types, "hint_tier": int}, [*types, "shard"], ["hint_tier"], "run")
    if not problem and run.get("hint_tier", 1) not in (1, 2):
        problem = f"run.hint_tier is {run['hint_tier']!r}, not 1 or 2"
    if problem:
        return problem
    if run["shard"] is not None and _shard_numbers(run["shard"]) is None:
        return f"run.shard is {run['shard']!r}, not K/N with 1 <= K <= N"
    if not all(isinstance(e, list) and len(e) == 2 and all(isinstance(x, str) for x in e) for e in run["class"]):
        return "run.class is not a list of [learner, notebook] pairs"
    return ""


def _record_name(record) -> str:
    """``learner 'alice' ('class/alice/03_kf.ipynb'): `` of a result record, as far as it says."""
    if not isinstance(record, dict):
        return ""
    named = [f"learner {_quoted(record['learner'])}" if isinstance(record.get("learner"), str) else "",
             f"({_quoted(record['path'])})" if isinstance(record.get("path"), str) else ""]
    return " ".join(word for word in named if word) + ": " if any(named) else ""


def _record_problem(record, i: int) -> str:
    where = f"results[{i}]"
    problem = _fields_problem(record, _TYPES, [*_RESULT_FIELDS, *_TOTALS], [], where)
    for name in ("tampered", "readded", "learner_errors", "flags"):
        if not problem and not all(isinstance(x, str) for x in record[name]):
            problem = f"{where}.{name} is not a list of strings"
    for j, check in enumerate(record["checks"] if not problem else []):
        problem = problem or _fields_problem(check, _CHECK_TYPES, [f for f in _CHECK_FIELDS if f != "in_kernel"],
                                             ["in_kernel"], f"{where}.checks[{j}]")
    return problem and _record_name(record) + problem


def _document_problem(document) -> str:
    """What makes ``document`` no gradebook this version wrote ('' if nothing)."""
    if isinstance(document, list):
        return "a list of results: a gradebook of an earlier version, grade again with this one"
    if not isinstance(document, dict) or document.get("format") != FORMAT:
        return f"its format is not {FORMAT!r}"
    if document.get("version") != VERSION:
        return f"version {document.get('version')!r}; this course reads version {VERSION}"
    if set(document) != {"format", "version", "run", "results", "signature"}:
        return "its fields are " + ", ".join(sorted(document)) + ", not format, version, run, results, signature"
    if document["signature"] is not None and not (isinstance(document["signature"], str)
                                                  and document["signature"].startswith(_SIGNATURE_PREFIX)):
        return "its signature is not an HMAC-SHA256 of this course"
    if not isinstance(document["results"], list):
        return "its results are not a list"
    return _run_problem(document["run"]) or next(
        (p for i, record in enumerate(document["results"]) if (p := _record_problem(record, i))), "")


#: What a gradebook file must be, as the errors say it.
GRADEBOOK = "a gradebook written by `kalman-course grade --json`"


class GradebookError(InputError):
    """A file is not a JSON gradebook of this course (the message names it and says why)."""

    template = "{path}: not {expected} ({problem})"

    def __init__(self, path, problem: str, expected: str = GRADEBOOK):
        super().__init__(path, problem, expected)


def read_json(path) -> Gradebook:
    """A gradebook written by :func:`json_text` (a whole class's or one shard's), checked for shape.

    Whether it is honest (signature, numbering, learners, points) is checked by
    :func:`merge_results`.

    Raises
    ------
    GradebookError
        If the file is not such a gradebook (the message names the file and what is wrong), or
        is missing, a folder, unreadable, empty or not UTF-8.
    """
    text = read_text(path, GRADEBOOK, GradebookError)  # missing, a folder, unreadable, empty, not UTF-8
    try:
        document = json.loads(text, object_pairs_hook=_unique_keys, parse_constant=_no_constant)
    except ValueError as exc:  # not JSON, a key twice, NaN or Infinity
        problem = f"{type(exc).__name__}: {exc}"
    else:
        problem = _document_problem(document)
    if problem:
        raise GradebookError(path, problem)
    results = []
    for record in document["results"]:
        fields = {name: record[name] for name in _RESULT_FIELDS}
        fields["checks"] = [CheckResult(**check) for check in record["checks"]]
        results.append(NotebookResult(**fields))
    return Gradebook(str(path), document["run"], results, document["results"],
                     {k: v for k, v in document.items() if k != "signature"}, document["signature"])


# --- merging ------------------------------------------------------------------------------------

@dataclass
class Merged:
    """A class's results merged from its shards (:func:`merge_results`)."""

    results: list[NotebookResult]
    run: dict
    key: bytes | None  # what signs the class's gradebook: None when some shard went unverified
    notices: list[str]


def _shard_numbers(text) -> tuple[int, int] | None:
    """(K, N) of ``"K/N"``, or None if it is not one."""
    m = re.fullmatch(r"([0-9]+)/([0-9]+)", text) if isinstance(text, str) else None
    k, n = (int(m.group(1)), int(m.group(2))) if m else (0, 0)
    return (k, n) if 1 <= k <= n else None


def _holding(book: Gradebook) -> str:
    names = sorted({r.learner for r in book.results})
    more = f" and {len(names) - 5} more" if len(names) > 5 else ""
    return f"its learners: {', '.join(map(_quoted, names[:5]))}{more}" if names else "it holds no learner"


def _signature_problems(book: Gradebook, key: bytes | None, unsigned: bool, notices: list[str]) -> list[str]:
    """Problems of ``book``'s signature (a notice instead when ``unsigned`` lets one pass unchecked)."""
    if book.signature is None:
        if unsigned:
            notices.append(f"{book.path} is unsigned: its points were not verified (--unsigned)")
            return []
        return [f"{book.path} is unsigned (graded without a key), so nothing shows its points are the ones "
                "graded: grade it with KALMAN_COURSE_GRADEBOOK_KEY or --key-file set, or merge with --unsigned"]
    if key is None:
        if unsigned:
            notices.append(f"{book.path} is signed, but no key was given: its signature was not checked (--unsigned)")
            return []
        return [f"{book.path} is signed, but no key was given to check it: set KALMAN_COURSE_GRADEBOOK_KEY "
                "or pass --key-file"]
    if not hmac.compare_digest(book.signature, signature(book.document, key)):
        return [f"{book.path}: its signature does not verify: the file was changed after grading (points, "
                f"messages, learners, anything), or signed with another key ({_holding(book)})"]
    return []


def _run_problems(books: list[Gradebook]) -> list[str]:
    """Every shard of one class, graded the same way, none interrupted."""
    problems, first = [], books[0]
    for book in books:
        if book.run["interrupted"]:
            problems.append(f"{book.path}: the run that wrote it was interrupted, so some of its notebooks were "
                            "never graded: grade it again")
        if book.run["class_size"] != len(book.run["class"]):
            problems.append(f"{book.path}: its run says the class has {book.run['class_size']} notebooks, "
                            f"its class roster lists {len(book.run['class'])}")
    for book in books[1:]:
        ours, theirs = set(map(tuple, first.run["class"])), set(map(tuple, book.run["class"]))
        if book.run["class"] != first.run["class"]:
            differ = [f"{_quoted(learner)} ({_quoted(path)}) only in {where}" for where, entries in
                      ((first.path, ours - theirs), (book.path, theirs - ours)) for learner, path in sorted(entries)]
            problems.append(f"{book.path} is of another class than {first.path}: "
                            + ("; ".join(differ[:6]) or "the same notebooks in another order"))
        for name in sorted((set(first.run) | set(book.run)) - {"shard", "class", "class_size", "interrupted"}):
            if first.run.get(name) != book.run.get(name):
                problems.append(f"{book.path} was graded with {name} {book.run.get(name)!r}, {first.path} with "
                                f"{first.run.get(name)!r}: grade every shard of a class the same way")
    return problems


def _numbering_problems(books: list[Gradebook]) -> list[str]:
    """Shards numbered 1/N .. N/N, each once; a whole class's gradebook only on its own."""
    problems = []
    numbered = [(book, _shard_numbers(book.run["shard"])) for book in books]
    if len(books) > 1:
        problems += [f"{book.path} is a whole class's gradebook (graded without --shard); it merges only on its own"
                     for book, kn in numbered if kn is None]
    numbered = [(book, kn) for book, kn in numbered if kn is not None]
    parts = sorted({n for _, (_, n) in numbered})
    if len(parts) > 1:  # e.g. a shard renumbered as 1/1, the whole class, beside the others
        return problems + ["the shards disagree on how many parts the class was dealt into: "
                           + ", ".join(f"{book.path} says {k}/{n}" for book, (k, n) in numbered)]
    if not parts:
        return problems
    n, by_k = parts[0], defaultdict(list)
    for book, (k, _) in numbered:
        by_k[k].append(book.path)
    problems += [f"{' and '.join(paths)} all say they are shard {k}/{n}"
                 for k, paths in sorted(by_k.items()) if len(paths) > 1]
    missing = [f"{k}/{n}" for k in range(1, n + 1) if k not in by_k]
    if missing:
        problems.append(f"shard {', '.join(missing)} is missing: no gradebook of it was given")
    return problems


def _learner_problems(book: Gradebook) -> list[str]:
    """``book`` holds exactly the notebooks its signed roster deals to its shard, each once."""
    roster = [tuple(entry) for entry in book.run["class"]]
    k, n = _shard_numbers(book.run["shard"]) or (1, 1)
    everyone = [(path, learner) for learner, path in roster]
    dealt = {i: part for part in range(1, n + 1) for i in shard_of(everyone, part, n)}
    where = f"{book.path} (shard {k}/{n})"
    seen = Counter(r.order for r in book.results)
    problems = []
    for r in book.results:
        if not 0 <= r.order < len(roster) or roster[r.order] != (r.learner, r.path):
            problems.append(f"{where} holds {_who(r)}, who is not in the class roster it was signed with "
                            "(at that place)")
        elif dealt[r.order] != k:
            problems.append(f"{where} holds {_who(r)}, whom the class roster deals to shard {dealt[r.order]}/{n}")
        elif seen[r.order] > 1:
            problems.append(f"{where} holds {_who(r)} {seen.pop(r.order)} times")
        if r.class_size != book.run["class_size"]:
            problems.append(f"{where}: {_who(r)} says the class has {r.class_size} notebooks, "
                            f"its run says {book.run['class_size']}")
    for i in sorted(i for i, part in dealt.items() if part == k and i not in seen):
        learner, path = roster[i]
        problems.append(f"{where} lacks learner {_quoted(learner)} ({_quoted(path)}), whom the class roster "
                        "deals to this shard")
    return problems


def _points_problems(book: Gradebook) -> list[str]:
    """Every check gives 0 or all of its points, and each notebook's totals add up."""
    problems = []
    for r, record in zip(book.results, book.records):
        who = f"{book.path}: {_who(r)}"
        for c in r.checks:
            points = f"check {_quoted(c.check)} records {c.points}/{c.possible} points"
            if c.possible < 0 or c.points < 0:
                problems.append(f"{who}: {points}, which is negative")
            elif c.points > c.possible:
                problems.append(f"{who}: {points}, more than the check is worth")
            elif c.points not in (0, c.possible):
                problems.append(f"{who}: {points}; a check gives 0 or all of its points")
        for name in _TOTALS:
            if record[name] != getattr(r, name):
                problems.append(f"{who}: its {name} reads {record[name]!r}, but its checks make it "
                                f"{getattr(r, name)!r}")
    return problems


def merge_results(books: list[Gradebook], key: bytes | None = None, *, unsigned: bool = False) -> Merged:
    """One class's results from its shards' gradebooks, in the order one run gives.

    ``key``: the instructor's key, which every signature must verify with; ``unsigned``: let a
    shard whose signature cannot be checked (none, or no key) pass, with a notice. The class's
    run record is the shards' with no shard number, as one run writes it; it is signed with
    ``key`` only if every shard's signature verified.

    Raises
    ------
    ValueError
        Naming the file and the learner, if a signature does not verify, the shards' numbering
        is not 1/N .. N/N each once, a shard does not hold exactly the learners its signed class
        roster deals to it, the shards are of different classes or runs, a run was interrupted,
        or a check's points are neither 0 nor its possible (above it, negative) or a total does
        not add up.
    """
    if not books:
        raise ValueError("no gradebooks to merge")
    notices, problems = [], []
    for book in books:
        problems += _signature_problems(book, key, unsigned, notices)
    problems += _run_problems(books) + _numbering_problems(books)
    for book in books:
        problems += _learner_problems(book) + _points_problems(book)
    if problems:
        raise ValueError("the gradebooks do not merge (nothing written):\n"
                         + "\n".join(f"  {p}" for p in dict.fromkeys(problems)))
    verified = key is not None and all(book.signature is not None for book in books)
    if not verified:
        notices.append("the merged gradebook is unsigned: some shard's signature was not checked")
    results = sorted((r for book in books for r in book.results), key=lambda r: r.order)
    return Merged(results, dict(books[0].run, shard=None), key if verified else None, notices)
