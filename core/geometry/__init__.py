"""Geometry every stage measures with: neighbourhoods (:mod:`.neighbors`, MeshStructure), one
spatial index (:mod:`.spatial`, TriangleGrid: closest points, rays, inscribed balls), crossing
triangles (:mod:`.intersections`), topology (:mod:`.topology`: closed, manifold, genus),
distances and measures (:mod:`.measure`), planar polygons (:mod:`.polygons`: nesting,
triangulation with holes) and the numba kernels shared across rooms
(:mod:`.kernels`). Imports only :mod:`anatomesh.core.model`."""
