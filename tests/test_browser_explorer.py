"""The HoleExplorer in a real headless browser: Voila serves a notebook, Chromium renders it.

Needs Debian's chromium (/usr/bin/chromium) and the ``browser`` extra (voila, playwright; no
``playwright install``: the system Chromium is used). Skips with the reason when they are absent.
"""

import os
import re
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


# The paper bench: its default 100-hole mask carries six random defects, two of them burred rims
# (holes 37 and 85 with seed 2005). Every 2nd calibration pose, one shot: 100 frames, enough for
# the edge roughness to flag both burrs (robust z 7.8 and 13.4 in the quick Table 5 run).
PAPER_CELL = """\
import numpy as np
import sunlab
from sunlab import centroid, plans, sim
from sunlab import multihole as mh
from sunlab.widgets import HoleExplorer

sunlab.set_options(progress=False)
from sunlab.reproduce.pipeline import mounting_offset_px

plan = plans.experiment("I").thin(2).with_shots(1)
# the sensor's mounting moves every spot by more than half the hole pitch: measure it with the
# one-hole mask first (as sunlab reproduce --table 5 does) to number the 100 spots
one = centroid.locate(sim.simulate(plans.custom([-12.0, -6.0, 0.0], [0.0, 6.0, 12.0], shots=1),
                                   sim.Bench.paper_single_hole(), seed=0), progress=False)
dx, dy = mounting_offset_px(one)
cube = sim.simulate(plan, sim.Bench.paper_multi_hole(), seed=0)
moved = cube.assign_coords(hole_x_cf=cube.hole_x_cf + dx, hole_y_cf=cube.hole_y_cf + dy)
cen = centroid.locate(moved, "tight", progress=False).assign_coords(
    hole_x_cf=cube.hole_x_cf, hole_y_cf=cube.hole_y_cf)
s2 = mh.PerHoleAverage(order=5).fit(cen)
metrics = mh.defect_metrics(cen, strategy=s2, cube=cube)
HoleExplorer(cube, cen, strategy=s2, metrics=metrics, metric="edge_roughness")
"""


def _serve(tmp_path, cell, name):
    """Start Voila on a one-cell notebook; return (process, url, log file)."""
    import nbformat

    nb = nbformat.v4.new_notebook()
    nb.cells = [nbformat.v4.new_code_cell(cell)]
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3",
                                 "language": "python"}
    path = tmp_path / f"{name}.ipynb"
    nbformat.write(nb, path)
    port = _free_port()
    env = {**os.environ, "MPLBACKEND": "Agg", "PYTHONPATH": str(Path(__file__).parents[1])}
    voila = shutil.which("voila", path=str(Path(sys.executable).parent)) or "voila"
    log = open(tmp_path / f"{name}.log", "w")  # noqa: SIM115 (closed by the caller)
    proc = subprocess.Popen(
        [voila, "--no-browser", f"--port={port}", "--Voila.ip=127.0.0.1",
         "--MappingKernelManager.cull_idle_timeout=0", str(path)],
        cwd=tmp_path, env=env, stdout=log, stderr=subprocess.STDOUT,
    )
    url = f"http://127.0.0.1:{port}/"
    for _ in range(150):
        try:
            urllib.request.urlopen(url + "voila/static/", timeout=1)  # noqa: S310
        except urllib.error.HTTPError:
            break
        except OSError:
            time.sleep(0.2)
            continue
        break
    return proc, url, log


@pytest.fixture(scope="module")
def paper_page(tmp_path_factory):
    """One Voila server, kernel, browser and page of the paper bench's explorer, shared by the
    tests below: each asserts its own things on it (the page, then the clicks of each test)."""
    _requirements()
    from playwright.sync_api import sync_playwright

    tmp_path = tmp_path_factory.mktemp("browser")
    proc, url, log = _serve(tmp_path, PAPER_CELL, "paper")
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
            page = browser.new_page(viewport={"width": 1500, "height": 1100})
            # Voila answers once the cell has run: 100 frames of 100 spots, about a minute
            page.goto(url, timeout=600000)
            try:
                page.wait_for_selector(".sunlab-closeup img", timeout=300000)
            except Exception as err:
                log.flush()
                tail = (tmp_path / "paper.log").read_text()[-3000:]
                raise AssertionError(f"no explorer in the page; voila log:\n{tail}") from err
            yield page
            browser.close()
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
        log.close()


