"""Smoothing surfaces: one entry point for a SurfaceSet (:func:`smooth_surfaces`), one for one
mesh (:func:`smooth_mesh`) and one for plain arrays (:func:`smooth`).

The whole shared mesh of a :class:`~anatomesh.core.model.surfaceset.SurfaceSet` is smoothed at
once: an interface vertex is one vertex for both labels, so the shells stay crack-free. The named
default :data:`DEFAULT` = ``"organ"`` (:mod:`~anatomesh.core.smooth.presets`) runs, in order:

1. Taubin's λ|μ filter (Taubin 1995, "A signal processing approach to fair surface design"),
   λ = 0.5, μ = −0.53, 20 iterations, every vertex kept in its voxel cell after every pass
   (Gibson 1998, "Constrained elastic surface nets"), junction curves of 3+ labels smoothed
   along the curve only, extra slice-axis passes for thick slices (Mönch, Adler & Preim 2010,
   "Staircase-aware smoothing of medical surface meshes");
2. the fold guard (:func:`~anatomesh.core.smooth.guards.unfold`);
3. the volume step (:func:`~anatomesh.core.smooth.guards.restore_volumes`): every label gets its
   volume back, inside the same cells; then the component guard
   (:mod:`~anatomesh.core.smooth.components`): every connected component of every label's shell
   (cavities included) ends within ``component_bound_pct`` (10 %) of its unsmoothed volume —
   the failing ones get their own volume regions, any still outside is blended back toward its
   unsmoothed positions — so single-voxel specks and small cavities are not flattened;
4. untangling (:func:`~anatomesh.core.smooth.untangle.untangle`): faces that now cross are
   pulled back toward their unsmoothed positions.

Measured on TotalSegmentator's maps (3 mm voxels): 41-label map (61k vertices) volume change
≤ 0.03 % on organs above 1000 voxels, ≤ 2.9 % on every label but a one-voxel speck (−19 %),
symmetric Hausdorff to the voxel surface ≤ 2.6 mm (half the voxel diagonal, the box's bound),
mean 0.49 mm, no folds, mean |H| 0.15 → 0.07 /mm; 61-label map (181k vertices): ≤ 0.16 % on
organs, worst label −2.4 % (a rib), Hausdorff ≤ 2.6 mm, mean 0.50 mm. Without the volume step
ribs lose up to 35 %, compact organs up to 2.8 % (Bade, Haase & Preim 2006, "Comparison of
fundamental mesh smoothing algorithms for medical surface models", measured such shrinkage for
every classic filter).

Re-smoothing the same surfaces with other settings (sliders): keep a
:class:`~anatomesh.core.smooth.session.SmoothingSession`. The filters, constraints and guards
are importable from here too.
"""
from __future__ import annotations

import dataclasses
from typing import Optional, Tuple

import numpy as np

from .components import DEFAULT_BOUND_PCT
from .constraints import (Constraint, distance_gain, lattice_constraint, staircase_params,
                          voxel_constraint)
from .filters import FILTERS, hc_laplacian, laplacian, mean_curvature_flow, normal_filter, taubin
from .guards import component_regions, region_volumes, restore_volumes, unfold
from .presets import DEFAULT, METHODS, PRESETS, resolve
from .report import SmoothingReport
from .session import SmoothingSession, face_groups_of
from .shell_measures import shell_key
from ..geometry.neighbors import MeshStructure, structure as _structure
from ..model.errors import AnatomeshError
from ..model.mesh import Mesh
from ..model.progress import Progress
from ..model.surfaceset import SurfaceSet

__all__ = ["DEFAULT", "METHODS", "PRESETS", "Constraint", "SmoothingReport", "SmoothingSession",
           "distance_gain", "face_groups_of", "hc_laplacian", "lattice_constraint", "laplacian",
           "mean_curvature_flow", "normal_filter", "region_volumes", "resolve", "restore_volumes",
           "smooth", "smooth_mesh", "smooth_surfaces", "staircase_params", "taubin", "unfold",
           "voxel_constraint"]


