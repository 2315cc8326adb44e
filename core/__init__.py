"""Anatomesh core: pure numpy/numba (+ pydicom, nibabel, pynrrd, scipy); never imports ``bpy``.

The rooms in flow order — read → extract → smooth → decimate → check → export:

=============  ==========================================================================
``model``      Volume, Mesh, SurfaceSet, label tables, errors, progress
``io``         readers (DICOM, NIfTI, NRRD, label tables, mesh files) → Volume; ``load()``
``extract``    isosurfaces of scans, conforming shells of label maps → SurfaceSet
``smooth``     bounded smoothing and its guards; the one driver every door calls
``decimate``   quadric decimation of a whole set, levels of detail
``printing``   print checks on all parts together, and fixes
``export``     STL/PLY/OBJ, 3MF, GLB writers (mm, space recorded)
``geometry``   neighbourhoods, spatial index, intersections, topology, measures
=============  ==========================================================================

Public entry points::

    from anatomesh.core import load, isosurface, isosurfaces, label_surfaces, SurfaceSet
    from anatomesh.core import smooth_surfaces, decimate_surfaces, check_parts, topology
"""
from importlib import import_module

from .model.errors import AnatomeshError, Cancelled

#: public name → the module defining it, imported on first use (PEP 562) so that a command
#: loads only the rooms it needs (``anatomesh inspect`` never imports smoothing or decimation)
_LAZY = {"LabelInfo": ".model.labels", "Mesh": ".model.mesh", "SurfaceSet": ".model.surfaceset",
         "Volume": ".model.volume", "load": ".io.load", "isosurface": ".extract.isosurface",
         "isosurfaces": ".extract.isosurface", "label_surfaces": ".extract.multilabel",
         "smooth_surfaces": ".smooth.driver", "decimate_mesh": ".decimate.qem",
         "decimate_surfaces": ".decimate.qem", "check_parts": ".printing.checks",
         "write_3mf": ".export.threemf", "write_glb": ".export.gltf",
         "write_mesh": ".export.mesh_files", "topology": ".geometry.topology"}

__all__ = ["AnatomeshError", "Cancelled"] + list(_LAZY)


def __getattr__(name):
    if name in _LAZY:
        value = getattr(import_module(_LAZY[name], __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_LAZY))
