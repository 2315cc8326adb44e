"""A smoothing session: the unsmoothed surface and everything that depends only on it, cached, so
that smoothing again with other settings (a slider in Blender) runs only the filter and the
guards, at kernel speed.

Made once from a :class:`~anatomesh.core.model.surfaceset.SurfaceSet`: a label map's set (each
vertex kept in its lattice cell, Gibson 1998, "Constrained elastic surface nets") or a set of
independent surfaces (:meth:`SurfaceSet.from_meshes`: each vertex kept in a voxel-sized box of
``surfaces.affine`` around its start). Cached: the neighbourhoods (1-ring, junction rings,
padded columns, vertex → faces), the cell boxes, the regions and target volumes of the volume
step, the shell components and their volumes (the component guard), the faces bucketed by
their boxes (which pairs can cross, :class:`~anatomesh.core.geometry.face_pairs.FaceBoxes`;
the pairs are listed from the second run on) and the unsmoothed side of the report.
:meth:`SmoothingSession.run` then runs the whole default driver — filter, fold guard, volume
step, fold guard, component guard (:mod:`~anatomesh.core.smooth.components`), untangling — for
any settings; :meth:`SmoothingSession.smooth` adds the per-shell report.

Usage (a slider)::

    session = SmoothingSession(surfaces)                                  # once per scan
    vertices, info = session.run("organ", lam=0.55, precision="float32")  # every move
    smoothed, report = session.smooth("organ")                            # with the report

A session keeps working buffers: use it from one thread at a time. A cell box is the voxel shrunk
by a hair (:attr:`SmoothingSession.margin`, 1e-4 voxel), so two vertices of neighbouring cells
never meet on their shared face: faces whose boxes only touch cannot cross, and testing only the
candidate pairs is exact.
"""
from __future__ import annotations

import time
from typing import Dict, Optional, Tuple

import numpy as np

from .checks import mesh_structure, precision_dtype
from .components import DEFAULT_BOUND_PCT, ComponentGuard, check_bound
from .constraints import (Constraint, clamp, distance_gain, lattice_constraint, staircase_params,
                          voxel_constraint)
from .filters import FILTERS
from .guards import VolumeRegions, component_regions, folded_faces, unfold_in_place
from .presets import DEFAULT, resolve
from .report import SmoothingReport, describe
from .shell_measures import ShellMeasures, label_sides, shell_key, shell_warnings
from .untangle import faces_around, untangle as untangle_crossings
from ..geometry.face_pairs import FaceBoxes
from ..geometry.neighbors import MeshStructure
from ..model.errors import AnatomeshError
from ..model.progress import Progress, report, sub
from ..model.surfaceset import SurfaceSet


