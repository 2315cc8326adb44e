"""A self-contained 3D page: a folder anyone opens with a double-click, offline, no plug-in.

What :func:`write_page` writes into the folder::

    index.html        the page (panel + canvas; no request leaves it: no CDN, no web fonts)
    viewer.js         three.js + meshoptimizer's decoder + Anatomesh's viewer, one minified
                      classic script (built from web/ with npm, shipped in the package)
    LICENSES.txt      the licences of the bundled libraries
    scene.js          the scene: models, structures (name, system, colour, opacity, volume),
                      levels, saved views
    data/lodK.js      one script per level of detail (lod0 the full detail), compressed surfaces

Every file is a classic script or the page itself, so the page works from ``file://`` (where
browsers refuse ``fetch`` and modules) and from any static server. The levels load coarsest
first: the first picture comes from the coarse level, the finer ones replace it as they arrive
(progressive transmission of levels of detail; the levels come from one progressive decimation
run, Hoppe 1996, "Progressive meshes"); the full detail is drawn before the page's load event,
so a plain screenshot shows it. Surfaces are compressed with meshoptimizer's codecs
(:mod:`anatomesh.app.web.pack`); a structure that several models share (resection variants) is
stored once.

The page's tree groups structures by body system (:func:`anatomesh.core.model.labels.structure_system`);
each has visibility and opacity; see-through structures are drawn back faces then front faces,
sorted per object (nested shells right), with optional oriented transparency (Stalling, Zöckler &
Hege 1999); a structure's default opacity is its colour's alpha. Hover or click names a structure
with its volume; a clipping plane whose cuts are capped in each structure's colour; named views;
a measuring tool (distances between points, and to the nearest other structure, mm); a reset
button and a scale bar in mm (orthographic view: the bar holds at every depth). The page keeps
its view in the URL's fragment (:mod:`anatomesh.app.web.views` lists the keys), and the views
given to :func:`write_page` are listed in it.
"""
from __future__ import annotations

import html
import json
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Dict, List, Optional, Sequence

import numpy as np

from ...core.export.common import atomic_write, refuse_overwrite
from ...core.model.errors import AnatomeshError
from ...core.model.labels import SYSTEMS, rgba, structure_system
from ...core.model.mesh import Mesh, signed_volume, surface_area
from ...core.model.progress import Progress, report
from .pack import LevelPack, display_vertices, encoded_level, level_script, quantization_for

VIEWER_DIR = Path(__file__).resolve().parent / "viewer"
#: files copied as they are from :data:`VIEWER_DIR`
VIEWER_FILES = ("viewer.js", "LICENSES.txt")
PAGE, SCENE, DATA = "index.html", "scene.js", "data"
#: format tag of scene.js (the viewer checks it)
SCENE_FORMAT = "anatomesh-web/2"


@dataclass
class WebModel:
    """One model of a page: its name and its surfaces per level of detail, coarsest first (every
    level lists the same structures in the same order; the last is the full detail). ``distance``
    is the summary of :func:`anatomesh.core.geometry.margins.color_by_distance`, if coloured."""

    name: str
    levels: List[List[Mesh]]
    distance: Optional[Dict] = None


def level_file(k: int, n_levels: int) -> str:
    """The data file of loading step ``k`` (0 = coarsest) of ``n_levels``: ``data/lod{n-1-k}.js``,
    so ``lod0`` is the full detail as for ``--lod`` GLB files."""
    return f"{DATA}/lod{n_levels - 1 - k}.js"


def page_paths(out_dir, n_levels: int) -> List[Path]:
    """Every file :func:`write_page` writes into ``out_dir`` for ``n_levels`` levels."""
    out = Path(out_dir)
    return ([out / PAGE, out / SCENE] + [out / f for f in VIEWER_FILES]
            + [out / level_file(k, n_levels) for k in range(n_levels)])


