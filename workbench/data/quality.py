"""Checks on the clean takes that benchmarks score against: capture glitches.

The fastest turn of a human joint on record is a baseball pitcher's shoulder, at about
7,000 degrees per second. Where a take's joint turns faster than that between two
frames, the recording is wrong there (a marker swap or a solver flip: on the CMU test
split, 35_26's right finger base turns 170 degrees in one frame at 120 fps), and an
engine that removes the glitch is scored as wrong by the frames it corrected. Benchmarks
name these places, so that their scores can be read with that in mind; they do not leave
them out of the scores.

Below 39 frames per second no turn between two frames can exceed the limit (at 30 fps
it is 233 degrees a frame; a turn is at most 180): a take that coarse cannot tell a
flip from a fast turn by speed, so none is named (Bandai's takes). ``workbench
inspect``'s ``spike`` rule, which asks whether a rotation fits its neighbours, still
finds such flips there (:mod:`workbench.data.inspection`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.kinematics import local_rotations
from ..core.motion import Motion
from ..core.rotations import rotation_angle_deg

#: degrees per second no human joint turns faster than (a pitcher's shoulder: ~7,000)
MAX_TURN_DPS = 7000.0
#: fast turns of one joint fewer than this many frames apart are one glitch (a flip and
#: its flip back)
MERGE_FRAMES = 5


@dataclass(frozen=True)
class Glitch:
    """A stretch of frames, ``first`` to ``last`` (0-based frames of the motion), over which
    ``joint`` turns faster than a body can, by at most ``turn_deg`` degrees between two
    consecutive frames."""

    joint: str
    first: int
    last: int
    turn_deg: float

    def __str__(self) -> str:
        return f"{self.joint} turns {self.turn_deg:.0f} degrees in one frame (frames {self.first}-{self.last})"


def runs(indices: np.ndarray, max_gap: int = 1) -> list[np.ndarray]:
    """Sorted indices split into runs: consecutive ones at most ``max_gap`` apart stay together."""
    if indices.size == 0:
        return []
    return np.split(indices, np.flatnonzero(np.diff(indices) > max_gap) + 1)


def reference_glitches(motion: Motion, max_turn_dps: float = MAX_TURN_DPS) -> list[Glitch]:
    """The places where a joint of ``motion`` turns faster than ``max_turn_dps`` between
    two consecutive frames, by joint, then frame."""
    skeleton = motion.skeleton
    joints = np.flatnonzero(skeleton.has_rotation)
    R = local_rotations(skeleton, motion.angles_deg, joints)
    turns = rotation_angle_deg(R[1:], R[:-1])  # (F - 1, n) degrees between frames t and t + 1
    found = []
    for k, j in enumerate(joints):
        fast = np.flatnonzero(turns[:, k] > max_turn_dps / motion.fps)
        for run in runs(fast, MERGE_FRAMES - 1):
            found.append(Glitch(skeleton.names[j], int(run[0]), int(run[-1]) + 1, float(turns[run, k].max())))
    return found
