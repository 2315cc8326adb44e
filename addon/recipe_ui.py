"""Anatomesh add-on: save/load the current settings as a recipe TOML file (the same file `anatomesh mesh --recipe` reads)."""

CLASSES = ()


def register() -> None:
    """Register properties this module owns (classes are registered from CLASSES by the package)."""


def unregister() -> None:
    """Remove what :func:`register` added."""