def face_groups_of(face_labels: np.ndarray) -> np.ndarray:
    """A group id per face from its (inside, outside) labels: faces of the same unordered label
    pair share a group (ids in the order of the pairs), so edges between groups are the
    junctions where 3+ labels meet."""
    fl = np.asarray(face_labels, np.int64).reshape(-1, 2)
    if fl.size == 0:
        return np.zeros(0, np.int64)
    r = int(fl.max()) + 1
    key = np.minimum(fl[:, 0], fl[:, 1]) * r + np.maximum(fl[:, 0], fl[:, 1])
    if r * r > 1 << 24:  # too many labels for a table
        return np.unique(key, return_inverse=True)[1].astype(np.int64).ravel()
    seen = np.zeros(r * r, np.int64)
    seen[key] = 1
    return (np.cumsum(seen) - 1)[key]


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
    rest : (N, 3) float64 — the unsmoothed positions, mm
    structure : MeshStructure
    margin : float — how much (voxels) a cell box is smaller than the voxel on each side
    """

    def __init__(self, surfaces: SurfaceSet, *, structure: Optional[MeshStructure] = None):
        if not isinstance(surfaces, SurfaceSet):
            raise AnatomeshError(f"smoothing needs a SurfaceSet (SurfaceSet.from_meshes for meshes), "
                                 f"got {type(surfaces).__name__}")
        self.surfaces = surfaces
        self.faces = surfaces.faces
        self.rest = np.ascontiguousarray(surfaces.vertices, np.float64)
        self.structure = mesh_structure(self.faces, len(self.rest), structure)
        a3 = np.asarray(surfaces.affine, np.float64)[:3, :3]
        scale = float(np.abs(self.rest).max(initial=0.0)) + float(np.abs(a3).sum())
        spacing = float(np.linalg.norm(a3, axis=0).min()) or 1.0
        # float32 positions round by < 2^-24 of the coordinates: stay well clear of that
        self.margin = max(1e-4, 8.0 * 2.0 ** -24 * scale / spacing)
        self._cache: Dict = {}
        self._cells: set = set()  # ids of the cached cell constraints
        self._runs = 0

    @property
    def runs(self) -> int:
        """How often :meth:`run` ran (from the second run on, the candidate pairs are listed)."""
        return self._runs

    @property
    def has_lattice(self) -> bool:
        """Vertices come from a label map's lattice (else: independent surfaces)."""
        return self.surfaces.lattice is not None

    def _cached(self, key, make):
        if key not in self._cache:
            self._cache[key] = make()
        return self._cache[key]

    def face_groups(self) -> Optional[np.ndarray]:
        """The junction groups of a label map's set: its (M, 2) ``face_labels``, which the
        feature rings compare as unordered pairs (the groups of :func:`face_groups_of` without
        building them, 8 bytes a face); None otherwise."""
        return self.surfaces.face_labels if self.has_lattice else None

    def regions(self) -> VolumeRegions:
        """The regions of the volume step with their unsmoothed volumes: the labels of a label
        map's set (background −1), the closed connected components of independent surfaces
        (open ones get none)."""
        return self._cached("regions", self._make_regions)

    def _make_regions(self) -> VolumeRegions:
        if self.has_lattice:
            sides, values = label_sides(self.surfaces)
            n = len(values)
        else:
            sides, n = component_regions(self.structure)
        regions = VolumeRegions(self.structure.faces, sides, np.zeros(n))
        regions.targets = regions.volumes(self.rest)[0]
        regions.release_buffers()  # memory: made before the filter in one-shot runs
        return regions

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
        s, half = self.surfaces, 0.5 - self.margin
        if self.has_lattice:
            c = lattice_constraint(s.affine, s.lattice, half=half, max_deviation=max_deviation)
        else:
            c = voxel_constraint(s.affine, half=half, max_deviation=max_deviation)
        self._cells.add(id(c))
        return c

    def boxes(self, listing: bool = True) -> FaceBoxes:
        """The faces bucketed by their cell boxes (which pairs can cross while every vertex
        stays in its box); cached, the pairs listed from the second run on (a slider).
        ``listing=False`` (one-shot runs): without what listing the pairs needs (memory)."""
        boxes = self._cache.get("boxes")
        if boxes is None or (listing and not boxes.listing):
            boxes = self._cache["boxes"] = self._make_boxes(listing)
        if self._runs > 1 and boxes.listing:
            boxes.materialize()
        return boxes

    def _make_boxes(self, listing: bool) -> FaceBoxes:
        s = self.surfaces
        if self.has_lattice:
            centres = s.lattice - 0.5
        else:
            a = np.asarray(s.affine, np.float64)
            centres = np.einsum("ij,kj->ik", self.rest - a[:3, 3], np.linalg.inv(a[:3, :3]))  # no BLAS threads
        return FaceBoxes(self.faces, centres, (0.5, 0.5, 0.5), listing)

    def gain(self, damping_distance: float) -> np.ndarray:
        """Distance-aware damping of the connected parts (:func:`distance_gain`), cached."""
        return self._cached(("gain", float(damping_distance)), lambda: distance_gain(
            self.rest, self.structure.components(), damping_distance))

    def measures(self) -> ShellMeasures:
        """The per-shell measures against the unsmoothed set; cached."""
        return self._cached("measures", lambda: ShellMeasures(self.surfaces, self.rest,
                                                              self.structure))

    def run(self, method: str = DEFAULT, *, constraint="auto", max_deviation: Optional[float] = None,
            junctions: bool = True, staircase="auto", damping_distance: Optional[float] = None,
            preserve_volume: Optional[bool] = None, fold_guard: bool = True, untangle: bool = True,
            component_bound_pct: Optional[float] = DEFAULT_BOUND_PCT, precision: str = "float64",
            progress: Optional[Progress] = None, keep: bool = True,
            **params) -> Tuple[np.ndarray, dict]:
        """Smooth the unsmoothed surfaces with these settings; see
        :func:`~anatomesh.core.smooth.driver.smooth_surfaces` for each setting. ``precision``:
        the arithmetic of the Taubin/Laplacian passes, "float64" or "float32" (live sliders:
        within 1e-3 mm of float64); the guards always run in float64. ``keep=False`` (one-shot
        runs): each step's caches are freed as soon as the step is done (the passes' buffers
        after the filter, the volume regions after the volume step, the face buckets at the
        end), so the peak memory is the largest step's, not their sum.

        Returns ``(vertices (N, 3) float32 mm, info)`` with ``info = {"method", "params",
        "seconds", "warnings"}``."""
        t0 = time.perf_counter()
        precision_dtype(precision)
        bound = check_bound(component_bound_pct)
        self._runs += 1
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
        cons = (c.anchored(self.rest) if c is not None else Constraint()).arrays(self.rest)
        # the filtered positions go straight to the guards, which drop them when done (memory)
        guards = dict(preserve=preserve, fold_guard=fold_guard, untangle=untangle,
                      bound=bound if preserve else None)
        out, extra, warnings = self._guards(self._filtered(name, kw, cons, keep), c, cons,
                                            kw.get("gain"), guards, progress, keep)
        if not keep:
            self.release()
        report(progress, 1.0, "smoothed")
        p.update(constraint=c, **{k: v for k, v in kw.items() if k.startswith("slice_")}, **extra)
        if precision != "float64":
            p["precision"] = precision
        return out, {"method": name, "params": describe(p), "seconds": time.perf_counter() - t0,
                     "warnings": warnings}

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

    def _filtered(self, name: str, kw: dict, cons: tuple, keep: bool) -> np.ndarray:
        """The filter's positions (N, 3) float64, clamped into the constraint in float64
        (float32 passes round); ``keep=False``: the passes' buffers and rings are freed."""
        if not keep and name in ("taubin", "laplacian"):
            kw["keep_buffers"] = False
        try:
            pos = np.ascontiguousarray(FILTERS[name](self.rest, self.faces, **kw), np.float64)
        except TypeError as e:  # an unknown keyword for this filter
            raise AnatomeshError(f"smoothing method {name!r}: {e}") from None
        if not keep:
            self.structure.release_buffers()
        clamp(pos, cons)
        return pos

    def components(self) -> ComponentGuard:
        """The components of every shell with their unsmoothed volumes (the component guard,
        :mod:`~anatomesh.core.smooth.components`); cached."""
        return self._cached("components", lambda: ComponentGuard(self.surfaces, self.rest,
                                                                 self.structure))

    def _guards(self, pos, c, cons, gain, guards: dict, progress, keep=True):
        """Fold guard, volume step, fold guard, component guard (float64, in place), then
        untangling on the float32 positions the set keeps and the components checked again
        (``keep=False``: the volume regions freed after their step). ``guards``: the switches
        ``preserve``, ``fold_guard``, ``untangle`` and the component ``bound`` (fraction or
        None). Returns (float32 positions, params, warnings)."""
        extra, warnings = {}, []
        gain = np.zeros(0) if gain is None else gain
        fold_guard, bound = guards["fold_guard"], guards["bound"]
        unfolded = unfold_in_place(pos, self.rest, self.structure) if fold_guard else 0
        if guards["preserve"]:
            pos = self.regions().restore(pos, self.structure, cons, gain)
            if not keep:  # and the feature rings the regions of independent surfaces need
                self._cache.pop("regions", None)
                self.structure.release_buffers()
            if fold_guard:
                unfolded += unfold_in_place(pos, self.rest, self.structure)
            extra["preserve_volume"] = True
        if fold_guard:
            extra["unfolded_vertices"] = unfolded
        restored, blended = set(), set()
        if bound is not None:
            restored, blended = self.components().guard(pos, cons, gain, bound, fold_guard)
        out = pos.astype(np.float32)
        del pos  # memory: untangling works on the float32 positions
        if guards["untangle"]:
            report(progress, 0.97, "checking for crossing faces")
            out = self._untangle(out, c, fold_guard, bound, blended, keep, extra, warnings)
        if bound is not None:
            extra.update(component_bound_pct=100.0 * bound,
                         restored_components=len(restored - blended),
                         blended_components=len(blended))
        return out, extra, warnings

    def _untangle(self, out, c, fold_guard, bound, blended: set, keep, extra, warnings):
        """Untangling (and the fold guard after it), then the components it pushed outside the
        bound blended back (:meth:`_components_after_untangling`, adding to ``blended``)."""
        pairs = self.boxes(listing=keep) if id(c) in self._cells else None
        out, info = untangle_crossings(out, self.surfaces.vertices, self.faces, pairs=pairs,
                                       structure=self.structure, in_place=True)
        extra["untangled_vertices"] = info["moved_vertices"]
        if fold_guard and info["moved_vertices"]:
            out, more, left = self._unfold_untangled(out, pairs)
            extra["unfolded_vertices"] += more
            info["crossings_left"] = left if left is not None else info["crossings_left"]
        if bound is not None and info["moved_vertices"]:
            out, more = self._components_after_untangling(out, pairs, bound, blended)
            extra["untangled_vertices"] += more
        if info["crossings_left"]:
            warnings.append(f"{info['crossings_left']} pairs of faces still cross after "
                            "smoothing (the unsmoothed surface crosses itself there)")
        return out

    def _components_after_untangling(self, out, pairs, bound: float, blended: set,
                                     rounds: int = 3):
        """Untangling pulls vertices toward their unsmoothed positions, which can move a small
        component's volume: blend those outside ``bound`` back, untangle around them, and so on
        for ``rounds`` rounds; any still outside goes back to its unsmoothed positions. Returns
        (float32 positions, vertices untangled)."""
        comps, s, moved = self.components(), self.structure, 0
        fail = comps.failing(out, bound)
        for _ in range(rounds):
            if fail.size == 0:
                return out, moved
            blended.update(fail.tolist())
            verts = comps.blend(out, fail, bound)
            out, info = untangle_crossings(out, self.surfaces.vertices, self.faces, pairs=pairs,
                                           structure=s, in_place=True,
                                           active=faces_around(s, verts))
            moved += info["moved_vertices"]
            fail = comps.failing(out, bound)
        for _ in range(comps.n if fail.size else 0):  # straight back: ends when all are raw
            blended.update(fail.tolist())
            comps.blend(out, fail, bound, exact=True)
            fail = comps.failing(out, bound)
            if fail.size == 0:
                break
        return out, moved

    def _unfold_untangled(self, out: np.ndarray, pairs, rounds: int = 3):
        """Untangling pulls vertices part of the way back and can fold a few faces: unfold
        them, then untangle around the vertices that moved, until neither finds anything.
        Returns (float32 positions, vertices unfolded, crossings left or None)."""
        s, unfolded, left = self.structure, 0, None
        for _ in range(rounds):
            bad = folded_faces(out, self.rest, s)  # memory: a float64 copy only if needed
            if bad.size == 0:
                break
            pos, touched = out.astype(np.float64), np.zeros(len(out), np.bool_)
            unfolded += unfold_in_place(pos, self.rest, s, touched=touched, bad=bad)
            out = pos.astype(np.float32)
            del pos  # memory: untangled in place, the float32 positions only
            out, info = untangle_crossings(out, self.surfaces.vertices, self.faces, pairs=pairs,
                                           structure=s, in_place=True,
                                           active=faces_around(s, np.flatnonzero(touched)))
            left = info["crossings_left"]
        return out, unfolded, left

    def measure(self, vertices: np.ndarray, *, distances: bool = True, topology: bool = True,
                volume_warning_pct: float = 5.0) -> Tuple[Dict, list]:
        """Per-shell measures of smoothed ``vertices`` (N, 3) against the unsmoothed set
        (:class:`~anatomesh.core.smooth.shell_measures.ShellMeasures`) and their warnings."""
        shells = self.measures().measure(np.ascontiguousarray(vertices, np.float64),
                                         distances=distances, topology=topology)
        warnings = []
        for value, r in zip(self.surfaces.values(), shells.values()):
            info = self.surfaces.labels.get(value)
            name = info.name if info is not None else "surface"
            key = shell_key(self.surfaces.shell_values.get(value, value))
            warnings += shell_warnings(f"{name} ({key})", r, volume_warning_pct)
        return shells, warnings

    def release(self) -> None:
        """Free what only the guards and passes use (the face buckets, the volume regions, the
        cell boxes, the structure's padded rings and buffers; rebuilt if needed): a one-shot
        run measures without them, so its peak memory is the larger of the two steps, not
        their sum."""
        for key in [k for k, v in self._cache.items()
                    if k in ("boxes", "regions", "components") or id(v) in self._cells]:
            del self._cache[key]
        self._cells.clear()
        self.structure.release_buffers()

    def smooth(self, method: str = DEFAULT, *, measure: bool = True, distances: bool = True,
               topology: bool = True, volume_warning_pct: float = 5.0, keep: bool = True,
               **settings) -> Tuple[SurfaceSet, SmoothingReport]:
        """:meth:`run`, then the smoothed set and its :class:`SmoothingReport` (per-shell
        measures when ``measure``; ``distances`` adds the Hausdorff and mean distances,
        ``topology`` each shell's topology).
        ``keep=False``: :meth:`release` the guards' caches before measuring (one-shot runs)."""
        vertices, info = self.run(method, keep=keep, **settings)
        out = self.surfaces.copy_with_vertices(vertices)
        shells, warnings = {}, list(info["warnings"])
        if measure and info["method"] != "none":
            shells, more = self.measure(vertices, distances=distances, topology=topology,
                                        volume_warning_pct=volume_warning_pct)
            warnings += more
        return out, SmoothingReport(info["method"], info["params"], info["seconds"], shells,
                                    warnings)
