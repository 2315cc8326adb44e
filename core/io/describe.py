"""What a user needs to know about a scan before meshing it (``anatomesh inspect``).

:func:`describe` returns plain JSON-ready facts (the CLI's ``inspect`` prints them).
"""
from __future__ import annotations

from typing import Dict, List, Optional, Tuple, Union

import numpy as np

from ..model.segmentation import Segmentation
from ..model.volume import Volume
from .values import value_counts

#: CT tissue classes by Hounsfield units, used to name histogram peaks
CT_CLASSES = (
    (-np.inf, -900.0, "air"),
    (-900.0, -400.0, "lung"),
    (-400.0, -200.0, "air/tissue mix"),
    (-200.0, -30.0, "fat"),
    (-30.0, 120.0, "soft tissue"),
    (120.0, 300.0, "contrast / dense tissue"),
    (300.0, np.inf, "bone"),
)

HIST_BINS = 48


#: meta entries left out of the facts: large (RT contours) or personal (patient and study identifiers)
PRIVATE_META = ("contours", "dicom_reference")


def describe(volume: Union[Volume, Segmentation], want_histogram: bool = True) -> Dict:
    """Facts about a volume as a JSON-ready dict (``want_histogram=False``: without the scan's
    histogram, which a run's report leaves out).

    Keys: ``format``, ``modality``, ``shape``, ``spacing`` (mm), ``space``, ``orientation`` (3 letters),
    ``affine`` (4x4 nested lists, voxel index → mm in ``space``), ``dtype``, ``min``, ``max``,
    ``extent_mm`` (size of the voxel grid), ``histogram`` (scalar scans: ``edges``, ``counts``,
    ``peaks``), ``labels`` (label maps: list of ``{value, name, color, voxels, volume_mm3}``),
    ``warnings`` and ``meta``. A :class:`Segmentation` (overlapping structures) gives the facts of
    its grid, every structure in ``labels`` (with its ``layer``), ``layers`` (the structures of
    each) and ``overlaps`` (pairs, voxels, mm³).
    """
    if isinstance(volume, Segmentation):
        return _describe_layers(volume, want_histogram)
    data = volume.data
    if volume.is_label_map:  # one counting pass gives the range and each label's voxels
        values, counts = value_counts(data)
        vals = values
    else:
        finite = np.isfinite(data) if data.dtype.kind == "f" else None
        vals = data[finite] if finite is not None and not finite.all() else data
    facts = {
        "format": volume.meta.get("format", "unknown"),
        "modality": volume.meta.get("modality", "label map" if volume.is_label_map else "unknown"),
        "shape": list(volume.shape),
        "spacing": [round(s, 6) for s in volume.spacing],
        "space": volume.space,
        "orientation": volume.orientation(),
        "affine": np.round(volume.affine, 6).tolist(),
        "dtype": str(data.dtype),
        "min": _num(vals.min()) if vals.size else None,
        "max": _num(vals.max()) if vals.size else None,
        "extent_mm": [round(float(s) * n, 3) for s, n in zip(volume.spacing, volume.shape)],
        "warnings": list(volume.warnings),
        "meta": {k: _jsonable(v) for k, v in volume.meta.items() if k not in PRIVATE_META},
    }
    if volume.is_label_map:
        facts["labels"] = label_facts(volume, (values, counts))
    else:
        hounsfield = looks_like_hounsfield(vals)
        if hounsfield and not volume.meta.get("modality"):
            facts["modality"] = "CT (guessed from the Hounsfield value range)"
        if want_histogram:
            facts["histogram"] = histogram(vals, hounsfield)
    return facts


def _describe_layers(seg: Segmentation, want_histogram: bool) -> Dict:
    facts = describe(seg.layers[0], want_histogram)
    facts["labels"] = []
    facts["layers"] = []
    for i, layer in enumerate(seg.layers):
        entries = [dict(e, layer=i) for e in label_facts(layer)]
        facts["labels"] += entries
        facts["layers"].append({"layer": i, "structures": [e["name"] for e in entries]})
    facts["labels"].sort(key=lambda e: e["value"])
    facts["overlaps"] = [dict(o) for o in seg.overlaps]
    facts["warnings"] = list(seg.warnings)
    facts["meta"] = {k: _jsonable(v) for k, v in seg.meta.items() if k not in PRIVATE_META}
    facts["max"] = max(int(layer.data.max()) for layer in seg.layers)
    return facts


