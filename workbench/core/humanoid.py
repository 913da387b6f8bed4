"""The canonical humanoid, and where a skeleton's joints sit on it.

A skeleton-agnostic engine models one body whatever exported the take: the 21 joints of
:data:`CANONICAL_JOINTS` (hips, spine, chest, neck, head, and per side shoulder, upper
arm, forearm, hand, thigh, shin, foot, toes), each a joint of the take's own skeleton
whose position it takes. :func:`map_humanoid` finds them from the tree and the joint
names, so that one rule serves CMU, CMU Daz, Bandai, Mixamo, HumanIK / MotionBuilder,
SMPL and LAFAN1 exports:

- **Hips** is the body root (:attr:`~workbench.core.skeleton.Skeleton.body_root`).
- **Head** is the shallowest joint named *head*; each **hand** the shallowest joint of its
  side named *hand* or *wrist* (finger joints excluded); each **foot** the shallowest of its
  side named *foot* or *ankle* (SMPL's ``L_Foot`` is deeper than ``L_Ankle``: its toes).
- **Chest** is where the arms and the head part: the lowest common ancestor of both hands
  and the head. **Spine** is the first joint between hips and chest that does not sit on
  the hips (CMU's ``LowerBack`` does; ``Spine`` is taken); **neck** the first between
  chest and head that does not sit on the chest.
- Up each limb from its end: **forearm** and **upper arm** are the next ancestors of the
  hand, **shoulder** the one after if it is still below the chest (so Mixamo's
  ``LeftShoulder`` is a clavicle and SMPL's ``L_Shoulder`` an upper arm, as each intends);
  **shin** and **thigh** are the next ancestors of the foot; **toes** the foot's child
  (one named *toe* where it has several). Joints named *roll*, *twist* or *bend* (HumanIK's
  ``LeftForeArmRoll``) are passed over on the way.
- A joint's side comes from its name (``Left``/``Right`` anywhere, ``L``/``R`` or
  ``l``/``r`` before a capital or a separator, ``_L``/``_R`` at the end); where the names
  say nothing, from the rest pose (left is +X of a body facing +Z, as BVH has it).

A user can pin or drop any of them (``overrides``, the ``--mapping`` file). The result is
checked: every joint of :data:`ESSENTIAL_JOINTS` mapped, each canonical joint below its
canonical parent's joint in the take's tree, no take joint used twice; otherwise
:class:`HumanoidError` names what is missing or wrong. Spine, neck, shoulders and toes
may be absent (CMU Daz has no toes); an engine treats an absent joint as never observed.

Body size (:meth:`HumanoidMapping.body_size_cm`): the rest-pose length of the canonical
chain from the head down to the feet: hips-spine-chest-neck-head plus the mean of
thigh-shin-foot over both sides, straight-line distances between the mapped joints, cm.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from .skeleton import Skeleton

_SIDES = ("left", "right")
_SPINE = ("hips", "spine", "chest", "neck", "head")
_ARM = ("shoulder", "upper_arm", "forearm", "hand")
_LEG = ("thigh", "shin", "foot", "toes")


def _chains() -> dict[str, str | None]:
    """Each canonical joint's canonical parent, parents first: the spine, the arms (from
    the chest), the legs (from the hips)."""
    out: dict[str, str | None] = {"hips": None, **dict(zip(_SPINE[1:], _SPINE))}
    for limb, base in ((_ARM, "chest"), (_LEG, "hips")):
        for side in _SIDES:
            names = [f"{side}_{part}" for part in limb]
            out.update(zip(names, [base, *names]))
    return out


#: each canonical joint's canonical parent (None for the hips)
CANONICAL_PARENTS: dict[str, str | None] = _chains()
#: the canonical joints, parents before children
CANONICAL_JOINTS: tuple[str, ...] = tuple(CANONICAL_PARENTS)
#: the joints a take must have for a skeleton-agnostic engine to model it
ESSENTIAL_JOINTS: tuple[str, ...] = ("hips", "chest", "head") + tuple(
    f"{s}_{part}" for s in _SIDES for part in ("upper_arm", "forearm", "hand", "thigh", "shin", "foot")
)

#: the canonical joints found by their names; the others follow from where these are
_NAMED_JOINTS = ("head",) + tuple(f"{s}_{part}" for s in _SIDES for part in ("hand", "foot"))
#: name prefixes of exporters, stripped before reading a name (``mixamorig:Hips``, ``Bip01 L Thigh``)
_PREFIX = re.compile(r"^(?:.*:|mixamorig\d*_|bip0?1[ _]|m_avg_|joint_|jnt_|def[-_])", re.IGNORECASE)
_FINGER = re.compile(r"index|thumb|middle|mid\d|ring|pinky|little|finger|carpal", re.IGNORECASE)
_PASS_OVER = re.compile(r"roll|twist|bend", re.IGNORECASE)
#: rest positions closer than this (file units, relative to the body's size) are one place
_SAME_PLACE = 1e-6


class HumanoidError(ValueError):
    """A skeleton that cannot be mapped onto the canonical humanoid, or a mapping file
    that does not fit it; the message names the joints and what to do."""


def _stem(name: str) -> str:
    """The name without an exporter's prefix."""
    return _PREFIX.sub("", name) or name


