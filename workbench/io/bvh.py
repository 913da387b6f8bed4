"""BVH read and write.

Reads any BVH whose joints carry three rotation channels or none and three position
channels or none, in any order on any joint (MotionBuilder exports all six on every
joint): CRLF, LF and mixed line endings, tabs or spaces, a UTF-8 byte order mark, channel
names in any case; joint names in UTF-8, or in any other encoding, read as Latin-1 and
written back byte for byte (:attr:`Skeleton.text_encoding`). A joint's position channels
replace its OFFSET as its local translation, as Blender reads them; where they hold one
value throughout the take it is folded into the skeleton, where they vary the joint is
translated (:mod:`workbench.core.skeleton`). Angles stay in degrees, lengths in the
file's unit. Every problem is a :class:`MotionFileError` naming the file and line.
Writing is atomic and keeps the channel layout, the Euler orders and the OFFSET lines
of the skeleton, so a file read and written back holds the same numbers (a folded
joint's channels as frame 0's, which the other frames repeat up to printing).
"""

from __future__ import annotations

import io
import math
import os
import re
from pathlib import Path
from typing import BinaryIO, Iterator

import numpy as np

from ..core.motion import Motion
from ..core.skeleton import POSITION_CHANNELS, ROTATION_CHANNELS, Skeleton, given_unit_cm
from .atomic import atomic_path
from .errors import MotionFileError
from .limits import MAX_ABS_VALUE, MAX_JOINTS, MIN_FRAME_TIME, Lines, name_fault


class _Tokens:
    """The header's whitespace tokens with their line numbers, split off as the parser
    asks for them from ``lines``, an iterator (a header of a million tokens costs nothing
    past its first error). Once the tokens before it are read, :attr:`motion_line` is the
    MOTION line's number and :attr:`motion_text` its text, and ``lines`` goes on after
    it; :attr:`lines_read` counts the lines taken."""

    def __init__(self, lines: Iterator[str], path: str) -> None:
        self.path = path
        self.motion_line: int | None = None
        self.motion_text = ""
        self.lines_read = 0
        self._stream = self._split(lines)
        self._line = 1
        self._back: tuple[str, int] | None = None  # a token read ahead and given back

    def _split(self, lines: Iterator[str]) -> Iterator[tuple[str, int]]:
        for n, line in enumerate(lines, start=1):
            self.lines_read = n
            words = (m.group() for m in _WORD.finditer(line))
            first = next(words, None)
            if first is not None and first.upper() == "MOTION":
                self.motion_line, self.motion_text = n, line
                return
            if first is not None:
                yield first, n
                yield from ((w, n) for w in words)

    def next(self, what: str) -> tuple[str, int]:
        tok, self._back = (self._back, None) if self._back is not None else (next(self._stream, None), None)
        if tok is None:
            raise MotionFileError(self.path, f"file ends inside the HIERARCHY section, expected {what}", self._line)
        self._line = tok[1]
        return tok

    def name(self, what: str) -> tuple[str, int]:
        """The next token and those after it on its line up to a ``{``, joined by spaces:
        a joint's name, which may hold spaces (3ds Max's ``Bip01 L Thigh``)."""
        first, line = self.next(what)
        words = [first]
        while (tok := next(self._stream, None)) is not None and tok[1] == line and tok[0] != "{":
            words.append(tok[0])
        self._back = tok
        name = " ".join(words)
        if (fault := name_fault(name)) is not None:
            raise MotionFileError(self.path, f"{what} {name!r} {fault}", line)
        return name, line

    def give_back(self, tok: tuple[str, int]) -> None:
        """Make ``tok`` the next token again."""
        self._back = tok

    def left_over(self) -> tuple[str, int] | None:
        """The next token before the MOTION line, if any."""
        return self._back if self._back is not None else next(self._stream, None)

    def expect(self, word: str) -> int:
        tok, line = self.next(repr(word))
        if tok != word:
            raise MotionFileError(self.path, f"expected {word!r}, found {tok!r}", line)
        return line

    def number(self, what: str) -> float:
        """The next token as a finite number (a header's: NaN or inf is no offset or frame time)."""
        tok, line = self.next(what)
        try:
            value = float(tok)
        except ValueError:
            value = math.nan
        if not math.isfinite(value):
            raise MotionFileError(self.path, f"expected a number for {what}, found {tok!r}", line)
        return value


