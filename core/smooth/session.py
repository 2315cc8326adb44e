"""A smoothing session: the unsmoothed surface and everything that depends only on it, cached, so
that smoothing again with other settings (a slider in Blender) runs only the filter and the
guards.

Made once from a :class:`~anatomesh.core.model.surfaceset.SurfaceSet`: a label map's set (each
vertex kept in its lattice cell, Gibson 1998, "Constrained elastic surface nets") or a set of
independent surfaces (:meth:`SurfaceSet.from_meshes`: each vertex kept in a voxel-sized box of
``surfaces.affine`` around its start). :meth:`SmoothingSession.run` then runs the whole driver —
filter, fold guard, volume restoration, untangling — for any settings.
"""
from __future__ import annotations

import time
from typing import Dict, Optional, Tuple

import numpy as np

from .checks import mesh_structure
from .constraints import Constraint, distance_gain, lattice_constraint, staircase_params, \
    voxel_constraint
from .filters import FILTERS
from .guards import component_regions, region_volumes, restore_volumes, unfold
from .presets import DEFAULT, resolve
from .report import SmoothingReport, describe, measure_shells
from .untangle import untangle as untangle_crossings
from ..geometry.neighbors import MeshStructure
from ..model.errors import AnatomeshError
from ..model.progress import Progress, report, sub
from ..model.surfaceset import SurfaceSet


def face_groups_of(face_labels: np.ndarray) -> np.ndarray:
    """A group id per face from its (inside, outside) labels: faces of the same unordered label
    pair share a group, so edges between groups are the junctions where 3+ labels meet."""
    fl = np.asarray(face_labels, np.int64).reshape(-1, 2)
    key = np.minimum(fl[:, 0], fl[:, 1]) * 65536 + np.maximum(fl[:, 0], fl[:, 1])
    return np.unique(key, return_inverse=True)[1].astype(np.int64).ravel()


