"""Anatomesh add-on: the Decimate panel: targets, preview with Blender's Decimate modifier, Apply with the core result, measured error per organ."""

CLASSES = ()


def register() -> None:
    """Register properties this module owns (classes are registered from CLASSES by the package)."""


def unregister() -> None:
    """Remove what :func:`register` added."""
