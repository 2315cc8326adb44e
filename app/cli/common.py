"""Pieces every sub-command shares: exit codes, the progress bar, input arguments, list parsing."""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Dict, List

from ...core.model.errors import AnatomeshError

#: 0 success, 1 a print check failed, 2 bad input (one line on stderr), 130 interrupted
EXIT_OK, EXIT_CHECK_FAILED, EXIT_BAD_INPUT, EXIT_INTERRUPTED = 0, 1, 2, 130


def add_input_args(p: argparse.ArgumentParser, required: bool = True) -> None:
    """The scan path(s) and the reader's options."""
    p.add_argument("path", nargs="+" if required else "*",
                   help="DICOM folder or files (image series, SEG, RTSTRUCT), .nii/.nii.gz, "
                        ".nrrd/.nhdr/.seg.nrrd, or a folder/list of binary masks (one per structure)")
    p.add_argument("--series", help="DICOM series or segmentation object (SEG/RTSTRUCT): its number in "
                                    "`anatomesh inspect`'s list, SeriesNumber or UID, when a folder holds several")
    p.add_argument("--volume", type=int, dest="volume_index", help="volume index of a 4D NIfTI")
    p.add_argument("--label-table", help="label names/colours (TotalSegmentator JSON, Slicer .ctbl, ITK-SNAP)")
    p.add_argument("--grid", help="mask folders: the grid to mesh on, a mask name or 'image' (default the "
                                  "finest mask grid); DICOM SEG/RTSTRUCT: 'image' (the referenced series, "
                                  "default when present) or 'native' (the object's own planes)")


def path_arg(paths: List[str]):
    """One path as itself, several as a list (a DICOM series given file by file)."""
    return paths[0] if len(paths) == 1 else paths


def split_list(text: str) -> List[str]:
    """``"liver, spleen,3"`` → ``["liver", "spleen", "3"]``."""
    return [t.strip() for t in text.split(",") if t.strip()]


def short_list(names: List[str], n: int = 4) -> str:
    if not names:
        return ""
    return "(" + ", ".join(names[:n]) + (f", +{len(names) - n} more" if len(names) > n else "") + ")"


def write_json(data: Dict, path) -> None:
    """A JSON report at ``path`` (folders made), or one clear error."""
    from ..flow.report import json_default  # speed: the report module pulls the whole flow

    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(data, indent=2, default=json_default))
    except OSError as exc:
        raise AnatomeshError(f"cannot write the report ({exc.strerror}); choose another --report path",
                             path) from None


class TerminalProgress:
    """A one-line progress bar on stderr when it is a terminal; silent otherwise."""

    def __init__(self, title: str, width: int = 30):
        self.title, self.width = title, width
        self.enabled = sys.stderr.isatty()
        self.t0 = time.perf_counter()
        self._last = None

    def __call__(self, fraction: float, text: str = "") -> None:
        if not self.enabled:
            return
        filled = int(round(self.width * fraction))
        if (filled, text) == self._last:
            return
        self._last = (filled, text)
        bar = "#" * filled + "-" * (self.width - filled)
        sys.stderr.write(f"\r{self.title} [{bar}] {fraction * 100:5.1f}% {time.perf_counter() - self.t0:6.1f}s "
                         f"{text[:40]:<40}")
        if fraction >= 1.0:
            sys.stderr.write("\n")
        sys.stderr.flush()