#: a header token: ASCII whitespace parts them (a name's no-break space, or a Latin-1
#: byte 0xA0 in a Shift-JIS name, is part of the name)
_WORD = re.compile(r"\S+", re.ASCII)
#: the channel names, by their lower case: exporters differ in case (``XROTATION``,
#: ``xrotation``); a take is written back in the standard's (``Xrotation``)
_CHANNEL_NAMES = {name.lower(): name for name in ROTATION_CHANNELS + POSITION_CHANNELS}


def _parse_hierarchy(tokens: _Tokens) -> Skeleton:
    names: list[str] = []
    parents: list[int] = []
    offsets: list[list[float]] = []
    channels: list[tuple[str, ...]] = []
    end_sites: list[tuple[int, tuple[float, float, float]]] = []
    path = tokens.path

    if (first := tokens.left_over()) is None:
        raise MotionFileError(path, "the file is empty" if tokens.motion_line is None else "no HIERARCHY section")
    tokens.give_back(first)
    tok, line = tokens.next("'HIERARCHY'")
    if tok.upper() != "HIERARCHY":
        shown = f"{tok[:20]!r}{'...' if len(tok) > 20 else ''}"
        raise MotionFileError(path, f"not a BVH file: expected 'HIERARCHY', found {shown}", line)
    tok, line = tokens.next("'ROOT'")
    if tok != "ROOT":
        raise MotionFileError(path, f"expected 'ROOT', found {tok!r}", line)

    def offset() -> list[float]:
        tokens.expect("OFFSET")
        return [tokens.number("OFFSET x"), tokens.number("OFFSET y"), tokens.number("OFFSET z")]

    seen: set[str] = set()

    def open_joint(parent: int) -> int:
        """Read a joint's name, brace, OFFSET and CHANNELS; its index."""
        name, line = tokens.name("a joint name")
        if len(names) >= MAX_JOINTS:
            raise MotionFileError(path, f"more than {MAX_JOINTS:,} joints: no capture skeleton has so many", line)
        if name in seen:
            raise MotionFileError(path, f"joint name {name!r} appears twice", line)
        seen.add(name)
        tokens.expect("{")
        names.append(name)
        parents.append(parent)
        offsets.append(offset())
        tok, line = tokens.next("'CHANNELS'")
        if tok != "CHANNELS":
            raise MotionFileError(path, f"expected 'CHANNELS' for joint {name!r}, found {tok!r}", line)
        count = tokens.number("the channel count")
        if not 0 <= count <= 6 or count != int(count):
            raise MotionFileError(path, f"joint {name!r}: channel count must be 0 to 6, got {count}", line)
        chans = []
        for _ in range(int(count)):
            ch, cline = tokens.next("a channel name")
            if ch in ("JOINT", "End", "}", "OFFSET", "CHANNELS", "MOTION"):  # the header goes on: too few names
                raise MotionFileError(
                    path, f"joint {name!r}: CHANNELS says {int(count)} but names {len(chans)}, then {ch!r}", cline
                )
            if ch.lower() not in _CHANNEL_NAMES:
                raise MotionFileError(path, f"joint {name!r}: unknown channel name {ch!r}", cline)
            chans.append(_CHANNEL_NAMES[ch.lower()])
        channels.append(tuple(chans))
        try:
            Skeleton._validate_channels(name, tuple(chans))
        except ValueError as err:
            raise MotionFileError(path, str(err), line) from None
        return len(names) - 1

    # the open joints, innermost last: a loop, not recursion, so any depth reads
    open_joints = [open_joint(-1)]
    while open_joints:
        tok, line = tokens.next("'JOINT', 'End Site' or '}'")
        if tok == "}":
            open_joints.pop()
        elif tok == "JOINT":
            open_joints.append(open_joint(open_joints[-1]))
        elif tok == "End":
            site, sline = tokens.next("'Site'")
            if site.lower() != "site":
                raise MotionFileError(path, f"expected 'End Site', found 'End {site}'", sline)
            tokens.expect("{")
            end_sites.append((open_joints[-1], tuple(offset())))
            tokens.expect("}")
        else:
            raise MotionFileError(path, f"expected 'JOINT', 'End Site' or '}}', found {tok!r}", line)
    extra = tokens.left_over()
    if extra is not None:
        raise MotionFileError(path, f"unexpected {extra[0]!r} after the root joint's closing brace", extra[1])
    # The root's position channels are its whole translation: they replace its OFFSET.
    file_offsets = np.array(offsets, float)
    root_offset = np.zeros(3) if any(c in POSITION_CHANNELS for c in channels[0]) else file_offsets[0]
    return Skeleton(
        tuple(names),
        tuple(parents),
        np.vstack([root_offset, file_offsets[1:]]),
        tuple(channels),
        tuple(end_sites),
        file_offsets=file_offsets,
    )


