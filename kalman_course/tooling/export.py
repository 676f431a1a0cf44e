"""Export the course for instructors: SymPy derivations as LaTeX/Markdown, lectures as HTML.

Derivations are written from the same :mod:`kalman_course.symbolic` objects the filters
use, so a handout can never disagree with the code. Producing them needs no TeX.
Lectures are written as HTML pages that render their maths offline with the MathJax copy
shipped by the ``jupyter-server-mathjax`` package.
"""

from __future__ import annotations

import html
import re
import shutil
from pathlib import Path

from kalman_course.tooling.notebooks import load_notebook, require_output

REMOTE_SCRIPT_RE = re.compile(r'<script[^>]*src="https?://[^"]*"[^>]*>\s*</script>\s*')

#: Every file the export writes carries this line near its top (a TeX, Markdown or HTML
#: comment), so that a later export may replace it; a file without it is the user's.
MARK = "written by kalman-course export; a later export replaces it"
_MARK_SPAN = 512      # the mark is within the first line or two: only this much is read
_COMMENTS = {".tex": "% {}\n", ".md": "<!-- {} -->\n", ".html": "<!-- {} -->\n"}


def _marked(path: Path, text: str) -> str:
    """``text`` with :data:`MARK` as a comment at its top (after an HTML page's doctype line)."""
    comment = _COMMENTS[path.suffix].format(MARK)
    if text.startswith("<!DOCTYPE"):
        doctype, _, rest = text.partition("\n")
        return f"{doctype}\n{comment}{rest}"
    return comment + text


def refuse_foreign(paths) -> None:
    """Raise FileExistsError naming the first of ``paths`` that exists and was not written by
    the export (a folder, or a file without :data:`MARK`): nothing of the user's is replaced."""
    for path in paths:
        path = Path(path)
        if not path.exists() and not path.is_symlink():
            continue
        own = False
        if path.is_file() and not path.is_symlink():
            with open(path, encoding="utf-8", errors="replace") as fh:
                own = MARK in fh.read(_MARK_SPAN)
        if not own:
            raise FileExistsError(f"{path} exists and was not written by kalman-course export: not replaced "
                                  "(move it, or export to another folder with -o); nothing was written")


#: What ``-o`` must be, as the errors say it.
OUTPUT_FOLDER = "the folder to export to (-o), or a place to make it"


def _write(path: Path, text: str) -> None:
    path.write_text(_marked(path, text), encoding="utf-8")

KIND_NOTE = {
    "definition": "definition",
    "identity": "identity, proved by SymPy",
    "check": "checked by SymPy with explicit symbolic matrices",
}


def all_derivations() -> dict:
    """Every derivation of the course, keyed by name, in course order (the symbolic registry).

    SymPy is imported here, not with this module, so that exporting the lectures does not
    load it.
    """
    from kalman_course.symbolic import registry

    return registry.derivations()


def equation_label(derivation_name: str, label: str) -> str:
    """A LaTeX-safe label, ``eq:<derivation>:<equation>``."""
    return "eq:" + re.sub(r"[^A-Za-z0-9:.-]+", "-", f"{derivation_name}:{label}")


def _latex_text(text: str) -> str:
    """Escape prose for LaTeX while keeping its ``$...$`` maths."""
    pieces = re.split(r"(\$[^$]*\$)", text)
    out = []
    for piece in pieces:
        if piece.startswith("$") and piece.endswith("$") and len(piece) > 1:
            out.append(piece)
        else:
            for ch, rep in (("\\", r"\textbackslash{}"), ("&", r"\&"), ("%", r"\%"), ("#", r"\#"),
                            ("_", r"\_"), ("{", r"\{"), ("}", r"\}")):
                piece = piece.replace(ch, rep)
            out.append(piece)
    return "".join(out)


#: An expanded identity (kind "check": explicit symbolic matrices) longer than this, in
#: characters of LaTeX, is two and a half page widths and more: the handouts name it and
#: say where SymPy checks it instead of printing it (the Markdown export keeps it whole).
EXPANDED_MAX_CHARS = 1500


def _numbered(derivations: dict):
    """(k, name, derivation, [(j, equation, shown)]) in course order; ``shown`` is False for an
    expanded identity too wide for a page."""
    for k, (name, d) in enumerate(derivations.items(), 1):
        yield k, name, d, [(j, eq, not (eq.kind == "check" and len(eq.latex()) > EXPANDED_MAX_CHARS))
                           for j, eq in enumerate(d.equations, 1)]


