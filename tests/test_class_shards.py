"""A class graded in shards gives exactly what one run gives, through the shipped recipes.

The same class is graded three ways: one `kalman-course grade` run; the GitHub Actions
workflow in `recipes/`, dry-run here (every `run:` step executed as the runner would, the
artifact steps emulated by copying files, the install steps skipped, the repository secret
given as the workflow maps it); and the Slurm recipe, run with a stand-in `sbatch` that
executes array tasks one after the other and then the dependent merge, with the key in a
file only its owner can read. Every shard is signed and the merge verifies them; the
gradebooks (CSV, JSON) and feedback files must be byte-for-byte those of the single run.
"""

import json
import os
import re
import shutil
import stat
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from kalman_course.tooling import cli, gradebook, grading

from conftest import ROOT

pytestmark = pytest.mark.slow

RECIPES = ROOT / "recipes"
KEY = "the instructor's key for this test"
#: The run seed of the single run, given to the recipes so that their shards draw the same inputs.
SEED = "4096"


def _class(folder: Path) -> Path:
    """Three learners: a solved chapter 01 and an untouched 02, an untouched 01, a broken file."""
    for learner, files in {"alice": [("solutions", "01_bayes_rule.ipynb"), ("exercises", "02_gaussians.ipynb")],
                           "bob": [("exercises", "01_bayes_rule.ipynb")]}.items():
        (folder / learner).mkdir(parents=True)
        for kind, name in files:
            shutil.copy(ROOT / kind / name, folder / learner / name)
    (folder / "dave").mkdir()
    (folder / "dave" / "01_bayes_rule.ipynb").write_text("{ not json")
    return folder


def _outputs(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()
            and (p.name.startswith("grades.") or p.parent.name == "feedback")}


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("shards")
    submissions = _class(tmp / "class")
    one = tmp / "one"
    with pytest.MonkeyPatch.context() as patch:  # the single run signs with the instructor's key
        patch.setenv(gradebook.KEY_VARIABLE, KEY)
        code = cli.main(["grade", str(submissions), "--release", str(ROOT / "exercises"), "--jobs", "2",
                         "--csv", str(one / "grades.csv"), "--json", str(one / "grades.json"),
                         "--feedback", str(one / "feedback"), "--seed", SEED])
    return tmp, submissions, code, _outputs(one)


def _without_key() -> dict:
    """The test's environment with no gradebook key in it: each recipe must pass its own."""
    return {k: v for k, v in os.environ.items() if k != gradebook.KEY_VARIABLE}