def label_facts(volume: Volume, counted: Optional[Tuple[np.ndarray, np.ndarray]] = None) -> List[Dict]:
    """Each label present or named: value, name, colour, voxel count and volume in mm³.

    The voxels are counted in one pass (:func:`~anatomesh.core.io.values.value_counts`), or
    taken from ``counted`` = ``(values, counts)`` of that function when the caller has them."""
    present, counts = counted if counted is not None else value_counts(volume.data)
    voxels = dict(zip(present.tolist(), counts.tolist()))
    vox = volume.voxel_volume_mm3()
    table = volume.labels or {}
    out = []
    for v in sorted(set(voxels) | set(table)):
        if v == 0:
            continue
        n = int(voxels.get(v, 0))
        info = table.get(v)
        out.append({"value": v, "name": info.name if info else f"label_{v}",
                    "color": [round(c, 4) for c in info.color] if info else None,
                    "voxels": n, "volume_mm3": round(n * vox, 3)})
    return out


def histogram(values: np.ndarray, hounsfield: bool = False) -> Dict:
    """A histogram of ``values`` with its peaks (local maxima of the smoothed counts).

    Values in Hounsfield units (CT with air near -1000) use fixed bins from -1100 to 2000 HU so peaks
    can be named (air, fat, soft tissue, bone); other scans (MR, CT stored without rescale) use bins
    between the 0.1 and 99.9 percentiles and unnamed peaks.
    """
    v = np.asarray(values).ravel()
    if v.size > 4_000_000:  # a strided sample is plenty for a histogram
        v = v[:: v.size // 4_000_000 + 1]
    is_ct = hounsfield
    if is_ct:
        lo, hi = -1100.0, 2000.0
    else:
        lo, hi = (float(x) for x in np.percentile(v, [0.1, 99.9])) if v.size else (0.0, 1.0)
        if hi <= lo:
            hi = lo + 1.0
    counts, edges = clamped_histogram(v, HIST_BINS, lo, hi)
    peaks = []
    for i in _peak_bins(counts):
        centre = 0.5 * (edges[i] + edges[i + 1])
        peak = {"value": round(float(centre), 2), "fraction": round(float(counts[i]) / max(1, v.size), 4)}
        if is_ct:
            peak["tissue"] = ct_class(centre)
        peaks.append(peak)
    return {"edges": [round(float(e), 3) for e in edges], "counts": counts.tolist(), "peaks": peaks}


def clamped_histogram(values: np.ndarray, bins: int, lo: float, hi: float):
    """``np.histogram(np.clip(values, lo, hi), bins, (lo, hi))`` without the clipped copy: values
    below ``lo`` count in the first bin, above ``hi`` in the last. Memory: numpy's type promotion
    makes the clipped copy of a 4 M-voxel int16 sample a 32 MB float64 array."""
    v = np.asarray(values)
    counts, edges = np.histogram(v, bins=bins, range=(lo, hi))
    counts[0] += np.count_nonzero(v < lo)
    counts[-1] += np.count_nonzero(v > hi)
    return counts, edges


def looks_like_hounsfield(values: np.ndarray) -> bool:
    """True when values look like CT Hounsfield units: air near -1000 and a soft-tissue body."""
    if values.size == 0 or values.dtype.kind not in "iuf":
        return False
    lo = float(values.min())
    hi = float(values.max())
    return -3100.0 <= lo <= -900.0 and 100.0 <= hi <= 40000.0


def ct_class(hu: float) -> str:
    for lo, hi, name in CT_CLASSES:
        if lo <= hu < hi:
            return name
    return "unknown"


def _peak_bins(counts: np.ndarray, min_fraction: float = 0.005) -> List[int]:
    """Bins that are local maxima of the 3-bin smoothed histogram and hold >= min_fraction."""
    c = np.convolve(counts.astype(np.float64), [0.25, 0.5, 0.25], mode="same")
    total = max(1.0, float(counts.sum()))
    out = []
    for i in range(len(c)):
        left = c[i - 1] if i > 0 else -1.0
        right = c[i + 1] if i + 1 < len(c) else -1.0
        if c[i] > left and c[i] >= right and counts[i] / total >= min_fraction:
            out.append(i)
    return out


def _num(x):
    x = x.item() if hasattr(x, "item") else x
    return round(x, 6) if isinstance(x, float) else x


def _jsonable(v):
    if isinstance(v, (str, int, float, bool)) or v is None:
        return v
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, (list, tuple)):
        return [_jsonable(x) for x in v]
    if isinstance(v, dict):
        return {str(k): _jsonable(x) for k, x in v.items()}
    return str(v)
