"""Reading our files back the way other tools do: vertices joined by position.

STL stores positions only; slicers (PrusaSlicer's admesh core, CuraEngine), repair tools and
trimesh join vertices at the same position. These helpers judge a written file by what such a
reader sees, with tools nobody here wrote (trimesh, admesh).
"""
import re
import shutil
import subprocess

import numpy as np

from anatomesh.core.geometry.pinches import PINCH_GAP_MM


def pinch_volume_bound(pinch_points: int, volume_mm3: float, voxel_mm3: float) -> float:
    """How far a raw (unsmoothed) surface's volume may be from its voxels' (mm³): each vertex
    copy at a pinch point moves at most :data:`PINCH_GAP_MM` into its own side, and a vertex of
    a voxel surface has at most 6 voxel faces around it, so it changes the volume by at most
    gap · (fan area) / 3 = 2 · gap · s² (s the voxel edge); plus float rounding."""
    edge2 = voxel_mm3 ** (2.0 / 3.0)
    return pinch_points * 2.0 * PINCH_GAP_MM * edge2 + 1e-6 * abs(volume_mm3)


def pinch_vertices(vertex_ids):
    """(N,) bool over several shells' (or Blender objects') vertices stacked, given each one's
    set vertex ids: those at a pinch point (an id that some shell holds twice), which files and
    Blender show moved apart by the pinch gap."""
    twice = [np.unique(v)[np.bincount(np.unique(v, return_inverse=True)[1]) > 1] for v in vertex_ids]
    points = np.unique(np.concatenate(twice)) if twice else np.zeros(0)
    return np.isin(np.concatenate(vertex_ids), points)


def trimesh_facts(path):
    """``(closed, 2-manifold, components)`` of a mesh file as trimesh reads it (vertices merged
    by position): every edge used by exactly two faces, and the face-connected components."""
    import trimesh

    mesh = trimesh.load(str(path), force="mesh", process=True)
    _, counts = np.unique(mesh.edges_sorted, axis=0, return_counts=True)
    closed = bool(np.all(counts >= 2)) and len(mesh.faces) > 0
    manifold = bool(np.all(counts <= 2)) and _vertex_fans_single(mesh)
    parts = trimesh.graph.connected_components(mesh.face_adjacency, nodes=np.arange(len(mesh.faces)))
    return closed, manifold, len(parts)


def _vertex_fans_single(mesh) -> bool:
    """Every vertex's faces form one fan (no two cones touching at a point)."""
    from anatomesh.core.geometry.topology import nonmanifold_vertices

    return nonmanifold_vertices(np.asarray(mesh.faces), len(mesh.vertices)).size == 0


def admesh_facts(path):
    """admesh's reading of an STL: ``{"parts", "disconnected", "degenerate", "backwards"}``
    (admesh joins facets by exact vertex positions, as PrusaSlicer's loader does)."""
    exe = shutil.which("admesh")
    assert exe, "admesh is not installed (Debian package admesh; tools/setup_env.sh installs it)"
    out = subprocess.run([exe, str(path)], capture_output=True, text=True, timeout=120).stdout

    def number(label):
        m = re.search(re.escape(label) + r"\s*:\s*(\d+)", out)
        assert m, f"admesh printed no '{label}' for {path}"
        return int(m.group(1))
    return {"parts": number("Number of parts"), "disconnected": number("Total disconnected facets"),
            "degenerate": number("Degenerate facets"), "backwards": number("Backwards edges")}

def by_position(m):
    """Vertices joined by position only (normals and UVs ignored), as STL readers do."""
    m.merge_vertices(merge_tex=True, merge_norm=True)
    return m


def read_back(path, fmt):
    """``{geometry name: trimesh.Trimesh}`` of one written file, as trimesh reads it."""
    import trimesh

    if fmt == "dicom":
        import io

        import pydicom

        ds = pydicom.dcmread(str(path))
        assert ds.MIMETypeOfEncapsulatedDocument == "model/stl"
        doc = bytes(ds.EncapsulatedDocument)
        n = ds.get("EncapsulatedDocumentLength")
        data = io.BytesIO(doc[:n] if n else doc)
        return {"": by_position(trimesh.load(data, file_type="stl", force="mesh", process=True))}
    if fmt in ("3mf", "glb"):
        scene = trimesh.load(str(path), process=True)
        if isinstance(scene, trimesh.Trimesh):
            return {"": by_position(scene)}
        return {name: by_position(g) for name, g in scene.geometry.items()}
    return {"": by_position(trimesh.load(str(path), force="mesh", process=True))}


def mesh_facts(m):
    """``(closed, 2-manifold, components)`` of a mesh as read: every edge in >= 2 / <= 2 faces,
    every vertex's faces one fan; face-connected components (trimesh's face adjacency)."""
    import trimesh
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    f = np.asarray(m.faces, np.int64)
    if len(f) == 0:
        return False, False, 0
    es = np.asarray(m.edges_sorted, np.int64)
    _, counts = np.unique(es[:, 0] * len(m.vertices) + es[:, 1], return_counts=True)
    adj = np.asarray(m.face_adjacency, np.int64).reshape(-1, 2)
    comps = len(trimesh.graph.connected_components(adj, nodes=np.arange(len(f))))
    # corners (face, vertex) joined across each shared edge at both its ends: one fan per vertex
    edges = np.asarray(m.face_adjacency_edges, np.int64).reshape(-1, 2)
    a = [adj[:, 0] * 3 + np.argmax(f[adj[:, 0]] == edges[:, e, None], axis=1) for e in (0, 1)]
    b = [adj[:, 1] * 3 + np.argmax(f[adj[:, 1]] == edges[:, e, None], axis=1) for e in (0, 1)]
    a, b, n = np.concatenate(a), np.concatenate(b), 3 * len(f)
    _, lab = connected_components(coo_matrix((np.ones(len(a)), (a, b)), shape=(n, n)), directed=False)
    fans = len(np.unique(f.ravel() * n + lab))
    return bool(np.all(counts >= 2)), bool(np.all(counts <= 2)) and fans == len(np.unique(f)), comps
