"""The one exception type users see, and the cancellation signal.

Every failure caused by the user's input (a file, a folder, an option) is raised as
:class:`AnatomeshError` with a one-line message that names the file and the problem and says
what to do. The CLI prints ``error: <message>`` and exits with code 2; the Blender add-on shows
the message in its report area. Nothing else should reach the user as a traceback.
"""
from __future__ import annotations


class AnatomeshError(Exception):
    """A user-facing error: ``str(err)`` is the full one-line message.

    Parameters
    ----------
    message : str
        What is wrong and what to do about it.
    path : str or os.PathLike, optional
        The file or folder concerned; it is put in front of the message.
    """

    def __init__(self, message: str, path=None):
        self.path = None if path is None else str(path)
        self.message = message
        super().__init__(f"{self.path}: {message}" if self.path else message)


class Cancelled(Exception):
    """Raised by a progress callback to stop long work; nothing is written after it."""
