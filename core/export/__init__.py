"""Writing surfaces to files, in mm with their space recorded: STL/PLY/OBJ one file per surface
(:mod:`.mesh_files`), 3MF and GLB one file per scene (:mod:`.threemf`, :mod:`.gltf`)."""
from importlib import import_module

#: formats whose writers take all surfaces at once (one file per scene)
SCENE_FORMAT_NAMES = ("3mf", "glb")

#: public name → defining module, imported on first use (PEP 562): writing STL files does not
#: load the 3MF/GLB writers
_LAZY = {"write_3mf": ".threemf", "write_glb": ".gltf", "write_mesh": ".mesh_files"}

__all__ = ["SCENE_FORMATS", "SCENE_FORMAT_NAMES", "write_3mf", "write_glb", "write_mesh"]


def __getattr__(name):
    if name == "SCENE_FORMATS":  # writers that take all surfaces at once, by format
        value = {fmt: __getattr__(f"write_{fmt}") for fmt in SCENE_FORMAT_NAMES}
    elif name in _LAZY:
        value = getattr(import_module(_LAZY[name], __name__), name)
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    globals()[name] = value
    return value
