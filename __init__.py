"""Anatomesh: medical volumes to surface meshes, as a Blender extension and a Python package.

This file is the Blender extension's entry point. It must import without ``bpy`` (pytest and the
headless CLI import the package), so the add-on is imported lazily inside ``register()``.
"""
import os as _os
import sys as _sys

__version__ = "0.1.0"


def _use_portable_kernels() -> bool:
    """When this install ships numba kernels compiled for a generic CPU (a wheel built by
    ``tools/build_wheel.py``: ``portable_kernels.txt`` beside this file) for this very platform,
    machine, Python and numba, ask numba for generic-CPU code (``NUMBA_CPU_NAME=generic``), so
    that it loads them instead of compiling for this CPU. Only before numba is imported and when
    the user has not chosen a CPU; returns whether it did."""
    marker = _os.path.join(_os.path.dirname(__file__), "portable_kernels.txt")
    if "numba" in _sys.modules or "NUMBA_CPU_NAME" in _os.environ or not _os.path.isfile(marker):
        return False
    import platform
    from importlib import metadata

    try:
        numba_version = metadata.version("numba")
    except metadata.PackageNotFoundError:
        return False
    here = f"{_sys.platform} {platform.machine()} {_sys.implementation.cache_tag} numba {numba_version}"
    with open(marker, encoding="utf-8") as fh:
        if here not in fh.read().splitlines():
            return False
    _os.environ["NUMBA_CPU_NAME"] = "generic"
    return True


_use_portable_kernels()


def register():
    from . import addon

    addon.register()


def unregister():
    from . import addon

    addon.unregister()
