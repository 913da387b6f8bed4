"""Shared machinery of the corruption models: parameters, spec text, random streams and
the working state a chain of models edits.

Units: angles in degrees, root positions in the skeleton's file unit
(``skeleton.unit_cm`` cm each), time in frames at ``motion.fps``; spatial noise levels
are given in centimetres. A parameter counted in frames may be given in seconds instead
(``block:2s``, ``gaps:0.0003,2s,4s``): a :class:`Seconds` value, turned into frames at
the frame rate of the take it corrupts (:meth:`Work.frames`), so that a span lasts as
long at 30 as at 120 fps. Probabilities stay per frame: ``gaps:P`` starts a quarter as
many gaps a second at 30 fps as at 120 (``gaps:4P`` starts as many).
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass, fields
from functools import cached_property
from typing import Any, ClassVar

import numpy as np

from ..core.channels import unwrap_deg
from ..core.motion import Motion, angle_columns
from .errors import CorruptionApplyError, CorruptionSpecError

#: A channel whose clean std (degrees) is at most this counts as constant.
ZERO_STD_DEG = 1e-9

_REQUIRED = object()

# kind -> (description used in messages, integer?, lower bound, upper bound)
_KINDS: dict[str, tuple[str, bool, float, float]] = {
    # (bounded far above any use: 1e308 overflowed into NaN, or left the IK of spatial noise turning for ever)
    "scale": ("a number from 0 to 1,000", False, 0.0, 1e3),
    "cm": ("a length in cm from 0 to 100,000", False, 0.0, 1e5),
    "prob": ("a probability in [0, 1]", False, 0.0, 1.0),
    "mean-frames": ("a number of frames >= 1", False, 1.0, math.inf),
    "count": ("a whole number >= 0", True, 0.0, math.inf),
    "frames": ("a whole number of frames >= 1", True, 1.0, math.inf),
    "frame-count": ("a whole number of frames >= 0", True, 0.0, math.inf),
    "frame": ("a frame index (whole number >= 0)", True, 0.0, math.inf),
}


@dataclass(frozen=True)
class Param:
    """One positional parameter of a model: its name in help texts, its kind (which sets
    the type and the valid range), what it means (``help``, in the messages that refuse a
    value) and its default (none: required; ``None`` means "drawn at random")."""

    name: str
    kind: str
    help: str
    default: Any = _REQUIRED

    @property
    def required(self) -> bool:
        return self.default is _REQUIRED

    @property
    def named(self) -> str:
        """The parameter as a message names it: ``MEAN (mean gap length, frames)`` (a
        default the help states is left out: the message is about the value given)."""
        return f"{self.name} ({self.help.split(' (default')[0]})"


#: the kinds of parameter counted in frames, which also take seconds
FRAME_KINDS = frozenset({"mean-frames", "frames", "frame-count", "frame"})


def format_number(x: float | int) -> str:
    """Shortest text that reads back to the same number: ``0.5``, ``12``, ``1e-05``."""
    x = float(x)
    if x.is_integer() and abs(x) < 1e15:
        return str(int(x))
    return repr(x)


@dataclass(frozen=True)
class Seconds:
    """A parameter counted in frames, given in seconds (``2s`` in a spec): ``value`` s."""

    value: float

    def __str__(self) -> str:
        return format_number(self.value) + "s"


def random_stream(seed: int, position: int, name: str) -> np.random.Generator:
    """The random stream of the model at ``position`` (0-based) in a chain applied with
    ``seed``: independent of every other model's stream."""
    return np.random.default_rng([int(seed), int(position), zlib.crc32(name.encode("utf-8"))])


class Work:
    """The state a chain of models edits in place: the channel matrix (F, 3 + 3J + 3T) of
    the corrupted motion and the observed mask (F, J). Values under the mask are kept (not
    NaN) until the end so later models can still use them; statistics come from the
    clean clip."""

    def __init__(self, clean: Motion) -> None:
        self.clean = clean
        self.channels = clean.channels.copy()
        self.observed = np.ones((clean.n_frames, clean.skeleton.n_joints), dtype=bool)

    @property
    def n_frames(self) -> int:
        return self.clean.n_frames

    def frames(self, model: "Model", name: str) -> Any:
        """The value of ``model``'s parameter ``name`` in frames: as given, or its
        :class:`Seconds` times the take's fps, rounded to whole frames for a whole-number
        kind. Raises CorruptionApplyError where that leaves less than the kind's least
        value (a span shorter than one frame)."""
        value = getattr(model, name)
        if not isinstance(value, Seconds):
            return value
        p = next(p for p, f in zip(model.params, fields(model)) if f.name == name)  # type: ignore[arg-type]
        _, integer, lo, _ = _KINDS[p.kind]
        frames = value.value * self.clean.fps
        frames = int(math.floor(frames + 0.5)) if integer else frames
        least = lo if p.kind == "frame" or value.value == 0 else max(lo, 1.0)  # a span of some seconds: a frame
        if frames < least:
            raise CorruptionApplyError(
                f"{model}: {p.name} = {value} is {format_number(frames)} frames at "
                f"{self.clean.fps:g} fps; it must be at least {format_number(least)}"
            )
        return frames

    @property
    def skeleton(self):
        return self.clean.skeleton

    @cached_property
    def angle_cols(self) -> np.ndarray:
        """Columns of the joint-angle channels (every joint but those of the root chain)."""
        return angle_columns(self.skeleton)

    @cached_property
    def gap_joints(self) -> np.ndarray:
        """Indices of the joints outside the root chain (``skeleton.root_chain``, whose
        motion is the trajectory): the joints a missing-data model hides one by one."""
        return np.setdiff1d(np.arange(self.skeleton.n_joints), self.skeleton.root_chain)

    @cached_property
    def angle_std(self) -> np.ndarray:
        """Std (degrees) of each joint-angle channel of the clean clip, on angles
        unwrapped robustly (:func:`~workbench.core.channels.unwrap_deg`): a capture
        glitch that flips a joint by half a turn and back must not leave a whole turn in
        the statistics (test run 35_26's RightFingerBase: 179.5 degrees with ``np.unwrap``
        against 18.9), which would scale its noise tenfold; exactly 0 for (numerically)
        constant channels."""
        X = unwrap_deg(self.clean.channels[:, self.angle_cols], robust=True)
        std = X.std(axis=0)
        std[std <= ZERO_STD_DEG] = 0.0
        return std

    def motion(self) -> Motion:
        """The current values as a Motion (no NaN)."""
        return self.clean.with_channels(self.channels)


