"""Surface extraction: isosurfaces of scans and conforming multi-label surfaces of label maps."""
from .isosurface import isosurface, isosurfaces
from .labels import label_surfaces

__all__ = ["isosurface", "isosurfaces", "label_surfaces"]
