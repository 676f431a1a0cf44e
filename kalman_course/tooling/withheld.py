"""The build of the package a graded kernel runs: the chapter's references withheld.

The course ships reference implementations of every function its exercises ask for (the
lectures and the checks need them), so a learner's kernel could reach them by import, by
alias, through ``gc`` or ``sys.modules``, or read their source. While grading, the kernel
therefore runs on a *guarded build* of the package (mounted in the sandbox where the package
is, or first on the kernel's path without one), made by :func:`build_guarded`:

- every function the exercise's ``# fix this`` cells define, wherever the package has one of
  that name, and every twin :data:`TWINS` lists for the chapter's checks (the package's
  functions that pass those checks under another name), keeps its signature and decorators
  but its docstring and body are replaced by a call of :func:`kalman_course.core.withheld.withheld`,
  which raises and records the calling cell;
- ``kalman_course.checks`` holds only the agent that answers the grading process
  (``kernel_agent``, ``plain_data``): the checks and their references run in the grading
  process (a check hands the learner's function only package code that the build keeps,
  which the tests verify);
- ``kalman_course.tooling`` (the grading tool itself) is left out;
- no ``__pycache__`` of the real package is copied (the build is compiled afresh).

Package code the exercises legitimately use (``so3``, the data loaders, plotting) is copied
unchanged; the tests grade every solution on its guarded build.
"""

from __future__ import annotations

import ast
import py_compile
import shutil
import sys
from pathlib import Path

from kalman_course.tooling.cells import FIX_THIS

__all__ = ["TWINS", "functions_to_write", "withheld_functions", "build_guarded"]

#: The package's own folder.
PACKAGE = Path(__file__).resolve().parent.parent

#: Folders of the package not copied into a guarded build (the grading machinery).
_LEFT_OUT = ("tooling",)
#: Modules of ``kalman_course.checks`` a graded kernel needs: the agent and its data protocol.
_AGENT_MODULES = ("kernel_agent.py", "plain_data.py")

#: Twins under other names: check → functions of the package that pass it (found by running
#: every package function of a fitting signature through each check; see tests/test_withheld.py),
#: or that the exercise's function is built from in one line.
TWINS: dict[str, tuple[str, ...]] = {
    "histogram_update": ("kalman_course.filters.bayes.histogram_update",),
    "histogram_predict": ("kalman_course.filters.bayes.histogram_predict",),
    "corridor_motion_model": ("kalman_course.filters.bayes.circular_motion_model",),
    "conditional_mean": ("kalman_course.core.gaussians.conditional",),
    "conditional_covariance": ("kalman_course.core.gaussians.conditional",),
    "linear_map_moments": ("kalman_course.core.gaussians.linear_map",),
    "gaussian_fusion": ("kalman_course.core.gaussians.product",),
    "cv_process_noise": ("kalman_course.symbolic.kalman.cv_process_noise",),
    "kf_predict": ("kalman_course.filters.kf.kf_predict",),
    "kf_gain": ("kalman_course.filters.kf.kf_gain", "kalman_course.filters.eskf._gain"),
    "kf_update": ("kalman_course.filters.kf.kf_update",),
    "ctrv_step": ("kalman_course.symbolic.motion.ctrv_step",),
    "ctrv_jacobian": ("kalman_course.symbolic.motion.ctrv_jacobian",),
    "radar_h": ("kalman_course.symbolic.radar.radar_observation",),
    "radar_jacobian": ("kalman_course.symbolic.radar.radar_jacobian",),
    "radar_residual": ("kalman_course.filters.ekf.radar_residual",),
    "ekf_update": ("kalman_course.filters.ekf.ekf_update",),
    "iekf_update": ("kalman_course.filters.ekf.iekf_update",),
    "eskf_error_dynamics": ("kalman_course.filters.eskf.error_dynamics",),
    "eskf_noise_jacobian": ("kalman_course.filters.eskf.noise_jacobian", "kalman_course.filters.eskf._noise_jacobian"),
    "eskf_discretisation": ("kalman_course.filters.eskf.discretise", "kalman_course.filters.eskf._discretise"),
    "eskf_propagate": ("kalman_course.filters.eskf.propagate_covariance",),
    "eskf_pose_residual": ("kalman_course.filters.eskf.pose_residual", "kalman_course.filters.eskf._pose_residual"),
    "eskf_gain": ("kalman_course.filters.eskf.kalman_gain",),
    "eskf_covariance_update": ("kalman_course.filters.eskf.update_covariance", "kalman_course.core.linalg.joseph_update",
                               "kalman_course.core.linalg.joseph_form",
                               "kalman_course.chapters.consistency.joseph_update"),
    "eskf_inject": ("kalman_course.filters.eskf.inject", "kalman_course.filters.eskf._inject"),
    "eskf_reset": ("kalman_course.filters.eskf.reset_covariance",),
    "nominal_ekf_jacobian": ("kalman_course.filters.nominal_ekf.continuous_jacobian",),
    "consistency_nees": ("kalman_course.evaluation.metrics.nees", "kalman_course.evaluation.metrics.nis"),
    "consistency_nis": ("kalman_course.evaluation.metrics.nis",),
    "chi2_interval": ("kalman_course.evaluation.metrics.chi2_bounds",),
    "innovation_gate": ("kalman_course.evaluation.consistency.gate",),
    "consistency_verdict": ("kalman_course.evaluation.consistency.verdict",),
    "relative_motion": ("kalman_course.filters.eskf_relative.relative_motion",
                        "kalman_course.filters.eskf_relative._relative_motion"),
    "relative_pose_residual": ("kalman_course.filters.eskf_relative.relative_pose_residual",),
    "relative_pose_jacobian": ("kalman_course.filters.eskf_relative.relative_pose_jacobian",
                               "kalman_course.filters.eskf_relative._relative_jacobian"),
    "drift_segments": ("kalman_course.chapters.real_sensors.segment_errors",),
}

