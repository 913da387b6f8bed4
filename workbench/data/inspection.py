"""Which frames of a take are broken: suspicious intervals, each with its reason.

Four rules that need no ground truth and no engine, each flagging samples (frame, joint):

- ``spike``: a joint's rotation far from where its neighbours put it. The prediction is the
  geodesic midpoint of frames t-1 and t+1, and of t-2 and t+2 (a spike two frames long
  still stands out against the wider pair); the score is the smaller of the two angles
  from the frame's rotation to them. A sample is flagged above :data:`SPIKE_FLOOR_DEG`
  and above :data:`SPIKE_SCALE` times the joint's median score over the take (a fast
  take at 30 fps predicts worse). Chosen on the CMU train split and the Bandai
  validation split with ``outliers:0.01``.
- ``turn``: a joint turning faster than a body can (:func:`.quality.reference_glitches`).
- ``linear``: a moving joint whose channels lie exactly on a line, to the file's printed
  precision, for at least :data:`LINEAR_MIN_FRAMES` frames: a gap an exporter filled by
  linear interpolation (real motion always bends).
- ``bone``: a translated joint (position channels) other than the body root whose bone
  length leaves its median by more than :data:`BONE_TOLERANCE` (a stretchy rig, a solver
  that lets bones grow).

Each rule is a function ``motion -> (flags (F, J) bool, scores (F, J) float)``.

Frames are 0-based frames of the motion; an interval is ``first`` to ``last`` inclusive.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.kinematics import local_rotations
from ..core.motion import Motion, channel_joints
from ..core.rotations import matrix_to_quaternion
from .quality import reference_glitches, runs

#: degrees a rotation must be off its neighbours' prediction to be a spike
SPIKE_FLOOR_DEG = 20.0
#: ... and multiples of the joint's median prediction error over the take
SPIKE_SCALE = 6.0
#: frames a joint's channels must lie on a line to count as a linear fill
LINEAR_MIN_FRAMES = 2
#: a channel moving less than this per frame (degrees or file units) is at rest, not filled
LINEAR_MIN_STEP = 0.01
#: relative change of a bone's length that counts as a stretch
BONE_TOLERANCE = 0.02
#: flagged frames of one rule at most this many frames apart are one interval
MERGE_FRAMES = 3

REASONS = {
    "spike": "rotation far off its neighbours'",
    "turn": "turns faster than a body can",
    "linear": "channels on a straight line (a linear fill)",
    "bone": "bone length varies",
}


@dataclass(frozen=True)
class Interval:
    """Frames ``first`` to ``last`` (inclusive) flagged by rule ``reason`` on ``joints``;
    ``score`` the rule's largest value there (degrees for spike and turn, frames for
    linear, relative stretch for bone)."""

    reason: str
    first: int
    last: int
    joints: tuple[str, ...]
    score: float

    def __str__(self) -> str:
        joints = ", ".join(self.joints[:4]) + (f" and {len(self.joints) - 4} more" if len(self.joints) > 4 else "")
        return f"frames {self.first}-{self.last}: {self.reason} ({REASONS[self.reason]}): {joints}"


def _quaternion_distance_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.rad2deg(2 * np.arccos(np.clip(np.abs(np.sum(a * b, -1)), 0.0, 1.0)))


def _midpoint(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    b = np.where(np.sum(a * b, -1, keepdims=True) < 0, -b, b)
    m = a + b
    return m / np.linalg.norm(m, axis=-1, keepdims=True)


def spike_flags(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """(flags (F, J) bool, scores (F, J) degrees) of the ``spike`` rule."""
    sk = motion.skeleton
    F, J = motion.n_frames, sk.n_joints
    joints = np.flatnonzero(sk.has_rotation)
    scores = np.zeros((F, J))
    if F < 3 or joints.size == 0:
        return np.zeros((F, J), bool), scores
    q = matrix_to_quaternion(local_rotations(sk, motion.angles_deg, joints))
    near = np.full((F, joints.size), np.inf)
    wide = np.full_like(near, np.inf)
    near[1:-1] = _quaternion_distance_deg(q[1:-1], _midpoint(q[:-2], q[2:]))
    if F >= 5:
        wide[2:-2] = _quaternion_distance_deg(q[2:-2], _midpoint(q[:-4], q[4:]))
    s = np.minimum(near, wide)
    s[0], s[-1] = near[1], near[-2]  # the end frames: as their neighbour
    scores[:, joints] = s
    flags = scores > np.maximum(SPIKE_FLOOR_DEG, SPIKE_SCALE * np.median(scores, axis=0))
    return flags, scores


def linear_flags(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """(flags (F, J) bool, length in frames of the straight run each flag is in) of the
    ``linear`` rule. A channel's second difference counts as zero within 2.5 units of the
    6th significant digit (at least 2.5e-4): rounding a file's values to that precision
    moves a second difference by at most 2 units."""
    X = motion.channels
    F, J = motion.n_frames, motion.skeleton.n_joints
    flags, lengths = np.zeros((F, J), bool), np.zeros((F, J))
    if F < 3:
        return flags, lengths
    cols = channel_joints(motion.skeleton)
    magnitude = np.floor(np.log10(np.abs(X[1:-1]) + 1e-12))
    tol = np.maximum(2.5e-4, 2.5 * 10.0 ** (magnitude - 5))
    straight = np.abs(X[2:] - 2 * X[1:-1] + X[:-2]) <= tol
    moving = np.abs(X[2:] - X[:-2]) / 2 > LINEAR_MIN_STEP
    all_straight = np.ones((F - 2, J), bool)
    any_moving = np.zeros((F - 2, J), bool)
    np.logical_and.at(all_straight, (slice(None), cols), straight)
    np.logical_or.at(any_moving, (slice(None), cols), moving)
    inner = all_straight & any_moving
    for j in np.flatnonzero(inner.any(0)):
        for run in runs(np.flatnonzero(inner[:, j])):
            if run.size >= LINEAR_MIN_FRAMES:
                flags[run + 1, j] = True
                lengths[run + 1, j] = run.size
    return flags, lengths


def bone_flags(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """(flags (F, J) bool, relative stretch (F, J)) of the ``bone`` rule."""
    F, J = motion.n_frames, motion.skeleton.n_joints
    stretch = np.zeros((F, J))
    for k, j in enumerate(motion.skeleton.translated):
        if j == motion.skeleton.body_root:  # its translation is the body's path, not a bone
            continue
        length = np.linalg.norm(motion.translations[:, k], axis=-1)
        median = np.median(length)
        if median > 0:
            stretch[:, j] = np.abs(length / median - 1.0)
    return stretch > BONE_TOLERANCE, stretch


def turn_flags(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """(flags (F, J) bool, degrees turned in one frame) of the ``turn`` rule."""
    F, J = motion.n_frames, motion.skeleton.n_joints
    flags, scores = np.zeros((F, J), bool), np.zeros((F, J))
    for g in reference_glitches(motion):
        j = motion.skeleton.index(g.joint)
        flags[g.first : g.last + 1, j] = True
        scores[g.first : g.last + 1, j] = g.turn_deg
    return flags, scores


@dataclass(frozen=True)
class Inspection:
    """What :func:`inspect_motion` found: per rule, the flagged samples (F, J) and scores."""

    motion: Motion
    flags: dict[str, np.ndarray]
    scores: dict[str, np.ndarray]

    def flagged_frames(self) -> np.ndarray:
        """(F,) bool: frames any rule flags on any joint."""
        return np.logical_or.reduce([f.any(1) for f in self.flags.values()])

    def intervals(self) -> list[Interval]:
        """The suspicious intervals, by first frame, then rule."""
        names = self.motion.skeleton.names
        out = []
        for reason, flags in self.flags.items():
            for run in runs(np.flatnonzero(flags.any(1)), MERGE_FRAMES):
                window = flags[run[0] : run[-1] + 1]
                joints = tuple(names[j] for j in np.flatnonzero(window.any(0)))
                score = float(self.scores[reason][run[0] : run[-1] + 1][window].max())
                out.append(Interval(reason, int(run[0]), int(run[-1]), joints, score))
        return sorted(out, key=lambda i: (i.first, i.reason))

    def to_json(self) -> dict:
        frames = self.flagged_frames()
        return {
            "take": self.motion.name,
            "frames": self.motion.n_frames,
            "fps": self.motion.fps,
            "flagged_frames": int(frames.sum()),
            "intervals": [
                {"reason": i.reason, "first": i.first, "last": i.last, "joints": list(i.joints), "score": i.score}
                for i in self.intervals()
            ],
        }


#: every rule by its reason (the keys of :data:`REASONS`)
RULES = {"spike": spike_flags, "turn": turn_flags, "linear": linear_flags, "bone": bone_flags}


def inspect_motion(motion: Motion) -> Inspection:
    """Run every rule on ``motion`` (a take as recorded: no ground truth needed)."""
    found = {reason: rule(motion) for reason, rule in RULES.items()}
    return Inspection(motion, {r: f for r, (f, _) in found.items()}, {r: s for r, (_, s) in found.items()})
