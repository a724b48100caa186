"""The documentation site (docs/, ``make docs``) builds with no warning.

``test_site_builds_without_a_warning`` builds the whole site as ``make docs`` does (nitpicky,
warnings as errors) but renders the notebooks as committed instead of running them, which keeps
it fast enough for the suite; ``make docs`` runs them. A docstring reference to a name that does
not exist, a docstring numpydoc or docutils cannot parse, a broken link between pages: each is a
warning, and the test fails naming it.
"""

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[1]
DOCS = ROOT / "docs"

#: the API pages the issue asks for by name, each with Parameters and Returns
MUST_HAVE = (
    "sunlab.calibration.fit",
    "sunlab.io.open_centroids",
    "sunlab.stats.evaluate",
    "sunlab.centroid.projection_window",
)


def _sunlab_docs():
    sys.path.insert(0, str(DOCS / "_ext"))
    try:
        import sunlab_docs
    finally:
        sys.path.remove(str(DOCS / "_ext"))
    return sunlab_docs


@pytest.fixture(scope="module")
def built_site(tmp_path_factory):
    for package in ("sphinx", "myst_nb", "numpydoc", "pydata_sphinx_theme"):
        pytest.importorskip(package, reason="the docs extra: pip install -e '.[docs]'")
    out = tmp_path_factory.mktemp("site")
    env = dict(os.environ, SUNLAB_DOCS_EXECUTE="off", PYTHONPATH=str(ROOT))
    proc = subprocess.run(
        [sys.executable, "-m", "sphinx", "-b", "html", "-n", "-W", "--keep-going", "-q",
         "-d", str(out / "doctrees"), str(DOCS), str(out / "html")],
        cwd=ROOT, env=env, capture_output=True, text=True, timeout=1200)
    return proc, out / "html"


@pytest.mark.slow
def test_site_builds_without_a_warning(built_site):
    proc, html = built_site
    assert proc.returncode == 0, f"the site has warnings:\n{proc.stderr[-6000:]}"
    assert (html / "index.html").is_file()


@pytest.mark.slow
@pytest.mark.parametrize("name", MUST_HAVE)
def test_api_page_shows_parameters_and_returns(built_site, name):
    _, html = built_site
    page = html / "api" / "generated" / f"{name}.html"
    assert page.is_file(), f"no API page for {name}"
    text = page.read_text(encoding="utf-8")
    assert f'id="{name}"' in text, f"{name}'s page does not document it"
    for section in ("Parameters", "Returns"):
        assert f">{section}<" in text, f"{name}'s page has no {section} section"


@pytest.mark.slow
def test_every_notebook_has_a_page(built_site):
    _, html = built_site
    missing = [p.stem for p in sorted((ROOT / "notebooks").glob("*.ipynb"))
               if not (html / "notebooks" / f"{p.stem}.html").is_file()]
    assert not missing, f"notebooks without a page: {missing}"


def test_every_room_of_sunlab_is_in_the_api_reference():
    pytest.importorskip("sphinx", reason="the docs extra: pip install -e '.[docs]'")
    docs = _sunlab_docs()
    grouped = {room for rooms in docs.GROUPS.values() for room in rooms}
    rooms = set(docs.rooms_on_disk(ROOT / "sunlab"))
    assert rooms <= grouped, f"rooms missing from the API reference: {sorted(rooms - grouped)}"
    assert grouped <= rooms, f"groups name rooms the package has not: {sorted(grouped - rooms)}"


def test_a_docstring_numpydoc_cannot_parse_is_reported():
    pytest.importorskip("numpydoc", reason="the docs extra: pip install -e '.[docs]'")
    docs = _sunlab_docs()
    good = "Add.\n\nParameters\n----------\nx : float\n    Degrees.\n\nReturns\n-------\nfloat\n"
    assert docs.numpydoc_problems(good) == []
    # a misspelt section header is one numpydoc does not know
    bad = good.replace("Returns\n-------", "Retruns\n-------")
    problems = docs.numpydoc_problems(bad)
    assert len(problems) == 1 and "Retruns" in problems[0], problems


def test_a_reference_resolves_only_to_an_object_that_exists():
    pytest.importorskip("sphinx", reason="the docs extra: pip install -e '.[docs]'")
    docs = _sunlab_docs()
    found = docs.locate("sunlab.multihole.defects.robust_z")
    import sunlab.multihole

    assert found is not None and found[0] is sunlab.multihole.defects.robust_z
    assert docs.locate("sunlab.multihole.defects.robust_zz") is None
    assert docs.locate("numpy.mean") is None  # another project's names are not sunlab's


def test_a_widget_is_drawn_from_its_saved_state():
    pytest.importorskip("myst_nb", reason="the docs extra: pip install -e '.[docs]'")
    pytest.importorskip("ipywidgets", reason="the widgets extra")
    import numpy as np
    from ipywidgets.embed import dependency_state

    from sunlab.sim import synthetic_centroids
    from sunlab.widgets import HoleExplorer

    sys.path.insert(0, str(DOCS / "_ext"))
    try:
        import sunlab_widgets
    finally:
        sys.path.remove(str(DOCS / "_ext"))
    a = np.repeat(np.linspace(-8, 2, 5), 5)
    b = np.tile(np.linspace(-2, 8, 5), 5)
    cen = synthetic_centroids(a, b, shots=2, layout="grid", noise_px=0.01,
                              defects={7: {"sigma_px": 1.0}})
    explorer = HoleExplorer(None, cen, order=2)
    explorer.buttons[7].click()
    page = sunlab_widgets.widget_html(dependency_state(explorer.ui), explorer.ui.model_id)
    # one button per hole with its colour on the metric's scale, the flagged hole marked
    assert page.count("<button") >= 100
    colour = explorer.buttons[3].style.button_color
    assert f"background: {colour}" in page
    assert ">7⚑</button>" in page
    # the Output widgets' figures (close-up, residual maps) as images, the statistics as HTML
    assert page.count('<img src="data:image/png;base64,') >= 2
    assert explorer.stats_html.value in page


def test_the_landing_page_counts_the_notebooks_and_those_with_exercises():
    import nbformat

    from sunlab.course import editions

    words = {n: w for n, w in enumerate("zero one two three four five six seven eight nine ten "
                                        "eleven twelve".split())}
    notebooks = sorted((ROOT / "notebooks").glob("[0-9][0-9]-*.ipynb"))
    with_exercises = sum(bool(editions.find_exercises(nbformat.read(p, 4), p.name))
                         for p in notebooks)
    text = " ".join((ROOT / "docs" / "index.md").read_text(encoding="utf-8").split())
    assert f"{words[len(notebooks)]} notebooks" in text
    assert f"{words[with_exercises]} of them with exercises" in text
