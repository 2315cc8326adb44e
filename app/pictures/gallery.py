"""Isovalue guidance: named levels for a scan and a preview gallery of their isosurfaces.

* :func:`preset_levels` — the levels worth looking at: for CT in Hounsfield units the tissue
  boundaries (skin −500, soft tissue 40, contrast-filled vessels 200, bone 300, dense bone 700
  HU); for other scans the values halfway between neighbouring histogram peaks
  (:func:`anatomesh.core.io.describe.histogram`), the first being the background/body boundary,
  and one halfway from the last peak to the 99th percentile (bright structures: bone, contrast).
* :func:`gallery` — one picture (a contact sheet) of small renders of the isosurface at each
  level (:func:`anatomesh.core.export.snapshot.render`, no Blender needed), each captioned with
  its name, value and triangle count, so a user picks a level by looking
  (``anatomesh preview SCAN --out gallery.png``; the Blender Import panel shows the same sheet).

Large scans are previewed on every n-th voxel (at most :data:`PREVIEW_VOXELS` voxels), which
keeps the sheet to a second or two; the footer says so.
"""
from __future__ import annotations

from typing import List, Optional, Sequence, Tuple

import numpy as np

from ...core.export.snapshot import contact_sheet, render
from ...core.extract.isosurface import isosurfaces
from ...core.io.describe import histogram, looks_like_hounsfield
from ...core.model.errors import AnatomeshError
from ...core.model.progress import Progress, report
from ...core.model.volume import Volume
from .bitmap_font import draw_text, text_size

#: (name, HU, sRGB colour) of the CT presets
CT_LEVELS: Tuple[Tuple[str, float, Tuple[float, float, float]], ...] = (
    ("skin", -500.0, (0.92, 0.74, 0.62)),
    ("soft tissue", 40.0, (0.8, 0.45, 0.4)),
    ("contrast vessels", 200.0, (0.85, 0.2, 0.2)),
    ("bone", 300.0, (0.93, 0.89, 0.78)),
    ("dense bone", 700.0, (0.95, 0.95, 0.9)),
)
#: larger scans are previewed on a strided grid of at most this many voxels
PREVIEW_VOXELS = 8_000_000
CAPTION = 36


def preset_levels(volume: Volume) -> List[Tuple[str, float, Tuple[float, float, float]]]:
    """``(name, value, colour)`` of the levels worth previewing (module docstring)."""
    sample = _sample(volume.data)
    if looks_like_hounsfield(sample):
        return list(CT_LEVELS)
    peaks = [p["value"] for p in histogram(sample)["peaks"]]
    if len(peaks) < 2:
        qs = np.percentile(sample, [25, 50, 75]) if sample.size else [0.0]
        return [(f"quartile {i + 1}", _nice(q), (0.85, 0.8, 0.75)) for i, q in enumerate(qs)]
    out = []
    for i, (a, b) in enumerate(zip(peaks[:-1], peaks[1:])):
        name = "body outline" if i == 0 else f"peaks {i + 1}|{i + 2}"
        out.append((name, _nice(0.5 * (a + b)), (0.92, 0.74, 0.62) if i == 0 else (0.8, 0.8, 0.85)))
    top = float(np.percentile(sample, 99))
    if top > peaks[-1]:  # bone, contrast: brighter than the last tissue peak
        out.append(("bright", _nice(0.5 * (peaks[-1] + top)), (0.93, 0.89, 0.78)))
    return out


def parse_levels(items: Sequence[str], flag: str = "--levels") -> List[Tuple[str, float, Tuple[float, float, float]]]:
    """``["-500", "bone:300", "skin=-500,fat:-100"]`` → named levels (a bare value is named
    "level"); one-line error naming ``flag`` for anything else."""
    out = []
    for item in items:
        for part in str(item).split(","):
            part = part.strip()
            if not part:
                continue
            name, sep, value = part.replace("=", ":").rpartition(":")
            try:
                v = float(value)
            except ValueError:
                raise AnatomeshError(f"{flag} takes VALUE or NAME:VALUE items, got {part!r}") from None
            if not np.isfinite(v):
                raise AnatomeshError(f"{flag} takes finite values, got {part!r}")
            out.append((name.strip() or "level", v, _colour(len(out))))
    if not out:
        raise AnatomeshError(f"{flag} needs at least one value")
    return out


