"""Levels of detail from one decimation run: a progressive mesh.

Hoppe 1996 ("Progressive meshes", SIGGRAPH) stores a mesh as a coarse base mesh ``M0`` plus the
sequence of vertex splits that refine it back to the full mesh ``Mn``; every prefix of the
sequence is a valid mesh. Here the sequence comes from one run of Anatomesh's quadric edge
collapse (:mod:`anatomesh.core.decimate.qem`, Garland & Heckbert 1997): the run goes as far as the
coarsest level and logs every collapse as arrays —

* ``keep``, ``drop`` (C,) int32: collapse ``i`` merged vertex ``drop`` into ``keep``;
* ``where`` (C, 3) float64: the position ``keep`` moved to (the vertex split record of Hoppe's
  ``vsplit``: the split undoes it);
* ``face_death`` (M,) int32: the collapse that removed each input face (C when it survives).

Level ``k`` is the mesh after the first ``collapses_per_level[k]`` collapses. It is rebuilt
exactly — bit for bit the arrays the decimation run held after that many collapses — without
re-running anything: a backwards pass over the log prefix maps every input vertex to the vertex
it became, the faces alive are those that die later, positions are the last ones written
(a numba replay of the log prefix; O(N + M) per level).

Every level keeps what the run keeps: each label's shell closed, 2-manifold and outward with its
components and genus, seams between labels shared (interfaces stored once), junction curves in
place. ``M0`` is by default the coarsest mesh the run reaches with all of that intact (every
remaining collapse would break topology, a junction or triangle quality).

Example
-------
>>> pm = progressive(surface_set, levels=4)          # M0 coarsest ... M3 the input
>>> pm.faces_per_level                                # e.g. [41122, 88000, 183000, 381048]
>>> lod0 = pm.level(0)                               # a SurfaceSet (a Mesh for a Mesh input)
>>> pm = progressive(mesh, face_ratios=[0.05, 0.2, 0.5])   # levels at 5 %, 20 %, 50 %, 100 %
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, List, Optional, Sequence, Union

import numpy as np

from . import engine
from ._replay_kernels import replay_collapses
from ..model.errors import AnatomeshError
from ..model.mesh import Mesh
from ..model.progress import Progress, report
from ..model.surfaceset import SurfaceSet


@dataclass
class ProgressiveMesh:
    """A mesh or SurfaceSet with its logged collapse sequence; any level is rebuilt on demand.

    Attributes
    ----------
    source : Mesh or SurfaceSet
        The input (the finest level); levels are built as copies of it.
    centre : (3,) float64
        The run worked on ``vertices - centre`` (mm); outputs add it back.
    positions : (N, 3) float64
        Input vertex positions minus ``centre``, mm.
    faces : (M, 3) int32
        Input faces.
    face_labels : (M, 2) int32 or None
        Input (inside, outside) labels (SurfaceSet input).
    keep, drop : (C,) int32
        Collapse ``i`` merged ``drop[i]`` into ``keep[i]``.
    where : (C, 3) float64
        Position of ``keep[i]`` after collapse ``i`` (centred, mm).
    face_death : (M,) int32
        Index of the collapse that removed each face; ``C`` for faces of the coarsest level.
    collapses_per_level : (L,) int64
        Collapses applied at each level, coarsest (``C``) first, the input (0) last.
    """

    source: object
    centre: np.ndarray
    positions: np.ndarray
    faces: np.ndarray
    face_labels: Optional[np.ndarray]
    keep: np.ndarray
    drop: np.ndarray
    where: np.ndarray
    face_death: np.ndarray
    collapses_per_level: np.ndarray

    @property
    def n_levels(self) -> int:
        return int(len(self.collapses_per_level))

    @property
    def n_collapses(self) -> int:
        return int(len(self.keep))

    @property
    def faces_per_level(self) -> List[int]:
        """Faces of each level, coarsest first (the last is the input's count)."""
        return [self.faces_after(c) for c in self.collapses_per_level]

    def faces_after(self, collapses: int) -> int:
        """Faces left after the first ``collapses`` collapses."""
        return int(np.count_nonzero(self.face_death >= collapses))

    def level(self, k: int):
        """Level ``k`` (0 = coarsest, ``n_levels - 1`` = the input) as the input's type: a
        :class:`Mesh` (name, value, colour, space kept; normals dropped) or a SurfaceSet (lattice
        and split rows carried over, seams shared)."""
        if not -self.n_levels <= k < self.n_levels:
            raise AnatomeshError(f"level {k} does not exist: this progressive mesh has "
                                 f"{self.n_levels} levels (0 = coarsest .. {self.n_levels - 1})")
        return self.at(int(self.collapses_per_level[k]))

    def levels(self) -> list:
        """All levels, coarsest first."""
        return [self.level(k) for k in range(self.n_levels)]

    def arrays(self, collapses: int):
        """``(vertices (N', 3) float32 mm, faces (M', 3) int32, face_labels (M', 2) or None,
        vertex_ids (N',), face_ids (M',))`` after the first ``collapses`` collapses — the
        decimation's own compaction: surviving faces and vertices in input order."""
        c = int(collapses)
        if not 0 <= c <= self.n_collapses:
            raise AnatomeshError(f"collapses must be in [0, {self.n_collapses}], got {collapses}")
        rep, pos = replay_collapses(self.keep, self.drop, self.where, c, self.positions)
        face_ids = np.flatnonzero(self.face_death >= c)
        f = rep[self.faces[face_ids]]
        used = np.flatnonzero(np.bincount(f.ravel(), minlength=len(pos)))
        remap = np.full(len(pos), -1, np.int64)
        remap[used] = np.arange(used.size)
        v = (pos[used] + self.centre).astype(np.float32)
        fl = self.face_labels[face_ids] if self.face_labels is not None else None
        return v, remap[f].astype(np.int32), fl, used, face_ids

    def at(self, collapses: int):
        """The mesh (or SurfaceSet) after the first ``collapses`` collapses."""
        v, f, fl, vertex_ids, face_ids = self.arrays(collapses)
        src = self.source
        if isinstance(src, Mesh):
            return Mesh(v, f, None, name=src.name, value=src.value, color=src.color,
                        space=src.space, meta=dict(src.meta, lod_collapses=int(collapses)))
        return engine.surfaces_result(src, v, f, fl, vertex_ids, face_ids)

    def measure(self, k: int, values: Optional[Sequence[int]] = None) -> Dict:
        """Per shell of level ``k`` against the input: ``faces_before``, ``faces_after``,
        ``hausdorff_mm``, ``mean_mm`` (symmetric, exact point-to-triangle distances) and
        ``volume_change_pct`` — the measures :func:`anatomesh.core.decimate.qem.decimate` reports;
        keyed by label value (``None`` for a Mesh). ``values``: the labels to measure (default
        all but the background)."""
        if not -self.n_levels <= k < self.n_levels:
            raise AnatomeshError(f"level {k} does not exist (0 .. {self.n_levels - 1})")
        v, f, fl, _, _ = self.arrays(int(self.collapses_per_level[k]))
        if self.face_labels is None:
            values = None
        elif values is None:
            values = self.source.values()
        else:
            values = [int(x) for x in values]
        v0 = np.asarray(self.source.vertices, np.float64)
        return engine.measure_shells(v0, self.faces, self.face_labels, v, f, fl, values)


def progressive(surfaces_or_mesh, *, levels: int = 4, face_ratios: Optional[Sequence[float]] = None,
                coarsest: Union[None, float] = None, locked=None,
                progress: Optional[Progress] = None, max_normal_angle: float = 60.0,
                min_quality: float = 0.05) -> ProgressiveMesh:
    """Decimate once, logging every collapse, and choose the levels of detail.

    Parameters
    ----------
    surfaces_or_mesh : Mesh or SurfaceSet
        A closed surface (vertices mm) or a multi-label SurfaceSet (all labels at once, seams
        shared; vertices of faces with split rows are locked, as in ``decimate_surfaces``).
    levels : int >= 2
        Number of levels when ``face_ratios`` is not given: face counts spaced geometrically from
        the coarsest to the input.
    face_ratios : sequence of floats in (0, 1], optional
        Face fractions of the levels (the input, 1.0, is always the last level); the run stops at
        the smallest.
    coarsest : float in (0, 1], optional
        With ``levels``: stop the run at this face fraction instead of the coarsest mesh that
        keeps the topology.
    locked : vertices that must not move (bool mask or indices).
    progress : callable(fraction, text), optional
    max_normal_angle, min_quality : triangle-quality guards, as in ``decimate``.

    Returns
    -------
    ProgressiveMesh
        ``.level(k)`` for k = 0 (coarsest) .. ``n_levels - 1`` (the input).
    """
    if isinstance(surfaces_or_mesh, SurfaceSet):
        lock, _ = engine.surface_lock(surfaces_or_mesh, locked)
        fl_in = surfaces_or_mesh.face_labels
    elif isinstance(surfaces_or_mesh, Mesh):
        lock, fl_in = locked, None
    else:
        raise AnatomeshError(f"progressive needs a Mesh or a SurfaceSet, got "
                             f"{type(surfaces_or_mesh).__name__}")
    ratios = _check_levels(levels, face_ratios, coarsest)
    p = engine.prepare(surfaces_or_mesh.vertices, surfaces_or_mesh.faces, fl_in, lock,
                       max_normal_angle, min_quality)
    m = len(p.f)
    final = int(round(min(ratios) * m)) if ratios is not None else int(round((coarsest or 0.0) * m))
    keep, drop, where, death = run(p, final, progress).log
    pm = ProgressiveMesh(surfaces_or_mesh, p.centre, p.v64, p.f, p.fl, keep, drop, where, death,
                         np.zeros(0, np.int64))
    pm.collapses_per_level = _choose_levels(death, len(keep), m, levels, ratios)
    report(progress, 1.0, "levels of detail ready")
    return pm


def lod_meshes(surfaces_or_mesh, *, levels: int = 4, face_ratios: Optional[Sequence[float]] = None,
               **options) -> list:
    """All levels of :func:`progressive`, coarsest first (Meshes or SurfaceSets)."""
    return progressive(surfaces_or_mesh, levels=levels, face_ratios=face_ratios, **options).levels()


# ---------------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------------
def _check_levels(levels, face_ratios, coarsest):
    if face_ratios is None:
        if not isinstance(levels, (int, np.integer)) or levels < 2:
            raise AnatomeshError(f"levels must be a whole number >= 2 (coarsest .. the input), "
                                 f"got {levels!r}")
        if coarsest is not None and not 0.0 < float(coarsest) <= 1.0:
            raise AnatomeshError(f"coarsest is a face fraction in (0, 1], got {coarsest}")
        return None
    try:
        r = np.asarray([float(x) for x in face_ratios])
    except (TypeError, ValueError):
        raise AnatomeshError(f"face_ratios must be numbers in (0, 1], got {face_ratios!r}")
    if r.size == 0 or np.any(~(r > 0.0)) or np.any(r > 1.0):
        raise AnatomeshError(f"face_ratios must be fractions of the faces in (0, 1], "
                             f"got {list(face_ratios)}")
    return np.unique(np.r_[r, 1.0])


def run(p: engine.Prepared, final_faces: int, progress: Optional[Progress] = None,
        stop_after: Optional[int] = None) -> engine.Collapsed:
    """One logged collapse run of prepared inputs down to ``final_faces`` (or stopped after
    ``stop_after`` collapses); ``.log`` holds the sequence (:func:`engine.collapse`)."""
    size = len(p.v) if stop_after is None else int(stop_after)
    lim = engine.limits("target_faces", int(final_faces), p)
    return engine.collapse(p, lim, progress, log_size=size, log_stop=stop_after is not None)


def _choose_levels(death, n_collapses, m, levels, ratios):
    """Collapse counts of the levels, coarsest first: for each face target the fewest
    collapses that reach it (the coarsest level is the whole run)."""
    # faces alive after c collapses: m - #(death < c); non-increasing in c
    dead_before = np.bincount(np.minimum(death, n_collapses), minlength=n_collapses + 1)
    alive = m - np.concatenate([[0], np.cumsum(dead_before[:-1])])      # (C + 1,)
    f_min = int(alive[-1])
    if ratios is None:
        t = np.arange(levels) / (levels - 1)
        targets = np.round(f_min * (m / max(f_min, 1)) ** t).astype(np.int64)
    else:
        targets = np.round(ratios * m).astype(np.int64)
    targets[-1] = m
    # fewest collapses c with alive[c] <= target (alive is non-increasing)
    c = np.searchsorted(-alive, -targets, side="left")
    c = np.minimum(c, n_collapses)
    c[-1] = 0
    out = np.maximum.accumulate(c[::-1])[::-1]       # coarser levels never have fewer collapses
    return np.unique(out)[::-1].astype(np.int64)
