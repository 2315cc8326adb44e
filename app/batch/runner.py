"""``run(inputs, recipe, out)``: one recipe over many studies, resumable, on this machine or Dask."""
from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Callable, Dict, List, Optional, Sequence, Union

from ...core.model.errors import AnatomeshError
from ...core.model.progress import Progress
from ..flow import outputs
from ..flow.recipe import BLENDER_FORMATS, Recipe, check_recipe, dump_recipe, load_recipe
from . import state
from .memory import estimate_bytes, pool_size
from .progress import BatchProgress
from .studies import Study, find_studies
from .summary import study_rows, write_summary
from .worker import StudyTask

GB = 2**30


def run(inputs: Union[str, Path, Sequence], recipe: Union[Recipe, str, Path, None] = None,
        out: Union[str, Path] = "batch", *, scheduler=None, workers: Optional[int] = None,
        memory_gb: Optional[float] = None, retry_failed: bool = False,
        progress: Optional[Progress] = None, study_func: Optional[Callable] = None) -> List[Dict]:
    """Run ``recipe`` over every study of ``inputs`` into ``out/<id>/``; returns the summary
    rows (a list of dicts, columns of :data:`~anatomesh.app.batch.summary.COLUMNS`; one per
    study and surface), also written to ``out/summary.csv`` (+ ``.parquet``) and ``summary.html``.

    Parameters
    ----------
    inputs : folder of studies, ``.csv``/``.tsv`` manifest, glob, list of paths or of :class:`Study`
        See :mod:`anatomesh.app.batch.studies`.
    recipe : Recipe, path of a TOML recipe, or None (the defaults)
        Its input and output folder are replaced per study; a manifest's labels replace its labels.
    out : folder
        Finished studies there are skipped when their input and the recipe are unchanged.
    scheduler : None, ``"tcp://host:8786"``, a ``distributed.Client`` or a cluster object
        None runs a process pool here; otherwise Dask distributed (:mod:`.cluster`).
    workers, memory_gb : pool size and memory budget (default: the cores, 80 % of the free memory)
    retry_failed : run studies that failed before with the same recipe and input again
    progress : ``progress(fraction, text)``: studies done/failed/left, ETA and current stages
    study_func : the function a pool worker runs per study (tests; default ``run_study``)

    Raises :class:`AnatomeshError` for a bad recipe, no studies, or another batch on ``out``;
    a failing study never raises: it is a "failed" row with its one-line reason.
    """
    recipe = batch_recipe(recipe)
    studies = list(inputs) if _all_studies(inputs) else find_studies(inputs)
    out = Path(out).expanduser().resolve()
    studies = [s for s in studies if not Path(s.path).resolve().is_relative_to(out)]  # OUT inside INPUTS
    out.mkdir(parents=True, exist_ok=True)
    with state.Lock(out):
        state.clear_partials(out)
        settled, tasks = _triage(studies, recipe, out, retry_failed, estimate=scheduler is None)
        _write_text(out / "recipe.toml", dump_recipe(dataclasses.replace(recipe, input="", out_dir=str(out)), base=out))
        bar = BatchProgress(len(studies), sum(1 for r in settled.values() if r[0]["status"] != "failed"),
                            sum(1 for r in settled.values() if r[0]["status"] == "failed"), progress)
        if scheduler is not None:
            from .cluster import run_dask
            engine = run_dask(tasks, scheduler, bar.stage)
        else:
            from .pool import run_pool
            budget = int(memory_gb * GB) if memory_gb else None
            n, budget = pool_size([t.memory for t in tasks], workers, budget)
            engine = run_pool(tasks, n, budget, bar.stage, **({"func": study_func} if study_func else {}))
        by_id = {t.id: t for t in tasks}
        try:
            for outcome in engine:
                settled[outcome["id"]] = _settle(outcome, out, by_id[outcome["id"]])
                bar.finished(outcome["id"], outcome["status"] == "done")
        finally:
            engine.close()  # stops the workers (or cancels the Dask tasks) now, also when interrupted
            rows = [r for s in studies for r in settled.get(s.id) or study_rows(s.id, "pending", s.path, None)]
            write_summary(out, rows)
    return rows


def batch_recipe(recipe: Union[Recipe, str, Path, None]) -> Recipe:
    """The batch's recipe, checked once (its input and output folder are set per study)."""
    if recipe is None:
        recipe = Recipe()
    elif not isinstance(recipe, Recipe):
        recipe = load_recipe(recipe)
    recipe = dataclasses.replace(recipe, report=None, overwrite=False)
    check_recipe(dataclasses.replace(recipe, input="(each study)"))
    if any(f in BLENDER_FORMATS for f in recipe.formats):
        outputs.blender_writer()  # no Blender: one error now rather than one per study
    return recipe


def recipe_sha(recipe: Recipe, labels) -> str:
    """The hash of what a study's outputs depend on besides its input: the recipe's settings
    (not its input or output folder) with the study's labels."""
    if labels is not None:
        recipe = dataclasses.replace(recipe, labels=labels if isinstance(labels, str) else list(labels))
    return state.text_sha256(dump_recipe(dataclasses.replace(recipe, input="", out_dir="")))


def _triage(studies: List[Study], recipe: Recipe, out: Path, retry_failed: bool, estimate: bool):
    """Rows of the studies settled already (done and unchanged, failed before), tasks of the rest."""
    settled: Dict[str, List[Dict]] = {}
    tasks: List[StudyTask] = []
    for s in studies:
        sha = recipe_sha(recipe, s.labels)
        report = state.completed(out, s.id, s.path, sha)
        if report is not None:
            settled[s.id] = study_rows(s.id, "skipped", s.path, report)
            continue
        failure = None if retry_failed else state.earlier_failure(out, s.id, s.path, sha)
        if failure is not None:
            settled[s.id] = study_rows(s.id, "failed", s.path, None, failure["error"], failure.get("seconds"))
            continue
        tasks.append(StudyTask(s.id, s.path, s.labels, recipe, sha, str(out),
                               estimate_bytes(s.path) if estimate else 0))
    return settled, tasks


def _settle(outcome: Dict, out: Path, task: StudyTask) -> List[Dict]:
    """Record a finished study (forget or write its failure) and return its summary rows."""
    if outcome["status"] == "done":
        state.forget_failure(out, task.id)
        return study_rows(task.id, "done", task.path, outcome["report"])
    inputs = outcome.get("inputs") or state.fingerprint(task.path, hashes=False)
    state.record_failure(out, task.id, {"id": task.id, "input": task.path, "error": outcome["error"],
                                        "seconds": outcome["seconds"], "inputs": inputs,
                                        "recipe_sha256": task.recipe_sha256})
    return study_rows(task.id, "failed", task.path, None, outcome["error"], outcome["seconds"])


def _all_studies(inputs) -> bool:
    return isinstance(inputs, (list, tuple)) and bool(inputs) and all(isinstance(s, Study) for s in inputs)


def _write_text(path: Path, text: str) -> None:
    try:
        path.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise AnatomeshError(f"cannot write into the output folder ({exc.strerror}); choose another --out",
                             path.parent) from None