def gallery(volume: Volume, levels: Optional[Sequence[Tuple[str, float, Sequence[float]]]] = None,
            tile: int = 256, view: str = "anterior", columns: Optional[int] = None,
            progress: Optional[Progress] = None) -> Tuple[np.ndarray, List[dict]]:
    """The contact sheet (H, W, 3) uint8 of the isosurfaces at ``levels`` (default
    :func:`preset_levels`) and, per picture, ``{name, value, faces}``."""
    if volume.is_label_map:
        raise AnatomeshError("the preview gallery shows isosurfaces of scalar scans; a label map's "
                             "labels are listed by `anatomesh inspect`", volume.meta.get("source"))
    levels = list(levels) if levels else preset_levels(volume)
    vol, stride = _preview_volume(volume)
    report(progress, 0.1, "preview: extracting")
    meshes = isosurfaces(vol, [float(v) for _, v, _ in levels], cap=True)
    units = " HU" if looks_like_hounsfield(_sample(volume.data)) else ""
    tiles, info = [], []
    for k, ((name, value, colour), m) in enumerate(zip(levels, meshes)):
        m.color = tuple(colour)[:3]
        picture = render([m], (tile, tile), view)
        tiles.append(_captioned(picture, f"{name} {value:g}{units}",
                                f"{m.n_faces:,} triangles" if m.n_faces else "nothing at this level"))
        info.append({"name": name, "value": float(value), "faces": m.n_faces})
        report(progress, 0.2 + 0.8 * (k + 1) / len(levels), f"preview: {name}")
    cols = columns or min(len(tiles), 4 if len(tiles) > 4 else len(tiles))
    sheet = contact_sheet(tiles, cols, gap=6)
    note = f"{_source(volume)}  {view} view" + (f", previewed on every {_nth(stride)} voxel per axis"
                                                if stride > 1 else "")
    return _with_footer(sheet, note), info


def _preview_volume(volume: Volume):
    stride = 1
    while volume.data.size / stride**3 > PREVIEW_VOXELS:
        stride += 1
    if stride == 1:
        return volume, 1
    affine = np.array(volume.affine)
    affine[:3, :3] *= stride
    return Volume(volume.data[::stride, ::stride, ::stride], affine, volume.space, volume.meta), stride


def _captioned(picture: np.ndarray, title: str, detail: str) -> np.ndarray:
    h, w, _ = picture.shape
    out = np.full((h + CAPTION, w, 3), 255, np.uint8)
    out[:h] = picture
    scale = 2 if text_size(title, 2)[0] <= w - 8 else 1
    draw_text(out, title, 4, h + 3, (20, 20, 20), scale)
    draw_text(out, detail, 4, h + 5 + 7 * scale, (110, 110, 110), 1)
    return out


def _with_footer(sheet: np.ndarray, note: str) -> np.ndarray:
    out = np.full((sheet.shape[0] + 14, sheet.shape[1], 3), 255, np.uint8)
    out[:sheet.shape[0]] = sheet
    draw_text(out, note[: max(1, (sheet.shape[1] - 8) // 6)], 6, sheet.shape[0] + 2, (90, 90, 90), 1)
    return out


def _nice(v: float) -> float:
    """A level rounded for people: whole numbers from 100 up, else 3 significant digits."""
    v = float(v)
    return float(round(v)) if abs(v) >= 100 else float(f"{v:.3g}")


def _nth(n: int) -> str:
    return f"{n}{'nd' if n == 2 else 'rd' if n == 3 else 'th'}"


def _source(volume: Volume) -> str:
    src = volume.meta.get("source") or ""
    if isinstance(src, (list, tuple)):
        src = src[0] if src else ""
    return str(src).rstrip("/").rsplit("/", 1)[-1] or "scan"


def _sample(data: np.ndarray) -> np.ndarray:
    flat = np.ravel(np.asarray(data), order="K")  # no copy for C or Fortran order
    return flat[:: max(1, flat.size // 2_000_000)]


def _colour(k: int) -> Tuple[float, float, float]:
    palette = ((0.92, 0.74, 0.62), (0.93, 0.89, 0.78), (0.8, 0.45, 0.4), (0.6, 0.7, 0.9), (0.7, 0.85, 0.6))
    return palette[k % len(palette)]
