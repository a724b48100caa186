"""The documentation site (docs/, ``make docs``) builds with no warning.

``test_site_builds_without_a_warning`` builds the whole site as ``make docs`` does (nitpicky,
warnings as errors) but renders the notebooks as committed instead of running them, which keeps
it fast enough for the suite; ``make docs`` runs them. A docstring reference to a name that does
not exist, a docstring numpydoc or docutils cannot parse, a broken link between pages: each is a
warning, and the test fails naming it.
"""

import os
import re
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
         "-j", "auto",  # pages read on every core: the suite's process only waits here
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


# ------------------------------------------------------ verdicts the sensitivity table supports

#: within one sentence (a dot inside a file name or a number does not end it)
_S = r"(?:[^.;]|\.(?=\w))"
#: phrasings that state a value of F as found; ``{v}`` is a value the table does not identify
F_CLAIMS = (r"\bF\s*=\s*{v}\s*mm\W+(by|from) the (evidence|data|identification)",
            r"\b(as|is|was) identified\W+F\s*=\s*{v}\s*mm",
            r"\bF\s*=\s*{v}\s*mm\W+(is |was )?identified\b",
            r"\b(evidence|identification|data)\b" + _S + r"{{0,40}}\b(picks|picked|prefers|chose|"
            r"favou?rs|settles|gives|shows)\b" + _S + r"{{0,60}}\bF\s*=\s*{v}\s*mm",
            r"\bsettle[sd]\b" + _S + r"{{0,100}}\bat F\s*=\s*{v}\s*mm")
#: phrasings that state the gear (or its absence) as found
GEAR_CLAIMS = (r"\b(identified|identification|evidence)\b" + _S + r"{0,40}(?<!nor )(?<!not )"
               r"\b(found|finds|shows|rules out|ruled out|rejects|rejected|confirms|confirmed)\b"
               + _S + r"{0,20}\b(a|the|no) gear\b",
               r"\bgear error\b" + _S + r"{0,30}\b(re-)?identified bench\b",
               r"\bidentified bench\b" + _S + r"{0,80}\b(and|its) gear\b")
#: phrasings of any finding by the evidence itself, whatever it is of
EVIDENCE_CLAIMS = (r"\bthe (held-out )?evidence (picks|prefers|chose|favou?rs)\b",
                   r"\b(identification|evidence) (found|finds)\b",
                   r"\bas identified\W+(shows|has|carries|gives)\b",
                   r"\bas the identification\b" + _S + r"{0,60}\bpicks\b")
#: results of earlier protocol versions, which only the protocol and its history may quote
OLD_RESULTS = (r"\bversions? [1-3]\b" + _S + r"{0,80}\b(picked|held(?!-)|gave|chose)\b",
               r"\bmedian half-width of 0\.72\b", r"\bheld all 56 cells\b")


def _prose(path: Path) -> str:
    """A file's text as one line: a notebook's cell sources and text outputs, comment markers
    and doctest prompts dropped, every run of white space one space."""
    import json

    text = path.read_text(encoding="utf-8")
    if path.suffix == ".ipynb":
        cells = json.loads(text)["cells"]
        text = "\n".join("".join(c["source"]) + "\n" + "".join(
            "".join(o.get("text", "")) for o in c.get("outputs", [])) for c in cells)
    if path.suffix == ".py":
        text = re.sub(r"(?m)^\s*(#:?|>>>|\.\.\.)\s?", " ", text)
    text = text.replace("\\n", " ")
    return re.sub(r"\s+", " ", text)


def _repository_texts():
    """README, the docs' pages, notebooks, the package's and the studies' sources and notes,
    the benchmarks and the tests (this file left out: it holds the phrasings)."""
    paths = [ROOT / "README.md", *sorted(DOCS.glob("*.md")),
             *sorted(ROOT.glob("notebooks/*.ipynb")),
             *sorted(ROOT.glob("sunlab/**/*.py")), *sorted(ROOT.glob("sunlab/**/*.pyi")),
             *sorted(ROOT.glob("sunlab/data/*.json")), *sorted(ROOT.glob("studies/*.py")),
             ROOT / "studies" / "preset_sources.json",  # the preset sources' references
             *sorted(ROOT.glob("benchmarks/*.py")), *sorted(ROOT.glob("tests/**/*.py"))]
    return {p.relative_to(ROOT).as_posix(): _prose(p) for p in paths if p != Path(__file__)}


