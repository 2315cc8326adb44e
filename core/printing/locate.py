"""Where a finding of the print checks is: the point the report gives for it, in mm."""
from __future__ import annotations

from typing import List, Optional

import numpy as np


def location(points: np.ndarray, weights: Optional[np.ndarray] = None) -> List[float]:
    """The centroid of ``points`` (K, 3) mm, weighted by ``weights`` (K,) when they sum above 0,
    as a list of three floats rounded to 0.001 mm (ready for the JSON report)."""
    p = np.asarray(points, np.float64).reshape(-1, 3)
    if weights is None or not np.sum(weights) > 0:
        return [round(float(x), 3) for x in p.mean(0)]
    return [round(float(x), 3) for x in np.average(p, axis=0, weights=weights)]


def location_text(point) -> str:
    """A location as a reason shows it: "(x, y, z)" in whole mm (never "-0")."""
    return "(" + ", ".join(str(round(float(x))) for x in point) + ")"
