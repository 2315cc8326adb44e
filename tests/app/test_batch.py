"""anatomesh batch / app.batch.run on real label maps copied as studies (plus a broken one):
results equal single `anatomesh mesh` runs, failures reported alone, re-runs skip finished
studies, a killed run resumes, a crashed worker fails only its study, the memory budget is kept,
and Dask distributed (a real LocalCluster, 2 worker processes) gives identical results."""
import csv
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import distributed
import psutil
import pyarrow.parquet as pq
import pytest

from anatomesh.app import batch
from anatomesh.app.batch import state
from anatomesh.app.batch.pool import run_pool
from anatomesh.app.batch.runner import batch_recipe, recipe_sha
from anatomesh.app.batch.worker import StudyTask
from anatomesh.app.cli import main
from conftest import shared
from helpers.batch_studies import CRASHING_STUDY, crash_on_brain, record_span

SEG = ("totalsegmentator", "example_seg.nii.gz")            # 41 labels, 122x101x30
SEG_MR = ("totalsegmentator", "example_seg_mr.nii.gz")      # 23 labels, LPS
BRAIN = ("pyradiomics_brain1", "brain1_label.nrrd")          # 1 label, 6.5 mm slices
FAST = '[smoothing]\nmethod = "none"\n\n[output]\nformats = ["stl"]\n'
GOOD = ("brain", "ct1", "ct2", "mr")


@pytest.fixture(scope="module")
def cohort(tmp_path_factory):
    """A folder of studies: two copies of the CT map (named by the TotalSegmentator label table
    beside them), a TotalSegmentator dataset folder (ct.nii.gz + segmentations.nii.gz), the
    brain tumour NRRD, a truncated NIfTI, and a text file that is no study; plus a fast recipe."""
    root = tmp_path_factory.mktemp("cohort")
    studies = root / "studies"
    (studies / "mr").mkdir(parents=True)
    shutil.copy(shared(*SEG), studies / "ct1.nii.gz")
    shutil.copy(shared(*SEG), studies / "ct2.nii.gz")
    shutil.copy(shared("totalsegmentator", "label_names_total_and_total_mr.json"), studies)
    shutil.copy(shared(*SEG_MR), studies / "mr" / "segmentations.nii.gz")
    shutil.copy(shared("totalsegmentator", "example_mr_sm.nii.gz"), studies / "mr" / "ct.nii.gz")
    shutil.copy(shared(*BRAIN), studies / "brain.nrrd")
    (studies / "broken.nii.gz").write_bytes(shared(*SEG).read_bytes()[:3000])
    (studies / "notes.txt").write_text("not a study")
    (root / "fast.toml").write_text(FAST)
    return root


@pytest.fixture(scope="module")
def pooled(cohort):
    """The cohort through the process pool (2 workers)."""
    out = cohort / "out_pool"
    return out, batch.run(cohort / "studies", cohort / "fast.toml", out, workers=2)


def _first(rows):
    return {r["study"]: r for r in reversed(rows)}


def _input_of(cohort, study):
    s = cohort / "studies"
    return {"ct1": s / "ct1.nii.gz", "ct2": s / "ct2.nii.gz", "brain": s / "brain.nrrd",
            "mr": s / "mr" / "segmentations.nii.gz"}[study]


def test_batch_equals_single_mesh_runs(cohort, pooled, tmp_path, capsys):
    out, rows = pooled
    first = _first(rows)
    assert sorted(first) == sorted(GOOD + ("broken",))  # notes.txt and the label table are no studies
    assert all(first[s]["status"] == "done" for s in GOOD)
    for study in GOOD:
        single = tmp_path / study
        assert main(["mesh", str(_input_of(cohort, study)), "--recipe", str(cohort / "fast.toml"),
                     "--out", str(single)]) == 0
        mine = json.loads((out / study / "report.json").read_text())
        theirs = json.loads((single / "report.json").read_text())
        assert mine["surfaces"] == theirs["surfaces"] and len(mine["surfaces"]) > 0
        for s in theirs["surfaces"]:
            assert (out / study / s["files"]["stl"]).read_bytes() == (single / s["files"]["stl"]).read_bytes()
        assert mine["batch"]["study"] == study and mine["batch"]["recipe_sha256"]
        assert [e["sha256"] for e in mine["batch"]["inputs"]] == [state.file_sha256(_input_of(cohort, study))]
        summary = [r for r in rows if r["study"] == study]
        assert [(r["surface"], r["faces"], r["volume_mm3"], r["closed"]) for r in summary] == \
               [(s["name"], s["faces"], s["volume_mm3"], s["closed"]) for s in theirs["surfaces"]]
    assert first["ct1"]["surface"] in {"spleen", "liver", "kidney_right"}  # named by the label table
    assert len([r for r in rows if r["study"] == "ct1"]) == 41
    assert len([r for r in rows if r["study"] == "mr"]) == 23  # the segmentations, not the MR scan


