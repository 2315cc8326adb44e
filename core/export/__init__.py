"""Writing surfaces to files, in mm with their space recorded: STL/PLY/OBJ one file per surface
(:mod:`.mesh_files`), 3MF and GLB one file per scene (:mod:`.threemf`, :mod:`.gltf`)."""
from .gltf import write_glb
from .mesh_files import write_mesh
from .threemf import write_3mf

#: writers that take all surfaces at once (one file per scene)
SCENE_FORMATS = {"3mf": write_3mf, "glb": write_glb}

__all__ = ["SCENE_FORMATS", "write_3mf", "write_glb", "write_mesh"]