def smooth_surfaces(surfaces: SurfaceSet, method: str = DEFAULT, *, constraint="auto",
                    max_deviation: Optional[float] = None, junctions: bool = True,
                    staircase="auto", damping_distance: Optional[float] = None,
                    preserve_volume: Optional[bool] = None, fold_guard: bool = True,
                    untangle: bool = True, component_bound_pct: Optional[float] = DEFAULT_BOUND_PCT,
                    measure: bool = True, distances: bool = True,
                    topology: bool = True, volume_warning_pct: float = 5.0,
                    structure: Optional[MeshStructure] = None, precision: str = "float64",
                    progress: Optional[Progress] = None, **params) -> Tuple[SurfaceSet, SmoothingReport]:
    """Smooth a :class:`~anatomesh.core.model.surfaceset.SurfaceSet` and measure it.

    Parameters
    ----------
    surfaces : SurfaceSet
        A label map's set (:func:`~anatomesh.core.extract.multilabel.label_surfaces`) or
        independent surfaces (:meth:`SurfaceSet.from_meshes`, e.g. isosurfaces).
    method : str
        A preset of :data:`PRESETS` (default ``"organ"``) or a filter of :data:`METHODS`;
        keyword ``params`` override the preset (e.g. ``iterations=30, lam=0.6``).
    constraint : "auto", "cell", None or Constraint
        ``"cell"``: each vertex stays in its voxel cell — its lattice cell in a label map's set,
        a box of ± half a voxel of ``surfaces.affine`` around its start for independent
        surfaces. ``"auto"``: the preset's choice (``"cell"`` for a bare filter name).
    max_deviation : float, mm, optional
        Also cap every vertex's displacement (hard bound, clamped every pass).
    junctions : bool
        Label maps: vertices where 3+ labels meet smooth only along their junction curve.
    staircase : "auto", True or False
        Taubin only: add slice-axis passes for thick slices (:func:`staircase_params`); "auto"
        when the slice spacing is >= 1.5x the in-plane spacing.
    damping_distance : float, mm, optional
        Distance-aware damping (Mönch, Gasteiger, Janiga, Theisel & Preim 2011, "Context-aware
        mesh smoothing for biomedical applications"): smoothing fades where a vertex of another
        connected part of the surface is closer than this.
    preserve_volume : bool, optional
        After the filter, give every label (every closed connected component of independent
        surfaces) its volume back (:func:`restore_volumes`), inside the same constraint. None:
        the preset's choice (``"organ"``: yes), else no.
    component_bound_pct : float, percent, optional
        With the volume step: the component guard's bound (:mod:`.components`): every connected
        component of every shell (``surfaces.shell(value)``'s components, cavities included;
        closed components of independent surfaces) keeps ``|V − V_raw| <= bound · |V_raw|``.
        ``report.params`` then holds ``component_bound_pct``, ``restored_components`` (outside
        the bound, restored by their own volume regions) and ``blended_components`` (blended
        back toward their unsmoothed positions). None: off.
    fold_guard : bool
        Undo folds the filter made (:func:`unfold`), after the filter and after restoring
        volumes; ``report.params["unfolded_vertices"]`` counts the vertices moved back.
    untangle : bool
        Last, pull the vertices of faces that now cross (inside a shell or between two shells a
        voxel apart) back toward their unsmoothed positions until nothing crosses;
        ``report.params["untangled_vertices"]`` counts them.
    measure, distances, topology : bool
        Per-shell report; ``distances`` adds the symmetric Hausdorff and mean distance to the
        unsmoothed shell, ``topology`` its components, genus, closed, manifold, oriented (else
        only its degenerate faces: smoothing never changes the rest).
    volume_warning_pct : float
        Shells whose volume changed more than this get a line in ``report.warnings``.
    structure : MeshStructure, optional
        The neighbourhoods of ``surfaces.faces``, if already built.
    precision : "float64" or "float32"
        Arithmetic of the Taubin/Laplacian passes (float32: live sliders, faster).

    Returns
    -------
    (smoothed SurfaceSet, SmoothingReport)
    """
    session = SmoothingSession(surfaces, structure=structure)
    return session.smooth(method, constraint=constraint, max_deviation=max_deviation,
                          junctions=junctions, staircase=staircase,
                          damping_distance=damping_distance, preserve_volume=preserve_volume,
                          fold_guard=fold_guard, untangle=untangle,
                          component_bound_pct=component_bound_pct, measure=measure,
                          distances=distances, topology=topology,
                          volume_warning_pct=volume_warning_pct,
                          precision=precision, progress=progress, keep=False, **params)


