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
#: bytes decoded and split into lines at a time by :class:`Lines`
_CHUNK_BYTES = 1 << 20


class Lines:
    """The lines of a motion file, split as ``str.splitlines`` splits them (any line
    ends; bytes that are not UTF-8 replaced), decoded and split a megabyte at a time as
    they are asked for: a reader that stops early (a bad header) never decodes the rest,
    and one that meets a block of frame numbers can hand its bytes (:meth:`rest`) to a
    compiled parser instead.

    Iterating raises :class:`MotionFileError` where a line is longer than
    :data:`MAX_LINE_CHARS`, naming that line.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = path
        try:
            self.raw = Path(path).read_bytes()
        except OSError as err:
            raise MotionFileError(path, f"cannot read the file ({err.strerror or err})") from None
        #: lines given out so far
        self.count = 0
        self._start = self._end = 0  # the bytes decoded last: raw[start:end]
        self._chunk = ""  # their text, and how many of its characters are given out
        self._given = 0
        self._iter = self._split()

    def __iter__(self) -> Iterator[str]:
        return self._iter

    def __next__(self) -> str:
        return next(self._iter)

    def _split(self) -> Iterator[str]:
        raw = self.raw
        while self._end < len(raw):
            cut = raw.find(b"\n", self._end + _CHUNK_BYTES)  # after a newline: no CRLF or UTF-8 sequence split
            self._start, self._end = self._end, len(raw) if cut < 0 else cut + 1
            self._chunk, self._given = raw[self._start : self._end].decode("utf-8", errors="replace"), 0
            for line, whole in zip(self._chunk.splitlines(), self._chunk.splitlines(keepends=True)):
                self.count += 1
                self._given += len(whole)
                if len(line) > MAX_LINE_CHARS:
                    raise MotionFileError(
                        self.path,
                        f"a line of {len(line):,} characters, longer than any motion file holds "
                        f"({MAX_LINE_CHARS:,}): the file is damaged or not a motion file",
                        self.count,
                    )
                yield line

    def rest(self) -> tuple[bytes, int] | None:
        """The file's bytes and the offset in them where the line after the last one
        given out starts, if that line follows a LF (a compiled CSV parser counts lines
        by LF) and everything before it was UTF-8; None otherwise."""
        given = self._chunk[: self._given]
        if not given.endswith("\n") or "\ufffd" in given:  # a replaced byte re-encodes to another length
            return None
        return self.raw, self._start + len(given.encode("utf-8"))


def read_lines(path: str | Path) -> list[str]:
    """Every line of a motion file (:class:`Lines`)."""
    return list(Lines(path))
