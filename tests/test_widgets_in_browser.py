"""The tuning sliders of lectures 03 and 09, used in a real JupyterLab in a real headless browser.

A JupyterLab server runs on a scratch notebook that builds chapter 03's explorer; headless
Chromium opens it, runs all cells through JupyterLab's own command, drags the σ_a slider's
handle with the mouse (Chrome DevTools protocol), and checks that the readout moved and the
kernel redrew the figure in place. Every Jupyter directory (config, data, runtime, settings,
workspaces) points into the test's temporary folder, so nothing of the user's is read or
written. Debian's ``chromium`` is needed, as for ``test_site_in_browser``.
"""

import asyncio
import json
import os
import re
import shutil
import socket
import subprocess
import sys
import time
import urllib.request

import nbformat
import pytest
from nbformat.v4 import new_code_cell, new_notebook

pytestmark = pytest.mark.slow

BROWSER = shutil.which("chromium") or shutil.which("chromium-browser")
TOKEN = "kc-widget-test"
EXPLORER = """\
from kalman_course.chapters import explorers
from kalman_course.data import cv_target
runs = [cv_target(40, 0.5, 0.4, 2.5, seed=s, dim=1) for s in range(5)]
explorers.cv_tuning_explorer(runs, [0.0, 1.0], [[6.25, 0.0], [0.0, 1.0]], 0.5, 0.4, 2.5)"""
READOUTS = "Array.from(document.querySelectorAll('.widget-readout')).map(e => e.textContent || e.value)"
FIGURE = "document.querySelector('.widget-output img')"


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _wait_for_server(port: int, proc, timeout: float = 90.0) -> None:
    start = time.monotonic()
    while time.monotonic() - start < timeout:
        if proc.poll() is not None:
            raise RuntimeError("jupyter lab exited before it served")
        try:
            urllib.request.urlopen(f"http://127.0.0.1:{port}/api/status?token={TOKEN}", timeout=2)
            return
        except OSError:
            time.sleep(0.5)
    raise TimeoutError("jupyter lab did not start")


class DevTools:
    """The few Chrome DevTools protocol calls the test needs, over tornado's websocket client."""

    def __init__(self, ws):
        self.ws, self.next_id = ws, 0

    async def call(self, method, **params):
        self.next_id += 1
        await self.ws.write_message(json.dumps({"id": self.next_id, "method": method, "params": params}))
        while True:
            message = json.loads(await self.ws.read_message())
            if message.get("id") == self.next_id:
                if "error" in message:
                    raise RuntimeError(f"{method}: {message['error']}")
                return message["result"]

    async def js(self, expression):
        result = await self.call("Runtime.evaluate", expression=expression, awaitPromise=True, returnByValue=True)
        if "exceptionDetails" in result:
            raise RuntimeError(f"{expression}: {result['exceptionDetails']}")
        return result["result"].get("value")

    async def wait_for(self, expression, what, timeout=120.0):
        start = time.monotonic()
        while time.monotonic() - start < timeout:
            value = await self.js(expression)
            if value:
                return value
            await asyncio.sleep(0.5)
        raise AssertionError(f"timed out waiting for {what}")

    async def drag(self, x, y, dx):
        await self.call("Input.dispatchMouseEvent", type="mousePressed", x=x, y=y, button="left", clickCount=1)
        for step in range(1, 11):
            await self.call("Input.dispatchMouseEvent", type="mouseMoved", x=x + dx * step / 10, y=y, button="left")
        await self.call("Input.dispatchMouseEvent", type="mouseReleased", x=x + dx, y=y, button="left", clickCount=1)


