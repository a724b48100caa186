"""Shared pytest set-up: quick notebook settings and a non-interactive matplotlib backend."""

import copy
import os
from pathlib import Path

import matplotlib
import pytest

matplotlib.use("Agg")
# Notebooks executed by the tests inherit this: small settings in CI.
os.environ.setdefault("SUNLAB_QUICK", "1")
os.environ.setdefault("MPLBACKEND", "Agg")


NOTEBOOK_DIR = Path(__file__).parents[1] / "notebooks"

#: per-cell limit; the slowest quick-mode cell (06's Table 5) takes about a minute on 2 cores
CELL_TIMEOUT_S = 900


def _execute(path, nbformat, nbclient):
    """The teacher edition of the notebook at ``path`` executed cell by cell in one kernel, and
    ``{exercise: (ename, evalue)}``: what its check raised on the plausible wrong answer of
    tests/_answers.py, run in the same kernel right after the check passed on the answer (a
    failing check stops the run); the answer is run again before the notebook goes on."""
    from _answers import WRONG

    from sunlab.course import editions

    src = nbformat.read(path, as_version=4)
    nb = editions.edition(src, path.name, student=False)
    # the teacher edition is the notebook's cells with nbgrader metadata and a quick cell
    # (SUNLAB_QUICK=1, set here too) inserted before the first code cell: indices move by one
    checks = {ex.check_cell + 1: ex for ex in editions.find_exercises(src, path.name)}
    client = nbclient.NotebookClient(nb, timeout=CELL_TIMEOUT_S, kernel_name="python3",
                                     store_widget_state=True,
                                     resources={"metadata": {"path": str(NOTEBOOK_DIR)}})
    caught = {}
    with client.setup_kernel():  # NotebookClient.execute's steps, with the probes between
        info = client.wait_for_reply(client.kc.kernel_info())
        nb.metadata["language_info"] = info["content"]["language_info"]
        for i, cell in enumerate(nb.cells):
            client.execute_cell(cell, i, execution_count=client.code_cells_executed + 1)
            ex = checks.get(i)
            if ex is None:
                continue
            answer = nb.cells[ex.solution_cell + 1]
            client.execute_cell(nbformat.v4.new_code_cell(
                editions.replace_solution(answer.source, WRONG[ex.number])), i)
            try:
                client.execute_cell(nbformat.v4.new_code_cell(cell.source), i)
                caught[ex.number] = (None, "the check passed on the wrong answer")
            except nbclient.exceptions.CellExecutionError as err:
                caught[ex.number] = (err.ename, err.evalue)
            client.execute_cell(nbformat.v4.new_code_cell(answer.source), i)
            nb.cells[i] = cell  # execute_cell stored the probe cells in its place
        client.set_widgets_metadata()
    quick = next(i for i, c in enumerate(nb.cells) if c.cell_type == "code")
    del nb.cells[quick]  # the notebook's own cells, as a reader runs them
    return nb, caught


@pytest.fixture(scope="session")
def executed_notebook():
    """``run(path)``: the notebook executed once per session in quick mode (nbclient, a fresh
    kernel, widget state stored as a front end saves it); each call gets its own copy.
    ``run.caught(path)``: from the same execution, what each exercise's check raised on a wrong
    answer (see :func:`_execute`). One execution serves the reader-facing test, the HTML-export
    test and the course's teacher-edition test: each notebook runs once in the suite."""
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    done = {}

    def execute(path):
        path = Path(path)
        if path not in done:
            # quick mode; and the kernel's own inline backend, not the Agg set above for tests
            env = {"SUNLAB_QUICK": "1", "MPLBACKEND": None}
            old = {k: os.environ.get(k) for k in env}
            for k, v in env.items():
                if v is None:
                    os.environ.pop(k, None)
                else:
                    os.environ[k] = v
            try:
                done[path] = _execute(path, nbformat, nbclient)
            finally:
                for k, v in old.items():
                    if v is None:
                        os.environ.pop(k, None)
                    else:
                        os.environ[k] = v
        return done[path]

    def run(path):
        return copy.deepcopy(execute(path)[0])

    run.caught = lambda path: dict(execute(path)[1])
    return run
