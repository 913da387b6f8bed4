"""The one error type readers raise for a bad file: it names the file and the line."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path


class MotionFileError(ValueError):
    """A motion file cannot be read: ``str(err)`` is ``PATH:LINE: what is wrong``."""

    def __init__(self, path: str | Path, message: str, line: int | None = None) -> None:
        self.path = str(path)
        self.line = line
        self.reason = message
        where = f"{self.path}:{line}" if line is not None else self.path
        super().__init__(f"{where}: {message}")


class OutputFileError(OSError):
    """A file cannot be written (a full disk, a read-only folder, no permission): ``str(err)``
    names the file, the system's reason, and that nothing there was lost, since every
    output is written atomically (:func:`workbench.io.atomic.atomic_path`)."""

    def __init__(self, path: str | Path, cause: OSError) -> None:
        number, reason = cause.errno, cause.strerror
        # polars writes the BVH frame lines itself and says "<reason> (os error N)"
        if number is None and (rust := re.fullmatch(r".* \(os error (\d+)\)", str(cause))):
            number = int(rust[1])
            reason = os.strerror(number)
        super().__init__(number, reason or str(cause))
        self.path = str(path)

    def __str__(self) -> str:
        return (
            f"{self.path}: cannot write it ({self.strerror}); nothing was written there, "
            "and any file it would have replaced is as it was"
        )


def read_json_file(path: str | Path, kind: str) -> object:
    """The JSON document in ``path``; a :class:`MotionFileError` naming the file and ``kind``
    (e.g. "mask", "mapping") where it cannot be read or is not JSON. A UTF-8 byte-order
    mark, which some editors write, is read past (as the BVH reader does)."""
    try:
        return json.loads(Path(path).read_text(encoding="utf-8-sig"))
    except OSError as err:
        raise MotionFileError(path, f"cannot read the {kind} file ({err.strerror or err})") from None
    except ValueError as err:
        raise MotionFileError(path, f"not a JSON {kind} file ({err})") from None
