"""numpy ↔ Blender meshes, fast: the attribute API with ``foreach_set`` / ``foreach_get``.

Creating a mesh writes the arrays straight into Blender's attribute storage (positions, corner
vertices, face offsets) and lets Blender derive the edges once (``mesh.update(calc_edges=True)``);
``Mesh.from_pydata`` goes through Python lists and is several times slower on large meshes
(``benchmarks/bench_blender_bridge.py``). Moving vertices (the live smoothing slider) rewrites only
the ``position`` attribute.

Units: one Blender unit is one millimetre (see :func:`anatomesh.addon.scene.objects.setup_units`), so the
arrays go in and come out unchanged, in mm, in the space recorded on the object.

Only ``bpy``, numpy and the switch of the drawn gap (:mod:`.render_gap`) here; nothing in ``core``
is imported, so the bridge works on any arrays.
"""
from __future__ import annotations

from typing import List, Optional, Tuple

import bpy
import numpy as np

from .render_gap import left_out

#: name of the per-vertex attribute holding the unsmoothed positions (float vector, mm)
REST_ATTRIBUTE = "anatomesh_rest"
#: name of the per-vertex attribute holding each vertex's index in the shared surface set (int)
SHARED_INDEX_ATTRIBUTE = "anatomesh_vid"


def new_mesh(name: str, vertices: np.ndarray, faces: np.ndarray) -> bpy.types.Mesh:
    """A new Blender mesh datablock from triangles.

    Parameters
    ----------
    name : str
        Datablock name (Blender appends ``.001`` if it is taken).
    vertices : array (N, 3), float
        Positions in mm (= Blender units).
    faces : array (M, 3), int
        Triangles as vertex indices, counter-clockwise seen from outside.

    Returns
    -------
    bpy.types.Mesh
        With N vertices, M triangles and the edges Blender derived from them; not validated
        (the arrays come from core, whose invariants are tested there).
    """
    me = bpy.data.meshes.new(name)
    set_geometry(me, vertices, faces)
    return me


def set_geometry(me: bpy.types.Mesh, vertices: np.ndarray, faces: np.ndarray,
                 edges: Optional[Tuple[np.ndarray, np.ndarray]] = None) -> None:
    """Replace a mesh's geometry with triangles in place through the attribute API (materials
    and the datablock stay): ``vertices`` (N, 3) mm, ``faces`` (M, 3) int. ``edges``: the
    unique edges (E, 2) and each corner's edge (3M,) when the caller has them
    (:func:`anatomesh.core.extract.edges.unique_edges`, linear time); else Blender derives them
    (``calc_edges``)."""
    v = np.ascontiguousarray(vertices, dtype=np.float32).reshape(-1, 3)
    f = np.ascontiguousarray(faces, dtype=np.int32).reshape(-1, 3)
    if f.size and (int(f.min()) < 0 or int(f.max()) >= len(v)):
        raise ValueError(f"face indices out of range for {len(v)} vertices")
    if len(me.vertices):
        me.clear_geometry()
    me.vertices.add(len(v))
    if edges is not None:
        me.edges.add(len(edges[0]))
    me.loops.add(f.size)
    me.polygons.add(len(f))
    if len(v):
        me.attributes["position"].data.foreach_set("vector", v.ravel())
    if len(f):
        if edges is not None:
            me.attributes[".edge_verts"].data.foreach_set("value", np.ascontiguousarray(edges[0], np.int32).ravel())
            me.attributes[".corner_edge"].data.foreach_set("value", np.ascontiguousarray(edges[1], np.int32))
        me.attributes[".corner_vert"].data.foreach_set("value", f.ravel())
        me.polygons.foreach_set("loop_start", np.arange(0, f.size, 3, dtype=np.int32))
    me.update(calc_edges=edges is None)


def set_positions(mesh: bpy.types.Mesh, vertices: np.ndarray) -> None:
    """Overwrite the vertex positions (N, 3) mm in place; topology is unchanged."""
    v = np.ascontiguousarray(vertices, dtype=np.float32).reshape(-1, 3)
    if len(v) != len(mesh.vertices):
        raise ValueError(f"{mesh.name}: got {len(v)} positions for {len(mesh.vertices)} vertices")
    mesh.attributes["position"].data.foreach_set("vector", v.ravel())
    mesh.update()


def positions(mesh: bpy.types.Mesh) -> np.ndarray:
    """Vertex positions as float32 (N, 3), in the mesh's own (object) coordinates."""
    out = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    if out.size:
        mesh.attributes["position"].data.foreach_get("vector", out)
    return out.reshape(-1, 3)


