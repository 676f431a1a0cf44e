"""Instructor exports: derivations as LaTeX and Markdown, lectures as offline HTML."""

import html
import os
import re
import shutil
import subprocess

import pytest

from kalman_course.tooling import cli, export
from kalman_course.tooling.notebooks import read_notebook

from conftest import ROOT


@pytest.fixture(scope="module")
def derivations():
    return export.all_derivations()


@pytest.fixture(scope="module")
def markdown(tmp_path_factory):
    out = tmp_path_factory.mktemp("md")
    assert cli.main(["export", "derivations", "--to", "md", "-o", str(out)]) == 0
    return (out / "derivations.md").read_text()


def test_markdown_has_every_derivation_and_readably_numbered_equation(derivations, markdown):
    for k, (name, d) in enumerate(derivations.items(), 1):
        assert f"## {k}. {d.title}" in markdown
        for j, eq in enumerate(d.equations, 1):
            assert f"**({k}.{j}) {eq.label}** <a id=\"{export.equation_label(name, eq.label)}\"></a>" in markdown
            assert f"\\tag{{{k}.{j}}}" in markdown
    assert markdown.count("$$") == 2 * sum(len(d.equations) for d in derivations.values())
    assert ":" not in "".join(re.findall(r"\\tag\{([^}]*)\}", markdown))   # no internal names as tags


def test_latex_is_a_standalone_document_with_unique_labels(derivations, tmp_path):
    tex = export.derivations_latex(derivations)
    assert tex.startswith("\\documentclass") and tex.rstrip().endswith("\\end{document}")
    labels = re.findall(r"\\label\{(eq:[^}]*)\}", tex)
    assert len(labels) == sum(len(d.equations) for d in derivations.values())
    assert len(set(labels)) == len(labels)
    assert "\n\n\\end{equation}" not in tex, "blank lines inside maths do not compile"


@pytest.mark.parametrize("fmt", ["tex", "beamer"])
def test_handout_and_slides_compile_and_every_line_fits_the_page(fmt, tmp_path):
    """pdflatex's log names every line wider than the page ("Overfull \\hbox"): none may be.
    CI installs TeX (`.ci/run` sets KALMAN_COURSE_REQUIRE_TEX, so there this never skips)."""
    if shutil.which("pdflatex") is None:
        if os.environ.get("KALMAN_COURSE_REQUIRE_TEX"):
            pytest.fail("pdflatex is required here (KALMAN_COURSE_REQUIRE_TEX is set) but not installed")
        pytest.skip("no TeX engine installed")
    path = export.export_derivations(fmt, tmp_path)
    run = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error", path.name],
                         cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stdout[-2000:]
    assert path.with_suffix(".pdf").stat().st_size > 10_000
    log = path.with_suffix(".log").read_text(errors="replace")
    assert "Overfull \\hbox" not in log, re.findall(r"Overfull \\hbox \(.*", log)[:5]


def test_expanded_identities_too_wide_for_a_page_are_named_not_printed(derivations):
    tex = export.derivations_latex(derivations)
    wide = [(name, eq) for name, d in derivations.items() for eq in d.equations
            if eq.kind == "check" and len(eq.latex()) > export.EXPANDED_MAX_CHARS]
    assert wide, "the course has expanded identities of several page widths"
    for name, eq in wide:
        assert eq.latex() not in tex
        assert f'derivation("{export._latex_text(name)}").verify()' in tex
    shown = [eq for d in derivations.values() for eq in d.equations if len(eq.latex()) <= 600]
    assert all(eq.latex() in tex for eq in shown)


def test_latex_escapes_prose_but_keeps_maths():
    assert export._latex_text("x_1 & 50% $a_1$") == r"x\_1 \& 50\% $a_1$"


def test_notebooks_export_to_offline_html(tmp_path):
    out = tmp_path / "site"
    lecture = ROOT / "notebooks" / "01_bayes_rule.ipynb"
    assert cli.main(["export", "notebooks", "--to", "html", "-o", str(out), str(lecture)]) == 0
    page = (out / "01_bayes_rule.html").read_text()
    assert "mathjax/MathJax.js" in page
    assert not re.search(r'(?:src|href)="https?://', page), "the page must not load anything remote"
    assert (out / "mathjax" / "MathJax.js").is_file()
    assert 'href="01_bayes_rule.html"' in (out / "index.html").read_text()
    # MathJax is told to use the web font the local copy ships, which is there
    assert export.MATHJAX_FONT_CONFIG in page and (out / "mathjax" / "fonts" / "HTML-CSS" / "STIX-Web").is_dir()


