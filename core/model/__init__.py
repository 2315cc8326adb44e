"""The data every stage shares: :class:`~.volume.Volume` (voxels + affine + space + label table),
:class:`~.mesh.Mesh` (one surface; the array validator, normals, welding), :class:`~.surfaceset.SurfaceSet`
(many surfaces with shared seams), :class:`~.segmentation.Segmentation` (overlapping structures as
label-map layers; RT contours), label tables and colours (:mod:`.labels`), the one user-facing
error (:mod:`.errors`) and progress callbacks (:mod:`.progress`). Imports nothing else of core."""