def triangles(mesh: bpy.types.Mesh) -> np.ndarray:
    """Faces as int32 (M, 3); polygons with more than three corners are split into fans.

    Fan splitting is exact for the convex polygons Blender's tools make; meshes from core are
    triangles already and come back unchanged (same order).
    """
    n_loops = len(mesh.loops)
    n_polys = len(mesh.polygons)
    corner = np.empty(n_loops, dtype=np.int32)
    if n_loops:
        mesh.attributes[".corner_vert"].data.foreach_get("value", corner)
    start = np.empty(n_polys, dtype=np.int32)
    total = np.empty(n_polys, dtype=np.int32)
    if n_polys:
        mesh.polygons.foreach_get("loop_start", start)
        mesh.polygons.foreach_get("loop_total", total)
    if n_polys and np.all(total == 3):
        return corner.reshape(-1, 3)
    # fan: polygon p with n corners gives triangles (c0, c_k, c_k+1), k = 1 .. n-2
    ntri = np.maximum(total - 2, 0)
    poly = np.repeat(np.arange(n_polys), ntri)
    k = np.arange(ntri.sum()) - np.repeat(np.cumsum(ntri) - ntri, ntri) + 1
    s = start[poly]
    return np.stack([corner[s], corner[s + k], corner[s + k + 1]], axis=1).astype(np.int32)


def arrays(mesh: bpy.types.Mesh) -> Tuple[np.ndarray, np.ndarray]:
    """``(vertices (N, 3) float32, faces (M, 3) int32)`` of a Blender mesh."""
    return positions(mesh), triangles(mesh)


# ---------------------------------------------------------------------------------------------
# per-vertex attributes (the unsmoothed copy lives on the mesh, so it survives save and reload)
# ---------------------------------------------------------------------------------------------
_KINDS = {  # numpy kind → (Blender data type, foreach key, numpy dtype, components)
    "vector": ("FLOAT_VECTOR", "vector", np.float32, 3),
    "float": ("FLOAT", "value", np.float32, 1),
    "int": ("INT", "value", np.int32, 1),
}


def set_point_attribute(mesh: bpy.types.Mesh, name: str, values: np.ndarray, kind: str = "vector") -> None:
    """Store a per-vertex array as attribute ``name`` (``kind``: "vector" (N, 3), "float", "int")."""
    btype, key, dtype, comps = _KINDS[kind]
    vals = np.ascontiguousarray(values, dtype=dtype).reshape(-1)
    if vals.size != len(mesh.vertices) * comps:
        raise ValueError(f"{mesh.name}: attribute {name!r} needs {len(mesh.vertices)} values")
    attr = mesh.attributes.get(name)
    if attr is not None and (attr.data_type != btype or attr.domain != "POINT"):
        mesh.attributes.remove(attr)
        attr = None
    if attr is None:
        attr = mesh.attributes.new(name, btype, "POINT")
    if vals.size:
        attr.data.foreach_set(key, vals)


def point_attribute(mesh: bpy.types.Mesh, name: str, kind: str = "vector") -> Optional[np.ndarray]:
    """Read back a per-vertex attribute, or None when the mesh has no such attribute."""
    btype, key, dtype, comps = _KINDS[kind]
    attr = mesh.attributes.get(name)
    if attr is None or attr.domain != "POINT" or attr.data_type != btype:
        return None
    out = np.empty(len(mesh.vertices) * comps, dtype=dtype)
    if out.size:
        attr.data.foreach_get(key, out)
    return out.reshape(-1, 3) if comps == 3 else out


def world_arrays(obj: bpy.types.Object, depsgraph=None) -> Tuple[np.ndarray, np.ndarray]:
    """Vertices (world coordinates, mm) and triangles of an object as shown (modifiers applied).

    With a ``depsgraph`` the evaluated mesh is read (modifiers, shape keys); otherwise the
    object's own mesh data. The object's transform is applied, so an organ the user moved is
    exported where it is shown.
    """
    if depsgraph is not None:
        ev = obj.evaluated_get(depsgraph)
        me = ev.to_mesh()
        try:
            v, f = arrays(me)
        finally:
            ev.to_mesh_clear()
    else:
        v, f = arrays(obj.data)
    m = np.array(obj.matrix_world, dtype=np.float64)
    if not np.allclose(m, np.eye(4)):
        v = (v.astype(np.float64) @ m[:3, :3].T + m[:3, 3]).astype(np.float32)
    return v, f


def shapes(context, objects) -> List[Tuple[np.ndarray, np.ndarray]]:
    """:func:`world_arrays` of each object as evaluated (modifiers applied) but for the drawn gap
    between touching structures (:mod:`.render_gap`): what exports and print checks read."""
    objects = list(objects)
    with left_out(objects):
        depsgraph = context.evaluated_depsgraph_get()
        return [world_arrays(o, depsgraph) for o in objects]