def _run(script: str, cwd: Path, env: dict) -> None:
    out = subprocess.run(["bash", "-e", "-o", "pipefail", "-c", script], cwd=cwd, env=env,
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stdout + out.stderr


def _expand(text: str, values: dict) -> str:
    def value(match):
        key = match.group(1).strip()
        assert key in values, f"the workflow uses ${{{{ {key} }}}}, which the dry run does not know"
        return str(values[key])
    return re.sub(r"\$\{\{(.*?)\}\}", value, text)


def test_one_run_reports_the_broken_notebook_and_signs_its_gradebook(graded):
    _, _, code, outputs = graded
    assert code == 1 and "grades.json" in outputs and len([k for k in outputs if "feedback" in k]) == 3
    document = json.loads(outputs["grades.json"])
    assert document["signature"] == gradebook.signature(document, KEY.encode())
    assert [learner for learner, _ in document["run"]["class"]] == ["alice", "alice", "bob", "dave"]
    assert document["run"]["seed"] == int(SEED), "the gradebook must record the run seed"


def test_github_actions_matrix_and_merge_give_the_single_runs_gradebook(graded):
    tmp, submissions, _, expected = graded
    workflow = yaml.safe_load((RECIPES / "grade-class-github.yml").read_text())
    trigger = workflow.get("on", workflow.get(True))  # YAML 1.1 reads the key `on` as True
    inputs = {f"inputs.{k}": v["default"] for k, v in trigger["workflow_dispatch"]["inputs"].items()}
    inputs.update({"inputs.submissions": str(submissions), "inputs.release": str(ROOT / "exercises"),
                   "inputs.seed": SEED, f"secrets.{gradebook.KEY_VARIABLE}": KEY})
    grade, merge = workflow["jobs"]["grade"], workflow["jobs"]["merge"]
    # the seed job: every shard is given the one seed it outputs
    draw = workflow["jobs"]["seed"]
    assert grade["needs"] == "seed"
    github_output = tmp / "seed-output"
    _run(_expand(draw["steps"][0]["run"], inputs), tmp, dict(_without_key(), GITHUB_OUTPUT=str(github_output)))
    inputs["needs.seed.outputs.seed"] = github_output.read_text().strip().partition("=")[2]
    assert inputs["needs.seed.outputs.seed"] == SEED
    assert merge["needs"] == "grade" and grade["strategy"]["fail-fast"] is False
    shards = grade["strategy"]["matrix"]["shard"]
    assert shards == list(range(1, int(grade["env"]["SHARDS"]) + 1))
    artifacts = tmp / "artifacts"
    env = dict(_without_key(), **{k: _expand(str(v), inputs) for k, v in grade["env"].items()})
    for shard in shards:
        workspace = tmp / f"runner-{shard}"
        workspace.mkdir()
        for step in grade["steps"]:
            values = dict(inputs, **{"matrix.shard": shard})
            if step.get("uses", "").startswith("actions/upload-artifact"):
                target = artifacts / _expand(step["with"]["name"], values)
                target.mkdir(parents=True)
                shutil.copy(workspace / _expand(step["with"]["path"], values), target)
            elif "run" in step and not step["run"].startswith(("pip install", "sudo apt-get install")):
                _run(_expand(step["run"], values), workspace, env)
    workspace = tmp / "runner-merge"
    workspace.mkdir()
    for step in merge["steps"]:
        if step.get("uses", "").startswith("actions/download-artifact"):
            pattern, path = step["with"]["pattern"], workspace / step["with"]["path"]
            assert step["with"]["merge-multiple"] is True
            path.mkdir()
            for folder in artifacts.glob(pattern):
                for file in folder.iterdir():
                    shutil.copy(file, path / file.name)
        elif "run" in step and not step["run"].startswith(("pip install", "sudo apt-get install")):
            _run(_expand(step["run"], inputs), workspace,
                 dict(_without_key(), **{k: _expand(str(v), inputs) for k, v in merge.get("env", {}).items()}))
    assert _outputs(workspace) == expected


SBATCH = """#!/usr/bin/env python3
# A stand-in for Slurm's sbatch: array tasks run one after the other, then --wrap commands.
import os, subprocess, sys
args = sys.argv[1:]
options = [a for a in args if a.startswith("--")]
rest = [a for a in args if not a.startswith("--")]
array = next((a.split("=", 1)[1] for a in options if a.startswith("--array=")), None)
wrap = next((a.split("=", 1)[1] for a in options if a.startswith("--wrap=")), None)
if "--wrap" in args:
    wrap = args[args.index("--wrap") + 1]
if array:
    first, last = (int(x) for x in array.split("-"))
    for task in range(first, last + 1):
        env = dict(os.environ, SLURM_ARRAY_TASK_ID=str(task), SLURM_ARRAY_TASK_COUNT=str(last - first + 1))
        subprocess.run(["bash", *rest], env=env, check=True)
else:
    subprocess.run(["sh", "-c", wrap], check=True)
print(4242)
"""


def test_slurm_array_and_dependent_merge_give_the_single_runs_gradebook(graded, tmp_path):
    _, submissions, _, expected = graded
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    sbatch = bin_dir / "sbatch"
    sbatch.write_text(SBATCH.replace("python3", Path(sys.executable).name, 1)
                      .replace("#!/usr/bin/env " + Path(sys.executable).name, "#!" + sys.executable, 1))
    sbatch.chmod(sbatch.stat().st_mode | stat.S_IEXEC)
    env = dict(_without_key(),
               PATH=f"{bin_dir}{os.pathsep}{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}")
    key_file = tmp_path / "gradebook.key"
    key_file.write_text(KEY + "\n")
    key_file.chmod(0o600)
    out = tmp_path / "out"
    _run(f"bash {RECIPES / 'grade-class-slurm.sh'} {submissions} {ROOT / 'exercises'} {out} 3 {key_file} {SEED}",
         tmp_path, env)
    assert sorted(p.name for p in (out / "shards").iterdir()) == ["shard-1.json", "shard-2.json", "shard-3.json"]
    assert _outputs(out) == expected


def test_merge_refuses_a_missing_or_repeated_shard(graded, tmp_path, monkeypatch, capsys):
    tmp, submissions, _, _ = graded
    monkeypatch.setenv(gradebook.KEY_VARIABLE, KEY)
    whole = gradebook.read_json(tmp / "one" / "grades.json")
    roster = [tuple(entry) for entry in whole.run["class"]]
    everyone = [(path, learner) for learner, path in roster]
    shards = []
    for k in (1, 2):
        shards.append(tmp_path / f"shard-{k}.json")
        gradebook.write_gradebooks([whole.results[i] for i in grading.shard_of(everyone, k, 2)],
                                   dict(whole.run, shard=f"{k}/2"), KEY.encode(), json_path=shards[-1])
    assert cli.main(["merge", *map(str, shards)]) == 1  # both shards verify; dave's file is no notebook
    capsys.readouterr()
    assert cli.main(["merge", str(shards[0])]) == 2
    assert "shard 2/2 is missing" in capsys.readouterr().err
    assert cli.main(["merge", str(shards[0]), str(shards[0]), str(shards[1])]) == 2
    assert "all say they are shard 1/2" in capsys.readouterr().err
    (tmp_path / "not.json").write_text("[1, 2]")
    with pytest.raises(ValueError, match="not a gradebook written by"):
        gradebook.read_json(tmp_path / "not.json")