async def _use_the_sliders(ws_url) -> dict:
    from tornado.websocket import websocket_connect

    tools = DevTools(await websocket_connect(ws_url, max_message_size=2**27))
    await tools.wait_for("(() => { const w = window.jupyterapp && window.jupyterapp.shell.currentWidget;"
                         " const k = w && w.sessionContext && w.sessionContext.session"
                         " && w.sessionContext.session.kernel; return !!k && k.connectionStatus === 'connected'; })()",
                         "the notebook's kernel")
    await tools.js("window.jupyterapp.commands.execute('notebook:run-all-cells')")
    await tools.wait_for(f"document.querySelectorAll('.widget-readout').length >= 2 && !!{FIGURE}",
                         "two sliders and a figure", timeout=180)
    before = {"readouts": await tools.js(READOUTS), "figure": await tools.js(f"{FIGURE}.src")}
    x, y = await tools.js("(() => { const h = document.querySelector('.noUi-handle'); h.scrollIntoView();"
                          " const r = h.getBoundingClientRect(); return [r.x + r.width / 2, r.y + r.height / 2]; })()")
    await tools.drag(x, y, 100)
    await tools.wait_for(f"{FIGURE} && {FIGURE}.src !== {json.dumps(before['figure'])}", "the redrawn figure")
    return {"before": before, "readouts": await tools.js(READOUTS),
            "figures": await tools.js("document.querySelectorAll('.widget-output img').length")}


@pytest.fixture
def lab_and_browser(tmp_path):
    if BROWSER is None:
        if os.environ.get("KALMAN_COURSE_REQUIRE_BROWSER"):
            pytest.fail("chromium is required here (KALMAN_COURSE_REQUIRE_BROWSER is set) but not installed")
        pytest.skip("needs Debian's chromium (apt-get install chromium)")
    nb = new_notebook(cells=[new_code_cell(EXPLORER)])
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    nbformat.write(nb, tmp_path / "sliders.ipynb")
    env = dict(os.environ, **{name: str(tmp_path / folder) for name, folder in (
        ("JUPYTER_CONFIG_DIR", "config"), ("JUPYTER_DATA_DIR", "data"), ("JUPYTER_RUNTIME_DIR", "runtime"),
        ("JUPYTERLAB_SETTINGS_DIR", "settings"), ("JUPYTERLAB_WORKSPACES_DIR", "workspaces"))})
    env.pop("MPLBACKEND", None)                         # the kernel's own inline backend, as a learner has it
    port = _free_port()
    lab = subprocess.Popen([sys.executable, "-m", "jupyter", "lab", "--no-browser", "--ip=127.0.0.1", f"--port={port}",
                            f"--IdentityProvider.token={TOKEN}", f"--ServerApp.root_dir={tmp_path}", "--allow-root",
                            "--LabApp.expose_app_in_browser=True", "--LabApp.news_url=None"],
                           env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    browser = None
    try:
        _wait_for_server(port, lab)
        browser = subprocess.Popen([BROWSER, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
                                    f"--user-data-dir={tmp_path / 'profile'}", "--remote-debugging-port=0",
                                    "--window-size=1400,1000",
                                    f"http://127.0.0.1:{port}/lab/tree/sliders.ipynb?token={TOKEN}"],
                                   stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        line = ""
        while "DevTools listening on" not in line:
            line = browser.stderr.readline()
            if not line and browser.poll() is not None:
                raise RuntimeError("chromium exited before it listened")
        devtools = int(re.search(r"127\.0\.0\.1:(\d+)/", line).group(1))
        pages = json.load(urllib.request.urlopen(f"http://127.0.0.1:{devtools}/json", timeout=10))
        yield next(p["webSocketDebuggerUrl"] for p in pages if p["type"] == "page")
    finally:
        if browser is not None:
            browser.kill()
            browser.wait(10)
        lab.terminate()
        try:
            lab.wait(30)
        except subprocess.TimeoutExpired:
            lab.kill()


def test_dragging_a_slider_redraws_the_figure_with_the_new_value(lab_and_browser):
    seen = asyncio.run(asyncio.wait_for(_use_the_sliders(lab_and_browser), timeout=300))
    (sigma_a, sigma), (moved_sigma_a, same_sigma) = seen["before"]["readouts"], seen["readouts"]
    assert (sigma_a, sigma) == ("0.400", "2.50")        # the explorer starts at the setting it was given
    assert float(moved_sigma_a) > 1.5 * float(sigma_a)  # dragged to the right on a log scale: a larger σ_a
    assert same_sigma == sigma                          # the other slider did not move
    assert seen["figures"] == 1                         # the old figure was replaced, not stacked
