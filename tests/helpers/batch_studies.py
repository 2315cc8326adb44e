"""Study functions for batch tests, importable by the pool's worker processes (``spawn``)."""
import json
import os
import signal
import time
from pathlib import Path

from anatomesh.app.batch.worker import run_study

#: the study whose worker :func:`crash_on_brain` kills
CRASHING_STUDY = "brain"


def crash_on_brain(task, progress=None):
    """Run the study, except that the worker process dies by SIGKILL (as the kernel's
    out-of-memory killer would kill it) on :data:`CRASHING_STUDY`."""
    if task.id == CRASHING_STUDY:
        os.kill(os.getpid(), signal.SIGKILL)
    return run_study(task, progress)


def record_span(task, progress=None):
    """Run the study and record when it ran (``OUT/spans/<id>.json``: start, end, pid)."""
    start = time.time()
    outcome = run_study(task, progress)
    spans = Path(task.out, "spans")
    spans.mkdir(exist_ok=True)
    (spans / f"{task.id}.json").write_text(json.dumps({"start": start, "end": time.time(), "pid": os.getpid()}))
    return outcome