def test_explorer_renders_in_chromium(paper_page, tmp_path):
    from PIL import Image
    from playwright.sync_api import Error as PlaywrightError

    page = paper_page
    # the clickable map: a grid of 100 buttons, labelled by hole
    buttons = page.locator(".widget-gridbox button")
    assert buttons.count() == 100
    # the colour bar, a stamp and a residual map, decoded by the browser
    imgs = page.locator(".widget-output img")
    assert imgs.count() >= 2
    width = imgs.first.evaluate("e => e.naturalWidth")
    assert width > 100
    # clicking a hole goes through the kernel and comes back
    page.locator(".widget-gridbox button", has_text=re.compile(r"^7\D*$")).click()
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
            page.locator(".sunlab-closeup img").first.screenshot(path=str(stamp_png),
                                                                 timeout=5000)
            break
        except PlaywrightError:
            if attempt == 19:
                raise
            page.wait_for_timeout(250)
    shot = tmp_path / "explorer.png"
    page.screenshot(path=str(shot), full_page=True)
    full = np.asarray(Image.open(shot).convert("RGB"), dtype=float)
    assert full.std() > 20  # not a blank page
    assert len(np.unique(full.reshape(-1, 3), axis=0)) > 100  # the coloured map and figures
    stamp = np.asarray(Image.open(stamp_png).convert("L"), dtype=float)
    assert stamp.std() > 10  # the stamp shows a spot, not an empty box


def test_burred_holes_of_the_paper_bench_are_flagged_in_chromium(paper_page):
    page = paper_page
    buttons = page.locator(".widget-gridbox button")
    assert buttons.count() == 100
    # the legend compares the flags with the simulator's injected defects
    legend = page.locator("text=injected (simulation)").first.inner_text()
    for h in (37, 85):
        assert f"{h} burred" in legend
        # flagged from the start: the button carries the flag before any click
        label = page.locator(".widget-gridbox button", has_text=f"{h}⚑")
        assert label.count() == 1, f"hole {h} is not marked as flagged on the map"
        label.click()
        page.wait_for_selector(f"text=hole {h} alone", timeout=60000)
        info = page.locator(".sunlab-info").inner_text()
        assert f"hole {h}" in info and "flagged" in info
        assert "injected defect (simulation): burred" in info
        # the close-up jumped to a frame where the hole's spot is on the detector
        assert page.locator(".sunlab-closeup img").count() == 1


def test_exported_html_of_notebook_06_keeps_the_explorer_state(tmp_path, executed_notebook):
    # an HTML export shows widgets from the widget state saved in the notebook; the state must
    # hold the explorer's last view: its map labels, flags and the close-up image
    import json
    import re

    nbconvert = pytest.importorskip("nbconvert")
    root = Path(__file__).parents[1]
    nb = executed_notebook(root / "notebooks" / "06-multi-hole-mask.ipynb")
    body, _ = nbconvert.HTMLExporter().from_notebook_node(nb)
    (tmp_path / "06.html").write_text(body)
    m = re.search(r'<script type="application/vnd.jupyter.widget-state\+json">(.*?)</script>',
                  body, re.S)
    assert m, "the exported HTML holds no widget state"
    state = json.loads(m.group(1))["state"]
    views = [o for o in (c.get("outputs", []) for c in nb.cells if c.cell_type == "code")
             for o in o if "application/vnd.jupyter.widget-view+json" in o.get("data", {})]
    assert views and views[-1]["data"]["application/vnd.jupyter.widget-view+json"]["model_id"] \
        in state
    labels = {s["state"].get("description") for s in state.values()
              if s["model_name"] == "ButtonModel"}
    assert {"37⚑", "85⚑"} <= labels  # the burred holes, flagged on the map
    closeups = [s for s in state.values() if s["model_name"] == "OutputModel"
                and "sunlab-closeup" in s["state"].get("_dom_classes", [])]
    assert closeups and "image/png" in closeups[0]["state"]["outputs"][0]["data"]
    infos = [s["state"]["value"] for s in state.values()
             if "sunlab-info" in s["state"].get("_dom_classes", [])]
    assert infos and "injected defect (simulation): burred" in infos[0]
