"""What a batch folder remembers, so a run can be resumed: content hashes, done studies, failures.

Layout of ``OUT``::

    OUT/<id>/               one finished study: the files of ``anatomesh mesh``, report.json
                            (with a "batch" entry: input and recipe hashes), thumbnail.png
    OUT/summary.csv|.parquet|.html
    OUT/recipe.toml         the batch's recipe
    OUT/.batch/lock         held by the running batch (a second one on OUT is refused)
    OUT/.batch/partial/     studies being written (renamed to OUT/<id> when complete)
    OUT/.batch/failed/      <id>.json per failed study: its one-line reason and hashes

A study folder appears under its final name only complete (written in ``.batch/partial``, then
renamed), so a killed run never leaves a half-written study that looks done. A study is *done*
when its report's batch entry matches the recipe hash and the input's content, and every file
the report lists exists. Inputs are compared by size and modification time first, and hashed
(SHA-256) only when those differ, so checking a large finished cohort reads no scan.
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
import uuid
from pathlib import Path
from typing import Dict, List, Optional

from ...core.model.errors import AnatomeshError
from ..flow.report import json_default

STATE = ".batch"
REPORT = "report.json"
THUMBNAIL = "thumbnail.png"


def state_dir(out: Path, *parts: str) -> Path:
    d = Path(out, STATE, *parts)
    d.mkdir(parents=True, exist_ok=True)
    return d


# -- input fingerprints -----------------------------------------------------------------------
def input_files(path: Path) -> List[Path]:
    """The files a study reads: the file (and a ``.nhdr``'s detached data file) or every file
    under a folder, sorted."""
    if path.is_dir():
        return sorted(f for f in path.rglob("*") if f.is_file())
    files = [path]
    if path.name.lower().endswith(".nhdr"):
        for line in path.read_text(errors="replace").splitlines():
            key, _, value = line.partition(":")
            if key.strip().lower() in ("data file", "datafile") and value.strip():
                files.append(path.parent / value.strip())
    return files


def fingerprint(path, hashes: bool = True) -> Optional[List[Dict]]:
    """Per input file: ``name`` (relative to the input), ``size``, ``mtime_ns`` and, with
    ``hashes``, ``sha256``; None when the input does not exist."""
    path = Path(path)
    if not path.exists():
        return None
    base = path if path.is_dir() else path.parent
    out = []
    for f in input_files(path):
        st = f.stat()
        entry = {"name": f.relative_to(base).as_posix(), "size": st.st_size, "mtime_ns": st.st_mtime_ns}
        if hashes:
            entry["sha256"] = file_sha256(f)
        out.append(entry)
    return out


def file_sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def unchanged(old: Optional[List[Dict]], path) -> bool:
    """True when the input at ``path`` has the content ``old`` (a :func:`fingerprint`) recorded."""
    now = fingerprint(path, hashes=False)
    if old is None or now is None:
        return old is None and now is None
    if [e["name"] for e in old] != [e["name"] for e in now]:
        return False
    base = Path(path) if Path(path).is_dir() else Path(path).parent
    for was, new in zip(old, now):
        if (was["size"], was["mtime_ns"]) == (new["size"], new["mtime_ns"]):
            continue
        if "sha256" not in was or was["size"] != new["size"] or file_sha256(base / new["name"]) != was["sha256"]:
            return False
    return True


def text_sha256(text: str) -> str:
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


# -- done and failed studies ------------------------------------------------------------------
def completed(out: Path, study_id: str, path, recipe_sha: str) -> Optional[Dict]:
    """The report of study ``study_id`` when it is done with this recipe and input, else None."""
    folder = Path(out, study_id)
    try:
        report = json.loads((folder / REPORT).read_text())
    except (OSError, ValueError):
        return None
    stamp = report.get("batch") or {}
    if stamp.get("recipe_sha256") != recipe_sha or not unchanged(stamp.get("inputs"), path):
        return None
    files = list(report.get("files", {}).values()) + [f for s in report.get("surfaces", [])
                                                      for f in s.get("files", {}).values()]
    if not all((folder / f).is_file() for f in files):
        return None
    return report


def record_failure(out: Path, study_id: str, record: Dict) -> None:
    """Write ``OUT/.batch/failed/<id>.json`` (reason, hashes, seconds)."""
    write_json_atomic(state_dir(out, "failed") / f"{study_id}.json", record)


def earlier_failure(out: Path, study_id: str, path, recipe_sha: str) -> Optional[Dict]:
    """The failure record of a study that failed with this recipe and input, else None."""
    try:
        record = json.loads((Path(out, STATE, "failed") / f"{study_id}.json").read_text())
    except (OSError, ValueError):
        return None
    if record.get("recipe_sha256") != recipe_sha or not unchanged(record.get("inputs"), path):
        return None
    return record


def forget_failure(out: Path, study_id: str) -> None:
    Path(out, STATE, "failed", f"{study_id}.json").unlink(missing_ok=True)


# -- atomic study folders ---------------------------------------------------------------------
def new_partial(out: Path, study_id: str) -> Path:
    """A fresh folder in ``OUT/.batch/partial`` to write a study into."""
    d = state_dir(out, "partial") / f"{study_id}.{uuid.uuid4().hex[:8]}"
    d.mkdir()
    return d


def publish(partial: Path, out: Path, study_id: str) -> Path:
    """Move a complete study folder to ``OUT/<id>`` (replacing an older one) by renames."""
    final = Path(out, study_id)
    old = None
    if final.exists():
        old = partial.with_name(partial.name + ".old")
        os.replace(final, old)
    os.replace(partial, final)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
    return final


def clear_partials(out: Path) -> None:
    """Remove what a killed run left half-written (called while holding the lock)."""
    shutil.rmtree(Path(out, STATE, "partial"), ignore_errors=True)


def write_json_atomic(path: Path, data: Dict) -> None:
    tmp = path.with_name(path.name + f".{uuid.uuid4().hex[:8]}.part")
    tmp.write_text(json.dumps(data, indent=2, default=json_default))
    os.replace(tmp, path)


class Lock:
    """``OUT/.batch/lock``, held (``flock``) while a batch runs on ``OUT``; released when the
    process ends however it ends."""

    def __init__(self, out: Path):
        self.path = state_dir(out) / "lock"
        self.fh = None

    def __enter__(self):
        self.fh = open(self.path, "a+")
        try:
            import fcntl
        except ImportError:  # Windows: no advisory lock
            return self
        try:
            fcntl.flock(self.fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            self.fh.seek(0)
            pid = self.fh.read().strip() or "?"
            self.fh.close()
            raise AnatomeshError(f"another batch (process {pid}) is writing into this folder; wait "
                                 "for it to finish or choose another --out", self.path.parent.parent) from None
        self.fh.seek(0)
        self.fh.truncate()
        self.fh.write(str(os.getpid()))
        self.fh.flush()
        return self

    def __exit__(self, *exc):
        self.fh.close()
