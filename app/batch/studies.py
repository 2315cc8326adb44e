"""The studies of a batch: what ``INPUTS`` names, one :class:`Study` (id, input path, labels) each.

``INPUTS`` is one of

* **a folder of studies**: every sub-folder and every scan file in it (``.nii``, ``.nii.gz``,
  ``.nrrd``, ``.nhdr``, ``.dcm``) is one study, its id the entry's name without the suffix. A
  sub-folder is given to :func:`anatomesh.core.io.load` as it is (a DICOM series, a folder of
  TotalSegmentator masks), except in TotalSegmentator's dataset layout: a study folder holding a
  ``segmentations/`` folder (beside ``ct.nii.gz``) or a ``segmentations.nii.gz`` multi-label file
  (``--ml``) is read from that. Hidden entries and other files (JSON, CSV, text) are passed over;
* **a manifest**: a ``.csv`` or ``.tsv`` file with the columns ``id,path[,labels]`` (a header row
  naming them is optional; ``#`` comment lines and blank lines are passed over; relative paths
  are relative to the manifest; ``labels`` is ``all`` or values/names separated by ``;``, ``,``
  or spaces);
* **a glob** (``"cohort/*/segmentations"``, ``**`` allowed) or **several paths** (a shell-expanded
  glob): one study per match, its id the parts of the path that differ between the matches.

Ids are file-name safe (letters, digits, ``._-``) and unique; a clash is one error naming both.
"""
from __future__ import annotations

import csv
import glob
import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Dict, List, Optional, Sequence, Union

from ...core.model.errors import AnatomeshError

SCAN_SUFFIXES = (".nii.gz", ".nii", ".seg.nrrd", ".nrrd", ".nhdr", ".dcm")
MANIFEST_SUFFIXES = (".csv", ".tsv")
#: TotalSegmentator's dataset layout: the CT beside a folder of masks or a multi-label file
TOTALSEG_INPUTS = ("segmentations", "segmentations.nii.gz", "segmentations.nii")
_NAMES_FILE = Path(__file__).resolve().parents[2] / "data" / "sample" / "label_names_total_and_total_mr.json"


@dataclass(frozen=True)
class Study:
    """One study: ``id`` (its folder name under the batch's output), ``path`` (what
    :func:`anatomesh.core.io.load` reads) and ``labels`` (None: the recipe's)."""

    id: str
    path: str
    labels: Optional[Union[str, tuple]] = None


def find_studies(inputs: Union[str, Path, Sequence[Union[str, Path]]]) -> List[Study]:
    """The studies ``inputs`` names (see the module docstring), sorted by id.

    Raises :class:`AnatomeshError` when nothing matches, a manifest is malformed or two studies
    would get the same id. A study whose path does not exist is not an error here: it fails
    alone when the batch runs it."""
    if isinstance(inputs, (list, tuple)):
        if len(inputs) == 1:
            return find_studies(inputs[0])
        if not inputs:
            raise AnatomeshError("no inputs: give a folder of studies, a manifest (.csv/.tsv) or a glob")
        return _by_id(_from_paths([Path(p) for p in inputs]))
    p = Path(str(inputs)).expanduser()
    if p.is_dir():
        return _by_id(_from_folder(p))
    if p.is_file() and p.name.lower().endswith(MANIFEST_SUFFIXES):
        return _by_id(read_manifest(p))
    if p.is_file():
        return _by_id(_from_paths([p]))
    if glob.has_magic(str(inputs)):
        matches = sorted(glob.glob(str(p), recursive=True))
        if not matches:
            raise AnatomeshError("the glob matches nothing; check the pattern (quote it so the "
                                 "shell leaves it alone)", inputs)
        return _by_id(_from_paths([Path(m) for m in matches]))
    raise AnatomeshError("no such folder, manifest or file; give a folder of studies, a .csv/.tsv "
                         "manifest (id,path[,labels]) or a glob", inputs)


def study_input(path: Path) -> Path:
    """What to read for a study entry: the entry itself, or inside a study folder in
    TotalSegmentator's dataset layout its ``segmentations`` folder or file."""
    if path.is_dir():
        for name in TOTALSEG_INPUTS:
            if (path / name).exists():
                return path / name
    return path


def study_id(name: str) -> str:
    """A file-name-safe id from an entry's name, without a scan suffix (``s0001.nii.gz`` → ``s0001``)."""
    base = name
    for suffix in SCAN_SUFFIXES:
        if base.lower().endswith(suffix) and len(base) > len(suffix):
            base = base[: -len(suffix)]
            break
    return re.sub(r"[^A-Za-z0-9._-]+", "_", base).strip("_.") or "study"


