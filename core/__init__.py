"""Anatomesh core: pure numpy/numba, never imports ``bpy``.

Public entry points::

    from anatomesh.core import load, isosurface, isosurfaces, label_surfaces
"""
from .model.errors import AnatomeshError, Cancelled
from .model.volume import Volume
from .model.labels import LabelInfo
from .model.mesh import Mesh
from .geometry.topology import topology
from .io import load
from .extract import isosurface, isosurfaces, label_surfaces

__all__ = ["AnatomeshError", "Cancelled", "LabelInfo", "Volume", "Mesh", "topology", "load",
           "isosurface", "isosurfaces", "label_surfaces"]
