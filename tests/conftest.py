"""Shared test fixtures: where the real scans are, and a temp Blender user folder."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
#: real scans and label maps (see ../shared/data/README.md); CI clones the repo next to shared/
SHARED_DATA = Path(os.environ.get("ANATOMESH_SHARED_DATA", REPO.parent / "shared" / "data"))
#: the small real sample bundled with the repo (TotalSegmentator example, Apache-2.0)
SAMPLE = REPO / "data" / "sample"


def shared(*parts: str) -> Path:
    """Path of a file in ../shared/data; fails the test (never skips silently) when missing."""
    p = SHARED_DATA.joinpath(*parts)
    if not p.exists():
        pytest.fail(f"test data missing: {p} (set ANATOMESH_SHARED_DATA to the shared/data folder)")
    return p


@pytest.fixture
def shared_data():
    return shared
