"""Structures that may overlap: a :class:`Segmentation` of label-map layers on one grid.

A label map holds one label per voxel, so overlapping structures (a lumen inside the aorta, the
overlapping segments of a DICOM SEG, nested RT structures) cannot share one. Readers of
per-structure inputs (mask folders, DICOM SEG, RTSTRUCT) hand their binary masks to
:func:`segmentation_from_masks`, which keeps every structure whole:

* structures are taken largest first and each goes into the first layer where it overlaps no
  structure already there (greedy colouring of the overlap graph, as 3D Slicer's segmentation
  layers); structures that do not overlap therefore share a layer, where their seams conform;
* every layer is an ordinary label-map :class:`~.volume.Volume` on the same grid; label values
  are unique across layers (structure k of the input is value k + 1), so a surface's value
  names its structure whatever its layer;
* the overlap of every pair of structures is measured in mm³.

When everything fits one layer the result is that layer (a plain label-map Volume); otherwise a
:class:`Segmentation`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from .errors import AnatomeshError
from .labels import LabelInfo
from .volume import Volume

if TYPE_CHECKING:  # pragma: no cover
    from .surfaceset import SurfaceSet


@dataclass
class Mask:
    """One structure's voxels on a grid, cropped to its bounding box.

    ``offset`` (3,) int: index of ``data[0, 0, 0]`` in the grid; ``data`` bool (a, b, c).
    """

    info: LabelInfo
    offset: Tuple[int, int, int]
    data: np.ndarray

    @property
    def voxels(self) -> int:
        return int(np.count_nonzero(self.data))

    def box(self) -> Tuple[np.ndarray, np.ndarray]:
        lo = np.asarray(self.offset, np.int64)
        return lo, lo + np.asarray(self.data.shape, np.int64)


def crop_mask(info: LabelInfo, full: np.ndarray, offset=(0, 0, 0)) -> Optional[Mask]:
    """The :class:`Mask` of the nonzero voxels of ``full`` (None when there are none);
    ``offset`` is the grid index of ``full[0, 0, 0]``."""
    nz = [np.flatnonzero(np.any(full, axis=tuple(a for a in range(3) if a != ax))) for ax in range(3)]
    if any(len(n) == 0 for n in nz):
        return None
    lo = [int(n[0]) for n in nz]
    hi = [int(n[-1]) + 1 for n in nz]
    sub = np.ascontiguousarray(full[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]] != 0)
    return Mask(info, tuple(int(o) + l for o, l in zip(offset, lo)), sub)


@dataclass
class Segmentation:
    """Possibly overlapping structures as label-map layers on one grid.

    Attributes
    ----------
    layers : list of Volume
        Label maps (uint8/uint16) with the same shape, affine and space; within a layer no two
        structures overlap. Label values are unique across layers.
    overlaps : list of dict
        ``{"a": name, "b": name, "voxels": n, "mm3": volume}`` for every overlapping pair.
    meta : dict
        Reader facts (``format``, ``source``, ``resampled``, ``image`` ...).
    warnings : list of str
    """

    layers: List[Volume]
    overlaps: List[Dict] = field(default_factory=list)
    meta: Dict = field(default_factory=dict)
    warnings: List[str] = field(default_factory=list)

    @property
    def affine(self) -> np.ndarray:
        return self.layers[0].affine

    @property
    def space(self) -> str:
        return self.layers[0].space

    @property
    def shape(self) -> Tuple[int, int, int]:
        return self.layers[0].shape

    @property
    def spacing(self) -> Tuple[float, float, float]:
        return self.layers[0].spacing

    @property
    def labels(self) -> Dict[int, LabelInfo]:
        """Every structure's label entry, by value (all layers)."""
        out: Dict[int, LabelInfo] = {}
        for layer in self.layers:
            out.update(layer.labels or {})
        return dict(sorted(out.items()))

    @property
    def is_label_map(self) -> bool:
        return True

    def orientation(self) -> str:
        return self.layers[0].orientation()

    def voxel_volume_mm3(self) -> float:
        return self.layers[0].voxel_volume_mm3()

    def in_space(self, space: str) -> "Segmentation":
        """The same segmentation with every layer's affine in ``space`` (data shared)."""
        return Segmentation([v.in_space(space) for v in self.layers], list(self.overlaps),
                            dict(self.meta), list(self.warnings))

    def layer_of(self) -> Dict[int, int]:
        """Label value → index of its layer."""
        return {v: i for i, layer in enumerate(self.layers) for v in (layer.labels or {})}


