"""The embedded engine: studies on this machine, in a pool of worker processes sized by cores and
memory.

Each worker is a long-lived process that runs one study at a time and reports its stages back
over a pipe. Workers are forked from a clean server process that has imported the pipeline once
(``forkserver``, where the system has it; else ``spawn``): nothing of the caller's state (threads,
open files) is shared, and a worker that replaces a dead one starts in milliseconds. A study starts only when its
estimated peak memory fits in what the running ones leave of the budget (one that fits nowhere
runs alone). A worker that dies while running a study — the kernel's out-of-memory killer, a
crash in native code — fails that study alone ("worker process died ..."); a fresh worker takes
its place and the other studies go on. Workers die with the process that started them (Linux:
``PR_SET_PDEATHSIG`` on their parent, which ends with the batch; elsewhere they notice within a
second), so a killed batch leaves nothing running.
"""
from __future__ import annotations

import collections
import itertools
import multiprocessing
import os
import signal
import threading
import time
from multiprocessing.connection import wait
from typing import Callable, Deque, Dict, Iterator, List, Optional

from ...core.model.memory import return_large_blocks
from .worker import StudyTask, run_study

#: how often (seconds) a worker sends a study's progress at most
STAGE_INTERVAL = 0.25
#: how far down the queue the pool looks for a study that fits in the free memory
LOOKAHEAD = 64


class _Slot:
    """One worker process, its pipe, and the study it runs (None when idle)."""

    def __init__(self, ctx, func: Callable, threads: int):
        self.conn, child = ctx.Pipe()
        self.process = ctx.Process(target=worker_main, args=(child, func, threads), daemon=True)
        self.process.start()
        child.close()
        self.task: Optional[StudyTask] = None

    def stop(self) -> None:
        """End the worker: an idle one by closing its pipe (it exits cleanly), a busy one (the
        batch was interrupted) by SIGTERM, then SIGKILL."""
        if self.task is None:
            self.conn.close()
            self.process.join(5)
        if self.process.is_alive():
            self.process.terminate()
            self.process.join(2)
        if self.process.is_alive():
            self.process.kill()
            self.process.join(2)
        if not self.conn.closed:
            self.conn.close()


def run_pool(tasks: List[StudyTask], workers: int, budget: int,
             on_stage: Optional[Callable[[str, float, str], None]] = None,
             func: Callable = run_study) -> Iterator[Dict]:
    """Run ``tasks`` on ``workers`` processes within ``budget`` bytes; yields each study's
    outcome (see :func:`~anatomesh.app.batch.worker.run_study`) as it finishes. ``func`` is
    the study function (importable at module level; tests pass one that crashes)."""
    ctx = worker_context()
    threads = max(1, (os.cpu_count() or 1) // max(1, workers))
    queue: Deque[StudyTask] = collections.deque(tasks)
    slots: List[_Slot] = []
    try:
        while queue or any(s.task for s in slots):
            _admit(queue, slots, workers, budget, lambda: _Slot(ctx, func, threads))
            busy = [s for s in slots if s.task is not None]
            ready = wait([s.conn for s in busy] + [s.process.sentinel for s in busy], timeout=1.0)
            for slot in busy:
                outcome = _collect(slot, ready, on_stage)
                if outcome is not None:
                    if not slot.process.is_alive():
                        slot.stop()
                        slots.remove(slot)
                    yield outcome
    finally:
        for slot in slots:
            slot.stop()


def worker_context():
    """The multiprocessing context of the workers: a fork server that preloads the pipeline, or
    ``spawn`` where there is none (Windows)."""
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload([__name__])
    return ctx


def _admit(queue: Deque[StudyTask], slots: List[_Slot], workers: int, budget: int, new_slot) -> None:
    """Hand queued studies to idle workers (starting workers up to ``workers``) while they fit."""
    while queue:
        used = sum(s.task.memory for s in slots if s.task is not None)
        running = sum(1 for s in slots if s.task is not None)
        if running >= workers:
            return
        pick = next((i for i, t in enumerate(itertools.islice(queue, LOOKAHEAD)) if used + t.memory <= budget), None)
        if pick is None and running == 0:
            pick = 0  # too large for the budget: it runs alone
        if pick is None:
            return
        task = queue[pick]
        del queue[pick]
        slot = next((s for s in slots if s.task is None), None)
        if slot is None:
            slot = new_slot()
            slots.append(slot)
        slot.task = task
        slot.conn.send(task)


def _collect(slot: _Slot, ready, on_stage) -> Optional[Dict]:
    """Read what ``slot`` sent: stage messages go to ``on_stage``; returns the study's outcome
    when it finished or its worker died, else None."""
    task = slot.task
    if slot.conn in ready:
        try:
            while slot.conn.poll():
                kind, payload = slot.conn.recv()
                if kind == "stage":
                    if on_stage is not None:
                        on_stage(task.id, payload[0], payload[1])
                else:
                    slot.task = None
                    return payload
        except (EOFError, OSError):
            pass
    if not slot.process.is_alive():
        slot.process.join(1)
        slot.task = None
        return died(task, slot.process.exitcode)
    return None


def died(task: StudyTask, exitcode: Optional[int]) -> Dict:
    """The outcome of a study whose worker process died while running it."""
    why = f"exit code {exitcode}"
    if exitcode is not None and exitcode < 0:
        try:
            name = signal.Signals(-exitcode).name
        except ValueError:
            name = f"signal {-exitcode}"
        why = f"killed by {name}" + (" (out of memory?)" if -exitcode == signal.SIGKILL else "")
    return {"id": task.id, "status": "failed", "seconds": 0.0, "report": None,
            "error": f"the worker process died while running this study ({why}); the others went on"}


def worker_main(conn, func: Callable, threads: int) -> None:
    """A worker process: run the studies sent over ``conn`` until it closes."""
    _die_with_parent()
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle
    return_large_blocks()  # memory: freed arrays go back to the system at once
    try:
        import numba

        numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    except ImportError:  # pragma: no cover - numba is a dependency
        pass
    while True:
        try:
            task = conn.recv()
        except (EOFError, OSError):
            return
        conn.send(("done", func(task, _stage_sender(conn))))


def _stage_sender(conn) -> Callable[[float, str], None]:
    last = [0.0, ""]

    def progress(fraction: float, text: str = "") -> None:
        now = time.monotonic()
        if text != last[1] or now - last[0] >= STAGE_INTERVAL:
            last[0], last[1] = now, text
            conn.send(("stage", (fraction, text)))

    return progress


def _die_with_parent() -> None:
    """Make this worker end when its parent ends (the batch process, or the fork server, which
    ends with it), even by SIGKILL."""
    parent = os.getppid()
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        if libc.prctl(1, signal.SIGKILL, 0, 0, 0) == 0:  # PR_SET_PDEATHSIG
            if os.getppid() != parent:  # the parent died before prctl
                os._exit(1)
            return
    except (OSError, AttributeError):
        pass

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(1.0)
        os._exit(1)

    threading.Thread(target=watch, daemon=True).start()