def _parse_motion(
    motion_text: str, lines: Lines, start: int, skeleton: Skeleton, path: str
) -> tuple[float, np.ndarray]:
    """Parse the MOTION section: its line ``motion_text``, line number ``start``
    (1-based), then the rest of ``lines`` to the file's end: returns (frames per second,
    :func:`fps_from_frame_time` of its frame time, values (F, D))."""

    def header(n: int, label: str) -> str:
        text = next(lines, None)
        if text is None:
            raise MotionFileError(path, f"file ends before the '{label}' line", n - 1)
        text = " ".join(text.split())  # 'Frame\tTime:' too: any whitespace between the words
        if not text.lower().startswith(label.lower()):
            raise MotionFileError(path, f"expected '{label} ...', found {text[:40]!r}", n)
        return text[len(label) :].strip()

    rest = motion_text.split()[1:]
    if rest:
        raise MotionFileError(path, f"unexpected {rest[0]!r} after MOTION", start)
    frames_text = header(start + 1, "Frames:")
    try:
        n_frames = int(frames_text)
    except ValueError:
        raise MotionFileError(path, f"'Frames:' must be a whole number, found {frames_text!r}", start + 1) from None
    if n_frames <= 0:
        raise MotionFileError(
            path, f"'Frames:' must be at least 1, found {frames_text!r}: no motion to read", start + 1
        )
    ft_text = header(start + 2, "Frame Time:")
    try:
        frame_time = float(ft_text)
    except ValueError:
        raise MotionFileError(path, f"'Frame Time:' must be a number, found {ft_text!r}", start + 2) from None
    if not frame_time > 0 or not np.isfinite(frame_time):
        raise MotionFileError(path, f"'Frame Time:' must be positive, found {ft_text!r}", start + 2)
    if frame_time < MIN_FRAME_TIME:
        raise MotionFileError(
            path,
            f"'Frame Time: {ft_text}' is {1 / frame_time:.3g} frames a second, faster than any capture; mend that "
            "line (the time from one frame to the next, in seconds: 0.0083333 at 120 fps)",
            start + 2,
        )

    D = sum(len(ch) for ch in skeleton.channels)
    values = _compiled_frames(lines.rest(), n_frames, D)
    if values is None:
        values = _frames_line_by_line(list(lines), start + 3, n_frames, D, path)
    with np.errstate(invalid="ignore"):  # NaN marks a missing value
        absurd = np.abs(values) > MAX_ABS_VALUE
    if absurd.any():
        n, c = (int(i) for i in np.argwhere(absurd)[0])
        raise MotionFileError(
            path,
            f"frame {n}: {values[n, c]:g} in channel {c + 1}, beyond the +-{MAX_ABS_VALUE:g} any position or angle "
            "lies within; write nan there to mark it missing",
            start + 3 + n,
        )
    decimals = None if "e" in ft_text.lower() else len(ft_text.partition(".")[2])  # as printed: 0.0417 to 4
    return fps_from_frame_time(frame_time, decimals), values


def _polars():
    """polars, its allocator (jemalloc) told to hand freed pages back at once unless the
    environment says otherwise: by default it keeps them for seconds, and a long take's
    read left 116 MB of them resident through the cleaning."""
    os.environ.setdefault("_RJEM_MALLOC_CONF", "dirty_decay_ms:0,muzzy_decay_ms:0")
    import polars

    return polars