def segmentation_from_masks(masks: Sequence[Mask], shape, affine, space: str,
                            meta: Optional[Dict] = None,
                            warnings: Optional[List[str]] = None) -> Union[Volume, Segmentation]:
    """Paint binary masks into as few label-map layers as keep every structure whole.

    Parameters
    ----------
    masks : sequence of Mask
        On the grid ``shape`` / ``affine`` (index → mm at voxel centres) in ``space``; structure k
        becomes label value ``masks[k].info.value`` (values must be distinct and >= 1).
    meta, warnings : reader facts and problems, passed on.

    Returns
    -------
    Volume (one layer: no structures overlap) or Segmentation. Layer assignment: largest
    structure first, each into the first layer where it overlaps nothing (greedy).
    """
    meta = dict(meta or {})
    warnings = list(warnings or [])
    if not masks:
        raise AnatomeshError("no structure has any voxel set, so there is nothing to mesh; check that the masks "
                             "hold the segmentation (values > 0) or choose other structures", meta.get("source"))
    values = [int(m.info.value) for m in masks]
    if len(set(values)) != len(values) or min(values) < 1:
        raise ValueError(f"mask label values must be distinct and >= 1, got {values}")
    pairs = overlap_pairs(masks)
    vox = float(abs(np.linalg.det(np.asarray(affine, np.float64)[:3, :3])))
    overlaps = [{"a": masks[i].info.name, "b": masks[j].info.name, "voxels": n, "mm3": round(n * vox, 3)}
                for (i, j), n in sorted(pairs.items())]
    layer = assign_layers([m.voxels for m in masks], pairs)
    dtype = np.uint8 if max(values) <= 255 else np.uint16
    vols = []
    for li in range(max(layer) + 1):
        data = np.zeros(tuple(int(s) for s in shape), dtype)
        table = {}
        for k in (k for k in range(len(masks)) if layer[k] == li):
            m = masks[k]
            lo, hi = m.box()
            view = data[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]]
            view[m.data] = m.info.value
            table[m.info.value] = m.info
        lmeta = dict(meta, layer=li) if layer.count(li) != len(masks) else dict(meta)
        vols.append(Volume(data, affine, space, lmeta, dict(sorted(table.items())), list(warnings)))
    if len(vols) == 1:
        return vols[0]
    return Segmentation(vols, overlaps, meta, warnings)


def overlap_pairs(masks: Sequence[Mask]) -> Dict[Tuple[int, int], int]:
    """Voxels shared by each overlapping pair ``(i, j)``, i < j (pairs that do not overlap left
    out); only pairs whose bounding boxes meet are compared."""
    boxes = [m.box() for m in masks]
    out: Dict[Tuple[int, int], int] = {}
    for i in range(len(masks)):
        for j in range(i + 1, len(masks)):
            lo = np.maximum(boxes[i][0], boxes[j][0])
            hi = np.minimum(boxes[i][1], boxes[j][1])
            if np.any(hi <= lo):
                continue
            a = _window(masks[i], lo, hi)
            b = _window(masks[j], lo, hi)
            n = int(np.count_nonzero(a & b))
            if n:
                out[(i, j)] = n
    return out


def _window(m: Mask, lo, hi) -> np.ndarray:
    o = np.asarray(m.offset)
    s = lo - o
    e = hi - o
    return m.data[s[0]:e[0], s[1]:e[1], s[2]:e[2]]


