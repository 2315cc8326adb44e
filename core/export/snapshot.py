"""Small pictures of surfaces without Blender or a GPU: an orthographic software rasteriser (z-buffer,
Lambert shading, one colour per surface) and a PNG writer (zlib only).

For thumbnails and contact sheets (batch summaries, isovalue previews, reports): a few hundred
pixels. Views are anatomical: ``"anterior"`` looks at the patient's front (patient's right on
the image's left, head up), ``"posterior"``, ``"left"``/``"right"`` (the patient's side the
viewer stands at), ``"superior"``/``"inferior"``.
"""
from __future__ import annotations

import struct
import zlib
from pathlib import Path
from typing import Sequence, Tuple

import numpy as np

from ..model.errors import AnatomeshError
from ..model.mesh import Mesh
from ..model.volume import space_flip
from . import _snapshot_kernels as _k
from .common import atomic_write

#: view → (screen-right, screen-up, toward-the-viewer) unit axes in RAS
VIEWS = {
    "anterior": ((1, 0, 0), (0, 0, 1), (0, 1, 0)),
    "posterior": ((-1, 0, 0), (0, 0, 1), (0, -1, 0)),
    "left": ((0, 1, 0), (0, 0, 1), (-1, 0, 0)),
    "right": ((0, -1, 0), (0, 0, 1), (1, 0, 0)),
    "superior": ((1, 0, 0), (0, 1, 0), (0, 0, 1)),
    "inferior": ((1, 0, 0), (0, -1, 0), (0, 0, -1)),
}
_LIGHT = np.array([0.3, 0.5, 1.0]) / np.linalg.norm([0.3, 0.5, 1.0])  # in screen axes


def render(meshes: Sequence[Mesh], size: Tuple[int, int] = (256, 256), view: str = "anterior",
           background=(1.0, 1.0, 1.0), margin: float = 0.05) -> np.ndarray:
    """An (H, W, 3) uint8 picture of ``meshes`` (vertices mm, each in its own ``space``), framed
    to fit with ``margin`` (fraction of the picture) on every side; colours are the meshes'
    sRGB ``color``, shaded by the angle of each face to a light over the viewer's shoulder."""
    if view not in VIEWS:
        raise AnatomeshError(f"unknown view {view!r}; use one of {', '.join(VIEWS)}")
    w, h = int(size[0]), int(size[1])
    if w < 8 or h < 8:
        raise AnatomeshError(f"a picture needs at least 8x8 pixels, got {w}x{h}")
    axes = np.asarray(VIEWS[view], np.float64)
    pts, faces, colours = _gather(meshes, axes)
    image = np.empty((h, w, 3), np.float32)
    image[:] = np.asarray(background, np.float32)
    if len(faces) == 0:
        return (image * 255).round().astype(np.uint8)
    lo, hi = pts[:, :2].min(0), pts[:, :2].max(0)
    scale = (1 - 2 * margin) * min(w / max(hi[0] - lo[0], 1e-9), h / max(hi[1] - lo[1], 1e-9))
    centre = 0.5 * (lo + hi)
    px = np.empty_like(pts)
    px[:, 0] = (pts[:, 0] - centre[0]) * scale + 0.5 * w
    px[:, 1] = 0.5 * h - (pts[:, 1] - centre[1]) * scale
    px[:, 2] = pts[:, 2]
    depth = np.full((h, w), -np.inf)
    _k.rasterise(px, faces, colours, _LIGHT, depth, image)
    return (np.clip(image, 0, 1) * 255).round().astype(np.uint8)


def _gather(meshes: Sequence[Mesh], axes: np.ndarray):
    """All meshes' vertices in screen axes (RAS first), stacked faces, and a colour per face."""
    pts, faces, colours, offset = [], [], [], 0
    for m in meshes:
        if not m.n_faces:
            continue
        v = np.asarray(m.vertices, np.float64) @ space_flip(m.space, "RAS")[:3, :3].T
        pts.append(v @ axes.T)
        faces.append(m.faces.astype(np.int64) + offset)
        colours.append(np.tile(np.asarray(m.color[:3], np.float32), (m.n_faces, 1)))
        offset += m.n_vertices
    if not faces:
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros((0, 3), np.float32)
    return np.concatenate(pts), np.concatenate(faces), np.concatenate(colours)


def write_png(image: np.ndarray, path) -> Path:
    """Write an (H, W, 3) or (H, W, 4) uint8 picture as a PNG (W3C PNG specification, 2003:
    8-bit truecolour, filter 0, one zlib stream). Returns the path."""
    a = np.ascontiguousarray(image)
    if a.dtype != np.uint8 or a.ndim != 3 or a.shape[2] not in (3, 4):
        raise AnatomeshError(f"a PNG picture must be (H, W, 3|4) uint8, got {a.shape} {a.dtype}")
    h, w, c = a.shape
    raw = np.concatenate([np.zeros((h, 1), np.uint8), a.reshape(h, w * c)], axis=1).tobytes()

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    header = struct.pack(">IIBBBBB", w, h, 8, 2 if c == 3 else 6, 0, 0, 0)
    path = Path(path)
    with atomic_write(path) as fh:
        fh.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(raw, 6))
                 + chunk(b"IEND", b""))
    return path


def contact_sheet(pictures: Sequence[np.ndarray], columns: int, gap: int = 4,
                  background=(255, 255, 255)) -> np.ndarray:
    """Pictures of one size side by side, ``columns`` per row, ``gap`` pixels apart."""
    if not pictures:
        raise AnatomeshError("a contact sheet needs at least one picture")
    h, w, c = pictures[0].shape
    rows = (len(pictures) + columns - 1) // columns
    sheet = np.empty((rows * h + (rows + 1) * gap, columns * w + (columns + 1) * gap, c), np.uint8)
    sheet[:] = np.asarray(background, np.uint8)[:c]
    for i, p in enumerate(pictures):
        r, q = divmod(i, columns)
        y, x = gap + r * (h + gap), gap + q * (w + gap)
        sheet[y:y + h, x:x + w] = p
    return sheet
