"""Anatomesh core: pure numpy/numba, never imports ``bpy``.

Public entry points::

    from anatomesh.core import load, isosurface, label_surfaces
"""
from .errors import AnatomeshError, Cancelled
from .volume import LabelInfo, Volume
from .mesh import Mesh, topology
from .io import load

__all__ = ["AnatomeshError", "Cancelled", "LabelInfo", "Volume", "Mesh", "topology", "load"]

try:  # extraction lands with its own modules; keep the package importable while they grow
    from .extract import isosurface, label_surfaces  # noqa: F401
    __all__ += ["isosurface", "label_surfaces"]
except ImportError:  # pragma: no cover
    pass