def smooth_mesh(mesh: Mesh, method: str = DEFAULT, *, affine: Optional[np.ndarray] = None,
                constraint="auto", staircase="auto", **settings) -> Tuple[Mesh, SmoothingReport]:
    """Smooth one :class:`~anatomesh.core.model.mesh.Mesh` as a one-surface set
    (:func:`smooth_surfaces`); returns the mesh with new vertices and the report (its shell
    keyed by the mesh's ``value``, 0 when it has none).

    ``affine`` (default ``mesh.meta["affine"]``): the voxel → mm matrix of the volume the mesh
    came from; ``"cell"`` keeps each vertex in a box of ± half a voxel around its start. Without
    an affine there is no box and no staircase step (``max_deviation`` still caps)."""
    if not isinstance(mesh, Mesh):
        raise AnatomeshError(f"smooth_mesh needs a Mesh, got {type(mesh).__name__}")
    if affine is None:
        affine = mesh.meta.get("affine")
    if affine is None:  # no voxel grid: no box, no slices
        affine, staircase = np.eye(4), False
        if isinstance(constraint, str) and constraint in ("auto", "cell"):
            constraint = None
    out, rep = smooth_surfaces(SurfaceSet.from_meshes([mesh], affine, mesh.space), method,
                               constraint=constraint, staircase=staircase, **settings)
    rep.shells = {shell_key(mesh.value): r for r in rep.shells.values()}
    smoothed = dataclasses.replace(mesh, vertices=out.vertices, normals=None, meta=dict(mesh.meta))
    return smoothed, rep


def smooth(vertices, faces, method: str = DEFAULT, *, affine: Optional[np.ndarray] = None,
           fold_guard: Optional[bool] = None, **params) -> np.ndarray:
    """Smooth one mesh given as arrays with a named preset or filter; returns (N, 3) positions.

    ``constraint="cell"`` (presets) becomes :func:`voxel_constraint` of ``affine`` (a box of
    ± half a voxel around each start) when ``affine`` is given, and no box otherwise;
    ``preserve_volume=True`` restores each closed component's volume (:func:`restore_volumes`).
    ``fold_guard`` (default: on for presets, off for bare filters) undoes folds (:func:`unfold`).
    Other keyword arguments go to the filter (see :data:`PRESETS`, :data:`METHODS`).
    """
    name, p = resolve(method, **params)
    preserve = p.pop("preserve_volume", False)
    if name == "none":
        return np.array(vertices, copy=True)
    c = p.get("constraint")
    if isinstance(c, str):
        if c != "cell":
            raise AnatomeshError(f"constraint must be 'cell', None or a Constraint, got {c!r}")
        p["constraint"] = voxel_constraint(affine) if affine is not None else None
    try:
        out = FILTERS[name](vertices, faces, **p)
    except TypeError as e:  # an unknown keyword for this filter
        raise AnatomeshError(f"smoothing method {name!r}: {e}") from None
    if fold_guard is None:
        fold_guard = method in PRESETS
    if fold_guard:
        out = unfold(out, vertices, faces)[0]
    if preserve:
        s = p.get("structure") or _structure(faces, np.asarray(vertices).shape[0])
        sides, n = component_regions(s)
        targets = region_volumes(vertices, s.faces, sides, n)
        out = restore_volumes(out, s.faces, sides, targets, constraint=p.get("constraint"),
                              gain=p.get("gain"), structure=s)
        if fold_guard:
            out = unfold(out, vertices, faces)[0]
    return out
