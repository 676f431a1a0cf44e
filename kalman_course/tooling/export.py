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

REMOTE_SCRIPT_RE = re.compile(r'<script[^>]*src="https?://[^"]*"[^>]*>\s*</script>\s*')

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


def derivations_latex(derivations: dict) -> str:
    """One standalone LaTeX document with every derivation, each equation labelled."""
    lines = [r"\documentclass[a4paper,10pt]{article}",
             r"\usepackage[margin=2cm]{geometry}",
             r"\usepackage{amsmath,amssymb}",
             r"\allowdisplaybreaks",
             r"\setcounter{MaxMatrixCols}{20}",
             r"\title{kalman-course: derivations}",
             r"\date{}",
             r"\begin{document}",
             r"\maketitle",
             "Every equation below is generated from \\texttt{kalman\\_course.symbolic}; identities and "
             "checks are proved there by SymPy.",
             ""]
    for name, d in derivations.items():
        lines += [rf"\section{{{_latex_text(d.title)}}}\label{{sec:{name}}}",
                  _latex_text(d.model), ""]
        for eq in d.equations:
            note = _latex_text(eq.description) if eq.description else ""
            lines += [rf"\paragraph{{{_latex_text(eq.label)}}} ({KIND_NOTE[eq.kind]}) {note}",
                      r"\begin{equation}", rf"\label{{{equation_label(name, eq.label)}}}",
                      eq.latex(), r"\end{equation}", ""]
    lines += [r"\end{document}", ""]
    return "\n".join(lines)


def derivations_markdown(derivations: dict) -> str:
    """Every derivation as Markdown with ``$...$`` / ``$$...$$`` maths and labelled equations."""
    lines = ["# kalman-course: derivations", "",
             "Generated from `kalman_course.symbolic`; identities and checks are proved there by SymPy.", ""]
    for name, d in derivations.items():
        lines += [f"## {d.title}", "", f"<a id=\"{name}\"></a>", "", d.model, ""]
        for eq in d.equations:
            anchor = equation_label(name, eq.label)
            note = f" {eq.description}" if eq.description else ""
            lines += [f"**({eq.label})** <a id=\"{anchor}\"></a> *{KIND_NOTE[eq.kind]}*.{note}", "",
                      f"$$ {eq.latex()} \\tag{{{name}:{eq.label}}} $$", ""]
    return "\n".join(lines)


def export_derivations(fmt: str, out_dir: str | Path) -> Path:
    """Write ``derivations.tex`` or ``derivations.md`` into ``out_dir`` and return its path."""
    if fmt not in ("tex", "md"):
        raise ValueError(f"fmt must be 'tex' or 'md', got {fmt!r}")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    derivations = all_derivations()
    text = derivations_latex(derivations) if fmt == "tex" else derivations_markdown(derivations)
    path = out_dir / f"derivations.{fmt}"
    path.write_text(text, encoding="utf-8")
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


def export_notebooks_html(notebooks: list[Path], out_dir: str | Path, progress=None) -> list[Path]:
    """Write each notebook as an HTML page using a local MathJax, plus ``index.html``."""
    from nbconvert import HTMLExporter

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    target = out_dir / "mathjax"
    if not (target / "MathJax.js").is_file():
        shutil.copytree(mathjax_dir(), target, dirs_exist_ok=True)
    exporter = HTMLExporter(template_name="lab")
    exporter.mathjax_url = "mathjax/MathJax.js?config=TeX-AMS-MML_HTMLorMML-full"
    written = []
    for i, nb_path in enumerate(notebooks, 1):
        body, _ = exporter.from_filename(str(nb_path))
        # The template loads require.js from a CDN for widgets, which the lectures do not use.
        body = REMOTE_SCRIPT_RE.sub("", body)
        page = out_dir / f"{Path(nb_path).stem}.html"
        page.write_text(body, encoding="utf-8")
        written.append(page)
        if progress:
            progress(i, len(notebooks), page)
    items = "\n".join(f'<li><a href="{html.escape(p.name)}">{html.escape(p.stem.replace("_", " "))}</a></li>'
                      for p in written)
    index = out_dir / "index.html"
    index.write_text("<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>kalman-course</title></head>\n"
                     f"<body><h1>kalman-course: lectures</h1>\n<ol>\n{items}\n</ol></body></html>\n",
                     encoding="utf-8")
    return [index, *written]
