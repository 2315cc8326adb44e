"""Anatomesh add-on: colour attributes (curvature, distance to the unsmoothed surface, wall thickness, gaps) selectable as viewport colour."""

CLASSES = ()


def register() -> None:
    """Register properties this module owns (classes are registered from CLASSES by the package)."""


def unregister() -> None:
    """Remove what :func:`register` added."""
