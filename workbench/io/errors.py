"""The one error type readers raise for a bad file: it names the file and the line."""

from __future__ import annotations

import json
from pathlib import Path


class MotionFileError(ValueError):
    """A motion file cannot be read: ``str(err)`` is ``PATH:LINE: what is wrong``."""

    def __init__(self, path: str | Path, message: str, line: int | None = None) -> None:
        self.path = str(path)
        self.line = line
        self.reason = message
        where = f"{self.path}:{line}" if line is not None else self.path
        super().__init__(f"{where}: {message}")


#: the longest line a motion file may hold (characters): a BVH frame of
#: :data:`MAX_JOINTS` joints with six channels, each printed to 17 digits, is shorter; a
#: longer one is a damaged or a hostile file, refused before it is split into words
MAX_LINE_CHARS = 4 << 20
#: the most joints (bones) a skeleton may have: studio skeletons with faces and fingers
#: have a few hundred; a header claiming a million would take minutes and gigabytes
MAX_JOINTS = 10_000


def read_lines(path: str | Path) -> list[str]:
    """The lines of a motion file (any line ends; bytes that are not UTF-8 replaced).

    Raises :class:`MotionFileError` where the file cannot be read or a line is longer
    than :data:`MAX_LINE_CHARS`, naming that line.
    """
    try:
        text = Path(path).read_bytes().decode("utf-8", errors="replace")
    except OSError as err:
        raise MotionFileError(path, f"cannot read the file ({err.strerror or err})") from None
    lines = text.splitlines()
    del text
    if lines and max(map(len, lines)) > MAX_LINE_CHARS:
        n = next(n for n, line in enumerate(lines, start=1) if len(line) > MAX_LINE_CHARS)
        raise MotionFileError(
            path,
            f"a line of {len(lines[n - 1]):,} characters, longer than any motion file holds "
            f"({MAX_LINE_CHARS:,}): the file is damaged or not a motion file",
            n,
        )
    return lines


class OutputFileError(OSError):
    """A file cannot be written (a full disk, a read-only folder, no permission): ``str(err)``
    names the file, the system's reason, and that nothing there was lost, since every
    output is written atomically (:func:`workbench.io.atomic.atomic_path`)."""

    def __init__(self, path: str | Path, cause: OSError) -> None:
        super().__init__(cause.errno, cause.strerror or str(cause))
        self.path = str(path)

    def __str__(self) -> str:
        return (
            f"{self.path}: cannot write it ({self.strerror}); nothing was written there, "
            "and any file it would have replaced is as it was"
        )


def read_json_file(path: str | Path, kind: str) -> object:
    """The JSON document in ``path``; a :class:`MotionFileError` naming the file and ``kind``
    (e.g. "mask", "mapping") where it cannot be read or is not JSON."""
    try:
        return json.loads(Path(path).read_text(encoding="utf-8"))
    except OSError as err:
        raise MotionFileError(path, f"cannot read the {kind} file ({err.strerror or err})") from None
    except ValueError as err:
        raise MotionFileError(path, f"not a JSON {kind} file ({err})") from None