def _left_out(name: str) -> str:
    return ("Expanded with explicit symbolic matrices, this equation is several page widths wide; "
            "it is left out here (the Markdown export prints it) and checked by SymPy in\\par"
            f"\\texttt{{kalman\\_course.symbolic.derivation(\"{_latex_text(name)}\").verify()}}")


def _fitted(latex: str) -> str:
    """A display scaled down to the text width when wider (adjustbox), never up."""
    return rf"\adjustbox{{max width=\linewidth}}{{$\displaystyle {latex}$}}"


_PREAMBLE = [r"\usepackage{amsmath,amssymb}", r"\usepackage{adjustbox}", r"\setcounter{MaxMatrixCols}{20}"]
_INTRO = ("Every equation below is generated from \\texttt{kalman\\_course.symbolic}; identities and "
          "checks are proved there by SymPy.")


def derivations_latex(derivations: dict) -> str:
    """One standalone LaTeX handout with every derivation; equations numbered k.j (derivation
    k, equation j), each fitted to the text width, expanded identities named not printed."""
    lines = [r"\documentclass[a4paper,10pt]{article}", r"\usepackage[margin=2cm]{geometry}", *_PREAMBLE,
             r"\allowdisplaybreaks", r"\emergencystretch=3em",  # long inline maths in the prose
             r"\title{kalman-course: derivations}", r"\date{}",
             r"\begin{document}", r"\maketitle", _INTRO, ""]
    for k, name, d, equations in _numbered(derivations):
        lines += [rf"\section{{{_latex_text(d.title)}}}\label{{sec:{name}}}", _latex_text(d.model), ""]
        for j, eq, shown in equations:
            note = _latex_text(eq.description) if eq.description else ""
            lines.append(rf"\paragraph{{({k}.{j}) {_latex_text(eq.label)}}} ({KIND_NOTE[eq.kind]}) {note}")
            if shown:
                lines += [r"\begin{equation}", rf"\label{{{equation_label(name, eq.label)}}}", rf"\tag{{{k}.{j}}}",
                          _fitted(eq.latex()), r"\end{equation}", ""]
            else:
                lines += [rf"\label{{{equation_label(name, eq.label)}}}", _left_out(name), ""]
    lines += [r"\end{document}", ""]
    return "\n".join(lines)


def derivations_beamer(derivations: dict) -> str:
    """The same derivations as slides for instructors: one derivation per frame (continued on
    more frames when long), equations fitted to the slide, numbered as in the handout."""
    lines = [r"\documentclass[aspectratio=169,10pt]{beamer}", *_PREAMBLE, r"\setbeamertemplate{navigation symbols}{}",
             r"\title{kalman-course: derivations}", r"\date{}", r"\begin{document}",
             r"\begin{frame}\titlepage\end{frame}", ""]
    for k, name, d, equations in _numbered(derivations):
        lines += [rf"\begin{{frame}}[allowframebreaks]{{{k}. {_latex_text(d.title)}}}",
                  rf"\small {_latex_text(d.model)}", ""]
        for j, eq, shown in equations:
            lines.append(rf"\par\medskip\textbf{{({k}.{j}) {_latex_text(eq.label)}}} \emph{{{KIND_NOTE[eq.kind]}}}")
            lines += [r"\[", _fitted(eq.latex()), r"\]"] if shown else [_left_out(name)]
        lines += [r"\end{frame}", ""]
    lines += [r"\end{document}", ""]
    return "\n".join(lines)


def derivations_markdown(derivations: dict) -> str:
    """Every derivation as Markdown with ``$...$`` / ``$$...$$`` maths, each equation numbered
    k.j as in the handout, with an anchor ``eq:<derivation>:<label>``."""
    lines = ["# kalman-course: derivations", "",
             "Generated from `kalman_course.symbolic`; identities and checks are proved there by SymPy.", ""]
    for k, name, d, equations in _numbered(derivations):
        lines += [f"## {k}. {d.title}", "", f"<a id=\"{name}\"></a>", "", d.model, ""]
        for j, eq, _ in equations:
            anchor = equation_label(name, eq.label)
            note = f" {eq.description}" if eq.description else ""
            lines += [f"**({k}.{j}) {eq.label}** <a id=\"{anchor}\"></a> *{KIND_NOTE[eq.kind]}*.{note}", "",
                      f"$$ {eq.latex()} \\tag{{{k}.{j}}} $$", ""]
    return "\n".join(lines)