def test_broken_study_is_reported_alone(pooled):
    out, rows = pooled
    broken = [r for r in rows if r["study"] == "broken"]
    assert len(broken) == 1 and broken[0]["status"] == "failed" and broken[0]["surface"] is None
    assert "broken.nii.gz" in broken[0]["error"] and "truncated" in broken[0]["error"]
    assert "\n" not in broken[0]["error"]
    assert not (out / "broken").exists()
    record = json.loads((out / ".batch" / "failed" / "broken.json").read_text())
    assert record["error"] == broken[0]["error"]
    assert list((out / ".batch" / "partial").iterdir()) == []


def test_summary_csv_parquet_and_html(pooled):
    out, rows = pooled
    with open(out / "summary.csv", newline="") as fh:
        table = list(csv.DictReader(fh))
    assert [r["study"] for r in table] == [r["study"] for r in rows]
    assert [int(r["faces"]) for r in table if r["faces"]] == [r["faces"] for r in rows if r["faces"] is not None]
    assert list(table[0]) == [name for name, _ in batch.COLUMNS]
    parquet = pq.read_table(out / "summary.parquet").to_pylist()
    assert [(r["study"], r["surface"], r["faces"], r["closed"]) for r in parquet] == \
           [(r["study"], r["surface"], r["faces"], r["closed"]) for r in rows]
    page = (out / "summary.html").read_text()
    for study in GOOD:
        assert f'src="{study}/thumbnail.png"' in page
        png = (out / study / "thumbnail.png").read_bytes()
        assert png[:8] == b"\x89PNG\r\n\x1a\n" and png[16:24] == (256).to_bytes(4, "big") * 2
    assert "broken" in page and "truncated or corrupt" in page


def test_rerun_skips_done_and_remembers_failures(cohort, pooled):
    out, _ = pooled
    before = {s: (out / s / "report.json").stat().st_mtime_ns for s in GOOD}
    os.utime(cohort / "studies" / "ct1.nii.gz")  # touched, same content: still unchanged
    rows = batch.run(cohort / "studies", cohort / "fast.toml", out, workers=2)
    first = _first(rows)
    assert {s: first[s]["status"] for s in GOOD} == {s: "skipped" for s in GOOD}
    assert first["broken"]["status"] == "failed" and "truncated" in first["broken"]["error"]
    assert {s: (out / s / "report.json").stat().st_mtime_ns for s in GOOD} == before


def test_changed_recipe_or_input_runs_again(cohort, tmp_path):
    studies = tmp_path / "studies"
    studies.mkdir()
    shutil.copy(shared(*BRAIN), studies / "brain.nrrd")
    shutil.copy(shared(*SEG_MR), studies / "mr.nii.gz")
    recipe = tmp_path / "r.toml"
    recipe.write_text(FAST)
    out = tmp_path / "out"
    batch.run(studies, recipe, out, workers=1)
    shutil.copy(shared(*SEG), studies / "mr.nii.gz")  # new content under the old name
    first = _first(batch.run(studies, recipe, out, workers=1))
    assert (first["brain"]["status"], first["mr"]["status"]) == ("skipped", "done")
    assert len(json.loads((out / "mr" / "report.json").read_text())["surfaces"]) == 41
    recipe.write_text(FAST.replace('["stl"]', '["stl", "ply"]'))
    first = _first(batch.run(studies, recipe, out, workers=1))
    assert (first["brain"]["status"], first["mr"]["status"]) == ("done", "done")
    assert (out / "brain" / "brain.ply").is_file()