def write_page(models: Sequence[WebModel], out_dir, *, title: str = "", overwrite: bool = False,
               views: Sequence[Dict[str, str]] = (), progress: Optional[Progress] = None) -> Dict:
    """Write the page of ``models`` into the folder ``out_dir`` (made if missing); ``views``
    (``[{"name", "fragment"}]``, :func:`anatomesh.app.web.views.read_views`) are listed in it.

    Raises :class:`AnatomeshError` when a file exists and ``overwrite`` is not set (nothing is
    written then), for models without surfaces or with different numbers of levels, or when
    meshoptimizer's binding is missing.

    Returns the summary for the report: ``page`` (path of index.html), ``levels`` (coarsest
    first: ``file``, ``triangles`` and ``vertices`` of the distinct surfaces stored, ``bytes`` of
    the file), ``viewer_bytes``, ``total_bytes`` (every file of the folder), ``structures``,
    ``stored_surfaces`` (distinct surfaces at full detail) and ``quantization_mm``.
    """
    models = _checked(models)
    n = len(models[0].levels)
    out = Path(out_dir)
    refuse_overwrite(page_paths(out, n), overwrite)
    q = quantization_for([m for model in models for level in model.levels for m in level])
    packs = [LevelPack() for _ in range(n)]
    scene_models = []
    for i, model in enumerate(models):
        ids = [encoded_level(level, q, packs[k]) for k, level in enumerate(model.levels)]
        scene_models.append(_scene_model(model, ids))
        report(progress, 0.8 * (i + 1) / len(models), f"encoded {model.name}")
    levels = []
    for k, pack in enumerate(packs):
        data = level_script(k, pack.deflated())
        with atomic_write(out / level_file(k, n)) as fh:
            fh.write(data)
        levels.append({"file": level_file(k, n), "triangles": pack.triangles, "bytes": len(data),
                       "vertices": sum(r["v"] for r in pack.records.values()), "geometries": pack.records})
    scene = {"format": SCENE_FORMAT, "title": title or models[0].name, "units": "mm",
             "frame": "display: +x patient left, +y superior, +z anterior (mm)",
             "space": models[0].levels[-1][0].space, "systems": list(SYSTEMS),
             "quantization": q.as_dict(), "levels": levels, "models": scene_models,
             "views": [{"name": v["name"], "fragment": v["fragment"]} for v in views]}
    _write_text(out / SCENE, "window.ANATOMESH_SCENE = " + json.dumps(scene, separators=(",", ":")) + ";\n")
    template = (VIEWER_DIR / PAGE).read_text(encoding="utf-8")
    _write_text(out / PAGE, template.replace("__TITLE__", html.escape(scene["title"]))
                .replace("__LEVEL_SCRIPTS__", level_script_tag(n)))
    for name in VIEWER_FILES:
        shutil.copyfile(VIEWER_DIR / name, out / name)
    report(progress, 1.0, "page written")
    return _summary(out, levels, scene_models, packs, q.step)


def level_script_tag(n_levels: int) -> str:
    """index.html's tag of the coarsest level's script (parsed with the page, fetched while
    viewer.js is parsed; the viewer requests the finer ones as it starts); a missing file is
    named on the page."""
    return f'<script src="{level_file(0, n_levels)}" onerror="anatomeshMissing(this)"></script>'


def _checked(models: Sequence[WebModel]) -> List[WebModel]:
    models = list(models)
    if not models or not all(model.levels and model.levels[-1] for model in models):
        raise AnatomeshError("nothing to put on the page: no surfaces")
    n = len(models[0].levels)
    for model in models:
        if len(model.levels) != n or any(len(lv) != len(model.levels[-1]) for lv in model.levels):
            raise AnatomeshError(f"model {model.name!r}: every model of a page needs the same number "
                                 f"of levels ({n}), each with the same structures")
    return models


def _scene_model(model: WebModel, ids: List[List[str]]) -> Dict:
    shells = (model.distance or {}).get("shells", {})
    structures = []
    for j, m in enumerate(model.levels[-1]):
        s = {"name": m.name or f"surface {j + 1}", "value": m.value, "system": structure_system(m.name),
             "color": [round(c, 4) for c in rgba(m.color)[:3]],
             "volume_mm3": round(abs(signed_volume(m.vertices, m.faces)), 1),
             "area_mm2": round(surface_area(m.vertices, m.faces), 1),
             "geometry": [level_ids[j] for level_ids in ids]}
        alpha = rgba(m.color)[3]
        if alpha < 1:
            s["opacity"] = round(alpha, 3)
        if m.name in shells and shells[m.name]["min_distance_mm"] is not None:
            s["min_distance_mm"] = shells[m.name]["min_distance_mm"]
        structures.append(s)
    pts = np.concatenate([display_vertices(m) for m in model.levels[-1]])
    out = {"name": model.name, "structures": structures,
           "triangles": [sum(x.n_faces for x in level) for level in model.levels],
           "box": {"min": [round(float(x), 3) for x in pts.min(0)],  # display frame, full detail
                   "max": [round(float(x), 3) for x in pts.max(0)]}}
    if model.distance:
        out["distance"] = {k: model.distance[k] for k in ("target", "colors")}
        out["distance"]["margins"] = model.distance["margins_mm"]
    return out


def _write_text(path: Path, text: str) -> None:
    with atomic_write(path) as fh:
        fh.write(text.encode("utf-8"))


def _summary(out: Path, levels: List[Dict], scene_models: List[Dict], packs: List[LevelPack],
             step: float) -> Dict:
    viewer = sum((out / f).stat().st_size for f in VIEWER_FILES)
    total = sum(p.stat().st_size for p in page_paths(out, len(levels)))
    return {"page": str(out / PAGE),
            "levels": [{k: lv[k] for k in ("file", "triangles", "vertices", "bytes")} for lv in levels],
            "viewer_bytes": viewer, "total_bytes": total,
            "structures": sum(len(m["structures"]) for m in scene_models),
            "stored_surfaces": len(packs[-1].records), "quantization_mm": step}
