"""What a motion file may hold, and its lines read within that: the limits that keep a
damaged or hostile file (a million joints, a 50 MB line) a clear error in under a second
rather than minutes and gigabytes."""

from __future__ import annotations

import codecs
import re
from dataclasses import dataclass
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
#: the shortest frame time a motion file may give (seconds): 100,000 frames a second,
#: far above any capture's rate; a shorter one is a damaged line, not a take
MIN_FRAME_TIME = 1e-5
#: the largest magnitude a motion file's value may have (degrees, or its length unit): a
#: thousand kilometres in millimetres, a million turns; a larger one is a damaged number,
#: and squared it would overflow every engine's arithmetic to infinity
MAX_ABS_VALUE = 1e9
#: bytes decoded and split into lines at a time by :class:`Lines`
_CHUNK_BYTES = 1 << 20


def name_fault(name: str) -> str | None:
    """What is wrong with a joint's (a bone's) ``name`` as a file gives it, completing a
    sentence that starts with the name; None for a name that may be written back. A control
    character is refused: a NUL ends the name in C's strings, so other tools would read
    another name."""
    bad = next((c for c in name if ord(c) < 32 or ord(c) == 127), None)
    return None if bad is None else f"holds the control character {ord(bad):#04x}: rename the joint"


class Lines:
    """The lines of a motion file, split as ``str.splitlines`` splits them (any line
    ends; a UTF-8 byte order mark skipped; a file that is not UTF-8 read as Latin-1, its
    lines ended by CR and LF only: :attr:`encoding`), decoded and split a megabyte at a time as
    they are asked for: a reader that stops early (a bad header) never decodes the rest,
    and one that meets a block of frame numbers can hand its bytes (:meth:`rest`) to a
    compiled parser instead.

    Iterating raises :class:`MotionFileError` where a line is longer than
    :data:`MAX_LINE_CHARS`, naming that line.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = path
        if Path(path).exists() and not Path(path).is_file():  # a pipe would block the read for ever
            raise MotionFileError(path, "not a file (a folder, a pipe or a device): name a motion file")
        try:
            raw = Path(path).read_bytes()
        except OSError as err:
            raise MotionFileError(path, f"cannot read the file ({err.strerror or err})") from None
        if raw.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):  # a Windows "Unicode" save: read as UTF-8
            try:
                raw = raw.decode("utf-16").encode("utf-8")
            except UnicodeDecodeError:
                raise MotionFileError(path, "starts as UTF-16 text but is not: the file is damaged") from None
        # a DOS end-of-file mark or NUL padding after the text is not a line of the take
        self.raw = raw.rstrip(b"\x00\x1a")
        self._progress = _Progress()
        # the generator sees the bytes and the progress, not this object: no reference
        # cycle, so the file's bytes go as soon as the reader drops it, not at the next
        # garbage collection (a 68 MB take's bytes lived on through its cleaning)
        self._iter = _split(self.raw, self._progress, path)

    @property
    def count(self) -> int:
        """Lines given out so far."""
        return self._progress.count

    def __iter__(self) -> Iterator[str]:
        return self._iter

    def __next__(self) -> str:
        return next(self._iter)

    def rest(self) -> tuple[bytes, int] | None:
        """The file's bytes and the offset in them where the line after the last one
        given out starts, if that line follows a LF (a compiled CSV parser counts lines
        by LF) and everything before it was UTF-8; None otherwise."""
        done = self._progress
        given = done.chunk[: done.given]
        if not given.endswith("\n") or done.encoding != "utf-8":
            return None
        return self.raw, done.start + len(given.encode("utf-8"))

    @property
    def encoding(self) -> str:
        """How the file was decoded: ``"utf-8"``, or ``"latin-1"`` where it is not UTF-8
        (each byte one character, so that text encoded back with it is the file's bytes)."""
        return self._progress.encoding


@dataclass
class _Progress:
    """How far :class:`Lines` has split its file: the lines given out, the bytes decoded
    last (``raw[start:end]``), their text and how many of its characters are given out."""

    count: int = 0
    start: int = 0
    end: int = 0
    chunk: str = ""
    given: int = 0
    encoding: str = "utf-8"


def _split(raw: bytes, done: _Progress, path) -> Iterator[str]:
    """The lines of ``raw`` for :class:`Lines`, recording its progress in ``done``."""
    if raw.startswith(codecs.BOM_UTF8):  # a UTF-8 byte order mark, which some editors write
        done.end = len(codecs.BOM_UTF8)
    if not _is_utf8(raw):
        done.encoding = "latin-1"
    while done.end < len(raw):
        cut = raw.find(b"\n", done.end + _CHUNK_BYTES)  # after a newline: no CRLF or UTF-8 sequence split
        done.start, done.end = done.end, len(raw) if cut < 0 else cut + 1
        done.chunk, done.given = raw[done.start : done.end].decode(done.encoding), 0
        for line, whole in _lines(done.chunk, done.encoding):
            done.count += 1
            done.given += len(whole)
            if len(line) > MAX_LINE_CHARS:
                raise MotionFileError(
                    path,
                    f"a line of {len(line):,} characters, longer than any motion file holds "
                    f"({MAX_LINE_CHARS:,}): the file is damaged or not a motion file",
                    done.count,
                )
            yield line


def _is_utf8(raw: bytes) -> bool:
    """Whether ``raw`` is UTF-8 text (ASCII, as most motion files, told at once)."""
    if raw.isascii():
        return True
    try:
        raw.decode("utf-8")
    except UnicodeDecodeError:
        return False
    return True


#: a line of Latin-1 text and its end: only CR and LF end one, since the bytes 0x85 and
#: 0x1C-0x1E, which ``str.splitlines`` also splits at, are letters of other encodings
#: (0x85 is the second byte of Shift-JIS katakana)
_LATIN1_LINE = re.compile(r"([^\r\n]*)(\r\n|\r|\n|\Z)")


def _lines(text: str, encoding: str) -> Iterator[tuple[str, str]]:
    """(line, the line with its end) of ``text`` decoded with ``encoding``."""
    if encoding == "utf-8":
        yield from zip(text.splitlines(), text.splitlines(keepends=True))
        return
    for match in _LATIN1_LINE.finditer(text):
        if match.group(0):
            yield match.group(1), match.group(0)


def read_lines(path: str | Path) -> list[str]:
    """Every line of a motion file (:class:`Lines`)."""
    return list(Lines(path))