def joint_side(name: str) -> str | None:
    """``"left"``, ``"right"`` or None: the side a joint name says (see the module docstring)."""
    stem = _stem(name)
    low = stem.lower()
    for side in _SIDES:
        if side in low:
            return side
    for side, letter in (("left", "l"), ("right", "r")):
        if (
            re.match(rf"^[{letter}{letter.upper()}](?=[A-Z0-9])", stem)  # lThigh, LHipJoint, RThumb
            or re.match(rf"^{letter}[_. ]", low)  # L_Hip, l.arm
            or re.search(rf"[_. ]{letter}(?:$|[_. ])", low)  # Hand_L, L Thigh after "Bip01 "
        ):
            return side
    return None


@dataclass(frozen=True)
class HumanoidMapping:
    """Where each canonical joint sits on one skeleton.

    joints: per canonical joint (in :data:`CANONICAL_JOINTS` order) the index of the
    take's joint whose position it takes, or -1 where the take has none; pinned: the
    canonical joints set by the user rather than found."""

    skeleton: Skeleton
    joints: tuple[int, ...]
    pinned: frozenset[str] = frozenset()

    @property
    def mapped(self) -> np.ndarray:
        """(21,) bool: the canonical joint has a joint of the take."""
        return np.array(self.joints) >= 0

    def joint(self, canonical: str) -> int:
        """The take's joint index of a canonical joint (-1 where absent)."""
        return self.joints[CANONICAL_JOINTS.index(canonical)]

    def lacking(self) -> list[str]:
        """The canonical joints the take has no joint for (optional ones, such as toes)."""
        return [c for c, j in zip(CANONICAL_JOINTS, self.joints) if j < 0]

    def unmapped_joints(self) -> tuple[int, ...]:
        """The take's joints no canonical joint takes (fingers, extra spine or neck joints,
        reference nodes above the hips), ascending."""
        used = set(self.joints)
        return tuple(j for j in range(self.skeleton.n_joints) if j not in used)

    def kept_joints(self) -> tuple[int, ...]:
        """The take's joints with no mapped joint strictly below them, ascending: the
        unmapped ends (fingers, eyes, toes' ends) and the canonical ends (hands, head, feet
        or toes), whose turn positions cannot show. On the way back from canonical
        positions they keep their own angles; an unmapped joint with a mapped one below
        (CMU's ``LowerBack``, a third spine joint) is aimed along the chain instead."""
        skeleton = self.skeleton
        mapped_below = np.zeros(skeleton.n_joints, bool)
        mapped = self.mapped_joints()
        for j in range(skeleton.n_joints - 1, 0, -1):  # children after parents
            if mapped[j] or mapped_below[j]:
                mapped_below[skeleton.parents[j]] = True
        return tuple(int(j) for j in np.flatnonzero(~mapped_below))

    def mapped_joints(self) -> np.ndarray:
        """(J,) bool: the take's joint is some canonical joint's."""
        out = np.zeros(self.skeleton.n_joints, bool)
        out[[j for j in self.joints if j >= 0]] = True
        return out

    def canonical_positions(self, positions: np.ndarray) -> np.ndarray:
        """(F, 21, 3) the canonical joints' positions from the take's joint positions (F, J, 3)
        (any unit; NaN for absent joints)."""
        out = np.full(positions.shape[:-2] + (len(CANONICAL_JOINTS), 3), np.nan)
        m = self.mapped
        out[..., m, :] = positions[..., np.array(self.joints)[m], :]
        return out

    def body_size_cm(self) -> float:
        """The rest-pose head-to-feet length of the canonical chain (module docstring), cm."""
        rest = self.canonical_positions(self.skeleton.rest_positions()[None])[0] * self.skeleton.unit_cm

        def chain(names) -> float:
            points = [rest[CANONICAL_JOINTS.index(n)] for n in names if self.joint(n) >= 0]
            return float(sum(np.linalg.norm(b - a) for a, b in zip(points, points[1:])))

        legs = [chain([f"{s}_thigh", f"{s}_shin", f"{s}_foot"]) for s in _SIDES]
        return chain(["hips", "spine", "chest", "neck", "head"]) + float(np.mean(legs))

    def describe(self) -> str:
        """The mapping as text: one line per canonical joint, then the unmapped joints."""
        names = self.skeleton.names
        width = max(len(c) for c in CANONICAL_JOINTS)
        lines = []
        for c, j in zip(CANONICAL_JOINTS, self.joints):
            how = " (mapping file)" if c in self.pinned else ""
            essential = "essential" if c in ESSENTIAL_JOINTS else "optional"
            lines.append(f"{c:<{width}}  {names[j] if j >= 0 else '-'}{how}" + ("" if j >= 0 else f"  ({essential})"))
        kept, carriers, unmapped = set(self.kept_joints()), set(self.skeleton.root_chain[:-1]), self.unmapped_joints()
        carried = [names[j] for j in unmapped if j in carriers]  # reference nodes carrying the body
        aimed = [names[j] for j in unmapped if j not in kept and j not in carriers]
        rest = [names[j] for j in unmapped if j in kept]
        if carried:
            lines.append(f"above the body root ({len(carried)}, kept as observed): {', '.join(carried)}")
        if aimed:
            lines.append(f"unmapped above mapped joints ({len(aimed)}, aimed along the chain): {', '.join(aimed)}")
        lines.append(f"unmapped ({len(rest)}, keep their own angles): {', '.join(rest) or 'none'}")
        lines.append(f"body size: {self.body_size_cm():.1f} cm (rest-pose hips-head chain plus mean leg)")
        return "\n".join(lines)


