"""``anatomesh check PATH...``: print-readiness checks of mesh files (see :mod:`.printcheck`)."""
from __future__ import annotations

import argparse


def add_parser(subs) -> argparse.ArgumentParser:
    """Add the ``check`` sub-command to ``subs`` (an argparse sub-parsers object)."""
    p = subs.add_parser("check", help="print-readiness checks of mesh files or a folder from `anatomesh mesh`")
    p.add_argument("--debug", action="store_true", help=argparse.SUPPRESS)
    p.set_defaults(func=cmd_check)
    return p


def cmd_check(args) -> int:
    raise NotImplementedError("anatomesh check: not written yet")
