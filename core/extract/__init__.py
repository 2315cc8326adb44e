"""Surface extraction: isosurfaces of scans and conforming multi-label surfaces of label maps."""
from .isosurface import isosurface, isosurfaces
from .multilabel import label_surfaces

__all__ = ["isosurface", "isosurfaces", "label_surfaces"]
