"""Shared pytest set-up: quick notebook settings and a non-interactive matplotlib backend."""

import asyncio
import copy
import os
from concurrent.futures import ThreadPoolExecutor
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

#: notebooks executed side by side: pytest only waits while a kernel computes, so two kernels
#: keep the 2 cores of CI busy (the outputs do not depend on it; the run time does)
PARALLEL_NOTEBOOKS = 2

#: the notebooks the selected tests execute, in the order they ask (pytest_collection_finish)
_WANTED = []


def pytest_collection_finish(session):
    for item in session.items:
        if "executed_notebook" not in getattr(item, "fixturenames", ()):
            continue
        params = getattr(getattr(item, "callspec", None), "params", {})
        path = params.get("path") or (NOTEBOOK_DIR / params["name"] if "name" in params else None)
        if path is not None and Path(path) not in _WANTED:
            _WANTED.append(Path(path))


def _execute(path, nbformat, nbclient, **kernel):
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
    with client.setup_kernel(**kernel):  # NotebookClient.execute's steps, probes between
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


def _execute_in_thread(path, nbformat, nbclient, env, logs):
    """:func:`_execute` in a worker thread, which closes the event loop nbclient opened for it;
    the kernel's own stdout and stderr (not the cells' outputs) go to ``logs/NAME.log``, not
    into the output pytest captures for whichever test runs meanwhile."""
    from jupyter_core.utils import ensure_event_loop

    try:
        with open(logs / f"{Path(path).stem}.log", "w") as log:
            return _execute(path, nbformat, nbclient, env=env, stdout=log, stderr=log)
    finally:
        loop = ensure_event_loop()  # this thread's loop (jupyter_core's run_sync keeps it)
        loop.run_until_complete(loop.shutdown_asyncgens())
        loop.close()
        asyncio.set_event_loop(None)


@pytest.fixture(scope="session")
def executed_notebook(tmp_path_factory):
    """``run(path)``: the notebook executed once per session in quick mode (nbclient, a fresh
    kernel, widget state stored as a front end saves it); each call gets its own copy.
    ``run.caught(path)``: from the same execution, what each exercise's check raised on a wrong
    answer (see :func:`_execute`). One execution serves the reader-facing test, the HTML-export
    test and the course's teacher-edition test: each notebook runs once in the suite. The first
    call also starts the other notebooks the selected tests ask for, PARALLEL_NOTEBOOKS at once."""
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    # quick mode; and the kernel's own inline backend, not the Agg set above for tests
    env = {k: v for k, v in os.environ.items() if k != "MPLBACKEND"}
    env["SUNLAB_QUICK"] = "1"
    pool = ThreadPoolExecutor(PARALLEL_NOTEBOOKS, thread_name_prefix="notebook")
    runs, logs = {}, tmp_path_factory.mktemp("kernels")

    def execute(path):
        for p in (Path(path), *_WANTED):  # the one asked for first
            if p not in runs:
                runs[p] = pool.submit(_execute_in_thread, p, nbformat, nbclient, env, logs)
        return runs[Path(path)].result()

    def run(path):
        return copy.deepcopy(execute(path)[0])

    run.caught = lambda path: dict(execute(path)[1])
    yield run
    pool.shutdown(cancel_futures=True)
