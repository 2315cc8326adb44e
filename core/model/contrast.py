"""Colour contrast between touching structures: CIELAB, CIE76 ΔE, and moving colours apart.

Two structures that touch must not look alike: :func:`separate_colors` moves label colours (mostly
CIELAB lightness L*, a little hue and chroma, never far) until every touching pair differs by at
least ``target`` CIE76 ΔE (the Euclidean distance in CIELAB; a ΔE of about 2.3 is a just
noticeable difference, Sharma 2003, *Digital Color Imaging Handbook*, ch. 1). Pairs of bones
(neighbouring vertebrae, ribs) only need a small step: they are one system and read as one.

Colours are sRGB (IEC 61966-2-1) in [0, 1]; CIELAB uses the D65 white point.
:func:`touching_pairs` finds the pairs: the shared faces of a label map's set, or, for
independent surfaces, shells that come within one voxel of each other.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Dict, Iterable, List, Mapping, Set, Tuple

import numpy as np

from .labels import LabelInfo, linear_to_srgb, srgb_to_linear

#: the smallest CIE76 ΔE between touching structures
TARGET_DELTA_E = 12.0
#: between two bones (one system): a small step, so neighbouring vertebrae stay told apart
BONE_DELTA_E = 3.0
#: how far a colour may move: lightness L*, and hue angle (degrees) / chroma factor steps
_L_STEPS = (0, 5, -5, 10, -10, 15, -15, 20, -20, 25, -25, 30, -30)
_HUE_STEPS = (0.0, 10.0, -10.0, 20.0, -20.0)
_CHROMA_STEPS = (1.0, 1.3, 0.75)
_MARGIN = 0.6  # ΔE kept above the target, so 8-bit colour files still meet it

_WHITE = np.array([0.95047, 1.0, 1.08883])
_M = np.array([[0.4124564, 0.3575761, 0.1804375],
               [0.2126729, 0.7151522, 0.0721750],
               [0.0193339, 0.1191920, 0.9503041]])
_M_INV = np.linalg.inv(_M)


def srgb_to_lab(rgb) -> np.ndarray:
    """sRGB in [0, 1] (..., 3) → CIELAB (..., 3) (L* 0..100, D65)."""
    xyz = srgb_to_linear(np.clip(np.asarray(rgb, np.float64), 0, 1)) @ _M.T / _WHITE
    f = np.where(xyz > (6 / 29) ** 3, np.cbrt(xyz), xyz / (3 * (6 / 29) ** 2) + 4 / 29)
    return np.stack([116 * f[..., 1] - 16, 500 * (f[..., 0] - f[..., 1]),
                     200 * (f[..., 1] - f[..., 2])], axis=-1)


def lab_to_srgb(lab) -> np.ndarray:
    """CIELAB (..., 3) → sRGB (..., 3), clipped to [0, 1] (colours outside the gamut move in)."""
    lab = np.asarray(lab, np.float64)
    fy = (lab[..., 0] + 16) / 116
    f = np.stack([fy + lab[..., 1] / 500, fy, fy - lab[..., 2] / 200], axis=-1)
    xyz = np.where(f > 6 / 29, f ** 3, 3 * (6 / 29) ** 2 * (f - 4 / 29)) * _WHITE
    return np.clip(linear_to_srgb(np.clip(xyz @ _M_INV.T, 0, 1)), 0, 1)


def delta_e(rgb1, rgb2) -> float:
    """CIE76 ΔE between two sRGB colours in [0, 1]."""
    return float(np.linalg.norm(srgb_to_lab(tuple(rgb1)[:3]) - srgb_to_lab(tuple(rgb2)[:3])))


def pair_target(a: LabelInfo, b: LabelInfo, target: float = TARGET_DELTA_E) -> float:
    """The ΔE two touching structures need: ``target``, or :data:`BONE_DELTA_E` for two bones."""
    return BONE_DELTA_E if a.material == "bone" and b.material == "bone" else target


def separate_colors(table: Mapping[int, LabelInfo], pairs: Iterable[Tuple[int, int]],
                    fixed: Iterable[int] = (), target: float = TARGET_DELTA_E) -> Dict[int, LabelInfo]:
    """``table`` with colours moved so every touching pair differs by ``target`` ΔE (CIE76).

    Parameters
    ----------
    table : dict int → LabelInfo
        Label colours (sRGB 0..1) and materials (two ``"bone"`` labels need only
        :data:`BONE_DELTA_E`).
    pairs : iterable of (a, b)
        Touching label values (e.g. :meth:`SurfaceSet.interfaces`); values not in ``table`` are
        ignored.
    fixed : values whose colour must not change (the user's explicit colours).
    target : float
        The ΔE every other pair must reach.

    Returns
    -------
    A new table (the same entries, moved colours). Deterministic: labels are placed in order of
    their number of contacts (then value), each at the nearest candidate colour — lightness steps
    of 5 up to ±30 L*, hue turns up to ±20°, chroma ×0.75..1.3 — that clears all its placed
    neighbours; then a few passes revisit labels that still clash. A pair that cannot be cleared
    within those bounds keeps the best colour found (its ΔE is the largest reachable).
    """
    table = dict(table)
    fixed = {v for v in fixed if v in table}
    neighbours: Dict[int, Set[int]] = {v: set() for v in table}
    for a, b in pairs:
        if a in table and b in table and a != b:
            neighbours[a].add(b)
            neighbours[b].add(a)
    lab = {v: srgb_to_lab(table[v].color[:3]) for v in table}
    movable = sorted((v for v in table if neighbours[v] and v not in fixed),
                     key=lambda v: (-len(neighbours[v]), v))
    choices = {v: _candidates(lab[v]) for v in movable}
    placed = set(fixed)
    for v in movable:
        lab[v] = _best(choices[v], _needs(v, neighbours, lab, placed, table, target))
        placed.add(v)
    for _ in range(4):  # revisit the labels that still clash, with every neighbour placed
        clashing = [v for v in movable
                    if _gaps(lab[v][None], *_needs(v, neighbours, lab, placed, table, target))[0] < 0]
        if not clashing:
            break
        for v in clashing:
            lab[v] = _best(choices[v], _needs(v, neighbours, lab, placed, table, target))
    out = {}
    for v, info in table.items():
        moved = v in movable and not np.array_equal(lab[v], choices[v][0])  # [0]: its own colour
        rgb = tuple(float(round(c, 4)) for c in lab_to_srgb(lab[v])) if moved else info.color
        out[v] = dataclasses.replace(info, color=tuple(rgb))
    return out


def _steps() -> np.ndarray:
    """Candidate moves (lightness, hue turn in radians, chroma factor), (K, 3), nearest first."""
    rows = [(abs(dl) + 0.6 * abs(dh) + 20 * abs(math.log(k)), i, dl, math.radians(dh), k)
            for i, (dh, k, dl) in enumerate((dh, k, dl) for dh in _HUE_STEPS
                                            for k in _CHROMA_STEPS for dl in _L_STEPS)]
    return np.array([r[2:] for r in sorted(rows)])


_STEPS = _steps()


def _candidates(base: np.ndarray) -> np.ndarray:
    """Colours near ``base`` (CIELAB), (K, 3), nearest first (lightness steps before hue and
    chroma), each as the files hold it (back from sRGB); the first is ``base`` itself."""
    chroma = math.hypot(base[1], base[2]) * _STEPS[:, 2]
    hue = math.atan2(base[2], base[1]) + _STEPS[:, 1]
    lab = np.stack([base[0] + _STEPS[:, 0], chroma * np.cos(hue), chroma * np.sin(hue)], axis=1)
    return srgb_to_lab(lab_to_srgb(lab))


def _needs(v, neighbours, lab, placed, table, target) -> Tuple[np.ndarray, np.ndarray]:
    """``v``'s placed neighbours' colours (N, 3) and the ΔE each pair needs (N,)."""
    others = [n for n in sorted(neighbours[v]) if n in placed]
    colours = np.array([lab[n] for n in others]).reshape(-1, 3)
    return colours, np.array([pair_target(table[v], table[n], target) for n in others]) + _MARGIN


def _gaps(candidates: np.ndarray, colours: np.ndarray, needed: np.ndarray) -> np.ndarray:
    """For each candidate (K, 3): the smallest ΔE minus the need over the neighbours (≥ 0: all
    clear; +inf without neighbours)."""
    if len(colours) == 0:
        return np.full(len(candidates), np.inf)
    d = np.linalg.norm(candidates[:, None, :] - colours[None, :, :], axis=2)
    return (d - needed[None, :]).min(axis=1)


def _best(candidates: np.ndarray, needs) -> np.ndarray:
    """The first candidate that clears every neighbour, else the one that comes closest."""
    gaps = _gaps(candidates, *needs)
    clear = np.flatnonzero(gaps >= 0)
    return candidates[clear[0] if len(clear) else int(np.argmax(gaps))]


def min_pair_delta_e(table: Mapping[int, LabelInfo], pairs: Iterable[Tuple[int, int]],
                     skip_bones: bool = True) -> Tuple[float, Tuple[int, int]]:
    """The smallest ΔE over touching pairs (two bones left out when ``skip_bones``) and its pair."""
    best = (math.inf, (0, 0))
    for a, b in pairs:
        if a not in table or b not in table:
            continue
        if skip_bones and table[a].material == "bone" and table[b].material == "bone":
            continue
        best = min(best, (delta_e(table[a].color, table[b].color), (a, b)))
    return best


def touching_pairs(surfaces) -> List[Tuple[int, int]]:
    """Touching label pairs (a < b) of a :class:`~anatomesh.core.model.surfaceset.SurfaceSet`:
    labels sharing faces, for a label map; for independent surfaces (no lattice), pairs of
    shells with vertices within one voxel (the largest spacing of ``affine``) of each other."""
    values = surfaces.values()
    if len(values) < 2:
        return []
    if surfaces.lattice is None:
        return _near_pairs(surfaces, values)
    fl, bg = surfaces.face_labels, surfaces.background
    top = int(fl.max()) + 1
    if top > 4096:  # many label values: the set's own (sorting) pass
        return [(a, b) for a, b, _ in surfaces.interfaces()]
    seen = np.zeros((top, top), np.bool_)
    for start in range(0, len(fl), 1 << 20):  # memory: index arrays of one chunk at a time
        chunk = fl[start:start + (1 << 20)]
        seen[chunk[:, 0], chunk[:, 1]] = True
    seen |= seen.T
    return [(int(a), int(b)) for a, b in zip(*np.nonzero(np.triu(seen, 1)))
            if a != bg and b != bg]


def _near_pairs(surfaces, values) -> List[Tuple[int, int]]:
    from scipy.spatial import cKDTree

    gap = float(np.linalg.norm(surfaces.affine[:3, :3], axis=0).max())
    inside = surfaces.face_labels[:, 0]
    points = {v: surfaces.vertices[np.unique(surfaces.faces[inside == v])] for v in values}
    boxes = {v: (p.min(axis=0) - gap, p.max(axis=0) + gap) for v, p in points.items() if len(p)}
    trees, out = {}, []
    for i, a in enumerate(values):
        for b in values[i + 1:]:
            if a not in boxes or b not in boxes or np.any(boxes[a][1] < boxes[b][0]) or \
                    np.any(boxes[b][1] < boxes[a][0]):
                continue
            tree = trees.setdefault(a, cKDTree(points[a]))
            d, _ = tree.query(points[b], k=1, distance_upper_bound=gap)
            if np.isfinite(d).any():
                out.append((a, b))
    return out
