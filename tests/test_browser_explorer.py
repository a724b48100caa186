"""The HoleExplorer in a real headless browser: Voila serves a notebook, Chromium renders it.

Needs Debian's chromium (/usr/bin/chromium) and the ``browser`` extra (voila, playwright; no
``playwright install``: the system Chromium is used). Skips with the reason when they are absent.
"""

import os
import shutil
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.browser

CHROMIUM = "/usr/bin/chromium"
ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--disable-quic"]

CELL = '''\
import numpy as np
import dask.array as da
from sunlab import multihole as mh, schema
from sunlab.widgets import HoleExplorer

a = np.repeat(np.linspace(-8.0, 2.0, 4), 4)
b = np.tile(np.linspace(-2.0, 8.0, 4), 4)
cen = mh.synthetic_centroids(a, b, shots=1, noise_px=0.01, defects={7: {"sigma_px": 1.5}})
frame = np.zeros((1024, 1280), np.uint16)
yy, xx = np.mgrid[:1024, :1280]
for x, y in zip(cen.x.values[0, 0], cen.y.values[0, 0]):
    sl = np.s_[int(y) - 20:int(y) + 21, int(x) - 20:int(x) + 21]
    frame[sl] += (600 * ((xx[sl] - x) ** 2 + (yy[sl] - y) ** 2 < 13**2)).astype(np.uint16)
frames = da.concatenate([da.from_array(frame[None, None]),
                         da.zeros((15, 1, 1024, 1280), dtype=np.uint16,
                                  chunks=(1, 1, 1024, 1280))])
cube = schema.frames_dataset(frames, a, b)
HoleExplorer(cube, cen, order=1, metric="scatter")
'''


def _requirements():
    if not Path(CHROMIUM).exists():
        pytest.skip(f"{CHROMIUM} not found: apt-get install -y chromium")
    for mod in ("voila", "playwright"):
        try:
            __import__(mod)
        except ImportError:
            pytest.skip(f"{mod} not installed: pip install 'sunlab[browser]'")


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_explorer_renders_in_chromium(tmp_path):
    _requirements()
    import nbformat
    from PIL import Image
    from playwright.sync_api import Error as PlaywrightError
    from playwright.sync_api import sync_playwright

    nb = nbformat.v4.new_notebook()
    nb.cells = [nbformat.v4.new_code_cell(CELL)]
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3",
                                 "language": "python"}
    path = tmp_path / "explorer.ipynb"
    nbformat.write(nb, path)
    port = _free_port()
    env = {**os.environ, "MPLBACKEND": "Agg", "PYTHONPATH": str(Path(__file__).parents[1])}
    voila = shutil.which("voila", path=str(Path(sys.executable).parent)) or "voila"
    log = open(tmp_path / "voila.log", "w")  # noqa: SIM115 (closed in finally)
    proc = subprocess.Popen(
        [voila, "--no-browser", f"--port={port}", "--Voila.ip=127.0.0.1", str(path)],
        cwd=tmp_path, env=env, stdout=log, stderr=subprocess.STDOUT,
    )
    url = f"http://127.0.0.1:{port}/"
    try:
        for _ in range(150):
            try:
                urllib.request.urlopen(url + "voila/static/", timeout=1)  # noqa: S310
            except urllib.error.HTTPError:
                break  # the server answers
            except OSError:
                time.sleep(0.2)
                continue
            break
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
            page = browser.new_page(viewport={"width": 1400, "height": 1000})
            page.goto(url, timeout=60000)
            try:
                page.wait_for_selector(".widget-output img", timeout=60000)
            except Exception as err:
                log.flush()
                tail = (tmp_path / "voila.log").read_text()[-3000:]
                raise AssertionError(f"no figure in the page; voila log:\n{tail}") from err
            # the clickable map: a grid of 100 buttons, labelled by hole
            buttons = page.locator(".widget-gridbox button")
            assert buttons.count() == 100
            # a stamp and a residual map, decoded by the browser
            imgs = page.locator(".widget-output img")
            assert imgs.count() >= 2
            width = imgs.first.evaluate("e => e.naturalWidth")
            assert width > 100
            page.screenshot(path=str(tmp_path / "before.png"), full_page=True)
            # clicking a hole goes through the kernel and comes back
            buttons.nth(7).click()
            page.wait_for_selector("text=hole 7 (row 0, column 7)", timeout=30000)
            # the statistics table is redrawn last by a selection: then stamp and residual
            # map have been re-rendered too
            page.wait_for_selector("text=hole 7 alone", timeout=30000)
            assert page.locator("text=hole 0 alone").count() == 0
            stamp_png = tmp_path / "stamp.png"
            # the click re-renders the figures: an image found mid-swap is detached from the
            # DOM, so take the stamp once the new one stands still (bounded retries)
            for attempt in range(20):
                try:
                    page.locator(".widget-output img").first.screenshot(
                        path=str(stamp_png), timeout=5000)
                    break
                except PlaywrightError:
                    if attempt == 19:
                        raise
                    page.wait_for_timeout(250)
            shot = tmp_path / "explorer.png"
            page.screenshot(path=str(shot), full_page=True)
            browser.close()
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
        log.close()
    full = np.asarray(Image.open(shot).convert("RGB"), dtype=float)
    assert full.std() > 20  # not a blank page
    assert len(np.unique(full.reshape(-1, 3), axis=0)) > 100  # the coloured map and figures
    stamp = np.asarray(Image.open(stamp_png).convert("L"), dtype=float)
    assert stamp.std() > 10  # the stamp shows a spot, not an empty box
