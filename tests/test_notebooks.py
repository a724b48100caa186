"""Contract of the notebooks: numbered, stripped of outputs, the skeleton of STYLE.md, and what a
reader sees when they run.

``test_executed_notebook_shows_what_a_reader_expects`` executes every notebook in quick mode
(``SUNLAB_QUICK=1``, one kernel per notebook, nbclient; the ``executed_notebook`` fixture of
conftest.py, shared with the HTML-export test and the course's teacher-edition test: it runs
the teacher edition, these cells with a quick cell first) and checks its outputs: at least one
figure, a PNG from every cell that makes a figure, and none of the noise that hides results (a
``<Figure size ...>`` text instead of the figure, ``Text(...)`` or ``np.float64(...)`` reprs,
Dask or tqdm progress bars, ``<... object at 0x...>`` reprs). This is how ``make test`` runs
the notebooks.
"""

import json
import re
from pathlib import Path

import pytest

NOTEBOOK_DIR = Path(__file__).parents[1] / "notebooks"
NOTEBOOKS = sorted(NOTEBOOK_DIR.glob("*.ipynb"))

#: a cell whose code calls one of these makes a figure and must show it as image/png
MAKES_FIGURE = re.compile(
    r"\b(plt\.(subplots|figure)|plots\.error_\w+|mh\.(fig1[345]_\w+|plot_metric_map))\("
)

#: output text a reader must never see
NOISE = {
    "figure shown as text": re.compile(r"<Figure size"),
    "Dask progress bar": re.compile(r"% Completed"),
    "matplotlib Text repr": re.compile(r"(^|\[)Text\(", re.M),
    "numpy scalar repr": re.compile(r"np\.(float|int)\d+\("),
    "object repr": re.compile(r"<[\w.]+ (object )?at 0x[0-9a-fA-F]+>"),
    "tqdm progress bar": re.compile(r"\d+%\|.*\||\d+(\.\d+)?(it|s)/(s|it)\]"),
}


def test_notebooks_exist():
    assert NOTEBOOKS, "notebooks/ holds no notebook"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_numbered_name(path):
    assert re.fullmatch(r"\d\d-[a-z0-9-]+\.ipynb", path.name), path.name


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_committed_without_outputs(path):
    nb = json.loads(path.read_text())
    dirty = [
        i
        for i, cell in enumerate(nb["cells"])
        if cell["cell_type"] == "code" and (cell.get("outputs") or cell.get("execution_count"))
    ]
    assert not dirty, f"{path.name}: cells {dirty} carry outputs; clear them before committing"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_skeleton(path):
    nb = json.loads(path.read_text())
    text = "\n".join("".join(c["source"]) for c in nb["cells"] if c["cell_type"] == "markdown")
    assert nb["cells"][0]["cell_type"] == "markdown" and "".join(
        nb["cells"][0]["source"]
    ).startswith("# "), "the first cell is the title"
    for heading in ("Overview", "Prerequisites", "Summary", "References"):
        assert re.search(rf"^#+ .*{heading}", text, re.M | re.I), f"{path.name}: no {heading!r}"
    code = "\n".join("".join(c["source"]) for c in nb["cells"] if c["cell_type"] == "code")
    assert "SUNLAB_QUICK" in code, f"{path.name}: no quick-mode switch for CI"


def _texts(output) -> list[str]:
    """Every text of one cell output that a reader can see."""
    if output.get("output_type") == "stream":
        return [output.get("text", "")]
    if output.get("output_type") == "error":
        return ["\n".join(output.get("traceback", []))]
    data = output.get("data", {})
    # a front end shows the richest format: beside an image, text/plain is never seen
    shown = ("text/html", "text/markdown") if "image/png" in data else (
        "text/plain", "text/html", "text/markdown")
    return [data[k] for k in shown if k in data]


def reader_problems(nb) -> list[str]:
    """What a reader of the executed notebook would stumble on (empty when nothing)."""
    problems = []
    code = [(i, c) for i, c in enumerate(nb.cells) if c.cell_type == "code"]
    pngs = {i: any("image/png" in o.get("data", {}) for o in c.outputs) for i, c in code}
    if not any(pngs.values()):
        problems.append("no image/png output at all")
    for i, c in code:
        if MAKES_FIGURE.search(c.source) and not pngs[i]:
            problems.append(f"cell {i} makes a figure but shows no image/png")
        for o in c.outputs:
            for text in _texts(o):
                for what, pattern in NOISE.items():
                    m = pattern.search(text)
                    if m:
                        seen = text[max(m.start() - 30, 0):m.end() + 30]
                        problems.append(f"cell {i}: {what}: {seen!r}")
    return problems


def test_reader_problems_are_caught():
    """The checks fire on what the issue saw: a figure as text, a Text repr, a bar, no PNG."""
    nbformat = pytest.importorskip("nbformat")
    v4 = nbformat.v4
    cells = [
        v4.new_code_cell("plots.error_maps(local)", outputs=[v4.new_output(
            "execute_result", {"text/plain": "<Figure size 550x500 with 1 Axes>"})]),
        v4.new_code_cell("ax.set_xlabel('a')", outputs=[v4.new_output(
            "execute_result", {"text/plain": "[Text(0.5, 0, 'a')]"})]),
        v4.new_code_cell("x", outputs=[v4.new_output(
            "stream", name="stderr", text="acquire:  40%|####  | 4/10 [00:01<00:02, 3.1it/s]")]),
        v4.new_code_cell("v", outputs=[v4.new_output(
            "execute_result", {"text/plain": "np.float64(-16.5)"})]),
        v4.new_code_cell("sunlab.set_options(progress=False)", outputs=[v4.new_output(
            "execute_result", {"text/plain": "<sunlab.options.set_options at 0x7fef5dc92d10>"})]),
    ]
    found = reader_problems(v4.new_notebook(cells=cells))
    assert any("no image/png" in p for p in found)
    assert any("cell 0 makes a figure" in p for p in found)
    assert any("figure shown as text" in p for p in found)
    assert any("Text repr" in p for p in found)
    assert any("tqdm" in p for p in found)
    assert any("numpy scalar" in p for p in found)
    assert any("cell 4: object repr" in p for p in found)
    good = v4.new_code_cell("plots.error_maps(local)", outputs=[v4.new_output(
        "execute_result", {"text/plain": "<Figure size 550x500 with 1 Axes>",
                           "image/png": "iVBO"})])
    assert reader_problems(v4.new_notebook(cells=[good])) == []


@pytest.mark.slow
@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_executed_notebook_shows_what_a_reader_expects(path, executed_notebook):
    nb = executed_notebook(path)
    problems = reader_problems(nb)
    assert not problems, f"{path.name}:\n" + "\n".join(problems)
