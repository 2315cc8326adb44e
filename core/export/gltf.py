"""Binary glTF 2.0 (GLB) writer and reader: the surfaces for viewers, at real size and upright.

Format: Khronos Group, *glTF 2.0 Specification* (2021), GLB container §4.4: a 12-byte header,
a JSON chunk and a BIN chunk, each 4-byte aligned.

What :func:`write_glb` writes:

* one mesh + node per surface, named ``Mesh.name``: ``POSITION`` float32 (with the ``min``/``max``
  the spec requires), ``NORMAL`` float32 unit vectors (``Mesh.normals`` when present, else
  area-weighted vertex normals), indices uint16 when fewer than 65 536 vertices else uint32;
* one PBR material per surface: ``baseColorFactor`` = ``Mesh.color`` (taken as sRGB, as the label
  tables give it) converted to linear light as glTF requires, alpha from an RGBA colour with
  ``alphaMode: "BLEND"`` when it is below 1; metallic 0, roughness 0.5; the node's ``extras``
  hold the label value;
* the vertices stay in mm in the patient space (mesh-local coordinates); all surface nodes hang
  under one root node that scales by 0.001 (glTF's unit is the metre) and rotates the patient
  space (Z = superior) into glTF's frame (+Y up, the front of the model facing +Z, +X to the
  viewer's right):

  ============  ================  ==================  =====================
  glTF axis     meaning           from RAS (x, y, z)  from LPS (x, y, z)
  ============  ================  ==================  =====================
  +X            patient left      −x                  +x
  +Y            superior (up)     +z                  +z
  +Z            anterior (front)  +y                  −y
  ============  ================  ==================  =====================

  (RAS: a 180° turn about (0, 1, 1)/√2; LPS: −90° about X.) Blender's importer turns +Y-up
  back into +Z-up, so the surfaces arrive in LPS, upright, facing the front view, in metres.
* ``asset.extras`` record ``space``, ``units`` and the title.
"""
from __future__ import annotations

import json
import struct
from pathlib import Path
from typing import Dict, List, Sequence

import numpy as np

from .common import atomic_write, check_meshes
from ..model.labels import linear_to_srgb, rgba, srgb_to_linear
from ..model.errors import AnatomeshError
from ..model.mesh import Mesh

_S = 0.7071067811865476
#: root-node rotation (x, y, z, w) taking each patient space to glTF's +Y-up frame (table above)
ROTATION = {"RAS": [0.0, _S, _S, 0.0], "LPS": [-_S, 0.0, 0.0, _S]}
#: the same as 3x3 matrices: glTF = R @ patient
AXES = {"RAS": np.array([[-1, 0, 0], [0, 0, 1], [0, 1, 0]], float),
        "LPS": np.array([[1, 0, 0], [0, 0, 1], [0, -1, 0]], float)}
UNITS = "vertices in mm under a 0.001 root scale"
_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963
_FLOAT, _UINT16, _UINT32, _UINT8 = 5126, 5123, 5125, 5121
_DTYPES = {_FLOAT: "<f4", _UINT32: "<u4", _UINT16: "<u2", _UINT8: "u1"}
_NCOMP = {"SCALAR": 1, "VEC3": 3, "VEC4": 4}


