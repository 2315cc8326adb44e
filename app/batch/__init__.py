"""Cohorts: one recipe over hundreds of studies, resumable, on this machine or a Dask cluster.

``anatomesh batch INPUTS --recipe R.toml --out DIR`` and :func:`run` (``anatomesh.app.batch.run``)
run every study (:mod:`.studies`) through :func:`anatomesh.app.flow.run.run` into ``DIR/<id>/`` with its
own report (:mod:`.worker`), in a process pool sized by cores and memory (:mod:`.pool`,
:mod:`.memory`) or on Dask distributed (:mod:`.cluster`). Finished studies whose input and recipe
are unchanged are skipped, failures are recorded and do not stop the others, study folders appear
only complete (:mod:`.state`); ``DIR/summary.csv``/``.parquet``/``.html`` sum it up (:mod:`.summary`).
"""
from .runner import run
from .studies import Study, find_studies
from .summary import COLUMNS

__all__ = ["run", "Study", "find_studies", "COLUMNS"]
