"""What a motion file may hold, and its lines read within that: the limits that keep a
damaged or hostile file (a million joints, a 50 MB line) a clear error in under a second
rather than minutes and gigabytes."""

from __future__ import annotations

from pathlib import Path
from typing import Iterator

from .errors import MotionFileError

#: the longest line a motion file may hold (characters): a BVH frame of
#: :data:`MAX_JOINTS` joints with six channels, each printed to 17 digits, is shorter; a
#: longer one is refused before it is split into words
MAX_LINE_CHARS = 4 << 20
#: the most joints (bones) a skeleton may have: studio skeletons with faces and fingers
#: have a few hundred
MAX_JOINTS = 10_000
#: characters split into lines at a time by :func:`iter_lines`
_CHUNK_CHARS = 1 << 20


def iter_lines(path: str | Path) -> Iterator[str]:
    """The lines of a motion file, split as ``str.splitlines`` splits them (any line
    ends; bytes that are not UTF-8 replaced), a megabyte at a time: a reader that stops
    early (a bad header) never splits the rest.

    Raises :class:`MotionFileError` where the file cannot be read or a line is longer
    than :data:`MAX_LINE_CHARS`, naming that line.
    """
    try:
        text = Path(path).read_bytes().decode("utf-8", errors="replace")
    except OSError as err:
        raise MotionFileError(path, f"cannot read the file ({err.strerror or err})") from None
    n, start = 0, 0
    while start < len(text):
        cut = text.find("\n", start + _CHUNK_CHARS)  # cut after a newline: a CRLF stays whole
        end = len(text) if cut < 0 else cut + 1
        for line in text[start:end].splitlines():
            n += 1
            if len(line) > MAX_LINE_CHARS:
                raise MotionFileError(
                    path,
                    f"a line of {len(line):,} characters, longer than any motion file holds "
                    f"({MAX_LINE_CHARS:,}): the file is damaged or not a motion file",
                    n,
                )
            yield line
        start = end


def read_lines(path: str | Path) -> list[str]:
    """Every line of :func:`iter_lines`."""
    return list(iter_lines(path))