def write_glb(meshes: Sequence[Mesh], path, *, title: str = "") -> Path:
    """Write all ``meshes`` into one binary glTF 2.0 file (see the module doc); returns the path.

    Parameters
    ----------
    meshes : sequence of Mesh
        Surfaces, vertices (N, 3) float32 in mm, faces (M, 3) int32; ``color`` RGB or RGBA 0..1.
        All in one ``space``, ``"RAS"`` or ``"LPS"``.
    path : str or PathLike
        Output ``.glb``; written to ``path + '.part'`` and renamed when complete.
    title : str
        Name of the root node and ``asset.extras.title`` (default: the file name's stem).

    Raises
    ------
    AnatomeshError
        For an empty list, mixed or unknown spaces, a mesh without triangles, NaN/infinite
        vertices, face indices out of range, more than 4 GiB of data, or an unwritable path.
    """

    path = Path(path)
    meshes = check_meshes(meshes, path, "GLB")
    space = meshes[0].space
    title = title or path.stem
    doc: Dict = {
        "asset": {"version": "2.0", "generator": "Anatomesh",
                  "extras": {"space": space, "units": UNITS, "title": title}},
        "scene": 0, "scenes": [{"name": title, "nodes": [0]}],
        "nodes": [{"name": title, "children": list(range(1, len(meshes) + 1)),
                   "rotation": ROTATION[space], "scale": [0.001, 0.001, 0.001]}],
        "meshes": [], "materials": [], "accessors": [], "bufferViews": [], "buffers": []}
    blobs: List[bytes] = []
    offset = 0

    def add(array: np.ndarray, ctype: int, atype: str, target: int, minmax: bool = False) -> int:
        nonlocal offset
        data = np.ascontiguousarray(array, _DTYPES[ctype]).tobytes()
        doc["bufferViews"].append({"buffer": 0, "byteOffset": offset, "byteLength": len(data),
                                   "target": target})
        acc = {"bufferView": len(doc["bufferViews"]) - 1, "componentType": ctype,
               "count": int(len(array)), "type": atype}
        if minmax:
            acc["min"] = [float(x) for x in array.min(axis=0)]
            acc["max"] = [float(x) for x in array.max(axis=0)]
        doc["accessors"].append(acc)
        pad = -len(data) % 4
        blobs.append(data + b"\0" * pad)
        offset += len(data) + pad
        return len(doc["accessors"]) - 1

    for k, m in enumerate(meshes):
        _add_mesh(doc, add, m, k)
    doc["buffers"].append({"byteLength": offset})
    body = json.dumps(doc, separators=(",", ":")).encode("utf-8")
    body += b" " * (-len(body) % 4)
    total = 12 + 8 + len(body) + 8 + offset
    if total >= 2 ** 32:
        raise AnatomeshError("the surfaces need more than 4 GiB, the GLB limit; decimate them or "
                             "export fewer", path)
    with atomic_write(path) as fh:
        fh.write(struct.pack("<4sII", b"glTF", 2, total))
        fh.write(struct.pack("<I4s", len(body), b"JSON"))
        fh.write(body)
        fh.write(struct.pack("<I4s", offset, b"BIN\0"))
        for b in blobs:
            fh.write(b)
    return path


def _add_mesh(doc: Dict, add, m: Mesh, k: int) -> None:
    """Mesh ``k`` as a glTF mesh (positions, normals, colours when given, indices), its material
    and its node; ``add(array, component type, type, target)`` stores an accessor."""
    attrs = {"POSITION": add(m.vertices, _FLOAT, "VEC3", _ARRAY_BUFFER, minmax=True),
             "NORMAL": add(_unit_normals(m), _FLOAT, "VEC3", _ARRAY_BUFFER)}
    if m.vertex_colors is not None:  # glTF's COLOR_0 is linear; it multiplies the base colour
        c = m.vertex_colors
        lin = np.concatenate([srgb_to_linear(c[:, :3]), c[:, 3:]], axis=1)
        attrs["COLOR_0"] = add(lin, _FLOAT, "VEC4" if c.shape[1] == 4 else "VEC3", _ARRAY_BUFFER)
    small = m.n_vertices < 65536
    idx = add(m.faces.ravel(), _UINT16 if small else _UINT32, "SCALAR", _ELEMENT_ARRAY_BUFFER)
    doc["meshes"].append({"name": m.name or f"surface_{k + 1}", "primitives": [
        {"attributes": attrs, "indices": idx, "material": k, "mode": 4}]})
    doc["materials"].append(_material(m, k))
    node = {"name": m.name or f"surface_{k + 1}", "mesh": k}
    if m.value is not None:
        node["extras"] = {"anatomesh_value": m.value, "anatomesh_space": m.space}
    doc["nodes"].append(node)


def _unit_normals(m: Mesh) -> np.ndarray:
    """(N, 3) float32 unit normals: ``m.normals`` normalised, else area-weighted vertex normals;
    zero normals (unused or degenerate vertices) become +Z so every one is a unit vector."""
    if m.normals is not None and len(m.normals) == m.n_vertices:
        n = m.normals.astype(np.float64)
    else:
        from ..model.mesh import vertex_normals

        n = vertex_normals(m.vertices, m.faces)
    ln = np.linalg.norm(n, axis=1, keepdims=True)
    ok = (ln[:, 0] > 1e-12) & np.isfinite(ln[:, 0])
    n = np.where(ok[:, None], n / np.where(ok[:, None], ln, 1.0), [0.0, 0.0, 1.0])
    return n.astype(np.float32)


def _material(m: Mesh, k: int) -> Dict:
    r, g, b, a = rgba(m.color)
    lin = [float(x) for x in srgb_to_linear([r, g, b])] if m.vertex_colors is None else [1.0, 1.0, 1.0]
    mat = {"name": m.name or f"surface_{k + 1}",
           "pbrMetallicRoughness": {"baseColorFactor": lin + [a], "metallicFactor": 0.0,
                                    "roughnessFactor": 0.5}}
    if a < 1.0:
        mat["alphaMode"] = "BLEND"
    return mat


