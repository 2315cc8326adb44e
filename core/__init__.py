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
from .model.errors import AnatomeshError, Cancelled
from .model.labels import LabelInfo
from .model.mesh import Mesh
from .model.surfaceset import SurfaceSet
from .model.volume import Volume
from .io import load
from .extract import isosurface, isosurfaces, label_surfaces
from .smooth.driver import smooth_surfaces
from .decimate.qem import decimate_mesh, decimate_surfaces
from .printing.checks import check_parts
from .export import write_3mf, write_glb, write_mesh
from .geometry.topology import topology

__all__ = ["AnatomeshError", "Cancelled", "LabelInfo", "Mesh", "SurfaceSet", "Volume", "load",
           "isosurface", "isosurfaces", "label_surfaces", "smooth_surfaces", "decimate_mesh",
           "decimate_surfaces", "check_parts", "write_3mf", "write_glb", "write_mesh", "topology"]
