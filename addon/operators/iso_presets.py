"""Isovalue presets for scalar scans, by modality.

CT values are Hounsfield units, so the levels are fixed tissue boundaries: air/skin halfway between
air (−1000) and soft tissue (~0), contrast-filled vessels above blood (~40) and below cortical bone.
Other scans (MR, unknown units) have no absolute scale: the levels are put halfway between
neighbouring peaks of the histogram (core's ``inspect.histogram``), the first being the
background/body boundary.
"""
from __future__ import annotations

from typing import List, Tuple

import numpy as np

#: (name, isovalue HU, colour, included by default)
CT_PRESETS: Tuple[Tuple[str, float, Tuple[float, float, float], bool], ...] = (
    ("Skin", -500.0, (0.92, 0.74, 0.62), True),
    ("Lung / airways", -650.0, (0.96, 0.66, 0.7), False),
    ("Soft tissue", 40.0, (0.8, 0.45, 0.4), False),
    ("Contrast vessels", 200.0, (0.85, 0.1, 0.1), False),
    ("Bone", 300.0, (0.93, 0.89, 0.78), True),
)


def looks_like_ct(volume) -> bool:
    """Values in Hounsfield units: air near −1000 and bone above 200.

    The modality alone is not enough: some CT series store raw values without the rescale to HU
    (the classic "headsq" series runs 0..3926); those get histogram presets instead.
    """
    modality = str(volume.meta.get("modality", "")).upper()
    if modality and modality != "CT":
        return False
    data = np.asarray(volume.data)
    sample = data.ravel()[:: max(1, data.size // 1_000_000)]
    return bool(sample.size and sample.min() <= -500 and np.percentile(sample, 99.5) >= 200)


def level_presets(volume) -> List[Tuple[str, float, Tuple[float, float, float], bool]]:
    """Named isovalues for a scalar volume: CT tissue boundaries, else histogram valleys."""
    if looks_like_ct(volume):
        return list(CT_PRESETS)
    from ...core.io.describe import histogram

    data = np.asarray(volume.data)
    sample = data.ravel()[:: max(1, data.size // 2_000_000)]
    peaks = [p["value"] for p in histogram(sample, str(volume.meta.get("modality", "")))["peaks"]]
    out = []
    if len(peaks) >= 2:
        cuts = [0.5 * (a + b) for a, b in zip(peaks[:-1], peaks[1:])]
        for i, c in enumerate(cuts):
            name = "Body outline" if i == 0 else f"Boundary {i + 1}"
            hue = (0.92, 0.74, 0.62) if i == 0 else (0.8, 0.8, 0.85)
            out.append((name, round(float(c), 3), hue, i == 0))
    else:  # one peak (or none): the mean separates the dark background from the body
        out.append(("Body outline", round(float(sample.mean()), 3) if sample.size else 0.0,
                    (0.92, 0.74, 0.62), True))
    return out
