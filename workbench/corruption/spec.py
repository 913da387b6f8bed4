"""Corruption specs: parse ``"angular:0.5+gaps:0.01"``, print it back canonically, and
apply it to a clean Motion reproducibly.

Units: as in the models (angles in degrees, positions in file units, spatial levels in
cm, lengths in frames, or in seconds written ``2s``). Text grammar: models joined by ``+``, applied left to right;
each ``name:p1,p2,...`` with positional numeric parameters, optional trailing ones
defaulted; ``""`` or ``"none"`` is no corruption. Model names are case-insensitive.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.motion import Case, Motion, Observation
from .base import Model, Work, random_stream
from .errors import CorruptionApplyError, CorruptionSpecError
from .gaps import Block, Drop, Gaps, Joints
from .noise import Angular, Bias, Jumps, Outliers, Sine, Uniform
from .spatial import Spatial, SpatialEnds

#: name -> model class, in help-text order. Each class has ``description`` (one line),
#: ``params`` (name, kind, help, default) and ``signature()`` (e.g. ``gaps:P[,MEAN[,MAX]]``).
MODELS: dict[str, type[Model]] = {
    cls.name: cls
    for cls in (Angular, Uniform, Bias, Sine, Spatial, SpatialEnds, Outliers, Jumps, Gaps, Block, Joints, Drop)
}

NONE = "none"


def models_help() -> str:
    """One line per model: its usage and description."""
    width = max(len(cls.signature()) for cls in MODELS.values())
    lines = [f"{cls.signature():<{width}}  {cls.description}" for cls in MODELS.values()]
    lines.append(f"{'A+B':<{width}}  apply A, then B (e.g. angular:0.5+gaps:0.01); '' or 'none': no corruption")
    lines.append(f"{'':<{width}}  lengths and frame numbers also take seconds: block:2s, gaps:0.0003,2s,4s")
    return "\n".join(lines)


def _valid_models() -> str:
    return ", ".join(cls.signature() for cls in MODELS.values())


@dataclass(frozen=True)
class Corruption:
    """A chain of corruption models applied left to right. ``str()`` is the canonical
    spec text (``"none"`` for the empty chain); ``parse_corruption(str(c)) == c``."""

    models: tuple[Model, ...] = ()

    def __str__(self) -> str:
        return "+".join(str(m) for m in self.models) if self.models else NONE

    def __bool__(self) -> bool:
        return bool(self.models)

    def __add__(self, other: "Corruption | Model | str") -> "Corruption":
        if isinstance(other, str):
            other = parse_corruption(other)
        if isinstance(other, Model):
            other = Corruption((other,))
        if not isinstance(other, Corruption):
            return NotImplemented
        return Corruption(self.models + other.models)

    def apply(self, motion: Motion, seed: int = 0) -> Observation:
        """The corrupted motion and its observed mask. Model i draws from its own stream
        ``random_stream(seed, i, name)``; the same seed gives identical output. The input
        is not modified."""
        seed = _check_seed(seed)
        _check_finite(motion)
        work = Work(motion)
        for i, model in enumerate(self.models):
            model.corrupt(work, random_stream(seed, i, model.name))
        return Observation(motion.with_channels(work.channels), work.observed)


def _check_seed(seed: int) -> int:
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise CorruptionApplyError(f"seed must be a whole number >= 0, got {seed!r}")
    return int(seed)


def _check_finite(motion: Motion) -> None:
    bad_root = ~np.isfinite(motion.root_positions).all(axis=1)
    bad_ang = ~np.isfinite(motion.angles_deg).all(axis=(1, 2))
    bad = np.flatnonzero(bad_root | bad_ang)
    if bad.size:
        raise CorruptionApplyError(
            f"the clean motion {motion.name!r} has non-finite values (NaN or inf) in {bad.size} frame(s), "
            f"first at frame {bad[0]}; corruption needs a complete clean clip"
        )


def parse_corruption(text: "str | Corruption") -> Corruption:
    """Parse a spec such as ``"angular:0.5+gaps:0.01,12"``. Raises CorruptionSpecError
    (a ValueError) naming the problem and listing the valid models."""
    if isinstance(text, Corruption):
        return text
    if not isinstance(text, str):
        raise CorruptionSpecError(f"a corruption spec must be text, got {type(text).__name__}")
    stripped = text.strip()
    if stripped == "" or stripped.lower() == NONE:
        return Corruption()
    models = []
    for part in stripped.split("+"):
        part = part.strip()
        if not part:
            raise CorruptionSpecError(f"empty model in corruption spec {text!r} (two '+' in a row, or one at an end)")
        name, colon, args = part.partition(":")
        key = name.strip().lower()
        if key == NONE:
            raise CorruptionSpecError(f"'none' cannot be combined with other models in {text!r}")
        cls = MODELS.get(key)
        if cls is None:
            raise CorruptionSpecError(
                f"unknown corruption model {name.strip()!r} in {text!r}; valid models: {_valid_models()}"
            )
        arg_list = args.split(",") if colon and args.strip() else []
        try:
            models.append(cls.from_args(arg_list))
        except CorruptionSpecError as err:
            raise CorruptionSpecError(f"{err} (in {text!r})") from None
    return Corruption(tuple(models))


def make_case(motion: Motion, corruption: "str | Corruption", seed: int = 0) -> Case:
    """A benchmark case: the clean motion, its corruption with ``seed``, the canonical
    spec text and the seed."""
    spec = parse_corruption(corruption)
    return Case(truth=motion, observation=spec.apply(motion, seed), corruption=str(spec), seed=int(seed))