def test_crashed_worker_fails_its_study_only_and_retry_failed(cohort, tmp_path):
    out = tmp_path / "out"
    first = _first(batch.run(cohort / "studies", cohort / "fast.toml", out, workers=2,
                             study_func=crash_on_brain))
    assert first[CRASHING_STUDY]["status"] == "failed"
    assert "worker process died" in first[CRASHING_STUDY]["error"] and "SIGKILL" in first[CRASHING_STUDY]["error"]
    assert all(first[s]["status"] == "done" for s in GOOD if s != CRASHING_STUDY)
    first = _first(batch.run(cohort / "studies", cohort / "fast.toml", out, workers=2))
    assert first[CRASHING_STUDY]["status"] == "failed"  # remembered, not retried
    first = _first(batch.run(cohort / "studies", cohort / "fast.toml", out, workers=2, retry_failed=True))
    assert first[CRASHING_STUDY]["status"] == "done" and first["broken"]["status"] == "failed"
    assert not (out / ".batch" / "failed" / f"{CRASHING_STUDY}.json").exists()


def test_pool_never_starts_more_than_fit_in_memory(tmp_path):
    """Two workers, but each study's estimate takes most of the budget: they run one by one."""
    studies = tmp_path / "studies"
    studies.mkdir()
    for i in range(3):
        shutil.copy(shared(*BRAIN), studies / f"b{i}.nrrd")
    out = tmp_path / "out"
    (tmp_path / "r.toml").write_text(FAST)
    recipe = batch_recipe(tmp_path / "r.toml")
    tasks = [StudyTask(f"b{i}", str(studies / f"b{i}.nrrd"), None, recipe, recipe_sha(recipe, None),
                       str(out), memory=600 * 2**20) for i in range(3)]
    outcomes = list(run_pool(tasks, workers=2, budget=1000 * 2**20, func=record_span))
    assert sorted(o["status"] for o in outcomes) == ["done"] * 3
    spans = sorted((json.loads(p.read_text()) for p in (out / "spans").iterdir()), key=lambda s: s["start"])
    assert all(a["end"] <= b["start"] for a, b in zip(spans, spans[1:]))


def test_manifest_with_labels(tmp_path):
    (tmp_path / "scans").mkdir()
    shutil.copy(shared(*SEG), tmp_path / "scans" / "a.nii.gz")
    shutil.copy(shared("totalsegmentator", "label_names_total_and_total_mr.json"), tmp_path / "scans")
    (tmp_path / "m.tsv").write_text("id\tpath\tlabels\n# a comment\npatient 7\tscans/a.nii.gz\tliver;spleen\n"
                                    "whole\tscans/a.nii.gz\t\n")
    (tmp_path / "r.toml").write_text(FAST.replace("[output]", '[input]\nlabels = ["kidney_left"]\n\n[output]'))
    rows = batch.run(tmp_path / "m.tsv", tmp_path / "r.toml", tmp_path / "out", workers=1)
    names = {}
    for r in rows:
        names.setdefault(r["study"], []).append(r["surface"])
    assert names == {"patient_7": ["spleen", "liver"], "whole": ["kidney_left"]}


def test_killed_run_resumes_with_the_default_recipe(tmp_path):
    """SIGTERM mid-run: the workers stop, no half-written study looks done; the re-run skips
    the finished ones and completes the rest, equal to a single `anatomesh mesh` run."""
    studies = tmp_path / "studies"
    studies.mkdir()
    for i in range(3):
        shutil.copy(shared(*SEG_MR), studies / f"mr{i}.nii.gz")
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "anatomesh.app.cli", "batch", str(studies), "--out", str(out),
                             "--workers", "1"], cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    finished = _wait_for_a_study(proc, out)
    workers = psutil.Process(proc.pid).children(recursive=True)
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(60) == 130, proc.stderr.read().decode()
    assert psutil.wait_procs(workers, timeout=15)[1] == []  # no worker left running
    done = sorted(p.name for p in out.iterdir() if p.is_dir() and not p.name.startswith("."))
    assert finished in done and len(done) < 3
    sha = recipe_sha(batch_recipe(None), None)
    assert all(state.completed(out, s, studies / f"{s}.nii.gz", sha) is not None for s in done)
    first = _first(batch.run(studies, None, out, workers=1))
    assert {s: first[s]["status"] for s in done} == {s: "skipped" for s in done}
    assert sorted(s for s, r in first.items() if r["status"] == "done") == sorted(set(first) - set(done))
    single = tmp_path / "single"
    assert main(["mesh", str(studies / "mr0.nii.gz"), "--out", str(single)]) == 0
    theirs = json.loads((single / "report.json").read_text())["surfaces"]
    assert theirs[0]["volume_change_pct"] is not None  # the default recipe smooths
    for study in first:
        mine = json.loads((out / study / "report.json").read_text())["surfaces"]
        assert [(s["name"], s["faces"], s["volume_mm3"]) for s in mine] == \
               [(s["name"], s["faces"], s["volume_mm3"]) for s in theirs]
        assert all((out / study / s["files"]["stl"]).read_bytes() == (single / s["files"]["stl"]).read_bytes()
                   for s in theirs)