def _compiled_frames(rest: tuple[bytes, int] | None, n_frames: int, D: int) -> np.ndarray | None:
    """The (F, D) frame values that start at byte ``offset`` of the file's bytes (``rest``
    = (bytes, offset)), read by polars' compiled CSV reader (multithreaded, correctly
    rounded: the same numbers as :func:`_numbers`), where the lines are as exporters
    write them: ``n_frames`` lines of D numbers one space apart, LF or CRLF ends, a space
    before the end allowed. None for anything else (tabs, runs of spaces, blank lines,
    a word that is no number, the wrong count): :func:`_frames_line_by_line` then reads
    the lines or says what is wrong with them."""
    if rest is None or D == 0:
        return None
    pl = _polars()

    raw, offset = rest
    end = raw.find(b"\n", offset)
    first = raw[offset : end if end >= 0 else len(raw)].rstrip(b"\r")
    width = D + first.endswith(b" ")  # the space before the end makes an empty last column
    try:
        frame = pl.read_csv(
            raw,
            has_header=False,
            separator=" ",
            quote_char=None,
            skip_lines=raw.count(b"\n", 0, offset),
            schema={f"c{i}": pl.Float64 for i in range(width)},
        )
    except (pl.exceptions.PolarsError, pl.exceptions.PanicException):
        return None
    nulls = frame.null_count().row(0)
    if frame.height != n_frames or any(nulls[:D]) or (width > D and nulls[D] != n_frames):
        return None
    return frame[:, :D].to_numpy()


def _is_frame(line: str, D: int) -> bool:
    """Whether ``line`` holds a frame's ``D`` numbers."""
    try:
        return _numbers(line.strip()).size == D
    except ValueError:
        return False


def _frames_line_by_line(body: list[str], first: int, n_frames: int, D: int, path: str) -> np.ndarray:
    """The (F, D) values of the frame lines ``body``, the first of them line number
    ``first``: any whitespace between numbers, trailing blank lines ignored; a
    :class:`MotionFileError` naming the line for anything else."""
    while body and not body[-1].strip():
        body.pop()
    blank = next((n for n, line in enumerate(body) if not line.strip()), None)
    if blank is not None:  # before the count, which it throws off
        raise MotionFileError(
            path, f"a blank line among the frame lines: delete it, or put a frame's {D} values there", first + blank
        )
    if len(body) < n_frames:
        whole = len(body) - (1 if body and not _is_frame(body[-1], D) else 0)  # the last line may be cut off
        raise MotionFileError(
            path,
            f"motion section is truncated: 'Frames:' says {n_frames} but only {whole} whole frame lines follow; if "
            f"the file was cut short, copy it again, else set 'Frames:' to {whole}"
            + (" and delete the cut-off line after them" if whole < len(body) else ""),
            first + len(body) - 1 if body else first - 1,
        )
    # the lines just after the frames, and the last: a count far too small costs no scan of all
    extra = [*range(n_frames, min(len(body), n_frames + 100)), *range(max(n_frames + 100, len(body) - 1), len(body))]
    junk = next((n for n in extra if not _is_frame(body[n], D)), None)
    if junk is not None:  # not frames: counting them in would not read the file either
        raise MotionFileError(
            path,
            f"after the {n_frames} frames 'Frames:' says, a line that is no frame of {D} values: delete it "
            "(and any other such line)",
            first + junk,
        )
    if len(body) > n_frames:
        raise MotionFileError(
            path,
            f"'Frames:' says {n_frames} but {len(body)} frame lines follow; if they are all frames of the take, "
            f"set 'Frames:' to {len(body)}, else delete the lines after frame {n_frames}",
            first + n_frames,
        )
    values = np.empty((n_frames, D))
    for n, line in enumerate(body):  # a line at a time: memory of the values, not of their words
        text = line.strip()
        try:
            row = _numbers(text)
        except ValueError:
            bad = next((w for w in text.split() if not _is_number(w)), None)
            what = f"{bad!r} is not a number" if bad else "values must be separated by spaces or tabs"
            raise MotionFileError(path, f"frame {n}: {what}", first + n) from None
        if row.size != D:
            raise MotionFileError(path, f"frame {n} has {row.size} values, the hierarchy has {D} channels", first + n)
        values[n] = row
    return values


def _numbers(text: str) -> np.ndarray:
    """The numbers of a frame line (not blank) in C's notation (``nan``, ``inf`` and
    exponents, as exporters print them): ValueError for anything else."""
    return np.fromstring(text, sep=" ")


def _is_number(word: str) -> bool:
    try:
        return _numbers(word).size == 1
    except ValueError:
        return False


