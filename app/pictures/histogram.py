"""The histogram of a scan as a picture, its peaks labelled and the chosen levels marked
(``anatomesh inspect SCAN --histogram FILE.png``).

Drawn directly into an RGB array (no plotting library): bars of log(1 + count) over the range of
:func:`anatomesh.core.io.describe.histogram` (−1100..2000 HU for CT, else the 0.1–99.9
percentiles) in :data:`BINS` bins, value ticks along the bottom, each histogram peak a blue mark
labelled with its value (and tissue for CT), each level a dashed red line labelled with its
name and value. Labels that would overlap go to the next row.
"""
from __future__ import annotations

import math
from typing import Dict, List, Sequence, Tuple

import numpy as np

from ...core.io.describe import clamped_histogram, histogram
from .bitmap_font import draw_text, text_size

BINS = 200
INK, GRID, BAR = (30, 30, 30), (225, 225, 225), (150, 150, 160)
PEAK, LEVEL = (30, 80, 200), (200, 30, 30)


def histogram_picture(values: np.ndarray, hounsfield: bool,
                      levels: Sequence[Tuple[str, float]] = (), title: str = "",
                      size: Tuple[int, int] = (960, 440)) -> Tuple[np.ndarray, Dict]:
    """``(picture (H, W, 3) uint8, facts)``: the histogram of ``values`` (any shape; a strided
    sample is enough) with its peaks and ``levels`` ((name, value) pairs) marked; ``facts`` holds
    the range, the peaks (value, tissue) and the levels drawn."""
    v = np.ravel(np.asarray(values), order="K")
    v = v[np.isfinite(v)] if v.dtype.kind == "f" else v
    facts = histogram(v, hounsfield)
    lo, hi = facts["edges"][0], facts["edges"][-1]
    counts, _ = clamped_histogram(v, BINS, lo, hi)
    w, h = size
    img = np.full((h, w, 3), 255, np.uint8)
    box = (64, 64, w - 20, h - 56)  # x0, y0 (top), x1, y1 (bottom) of the plot area
    xof = lambda x: int(round(box[0] + (x - lo) / (hi - lo) * (box[2] - box[0])))  # noqa: E731
    _axes(img, box, lo, hi, xof, "value (HU)" if hounsfield else "value")
    heights = np.log1p(counts) / max(np.log1p(counts).max(), 1e-9)
    for i, c in enumerate(heights):
        x0, x1 = xof(lo + i * (hi - lo) / BINS), xof(lo + (i + 1) * (hi - lo) / BINS)
        top = int(round(box[3] - c * (box[3] - box[1] - 40)))
        img[top:box[3], x0:max(x0 + 1, x1)] = BAR
    rows: List[List[Tuple[int, int]]] = []
    for p in facts["peaks"]:
        text = _value(p["value"]) + (f" {p['tissue']}" if "tissue" in p else "")
        x = xof(p["value"])
        i = min(BINS - 1, max(0, int((p["value"] - lo) / (hi - lo) * BINS)))
        top = int(round(box[3] - heights[i] * (box[3] - box[1] - 40)))
        _vline(img, x, top - 6, top - 1, PEAK)
        _label(img, rows, x, text, PEAK, top - 16, -10)
    drawn, level_rows = [], []
    for name, value in levels:
        if not lo <= value <= hi:
            continue
        x = xof(value)
        _vline(img, x, box[1], box[3], LEVEL, dashed=True)
        _label(img, level_rows, x, f"{name} {_value(value)}", LEVEL, box[1] + 3, 10)
        drawn.append({"name": name, "value": float(value)})
    draw_text(img, title[: (w - 20) // 12], 10, 10, INK, 2)
    draw_text(img, "bars: log(1 + voxels); blue: histogram peaks; red: chosen levels", 10, 34,
              (100, 100, 100), 1)
    return img, {"range": [lo, hi], "peaks": facts["peaks"], "levels": drawn}


def _axes(img, box, lo, hi, xof, label) -> None:
    x0, y0, x1, y1 = box
    step = _nice_step((hi - lo) / 8)
    t = math.ceil(lo / step) * step
    while t <= hi:
        x = xof(t)
        img[y0:y1, x] = GRID
        img[y1:y1 + 5, x] = INK
        text = f"{t:g}"
        draw_text(img, text, x - text_size(text)[0] // 2, y1 + 8, INK, 1)
        t += step
    img[y1, x0:x1 + 1] = INK
    img[y0:y1 + 1, x0] = INK
    draw_text(img, label, (x0 + x1) // 2 - text_size(label, 2)[0] // 2, y1 + 24, INK, 2)


def _nice_step(raw: float) -> float:
    mag = 10 ** math.floor(math.log10(max(raw, 1e-12)))
    return next(m * mag for m in (1, 2, 2.5, 5, 10) if m * mag >= raw)


def _vline(img, x, y0, y1, color, dashed: bool = False) -> None:
    if not 0 <= x < img.shape[1]:
        return
    for y in range(max(0, y0), min(img.shape[0], y1 + 1)):
        if not dashed or (y // 4) % 2 == 0:
            img[y, max(0, x - 1):x + 1] = color


def _label(img, rows: List[List[Tuple[int, int]]], x: int, text: str, color, y0: int, step: int) -> None:
    """Write ``text`` centred on ``x`` at height ``y0``, or ``step`` pixels further per row when
    an earlier label of ``rows`` is in the way."""
    w, h = text_size(text, 1)
    x0 = min(max(2, x - w // 2), img.shape[1] - w - 2)
    row = 0
    while row < len(rows) and any(not (x0 + w + 6 < a or b + 6 < x0) for a, b in rows[row]):
        row += 1
    if row == len(rows):
        rows.append([])
    rows[row].append((x0, x0 + w))
    y = min(max(1, y0 + row * step), img.shape[0] - h - 1)
    img[y - 1:y + h + 1, x0 - 1:x0 + w + 1] = 255
    draw_text(img, text, x0, y, color, 1)


def _value(v: float) -> str:
    return f"{v:.0f}" if abs(v) >= 100 else f"{v:.3g}"