# ---------------------------------------------------------------------------------------------
# reading (our own files: the mesh-local coordinates, no node transforms applied)
# ---------------------------------------------------------------------------------------------
def read_glb(path) -> List[Mesh]:
    """The surfaces of a GLB written by :func:`write_glb`: one :class:`Mesh` per node with a mesh.

    Vertices are the mesh-local coordinates (mm in the patient space for our files; no node
    transform is applied), faces from the indices, normals, the colour back in sRGB (RGBA when
    the material is translucent), ``space`` and ``value`` from the extras.

    Raises
    ------
    AnatomeshError
        When the file is not a GLB 2.0 or uses what this reader does not handle (non-triangle
        primitives, sparse or strided accessors, external buffers).
    """
    path = Path(path)
    try:
        raw = Path(path).read_bytes()
    except OSError as exc:
        raise AnatomeshError(f"cannot read the file ({exc.strerror})", path) from None
    try:
        doc, binary = _chunks(raw)
        space = (doc.get("asset", {}).get("extras") or {}).get("space", "RAS")
        out = []
        for node in doc.get("nodes", []):
            if "mesh" not in node:
                continue
            out.append(_node_mesh(doc, binary, node, space))
        return out
    except (ValueError, KeyError, IndexError, TypeError, struct.error) as exc:
        raise AnatomeshError(f"cannot read this GLB ({exc}); only GLB 2.0 with triangle meshes "
                             f"is supported", path) from None


def _chunks(raw: bytes):
    magic, version, length = struct.unpack_from("<4sII", raw, 0)
    if magic != b"glTF" or version != 2:
        raise ValueError("not a binary glTF 2.0 file")
    pos, doc, binary = 12, None, b""
    while pos + 8 <= min(length, len(raw)):
        n, kind = struct.unpack_from("<I4s", raw, pos)
        data = raw[pos + 8:pos + 8 + n]
        if kind == b"JSON":
            doc = json.loads(data.decode("utf-8"))
        elif kind == b"BIN\0":
            binary = data
        pos += 8 + n
    if doc is None:
        raise ValueError("no JSON chunk")
    return doc, binary


def _accessor(doc: Dict, binary: bytes, index: int) -> np.ndarray:
    acc = doc["accessors"][index]
    view = doc["bufferViews"][acc["bufferView"]]
    if view.get("buffer", 0) != 0 or "sparse" in acc:
        raise ValueError("external buffers and sparse accessors are not supported")
    dtype = np.dtype(_DTYPES[acc["componentType"]])
    ncomp = _NCOMP[acc["type"]]
    if view.get("byteStride", dtype.itemsize * ncomp) != dtype.itemsize * ncomp:
        raise ValueError("interleaved (strided) buffer views are not supported")
    start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    a = np.frombuffer(binary, dtype, acc["count"] * ncomp, start)
    return a.reshape(-1, ncomp) if ncomp > 1 else a


def _node_mesh(doc: Dict, binary: bytes, node: Dict, space: str) -> Mesh:
    gm = doc["meshes"][node["mesh"]]
    vs, fs, ns, cs, n, color = [], [], [], [], 0, (0.8, 0.8, 0.8)
    for k, prim in enumerate(gm["primitives"]):
        if prim.get("mode", 4) != 4:
            raise ValueError("only triangle primitives (mode 4) are supported")
        v = _accessor(doc, binary, prim["attributes"]["POSITION"])
        f = (_accessor(doc, binary, prim["indices"]).astype(np.int64) if "indices" in prim
             else np.arange(len(v), dtype=np.int64))
        vs.append(v)
        fs.append(f.reshape(-1, 3) + n)
        if "NORMAL" in prim["attributes"]:
            ns.append(_accessor(doc, binary, prim["attributes"]["NORMAL"]))
        if "COLOR_0" in prim["attributes"]:
            c = _accessor(doc, binary, prim["attributes"]["COLOR_0"]).astype(np.float64)
            cs.append(np.concatenate([linear_to_srgb(c[:, :3]), c[:, 3:]], axis=1))
        n += len(v)
        if k == 0 and "material" in prim:
            color = _color(doc["materials"][prim["material"]])
    extras = node.get("extras") or {}
    normals = np.concatenate(ns) if len(ns) == len(vs) else None
    colors = np.concatenate(cs) if len(cs) == len(vs) else None
    return Mesh(np.concatenate(vs), np.concatenate(fs), normals=normals,
                name=node.get("name") or gm.get("name", ""), value=extras.get("anatomesh_value"),
                color=color, space=str(extras.get("anatomesh_space", space)), vertex_colors=colors)


def _color(material: Dict):
    f = material.get("pbrMetallicRoughness", {}).get("baseColorFactor", [1.0, 1.0, 1.0, 1.0])
    rgb = tuple(float(x) for x in linear_to_srgb(f[:3]))
    return rgb + (float(f[3]),) if len(f) > 3 and f[3] < 1.0 else rgb
