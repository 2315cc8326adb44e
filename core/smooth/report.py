"""What smoothing did: :class:`SmoothingReport` (the per-shell measures come from
:mod:`~anatomesh.core.smooth.shell_measures`)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Dict

import numpy as np

from .constraints import Constraint


@dataclass
class SmoothingReport:
    """What :func:`~anatomesh.core.smooth.driver.smooth_surfaces` did, per shell, JSON-ready via
    :meth:`as_dict`.

    Attributes
    ----------
    method : str — the filter run ("none" when nothing moved)
    params : dict — its parameters (constraint described, not its arrays), plus
        ``unfolded_vertices`` / ``untangled_vertices`` when those guards ran and, when the
        component guard ran (:mod:`~anatomesh.core.smooth.components`): ``component_bound_pct``
        (its bound: every shell component within this percentage of its unsmoothed volume),
        ``restored_components`` (components outside it after the volume step, brought back by
        their own volume regions) and ``blended_components`` (components blended back toward
        their unsmoothed positions to get within it)
    seconds : float — smoothing time (set-up + filter + guards), without measuring
    shells : dict — per label value the measures of
        :func:`anatomesh.core.geometry.measure.compare` (volume change, distances, ...)
    warnings : list[str] — volume changes beyond ``volume_warning_pct``, folds, crossings left
    """

    method: str
    params: dict
    seconds: float
    shells: Dict[int, dict]
    warnings: list

    def as_dict(self) -> dict:
        return {"method": self.method, "params": self.params, "seconds": self.seconds,
                "shells": {str(k): v for k, v in self.shells.items()}, "warnings": list(self.warnings)}

    def summary(self) -> dict:
        """Worst values over all shells."""
        s = list(self.shells.values())
        if not s:
            return {}
        out = {"shells": len(s),
               "max_abs_volume_change_pct": max(abs(x["volume_change_pct"]) for x in s),
               "max_displacement_mm": max(x["max_displacement_mm"] for x in s),
               "flipped_faces": sum(x["flipped_faces"] for x in s),
               "topology_changed": sorted(k for k, x in self.shells.items() if x["topology_changed"])}
        if "hausdorff_mm" in s[0]:
            out["max_hausdorff_mm"] = max(x["hausdorff_mm"] for x in s)
            out["mean_distance_mm"] = float(np.mean([x["mean_distance_mm"] for x in s]))
        return out


def describe(params: dict) -> dict:
    """JSON-ready parameters: a constraint described by kind, half extents, frame and cap."""
    out = {}
    for k, v in params.items():
        if k in ("structure", "progress", "gain", "face_groups"):
            continue
        if isinstance(v, Constraint):
            out[k] = {"kind": v.kind, "half": [float(h) for h in np.broadcast_to(v.half, 3)],
                      "frame": "voxel" if v.frame is not None else "mm",
                      "max_deviation_mm": v.max_deviation}
        elif isinstance(v, np.ndarray):
            out[k] = v.tolist()
        else:
            out[k] = v
    return out