def test_killed_driver_takes_its_workers_along(cohort, tmp_path):
    """SIGKILL of the batch process (no chance to clean up): its workers end too, the lock is
    free, and the re-run completes."""
    studies = tmp_path / "studies"
    studies.mkdir()
    for i in range(4):
        shutil.copy(shared(*SEG), studies / f"ct{i}.nii.gz")
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "anatomesh.app.cli", "batch", str(studies), "--recipe",
                             str(cohort / "fast.toml"), "--out", str(out), "--workers", "1"],
                            cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    _wait_for_a_study(proc, out)
    workers = psutil.Process(proc.pid).children(recursive=True)
    proc.kill()
    proc.wait(30)
    assert workers and psutil.wait_procs(workers, timeout=15)[1] == []
    first = _first(batch.run(studies, cohort / "fast.toml", out, workers=1))
    assert all(r["status"] in ("done", "skipped") for r in first.values())
    assert any(r["status"] == "skipped" for r in first.values())


def test_cli_exit_codes_and_counts(cohort, pooled, capsys):
    out, _ = pooled
    code = main(["batch", str(cohort / "studies"), "--recipe", str(cohort / "fast.toml"), "--out", str(out)])
    stdout, stderr = capsys.readouterr()
    assert code == 1  # a study failed
    assert "5 studies: 0 done, 4 unchanged (skipped), 1 failed" in stdout
    assert "failed: broken:" in stderr
    assert main(["batch", str(cohort / "nothing_here"), "--out", str(out)]) == 2


def test_dask_local_cluster_gives_identical_results(cohort, pooled):
    out_pool, rows_pool = pooled
    out = cohort / "out_dask"
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        stages = []
        rows = batch.run(cohort / "studies", cohort / "fast.toml", out, scheduler=cluster.scheduler_address,
                         progress=lambda f, t: stages.append(t))
        again = batch.run(cohort / "studies", cohort / "fast.toml", out, scheduler=cluster)  # the object
    assert {r["study"]: r["status"] for r in again} == {**{s: "skipped" for s in GOOD}, "broken": "failed"}
    keep = ("study", "status", "surface", "value", "faces", "volume_mm3", "area_mm2", "closed", "error")
    assert [{k: r[k] for k in keep} for r in rows] == [{k: r[k] for k in keep} for r in rows_pool]
    for study in GOOD:
        files = sorted(p.name for p in (out_pool / study).iterdir())
        assert files == sorted(p.name for p in (out / study).iterdir())
        for name in files:
            if name.endswith(".stl"):
                assert (out / study / name).read_bytes() == (out_pool / study / name).read_bytes()
    # the workers' stages reached the bar (which shows at most one update per 0.2 s)
    assert any(re.search(r"\| (ct1|ct2|mr|brain): \w", t) for t in stages)
    assert stages[-1].startswith("4 done, 1 failed, 0 left")


def _wait_for_a_study(proc, out: Path, timeout: float = 240) -> str:
    t0 = time.time()
    while time.time() - t0 < timeout:
        done = [p.parent.name for p in out.glob("*/report.json")]
        if done:
            return done[0]
        assert proc.poll() is None, proc.stderr.read().decode()
        time.sleep(0.02)
    proc.kill()
    pytest.fail("no study finished in time")


def test_output_folder_inside_the_inputs_is_no_study(cohort, tmp_path):
    shutil.copy(shared(*BRAIN), tmp_path / "brain.nrrd")
    batch.run(tmp_path, cohort / "fast.toml", tmp_path / "results", workers=1)
    rows = batch.run(tmp_path, cohort / "fast.toml", tmp_path / "results", workers=1)
    assert [(r["study"], r["status"]) for r in rows] == [("brain", "skipped")]