class Model:
    """Base of the corruption models. Subclasses are frozen dataclasses whose fields are
    the parameters, in the order of ``params``; they set ``name``, ``description`` (one
    line) and ``params`` and implement :meth:`corrupt`."""

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    params: ClassVar[tuple[Param, ...]] = ()

    # -- construction and validation -------------------------------------------------
    def __post_init__(self) -> None:
        for p, f in zip(self.params, fields(self)):  # type: ignore[arg-type]
            value = getattr(self, f.name)
            object.__setattr__(self, f.name, self._check(p, value))
        self.validate()

    def validate(self) -> None:
        """Checks between parameters (raise CorruptionSpecError)."""

    @classmethod
    def _check(cls, p: Param, value: Any) -> Any:
        if value is None and not p.required and p.default is None:
            return None
        what, integer, lo, hi = _KINDS[p.kind]
        if isinstance(value, Seconds):
            if p.kind not in FRAME_KINDS:
                raise CorruptionSpecError(f"{cls.name}: {p.named} must be {what}, not a time in seconds ({value})")
            least = 0.0 if lo == 0 else math.nextafter(0.0, 1.0)  # a span must last; a frame index may be 0
            if not (math.isfinite(value.value) and least <= value.value):
                raise CorruptionSpecError(
                    f"{cls.name}: {p.name} must be {'>= 0' if lo == 0 else '> 0'} seconds, got {value}"
                )
            return Seconds(value.value + 0.0)
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
            raise CorruptionSpecError(f"{cls.name}: {p.named} must be {what}, got {value!r}")
        x = float(value)
        if not math.isfinite(x):
            raise CorruptionSpecError(f"{cls.name}: {p.named} must be {what}, got {format_number(x)}")
        if integer and not x.is_integer():
            raise CorruptionSpecError(f"{cls.name}: {p.named} must be {what}, got {format_number(x)}")
        if not lo <= x <= hi:
            raise CorruptionSpecError(f"{cls.name}: {p.named} must be {what}, got {format_number(x)}")
        return int(x) if integer else x + 0.0  # + 0.0 turns -0.0 into 0.0

    @classmethod
    def signature(cls) -> str:
        """``name:A,B[,C]`` for help texts."""
        req = [p.name for p in cls.params if p.required]
        opt = [p.name for p in cls.params if not p.required]
        return f"{cls.name}:{','.join(req)}" + "".join(f"[,{name}" for name in opt) + "]" * len(opt)

    @classmethod
    def from_args(cls, args: list[str]) -> "Model":
        """Build from the comma-separated parameter texts of a spec."""
        n_req = sum(p.required for p in cls.params)
        n_all = len(cls.params)
        if not n_req <= len(args) <= n_all:
            names = ", ".join(p.name if p.required else f"{p.name} (optional)" for p in cls.params)
            want = f"{n_req}" if n_req == n_all else f"{n_req} to {n_all}"
            raise CorruptionSpecError(
                f"{cls.name}: takes {want} parameter{'s' if n_all > 1 else ''} ({names}), got {len(args)}; "
                f"usage: {cls.signature()}"
            )
        values: list[Any] = []
        for p, text in zip(cls.params, args):
            text = text.strip()
            seconds = p.kind in FRAME_KINDS and text.lower().endswith("s")
            try:
                number = float(text[:-1] if seconds else text)
            except ValueError:
                what = _KINDS[p.kind][0] + (", or seconds (as in 2s)" if p.kind in FRAME_KINDS else "")
                raise CorruptionSpecError(
                    f"{cls.name}: {p.named} must be {what}, got {text!r}; usage: {cls.signature()}"
                ) from None
            values.append(Seconds(number) if seconds else number)
        return cls(*values)  # type: ignore[call-arg]

    # -- text ----------------------------------------------------------------------------
    def values(self) -> tuple[Any, ...]:
        return tuple(getattr(self, f.name) for f in fields(self))  # type: ignore[arg-type]

    def __str__(self) -> str:
        vals = list(self.values())
        while vals and not self.params[len(vals) - 1].required and vals[-1] == self.params[len(vals) - 1].default:
            vals.pop()
        return f"{self.name}:{','.join(str(v) if isinstance(v, Seconds) else format_number(v) for v in vals)}"

    # -- application ---------------------------------------------------------------------
    def corrupt(self, work: Work, rng: np.random.Generator) -> None:
        """Edit ``work`` in place, drawing only from ``rng``."""
        raise NotImplementedError
