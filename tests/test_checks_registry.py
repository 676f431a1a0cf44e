"""The check registry: every grader cell's check exists, names are unique, written once."""

import ast
import re
from pathlib import Path

import nbformat
import pytest

from kalman_course import checks
from kalman_course.checks import harness

ROOT = Path(__file__).resolve().parents[1]
CHECKS_DIR = ROOT / "kalman_course" / "checks"


def grader_check_names() -> set[str]:
    """Check names that the solutions' grader cells declare in their metadata."""
    names = set()
    for path in sorted((ROOT / "solutions").glob("*.ipynb")):
        for cell in nbformat.read(path, as_version=4).cells:
            meta = cell.get("metadata", {}).get("kalman_course", {})
            if "check" in meta:
                names.add(meta["check"])
    return names


def test_every_grader_cell_names_a_registered_check():
    names = grader_check_names()
    assert len(names) >= 40                      # nine chapters' worth of grader cells
    missing = names - set(checks.registered())
    assert not missing, f"grader cells name unregistered checks: {sorted(missing)}"


def test_every_registered_check_is_graded_somewhere():
    unused = set(checks.registered()) - grader_check_names()
    assert not unused, f"registered checks no grader cell uses: {sorted(unused)}"


def test_grader_cells_call_the_check_their_metadata_names():
    for path in sorted((ROOT / "solutions").glob("*.ipynb")):
        for cell in nbformat.read(path, as_version=4).cells:
            meta = cell.get("metadata", {}).get("kalman_course", {})
            if "check" in meta:
                assert re.search(rf"\bchecks\.{meta['check']}\(", cell.source), (path.name, cell.source)


def test_each_check_is_exposed_under_its_name_and_in_all():
    for name, fn in checks.registered().items():
        assert getattr(checks, name) is fn
        assert fn.check_name == name
        assert fn.__name__ == f"check_{name}"
        assert name in checks.__all__
    assert {"CheckFailed", "SUCCESS", "registered"} <= set(checks.__all__)


def test_no_check_name_is_written_twice_in_the_source():
    # the name lives in the def line only: no @check("name") and no hand-kept list
    for path in sorted(CHECKS_DIR.glob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef) and node.name.startswith("check_"):
                # @check, or @check(uses=...) with keyword arguments only (no name string)
                decorators = [d for d in node.decorator_list
                              if (isinstance(d, ast.Name) and d.id == "check")
                              or (isinstance(d, ast.Call) and isinstance(d.func, ast.Name)
                                  and d.func.id == "check" and not d.args)]
                assert decorators, f"{path.name}: {node.name} is not decorated with @check"
    init = (CHECKS_DIR / "__init__.py").read_text(encoding="utf-8")
    for name in checks.registered():
        assert not re.search(rf"\b{name}\b", init), f"checks/__init__.py repeats {name!r}"


def test_success_line_and_failure_prefix_use_the_registered_name(capsys):
    @harness.check
    def check_registry_test_passes(value):
        if value != 1:
            raise checks.CheckFailed("value should be 1")

    try:
        check_registry_test_passes(1)
        assert capsys.readouterr().out == "registry_test_passes: passed\n"
        with pytest.raises(checks.CheckFailed, match=r"^registry_test_passes: value should be 1$"):
            check_registry_test_passes(2)
        assert checks.registered()["registry_test_passes"] is check_registry_test_passes
    finally:
        harness._REGISTRY.pop("registry_test_passes", None)


def test_a_failing_used_function_is_named_instead_of_the_function_under_test():
    # the learner's downstream function is right; the upstream one it calls is wrong
    namespace = {}
    exec("def upstream(x):\n    return x + 1\n"
         "def downstream(x):\n    return upstream(x)\n", namespace)

    @harness.check
    def check_registry_upstream(fn):
        if fn(1) != 1:
            raise checks.CheckFailed("upstream(1) should be 1")

    @harness.check(uses={"upstream": "registry_upstream"})
    def check_registry_downstream(fn):
        if fn(1) != 1:
            raise checks.CheckFailed("downstream(1) should be 1")

    try:
        with pytest.raises(checks.CheckFailed, match=r"^registry_downstream: this function calls your upstream, "
                                                     r"which does not pass its own check yet: upstream\(1\) "
                                                     r"should be 1\. Hint: fix upstream first"):
            check_registry_downstream(namespace["downstream"])
        exec("def upstream(x):\n    return x\n", namespace)          # fixed upstream: no redirection
        check_registry_downstream(namespace["downstream"])
        exec("def downstream(x):\n    return upstream(x) + 1\n", namespace)
        with pytest.raises(checks.CheckFailed, match=r"^registry_downstream: downstream\(1\) should be 1$"):
            check_registry_downstream(namespace["downstream"])
    finally:
        harness._REGISTRY.pop("registry_upstream", None)
        harness._REGISTRY.pop("registry_downstream", None)


def test_a_duplicate_registration_is_rejected():
    existing = next(iter(checks.registered()))
    before = checks.registered()
    duplicate = f"def check_{existing}(fn):\n    pass\n"
    namespace = {"__name__": "some_other_module"}
    exec(compile(duplicate, "<duplicate>", "exec"), namespace)
    with pytest.raises(ValueError, match=rf"check name '{existing}' is registered twice"):
        harness.check(namespace[f"check_{existing}"])
    assert checks.registered() == before          # the original is still the one registered


@pytest.mark.parametrize("name", ["kf_update", "check_", "checkkf", "grade_kf"])
def test_a_function_not_named_check_something_is_rejected(name):
    def fn():
        pass
    fn.__name__ = name
    with pytest.raises(ValueError, match=r"@check decorates a function named check_<name>"):
        harness.check(fn)


def test_a_failed_check_shows_its_hint_first_and_no_grader_frames(capsys):
    # what JupyterLab (and nbval) show is IPython's rendering of the exception
    from IPython.core.interactiveshell import InteractiveShell

    shell = InteractiveShell.instance()
    shell.user_ns.update(checks=checks, kf_predict=lambda x_hat, P_hat, F, Q: (F @ x_hat, F @ P_hat @ F.T))
    capsys.readouterr()
    result = shell.run_cell("checks.kf_predict(kf_predict)")
    shown = re.sub(r"\x1b\[[0-9;]*m", "", capsys.readouterr().out).strip().splitlines()
    assert isinstance(result.error_in_exec, checks.CheckFailed)
    message = str(result.error_in_exec)
    assert message.startswith("kf_predict: ") and " Hint: " in message  # the gradebook's text, unchanged
    saw, hint = message.removeprefix("kf_predict: ").split(" Hint: ", 1)
    assert shown == ["kf_predict: not passed yet", f"Hint: {hint}", f"What the check saw: {saw}"]


def test_a_message_without_a_hint_is_shown_whole():
    assert checks.CheckFailed("kf_gain: K has shape (3,), expected (6, 3)")._render_traceback_() == [
        "\x1b[31m\x1b[1mkf_gain: not passed yet\x1b[0m", "K has shape (3,), expected (6, 3)"]
