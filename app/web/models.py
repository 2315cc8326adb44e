"""The models of a web page: from a run (``anatomesh mesh --format web``), from the reports of
earlier runs or from mesh files (``anatomesh web``), each with its levels of detail and, when
asked, its distance colouring.

Levels of detail come from one progressive decimation run (:func:`anatomesh.core.decimate.progressive.progressive`,
Hoppe 1996): for a run, the whole label set at once (seams stay shared at every level); for
files, each surface on its own, so a surface that several models share (resection variants)
gets the same coarse levels in each and is stored once. Level ``k`` of ``n`` keeps
``8^-(n-1-k)`` of the faces (two levels: an eighth, then everything), or the coarsest mesh that
keeps every shell's topology.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Dict, List, Optional, Sequence

from ...core.decimate.progressive import progressive
from ...core.export.gltf import read_glb
from ...core.geometry.margins import MARGINS_MM, color_by_distance, find_target
from ...core.io.mesh_files import MESH_SUFFIXES, read_mesh
from ...core.model.errors import AnatomeshError
from ...core.model.mesh import Mesh
from ...core.model.progress import Progress, report, sub
from .page import WebModel

#: how many times fewer faces each coarser level has
LEVEL_FACTOR = 8.0


def level_ratios(n_levels: int) -> List[float]:
    """Face fractions of the coarser levels, coarsest first (the full detail, 1, is implied)."""
    if not (isinstance(n_levels, int) and 1 <= n_levels <= 4):
        raise AnatomeshError(f"--web-levels is the number of levels of detail of the page, 1..4, got {n_levels!r}")
    return [LEVEL_FACTOR ** -(n_levels - 1 - k) for k in range(n_levels - 1)]


def mesh_levels(meshes: List[Mesh], n_levels: int, progress: Optional[Progress] = None) -> List[List[Mesh]]:
    """Levels of independent surfaces, coarsest first, each surface decimated on its own."""
    ratios = level_ratios(n_levels)
    levels: List[List[Mesh]] = [[] for _ in ratios]
    for i, m in enumerate(meshes):
        if ratios:
            pm = progressive(m, face_ratios=ratios)
            for k in range(len(ratios)):
                lv = pm.level(min(k, pm.n_levels - 1))
                levels[k].append(Mesh(lv.vertices, lv.faces, name=m.name, value=m.value, color=m.color,
                                      space=m.space))
        report(progress, (i + 1) / max(1, len(meshes)), f"levels of {m.name}")
    return levels + [list(meshes)]


def color_levels(levels: List[List[Mesh]], target, margins: Sequence[float]) -> Dict:
    """Distance colours on every level, measured to the full-detail target; returns the summary
    of the full level (:func:`anatomesh.core.geometry.margins.color_by_distance`)."""
    full = levels[-1]
    _, summary = color_by_distance(full, target, margins)
    surface = full[find_target(full, target)]
    for level in levels[:-1]:
        color_by_distance(level, target, margins, target_surface=surface)
    return summary


# ---------------------------------------------------------------------------------------------
# anatomesh web REPORT_OR_FILES
# ---------------------------------------------------------------------------------------------
def models_of_inputs(paths: Sequence, n_levels: int = 2, distance_to=None,
                     margins: Optional[Sequence[float]] = None,
                     progress: Optional[Progress] = None) -> List[WebModel]:
    """One model per report (``report.json`` of ``anatomesh mesh``), plus one model of all mesh
    files given (STL, PLY, OBJ, GLB). A report's own distance colouring is redone on every level
    unless ``distance_to`` asks for another target."""
    paths = [Path(p) for p in paths]
    if not paths:
        raise AnatomeshError("give one or more report.json files or mesh files (stl, ply, obj, glb)")
    reports = [p for p in paths if p.suffix.lower() == ".json"]
    files = [p for p in paths if p not in reports]
    groups = [(_report_name(p), *_report_meshes(p)) for p in reports]
    if files:
        groups.append((files[0].stem if len(files) == 1 else files[0].parent.name or "surfaces",
                       [m for f in files for m in _mesh_file(f)], None))
    models = []
    for i, (name, meshes, dist) in enumerate(groups):
        levels = mesh_levels(meshes, n_levels, sub(progress, i / len(groups), (i + 1) / len(groups)))
        target = distance_to if distance_to is not None else (dist or {}).get("target")
        summary = None
        if target is not None:
            m = margins if margins is not None else (dist or {}).get("margins_mm", MARGINS_MM)
            summary = color_levels(levels, target, m)
        else:
            for level in levels:
                for mesh in level:
                    mesh.vertex_colors = None
        models.append(WebModel(name, levels, summary))
    return models


def _report_name(path: Path) -> str:
    return path.parent.name if path.name == "report.json" and path.parent.name else path.stem


def _report_meshes(path: Path):
    """The surfaces of a report: its GLB when it wrote one, else each surface's mesh file."""
    try:
        rep = json.loads(path.read_text(encoding="utf-8"))
        surfaces = rep["surfaces"]
    except FileNotFoundError:
        raise AnatomeshError("no such report; check the path", path) from None
    except (OSError, ValueError, KeyError, TypeError):
        raise AnatomeshError("not an Anatomesh report (report.json of `anatomesh mesh`)", path) from None
    base = path.parent
    glb = (rep.get("files") or {}).get("glb")
    if glb:
        meshes = read_glb(base / glb)
    else:
        found = [next((base / s["files"][f] for f in ("stl", "ply", "obj") if f in s.get("files", {})), None)
                 for s in surfaces]
        if any(f is None for f in found):
            raise AnatomeshError("the report lists no glb, stl, ply or obj file for every surface; "
                                 "re-run `anatomesh mesh` with --format glb (or stl)", path)
        meshes = [read_mesh(f) for f in found]
    for m, s in zip(meshes, surfaces):
        m.name, m.value, m.color = s.get("name", m.name), s.get("value", m.value), tuple(s.get("color", m.color))
    return meshes, rep.get("distance")


def _mesh_file(path: Path) -> List[Mesh]:
    suffix = path.suffix.lower()
    if suffix == ".glb":
        return read_glb(path)
    if suffix in MESH_SUFFIXES:
        m = read_mesh(path)
        m.name = m.name or path.stem
        return [m]
    raise AnatomeshError(f"cannot put a {suffix or 'suffix-less'} file on a page; give report.json or "
                         f"mesh files ({', '.join(MESH_SUFFIXES)}, .glb)", path)
