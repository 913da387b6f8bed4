"""Skeleton: joint hierarchy, rest offsets and the channel layout of a BVH file.

Units: offsets are in the file's own length unit; ``unit_cm`` says how many centimetres
one unit is (CMU cgspeed BVH: 1 unit = 5.64 cm), which the metrics use to report cm.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

ROTATION_CHANNELS = ("Xrotation", "Yrotation", "Zrotation")
POSITION_CHANNELS = ("Xposition", "Yposition", "Zposition")

# Rest-pose height (in file units) -> unit size in cm, for files that do not say.
# A standing adult is 150-200 cm tall; the table names the unit that makes it so.
_KNOWN_UNITS_CM = ((5.64, "CMU cgspeed units"), (1.0, "cm"), (2.54, "inches"), (100.0, "m"))


@dataclass(frozen=True, eq=False)
class Skeleton:
    """An immutable joint hierarchy.

    names: J joint names; parents: J parent indices (parents[j] < j, root -1);
    offsets: (J, 3) rest offsets from the parent; channels: per joint the channel names as
    written in the file (root: 3 positions + 3 rotations; others: 3 rotations);
    end_sites: (parent joint index, offset (3,)) for each End Site; unit_cm: cm per unit.
    """

    names: tuple[str, ...]
    parents: tuple[int, ...]
    offsets: np.ndarray
    channels: tuple[tuple[str, ...], ...]
    end_sites: tuple[tuple[int, tuple[float, float, float]], ...] = ()
    unit_cm: float = field(default=0.0)

    def __post_init__(self) -> None:
        J = len(self.names)
        offsets = np.array(self.offsets, dtype=float).reshape(J, 3)
        offsets.setflags(write=False)
        object.__setattr__(self, "offsets", offsets)
        if len(self.parents) != J or len(self.channels) != J:
            raise ValueError("names, parents and channels must have one entry per joint")
        if J == 0 or self.parents[0] != -1:
            raise ValueError("the first joint must be the root (parent -1)")
        for j, p in enumerate(self.parents[1:], start=1):
            if not 0 <= p < j:
                raise ValueError(f"joint {self.names[j]!r}: parent index {p} must precede it")
        if len(set(self.names)) != J:
            raise ValueError("joint names must be unique")
        for j, ch in enumerate(self.channels):
            self._validate_channels(self.names[j], j, ch)
        if self.unit_cm <= 0:
            object.__setattr__(self, "unit_cm", guess_unit_cm(self))

    @staticmethod
    def _validate_channels(name: str, index: int, channels: tuple[str, ...]) -> None:
        """Raise ValueError unless a joint's channels are 0 or 3 distinct rotations, plus
        all three positions on the root (index 0) only."""
        rot = [c for c in channels if c in ROTATION_CHANNELS]
        pos = [c for c in channels if c in POSITION_CHANNELS]
        unknown = [c for c in channels if c not in ROTATION_CHANNELS + POSITION_CHANNELS]
        if unknown:
            raise ValueError(f"joint {name!r}: unknown channel name(s) {unknown}")
        if len(rot) not in (0, 3) or len(set(rot)) != len(rot):
            raise ValueError(f"joint {name!r}: needs 0 or 3 distinct rotation channels, has {rot}")
        if pos and (index != 0 or sorted(pos) != sorted(POSITION_CHANNELS)):
            raise ValueError(f"joint {name!r}: position channels are supported on the root only, all three of them")

    # -- derived layout -------------------------------------------------------------
    @property
    def n_joints(self) -> int:
        return len(self.names)

    def rotation_order(self, j: int) -> str:
        """Euler order of joint j, e.g. ``"ZYX"`` (``"ZYX"`` for a joint with no rotation)."""
        rot = [c[0] for c in self.channels[j] if c in ROTATION_CHANNELS]
        return "".join(rot) if rot else "ZYX"

    # The layout below is built once per skeleton: FK, IK and every clean look it up.
    @cached_property
    def rotation_orders(self) -> tuple[str, ...]:
        return tuple(self.rotation_order(j) for j in range(self.n_joints))

    @cached_property
    def has_rotation(self) -> np.ndarray:
        """(J,) bool, read-only: the joint has rotation channels in the file."""
        out = np.array([any(c in ROTATION_CHANNELS for c in ch) for ch in self.channels])
        out.setflags(write=False)
        return out

    @cached_property
    def children(self) -> tuple[tuple[int, ...], ...]:
        """Each joint's child indices."""
        kids: list[list[int]] = [[] for _ in self.names]
        for j, p in enumerate(self.parents):
            if p >= 0:
                kids[p].append(j)
        return tuple(tuple(k) for k in kids)

    @cached_property
    def aimed_descendants(self) -> tuple[tuple[tuple[int, tuple[int, ...]], ...], ...]:
        """Per joint j, the descendants whose positions j's rotation fixes, each with the
        zero-offset joints on the way from j to it (outermost first). A child with a zero
        offset sits on j itself and says nothing about j's rotation: the walk looks
        through it to its own children."""
        out = []
        for j in range(self.n_joints):
            aimed: list[tuple[int, tuple[int, ...]]] = []
            stack = [(c, ()) for c in self.children[j]]
            while stack:
                c, via = stack.pop()
                if np.linalg.norm(self.offsets[c]) > 1e-9:
                    aimed.append((c, via))
                else:
                    stack.extend((g, via + (c,)) for g in self.children[c])
            out.append(tuple(aimed))
        return tuple(out)

    def index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"no joint named {name!r} in this skeleton") from None

    @property
    def bones(self) -> tuple[tuple[int, int], ...]:
        """(parent, child) pairs for every joint but the root."""
        return tuple((p, j) for j, p in enumerate(self.parents) if p >= 0)

    def signature(self) -> str:
        """A short string naming the topology and channel layout (not the bone lengths):
        two skeletons with equal signatures can share a trained engine."""
        parts = [f"{n}<{p}>{''.join(c[0] + c[1] for c in ch)}" for n, p, ch in zip(self.names, self.parents, self.channels)]
        return ";".join(parts)

    def same_layout(self, other: "Skeleton") -> bool:
        return self.signature() == other.signature()

    def allclose(self, other: "Skeleton", atol: float = 1e-6) -> bool:
        return self.same_layout(other) and np.allclose(self.offsets, other.offsets, atol=atol)

    def with_offsets(self, offsets: np.ndarray) -> "Skeleton":
        return Skeleton(self.names, self.parents, offsets, self.channels, self.end_sites, self.unit_cm)

    def rest_height(self) -> float:
        """Vertical extent of the rest pose (file units), end sites included; Y is up."""
        pos = np.zeros((self.n_joints, 3))
        for j, p in enumerate(self.parents):
            pos[j] = self.offsets[j] + (pos[p] if p >= 0 else 0.0)
        ys = list(pos[:, 1]) + [pos[p, 1] + off[1] for p, off in self.end_sites]
        return float(max(ys) - min(ys))


def guess_unit_cm(skeleton: Skeleton) -> float:
    """Guess the unit from the rest-pose height: the unit that makes it 120-220 cm.

    Falls back to 1.0 (centimetres) when none fits.
    """
    height = skeleton.rest_height()
    for unit_cm, _name in _KNOWN_UNITS_CM:
        if 120.0 <= height * unit_cm <= 220.0:
            return unit_cm
    return 1.0