def fps_from_frame_time(frame_time: float, decimals: int | None = None) -> float:
    """Frames per second; snapped to a whole number when the file rounded its frame time
    (``.0083333`` is 120 fps), or to the NTSC rate N / 1.001 near it (``0.0166833`` is
    59.94 fps, not 60: a take kept at 60 would drift from its video by 0.1 %), whichever
    lies nearer. A frame time printed to 4 or more ``decimals`` is the rate whose frame
    time prints as it, the whole number first (``0.0417`` is 24 fps, though nearer 23.976;
    ``0.0167`` is 60)."""
    fps = 1.0 / frame_time
    whole, ntsc = round(fps), round(fps * 1.001) / 1.001
    for rate in (whole, ntsc) if decimals is not None and decimals >= 4 else ():
        if rate > 0 and round(1.0 / rate, decimals) == round(frame_time, decimals):
            return float(rate)
    nearest = min((whole, ntsc), key=lambda rate: abs(fps - rate))
    return float(nearest) if abs(fps - nearest) < 1e-3 * fps else fps


def read_bvh(path: str | Path, *, unit_cm: float | None = None) -> Motion:
    """Read a BVH file into a Motion. ``unit_cm`` overrides the guessed unit size
    (:func:`workbench.core.skeleton.given_unit_cm`: ValueError for one that is no size).

    Raises :class:`MotionFileError` for anything that is not a well-formed BVH file.
    NaN values are kept (they mark missing data).
    """
    path, unit_cm = Path(path), given_unit_cm(unit_cm)
    lines = Lines(path)
    tokens = _Tokens(lines, str(path))
    header = _parse_hierarchy(tokens).replace(text_encoding=lines.encoding)
    if tokens.motion_line is None:
        raise MotionFileError(path, "no MOTION section: the file ends after the hierarchy", tokens.lines_read)
    fps, values = _parse_motion(tokens.motion_text, lines, tokens.motion_line, header, str(path))
    motion = _motion_from_values(header, fps, values, name=path.stem)
    return motion if unit_cm is None else motion.replace(skeleton=motion.skeleton.replace(unit_cm=unit_cm))


def _column_layout(skeleton: Skeleton) -> list[tuple[int, bool, int]]:
    """For each file column, in order: (joint, is a position channel, slot), the slot
    being the axis (0 x, 1 y, 2 z) of a position and the place in the joint's Euler
    order of a rotation."""
    layout = []
    for j, chans in enumerate(skeleton.channels):
        rotations = [c for c in chans if c in ROTATION_CHANNELS]
        for ch in chans:
            if ch in POSITION_CHANNELS:
                layout.append((j, True, POSITION_CHANNELS.index(ch)))
            else:
                layout.append((j, False, rotations.index(ch)))
    return layout


#: how close, relative to their size or the skeleton's, two translations print as one:
#: exporters print 6 significant digits (MotionBuilder: -5.51765e-07 in one frame,
#: -5.51764e-07 in the next) or 6 decimals (an SMPL-X export in metres: a 1.7-cm jaw
#: bone at 0.016750 in one frame and 0.016751 in the next, from float32 rounding)
SAME_RELATIVE = 1e-5


def _same_translation(a: np.ndarray, b: np.ndarray, size: float) -> np.ndarray:
    """Whether translations ``a`` and ``b`` (..., 3), in file units, are one as printed:
    within :data:`SAME_RELATIVE` of the larger's length or of ``size`` (the skeleton's
    longest OFFSET), and 1e-9 units."""
    scale = np.maximum(np.maximum(np.linalg.norm(a, axis=-1), np.linalg.norm(b, axis=-1)), size)
    return np.linalg.norm(a - b, axis=-1) <= SAME_RELATIVE * scale + 1e-9


def _motion_from_values(header: Skeleton, fps: float, values: np.ndarray, name: str = "") -> Motion:
    """The Motion of a file's frame values (F, D) in the column layout of ``header``, the
    skeleton as the hierarchy gives it. A non-root joint's position channels that repeat
    its OFFSET line in every frame, as printed (:func:`_same_translation`; MotionBuilder
    exports all six channels on every joint), are folded into its offset and written
    back as frame 0's values; any other makes it translated: a moving Hips under a
    reference root (even in a take where it stands still), a stretchy bone. The unit is
    guessed on the resulting rest pose."""
    F, J = values.shape[0], header.n_joints
    positioned = np.flatnonzero(header.has_position[1:]) + 1  # the joints below the root with position channels
    slots = np.zeros(J, int)  # each of those joints' slot in `local`; the root's is 0
    slots[positioned] = np.arange(1, positioned.size + 1)
    angles = np.zeros((F, J, 3))
    local = np.zeros((F, 1 + positioned.size, 3))  # the root's position channels, then theirs (0 where none)
    for col, (j, is_position, slot) in enumerate(_column_layout(header)):
        if is_position:
            local[:, slots[j], slot] = values[:, col]
        else:
            angles[:, j, slot] = values[:, col]
    angles.setflags(write=False)  # the Motion takes it as it is: a long take's 50 MB are not copied
    size = float(np.linalg.norm(header.file_offsets, axis=1).max())
    rest = _same_translation(local[:, 1:], header.file_offsets[positioned], size).all(axis=0)  # NaN is no rest
    moving = positioned[~rest]
    offsets = np.array(header.offsets)
    offsets[positioned[rest]] = local[0, 1:][rest]
    skeleton = header.replace(offsets=offsets, translated=tuple(moving.tolist()), unit_cm=0.0)
    return Motion(skeleton, fps, local[:, 0], angles, name, translations=local[:, slots[moving]])


