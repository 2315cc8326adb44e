"""Printer profiles and the fixed limits of the print checks, in mm, mm², mm³.

:data:`PROFILES` gives, per kind of printer, the thinnest wall it prints, the narrowest gap
between parts that stays open and the smallest shell worth printing; :func:`resolve_profile`
picks one and applies the user's overrides. The other limits (gap report distance, sliver
angle, degenerate area) are the same for every printer.
"""
from __future__ import annotations

from typing import Dict, Optional

import numpy as np

from ..model.errors import AnatomeshError

#: printer profiles, mm: the thinnest wall printed (``min_wall``), the narrowest gap between parts
#: that stays open (``min_gap``), the smallest loose shell worth printing (``min_shell_mm3``), the
#: smallest detail (``min_feature``: the nozzle, or a few pixels of a resin printer) — thinner
#: material reaching less than this beyond the part's full-thickness body is a rim, not a thin
#: spot (:mod:`.features`) — and the hole sizes and fits of the printable-part tools (drain
#: holes, connector clearance)
PROFILES: Dict[str, Dict[str, float]] = {
    "fdm": {"min_wall": 0.8, "min_gap": 0.5, "min_shell_mm3": 1.0, "min_feature": 0.4,
            "drain_diameter": 4.0, "connector_clearance": 0.2},
    "resin": {"min_wall": 0.4, "min_gap": 0.2, "min_shell_mm3": 0.1, "min_feature": 0.1,
              "drain_diameter": 3.0, "connector_clearance": 0.1},
}
#: pairs of parts closer than this are listed in the report, mm
GAP_REPORT_MM = 5.0
#: faces with an angle below this are slivers, degrees
SLIVER_ANGLE_DEG = 1.0
#: faces at most this large are degenerate, mm²
DEGENERATE_AREA_MM2 = 1e-10
#: a face of one part reaching no farther than this into another part touches it, mm (a
#: micrometre: far below any printer's resolution, far above the float32 rounding of positions
#: within a body, ~3e-5 mm)
CONTACT_MM = 1e-3


def resolve_profile(profile="fdm", min_wall: Optional[float] = None, min_gap: Optional[float] = None,
                    min_shell_mm3: Optional[float] = None) -> Dict[str, float]:
    """The profile's limits (a name in :data:`PROFILES` or a dict), with overrides applied."""
    if isinstance(profile, dict):
        base = dict(PROFILES["fdm"])
        base.update(profile)
        name = str(profile.get("name", "custom"))
    else:
        if profile not in PROFILES:
            raise AnatomeshError(f"unknown printer profile {profile!r}: use one of "
                                 f"{', '.join(sorted(PROFILES))} or pass min_wall/min_gap in mm")
        base = dict(PROFILES[profile])
        name = profile
    for key, val in (("min_wall", min_wall), ("min_gap", min_gap), ("min_shell_mm3", min_shell_mm3)):
        if val is not None:
            if not np.isfinite(val) or val < 0:
                raise AnatomeshError(f"{key} must be a non-negative number of mm, got {val}")
            base[key] = float(val)
    base["name"] = name
    return base