class SmoothingSession:
    """Cached smoothing of one :class:`~anatomesh.core.model.surfaceset.SurfaceSet`.

    Parameters
    ----------
    surfaces : SurfaceSet
        The unsmoothed surfaces; never modified.
    structure : MeshStructure, optional
        The neighbourhoods of ``surfaces.faces`` if already built.

    Attributes
    ----------
    surfaces : SurfaceSet
    rest : (N, 3) float32 — the unsmoothed positions, mm (the set's own array)
    structure : MeshStructure
    """

    def __init__(self, surfaces: SurfaceSet, *, structure: Optional[MeshStructure] = None):
        if not isinstance(surfaces, SurfaceSet):
            raise AnatomeshError(f"smoothing needs a SurfaceSet (SurfaceSet.from_meshes for meshes), "
                                 f"got {type(surfaces).__name__}")
        self.surfaces = surfaces
        self.rest = surfaces.vertices
        self.faces = surfaces.faces
        self.structure = mesh_structure(self.faces, len(self.rest), structure)
        self._cache: Dict = {}

    @property
    def has_lattice(self) -> bool:
        """Vertices come from a label map's lattice (else: independent surfaces)."""
        return self.surfaces.lattice is not None

    def _cached(self, key, make):
        if key not in self._cache:
            self._cache[key] = make()
        return self._cache[key]

    def face_groups(self) -> Optional[np.ndarray]:
        """(M,) junction groups of a label map's set (:func:`face_groups_of`); None otherwise."""
        if not self.has_lattice:
            return None
        return self._cached("groups", lambda: face_groups_of(self.surfaces.face_labels))

    def regions(self) -> Tuple[np.ndarray, int, np.ndarray]:
        """``(face_sides (M, 2), n_regions, target volumes (R,) mm³)`` for the volume step: the
        labels of a label map's set (background −1), the closed connected components of
        independent surfaces (open ones get no region)."""
        return self._cached("regions", self._make_regions)

    def _make_regions(self):
        if self.has_lattice:
            fl = np.asarray(self.surfaces.face_labels, np.int64)
            values = np.unique(fl)
            values = values[values != self.surfaces.background]
            index = np.full(int(fl.max()) + 1, -1, np.int64)
            index[values] = np.arange(values.size)
            sides, n = index[fl], int(values.size)
        else:
            sides, n = component_regions(self.structure)
        return sides, n, region_volumes(self.rest, self.faces, sides, n)

    def constraint(self, constraint, max_deviation: Optional[float]) -> Optional[Constraint]:
        """The constraint for a setting: ``"cell"`` → the lattice cell box (label map) or the
        voxel box around each start (independent surfaces), ``None``, or a given
        :class:`Constraint`; ``max_deviation`` mm added as a cap. Cell boxes are cached."""
        if isinstance(constraint, Constraint):
            if max_deviation is None:
                return constraint
            return Constraint(constraint.kind, constraint.center, constraint.frame,
                              constraint.half, max_deviation)
        if constraint is None:
            return Constraint(max_deviation=max_deviation) if max_deviation is not None else None
        if constraint != "cell":
            raise AnatomeshError(f"constraint must be 'cell', None or a Constraint, got {constraint!r}")
        return self._cached(("cell", max_deviation), lambda: self._cell(max_deviation))

    def _cell(self, max_deviation):
        s = self.surfaces
        if self.has_lattice:
            return lattice_constraint(s.affine, s.lattice, max_deviation=max_deviation)
        return voxel_constraint(s.affine, max_deviation=max_deviation)

    def gain(self, damping_distance: float) -> np.ndarray:
        """Distance-aware damping of the connected parts (:func:`distance_gain`), cached."""
        return self._cached(("gain", float(damping_distance)), lambda: distance_gain(
            self.rest, self.structure.components(), damping_distance))

    def run(self, method: str = DEFAULT, *, constraint="auto", max_deviation: Optional[float] = None,
            junctions: bool = True, staircase="auto", damping_distance: Optional[float] = None,
            preserve_volume: Optional[bool] = None, fold_guard: bool = True, untangle: bool = True,
            precision: str = "float64", progress: Optional[Progress] = None,
            **params) -> Tuple[np.ndarray, dict]:
        """Smooth the unsmoothed surfaces with these settings; see
        :func:`~anatomesh.core.smooth.driver.smooth_surfaces` for each setting. ``precision``:
        the arithmetic of Taubin/Laplacian passes, "float64" or "float32" (live sliders).

        Returns ``(vertices (N, 3) float32 mm, info)`` with ``info = {"method", "params",
        "seconds", "warnings"}``."""
        t0 = time.perf_counter()
        name, p = resolve(method, **params)
        preset_constraint = p.pop("constraint", "cell")
        preserve = p.pop("preserve_volume", False) if preserve_volume is None else preserve_volume
        p.pop("preserve_volume", None)
        if name == "none" or not self.faces.shape[0]:
            return self.surfaces.vertices.copy(), {"method": "none", "params": describe(p),
                                                    "seconds": time.perf_counter() - t0,
                                                    "warnings": []}
        c = self.constraint(preset_constraint if constraint == "auto" else constraint, max_deviation)
        kw = self._filter_args(name, p, c, junctions, staircase, damping_distance, precision)
        kw["progress"] = sub(progress, 0.0, 0.9) if preserve else progress
        try:
            new = FILTERS[name](self.rest, self.faces, **kw)
        except TypeError as e:  # an unknown keyword for this filter
            raise AnatomeshError(f"smoothing method {name!r}: {e}") from None
        new, extra, warnings = self._guards(new, c, kw.get("gain"), preserve, fold_guard,
                                            untangle, progress)
        report(progress, 1.0, "smoothed")
        p.update(constraint=c, **{k: v for k, v in kw.items() if k.startswith("slice_")}, **extra)
        return new.astype(np.float32), {"method": name, "params": describe(p),
                                        "seconds": time.perf_counter() - t0, "warnings": warnings}

    def _filter_args(self, name, p, c, junctions, staircase, damping_distance, precision) -> dict:
        kw = dict(p, constraint=c, structure=self.structure)
        if junctions and self.has_lattice:
            kw["face_groups"] = self.face_groups()
        if damping_distance is not None:
            kw["gain"] = self.gain(damping_distance)
        if name == "taubin" and staircase and "slice_axis" not in kw:
            kw.update(staircase_params(self.surfaces.affine, kw.get("iterations", 20),
                                       min_ratio=1.5 if staircase == "auto" else 1.0))
        if name in ("taubin", "laplacian"):
            kw["precision"] = precision
        return kw

    def _guards(self, new, c, gain, preserve, fold_guard, untangle, progress):
        extra, warnings = {}, []
        unfolded = 0
        if fold_guard:
            new, unfolded = unfold(new, self.rest, self.faces)
        if preserve:
            sides, _, targets = self.regions()
            anchored = c.anchored(self.rest) if c is not None else None
            new = restore_volumes(new, self.faces, sides, targets, constraint=anchored, gain=gain,
                                  structure=self.structure)
            if fold_guard:
                new, more = unfold(new, self.rest, self.faces)
                unfolded += more
            extra["preserve_volume"] = True
        if fold_guard:
            extra["unfolded_vertices"] = unfolded
        if untangle:
            report(progress, 0.97, "checking for crossing faces")
            new, info = untangle_crossings(new, self.rest, self.faces)
            extra["untangled_vertices"] = info["moved_vertices"]
            if info["crossings_left"]:
                warnings.append(f"{info['crossings_left']} pairs of faces still cross after "
                                "smoothing (the unsmoothed surface crosses itself there)")
        return new, extra, warnings

    def smooth(self, method: str = DEFAULT, *, measure: bool = True, distances: bool = True,
               volume_warning_pct: float = 5.0, **settings) -> Tuple[SurfaceSet, SmoothingReport]:
        """:meth:`run`, then the smoothed set and its :class:`SmoothingReport` (per-shell
        measures when ``measure``; ``distances`` adds the Hausdorff and mean distances)."""
        vertices, info = self.run(method, **settings)
        out = self.surfaces.copy_with_vertices(vertices)
        shells, warnings = {}, list(info["warnings"])
        if measure and info["method"] != "none":
            shells, more = measure_shells(self.surfaces, out, distances=distances,
                                          volume_warning_pct=volume_warning_pct)
            warnings += more
        return out, SmoothingReport(info["method"], info["params"], info["seconds"], shells,
                                    warnings)
