"""The cluster engine: the same studies as tasks of a Dask distributed cluster (Rocklin 2015,
"Dask: Parallel computation with blocked algorithms and task scheduling").

``scheduler`` is a scheduler address (``tcp://host:8786``), a ``distributed.Client``, or a
cluster object the user already has (``dask_jobqueue.SLURMCluster``, ``dask_kubernetes``'
``KubeCluster``, ``distributed.LocalCluster`` — anything with a ``scheduler_address``). Dask
places the studies, watches the workers' memory (a worker over its ``--memory-limit`` is
restarted by its nanny) and reschedules the study of a lost worker; a study whose workers died
too often (``KilledWorker``) fails alone. Workers need Anatomesh installed and must see the
inputs and the output folder under the same paths (a shared file system). Start them with one
thread each (``dask worker tcp://host:8786 --nworkers N --nthreads 1 --memory-limit 4GB``):
a study is one process's work (numba's threads are set to one per task unless
``NUMBA_NUM_THREADS`` is set). Stages come back as Dask events (topic ``anatomesh-batch``).
"""
from __future__ import annotations

import os
import time
import uuid
from typing import Callable, Dict, Iterator, List, Optional

from ...core.model.errors import AnatomeshError
from .pool import STAGE_INTERVAL
from .worker import StudyTask, one_line, run_study

TOPIC = "anatomesh-batch"


def run_dask(tasks: List[StudyTask], scheduler,
             on_stage: Optional[Callable[[str, float, str], None]] = None) -> Iterator[Dict]:
    """Run ``tasks`` on the Dask cluster ``scheduler``; yields each study's outcome as it
    finishes (see :func:`~anatomesh.app.batch.worker.run_study`)."""
    try:
        from distributed import as_completed
    except ImportError:
        raise AnatomeshError("--scheduler needs Dask distributed: pip install 'anatomesh[batch]' "
                             "(or dask[distributed])") from None
    client, owned = _client(scheduler)
    if on_stage is not None:
        client.subscribe_topic(TOPIC, lambda event: on_stage(*event[1]))
    run_id = uuid.uuid4().hex[:8]
    futures = {client.submit(dask_study, t, key=f"anatomesh-{t.id}-{run_id}", pure=False): t
               for t in tasks}
    try:
        for future in as_completed(futures):
            yield _outcome(future, futures[future])
            future.release()
    finally:
        for future in futures:
            future.cancel()
        if on_stage is not None:
            client.unsubscribe_topic(TOPIC)
        if owned:
            client.close()


def dask_study(task: StudyTask) -> Dict:
    """:func:`run_study` on a Dask worker, its stages sent as events to the client."""
    from distributed import get_worker

    worker, last = get_worker(), [0.0, ""]
    if "NUMBA_NUM_THREADS" not in os.environ:  # one core per worker process, as Dask advises
        import numba

        numba.set_num_threads(1)

    def progress(fraction: float, text: str = "") -> None:
        now = time.monotonic()
        if text != last[1] or now - last[0] >= STAGE_INTERVAL:
            last[0], last[1] = now, text
            worker.log_event(TOPIC, (task.id, fraction, text))

    return run_study(task, progress)


def _outcome(future, task: StudyTask) -> Dict:
    from distributed import KilledWorker

    try:
        return future.result()
    except KilledWorker:
        error = ("the Dask workers running this study died (KilledWorker: out of memory or a "
                 "crash, see the workers' logs); the others went on")
    except Exception as exc:  # noqa: BLE001 - a lost task fails its study alone
        error = f"Dask could not run this study: {one_line(exc)}"
    return {"id": task.id, "status": "failed", "seconds": 0.0, "report": None, "error": error}


def _client(scheduler):
    """``(client, owned)`` for an address, a client or a cluster object."""
    from distributed import Client

    if isinstance(scheduler, Client):
        return scheduler, False
    target = scheduler if isinstance(scheduler, str) or hasattr(scheduler, "scheduler_address") else None
    if target is None:
        raise AnatomeshError(f"--scheduler must be an address (tcp://host:8786), a dask Client or a "
                             f"cluster object, got {type(scheduler).__name__}")
    try:
        return Client(target, timeout="20s"), True
    except (OSError, TimeoutError) as exc:
        raise AnatomeshError(f"cannot reach the Dask scheduler ({one_line(exc)}); is it running?",
                             scheduler if isinstance(scheduler, str) else None) from None