def test_the_lectures_form_a_site_with_working_links(tmp_path):
    out = tmp_path / "site"
    lectures = [ROOT / "notebooks" / name for name in ("01_bayes_rule.ipynb", "02_gaussians.ipynb",
                                                        "A1_notation_glossary.ipynb")]
    assert cli.main(["export", "notebooks", "--to", "html", "-o", str(out), *map(str, lectures)]) == 0
    index = (out / "index.html").read_text()
    titles = re.findall(r'<li><a href="([^"]+)">([^<]+)</a><br><span class="kc-summary">([^<]+)</span>', index)
    assert [t[0] for t in titles] == ["01_bayes_rule.html", "02_gaussians.html", "A1_notation_glossary.html"]
    assert titles[0][1].startswith("01") and "Bayes" in titles[0][1] and all(len(t[2]) > 20 for t in titles)
    assert "*" not in "".join(t[2] for t in titles)            # markdown emphasis stripped
    for k, (name, _, _) in enumerate(titles):
        page = (out / name).read_text()
        navs = re.findall(r'<nav class="kc-nav kc-(top|bottom)">(.*?)</nav>', page)
        assert [where for where, _ in navs] == ["top", "bottom"]
        links = re.findall(r'href="([^"]+)"', navs[0][1])
        expected = ([titles[k - 1][0]] if k else []) + ["index.html"] + \
            ([titles[k + 1][0]] if k + 1 < len(titles) else [])
        assert links == expected and all((out / link).is_file() for link in links)
        # the browser tab shows the page's heading, as the index does
        assert html.unescape(re.search(r"<title>([^<]*)</title>", page).group(1)) == html.unescape(titles[k][1])


def test_every_lecture_heading_reads_NN_dot_title():
    # one style in the site index: "07 · Rotations …", never "07 — …"
    for path in sorted((ROOT / "notebooks").glob("*.ipynb")):
        title, _ = export.notebook_title_and_summary(read_notebook(path))
        assert re.fullmatch(r"(\d\d|A\d) · \S.*", title), (path.name, title)


def test_bad_format_is_refused(tmp_path, capsys):
    assert cli.main(["export", "derivations", "--to", "pdf", "-o", str(tmp_path)]) == 2
    assert cli.main(["export", "notebooks", "--to", "tex", "-o", str(tmp_path)]) == 2
    assert "--to" in capsys.readouterr().err


def test_an_export_never_replaces_a_file_it_did_not_write(tmp_path, capsys):
    out = tmp_path / "handouts"
    out.mkdir()
    mine = out / "derivations.md"
    mine.write_text("my own notes\n")
    assert cli.main(["export", "derivations", "--to", "md", "-o", str(out)]) == 2
    assert str(mine) in capsys.readouterr().err and mine.read_text() == "my own notes\n"
    # a file the export wrote is replaced by the next export, and carries the mark to say so
    mine.unlink()
    assert cli.main(["export", "derivations", "--to", "md", "-o", str(out)]) == 0
    first = mine.read_text()
    assert export.MARK in first.splitlines()[0] and first.splitlines()[1] == "# kalman-course: derivations"
    assert cli.main(["export", "derivations", "--to", "md", "-o", str(out)]) == 0
    assert mine.read_text() == first
    # a folder where the file would go is the user's too
    (out / "derivations.tex").mkdir()
    with pytest.raises(FileExistsError, match="derivations.tex"):
        export.export_derivations("tex", out)


def test_pages_are_named_uniquely_and_a_users_index_is_kept(tmp_path, capsys):
    lecture = ROOT / "notebooks" / "A1_notation_glossary.ipynb"
    for folder, name in (("a", "n"), ("b", "n"), ("c", "index")):
        (tmp_path / folder).mkdir()
        shutil.copy(lecture, tmp_path / folder / f"{name}.ipynb")
    notebooks = [tmp_path / "a" / "n.ipynb", tmp_path / "b" / "n.ipynb", tmp_path / "c" / "index.ipynb"]
    assert export.page_names(notebooks) == ["a-n.html", "b-n.html", "c-index.html"]
    assert export.page_names([tmp_path / "a" / "n.ipynb"]) == ["n.html"]
    with pytest.raises(ValueError, match="different files"):
        export.page_names([notebooks[0], notebooks[0]])
    site = tmp_path / "site"
    assert cli.main(["export", "notebooks", "--to", "html", "-o", str(site), *map(str, notebooks)]) == 0
    assert sorted(p.name for p in site.glob("*.html")) == ["a-n.html", "b-n.html", "c-index.html", "index.html"]
    page = (site / "a-n.html").read_text()
    assert page.startswith("<!DOCTYPE html>\n<!-- " + export.MARK)
    # the user's own index.html in the output folder: refused before anything is written
    other = tmp_path / "other"
    other.mkdir()
    (other / "index.html").write_text("<p>my page</p>")
    capsys.readouterr()
    assert cli.main(["export", "notebooks", "--to", "html", "-o", str(other), *map(str, notebooks)]) == 2
    assert "index.html" in capsys.readouterr().err
    assert [p.name for p in other.iterdir()] == ["index.html"] and (other / "index.html").read_text() == "<p>my page</p>"