def assign_layers(sizes: Sequence[int], pairs: Dict[Tuple[int, int], int]) -> List[int]:
    """Layer index of each structure: largest first (ties in input order), into the first layer
    holding none of the structures it overlaps (greedy graph colouring, Welsh & Powell 1967)."""
    conflicts: Dict[int, set] = {k: set() for k in range(len(sizes))}
    for i, j in pairs:
        conflicts[i].add(j)
        conflicts[j].add(i)
    layer = [-1] * len(sizes)
    for k in sorted(range(len(sizes)), key=lambda k: (-int(sizes[k]), k)):
        taken = {layer[o] for o in conflicts[k] if layer[o] >= 0}
        layer[k] = next(li for li in range(len(sizes) + 1) if li not in taken)
    return layer


def as_layers(volume: Union[Volume, Segmentation]) -> List[Volume]:
    """The label-map layers of a Segmentation, or ``[volume]`` for a Volume."""
    return list(volume.layers) if isinstance(volume, Segmentation) else [volume]


def same_grid_affine(a, b, atol: float = 1e-4) -> bool:
    """True when two 4x4 affines describe the same voxel grid (to ``atol`` mm)."""
    return bool(np.allclose(np.asarray(a), np.asarray(b), atol=atol))


def to_space(volume: Union[Volume, Segmentation], space: Optional[str]):
    """``volume`` with its affine(s) in ``space`` (None: unchanged)."""
    if space is None or space == volume.space:
        return volume
    return volume.in_space(space)




def stack_surface_sets(sets: Sequence["SurfaceSet"]) -> "SurfaceSet":
    """Several SurfaceSets on one grid (the layers of a Segmentation) as one set: vertices
    stacked (layers share none), faces/labels/splits re-indexed; label values must be unique
    across the sets. One set is returned as it is."""
    from .surfaceset import SurfaceSet

    sets = list(sets)
    if len(sets) == 1:
        return sets[0]
    voff = np.cumsum([0] + [s.n_vertices for s in sets])
    foff = np.cumsum([0] + [s.n_faces for s in sets])
    lattice = None if any(s.lattice is None for s in sets) else np.concatenate([s.lattice for s in sets])
    splits = [s.splits.astype(np.int64) + np.array([f, 0, 0, 0]) for s, f in zip(sets, foff[:-1])]
    labels, counts, warnings = {}, {}, []
    for s in sets:
        labels.update(s.labels)
        counts.update(s.voxel_counts)
        warnings += [w for w in s.warnings if w not in warnings]
    return SurfaceSet(np.concatenate([s.vertices for s in sets]),
                      np.concatenate([s.faces.astype(np.int64) + o for s, o in zip(sets, voff[:-1])]),
                      np.concatenate([s.face_labels for s in sets]), lattice, sets[0].affine,
                      sets[0].space, dict(sorted(labels.items())), np.concatenate(splits),
                      sets[0].background, counts, warnings,
                      {k: v for s in sets for k, v in s.shell_values.items()})


@dataclass
class RoiContours:
    """One RT structure's closed planar contours, as read (DICOM RTSTRUCT, LPS mm).

    ``contours``: list of (n, 3) float64 point arrays (the last point joins the first);
    ``planes``: (len(contours),) int, the index of each contour's plane in the stack;
    ``normal`` (3,): the stack's unit normal; ``plane_t``: (P,) position of plane p along it (mm),
    ascending. ``source`` names the file for messages."""

    info: LabelInfo
    contours: List[np.ndarray]
    planes: np.ndarray
    normal: np.ndarray
    plane_t: np.ndarray
    source: str = ""

    def on_plane(self, p: int) -> List[np.ndarray]:
        return [c for c, q in zip(self.contours, self.planes) if q == p]


def in_plane_axes(normal: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Unit in-plane axes (u, v) with u × v = normal; u is the patient x axis projected into the
    plane (or y when x is along the normal)."""
    n = np.asarray(normal, np.float64) / np.linalg.norm(normal)
    x = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = x - (x @ n) * n
    u /= np.linalg.norm(u)
    return u, np.cross(n, u)