def read_manifest(path: Path) -> List[Study]:
    """The studies of a ``.csv``/``.tsv`` manifest: ``id,path[,labels]`` per row."""
    delimiter = "\t" if path.name.lower().endswith(".tsv") else ","
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise AnatomeshError(f"cannot read the manifest ({exc})", path) from None
    rows = [(n, r) for n, r in enumerate(csv.reader(text.splitlines(), delimiter=delimiter), 1)
            if r and any(c.strip() for c in r) and not r[0].lstrip().startswith("#")]
    columns = {"id": 0, "path": 1, "labels": 2}
    if rows and [c.strip().lower() for c in rows[0][1][:2]] == ["id", "path"]:
        header = [c.strip().lower() for c in rows.pop(0)[1]]
        columns = {name: header.index(name) for name in ("id", "path", "labels") if name in header}
    studies = []
    for n, row in rows:
        cells = [c.strip() for c in row]
        if len(cells) <= max(columns["id"], columns["path"]) or not cells[columns["id"]] or not cells[columns["path"]]:
            raise AnatomeshError(f"line {n}: expected id{delimiter}path[{delimiter}labels], got "
                                 f"{delimiter.join(cells)!r}", path)
        p = Path(cells[columns["path"]]).expanduser()
        p = p if p.is_absolute() else path.parent / p
        labels = cells[columns["labels"]] if "labels" in columns and len(cells) > columns["labels"] else ""
        studies.append(Study(study_id(cells[columns["id"]]), str(study_input(p)), parse_labels(labels)))
    if not studies:
        raise AnatomeshError("the manifest lists no study (expected rows id,path[,labels])", path)
    return studies


def parse_labels(text: str) -> Optional[Union[str, tuple]]:
    """``"liver; spleen 3"`` → ``("liver", "spleen", 3)``; ``"all"`` → ``"all"``; ``""`` → None."""
    parts = [t for t in re.split(r"[;,\s]+", text.strip()) if t]
    if not parts:
        return None
    if len(parts) == 1 and parts[0].lower() == "all":
        return "all"
    return tuple(int(t) if t.isdigit() else t for t in parts)


def _from_folder(folder: Path) -> List[Study]:
    entries = [e for e in sorted(folder.iterdir()) if not e.name.startswith((".", "_"))
               and (e.is_dir() or e.name.lower().endswith(SCAN_SUFFIXES))]
    if not entries:
        raise AnatomeshError("no studies in this folder: expected one sub-folder or scan file "
                             "(.nii.gz, .nrrd, .dcm) per study", folder)
    _refuse_mask_folder(folder, entries)
    return [Study(study_id(e.name), str(study_input(e))) for e in entries]


def _refuse_mask_folder(folder: Path, entries: List[Path]) -> None:
    """A folder of TotalSegmentator masks is one study, not a folder of studies."""
    names = _totalsegmentator_names()
    stems = [study_id(e.name) for e in entries if e.is_file()]
    if len(stems) >= 3 and len(stems) == len(entries) and sum(s in names for s in stems) > len(stems) / 2:
        raise AnatomeshError(f"this looks like one TotalSegmentator output folder ({', '.join(stems[:3])}, "
                             "...), i.e. one study: give the folder that holds one such folder per "
                             "study, or a manifest", folder)


def _totalsegmentator_names() -> set:
    try:
        doc = json.loads(_NAMES_FILE.read_text())
    except (OSError, ValueError):
        return set()
    return {name for table in doc.values() for name in table.values()}


def _from_paths(paths: List[Path]) -> List[Study]:
    """One study per path; ids from the path parts that differ between the paths."""
    parts = [p.resolve().parts[:-1] + (study_id(p.name),) for p in paths]
    ids = []
    for ps in parts:
        keep = [x for i, x in enumerate(ps)
                if not all(len(q) == len(ps) and q[i] == x for q in parts)]
        ids.append("_".join(study_id(x) for x in keep) if keep else ps[-1])
    return [Study(i, str(study_input(p))) for i, p in zip(ids, paths)]


def _by_id(studies: List[Study]) -> List[Study]:
    seen: Dict[str, Study] = {}
    for s in studies:
        if s.id in seen:
            raise AnatomeshError(f"two studies get the id {s.id!r} ({seen[s.id].path} and {s.path}); "
                                 "rename one or list them in a manifest with their own ids")
        seen[s.id] = s
    return sorted(studies, key=lambda s: s.id)
