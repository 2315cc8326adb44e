"""A gap between touching structures as they are drawn, so see-through organs show no speckle.

Neighbouring shells of a label map share their interface: the lung's face against the liver and
the liver's face against the lung are the very same triangle, turned opposite ways. A ray that
passes through a see-through lung meets both at the same distance, and which one the renderer
finds first is left to rounding: Cycles shows a speckle of the two colours, EEVEE and the Solid
view fight over the depth ("z-fighting"). Each surface therefore gets a Displace modifier (no
texture: a constant offset along the vertex normals) that moves it inward by a small fraction of
a voxel, in the viewport (Solid, Material Preview) and in renders. The two faces of an interface
part by twice that and the shells stay closed. Nothing the add-on measures or exports changes:
the exporters, print checks and the web page read the shapes with the modifier left out
(:func:`left_out`).
"""
from __future__ import annotations

from contextlib import contextmanager
from typing import Iterable, Iterator, Sequence

import bpy

#: the modifier's name on every surface object
GAP_MODIFIER = "Anatomesh Render Gap"
#: inward offset of each surface, as a fraction of the smallest voxel spacing
GAP_FRACTION = 0.02
#: and at least this far (mm), well above single-precision rounding at scanner coordinates
MIN_GAP_MM = 0.005


def gap_mm(spacing: Sequence[float]) -> float:
    """The inward offset (mm) of each surface for a volume of voxel ``spacing`` (mm)."""
    return max(MIN_GAP_MM, GAP_FRACTION * float(min(spacing)))


def add_render_gap(objects: Iterable[bpy.types.Object], offset_mm: float) -> None:
    """Give each object (or update) the drawn inward offset of ``offset_mm`` mm."""
    for obj in objects:
        mod = obj.modifiers.get(GAP_MODIFIER) or obj.modifiers.new(GAP_MODIFIER, "DISPLACE")
        mod.direction = "NORMAL"
        mod.mid_level = 0.0  # no texture: displacement = (1 - mid level) * strength
        mod.strength = -float(offset_mm)
        mod.show_viewport = True
        mod.show_in_editmode = False
        mod.show_render = True


@contextmanager
def left_out(objects: Iterable[bpy.types.Object]) -> Iterator[None]:
    """Within the block, the viewport's evaluation of ``objects`` (``evaluated_depsgraph_get``)
    has no gap: the shapes as extracted and edited, which the add-on measures and exports."""
    mods = [m for o in objects for m in o.modifiers if m.name == GAP_MODIFIER and m.show_viewport]
    for m in mods:
        m.show_viewport = False
    try:
        yield
    finally:
        for m in mods:
            m.show_viewport = True
