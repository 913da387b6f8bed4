"""Which way is up in a take, and the exact turn that stands it on +Y.

BVH has Y up, and so do the engines that model a body in the world (the motion image's
heading and floor, the canonical body's facing) and the app's floor and camera. Some
exporters write Z up (3ds Max, some Blender and game-engine pipelines), and a Y-up rest
pose may be turned to Z up by the root's rotation in every frame. A take's up is read
from its motion (:func:`up_turn`): the axis along which its head stands above its feet,
on average over the take (the rest pose cannot tell: Bandai's and LAFAN1's rest poses lie
along X in a Y-up world, one exporter's Y-up rest pose stands on Z in its frames).

The turn is a quarter or half turn about a coordinate axis, so it only relabels axes and
flips signs: a rotation channel about X by ``a`` becomes one about the axis X turns to, by
``a`` or ``-a``, in the same place of the joint's Euler order; offsets, positions and
translations permute and flip likewise (:func:`turn_motion`). No number is rounded, and
turning back with the transposed turn gives the take bit for bit.

Units: positions in the take's file unit.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from .humanoid import HumanoidError, map_humanoid
from .kinematics import joint_positions
from .motion import Motion
from .skeleton import POSITION_CHANNELS, ROTATION_CHANNELS, Skeleton

__all__ = ["up_turn", "turn_vectors", "turn_skeleton", "turn_motion"]

#: frames (at most) whose poses say where up is, evenly spread over the take
UP_FRAMES = 64
#: the mean head-over-feet vector must lean this far (a share of the body size) along one
#: axis, and this many times further than along any other, for that axis to be the take's
#: up; otherwise the take is taken as BVH's Y-up. Humanoid takes from 20 exporters lean
#: 0.66-1.03 body sizes along their up, 4.8-190 times further than across; a quadruped
#: mapped as a humanoid (its head ahead of its feet) 1.2 times.
UP_SHARE, UP_DOMINANCE = 0.5, 2.0
#: the turn (a signed axis permutation, rows: new axes) that stands each up axis on +Y
_TURNS = {
    (1, -1): ((-1, 0, 0), (0, -1, 0), (0, 0, 1)),  # half a turn about Z
    (2, 1): ((1, 0, 0), (0, 0, 1), (0, -1, 0)),  # a quarter about X, Z to Y
    (2, -1): ((1, 0, 0), (0, 0, -1), (0, 1, 0)),
    (0, 1): ((0, -1, 0), (1, 0, 0), (0, 0, 1)),  # a quarter about Z, X to Y
    (0, -1): ((0, 1, 0), (-1, 0, 0), (0, 0, 1)),
}


def up_turn(motion: Motion, overrides: Mapping[str, str | None] | None = None) -> np.ndarray | None:
    """The turn (3, 3) that stands ``motion`` on +Y, or None where it already stands on
    +Y, or where it cannot tell (a skeleton with no humanoid mapping, no frame with the
    head and both feet, no axis its head leans along by :data:`UP_SHARE` of the body
    size and :data:`UP_DOMINANCE` times further than along the others): BVH's
    convention then holds.

    Parameters
    ----------
    motion : Motion
        The take (NaN where it is missing; those frames do not count).
    overrides : Mapping, optional
        The user's mapping file, as :func:`~workbench.core.humanoid.map_humanoid` takes it.

    Returns
    -------
    numpy.ndarray or None
        A signed axis permutation ``R`` (integers as floats, determinant 1): a point
        ``p`` of the take is at ``R @ p`` in the upright take.

    Raises
    ------
    HumanoidError
        ``overrides`` that do not fit the skeleton (without them, a skeleton with no
        humanoid mapping is taken as it stands).
    """
    skeleton = motion.skeleton
    try:
        mapping = map_humanoid(skeleton, overrides)
    except HumanoidError:
        if overrides:  # the user's mapping, refused: said, not dropped with the turn it asks for
            raise
        return None
    head, feet = mapping.joint("head"), [mapping.joint("left_foot"), mapping.joint("right_foot")]
    frames = np.unique(np.linspace(0, motion.n_frames - 1, min(motion.n_frames, UP_FRAMES)).round().astype(int))
    p = joint_positions(
        skeleton,
        motion.root_positions[frames],
        motion.angles_deg[frames],
        None if motion.translations is None else motion.translations[frames],
    )
    lean = p[:, head] - p[:, feet].mean(axis=1)
    lean = lean[np.isfinite(lean).all(axis=1)]
    if not len(lean):
        return None
    mean = lean.mean(axis=0)
    lengths = np.sort(np.abs(mean))
    axis = int(np.argmax(np.abs(mean)))
    if not (
        lengths[2] >= UP_SHARE * mapping.body_size_cm() / skeleton.unit_cm and lengths[2] >= UP_DOMINANCE * lengths[1]
    ):
        return None
    key = (axis, int(np.sign(mean[axis])))
    return None if key == (1, 1) else np.array(_TURNS[key], dtype=float)


def turn_vectors(vectors: np.ndarray, turn: np.ndarray) -> np.ndarray:
    """Vectors (..., 3) turned by ``turn``: ``turn @ v`` for each, exactly, by picking and
    negating coordinates (a NaN stays in its own coordinate)."""
    axes = np.argmax(np.abs(turn), axis=1)
    return np.asarray(vectors, float)[..., axes] * turn[np.arange(3), axes]


def _relabel(names: tuple[str, ...], turn: np.ndarray) -> tuple[tuple[str, ...], np.ndarray]:
    """A joint's channel names under ``turn`` and each one's sign (-1 where its value flips)."""
    out, signs = [], []
    for name in names:
        kind = ROTATION_CHANNELS if name in ROTATION_CHANNELS else POSITION_CHANNELS
        axis = kind.index(name)
        new = int(np.flatnonzero(turn[:, axis])[0])  # the axis this one turns to
        out.append(kind[new])
        signs.append(turn[new, axis])
    return tuple(out), np.array(signs)


def turn_skeleton(skeleton: Skeleton, turn: np.ndarray) -> Skeleton:
    """``skeleton`` in the turned frame: offsets, file offsets and end sites turned, each
    channel renamed after the axis its own turns to (module docstring); the same joints,
    order and unit."""
    return skeleton.replace(
        offsets=turn_vectors(skeleton.offsets, turn),
        file_offsets=turn_vectors(skeleton.file_offsets, turn),
        channels=tuple(_relabel(ch, turn)[0] for ch in skeleton.channels),
        end_sites=tuple((p, tuple(turn_vectors(off, turn).tolist())) for p, off in skeleton.end_sites),
    )


def turn_motion(motion: Motion, turn: np.ndarray, skeleton: Skeleton | None = None) -> Motion:
    """``motion`` with its world turned by ``turn`` (a signed axis permutation, as from
    :func:`up_turn`), exactly: its joints' world positions are ``turn @ p``. ``skeleton``:
    the turned skeleton, where the caller has it (turning back, the take's own)."""
    skeleton = turn_skeleton(motion.skeleton, turn) if skeleton is None else skeleton
    angles = motion.angles_deg.copy()
    for j, names in enumerate(motion.skeleton.channels):
        rotations = tuple(c for c in names if c in ROTATION_CHANNELS)
        if rotations:
            angles[:, j] *= _relabel(rotations, turn)[1]
    translations = None if motion.translations is None else turn_vectors(motion.translations, turn)
    return Motion(skeleton, motion.fps, turn_vectors(motion.root_positions, turn), angles, motion.name, translations)
