"""The ``kalman-course`` command line.

Subcommands
-----------
execute   run lecture/solution notebooks in place and store their outputs
build     write exercises/ from solutions/ (``--check`` verifies they are in sync)
grade     grade exercise notebooks and print a points table
data      rebuild the shipped KITTI excerpts from the PyPI packages
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def _cmd_execute(args: argparse.Namespace) -> int:
    from kalman_course.notebooks import execute_notebook

    paths = _expand_notebooks(args.paths)
    if not paths:
        print("error: no notebooks found in " + " ".join(args.paths), file=sys.stderr)
        return 2
    for i, path in enumerate(paths, 1):
        print(f"[{i}/{len(paths)}] executing {path} ...", flush=True)
        elapsed = execute_notebook(path, timeout=args.timeout)
        print(f"        done in {elapsed:.1f} s", flush=True)
    return 0


def _expand_notebooks(items: list[str]) -> list[Path]:
    """Turn files and folders into a sorted list of .ipynb files (checkpoints skipped)."""
    found: list[Path] = []
    for item in items:
        p = Path(item)
        if p.is_dir():
            found.extend(q for q in sorted(p.glob("*.ipynb")) if ".ipynb_checkpoints" not in q.parts)
        else:
            found.append(p)
    return found


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="kalman-course", description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("execute", help="run notebooks in place and store their outputs")
    p.add_argument("paths", nargs="+", help="notebooks or folders of notebooks")
    p.add_argument("--timeout", type=int, default=600, help="per-cell timeout in seconds (default 600)")
    p.set_defaults(func=_cmd_execute)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    return args.func(args)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
