"""The web page's model data: surfaces quantised, compressed with meshoptimizer, packed per level.

Each surface of each level of detail becomes three byte strings, encoded with meshoptimizer's
codecs (Kapoulkine, *meshoptimizer*, MIT; the Python binding ``meshopt`` vendors its sources, the
page decodes with the same release's JavaScript decoder):

* positions: the display frame (glTF's axes: +x patient left, +y superior, +z anterior, see
  :data:`anatomesh.core.export.gltf.AXES`) in mm, quantised to a grid of ``step`` mm (1/16 mm by
  default, so every vertex moves at most step/2 per axis) from a page-wide ``origin``, as uint16
  x, y, z, 0 per vertex, vertex codec;
* triangles: reordered for the vertex cache and for size (meshoptimizer's ``optimizeVertexCache``
  in strip order + ``optimizeVertexFetch``), index codec;
* vertex colours (distance maps), when the mesh has them: sRGB uint8 r, g, b, 255, vertex codec.

Identical byte strings are stored once: a record's id is a hash of its content, so the structures
several models (resection variants) share cost nothing the second time. A level's records are
concatenated and deflated (zlib): the codecs leave byte patterns that a general compressor still
shrinks by a quarter. The deflated bytes travel as Z85 text (ZeroMQ RFC 32/Z85: 4 bytes in 5
printable characters, none of them a quote or a backslash), a quarter more than the bytes where
base64 costs a third.
"""
from __future__ import annotations

import hashlib
import zlib
from dataclasses import dataclass, field
from typing import Dict, List

import numpy as np

from ...core.export.gltf import AXES
from ...core.model.errors import AnatomeshError
from ...core.model.mesh import Mesh

#: default quantisation grid (mm): at most 1/32 mm per axis from the exact vertex
STEP_MM = 1.0 / 16.0
_MAX_Q = 65535


def meshopt_module():
    """The ``meshopt`` binding of meshoptimizer, or a one-line error saying how to install it."""
    try:
        import meshopt
    except ImportError:
        raise AnatomeshError("the web page needs meshoptimizer's Python binding, meshopt (Python 3.11 "
                             "or newer): pip install meshopt") from None
    return meshopt


@dataclass
class Quantization:
    """Positions stored as ``origin + q * step`` (mm, display frame), q uint16."""

    origin: np.ndarray
    step: float = STEP_MM

    def as_dict(self) -> Dict:
        return {"origin": [float(x) for x in self.origin], "step": float(self.step)}


def display_vertices(m: Mesh) -> np.ndarray:
    """(N, 3) float64 vertices of ``m`` in the page's display frame (mm, glTF's axes)."""
    if m.space not in AXES:
        raise AnatomeshError(f"surface {m.name!r}: unknown space {m.space!r} (RAS or LPS)")
    return np.asarray(m.vertices, np.float64) @ AXES[m.space].T


def quantization_for(meshes: List[Mesh], step: float = STEP_MM) -> Quantization:
    """One grid for every mesh of a page: origin at the lower corner of all vertices, the step
    doubled until the whole extent fits in 16 bits."""
    pts = [display_vertices(m) for m in meshes if m.n_vertices]
    if not pts:
        raise AnatomeshError("no vertices to put on the page")
    lo = np.min([p.min(0) for p in pts], axis=0)
    hi = np.max([p.max(0) for p in pts], axis=0)
    while float(np.max(hi - lo)) / step > _MAX_Q - 1:
        step *= 2.0
    return Quantization(np.floor(lo / step) * step, step)


