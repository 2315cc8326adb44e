"""Per-part filaments in a 3MF: the slicers' own metadata parts, so that each part of an Anatomesh
3MF prints with its own filament (colour) in a multi-material printer without re-assigning.

The 3MF core specification carries colours (``<basematerials>``, and the materials extension's
``<m:colorgroup>``, 3MF Consortium, *Materials and Properties Extension* 1.2) but no notion of an
extruder. Slicers keep that in vendor parts of the package (not in the specification, read from
the files the slicers write):

* PrusaSlicer: ``Metadata/Slic3r_PE_model.config``, one ``<object id=…>`` per model object (its
  id in the model part) with ``<metadata type="object" key="extruder" value="N"/>`` and one
  ``<volume firstid lastid>`` covering the object's triangles;
* Bambu Studio and OrcaSlicer: ``Metadata/model_settings.config``, one ``<object id=…>`` with
  ``<metadata key="extruder" value="N"/>`` and one ``<part id=… subtype="normal_part">``.

Filament numbers are 1-based. :func:`filament_numbers` gives every distinct colour its own
filament (parts of one colour share it), in the order the parts come.
"""
from __future__ import annotations

import re
from typing import Dict, List, Sequence
from xml.sax.saxutils import quoteattr

from ..model.mesh import Mesh

PRUSA_CONFIG = "Metadata/Slic3r_PE_model.config"
BAMBU_CONFIG = "Metadata/model_settings.config"
#: the materials extension's namespace (colour groups)
NS_MATERIAL = "http://schemas.microsoft.com/3dmanufacturing/material/2015/02"
_XML_BAD = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f]")


def xml_text(s) -> str:
    """``s`` as a string without the control characters XML 1.0 forbids."""
    return _XML_BAD.sub("", str(s))


def filament_numbers(meshes: Sequence[Mesh], colours: Sequence[str]) -> List[int]:
    """1-based filament number per mesh: one per distinct ``colours`` entry (hex strings), in the
    order of first appearance."""
    seen: Dict[str, int] = {}
    return [seen.setdefault(c.upper(), len(seen) + 1) for c in colours[:len(meshes)]]


def prusa_model_config(meshes: Sequence[Mesh], object_ids: Sequence[int], filaments: Sequence[int]) -> str:
    """The text of PrusaSlicer's ``Slic3r_PE_model.config`` for the model's objects."""
    rows = ['<?xml version="1.0" encoding="UTF-8"?>', "<config>"]
    for m, oid, fil in zip(meshes, object_ids, filaments):
        name = quoteattr(_name(m))
        rows += [f' <object id="{oid}" instances_count="1">',
                 f'  <metadata type="object" key="name" value={name}/>',
                 f'  <metadata type="object" key="extruder" value="{fil}"/>',
                 f'  <volume firstid="0" lastid="{max(m.n_faces - 1, 0)}">',
                 f'   <metadata type="volume" key="name" value={name}/>',
                 '   <metadata type="volume" key="volume_type" value="ModelPart"/>',
                 "  </volume>", " </object>"]
    rows.append("</config>")
    return "\n".join(rows) + "\n"


def bambu_model_settings(meshes: Sequence[Mesh], object_ids: Sequence[int], filaments: Sequence[int]) -> str:
    """The text of Bambu Studio / OrcaSlicer's ``model_settings.config`` for the model's objects
    (all on plate 1)."""
    rows = ['<?xml version="1.0" encoding="UTF-8"?>', "<config>"]
    for m, oid, fil in zip(meshes, object_ids, filaments):
        name = quoteattr(_name(m))
        rows += [f'  <object id="{oid}">', f'    <metadata key="name" value={name}/>',
                 f'    <metadata key="extruder" value="{fil}"/>',
                 f'    <part id="{oid}" subtype="normal_part">',
                 f'      <metadata key="name" value={name}/>',
                 f'      <metadata key="extruder" value="{fil}"/>', "    </part>", "  </object>"]
    rows += ["  <plate>", '    <metadata key="plater_id" value="1"/>']
    for k, oid in enumerate(object_ids):
        rows += ["    <model_instance>", f'      <metadata key="object_id" value="{oid}"/>',
                 '      <metadata key="instance_id" value="0"/>',
                 f'      <metadata key="identify_id" value="{k + 1}"/>', "    </model_instance>"]
    rows += ["  </plate>", "</config>"]
    return "\n".join(rows) + "\n"


def _name(m: Mesh) -> str:
    return xml_text(m.name or "surface")
