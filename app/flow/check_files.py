"""The check flow: read mesh files and folders, then run the print checks on all parts together.

:func:`read_parts` turns files (STL/PLY/OBJ, 3MF with one part per object) and folders (written by
``anatomesh mesh``: their ``report.json`` names the files; other folders: every mesh file in them)
into meshes; :func:`check_files` checks them (:func:`anatomesh.core.printing.checks.check_parts`).
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Dict, List, Optional

import numpy as np

from ...core.export.threemf import read_3mf
from ...core.io.mesh_files import MESH_SUFFIXES, read_mesh
from ...core.model.errors import AnatomeshError
from ...core.model.mesh import Mesh
from ...core.model.progress import Progress, report, sub
from ...core.printing import fixes as printfix
from ...core.printing.checks import check_parts


def _report_meshes(folder, progress: Optional[Progress] = None) -> List[Mesh]:
    """The surfaces listed in ``folder/report.json`` (written by ``anatomesh mesh``), named as
    there; per surface the first of STL, PLY, OBJ, 3MF that was written."""
    folder = Path(folder)
    rp = folder / "report.json"
    try:
        rep = json.loads(rp.read_text())
        surfaces = rep["surfaces"]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise AnatomeshError(f"cannot read the mesh report ({exc}); re-run `anatomesh mesh` or "
                             f"give the mesh files themselves", rp) from None
    out = []
    for k, s in enumerate(surfaces):
        files = s.get("files") or {}
        fmt = next((x for x in ("stl", "ply", "obj", "3mf") if x in files), None)
        if fmt is None:
            raise AnatomeshError(f"surface {s.get('name')!r} lists no STL/PLY/OBJ/3MF file; re-run "
                                 f"`anatomesh mesh` with --format stl", rp)
        path = Path(files[fmt])
        path = path if path.is_absolute() else folder / path
        report(progress, k / max(len(surfaces), 1), f"reading {path.name}")
        m = read_mesh(path) if fmt != "3mf" else _one_mesh(_read_3mf(path), path.stem)
        m.name = str(s.get("name") or m.name)
        m.value = s.get("value")
        if s.get("color"):
            m.color = tuple(s["color"][:3])
        m.space = str(rep.get("space", m.space))
        out.append(m)
    return out


def _read_3mf(path) -> List[Mesh]:
    return list(read_3mf(path))


def _one_mesh(meshes: List[Mesh], name: str) -> Mesh:
    """The objects of one surface's file as one Mesh (they are usually just one)."""
    if len(meshes) == 1:
        return meshes[0]
    offs = np.cumsum([0] + [m.n_vertices for m in meshes])
    return Mesh(np.concatenate([m.vertices for m in meshes]),
                np.concatenate([m.faces + o for m, o in zip(meshes, offs[:-1])]), name=name,
                color=meshes[0].color if meshes else (0.8, 0.8, 0.8),
                space=meshes[0].space if meshes else "RAS")


def read_parts(paths, progress: Optional[Progress] = None) -> List[Mesh]:
    """Meshes to check from files and folders: STL/PLY/OBJ files (one part each), 3MF files
    (one part per object, via :func:`anatomesh.core.export.threemf.read_3mf`), folders written by
    ``anatomesh mesh`` (their ``report.json`` names the files), or other folders (every mesh file
    in them, sorted). Raises :class:`AnatomeshError` for a missing path or an unreadable file."""

    if isinstance(paths, (str, Path)):
        paths = [paths]
    meshes: List[Mesh] = []
    paths = [Path(p) for p in paths]
    if not paths:
        raise AnatomeshError("no mesh files given: pass STL/PLY/OBJ/3MF files or a folder")
    for k, p in enumerate(paths):
        sp = sub(progress, k / len(paths), (k + 1) / len(paths))
        if p.is_dir():
            if (p / "report.json").is_file():
                meshes += _report_meshes(p, sp)
                continue
            files = sorted(x for x in p.iterdir()
                           if x.suffix.lower() in MESH_SUFFIXES + (".3mf",) and x.is_file())
            if not files:
                raise AnatomeshError("this folder has no report.json and no STL/PLY/OBJ/3MF files; "
                                     "give mesh files or a folder written by `anatomesh mesh`", p)
            meshes += read_parts(files, sp)
        elif not p.exists():
            raise AnatomeshError("no such file or folder: check the path", p)
        elif p.suffix.lower() == ".3mf":
            meshes += _read_3mf(p)
        else:
            report(sp, 0.0, f"reading {p.name}")
            meshes.append(read_mesh(p))
    names = [m.name for m in meshes]
    for i, m in enumerate(meshes):  # keep names unique: they key the report
        if not m.name or names.count(m.name) > 1:
            m.name = f"{m.name or 'part'}#{i + 1}"
    return meshes


def check_files(paths, profile="fdm", min_wall: Optional[float] = None,
                min_gap: Optional[float] = None, progress: Optional[Progress] = None) -> Dict:
    """:func:`check_parts` on the meshes of ``paths`` (see :func:`read_parts`); the report also
    lists the ``files`` read."""
    meshes = read_parts(paths, sub(progress, 0.0, 0.1))
    rep = check_parts(meshes, profile, min_wall, min_gap, progress=sub(progress, 0.1, 1.0))
    rep["files"] = [str(p) for p in ([paths] if isinstance(paths, str) else paths)]
    return rep


def fix_parts(meshes: List[Mesh], remove_tiny: Optional[float] = None, close_holes: Optional[int] = None,
              separate: Optional[float] = None):
    """Mesh fixes of the check flow on each part (:mod:`anatomesh.core.printing.fixes`): remove
    shells under ``remove_tiny`` mm³, close holes of up to ``close_holes`` edges, pull touching
    parts ``separate`` mm apart. Returns the fixed meshes and per part ``{"name", "summary"}``."""
    fixed, done = [], []
    for m in meshes:
        did = []
        if remove_tiny is not None:
            m, info = printfix.remove_tiny(m, remove_tiny)
            did += [f"removed {info['removed']} tiny shell(s)"] if info["removed"] else []
        if close_holes is not None:
            m, info = printfix.close_holes(m, close_holes)
            did += [f"closed {info['closed']} hole(s)"] if info["closed"] else []
            did += [f"{info['left_open']} larger hole(s) left open"] if info["left_open"] else []
        fixed.append(m)
        done.append(did)
    if separate is not None:
        fixed, info = printfix.separate_meshes(fixed, separate)
        for i, j in info["pairs"]:
            done[i].append(f"pulled {separate:g} mm away from {fixed[j].name}")
            done[j].append(f"pulled {separate:g} mm away from {fixed[i].name}")
    return fixed, [{"name": m.name, "summary": "; ".join(d) or "nothing to fix"} for m, d in zip(fixed, done)]