class _Tree:
    """Ancestry and rest places of a skeleton, for the mapping rules."""

    def __init__(self, skeleton: Skeleton):
        self.s = skeleton
        self.depth = [0] * skeleton.n_joints
        for j, p in enumerate(skeleton.parents):
            self.depth[j] = self.depth[p] + 1 if p >= 0 else 0
        self.rest = skeleton.rest_positions()
        self.scale = max(skeleton.rest_height(), 1e-9)
        self.in_body = [False] * skeleton.n_joints  # the body root and its descendants
        for j, p in enumerate(skeleton.parents):  # parents come before their children
            self.in_body[j] = j == skeleton.body_root or (p >= 0 and self.in_body[p])

    def ancestors(self, j: int) -> list[int]:
        """j's ancestors, nearest first."""
        out = []
        while (j := self.s.parents[j]) >= 0:
            out.append(j)
        return out

    def below(self, j: int, a: int) -> bool:
        """j is a strict descendant of a."""
        return a in self.ancestors(j)

    def same_place(self, a: int, b: int) -> bool:
        return bool(np.linalg.norm(self.rest[a] - self.rest[b]) <= _SAME_PLACE * self.scale)

    def limb_parent(self, j: int) -> int:
        """j's nearest ancestor not passed over (roll or twist joints), -1 at the root."""
        return next((a for a in self.ancestors(j) if not _PASS_OVER.search(self.s.names[a])), -1)

    def shallowest(self, pattern: str, side: str | None, exclude: re.Pattern | None = None) -> list[int]:
        """Joints below the body root whose name matches, of that side, shallowest first."""
        s = self.s
        hits = [
            j
            for j in range(s.n_joints)
            if self.in_body[j]
            and re.search(pattern, _stem(s.names[j]), re.IGNORECASE)
            and not (exclude and exclude.search(s.names[j]))
            and (side is None or joint_side(s.names[j]) == side)
        ]
        return sorted(hits, key=lambda j: self.depth[j])


