"""``anatomesh batch``: one recipe over many studies into ``OUT/<id>/``, resumable, with a summary.

The work is :func:`anatomesh.app.batch.run`; this module parses the command line, draws the
batch's progress bar and prints the counts. Exit code 0 when every study is done, 1 when some
failed (their reasons are in ``OUT/summary.csv``), 2 for bad input, 130 when interrupted.
"""
from __future__ import annotations

import argparse
import shutil
import signal
import sys
import time

from .common import EXIT_CHECK_FAILED, EXIT_OK


def add_parser(subs) -> argparse.ArgumentParser:
    b = subs.add_parser("batch", help="run one recipe over many studies (resumable; process pool or Dask)",
                        description="Run one recipe over every study of INPUTS into OUT/<id>/ (each with "
                                    "its report and a thumbnail), with OUT/summary.csv and summary.html. "
                                    "Re-running skips the studies done with the same recipe and input.")
    b.add_argument("inputs", nargs="+", metavar="INPUTS",
                   help="a folder of studies (one sub-folder or scan file each; TotalSegmentator "
                        "output folders recognised), a .csv/.tsv manifest (id,path[,labels]) or a glob")
    b.add_argument("--recipe", metavar="FILE", help="TOML recipe (default: the default settings); its "
                                                    "input and output folder are set per study")
    b.add_argument("--out", required=True, help="output folder: OUT/<id>/ per study, OUT/summary.*")
    b.add_argument("--workers", type=int, metavar="N",
                   help="studies at once on this machine (default: the cores, fewer when memory is short)")
    b.add_argument("--memory", type=float, metavar="GB",
                   help="memory the studies may use together (default: 80%% of the free memory)")
    b.add_argument("--scheduler", metavar="ADDRESS",
                   help="run on a Dask distributed cluster (tcp://host:8786) instead of this machine")
    b.add_argument("--retry-failed", action="store_true",
                   help="run again the studies that failed before with the same recipe and input")
    b.set_defaults(func=cmd_batch)
    return b


def cmd_batch(args) -> int:
    from ..batch import run  # speed: the batch modules load for this command only

    previous = signal.signal(signal.SIGTERM, _interrupt)  # `kill` stops the workers as Ctrl-C does
    bar = BatchBar()
    try:
        rows = run(args.inputs, args.recipe, args.out, scheduler=args.scheduler, workers=args.workers,
                   memory_gb=args.memory, retry_failed=args.retry_failed, progress=bar)
    finally:
        signal.signal(signal.SIGTERM, previous)
        bar.close()
    first = {}
    for r in rows:
        first.setdefault(r["study"], r)
    counts = {s: sum(1 for r in first.values() if r["status"] == s) for s in ("done", "skipped", "failed")}
    for r in first.values():
        if r["status"] == "failed":
            print(f"failed: {r['study']}: {r['error']}", file=sys.stderr)
    print(f"{len(first)} studies: {counts['done']} done, {counts['skipped']} unchanged (skipped), "
          f"{counts['failed']} failed -> {args.out}/summary.csv, {args.out}/summary.html")
    return EXIT_CHECK_FAILED if counts["failed"] else EXIT_OK


def _interrupt(signum, frame):
    raise KeyboardInterrupt


class BatchBar:
    """The batch's bar on stderr: a live line on a terminal, else one line every 30 s (logs)."""

    def __init__(self, width: int = 24, every: float = 30.0):
        self.width, self.every = width, every
        self.tty = sys.stderr.isatty()
        self.t0 = self._printed = time.perf_counter()
        self.fraction, self.text = 0.0, ""

    def __call__(self, fraction: float, text: str = "") -> None:
        self.fraction, self.text = fraction, text
        now = time.perf_counter()
        if self.tty:
            filled = int(round(self.width * fraction))
            line = f"batch [{'#' * filled}{'-' * (self.width - filled)}] {text}"
            cols = shutil.get_terminal_size((100, 20)).columns - 1
            sys.stderr.write("\r" + line[:cols].ljust(cols))
            sys.stderr.flush()
        elif now - self._printed >= self.every:
            self._printed = now
            print(f"batch {fraction * 100:5.1f}% {text}", file=sys.stderr, flush=True)

    def close(self) -> None:
        if self.tty and self.text:
            sys.stderr.write("\n")
            sys.stderr.flush()
