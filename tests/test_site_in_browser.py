"""The exported course site, opened in a real headless browser with the network blocked.

Each page is loaded from a copy with a small probe appended: when MathJax has finished, the
probe writes what it found into the page (formulas typeset, MathJax errors, the web font
MathJax used, images that did not load, navigation links), and Chromium prints the final
DOM (``--dump-dom``). Debian's ``chromium`` is needed: `.ci/run` installs it and sets
``KALMAN_COURSE_REQUIRE_BROWSER=1``, so that in CI a missing browser fails instead of
skipping.
"""

import json
import os
import re
import shutil
import subprocess

import pytest

from kalman_course.tooling import cli

from conftest import ROOT

pytestmark = pytest.mark.slow

BROWSER = shutil.which("chromium") or shutil.which("chromium-browser")
LECTURES = ["01_bayes_rule.ipynb", "06_iterated_ekf.ipynb", "A1_notation_glossary.ipynb"]  # maths, plots, tables

PROBE = """
<script>
(function () {
  function report() {
    var out = {};
    out.math = document.querySelectorAll('.MathJax, .MathJax_Display').length;
    out.errors = document.querySelectorAll('.MathJax_Error, merror, [data-mjx-error]').length;
    var jax = window.MathJax && MathJax.OutputJax && MathJax.OutputJax['HTML-CSS'];
    out.font = jax && jax.fontInUse ? jax.fontInUse : null;
    out.broken_images = Array.prototype.filter.call(document.images, function (img) {
      return !(img.complete && img.naturalWidth > 0); }).map(function (img) { return img.src.slice(0, 60); });
    out.nav = Array.prototype.map.call(document.querySelectorAll('nav.kc-nav a'),
                                       function (a) { return a.getAttribute('href'); });
    var pre = document.createElement('pre');
    pre.id = 'kc-probe';
    pre.textContent = JSON.stringify(out);
    document.body.appendChild(pre);
  }
  window.addEventListener('load', function () {
    if (window.MathJax && MathJax.Hub) { MathJax.Hub.Queue(report); } else { report(); }
  });
})();
</script>
"""


def _probe(page, tmp_path) -> dict:
    """Load ``page`` (a copy with the probe) in headless Chromium; return what the probe saw."""
    probed = page.with_name(f"probe-{page.name}")
    probed.write_text(page.read_text(encoding="utf-8").replace("</body>", PROBE + "</body>", 1), encoding="utf-8")
    out = subprocess.run(
        [BROWSER, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
         f"--user-data-dir={tmp_path / 'profile'}", "--host-resolver-rules=MAP * ~NOTFOUND",  # no network
         "--allow-file-access-from-files", "--virtual-time-budget=30000", "--dump-dom", probed.as_uri()],
        capture_output=True, text=True, timeout=180)
    found = re.search(r'<pre id="kc-probe">(.*?)</pre>', out.stdout, re.S)
    assert found, f"the page did not finish (MathJax never ran?): {out.stderr[-500:]}"
    return json.loads(found.group(1).replace("&quot;", '"').replace("&amp;", "&"))


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    if BROWSER is None:
        if os.environ.get("KALMAN_COURSE_REQUIRE_BROWSER"):
            pytest.fail("chromium is required here (KALMAN_COURSE_REQUIRE_BROWSER is set) but not installed")
        pytest.skip("needs Debian's chromium (apt-get install chromium)")
    out = tmp_path_factory.mktemp("site")
    assert cli.main(["export", "notebooks", "--to", "html", "-o", str(out),
                     *[str(ROOT / "notebooks" / name) for name in LECTURES]]) == 0
    return out


@pytest.mark.parametrize("name", LECTURES)
def test_every_formula_is_typeset_with_mathjax_fonts_and_every_image_loads(site, tmp_path, name):
    seen = _probe(site / name.replace(".ipynb", ".html"), tmp_path)
    assert seen["math"] > 5, seen
    assert seen["errors"] == 0, seen
    assert seen["font"] == "STIX-Web", seen           # MathJax's own web font, not a system fallback
    assert seen["broken_images"] == [], seen
    assert seen["nav"] and all((site / href).is_file() for href in seen["nav"]), seen


def test_the_index_typesets_its_summaries(site, tmp_path):
    seen = _probe(site / "index.html", tmp_path)
    assert seen["errors"] == 0 and seen["math"] >= 1 and seen["font"] == "STIX-Web", seen
