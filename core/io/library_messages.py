"""What pydicom, highdicom, nibabel and pynrrd say while a file is read, in our own words: their
warnings and log records become one-line notes, their exceptions a complete clause of our errors.

Those libraries report oddities of a file (a value too long for its VR, a qfac of 0, a header field
they do not know) as Python ``UserWarning``s and log records, which would reach the user as raw
text on stderr, without the file's name. Readers run their library calls inside :func:`collect`;
each distinct message becomes one line of the reader's warnings::

    pydicom says about RS.dcm: The value length (18) exceeds the maximum length of 16 allowed for VR SH

Identical messages from several files are merged (``... (in 93 files, e.g. CTHead1.dcm)``).
Readers that return a Volume or Segmentation can be wrapped whole with :func:`notes_of_library`.
An exception's text enters our messages through :func:`reason`: its first sentence, never cut
mid-word.
"""
from __future__ import annotations

import functools
import logging
import os
import re
import warnings
from contextlib import contextmanager
from pathlib import Path
from typing import Dict, Iterator, List, Tuple

#: loggers whose records (warning level and above) are collected instead of printed
LOGGERS = ("pydicom", "highdicom", "nibabel", "nrrd")
#: library named in a note, by the package folder its warning came from
_PACKAGES = ("pydicom", "highdicom", "nibabel", "nrrd", "numpy", "scipy", "pylibjpeg", "openjpeg")


class WarningLog:
    """Library messages seen while reading, by message: ``{(library, text): [paths]}``."""

    def __init__(self) -> None:
        self.seen: Dict[Tuple[str, str], List[Path]] = {}

    def add(self, library: str, text: str, path) -> None:
        where = self.seen.setdefault((library, text), [])
        if path is not None and Path(path) not in where:
            where.append(Path(path))

    def merge(self, other: "WarningLog") -> None:
        """Add the messages of ``other`` (e.g. one file's, once the file is known to matter)."""
        for (library, text), paths in other.seen.items():
            for p in paths or [None]:
                self.add(library, text, p)

    def notes(self) -> List[str]:
        """One line per distinct message: the library, the file(s) and the message."""
        out = []
        for (library, text), paths in self.seen.items():
            if len(paths) > 1:
                where = f" (in {len(paths)} files, e.g. {paths[0].name})"
                out.append(f"{library} says: {text}{where}")
            elif paths:
                out.append(f"{library} says about {paths[0].name}: {text}")
            else:
                out.append(f"{library} says: {text}")
        return out


class _Collector(logging.Handler):
    def __init__(self, log: WarningLog, path) -> None:
        super().__init__(logging.WARNING)
        self.log, self.path = log, path

    def emit(self, record: logging.LogRecord) -> None:
        library = record.name.split(".")[0]
        self.log.add(library, short(record.getMessage()), self.path)


@contextmanager
def collect(log: WarningLog, path=None) -> Iterator[WarningLog]:
    """Run the block with library warnings and log records going into ``log`` (about ``path``)."""
    handler = _Collector(log, path)
    saved = []
    for name in LOGGERS:
        logger = logging.getLogger(name)
        saved.append((logger, logger.handlers[:], logger.propagate))
        logger.handlers, logger.propagate = [handler], False
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            yield log
    finally:
        for logger, handlers, propagate in saved:
            logger.handlers, logger.propagate = handlers, propagate
    for w in caught:
        log.add(_library(w.filename), short(str(w.message)), path)


def one_line(text: str) -> str:
    """A library message as one line: whitespace runs collapsed, trailing full stop dropped."""
    return " ".join(str(text).split()).rstrip(".") or "(no message)"


#: a long library message is shortened to its first sentence from this many characters on
LONG_REASON = 120
_MISSING_ATTRIBUTE = re.compile(r"^'\w+' object has no attribute '(\w+)'$")


def reason(err: BaseException) -> str:
    """A library exception as a complete clause for one of our messages (see :func:`short`);
    ``'X' object has no attribute 'Y'`` becomes ``Y is missing``; an exception without text gives
    its type name."""
    text = short(str(err)) if str(err).strip() else type(err).__name__
    missing = _MISSING_ATTRIBUTE.match(text)
    return f"{missing.group(1)} is missing" if missing else text


def short(text: str) -> str:
    """A library message as one complete line: its first line, shortened to its first sentence
    (or clause) when longer than :data:`LONG_REASON` characters; never cut mid-word."""
    lines = str(text).strip().splitlines()
    text = one_line(lines[0]) if lines else "(no message)"
    if len(text) > LONG_REASON:
        for stop in (" - ", ". ", "; ", ": "):
            head = text.split(stop)[0]
            if 20 <= len(head) < len(text):
                return head.rstrip(".,: ")
    return text


def _library(filename: str) -> str:
    parts = Path(filename or "").parts
    for name in _PACKAGES:
        if name in parts:
            return name
    return "python"


def notes_of_library(reader):
    """Wrap ``reader(path, ...)`` (returning an object with ``.warnings``): the library messages
    emitted while it runs are appended to the result's warnings as notes about ``path``."""

    @functools.wraps(reader)
    def wrapped(path, *args, **kwargs):
        log = WarningLog()
        named = path if isinstance(path, (str, os.PathLike)) else None
        with collect(log, named):
            out = reader(path, *args, **kwargs)
        add_notes(out, log.notes())
        return out

    return wrapped


def add_notes(result, notes: List[str]) -> None:
    """Append ``notes`` not already there to ``result.warnings`` (and to each layer's)."""
    targets = [result.warnings] + [layer.warnings for layer in getattr(result, "layers", [])]
    for target in targets:
        target.extend(n for n in notes if n not in target)


__all__ = ["WarningLog", "collect", "notes_of_library", "add_notes", "one_line", "reason", "short"]