def _module_of(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _sources() -> dict[str, Path]:
    """Every module of the package a guarded build may hold: dotted name → file."""
    found = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE).parts
        if "__pycache__" in rel or rel[0] in _LEFT_OUT or rel[0] == "checks":
            continue
        found[_module_of(path)] = path
    return found


def functions_to_write(release) -> dict[str, int]:
    """The functions an exercise asks for (those its ``# fix this`` cells define): name → how
    many positional arguments a call of it passes (its parameters without a default)."""
    functions = {}
    for cell in release.cells:
        if cell.cell_type != "code" or FIX_THIS not in cell.source:
            continue
        try:
            tree = ast.parse(cell.source)
        except SyntaxError:  # a cell with magics: IPython's syntax, not Python's
            from IPython.core.inputtransformer2 import TransformerManager

            tree = ast.parse(TransformerManager().transform_cell(cell.source))
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                positional = [*node.args.posonlyargs, *node.args.args]
                functions[node.name] = len(positional) - len(node.args.defaults)
    return functions


def _accepts(node: ast.FunctionDef, count: int) -> bool:
    """Whether a call with ``count`` positional arguments fits the function ``node``."""
    positional = [*node.args.posonlyargs, *node.args.args]
    return len(positional) - len(node.args.defaults) <= count and (node.args.vararg or count <= len(positional))


def withheld_functions(learner_functions, check_names) -> dict[str, str]:
    """The package functions withheld for an exercise: dotted name → the exercise's function.

    Parameters
    ----------
    learner_functions : dict of str to int, or iterable of str
        The functions the exercise asks for (:func:`functions_to_write`). A package function
        of the same name is withheld when a call of the exercise's fits it (a namesake that
        takes other arguments is another function); with names only, whatever its arguments.
    check_names : iterable of str
        The checks of its grader cells.
    """
    arity = learner_functions if isinstance(learner_functions, dict) else dict.fromkeys(learner_functions)
    out = {}
    for module, path in _sources().items():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in tree.body:
            if (isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.name in arity
                    and (arity[node.name] is None or _accepts(node, arity[node.name]))):
                out[f"{module}.{node.name}"] = node.name
    for check in check_names:
        for dotted in TWINS.get(check, ()):
            out.setdefault(dotted, check)
    return out