def _ends(tree: _Tree, pattern: str, exclude: re.Pattern | None = None) -> dict[str, int]:
    """The two limb ends of a kind (hands or feet) by side: named, or placed by the rest
    pose (+X is left) where the names say no side."""
    named = {side: hits[0] for side in _SIDES if (hits := tree.shallowest(pattern, side, exclude))}
    if len(named) == 2:
        return named
    unsided = [j for j in tree.shallowest(pattern, None, exclude) if joint_side(tree.s.names[j]) is None]
    shallow = [j for j in unsided if tree.depth[j] == tree.depth[unsided[0]]] if unsided else []
    if not named and len(shallow) == 2:
        a, b = sorted(shallow, key=lambda j: tree.rest[j][0])
        return {"right": a, "left": b}
    return named


def _lowest_common_ancestor(tree: _Tree, joints: list[int]) -> int:
    lines = [[j] + tree.ancestors(j) for j in joints]
    common = set(lines[0]).intersection(*lines[1:])
    return max(common, key=lambda j: tree.depth[j]) if common else -1


def unknown_canonical(names) -> str | None:
    """What is wrong with ``names`` as canonical joints (a mapping file's keys): the ones
    there are not, and the ones there are; None where every one is."""
    unknown = sorted(set(names) - set(CANONICAL_JOINTS))
    if not unknown:
        return None
    what = "a canonical joint" if len(unknown) == 1 else "canonical joints"
    return f"{', '.join(unknown)}: not {what}; they are {', '.join(CANONICAL_JOINTS)}"


