"""The one error type readers raise for a bad file: it names the file and the line."""

from __future__ import annotations

from pathlib import Path


class MotionFileError(ValueError):
    """A motion file cannot be read: ``str(err)`` is ``PATH:LINE: what is wrong``."""

    def __init__(self, path: str | Path, message: str, line: int | None = None) -> None:
        self.path = str(path)
        self.line = line
        self.reason = message
        where = f"{self.path}:{line}" if line is not None else self.path
        super().__init__(f"{where}: {message}")
