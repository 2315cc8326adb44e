"""Anatomesh add-on: the Print panel: check all Anatomesh objects at once, list problems, select/frame them, fixes."""

CLASSES = ()


def register() -> None:
    """Register properties this module owns (classes are registered from CLASSES by the package)."""


def unregister() -> None:
    """Remove what :func:`register` added."""