def motion_values(motion: Motion) -> np.ndarray:
    """The (F, D) frame values in the file's column layout (column-major: a column is a
    channel's frames), a folded joint's position channels holding its offset in every
    frame."""
    sk = motion.skeleton
    F = motion.n_frames
    moving = {0: motion.root_positions, **{j: motion.translations[:, t] for t, j in enumerate(sk.translated)}}
    layout = _column_layout(sk)
    values = np.empty((F, len(layout)), order="F")
    for col, (j, is_position, slot) in enumerate(layout):
        if not is_position:
            values[:, col] = motion.angles_deg[:, j, slot]
        else:
            values[:, col] = moving[j][:, slot] if j in moving else sk.offsets[j, slot]
    return values


#: significant digits of every number written: each number of a file with at most this
#: many (studio exports print 6, the cgspeed conversions up to 7) is written back exactly
DIGITS = 10


#: the deepest indentation written (tabs): deeper joints are written at this one, so a
#: chain of 10,000 joints is 4 MB of text rather than 250
MAX_INDENT = 64


def _hierarchy_text(motion: Motion, digits: int) -> str:
    """The BVH text of a motion up to its first frame line: the HIERARCHY (tab
    indentation, each number to ``digits`` significant digits), MOTION, ``Frames:`` and
    ``Frame Time:``, LF line ends."""
    sk = motion.skeleton
    out = io.StringIO()
    out.write("HIERARCHY\n")
    ends: dict[int, list] = {}
    for p, off in sk.end_sites:
        ends.setdefault(p, []).append(off)
    children = sk.children

    def fmt(v) -> str:
        return " ".join(f"{x:.{digits}g}" for x in v)

    # depth-first with an explicit stack (any depth): a joint opens, its children follow,
    # then its End Sites and its closing brace
    stack: list[tuple[int, int, bool]] = [(0, 0, False)]  # joint, depth, closing
    while stack:
        j, depth, closing = stack.pop()
        ind = "\t" * min(depth, MAX_INDENT)
        if closing:
            for off in ends.get(j, []):
                out.write(f"{ind}\tEnd Site\n{ind}\t{{\n{ind}\t\tOFFSET {fmt(off)}\n{ind}\t}}\n")
            out.write(f"{ind}}}\n")
            continue
        out.write(f"{ind}{'ROOT' if j == 0 else 'JOINT'} {sk.names[j]}\n{ind}{{\n")
        out.write(f"{ind}\tOFFSET {fmt(sk.file_offsets[j])}\n")
        out.write(f"{ind}\tCHANNELS {len(sk.channels[j])}{''.join(' ' + c for c in sk.channels[j])}\n")
        stack.append((j, depth, True))
        stack.extend((c, depth + 1, False) for c in reversed(children[j]))
    frame_time = 1.0 / motion.fps
    text = f"{frame_time:.7f}"  # as exporters write it; to more digits where that would lose the rate
    if abs(float(text) - frame_time) > 1e-3 * frame_time:
        text = f"{frame_time:.{digits}g}"
    out.write(f"MOTION\nFrames: {motion.n_frames}\nFrame Time: {text}\n")
    return out.getvalue()


#: exact powers of ten, 1 to 1e22 (the largest a double holds exactly)
_POWERS_OF_TEN = 10.0 ** np.arange(23)
#: numbers rounded at a time by :func:`significant`: its temporaries stay in reused memory
#: (a fresh 50 MB array costs 140 ms of page faults on the 2-core EPYC, more than the sums)
_ROUNDING_BLOCK = 1 << 18


