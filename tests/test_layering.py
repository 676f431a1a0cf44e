"""The package's layers, read from its imports: no module imports from a layer above it,
the package never loads repository scripts, and there is no import cycle.

Every import counts, including the ones inside functions (a lazy import is still a
dependency). The layers and what each may import are those of DESIGN.md.
"""

import ast
from pathlib import Path

import pytest

import kalman_course

PACKAGE = Path(kalman_course.__file__).resolve().parent

# layer -> the layers it may import from (itself included)
ALLOWED = {
    "core": {"core"},
    "symbolic": {"core", "symbolic"},
    "filters": {"core", "symbolic", "filters"},
    "evaluation": {"core", "evaluation"},
    "data": {"core", "data"},
    "chapters": {"core", "symbolic", "filters", "evaluation", "data", "chapters", "plotting"},
    "plotting": {"core", "symbolic", "filters", "evaluation", "data", "plotting"},
    "checks": {"core", "symbolic", "filters", "evaluation", "data", "chapters", "plotting", "checks"},
    "tooling": set(),  # the top: filled in below with every layer
}
ALLOWED["tooling"] = set(ALLOWED)


def module_name(path: Path, package: Path) -> str:
    parts = list(path.relative_to(package.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imported_modules(path: Path, name: str, known: set[str]) -> set[str]:
    """The ``kalman_course`` modules that the file at ``path`` imports, resolved to real modules."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    is_package = path.name == "__init__.py"
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = name.split(".") if is_package else name.split(".")[:-1]
                anchor = anchor[: len(anchor) - (node.level - 1)]
                base = ".".join(anchor + ([base] if base else []))
            # `from pkg import sub` imports the submodule when one exists
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in known else base for a in node.names]
        else:
            continue
        for target in targets:
            if target == "kalman_course" or target.startswith("kalman_course."):
                while target not in known and "." in target:
                    target = target.rsplit(".", 1)[0]
                found.add(target)
    return found - {name}


def layer_of(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else None


def import_graph(package: Path) -> dict[str, set[str]]:
    modules = {module_name(p, package): p for p in sorted(package.rglob("*.py"))}
    return {name: imported_modules(path, name, set(modules)) for name, path in modules.items()}


def layer_violations(graph: dict[str, set[str]]) -> list[str]:
    wrong = []
    for module, imports in graph.items():
        layer = layer_of(module)
        if layer is not None and layer not in ALLOWED:
            wrong.append(f"{module} is in no layer")
        for target in imports:
            target_layer = layer_of(target)
            if layer is None or target_layer is None:
                wrong.append(f"{module} -> {target} (the package root is the learners' facade only)")
            elif layer in ALLOWED and target_layer not in ALLOWED[layer]:
                wrong.append(f"{module} ({layer}) -> {target} ({target_layer})")
    return sorted(wrong)


def find_cycles(graph: dict[str, set[str]]) -> list[str]:
    """Each back edge of a depth-first search, as the cycle it closes."""
    state = dict.fromkeys(graph, "new")
    cycles = []

    def visit(module, stack):
        state[module] = "open"
        stack.append(module)
        for target in sorted(graph[module]):
            if state.get(target) == "open":
                cycles.append(" -> ".join(stack[stack.index(target):] + [target]))
            elif state.get(target) == "new":
                visit(target, stack)
        stack.pop()
        state[module] = "done"

    for module in sorted(graph):
        if state[module] == "new":
            visit(module, [])
    return cycles


def script_loading(package: Path) -> list[str]:
    """Places where the package would load code from outside itself by path."""
    found = []
    for path in sorted(package.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Attribute) and node.attr in ("spec_from_file_location", "run_path"):
                found.append(f"{path.name}: {node.attr}")
            if isinstance(node, ast.Attribute) and node.attr == "path" and getattr(node.value, "id", "") == "sys":
                found.append(f"{path.name}: sys.path")
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                names = [a.name for a in node.names] + [getattr(node, "module", None) or ""]
                if any(n.split(".")[0] in ("benchmarks", "runpy") for n in names):
                    found.append(f"{path.name}: imports {names}")
    return found


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    return import_graph(PACKAGE)


def test_no_import_from_a_higher_layer(graph):
    assert set(map(layer_of, graph)) - {None} == set(ALLOWED), "a layer is missing or unknown"
    assert layer_violations(graph) == []


def test_no_import_cycle(graph):
    assert find_cycles(graph) == []


def test_package_never_loads_repository_scripts():
    assert script_loading(PACKAGE) == []


def test_the_checks_find_what_they_look_for(tmp_path):
    # an upward import, a cycle and a script loaded by path, in a scratch package
    pkg = tmp_path / "kalman_course"
    (pkg / "core").mkdir(parents=True)
    (pkg / "filters").mkdir()
    for init in (pkg / "__init__.py", pkg / "core" / "__init__.py", pkg / "filters" / "__init__.py"):
        init.write_text("")
    (pkg / "core" / "a.py").write_text("from kalman_course.filters import b\n")
    (pkg / "filters" / "b.py").write_text("def f():\n    from kalman_course.core import a\n")
    (pkg / "filters" / "c.py").write_text("import importlib.util\nimportlib.util.spec_from_file_location('x', 'y')\n")
    scratch = import_graph(pkg)
    assert layer_violations(scratch) == ["kalman_course.core.a (core) -> kalman_course.filters.b (filters)"]
    assert find_cycles(scratch) == ["kalman_course.core.a -> kalman_course.filters.b -> kalman_course.core.a"]
    assert script_loading(pkg) == ["c.py: spec_from_file_location"]


def test_short_names_resolve_to_real_modules():
    import importlib

    for short, real in kalman_course._SHORT_NAMES.items():
        assert getattr(kalman_course, short) is importlib.import_module(real)
    with pytest.raises(AttributeError, match="no_such_module"):
        kalman_course.no_such_module  # noqa: B018


def _third_party_imports(package: Path) -> dict[str, set[str]]:
    """Top-level names of every non-stdlib, non-kalman_course module imported, with the files."""
    import sys

    found: dict[str, set[str]] = {}
    for path in package.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
                names = [node.module]
            else:
                continue
            for top in {n.split(".")[0] for n in names}:
                if top != "kalman_course" and top not in sys.stdlib_module_names:
                    found.setdefault(top, set()).add(path.name)
    return found


def test_the_package_imports_only_its_declared_dependencies():
    # a learner's `pip install -e .` has these and nothing more (SciPy and FilterPy are test oracles)
    runtime = {"numpy", "sympy", "matplotlib", "yaml", "nbformat", "nbclient", "jupyter_client", "IPython",
               "jupyter_server_mathjax", "pytest", "zmq", "ipykernel", "ipywidgets",
               "nbconvert"}  # installed with jupyterlab (its server exports notebooks)
    # the benchmark report compares with FilterPy: an instructor's tool, documented as needing .[dev]
    dev_only = {"filterpy": {"bench.py"}}
    stray = {name: sorted(files) for name, files in _third_party_imports(PACKAGE).items()
             if name not in runtime and not files <= dev_only.get(name, set())}
    assert not stray, f"imports of packages the course does not install: {stray}"
