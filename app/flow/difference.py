"""How far one set of surfaces is from another, per surface, and as colours on the surface.

* :func:`compare_sets` — per surface (matched by label value or isovalue) the symmetric Hausdorff
  and mean distance in mm (:func:`anatomesh.core.geometry.measure.surface_distance`'s sampling:
  vertices and face centroids of each surface to the triangles of the other; more than
  :data:`MAX_SAMPLES` samples are thinned evenly), optionally genus and components before/after.
* :func:`color_differences` — each vertex's *signed* distance to the other surface (positive
  outside it, negative inside, exact point-to-triangle distances) as a diverging colour map on
  ``Mesh.vertex_colors``: blue inside, white on it, red outside, saturated at ``scale_mm``
  (default: the 99th percentile of |distance| over all surfaces) — the PLY and GLB writers and the
  Blender scene carry the colours.
"""
from __future__ import annotations

from typing import Dict, List, Optional, Sequence

import numpy as np

from ...core.geometry.measure import TriangleGrid, sample_points
from ...core.geometry.topology import topology as mesh_topology
from ...core.model.mesh import Mesh
from ...core.model.surfaceset import SurfaceSet

#: samples per direction and surface above which the samples are thinned evenly
MAX_SAMPLES = 200_000
#: distances are searched up to this many voxels (of the coarser grid); farther ones count as that
CAP_VOXELS = 10.0
#: the ends of the colour map (sRGB): inside, on the surface, outside (after Moreland 2009,
#: "Diverging color maps for scientific visualization")
INSIDE, ON, OUTSIDE = (0.23, 0.30, 0.75), (0.87, 0.87, 0.87), (0.71, 0.02, 0.15)


def surface_difference(a: Mesh, b: Mesh, max_samples: int = MAX_SAMPLES,
                       cap_mm: float = np.inf) -> Dict[str, float]:
    """``{"max_mm", "mean_mm", "p99_mm"}``: symmetric Hausdorff, mean and 99th-percentile
    distance between two meshes (a speck of noise present in only one of them sets the
    Hausdorff distance; the percentile says how far the bulk of the surface moved). Distances
    are searched no farther than ``cap_mm`` (the search costs grow with the distance cubed);
    farther samples count as ``cap_mm`` and add ``"capped": True``."""
    d = np.concatenate([_distances(a, b, max_samples, cap_mm), _distances(b, a, max_samples, cap_mm)])
    capped = bool(np.isinf(d).any())
    d = np.minimum(d, cap_mm)
    out = {"max_mm": float(d.max()), "mean_mm": float(d.mean()), "p99_mm": float(np.percentile(d, 99))}
    return dict(out, capped=True) if capped else out


def _distances(a: Mesh, b: Mesh, max_samples: int, cap_mm: float) -> np.ndarray:
    pts = sample_points(a.vertices, a.faces)
    if len(pts) > max_samples:
        pts = pts[:: int(np.ceil(len(pts) / max_samples))]
    return TriangleGrid(b.vertices, b.faces).closest(pts, max_distance=cap_mm)[0]


