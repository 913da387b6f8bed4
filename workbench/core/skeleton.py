"""Skeleton: joint hierarchy, rest offsets and the channel layout of a BVH file.

Units: offsets are in the file's own length unit; ``unit_cm`` says how many centimetres
one unit is (CMU cgspeed BVH: 1 unit = 5.64 cm), which the metrics use to report cm.

Translations. A joint's position channels, on any joint, replace its OFFSET as its local
translation, as Blender's importer reads them. The root's are the motion's root
positions, so a root with position channels has a zero offset here (its OFFSET line is
kept in ``file_offsets``). A non-root joint whose position channels hold one value
throughout the take (MotionBuilder exports them on every joint) has that value folded
into ``offsets``; one whose translation varies (a trajectory carrier under a reference
root, a stretchy rig) is listed in ``translated`` and animated by
``Motion.translations``. The file's OFFSET lines stay in ``file_offsets``, for writing
the file back as it was.
"""

from __future__ import annotations

import dataclasses
import numbers
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from ..errors import NameNotFoundError

ROTATION_CHANNELS = ("Xrotation", "Yrotation", "Zrotation")
POSITION_CHANNELS = ("Xposition", "Yposition", "Zposition")

#: the length units of motion files, by name, in cm (``cmu``: the CMU cgspeed conversion's);
#: the heights of 120-220 cm in them do not overlap, so :func:`fitting_unit_cm` finds one at most
UNITS_CM = {"mm": 0.1, "cm": 1.0, "m": 100.0, "in": 2.54, "cmu": 5.64}


