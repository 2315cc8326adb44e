"""Anatomesh: medical volumes to surface meshes, as a Blender extension and a Python package.

This file is the Blender extension's entry point. It must import without ``bpy`` (pytest and the
headless CLI import the package), so the add-on is imported lazily inside ``register()``.
"""

__version__ = "0.1.0"


def register():
    from . import addon

    addon.register()


def unregister():
    from . import addon

    addon.unregister()