def encode_mesh(m: Mesh, q: Quantization) -> Dict:
    """``{"v": vertices, "t": triangles, "parts": {"p": bytes, "i": bytes[, "c": bytes]}}`` of one
    surface (unused vertices dropped, order as meshoptimizer prefers)."""
    mo = meshopt_module()
    if m.n_faces == 0:
        raise AnatomeshError(f"surface {m.name!r} has no triangles; leave it out of the page")
    idx, remap, n = mo.reorder_mesh(np.ascontiguousarray(m.faces, np.uint32).ravel(),
                                    triangles=True, optsize=True)
    remap = np.concatenate([remap, np.full(m.n_vertices - len(remap), 0xFFFFFFFF, remap.dtype)])
    used = remap != np.uint32(0xFFFFFFFF)  # (remap covers the vertices up to the last used one)
    new = remap[used].astype(np.int64)
    grid = np.rint((display_vertices(m) - q.origin) / q.step)
    pos = np.zeros((n, 4), np.uint16)
    pos[new, :3] = np.clip(grid[used], 0, _MAX_Q).astype(np.uint16)
    parts = {"p": mo.encode_vertex_buffer_level(pos, 2, 1), "i": mo.encode_index_buffer(idx)}
    if m.vertex_colors is not None:
        rgb = np.full((n, 4), 255, np.uint8)
        rgb[new, :3] = np.rint(np.clip(m.vertex_colors[used, :3], 0, 1) * 255).astype(np.uint8)
        parts["c"] = mo.encode_vertex_buffer_level(rgb, 2, 1)
    return {"v": int(n), "t": int(m.n_faces), "parts": parts}


def content_id(encoded: Dict) -> str:
    """A short hash of an encoded surface (counts and bytes): equal content, equal id."""
    h = hashlib.sha1(f"{encoded['v']},{encoded['t']}".encode())
    for key in sorted(encoded["parts"]):
        h.update(key.encode() + len(encoded["parts"][key]).to_bytes(8, "little") + encoded["parts"][key])
    return h.hexdigest()[:16]


@dataclass
class LevelPack:
    """The records of one level: each distinct surface once, its parts at byte offsets of one
    blob (deflated when written)."""

    records: Dict[str, Dict] = field(default_factory=dict)
    chunks: List[bytes] = field(default_factory=list)
    size: int = 0
    triangles: int = 0

    def add(self, encoded: Dict) -> str:
        """Store ``encoded`` (from :func:`encode_mesh`) unless stored already; returns its id."""
        cid = content_id(encoded)
        if cid not in self.records:
            rec: Dict = {"v": encoded["v"], "t": encoded["t"]}
            for key, data in encoded["parts"].items():
                rec[key] = [self.size, len(data)]
                self.chunks.append(data)
                self.size += len(data)
            self.records[cid] = rec
            self.triangles += encoded["t"]
        return cid

    def deflated(self) -> bytes:
        return zlib.compress(b"".join(self.chunks), 9)


#: Z85's alphabet (ZeroMQ RFC 32): digit values 0..84 in base 85
Z85 = b"0123456789abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ.-:+=^!/*?&<>()[]{}@%$#"


def z85(data: bytes) -> bytes:
    """``data`` as Z85 text: zero bytes pad it to a multiple of 4, then each big-endian 32-bit
    word becomes 5 base-85 digits, most significant first."""
    words = np.frombuffer(data + bytes(-len(data) % 4), ">u4").astype(np.uint64)
    digits = np.empty((len(words), 5), np.uint8)
    for k in range(4, -1, -1):
        digits[:, k] = words % 85
        words //= 85
    return np.frombuffer(Z85, np.uint8)[digits].tobytes()


def level_script(level: int, deflated: bytes) -> bytes:
    """The JavaScript file of one level: ``anatomeshLevel(k, "<Z85>", n);`` with n the bytes the
    text carries before its padding (a classic script, so pages opened from ``file://`` can load
    it; no request is made)."""
    return b"anatomeshLevel(%d,\"%s\",%d);\n" % (level, z85(deflated), len(deflated))


def encoded_level(meshes: List[Mesh], q: Quantization, pack: LevelPack) -> List[str]:
    """Encode ``meshes`` into ``pack``; their ids in order."""
    return [pack.add(encode_mesh(m, q)) for m in meshes]

