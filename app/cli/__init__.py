"""The ``anatomesh`` command: ``inspect``, ``mesh``, ``check``, ``web``, ``batch`` and ``preview`` (one module each);
``python -m anatomesh.app.cli`` runs it too.

Exit codes (:mod:`.common`): 0 success, 1 a print check failed, 2 bad input — one line on stderr
naming the file and the problem, no traceback unless ``--debug``.
"""
from __future__ import annotations

import argparse
import gc
import os
import sys
from typing import List, Optional

from ...core.model.errors import AnatomeshError, Cancelled
from ...core.model.memory import return_large_blocks
from . import batch, check, inspect, mesh, preview, web
from .common import EXIT_BAD_INPUT, EXIT_INTERRUPTED


def main(argv: Optional[List[str]] = None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as done:  # --help, --version, or a bad flag (one line printed)
        return done.code
    if not getattr(args, "command", None):
        parser.print_help()
        return EXIT_BAD_INPUT
    from ..warmup.compile import announce_compiling  # loaded after the flags are read

    try:
        with announce_compiling():
            return args.func(args)
    except AnatomeshError as err:
        if args.debug:
            raise
        print(f"error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except Cancelled:
        print("cancelled", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED


def entry() -> None:
    """The ``anatomesh`` program: :func:`main`, then leave at once.

    Tearing down the interpreter (numba's and LLVM's registries, thousands of modules) costs
    CPU time after the work is done; every file is closed and written by then, so the process
    flushes its output and ends with ``os._exit``. The objects of the imports live as long as
    the process: frozen out of the garbage collector's reach, so its full collections skip them.
    Large arrays get their own mappings, handed back when freed
    (:func:`~anatomesh.core.model.memory.return_large_blocks`). In-process callers use :func:`main`.
    """
    gc.freeze()
    return_large_blocks()
    code = main()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


class OneLineParser(argparse.ArgumentParser):
    """argparse with bad flags as one line on stderr (exit code 2), not a usage dump."""

    def error(self, message):
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    p = OneLineParser(prog="anatomesh", description="Medical scans to surface meshes (mm).")
    p.add_argument("--version", action="version", version=f"anatomesh {installed_version()}")
    p.add_argument("--debug", action="store_true", help="show tracebacks")
    subs = p.add_subparsers(dest="command")
    for command in (inspect, mesh, check, web, batch, preview):
        sp = command.add_parser(subs)
        sp.add_argument("--debug", action="store_true", help=argparse.SUPPRESS)
    return p


def installed_version() -> str:
    """The installed package's version (its metadata), or a word saying it is not installed."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("anatomesh")
    except PackageNotFoundError:
        return "(not installed: run from a checkout)"
