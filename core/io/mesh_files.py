"""Reading mesh files back: STL (binary and ASCII), PLY (ASCII and binary), OBJ → :class:`Mesh`.

Used by ``anatomesh check`` to check meshes written by Anatomesh or any other tool. STL stores
every triangle with its own three corners: corners at exactly the same position are merged into
one vertex (what every slicer does), so a watertight STL reads back as a closed indexed mesh.
The coordinate space is taken from a ``SPACE=RAS|LPS`` tag in the header or comments (Anatomesh
and 3D Slicer write one), else ``RAS``. Units are assumed to be mm.
"""
from __future__ import annotations

import re
from pathlib import Path
from typing import Dict, List, Tuple

import numpy as np

from ..model.errors import AnatomeshError
from ..model.mesh import Mesh
from .library_messages import reason

MESH_SUFFIXES = (".stl", ".ply", ".obj")
_SPACE = re.compile(rb"SPACE=(RAS|LPS)")


def weld(points: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Merge points at exactly the same position: (unique (U, 3), index (P,) into unique)."""
    p = np.ascontiguousarray(points, np.float32).reshape(-1, 3)
    if p.shape[0] == 0:
        return np.zeros((0, 3), np.float32), np.zeros(0, np.int64)
    u, inv = np.unique(p, axis=0, return_inverse=True)
    return u, inv.ravel()


def split_nonmanifold(vertices: np.ndarray, faces: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Undo position welding where it glued separate sheets: one vertex per fan of faces.

    A closed solid touching itself along an edge or at a point (voxel shells do) has, once its
    corners are merged by position, edges with four faces and pinch vertices. Each half-edge
    a→b is paired with an opposite half-edge b→a: the only one on a 2-face edge; on a 4-face
    edge the one face already in the same fans as a→b's face at both a and b (fans linked
    through 2-face edges), else — faces alternating in orientation around the edge — the face
    met first when turning from a→b's face into its solid, else (sheets crossing near the edge,
    e.g. after smoothing) the one face sharing a fan at a or b. Corners linked through paired
    half-edges form the fans; each fan gets its own vertex (same position). Returns (vertices (N', 3), faces (M, 3) int32).
    """
    from ..geometry.topology import directed_edges

    v = np.asarray(vertices)
    f = np.asarray(faces, np.int64)
    m = f.shape[0]
    if m == 0:
        return v, f.astype(np.int32)
    he = directed_edges(f)  # row 3*face + k: f[k] -> f[k+1]
    n = np.int64(max(len(v), 1))
    lo, hi = np.minimum(he[:, 0], he[:, 1]), np.maximum(he[:, 0], he[:, 1])
    key = lo * n + hi
    order = np.argsort(key, kind="stable")
    ks = key[order]
    starts = np.flatnonzero(np.r_[True, ks[1:] != ks[:-1]])
    counts = np.diff(np.r_[starts, ks.size])
    mate = np.full(3 * m, -1, np.int64)
    two = starts[counts == 2]
    a, b = order[two], order[two + 1]
    opp = he[a, 0] == he[b, 1]
    mate[a[opp]], mate[b[opp]] = b[opp], a[opp]
    # fans so far (through 2-face edges only): faces of one original sheet around a vertex are
    # usually linked already, which tells how to pair the faces at a 4-face edge
    pre = _corner_roots(mate, m)
    vv = np.asarray(v, np.float64)
    for s, c in zip(starts[counts > 2], counts[counts > 2]):
        hs = order[s:s + c]
        fwd = he[hs, 0] == he[hs[0], 0]
        # 1. the face sharing its fans at both ends with a->b's face (its own sheet; fans so far
        #    are linked through 2-face edges only)
        at_a = np.where(fwd, hs, 3 * (hs // 3) + (hs % 3 + 1) % 3)
        at_b = np.where(fwd, 3 * (hs // 3) + (hs % 3 + 1) % 3, hs)
        _pair_by_fans(hs, fwd, at_a, at_b, pre, mate, need=2)
        if np.all(mate[hs] >= 0):
            continue
        # 2. faces alternating around the edge: the face met first turning into the solid
        p0, p1 = vv[he[hs[0], 0]], vv[he[hs[0], 1]]
        e = p1 - p0
        e /= max(np.linalg.norm(e), 1e-300)
        u = np.cross(e, [1.0, 0, 0] if abs(e[0]) < 0.9 else [0, 1.0, 0])
        u /= np.linalg.norm(u)
        w = np.cross(e, u)
        third = vv[f[hs // 3, (hs % 3 + 2) % 3]] - p0
        ang = np.arctan2(third @ w, third @ u)
        around = fwd[np.argsort(ang)]
        if np.all(around != np.roll(around, 1)):
            sign = np.where(fwd, 1.0, -1.0)
            for i in np.flatnonzero(fwd & (mate[hs] < 0)):
                cand = np.flatnonzero(~fwd & (mate[hs] < 0))
                d = np.mod(sign[i] * (ang[i] - ang[cand]), 2 * np.pi)
                j = cand[np.argmin(np.where(d > 0, d, 2 * np.pi))]
                mate[hs[i]], mate[hs[j]] = hs[j], hs[i]
            continue
        # 3. sheets crossing near the edge: the face sharing a fan at one end; then any
        _pair_by_fans(hs, fwd, at_a, at_b, pre, mate, need=1)
        left_f = [h for h in hs[fwd] if mate[h] < 0]
        left_b = [h for h in hs[~fwd] if mate[h] < 0]
        for a_, b_ in zip(left_f, left_b):
            mate[a_], mate[b_] = b_, a_
    uniq, new = np.unique(_corner_roots(mate, m), return_inverse=True)
    nv = v[f.ravel()[uniq]]
    return nv, new.reshape(-1, 3).astype(np.int32)


def _pair_by_fans(hs, fwd, at_a, at_b, pre, mate, need: int) -> None:
    """Pair each open a->b half-edge of ``hs`` with the one open b->a half-edge whose face shares
    ``need`` or more of its fans (at a, at b) — if exactly one does."""
    for i in np.flatnonzero(fwd & (mate[hs] < 0)):
        cand = np.flatnonzero(~fwd & (mate[hs] < 0))
        score = (pre[at_a[cand]] == pre[at_a[i]]).astype(int) + (pre[at_b[cand]] == pre[at_b[i]])
        if cand.size and score.max() >= need and np.sum(score == score.max()) == 1:
            j = cand[np.argmax(score)]
            mate[hs[i]], mate[hs[j]] = hs[j], hs[i]


def _corner_roots(mate: np.ndarray, m: int) -> np.ndarray:
    """Fan id (3M,) of each corner: corner (face, k) sits at f[face, k] and its outgoing
    half-edge is row 3*face + k; the mate b->a of a->b ends at a, in its face at corner
    (row + 1) % 3. (A corner's incoming half-edge links it too: its mate's corner links back.)"""
    from ..geometry.kernels import union_find_roots

    rows = np.flatnonzero(mate >= 0)
    mr = mate[rows]
    other = 3 * (mr // 3) + (mr % 3 + 1) % 3
    return union_find_roots(rows.astype(np.int64), other.astype(np.int64), 3 * m)


def read_mesh(path) -> Mesh:
    """One mesh from an STL, PLY or OBJ file (vertices float32 mm, faces int32).

    The name is the file's stem; raises :class:`AnatomeshError` for an unknown suffix, a
    missing file or a file that cannot be parsed."""
    path = Path(path)
    suffix = path.suffix.lower()
    reader = {".stl": _read_stl, ".ply": _read_ply, ".obj": _read_obj}.get(suffix)
    if reader is None:
        raise AnatomeshError(f"not a mesh file ({suffix or 'no suffix'}): give .stl, .ply, .obj "
                             f"or .3mf files, or a folder written by `anatomesh mesh`", path)
    if not path.is_file():
        raise AnatomeshError("file not found: check the path", path)
    data = path.read_bytes()
    try:
        v, f, space = reader(data)
    except AnatomeshError as err:
        raise AnatomeshError(str(err), path) from None
    except (ValueError, IndexError, KeyError, UnicodeDecodeError) as exc:
        raise AnatomeshError(f"cannot parse this {suffix[1:].upper()} file ({reason(exc)}); "
                             f"re-export it from the tool that made it", path) from None
    if f.size and (f.min() < 0 or f.max() >= len(v)):
        raise AnatomeshError("faces refer to vertices the file does not have: the file is corrupt; "
                             "export it again", path)
    if not np.all(np.isfinite(v)):
        raise AnatomeshError("the file has NaN or infinite coordinates: it is corrupt; export it again", path)
    return Mesh(v, f, name=path.stem, space=space, meta={"path": str(path)})


def _space(data: bytes) -> str:
    m = _SPACE.search(data[:4096])
    return m.group(1).decode() if m else "RAS"


# ---------------------------------------------------------------------------------------------
# STL
# ---------------------------------------------------------------------------------------------
def _read_stl(data: bytes):
    if len(data) >= 84:
        n = int(np.frombuffer(data[80:84], "<u4")[0])
        if len(data) == 84 + 50 * n:
            rec = np.frombuffer(data[84:], dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)),
                                                 ("a", "<u2")])
            v, idx = weld(rec["v"].reshape(-1, 3))
            v, f = split_nonmanifold(v, idx.reshape(-1, 3))
            return v, f, _space(data[:80])
    head = data[:512].lstrip().lower()
    if not head.startswith(b"solid"):
        raise AnatomeshError("not an STL file (binary size does not match its triangle count and "
                             "it does not start with 'solid')")
    nums = re.findall(rb"vertex\s+(\S+)\s+(\S+)\s+(\S+)", data)
    if len(nums) % 3:
        raise AnatomeshError("ASCII STL with a facet that has no three vertices: the file is cut off; "
                             "export it again")
    pts = np.array(nums, dtype=np.float64).reshape(-1, 3)
    v, idx = weld(pts)
    v, f = split_nonmanifold(v, idx.reshape(-1, 3))
    return v, f, _space(data[:4096])


# ---------------------------------------------------------------------------------------------
# PLY
# ---------------------------------------------------------------------------------------------
_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2",
              "int16": "i2", "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4",
              "uint": "u4", "uint32": "u4", "float": "f4", "float32": "f4", "double": "f8",
              "float64": "f8"}


def _read_ply(data: bytes):
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        raise AnatomeshError("not a PLY file (no 'ply' magic or no 'end_header'); export it again "
                             "as PLY")
    nl = data.find(b"\n", end)
    header = data[:nl].decode("ascii", "replace").splitlines()
    body = data[nl + 1:]
    fmt = "ascii"
    elements = []  # [name, count, [(prop name, type, list count type or None)]]
    for line in header:
        w = line.split()
        if not w:
            continue
        if w[0] == "format":
            fmt = w[1]
        elif w[0] == "element":
            elements.append([w[1], int(w[2]), []])
        elif w[0] == "property" and elements:
            if w[1] == "list":
                elements[-1][2].append((w[4], _PLY_TYPES[w[3]], _PLY_TYPES[w[2]]))
            else:
                elements[-1][2].append((w[2], _PLY_TYPES[w[1]], None))
    if fmt == "ascii":
        v, f = _ply_ascii(body, elements)
    else:
        v, f = _ply_binary(body, elements, "<" if fmt == "binary_little_endian" else ">")
    return v, f, _space(data[:nl])


def _ply_ascii(body: bytes, elements):
    lines = iter(body.decode("ascii").splitlines())
    v = np.zeros((0, 3))
    faces = []
    for name, count, props in elements:
        rows = [next(lines).split() for _ in range(count)]
        if name == "vertex":
            names = [p[0] for p in props]
            cols = [names.index(c) for c in ("x", "y", "z")]
            v = np.array([[float(r[c]) for c in cols] for r in rows]).reshape(-1, 3)
        elif name == "face":
            for r in rows:
                k = int(r[0])
                faces.extend(_fan([int(x) for x in r[1:1 + k]]))
    return v, np.array(faces, np.int64).reshape(-1, 3).astype(np.int32)


def _ply_binary(body: bytes, elements, order: str):
    pos = 0
    v = np.zeros((0, 3))
    f = np.zeros((0, 3), np.int32)
    for name, count, props in elements:
        if all(p[2] is None for p in props):
            dt = np.dtype([(p[0], order + p[1]) for p in props])
            arr = np.frombuffer(body, dt, count, pos)
            pos += dt.itemsize * count
            if name == "vertex":
                v = np.stack([arr["x"], arr["y"], arr["z"]], 1).astype(np.float64)
            continue
        if len(props) == 1 and name == "face":  # the common case: one list property
            _, it, ct = props[0]
            cdt, idt = np.dtype(order + ct), np.dtype(order + it)
            # fast path: all triangles
            rec = np.dtype([("n", cdt), ("i", idt, 3)])
            if count and pos + rec.itemsize * count <= len(body):
                arr = np.frombuffer(body, rec, count, pos)
                if np.all(arr["n"] == 3):
                    f = arr["i"].astype(np.int32)
                    pos += rec.itemsize * count
                    continue
        tris = []
        for _ in range(count):  # general case: polygons and extra properties, element by element
            poly = None
            for pname, it, ct in props:
                if ct is None:
                    pos += np.dtype(it).itemsize
                    continue
                k = int(np.frombuffer(body, order + ct, 1, pos)[0])
                pos += np.dtype(ct).itemsize
                vals = np.frombuffer(body, order + it, k, pos)
                pos += np.dtype(it).itemsize * k
                if pname in ("vertex_indices", "vertex_index"):
                    poly = [int(x) for x in vals]
            if name == "face" and poly is not None:
                tris.extend(_fan(poly))
        if name == "face":
            f = np.array(tris, np.int64).reshape(-1, 3).astype(np.int32)
    return v, f


def _fan(poly: List[int]) -> List[Tuple[int, int, int]]:
    return [(poly[0], poly[i], poly[i + 1]) for i in range(1, len(poly) - 1)]


# ---------------------------------------------------------------------------------------------
# OBJ
# ---------------------------------------------------------------------------------------------
def _read_obj(data: bytes):
    verts, faces = [], []
    for line in data.decode("utf-8", "replace").splitlines():
        if line.startswith("v "):
            verts.append([float(x) for x in line.split()[1:4]])
        elif line.startswith("f "):
            idx = []
            for tok in line.split()[1:]:
                i = int(tok.split("/")[0])
                idx.append(i - 1 if i > 0 else len(verts) + i)  # 1-based or negative (relative)
            faces.extend(_fan(idx))
    v = np.array(verts, np.float64).reshape(-1, 3)
    return v, np.array(faces, np.int64).reshape(-1, 3).astype(np.int32), _space(data[:4096])


def read_stl(path) -> Dict:
    """Read a binary STL written by any tool: ``{"header": bytes, "triangles": (M,3,3) float32}``."""
    data = Path(path).read_bytes()
    n = int(np.frombuffer(data[80:84], "<u4")[0])
    rec = np.frombuffer(data[84:84 + 50 * n], dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    return {"header": data[:80], "triangles": rec["v"].copy()}
