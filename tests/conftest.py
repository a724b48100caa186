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


@pytest.fixture(scope="session")
def executed_notebook():
    """``run(path)``: the notebook executed once per session in quick mode (nbclient, a fresh
    kernel, widget state stored as a front end saves it); each call gets its own copy, so the
    reader-facing test and the HTML-export test share one execution."""
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    done = {}

    def run(path):
        path = Path(path)
        if path not in done:
            nb = nbformat.read(path, as_version=4)
            # quick mode; and the kernel's own inline backend, not the Agg set above for tests
            env = {"SUNLAB_QUICK": "1", "MPLBACKEND": None}
            old = {k: os.environ.get(k) for k in env}
            for k, v in env.items():
                if v is None:
                    os.environ.pop(k, None)
                else:
                    os.environ[k] = v
            try:
                nbclient.NotebookClient(nb, timeout=CELL_TIMEOUT_S, kernel_name="python3",
                                        store_widget_state=True,
                                        resources={"metadata": {"path": str(NOTEBOOK_DIR)}}
                                        ).execute()
            finally:
                for k, v in old.items():
                    if v is None:
                        os.environ.pop(k, None)
                    else:
                        os.environ[k] = v
            done[path] = nb
        return copy.deepcopy(done[path])

    return run
