"""One submission's kernel: run in a scratch folder, cell by cell, within a time limit per cell
and a budget per notebook, asked for outputs as data, and killed with its whole process group.

:class:`NotebookRun` starts a fresh ``python3`` kernel whose working folder is a new scratch
folder (a copy of nothing: the submission is read by the grader, never by the kernel), runs the
graded notebook's cells one at a time (:meth:`NotebookRun.execute`), and turns every way a
kernel can fail into :class:`KernelFailure`: a cell past its limit (``timeout``) or past the
notebook's budget, a kernel that died (``os._exit`` in an answer: nbclient's poll sees it within
about a second), or an error of the client itself. :meth:`NotebookRun.call` asks the kernel
to call one of the notebook's functions on the grader's inputs and returns its output as data
(:mod:`sunlab.course.wire`): the hidden checks (:mod:`sunlab.course.hidden`) see the run in
place of the notebook's globals when the grader runs them in its own process. Leaving the
``with`` block shuts the kernel down and then kills its process group (``SIGKILL``), so that
no process of the student's is left when the marks are written.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import tempfile
import time
from pathlib import Path

from . import wire
from .editions import _jupyter

__all__: list[str] = []


#: seconds without a word from the kernel about a sent cell before it is nudged
NUDGE_S = 3.0
#: seconds without a word, nudges included, before the kernel is said to have stopped reading
STALL_S = 30.0


def _client_class():
    """nbclient's NotebookClient, watching for a request the kernel never reads.

    ipykernel 7 can leave a request unread in its shell socket (a reply sent raw on the socket
    consumes the wake-up of a request that arrives meanwhile: ipython/ipykernel#1554, the hang
    of microsoft/vscode-jupyter#17228): the kernel sits idle and the client waits for the
    cell's whole time limit. Each second, with the kernel's liveness, this client checks that
    the kernel has said something about the cell (its ``busy`` status comes first); after
    :data:`NUDGE_S` s of silence it sends a ``kernel_info`` request, a new message on the
    socket that wakes the kernel's reading, every :data:`NUDGE_S` s; after :data:`STALL_S` s it
    gives up on the cell (``stalled``) instead of waiting for the time limit.
    """
    import asyncio

    nbclient = _jupyter("nbclient")

    class Client(nbclient.NotebookClient):
        stalled = False
        _sent = 0.0
        _heard = True

        async def async_execute_cell(self, cell, cell_index, execution_count=None,
                                     store_history=True):
            self._sent, self._heard, self.stalled = time.monotonic(), False, False
            try:
                return await super().async_execute_cell(cell, cell_index, execution_count,
                                                        store_history)
            finally:
                self._heard = True

        execute_cell = nbclient.util.run_sync(async_execute_cell)

        def process_message(self, msg, cell, cell_index):
            self._heard = True
            return super().process_message(msg, cell, cell_index)

        async def _async_poll_kernel_alive(self):
            nudged = self._sent
            while True:
                await asyncio.sleep(1)
                try:
                    await self._async_check_alive()
                except nbclient.exceptions.DeadKernelError:
                    self.task_poll_for_reply.cancel()
                    return
                now = time.monotonic()
                if self._heard:
                    continue
                if now - self._sent > STALL_S:
                    self.stalled = True
                    self.task_poll_for_reply.cancel()
                    return
                if now - nudged > NUDGE_S:
                    nudged = now
                    self.kc.kernel_info()

    return Client


class KernelFailure(Exception):
    """The kernel stopped answering: ``kind`` is ``time-out``, ``dead kernel`` or ``crash``."""

    def __init__(self, kind: str, message: str):
        super().__init__(message)
        self.kind, self.message = kind, message


class NotebookRun:
    """A fresh kernel for one graded notebook (see the module's text).

    Parameters
    ----------
    nb : nbformat.NotebookNode
        The notebook to run (its cells receive their outputs).
    env : dict
        The kernel's environment.
    timeout : float
        Limit per cell, s.
    budget : float
        Limit for the whole notebook (every cell and every request of the grader), s.
    """

    def __init__(self, nb, *, env: dict, timeout: float, budget: float):
        self.nb, self.env, self.timeout, self.budget = nb, env, float(timeout), float(budget)
        self.scratch: Path | None = None
        #: the first call of each function with forbidden library functions, for the check in
        #: a fresh process (:mod:`sunlab.course.probe`); the hidden checks append to it
        self.calls: list[dict] = []
        self._pgid: int | None = None

    def __enter__(self):
        self.scratch = Path(tempfile.mkdtemp(prefix="sunlab-kernel-"))
        self.client = _client_class()(
            self.nb, timeout=self.timeout, kernel_name="python3", allow_errors=True,
            resources={"metadata": {"path": str(self.scratch)}})
        self._deadline = time.monotonic() + self.budget
        self._ctx = self.client.setup_kernel(  # the kernel's own chatter stays out of the report
            env={**self.env, "HOME": str(self.scratch)}, stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL)
        try:
            self._ctx.__enter__()
        except Exception as err:
            self._kill()
            raise KernelFailure("crash", f"the kernel did not start ({type(err).__name__}: "
                                f"{err})") from None
        self._pgid = getattr(getattr(self.client.km, "provisioner", None), "pgid", None)
        return self

    def __exit__(self, *exc):
        with contextlib.suppress(Exception):
            self._ctx.__exit__(None, None, None)
        self._kill()
        return False

    def _kill(self):
        if self._pgid:
            with contextlib.suppress(OSError):
                os.killpg(self._pgid, signal.SIGKILL)
        if self.scratch is not None:
            shutil.rmtree(self.scratch, ignore_errors=True)

    def execute(self, cell, index: int) -> None:
        """Run one cell; raise :class:`KernelFailure` when the kernel stops answering."""
        nbclient = _jupyter("nbclient")
        left = self._deadline - time.monotonic()
        if left <= 0:
            raise KernelFailure("time-out", f"the notebook ran past its budget of "
                                f"{self.budget:g} s")
        limit = min(self.timeout, left)
        self.client.timeout = max(1, int(round(limit)))
        try:
            self.client.execute_cell(cell, index)
        except nbclient.exceptions.CellTimeoutError:
            what = (f"its budget of {self.budget:g} s" if limit < self.timeout
                    else f"the limit of {self.timeout:g} s per cell")
            raise KernelFailure("time-out", f"a cell ran past {what}") from None
        except nbclient.exceptions.DeadKernelError:
            if getattr(self.client, "stalled", False):
                raise KernelFailure("crash", (
                    f"the kernel stopped reading requests (nothing for {STALL_S:g} s after "
                    "the cell was sent, nudges included: the lost-request fault of ipykernel 7, "
                    "ipython/ipykernel#1554); not the student's fault: grade this notebook "
                    "again")) from None
            raise KernelFailure("dead kernel", "the kernel died (an answer ended its process)"
                                ) from None
        except Exception as err:
            raise KernelFailure("crash", f"the kernel stopped answering ({type(err).__name__}: "
                                f"{' '.join(str(err).split())[:200]})") from None

    def call(self, name: str, args=(), kwargs=None, bind=None):
        """Call the notebook's function ``name`` in the kernel, the names ``bind`` of the
        notebook rebound for the call (:func:`sunlab.course.wire.answer`); return its output
        as data. A hidden check (:mod:`sunlab.course.hidden`) calls this in place of the
        notebook's globals, and keeps in :attr:`calls` the calls to check in a fresh process.

        Parameters
        ----------
        name : str
            The notebook's function.
        args, kwargs, bind : tuple, dict, dict
            Its arguments, and the notebook's names rebound for the call.

        Returns
        -------
        object
            The decoded output (:func:`sunlab.course.wire.reply`).

        Raises
        ------
        AssertionError
            The function is not defined, raised (its type and message) or gave no data.
        KernelFailure
            The kernel stopped answering.
        """
        cell = _jupyter("nbformat").v4.new_code_cell(wire.request(name, args, kwargs, bind))
        self.nb.cells.append(cell)  # nbclient stores the cell at its index: a slot of its own
        try:
            self.execute(cell, len(self.nb.cells) - 1)
        finally:
            self.nb.cells.pop()
        texts = [o["data"][wire.MIME] for o in cell.get("outputs", [])
                 if o.get("output_type") == "display_data" and wire.MIME in o.get("data", {})]
        if not texts:
            err = next((o for o in cell.outputs if o.get("output_type") == "error"), None)
            why = f"{err['ename']}: {err['evalue']}" if err else "no output"
            raise AssertionError(f"your `{name}` gave no answer ({why})")
        return wire.reply(texts[-1], name)