def export_derivations(fmt: str, out_dir: str | Path) -> Path:
    """Write the derivations into ``out_dir`` and return the file's path: ``derivations.tex``
    (handout), ``derivation-slides.tex`` (beamer) or ``derivations.md``."""
    if fmt not in ("tex", "md", "beamer"):
        raise ValueError(f"fmt must be 'tex', 'beamer' or 'md', got {fmt!r}")
    out_dir = require_output(out_dir, OUTPUT_FOLDER, folder=True)
    path = out_dir / ("derivation-slides.tex" if fmt == "beamer" else f"derivations.{fmt}")
    refuse_foreign([path])
    text = {"tex": derivations_latex, "beamer": derivations_beamer, "md": derivations_markdown}[fmt](all_derivations())
    out_dir.mkdir(parents=True, exist_ok=True)
    _write(path, text)
    return path


def mathjax_dir() -> Path:
    """The folder of the MathJax copy shipped by ``jupyter-server-mathjax``."""
    try:
        import jupyter_server_mathjax
    except ImportError:
        raise FileNotFoundError("offline MathJax needs the package jupyter-server-mathjax "
                                "(pip install jupyter-server-mathjax)") from None
    folder = Path(jupyter_server_mathjax.__file__).parent / "static"
    if not (folder / "MathJax.js").is_file():
        raise FileNotFoundError(f"MathJax.js not found in {folder}")
    return folder


#: MathJax's own web font that the local copy ships (its default TeX fonts are not shipped, and
#: without this the formulas fall back to system fonts: upright letters, misplaced accents).
MATHJAX_FONT_CONFIG = ('"HTML-CSS": {availableFonts: [], preferredFont: null, webFont: "STIX-Web", '
                       'imageFont: null},')

#: The quiet style of the course site's navigation bars and index.
SITE_STYLE = """<style>
.kc-nav { font: 14px/1.5 system-ui, sans-serif; display: flex; justify-content: space-between;
  gap: 1em; max-width: 1100px; margin: 0 auto; padding: 0.6em 1em; border-bottom: 1px solid #ddd; }
.kc-nav a { color: #2a5d8f; text-decoration: none; } .kc-nav a:hover { text-decoration: underline; }
.kc-nav.kc-bottom { border-top: 1px solid #ddd; border-bottom: none; }
body.kc-index { font: 16px/1.6 system-ui, sans-serif; max-width: 760px; margin: 2em auto; padding: 0 1em;
  color: #222; }
body.kc-index li { margin: 0.5em 0; } body.kc-index .kc-summary { color: #555; }
</style>"""


def notebook_title_and_summary(nb) -> tuple[str, str]:
    """The first ``# `` heading of a notebook and the first sentence of the prose under it."""
    title, summary = "", ""
    for cell in nb.cells:
        if cell.cell_type != "markdown":
            continue
        for block in re.split(r"\n\s*\n", cell.source.strip()):
            block = " ".join(block.split())
            if not title and block.startswith("# "):
                title = block[2:].strip()
            elif title and block and not block.startswith(("#", "|", "$$", "<", "!")):
                summary = re.split(r"(?<=[.!?])\s", block, maxsplit=1)[0]
                return title, re.sub(r"\*+|`", "", summary)  # the index shows it as plain text
    return title, summary


def _nav(pages: list[tuple[Path, str]], i: int, where: str) -> str:
    def link(j, arrow_before, arrow_after):
        if not 0 <= j < len(pages):
            return "<span></span>"
        page, title = pages[j]
        return f'<a href="{html.escape(page.name)}">{arrow_before}{html.escape(title)}{arrow_after}</a>'
    return (f'<nav class="kc-nav kc-{where}">{link(i - 1, "← ", "")}'
            f'<a href="index.html">course index</a>{link(i + 1, "", " →")}</nav>')