def significant(values: np.ndarray, digits: int, out: np.ndarray | None = None) -> np.ndarray:
    """``values`` (any shape, finite) each rounded to ``digits`` significant digits (1 to
    17): the double nearest to the decimal that ``f"{x:.{digits}g}"`` prints, so that its
    shortest printed form has at most ``digits`` digits. Exact arithmetic where ``digits``
    is at most 15 (the scaled digits stay below 2^53) and the magnitude is from
    10^(digits-23) to 10^digits (the decimal's digits over an exact power of ten, one
    correctly rounded division); Python's formatting for the others. Written to ``out``
    (returned) when given: ``values`` itself, or an array of its shape and strides; a new
    array by default."""
    values = np.asarray(values, float)
    if not (values.flags.c_contiguous or values.flags.f_contiguous):
        values = np.ascontiguousarray(values)
    if out is None:
        out = np.empty_like(values)
    elif out.shape != values.shape or out.strides != values.strides or out.dtype != values.dtype:
        raise ValueError("significant: out must be a float64 array of the values' shape and strides")
    flat, flat_out = values.ravel(order="K"), out.ravel(order="K")  # views, in memory order
    for i in range(0, flat.size, _ROUNDING_BLOCK):
        x = flat[i : i + _ROUNDING_BLOCK]
        places = np.abs(x)  # decimal places that keep `digits` significant digits
        with np.errstate(divide="ignore"):
            np.log10(places, out=places)
        np.floor(places, out=places)
        np.subtract(digits - 1, places, out=places)
        exact = (places >= 0) & (places < len(_POWERS_OF_TEN)) & (digits <= 15)
        scale = _POWERS_OF_TEN.take(np.where(exact, places, 0).astype(np.intp))  # 1 where not exact
        others = ~exact & (x != 0)  # zeros (scale 1) come through the arithmetic as they are, signed
        formatted = [float(f"{v:.{digits}g}") for v in x[others]] if others.any() else None  # before x is written
        rounded = flat_out[i : i + _ROUNDING_BLOCK]
        np.multiply(x, scale, out=rounded)
        np.rint(rounded, out=rounded)
        np.divide(rounded, scale, out=rounded)
        if formatted is not None:
            rounded[others] = formatted
    return out


def _write_frame_lines(out: BinaryIO, values: np.ndarray, digits: int) -> None:
    """Write the frame lines of values (F, D) to ``out``, rounding ``values`` in place:
    each number :func:`significant` to ``digits`` digits and printed in its shortest form
    that reads back as it, by polars' compiled, multithreaded CSV writer ("12.5", "0.0",
    "1e-7"), one space apart, LF ends. polars writes to the file itself: through a buffer
    in memory, a 10-minute take's 68 MB of lines were copied twice more (0.09 s of 0.3)."""
    if values.shape[1] == 0:
        out.write(b"\n" * len(values))
        return
    frame = _polars().from_numpy(significant(values, digits, out=values))
    out.flush()  # what is written so far comes first
    frame.write_csv(out, include_header=False, separator=" ", quote_style="never", line_terminator="\n")


def format_bvh(motion: Motion, digits: int = DIGITS) -> str:
    """The BVH text of a motion (what :func:`write_bvh` writes). Raises ValueError for
    missing (NaN) values."""
    out = io.BytesIO()
    _write_bvh_to(out, motion, _finite_values(motion), digits)
    return out.getvalue().decode(motion.skeleton.text_encoding)


def _finite_values(motion: Motion) -> np.ndarray:
    """:func:`motion_values`; raises ValueError for missing (NaN) values."""
    values = motion_values(motion)
    if not np.isfinite(values).all():
        raise ValueError("the motion has missing (NaN) values: fill its gaps before writing it as BVH")
    return values


def _write_bvh_to(out: BinaryIO, motion: Motion, values: np.ndarray, digits: int) -> None:
    """Write the BVH file of a motion, whose :func:`motion_values` are ``values``, to the
    binary file ``out``: its :func:`_hierarchy_text`, then its frame lines."""
    out.write(_hierarchy_text(motion, digits).encode(motion.skeleton.text_encoding))
    _write_frame_lines(out, values, digits)


def write_bvh(path: str | Path, motion: Motion, digits: int = DIGITS) -> None:
    """Write ``motion`` as BVH, atomically (no partial file on error). Raises ValueError
    for missing (NaN) values, before any file is made."""
    values = _finite_values(motion)
    with atomic_path(path) as tmp, tmp.open("wb") as out:
        _write_bvh_to(out, motion, values, digits)