@dataclass(frozen=True, eq=False)
class Skeleton:
    """An immutable joint hierarchy.

    names: J joint names; parents: J parent indices (parents[j] < j, root -1);
    offsets: (J, 3) each joint's local translation from its parent where no channel
    animates it (see the module docstring; zero for a root with position channels), and
    for a translated joint its OFFSET line, which FK ignores and the rest pose uses;
    channels: per joint the channel names as written in the file, in the file's order
    (0 or 3 rotations and 0 or 3 positions, on any joint); end_sites: (parent joint index,
    offset (3,)) for each End Site; unit_cm: cm per unit; translated: the non-root joints,
    ascending, whose translation ``Motion.translations`` animates (they have position
    channels); file_offsets: (J, 3) the OFFSET lines of the file (default ``offsets``;
    only the rows of joints with position channels may differ, as FK ignores those lines);
    text_encoding: how the file's joint names were encoded, and how a take of this
    skeleton is written (``"utf-8"``; ``"latin-1"`` for a file that is not UTF-8, whose
    names' bytes are then written back as they were).
    """

    names: tuple[str, ...]
    parents: tuple[int, ...]
    offsets: np.ndarray
    channels: tuple[tuple[str, ...], ...]
    end_sites: tuple[tuple[int, tuple[float, float, float]], ...] = ()
    unit_cm: float = field(default=0.0)
    translated: tuple[int, ...] = ()
    file_offsets: np.ndarray | None = None
    text_encoding: str = "utf-8"

    def __post_init__(self) -> None:
        J = len(self.names)
        if len(self.parents) != J or len(self.channels) != J:
            raise ValueError("names, parents and channels must have one entry per joint")
        offsets = np.array(self.offsets, dtype=float).reshape(J, 3)
        positioned = self.has_position
        written = offsets if self.file_offsets is None else np.array(self.file_offsets, dtype=float).reshape(J, 3)
        written = np.where(positioned[:, None], written, offsets)  # only position channels replace OFFSET
        for a in (offsets, written):
            a.setflags(write=False)
        object.__setattr__(self, "offsets", offsets)
        object.__setattr__(self, "file_offsets", written)
        object.__setattr__(self, "translated", tuple(int(j) for j in self.translated))
        if J == 0 or self.parents[0] != -1:
            raise ValueError("the first joint must be the root (parent -1)")
        for j, p in enumerate(self.parents[1:], start=1):
            if not 0 <= p < j:
                raise ValueError(f"joint {self.names[j]!r}: parent index {p} must precede it")
        if len(set(self.names)) != J:
            raise ValueError("joint names must be unique")
        for j, ch in enumerate(self.channels):
            self._validate_channels(self.names[j], ch)
        if J and positioned[0] and np.any(offsets[0] != 0):
            raise ValueError(
                f"root {self.names[0]!r} has position channels, so its offset must be zero "
                "(its OFFSET line goes in file_offsets)"
            )
        if list(self.translated) != sorted(set(self.translated)) or not all(
            0 < j < J and positioned[j] for j in self.translated
        ):
            raise ValueError(
                f"translated joints must be ascending non-root joints with position channels, got {self.translated}"
            )
        if self.unit_cm <= 0:
            object.__setattr__(self, "unit_cm", guess_unit_cm(self))

    @staticmethod
    def _validate_channels(name: str, channels: tuple[str, ...]) -> None:
        """Raise ValueError unless a joint's channels are 0 or 3 distinct rotations and 0
        or 3 distinct positions, in any order."""
        rot = [c for c in channels if c in ROTATION_CHANNELS]
        pos = [c for c in channels if c in POSITION_CHANNELS]
        unknown = [c for c in channels if c not in ROTATION_CHANNELS + POSITION_CHANNELS]
        if unknown:
            raise ValueError(f"joint {name!r}: unknown channel name(s) {unknown}")
        if len(rot) not in (0, 3) or len(set(rot)) != len(rot):
            raise ValueError(f"joint {name!r}: needs 0 or 3 distinct rotation channels, has {rot}")
        if len(pos) not in (0, 3) or len(set(pos)) != len(pos):
            raise ValueError(f"joint {name!r}: needs 0 or 3 distinct position channels, has {pos}")

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
    def has_position(self) -> np.ndarray:
        """(J,) bool, read-only: the joint has position channels in the file."""
        out = np.array([any(c in POSITION_CHANNELS for c in ch) for ch in self.channels])
        out.setflags(write=False)
        return out

    @cached_property
    def root_chain(self) -> tuple[int, ...]:
        """The root and the translated joints it carries one by one: each the only child of
        the one before, down to the first that branches or is not translated. ``(0,)`` for
        CMU's Hips; ``(0, 1)`` for a MotionBuilder export whose reference node
        ``joint_Root`` carries the moving ``Hips``. These joints place and turn the whole
        body: their motion is its trajectory, which the papers treat as clean and the
        root-aligned scores leave out."""
        chain = [0]
        while len(self.children[chain[-1]]) == 1 and self.children[chain[-1]][0] in self.translated:
            chain.append(self.children[chain[-1]][0])
        return tuple(chain)

    @property
    def body_root(self) -> int:
        """The last joint of :attr:`root_chain` (the pelvis): where the root-aligned scores
        align the body."""
        return self.root_chain[-1]

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
        through it to its own children. A translated child moves on its own and says
        nothing either, nor do the joints below it."""
        out = []
        for j in range(self.n_joints):
            aimed: list[tuple[int, tuple[int, ...]]] = []
            stack = [(c, ()) for c in self.children[j]]
            while stack:
                c, via = stack.pop()
                if c in self.translated:
                    continue
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
            raise NameNotFoundError(f"no joint named {name!r} in this skeleton") from None

    @property
    def bones(self) -> tuple[tuple[int, int], ...]:
        """(parent, child) pairs for every joint but the root."""
        return tuple((p, j) for j, p in enumerate(self.parents) if p >= 0)

    def signature(self) -> str:
        """A short string naming the topology and channel layout (not the bone lengths),
        and the translated joints, which widen the channel matrix: two skeletons with
        equal signatures can share a trained engine."""
        parts = [
            f"{n}<{p}>{''.join(c[0] + c[1] for c in ch)}" for n, p, ch in zip(self.names, self.parents, self.channels)
        ]
        if self.translated:
            parts.append("translated:" + ",".join(self.names[j] for j in self.translated))
        return ";".join(parts)

    def same_layout(self, other: "Skeleton") -> bool:
        return self.signature() == other.signature()

    def allclose(self, other: "Skeleton", atol: float = 1e-6) -> bool:
        return self.same_layout(other) and np.allclose(self.offsets, other.offsets, atol=atol)

    def replace(self, **changes) -> "Skeleton":
        """A copy with the given fields changed (validated as a new Skeleton)."""
        return dataclasses.replace(self, **changes)

    def rest_positions(self) -> np.ndarray:
        """(J, 3) the joints' rest-pose positions from the offsets (file units)."""
        pos = np.zeros((self.n_joints, 3))
        for j, p in enumerate(self.parents):
            pos[j] = self.offsets[j] + (pos[p] if p >= 0 else 0.0)
        return pos

    def rest_extents(self) -> np.ndarray:
        """(3,) the rest pose's extent along X, Y and Z (file units), end sites included."""
        pos = self.rest_positions()
        points = (
            np.concatenate([pos, [pos[p] + np.asarray(off) for p, off in self.end_sites]]) if self.end_sites else pos
        )
        return points.max(axis=0) - points.min(axis=0)

    def rest_height(self) -> float:
        """Vertical extent of the rest pose (file units), end sites included; Y is up."""
        return float(self.rest_extents()[1])


def given_unit_cm(unit_cm: object) -> float | None:
    """``unit_cm`` as a reader takes it: None (guess the unit), or a finite number above 0
    (the unit's size in cm); ValueError for anything else (0, a negative, NaN, a name)."""
    if unit_cm is None:
        return None
    if isinstance(unit_cm, bool) or not isinstance(unit_cm, numbers.Real) or not 0 < unit_cm < float("inf"):
        raise ValueError(
            f"unit_cm is the length unit's size in cm, a number above 0 (UNITS_CM has the usual ones), or None "
            f"to guess it, not {unit_cm!r}"
        )
    return float(unit_cm)


def guess_unit_cm(skeleton: Skeleton) -> float:
    """Guess the unit from the rest-pose height: :func:`fitting_unit_cm`, else 1.0
    (centimetres)."""
    fitting = fitting_unit_cm(skeleton)
    return 1.0 if fitting is None else fitting


def fitting_unit_cm(skeleton: Skeleton) -> float | None:
    """The known unit that makes the rest pose 120-220 cm tall, the height measured along
    Y, else along the axis the rest pose is longest on (a rest pose standing on Z, as some
    exporters write it; :mod:`workbench.core.upright`); None when none does."""
    extents = skeleton.rest_extents()
    for height in (extents[1], extents.max()):
        for unit_cm in UNITS_CM.values():
            if 120.0 <= height * unit_cm <= 220.0:
                return unit_cm
    return None
