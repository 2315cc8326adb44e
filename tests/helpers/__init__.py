"""Shared test helpers: analytic meshes, synthetic DICOM series, slow reference implementations."""