def page_names(notebooks) -> list[str]:
    """One HTML file name per notebook, all different and none ``index.html``: the stem,
    or, where stems repeat (``a/n.ipynb``, ``b/n.ipynb``) or one is ``index``, the stem
    prefixed by as many of its parent folders as make it unique (``a-n.html``)."""
    paths = [Path(p).resolve() for p in notebooks]
    depth = [0] * len(paths)

    def name(i):
        parts = paths[i].parent.parts[len(paths[i].parent.parts) - depth[i]:] if depth[i] else ()
        return "-".join([*parts, paths[i].stem]) + ".html"

    while True:
        names = [name(i) for i in range(len(paths))]
        clash = [i for i, n in enumerate(names)
                 if n == "index.html" or names.count(n) > 1]
        deeper = [i for i in clash if depth[i] < len(paths[i].parent.parts)]
        if not clash:
            return names
        if not deeper:   # the same notebook twice, or nothing left to tell them apart
            raise ValueError(f"notebooks must be different files, got {notebooks[clash[0]]} twice")
        for i in deeper:
            depth[i] += 1


def export_notebooks_html(notebooks: list[Path], out_dir: str | Path, progress=None) -> list[Path]:
    """Write each notebook as an HTML page using a local MathJax, plus ``index.html``.

    Page names come from :func:`page_names`. Nothing is written if a page or the index would
    replace a file the export did not write (:func:`refuse_foreign`), if ``out_dir`` cannot be a
    folder, or if one of the notebooks is not one (a ``NotebookError`` names it).

    The pages form a small site in the order given: each has previous / index / next links
    at its top and bottom, and the index lists every page's title with the first sentence
    of its introduction.
    """
    nbs = [load_notebook(path) for path in notebooks]  # every one, before anything is written
    out_dir = require_output(out_dir, OUTPUT_FOLDER, folder=True)
    names = page_names(notebooks)
    refuse_foreign([out_dir / "index.html", *(out_dir / name for name in names)])
    from nbconvert import HTMLExporter

    out_dir.mkdir(parents=True, exist_ok=True)
    target = out_dir / "mathjax"
    if not (target / "MathJax.js").is_file():
        shutil.copytree(mathjax_dir(), target, dirs_exist_ok=True)
    exporter = HTMLExporter(template_name="lab")
    exporter.mathjax_url = "mathjax/MathJax.js?config=TeX-AMS-MML_HTMLorMML-full"
    pages = [(out_dir / name, notebook_title_and_summary(nb)[0] or Path(path).stem)
             for name, path, nb in zip(names, notebooks, nbs)]
    written = []
    for i, (nb_path, nb) in enumerate(zip(notebooks, nbs)):
        # "name" is what the template puts in <title> (the page's heading, as the index shows it)
        body, _ = exporter.from_notebook_node(nb, resources={"metadata": {"path": str(Path(nb_path).parent),
                                                                          "name": pages[i][1]}})
        # The template loads require.js from a CDN for widgets, which the lectures do not use.
        body = REMOTE_SCRIPT_RE.sub("", body)
        body = body.replace("MathJax.Hub.Config({", "MathJax.Hub.Config({\n" + MATHJAX_FONT_CONFIG, 1)
        body = body.replace("</head>", SITE_STYLE + "\n</head>", 1)
        body = re.sub(r"(<body[^>]*>)", lambda m: m.group(1) + _nav(pages, i, "top"), body, count=1)
        body = body.replace("</body>", _nav(pages, i, "bottom") + "\n</body>", 1)
        page = pages[i][0]
        _write(page, body)
        written.append(page)
        if progress:
            progress(i + 1, len(notebooks), page)
    items = "\n".join(f'<li><a href="{html.escape(page.name)}">{html.escape(title)}</a>'
                      f'<br><span class="kc-summary">{html.escape(notebook_title_and_summary(nb)[1])}</span></li>'
                      for (page, title), nb in zip(pages, nbs))
    index = out_dir / "index.html"
    _write(index, "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\">"
                     "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">"
                     f"<title>kalman-course</title>\n{SITE_STYLE}\n"
                     # the summaries' inline maths, typeset by the same local MathJax as the pages
                     "<script type=\"text/x-mathjax-config\">MathJax.Hub.Config({"
                     f"{MATHJAX_FONT_CONFIG} tex2jax: {{inlineMath: [['$', '$']]}}, messageStyle: 'none'}});</script>\n"
                     f"<script src=\"{exporter.mathjax_url}\"></script>\n</head>\n"
                     "<body class=\"kc-index\"><h1>kalman-course</h1>\n"
                     "<p>A Kalman-filtering course: every derivation shown and checked by code, from Bayes' "
                     "rule to an error-state filter on KITTI.</p>\n"
                     f"<ol>\n{items}\n</ol></body></html>\n")
    return [index, *written]