def _guard_source(source: str, functions: dict[str, str], module: str, chapter: str) -> str:
    """``source`` with the bodies of its top-level ``functions`` (name → exercise function)
    replaced by a call of the guard, line numbers of everything else kept."""
    tree = ast.parse(source)
    lines = source.splitlines(keepends=True)
    edits = []
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.name in functions:
            first, last = node.body[0].lineno, node.body[-1].end_lineno
            indent = " " * node.body[0].col_offset
            call = (f"{indent}return __import__('kalman_course.core.withheld', fromlist=['withheld']).withheld("
                    f"{module + '.' + node.name!r}, {functions[node.name]!r}, {chapter!r})\n")
            if node.body[0].lineno == node.lineno:  # a one-line def: the body follows the colon
                head = lines[node.lineno - 1][:node.body[0].col_offset]
                edits.append((first, last, [head.rstrip() + "\n", " " * (node.col_offset + 4) + call.lstrip()]))
            else:
                edits.append((first, last, [call] + ["\n"] * (last - first)))
    missing = set(functions) - {node.name for node in tree.body if isinstance(node, (ast.FunctionDef,
                                                                                        ast.AsyncFunctionDef))}
    if missing:
        raise ValueError(f"{module} defines no top-level {sorted(missing)} (TWINS is out of date)")
    for first, last, new in sorted(edits, reverse=True):
        lines[first - 1:last] = new
    guarded = "".join(lines)
    ast.parse(guarded)  # a guard that breaks the module is a bug here, not at a learner's import
    return guarded


_CHECKS_INIT = '''"""While grading, the checks run in the grading process, outside this kernel."""


def __getattr__(name):
    raise AttributeError(f"kalman_course.checks.{name} is not available in a graded kernel: the "
                         "grader cells run outside it")
'''


def build_guarded(destination: str | Path, withheld: dict[str, str], chapter: str) -> Path:
    """Write a guarded build of the package under ``destination`` and return its folder.

    Parameters
    ----------
    destination : path
        An empty or missing folder; the build is ``destination / "kalman_course"``.
    withheld : dict
        Dotted function name → the exercise's function it stands for
        (:func:`withheld_functions`).
    chapter : str
        The chapter graded (named in the guard's message).
    """
    target = Path(destination) / PACKAGE.name
    if target.exists():
        raise FileExistsError(f"destination already holds a build: {target}")
    by_module: dict[str, dict[str, str]] = {}
    for dotted, exercise_function in withheld.items():
        module, _, name = dotted.rpartition(".")
        by_module.setdefault(module, {})[name] = exercise_function
    sources = _sources()
    unknown = set(by_module) - set(sources)
    if unknown:
        raise ValueError(f"no module {sorted(unknown)} in the package (TWINS is out of date)")
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    shutil.copytree(PACKAGE, target, ignore=lambda folder, names: (
        set(ignore(folder, names)) | ({*_LEFT_OUT, "checks"} if Path(folder) == PACKAGE else set())))
    for module, functions in by_module.items():
        path = target / sources[module].relative_to(PACKAGE)
        path.write_text(_guard_source(sources[module].read_text(encoding="utf-8"), functions, module, chapter),
                        encoding="utf-8")
    checks = target / "checks"
    checks.mkdir()
    (checks / "__init__.py").write_text(_CHECKS_INIT, encoding="utf-8")
    for name in _AGENT_MODULES:
        shutil.copy2(PACKAGE / "checks" / name, checks / name)
    _compile(target)
    return target


def _compile(target: Path) -> None:
    """Bytecode of every module of the build, beside it (a kernel cannot write any there), at
    paths given explicitly: the sealed grading process's ``pycache_prefix`` must stay empty."""
    for source in target.rglob("*.py"):
        cfile = source.parent / "__pycache__" / f"{source.stem}.{sys.implementation.cache_tag}.pyc"
        py_compile.compile(str(source), cfile=str(cfile), doraise=True)
