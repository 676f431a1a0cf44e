"""Each shared formula is written once in the package, in its home module.

A regular expression per formula finds every place that writes it out; the only places
allowed besides its home are listed with the reason (the graders' catalogues of wrong
formulas, which name a learner's mistake by computing it, and lecture 09's deliberately
unsymmetrised forms). Docstrings and comments do not count: the scan reads code tokens.
"""

import io
import re
import tokenize
from pathlib import Path

import pytest

import kalman_course

PACKAGE = Path(kalman_course.__file__).resolve().parent

MISTAKE_CATALOGUE = "a grader's catalogue of wrong formulas (each names a learner mistake)"

# formula -> (regex over code, home module, {other module: why it may write it})
FORMULAS = {
    "angle wrapping": (r"np\.mod\(|%\(2(\.0)?\*(np\.|math\.)pi\)", "core/angles.py", {
        "checks/ekf.py": MISTAKE_CATALOGUE,
    }),
    "RMSE": (r"sqrt\((np\.)?mean\(|sqrt\(mean_square\)", "evaluation/metrics.py", {}),
    "symmetrisation": (r"0\.5\*\((\w+)\+\1\.T\)|\((\w+)\+\2\.T\)/2|add\((\w+),\3\.T", "core/linalg.py", {
        "checks/eskf.py": MISTAKE_CATALOGUE,
    }),
    "Joseph form / I - K G": (r"I_KG\b|(np\.eye\([^)]*\)|\bI)-(dot\()?(\w+\.)?K\b", "core/linalg.py", {
        "symbolic/kalman.py": "the SymPy derivation that the numeric kernel is tested against",
        "checks/kf.py": MISTAKE_CATALOGUE,
        "checks/eskf.py": MISTAKE_CATALOGUE,
        "checks/ekf.py": MISTAKE_CATALOGUE,
        "chapters/consistency.py": "lecture 09's short form (I - K G) P, unsymmetrised on purpose",
    }),
    "Kalman gain by solve or inverse of S": (r"(solve|inv)\(S\b", "core/linalg.py", {
        "core/gaussians.py": "block_inverse: S is the Schur complement there, not an innovation covariance",
        "checks/ekf.py": MISTAKE_CATALOGUE,
    }),
    "SO(3) exponential coefficients": (r"sin\(\w+\)/\w+|1(\.0)?-(np|math)\.cos\(", "core/so3.py", {}),
    # the mean of the navigation-frame accelerations at both ends of a step
    "midpoint mechanisation": (r"0\.5\*\(a0\+a1\)|\ba(cc)?\w*\[:-1\]\+a(cc)?\w*\[1:\]", "core/imu.py", {}),
}


def code_lines(path: Path) -> dict[int, str]:
    """Line number -> the line's code with strings and comments blanked out."""
    lines: dict[int, list[str]] = {}
    with open(path, encoding="utf-8") as f:
        for tok in tokenize.generate_tokens(f.readline):
            if tok.type in (tokenize.STRING, tokenize.COMMENT, tokenize.NL, tokenize.NEWLINE):
                continue
            if tok.type == getattr(tokenize, "FSTRING_START", None):
                continue
            lines.setdefault(tok.start[0], []).append(tok.string)
    # tokens joined without spaces, so that the patterns need not allow for layout
    return {n: "".join(parts) for n, parts in lines.items()}


def places(pattern: str) -> dict[str, list[int]]:
    found: dict[str, list[int]] = {}
    regex = re.compile(pattern)
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE).as_posix()
        for n, code in code_lines(path).items():
            if regex.search(code):
                found.setdefault(rel, []).append(n)
    return found


@pytest.mark.parametrize("formula", list(FORMULAS))
def test_formula_is_written_only_in_its_home(formula):
    pattern, home, allowed = FORMULAS[formula]
    found = places(pattern)
    assert home in found, f"{formula}: not found in its home {home} (the pattern is stale)"
    strays = {f"{module}:{lines}" for module, lines in found.items() if module != home and module not in allowed}
    assert not strays, f"{formula} written again outside {home}: {sorted(strays)}"


def test_the_scan_finds_a_copy(tmp_path, monkeypatch):
    # a scratch package with the Joseph form written twice: the scan reports the copy
    pkg = tmp_path / "kalman_course"
    (pkg / "core").mkdir(parents=True)
    (pkg / "filters").mkdir()
    (pkg / "core" / "linalg.py").write_text("def j(P, K, G, R, I):\n    return (I - K @ G) @ P\n")
    (pkg / "filters" / "x.py").write_text(
        "def f(P, K, G):\n    '''I - K G in a docstring does not count'''\n"
        "    # nor I_KG in a comment\n    return (np.eye(3) - K @ G) @ P\n")
    monkeypatch.setattr(__import__(__name__), "PACKAGE", pkg)
    found = places(FORMULAS["Joseph form / I - K G"][0])
    assert found == {"core/linalg.py": [2], "filters/x.py": [4]}
