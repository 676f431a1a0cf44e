"""Reasons to look at a graded submission by hand, found by reading its code.

Grading runs the learner's notebook, so code that passes a check without doing the work
can earn the points: importing the function the exercise asks for (the course ships its
reference implementations) or changing the grading code from an earlier cell. Neither can
be prevented inside the kernel, but both are visible in the source. :func:`review_flags`
reads every non-grader code cell that differs from the released exercise and reports

- an import of a function the learner must write (one defined in a released cell with a
  ``# fix this`` line), or a binding or call of such a function through a module
  attribute (``histogram_update = bayes.histogram_update``);
- an import of the grading machinery (``kalman_course.checks``, ``kalman_course.tooling.grading``,
  nbval) that the release does not make, an assignment to an attribute of it, or
  ``setattr`` on it;
- an import of ``importlib`` or ``builtins``, or use of ``__builtins__`` or ``sys.modules``.

The flags never change points or status: they are shown to the instructor (and to a
learner grading themselves) next to the grade.
"""

from __future__ import annotations

import ast

from kalman_course.tooling.authoring import FIX_THIS, grader_info

__all__ = ["review_flags", "MACHINERY"]

#: Modules whose import by learner code is flagged: they run or report the checks.
MACHINERY = ("kalman_course.checks", "kalman_course.tooling.grading", "kalman_course.tooling.nbval_results", "nbval")
_ESCAPES = ("importlib", "builtins", "__builtins__")


def _parser():
    """A function source -> AST (IPython magics and shell escapes translated; None if the
    cell is not valid Python), parsing each distinct source once."""
    from IPython.core.inputtransformer2 import TransformerManager

    transformer, trees = TransformerManager(), {}

    def parse(source: str) -> ast.Module | None:
        if source not in trees:
            try:
                trees[source] = ast.parse(transformer.transform_cell(source))
            except (SyntaxError, ValueError):
                trees[source] = None  # the learner's own error; the run reports it
        return trees[source]

    return parse


def _is_machinery(module: str) -> bool:
    return any(module == m or module.startswith(m + ".") for m in MACHINERY)


def _dotted(node: ast.AST) -> str:
    """``a.b.c`` for a chain of attributes on a name, else ''."""
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if isinstance(node, ast.Name):
        return ".".join([node.id, *reversed(parts)])
    return ""


def _root(node: ast.AST) -> str:
    return _dotted(node).split(".", 1)[0]


def _machinery_names(tree: ast.Module) -> set[str]:
    """Names that a cell binds to the grading machinery (``from kalman_course import checks``)."""
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if _is_machinery(a.name):
                    names.add(a.asname or a.name.split(".", 1)[0])
        elif isinstance(node, ast.ImportFrom) and node.module:
            for a in node.names:
                if _is_machinery(node.module) or _is_machinery(f"{node.module}.{a.name}"):
                    names.add(a.asname or a.name)
    return names


def _cell_flags(tree: ast.Module, to_write: set[str], machinery: set[str]) -> set[str]:
    """The flags of one cell, without its id (so that they can be compared with the release)."""
    flags = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if _is_machinery(a.name) or a.name.split(".", 1)[0] in _ESCAPES:
                    flags.add(f"imports `{a.name}`")
        elif isinstance(node, ast.ImportFrom):
            module = node.module or ""
            for a in node.names:
                if a.name in to_write or (a.asname or "") in to_write:
                    flags.add(f"imports `{a.name}` from `{module}` instead of writing it")
                elif _is_machinery(module) or _is_machinery(f"{module}.{a.name}"):
                    flags.add(f"imports `{a.name}` from `{module}`")
                elif module.split(".", 1)[0] in _ESCAPES:
                    flags.add(f"imports from `{module}`")
        elif isinstance(node, (ast.Assign, ast.AugAssign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for target in targets:
                for t in ast.walk(target):
                    if isinstance(t, ast.Attribute) and _root(t) in machinery:
                        flags.add(f"assigns to `{_dotted(t)}`, part of the grading code")
                    elif isinstance(t, ast.Name) and t.id in to_write and _dotted(node.value).count("."):
                        flags.add(f"binds `{t.id}` to `{_dotted(node.value)}` instead of writing it")
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ("setattr", "delattr"):
            if node.args and _root(node.args[0]) in machinery:
                flags.add(f"calls `{node.func.id}` on `{_dotted(node.args[0])}`, part of the grading code")
        elif isinstance(node, ast.Attribute) and _dotted(node) == "sys.modules":
            flags.add("uses `sys.modules`")
        elif isinstance(node, ast.Name) and node.id == "__builtins__":
            flags.add("uses `__builtins__`")
        if isinstance(node, ast.FunctionDef) and node.name in to_write:
            for inner in ast.walk(node):
                if isinstance(inner, ast.Attribute) and inner.attr == node.name and _dotted(inner):
                    flags.add(f"`{node.name}` calls `{_dotted(inner)}` instead of doing the work")
    return flags


def _functions_to_write(release, parse) -> set[str]:
    names = set()
    for cell in release.cells:
        if cell.cell_type == "code" and FIX_THIS in cell.source and (tree := parse(cell.source)):
            names |= {n.name for n in ast.walk(tree) if isinstance(n, ast.FunctionDef)}
    return names


def review_flags(submission, release) -> list[str]:
    """Reasons to review ``submission`` by hand, one line each (empty when there are none).

    Parameters
    ----------
    submission : nbformat.NotebookNode
        The learner's notebook (grader cells are skipped: grading restores them).
    release : nbformat.NotebookNode
        The released exercise of the same chapter.

    Returns
    -------
    list of str
        ``"cell <id>: <what the code does>"``, in cell order; flags that the released
        cell of the same id raises too are left out.
    """
    released = {c.get("id"): c for c in release.cells if c.cell_type == "code"}
    graders = {cid for cid, c in released.items() if grader_info(c)}
    parse = _parser()
    to_write = _functions_to_write(release, parse)
    machinery = set()
    for cell in [*release.cells, *submission.cells]:
        if cell.cell_type == "code" and (tree := parse(cell.source)):
            machinery |= _machinery_names(tree)

    out = []
    for cell in submission.cells:
        cid = cell.get("id")
        if cell.cell_type != "code" or cid in graders or grader_info(cell):
            continue
        original = released.get(cid)
        if original is not None and original.source == cell.source:
            continue
        tree = parse(cell.source)
        if tree is None:
            continue
        flags = _cell_flags(tree, to_write, machinery)
        if original is not None and (original_tree := parse(original.source)):
            flags -= _cell_flags(original_tree, to_write, machinery)
        out += [f"cell {cid}: {flag}" for flag in sorted(flags)]
    return out