def verdict_claims(texts: dict, table) -> list[str]:
    """Each sentence of ``texts`` (name -> text) that states a verdict the sensitivity table
    (its ``F`` and ``gear`` columns) does not support, or quotes an earlier protocol version's
    result outside docs/identification.md's protocol and history (before its Results)."""
    from studies import sensitivity

    verdicts = sensitivity.verdicts(table)
    if verdicts["F"] == "not identified":  # every value a row gives is a claim
        value = "(" + "|".join(sorted({re.escape(v.split()[0]) for v in table["F"]
                                       if v != "not identified"})) + ")"
    else:  # any other value is
        value = rf"(?!{re.escape(verdicts['F'].split(': ', 1)[1].split()[0])}\b)\d+(\.\d+)?"
    patterns = [p.format(v=value) for p in F_CLAIMS]
    if verdicts["gear"] == "not identified":
        patterns += GEAR_CLAIMS
    if "not identified" in verdicts.values():
        patterns += EVIDENCE_CLAIMS
    found = []
    for name, text in texts.items():
        after = text.split("## Results", 1)[-1] if name == "docs/identification.md" else text
        found += [f"{name}: ...{t[max(m.start() - 60, 0):m.end() + 40]}..."
                  for t, ps in ((text, patterns), (after, OLD_RESULTS)) for p in ps
                  for m in re.finditer(p, t, re.I)]
    return found


def test_no_sentence_states_a_verdict_the_sensitivity_table_does_not_support():
    """Issue 46: F and the gear are choices of the presets where the table's rows disagree; no
    file says the evidence found them, and no earlier version's result is quoted outside the
    protocol's history."""
    import pandas as pd

    table = pd.read_csv(ROOT / "studies" / "results" / "sensitivity.csv")
    found = verdict_claims(_repository_texts(), table)
    assert not found, "\n".join(found)


def test_a_verdict_claim_is_caught():
    import pandas as pd

    split = pd.DataFrame({"F": ["5 mm", "17 mm"], "gear": ["no gear error", "gear error"]})
    said = {"a.md": "The paper's bench has F = 5 mm by the evidence. The gear error of the "
                    "re-identified bench moves beta. Under version 3 the rule picked F5-gear."}
    assert len(verdict_claims(said, split)) == 3
    # where every row agrees, saying so is the verdict
    agreed = pd.DataFrame({"F": ["5 mm", "5 mm"], "gear": ["gear error", "gear error"]})
    assert verdict_claims({"a.md": "F = 5 mm by the evidence."}, agreed) == []
    assert len(verdict_claims({"a.md": "F = 17 mm by the evidence."}, agreed)) == 1


def test_one_list_of_what_the_bench_does_not_explain_read_by_notebooks_05_and_06():
    """Issue 46: the list is written once (docs/identification.md, Results) and notebooks 05 and
    06 show it read from there, not a copy."""
    import json

    heading = "### What the bench does not explain"
    results = (DOCS / "identification.md").read_text(encoding="utf-8").split("## Results", 1)[1]
    assert results.count(heading) == 1
    for name in ("05-single-hole-experiments.ipynb", "06-multi-hole-mask.ipynb"):
        cells = json.loads((ROOT / "notebooks" / name).read_text(encoding="utf-8"))["cells"]
        code = ["".join(c["source"]) for c in cells if c["cell_type"] == "code"]
        assert any(f'"{heading}"' in c and '"identification.md"' in c for c in code), name
    copies = [p.name for p in DOCS.glob("*.md") if p.name != "identification.md"
              and heading in p.read_text(encoding="utf-8")]
    assert not copies, copies
