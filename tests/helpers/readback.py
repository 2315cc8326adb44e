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