def map_humanoid(
    skeleton: Skeleton, overrides: Mapping[str, str | None] | None = None, *, checked: bool = True
) -> HumanoidMapping:
    """The canonical joints of ``skeleton`` (rules in the module docstring); ``overrides``
    maps canonical joint names to the take's joint names (None: absent), set before the
    rules run so that what follows from them (the chest from the hands) follows. With
    ``checked`` False, what the rules found, however incomplete (to show it).

    Raises
    ------
    HumanoidError
        An override names an unknown canonical or take joint, an essential joint cannot be
        mapped, or the result breaks the canonical tree.
    """
    overrides = dict(overrides or {})
    names = skeleton.names
    if (problem := unknown_canonical(overrides)) is not None:
        raise HumanoidError(f"mapping: {problem}")
    pinned: dict[str, int] = {}
    for c, name in overrides.items():
        if name is not None and name not in names:
            raise HumanoidError(f"mapping: {c} = {name!r}, but the take has no joint {name!r}")
        pinned[c] = -1 if name is None else names.index(name)

    tree = _Tree(skeleton)
    found: dict[str, int] = {}

    def put(c: str, rule) -> int:
        found[c] = pinned[c] if c in pinned else rule()
        return found[c]

    hips = put("hips", lambda: skeleton.body_root)
    head = put("head", lambda: next(iter(tree.shallowest("head", None)), -1))
    hands = _ends(tree, "hand|wrist", _FINGER)
    for side in _SIDES:
        put(f"{side}_hand", lambda side=side: hands.get(side, -1))
    ends = [found[c] for c in ("head", "left_hand", "right_hand") if found[c] >= 0]
    chest = put("chest", lambda: _lowest_common_ancestor(tree, ends) if len(ends) == 3 else -1)
    if chest == hips:
        chest = found["chest"] = -1 if "chest" not in pinned else chest

    def next_up(j: int, stop: int) -> int:
        """The next limb joint above j, strictly below ``stop``; -1 if none."""
        if j < 0 or stop < 0:
            return -1
        up = tree.limb_parent(j)
        return up if up >= 0 and tree.below(up, stop) else -1

    for side in _SIDES:
        forearm = put(f"{side}_forearm", lambda side=side: next_up(found[f"{side}_hand"], chest))
        upper = put(f"{side}_upper_arm", lambda: next_up(forearm, chest))
        put(f"{side}_shoulder", lambda: next_up(upper, chest))

    def first_apart(path_from: int, to: int) -> int:
        """The first joint on the way from ``path_from`` down to ``to`` (both excluded) that
        does not sit on ``path_from``."""
        if path_from < 0 or to < 0 or not tree.below(to, path_from):
            return -1
        path = [a for a in reversed(tree.ancestors(to)) if tree.below(a, path_from)]
        return next((a for a in path if not tree.same_place(a, path_from) and not _PASS_OVER.search(names[a])), -1)

    put("spine", lambda: first_apart(hips, chest))
    put("neck", lambda: first_apart(chest, head))

    feet = _ends(tree, "foot|ankle", re.compile("toe", re.IGNORECASE))
    for side in _SIDES:
        foot = put(f"{side}_foot", lambda side=side: feet.get(side, -1))
        shin = put(f"{side}_shin", lambda: next_up(foot, hips))
        put(f"{side}_thigh", lambda: next_up(shin, hips))

        def toes(foot=foot) -> int:
            kids = [k for k in skeleton.children[foot]] if foot >= 0 else []
            toe = [k for k in kids if "toe" in names[k].lower()]
            return (toe or kids)[0] if len(toe) == 1 or len(kids) == 1 else -1

        put(f"{side}_toes", toes)

    joints = tuple(found[c] for c in CANONICAL_JOINTS)
    if not checked:
        return HumanoidMapping(skeleton, joints, frozenset(overrides))
    try:
        _check(skeleton, tree, joints, frozenset(pinned))
    except HumanoidError as err:
        if not overrides:
            raise
        pins = ", ".join(f"{c} = {name!r}" for c, name in overrides.items())
        raise HumanoidError(
            f"{err} (the mapping pins {pins}, and the joints next to a pinned one follow from it)"
        ) from None
    return HumanoidMapping(skeleton, joints, frozenset(overrides))


def _check(skeleton: Skeleton, tree: _Tree, joints: tuple[int, ...], pinned: frozenset[str] = frozenset()) -> None:
    names = skeleton.names
    at = dict(zip(CANONICAL_JOINTS, joints))
    missing = [c for c in ESSENTIAL_JOINTS if at[c] < 0]
    if missing:
        # the head, hands and feet are found by their names, the rest from them: name the first
        named = [c for c in missing if c in _NAMED_JOINTS and c not in pinned]  # (a pin says it is absent)
        followers = [c for c in missing if c not in named]
        because = (
            f" ({', '.join(followers)} {'is' if len(followers) == 1 else 'are'} found from {', '.join(named)}, "
            "which no joint's name says)"
            if named and followers
            else ""
        )
        raise HumanoidError(
            f"the skeleton ({skeleton.n_joints} joints, root {names[0]!r}) has no joint for "
            f"{', '.join(missing)}, which a skeleton-agnostic engine needs{because}; name "
            f"{'them' if len(missing) > 1 else 'it'} in a mapping file (JSON, "
            f'{{"{(named or missing)[0]}": "JointName"}}) passed with --mapping (clean, inspect, train; skeleton '
            "shows what it maps), or clean with a classical engine"
        )
    used: dict[int, str] = {}
    for c, j in at.items():
        if j < 0:
            continue
        if j in used:
            raise HumanoidError(f"mapping: {names[j]!r} is both {used[j]} and {c}; give each its own joint")
        used[j] = c
        parent = CANONICAL_PARENTS[c]
        while parent is not None and at[parent] < 0:
            parent = CANONICAL_PARENTS[parent]
        if parent is not None and not tree.below(j, at[parent]):
            raise HumanoidError(
                f"mapping: {c} = {names[j]!r} is not below {parent} = {names[at[parent]]!r} in the skeleton's tree"
            )