def compare_sets(before: SurfaceSet, after: SurfaceSet, topology: bool = False,
                 cap_voxels: float = CAP_VOXELS) -> Dict:
    """Per surface of ``after`` its distance to the same surface in ``before`` (module doc);
    ``{"surfaces": {value: {name, max_mm, mean_mm, p99_mm[, genus_before, genus_after,
    components_before, components_after]}}, "max_mm", "mean_mm", "p99_mm"}`` (the worst
    surface's). Distances are searched up to ``cap_voxels`` voxels of ``before`` (farther ones
    count as that: ``capped``)."""
    cap = cap_voxels * float(np.linalg.norm(before.affine[:3, :3], axis=0).max())
    a = {_key(m.value): m for m in before.shells() if m.n_faces}
    b = {_key(m.value): m for m in after.shells() if m.n_faces}
    per: Dict[str, Dict] = {}
    for key in list(dict.fromkeys(list(b) + list(a))):
        if key not in a or key not in b:
            m = b.get(key) or a[key]
            per[key] = {"name": m.name, "note": "no surface before" if key not in a else "no surface after"}
            continue
        d = surface_difference(a[key], b[key], cap_mm=cap)
        per[key] = {"name": b[key].name, **{k: round(x, 4) for k, x in d.items()}}
        if topology:
            t0, t1 = mesh_topology(a[key].vertices, a[key].faces), mesh_topology(b[key].vertices, b[key].faces)
            per[key].update(genus_before=t0.genus, genus_after=t1.genus,
                            components_before=t0.components, components_after=t1.components)
    measured = [p for p in per.values() if "max_mm" in p]
    return {"surfaces": per, **{k: max((p[k] for p in measured), default=0.0)
                                for k in ("max_mm", "mean_mm", "p99_mm")}}


def signed_distances(points: np.ndarray, surface: Mesh) -> np.ndarray:
    """Distance (mm, (P,) float64) from each point to ``surface``, positive on the side its
    (outward) face normals point to, negative inside."""
    grid = TriangleGrid(surface.vertices, surface.faces)
    d, face, closest = grid.closest(np.asarray(points, np.float64))
    v = grid.vertices
    f = grid.faces[np.maximum(face, 0)]
    normal = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    side = np.einsum("ij,ij->i", np.asarray(points, np.float64) - closest, normal)
    return np.where(side < 0, -d, d)


def diverging_colors(d: np.ndarray, scale: float) -> np.ndarray:
    """sRGB colours (N, 3) float32 for signed distances ``d`` (mm): :data:`INSIDE` at
    ``-scale``, :data:`ON` at 0, :data:`OUTSIDE` at ``+scale`` (linear in between, clipped)."""
    t = np.clip(np.asarray(d, np.float64) / max(float(scale), 1e-9), -1.0, 1.0)[:, None]
    on = np.asarray(ON)
    out = np.where(t < 0, on + (-t) * (np.asarray(INSIDE) - on), on + t * (np.asarray(OUTSIDE) - on))
    return out.astype(np.float32)


def color_differences(meshes: Sequence[Mesh], reference: Sequence[Mesh],
                      scale_mm: Optional[float] = None) -> Dict:
    """Colour each mesh by its signed distance to the reference mesh of the same value (in
    place: ``vertex_colors``); returns ``{"scale_mm", "legend", "surfaces": {value: {name,
    max_mm, mean_mm, inside_max_mm, outside_max_mm}}}``. Meshes without a reference stay
    uncoloured."""
    ref = {_key(m.value): m for m in reference if m.n_faces}
    dists: List = []
    for m in meshes:
        r = ref.get(_key(m.value))
        dists.append(signed_distances(m.vertices, r) if r is not None and m.n_faces else None)
    every = [np.abs(d) for d in dists if d is not None and d.size]
    scale = scale_mm if scale_mm else (float(np.percentile(np.concatenate(every), 99)) if every else 0.0)
    scale = max(scale, 1e-3)
    per = {}
    for m, d in zip(meshes, dists):
        if d is None:
            continue
        m.vertex_colors = diverging_colors(d, scale)
        per[_key(m.value)] = {"name": m.name, "max_mm": round(float(np.abs(d).max()), 4),
                              "mean_mm": round(float(np.abs(d).mean()), 4),
                              "inside_max_mm": round(float(max(0.0, -d.min())), 4),
                              "outside_max_mm": round(float(max(0.0, d.max())), 4)}
    return {"scale_mm": round(scale, 4),
            "legend": f"vertex colours: blue {scale:.3g} mm or more inside the surface without "
                      f"preprocessing, white on it, red {scale:.3g} mm or more outside",
            "surfaces": per}


def _key(value) -> str:
    v = float(value)
    return str(int(v)) if v.is_integer() else str(v)
