"""The :class:`SurfaceSet`: one conforming surface for many labels, and per-label shell views.

Every face between two different labels (or a label and the background) is stored once, with
the two labels on its sides. Where two labels touch they share the very same vertices, so shells
built from the set have bit-identical seams. A label's closed shell is a *view*: its faces,
oriented outward, with a few vertex copies (``splits``) that keep the shell 2-manifold where the
label touches itself along an edge or at a point (see ``extract/shell_table.py``).

Each vertex of a label map's set keeps the lattice point it came from: lattice point (a, b, c)
sits at voxel-index position (a - 0.5, b - 0.5, c - 0.5), a voxel corner. Constrained smoothing (Gibson 1998,
"Constrained elastic surface nets") keeps each vertex inside its *cell*, the voxel-sized box
index-space [a - 1, a] x [b - 1, b] x [c - 1, c] mapped to mm by ``affine``.

Independent surfaces (isosurfaces of a scan, one per level; meshes read from files) form a set
too (:meth:`SurfaceSet.from_meshes`): surface k is label k + 1 against the background, with no
shared vertices and no lattice. So every stage takes one type.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Dict, List, Sequence, Tuple

import numpy as np

from . import _surfaceset_kernels as K
from .errors import AnatomeshError
from .mesh import Mesh
from .labels import LabelInfo, rgba


@dataclass
class SurfaceSet:
    """A multi-label surface with shared vertices.

    Attributes
    ----------
    vertices : float32 (N, 3)
        Positions in mm in ``space``.
    faces : int32 (M, 3)
        Triangles; the normal (counter-clockwise, right hand) points from ``face_labels[:, 0]``
        to ``face_labels[:, 1]``.
    face_labels : int32 (M, 2)
        (inside, outside) label values of each triangle. The background value (``background``,
        stored as is) is only ever the outside label.
    lattice : int32 (N, 3) or None
        Lattice point of each vertex (see module docstring); None for a set of independent
        surfaces (:meth:`from_meshes`), whose vertices are not on a voxel lattice.
    affine : float64 (4, 4)
        The volume's voxel index → mm affine (at voxel centres).
    space : "RAS" or "LPS"
    labels : dict[int, LabelInfo]
        Name and colour of each label value present.
    splits : int32 (S, 4)
        Rows (face, side, corner, copy), copy >= 1: in the shell of label
        ``face_labels[face, side]``, corner ``corner`` of triangle ``face`` uses extra copy
        ``copy`` of vertex ``faces[face, corner]`` — at the same position, a separate vertex of
        that shell. Ordered by face.
    background : int
        The background value of the label map.
    voxel_counts : dict[int, int]
        Voxels of each label value present (the raw shells enclose exactly count x voxel volume).
    warnings : list[str]
        Problems that did not stop extraction (e.g. a requested label not in the volume).
    shell_values : dict[int, float]
        The ``value`` a label's shell reports when it is not the label itself (the isovalue of
        an isosurface set's label); empty for label maps.
    """

    vertices: np.ndarray
    faces: np.ndarray
    face_labels: np.ndarray
    lattice: np.ndarray
    affine: np.ndarray
    space: str = "RAS"
    labels: Dict[int, LabelInfo] = field(default_factory=dict)
    splits: np.ndarray = field(default_factory=lambda: np.zeros((0, 4), np.int32))
    background: int = 0
    voxel_counts: Dict[int, int] = field(default_factory=dict)
    warnings: List[str] = field(default_factory=list)
    shell_values: Dict[int, float] = field(default_factory=dict)

    def __post_init__(self):
        self.vertices = np.ascontiguousarray(self.vertices, np.float32).reshape(-1, 3)
        self.faces = np.ascontiguousarray(self.faces, np.int32).reshape(-1, 3)
        self.face_labels = np.ascontiguousarray(self.face_labels, np.int32).reshape(-1, 2)
        if self.lattice is not None:
            self.lattice = np.ascontiguousarray(self.lattice, np.int32).reshape(-1, 3)
        self.affine = np.asarray(self.affine, np.float64)
        self.splits = np.ascontiguousarray(self.splits, np.int32).reshape(-1, 4)
        if (self.lattice is not None and len(self.lattice) != len(self.vertices)) or \
                len(self.face_labels) != len(self.faces):
            raise ValueError("vertices/lattice or faces/face_labels lengths differ")

    @classmethod
    def from_meshes(cls, meshes: Sequence[Mesh], affine: np.ndarray, space: str = "RAS") -> "SurfaceSet":
        """Independent surfaces as one set: mesh k becomes label k + 1 (faces inside k + 1,
        outside the background 0), vertices stacked, no lattice. Each shell gives back its mesh
        (name, colour, ``value``; ``meta["vertex_ids"]`` into the stacked vertices).

        ``affine``: the voxel → mm matrix of the volume the surfaces came from (smoothing boxes
        each vertex in a voxel around its start); ``space`` the meshes' space."""
        meshes = list(meshes)
        offsets = np.cumsum([0] + [m.n_vertices for m in meshes])
        rows = np.cumsum([0] + [m.n_faces for m in meshes])
        # memory: the set's int32 arrays filled mesh by mesh, no int64 copies to convert
        faces = np.empty((rows[-1], 3), np.int32)
        labels = np.zeros((rows[-1], 2), np.int32)
        for k, m in enumerate(meshes):
            np.add(m.faces, offsets[k], out=faces[rows[k]:rows[k + 1]], casting="unsafe")
            labels[rows[k]:rows[k + 1], 0] = k + 1
        table = {k + 1: LabelInfo(k + 1, m.name or f"surface {k + 1}", rgba(m.color)[:3],
                                  m.meta.get("material", "other"), rgba(m.color)[3])
                 for k, m in enumerate(meshes)}
        return cls(np.concatenate([m.vertices for m in meshes] or [np.zeros((0, 3))]),
                   faces, labels, None, affine, space, table,
                   shell_values={k + 1: m.value for k, m in enumerate(meshes)
                                 if m.value is not None})

    def __repr__(self) -> str:
        return (f"SurfaceSet({self.n_vertices:,} vertices, {self.n_faces:,} faces, "
                f"labels {_short_list(self.values(), 8)}, {len(self.splits)} split rows, "
                f"space {self.space}, background {self.background})")

    @property
    def n_vertices(self) -> int:
        return int(self.vertices.shape[0])

    @property
    def n_faces(self) -> int:
        return int(self.faces.shape[0])

    def values(self) -> List[int]:
        """Label values that have faces, ascending (the background excluded)."""
        if self.face_labels.size == 0:
            return []
        if int(self.face_labels.min()) < 0:
            raise AnatomeshError("face_labels must be non-negative label values")
        seen = np.zeros(int(self.face_labels.max()) + 1, np.bool_)
        K.mark_present(self.face_labels, seen)  # one pass in a kernel, no temporary arrays
        return [int(v) for v in np.flatnonzero(seen) if v != self.background]

    def shell(self, value: int) -> Mesh:
        """The closed, outward-oriented shell of one label as a :class:`Mesh`.

        Vertices are compacted (shared ones first, then the split copies); ``meta["vertex_ids"]``
        gives, for each shell vertex, its index in this set's ``vertices`` (so results computed on
        the set map back, and vice versa); ``meta["copies"]`` counts the split copies, which sit
        at the position of their shared vertex (the last ``copies`` vertices, in the order of
        their copy numbers). Files show the shells with their pinch points resolved
        (:mod:`anatomesh.core.geometry.pinches`).

        Raises
        ------
        AnatomeshError
            When the label has no faces in this set.
        """
        value = int(value)
        present = self.values()
        if value not in present:
            raise AnatomeshError(
                f"label {value} has no surface here; labels present: {_short_list(present)}")
        return self._shells([value])[0]

    def shells(self) -> List[Mesh]:
        """The shells of all labels, ascending by value (one pass over the faces)."""
        return self._shells(self.values())

    def _shells(self, values: List[int]) -> List[Mesh]:
        if not values:
            return []
        index = np.full(max(max(values), self.background, int(self.face_labels.max())) + 1,
                        -1, np.int64)
        index[np.asarray(values)] = np.arange(len(values))
        order, starts = self._grouped_faces(index, len(values))
        split_label = self.face_labels[self.splits[:, 0], self.splits[:, 1]] if len(self.splits) \
            else np.zeros(0, np.int32)
        mark = np.full(self.n_vertices, -1, np.int64)
        out = []
        for g, value in enumerate(values):
            rows = self.splits[split_label == value]
            rows = rows[np.argsort(rows[:, 0], kind="stable")]  # by face, as the kernel reads them
            # distinct (vertex, copy) pairs; a lattice corner has at most 4 fans, so copy < 16
            keys = self.faces[rows[:, 0], rows[:, 2]].astype(np.int64) * 16 + rows[:, 3]
            ukeys, copy_index = np.unique(keys, return_inverse=True)
            entries = order[starts[g]:starts[g + 1]]
            faces, ids = np.empty((entries.size, 3), np.int32), np.empty(3 * entries.size, np.int64)
            n0 = K.shell(self.faces, entries, rows, copy_index.astype(np.int64).reshape(-1), mark,
                         faces, ids)
            ids = np.concatenate([ids[:n0], ukeys // 16])
            info = self.labels.get(value) or LabelInfo(value, f"label {value}")
            out.append(Mesh(self.vertices[ids], faces, name=info.name,
                            value=self.shell_values.get(value, value),
                            color=info.mesh_color(), space=self.space,
                            meta={"vertex_ids": ids, "copies": int(ukeys.size),
                                  "material": info.material}))
        return out

    def _grouped_faces(self, index: np.ndarray, groups: int):
        """``(order, starts)``: the entries ``2 f + side`` of each group's faces
        (:func:`._surfaceset_kernels.group_faces`), group g's at ``order[starts[g]:starts[g + 1]]``."""
        starts = np.zeros(groups + 1, np.int64)
        K.group_faces(self.face_labels, index, starts, np.empty(0, np.int64))
        order = np.empty(starts[-1], np.int64)
        if order.size:
            K.group_faces(self.face_labels, index, starts[:-1].copy(), order)
        return order, starts

    def interfaces(self) -> List[Tuple[int, int, int]]:
        """Pairs of touching labels ``(a, b, triangles)`` with a < b (background excluded)."""
        fl = self.face_labels.astype(np.int64)
        keep = (fl[:, 0] != self.background) & (fl[:, 1] != self.background)
        lo = np.minimum(fl[keep, 0], fl[keep, 1])
        hi = np.maximum(fl[keep, 0], fl[keep, 1])
        keys, counts = np.unique(lo * 65536 + hi, return_counts=True)
        return [(int(k // 65536), int(k % 65536), int(n)) for k, n in zip(keys, counts)]

    def copy_with_vertices(self, new_vertices: np.ndarray) -> "SurfaceSet":
        """The same set with moved vertices (e.g. after smoothing); faces, labels, splits shared."""
        v = np.asarray(new_vertices)
        if v.shape != self.vertices.shape:
            raise ValueError(f"new vertices must have shape {self.vertices.shape}, got {v.shape}")
        return dataclasses.replace(self, vertices=v.astype(np.float32, copy=True),
                                   warnings=list(self.warnings))


def _short_list(values: List[int], n: int = 12) -> str:
    if not values:
        return "none"
    s = ", ".join(str(v) for v in values[:n])
    return s + (f", ... ({len(values)} in all)" if len(values) > n else "")
