"""Which frames of a take are broken: suspicious intervals, each with its reason.

Five rules that need no ground truth and no engine, each flagging samples (frame, joint):

- ``spike``: a joint's rotation far from where its neighbours put it. The prediction is the
  geodesic midpoint of frames t-1 and t+1, and of t-2 and t+2 (a spike two frames long
  still stands out against the wider pair); the score is the smaller of the two angles
  from the frame's rotation to them. A sample is flagged above :data:`SPIKE_FLOOR_DEG`
  and above :data:`SPIKE_SCALE` times the joint's median score over the take (a fast
  take at 30 fps predicts worse). Chosen on the CMU train split and the Bandai
  validation split with ``outliers:0.01``.
- ``turn``: a joint turning faster than a body can (:func:`.quality.reference_glitches`);
  silent below 39 fps, where no turn between two frames is faster than a body can.
- ``jump``: the body root moving faster than a body can between two frames, above
  :data:`JUMP_SPEED_M_S` (a dropped stretch of frames, a marker swap on the pelvis, an
  exporter's stray frames that put the body a kilometre off): the frames it is off its
  path, on the body root (:func:`jump_flags`).
- ``linear``: a moving joint whose channels lie exactly on a line, to the file's printed
  precision, for at least :data:`LINEAR_MIN_FRAMES` frames: a gap an exporter filled by
  linear interpolation (real motion always bends). Not a reference node above the body
  root (MotionBuilder's ``joint_Root``): the exporter moves it, and three Bandai takes
  carry it along a straight line.
- ``bone``: a translated joint (position channels) other than the body root whose bone
  length leaves its median by more than :data:`BONE_TOLERANCE` (a stretchy rig, a solver
  that lets bones grow).

Each rule is a function ``motion -> (flags (F, J) bool, scores (F, J) float)``.

Three more reasons need more than the motion: ``missing``, the samples an observed mask
(a ``workbench corrupt`` sidecar) lists as missing; ``rejected``, the samples a robust
engine's estimator treated as outliers (its ``robust_weight`` diagnostic below
:data:`REJECT_WEIGHT`); and ``disagree``, the joints where engines' cleaned poses spread
apart (:func:`disagreement_flags`). :func:`inspect_motion` adds each when given what it needs.

Frames are 0-based frames of the motion; an interval is ``first`` to ``last`` inclusive.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..core.kinematics import joint_positions, local_rotations
from ..core.motion import (
    Motion,
    Observation,
    Skeleton,
    channel_count,
    channel_joints,
    channel_mask,
    position_unknown,
)
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
#: metres per second the body root cannot move at between two frames: sprinters peak near
#: 12; the shared takes' runs and dashes reach 5.2, and the one step above 10 is a capture
#: fault (CMU 03_02 holds its first pose for 23 frames, then jumps 11 cm)
JUMP_SPEED_M_S = 10.0
#: seconds within which a later fast step may undo a jump (a longer stray stretch is two
#: jumps, each flagged at its step; the search stays short on a take full of them)
JUMP_RETURN_S = 2.0
#: relative change of a bone's length that counts as a stretch
BONE_TOLERANCE = 0.02
#: a robust engine's data weight below this is a rejected sample (Welsch: exp(-r^2 / p^2) < 0.1
#: for a residual r over 1.5 times the scale p)
REJECT_WEIGHT = 0.1
#: cm a joint's cleaned positions must spread (the farthest engine from their mean) to disagree
DISAGREE_FLOOR_CM = 2.0
#: ... and multiples of the joint's median spread over the take
DISAGREE_SCALE = 4.0
#: flagged frames of one rule at most this many frames apart are one interval
MERGE_FRAMES = 3

REASONS = {
    "spike": "rotation far off its neighbours'",
    "turn": "turns faster than a body can",
    "jump": "moves faster than a body can",
    "linear": "channels on a straight line (a linear fill)",
    "bone": "bone length varies",
    "missing": "no sample (a gap in the observed mask)",
    "rejected": "a robust engine treated it as an outlier",
    "disagree": "the engines' cleaned poses disagree",
}


@dataclass(frozen=True)
class Interval:
    """Frames ``first`` to ``last`` (inclusive) flagged by rule ``reason`` on ``joints``;
    ``score`` the rule's largest value there (degrees for spike and turn, frames for
    linear, relative stretch for bone, 1 for missing, 1 - weight for rejected, cm for
    disagree)."""

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
    inner[:, list(motion.skeleton.root_chain[:-1])] = False  # reference nodes: no capture to fill
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


def jump_flags(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """(flags (F, J) bool, the fastest step's speed (F, J) m/s) of the ``jump`` rule, on
    the body root. A step faster than :data:`JUMP_SPEED_M_S` that a later fast step
    undoes within :data:`JUMP_RETURN_S` (after it the root is back where a body could
    have walked to from where it left, and less than half as far from there as it went)
    flags the frames between them: the body was off its path there. One that nothing
    undoes (dropped frames, a path that restarts elsewhere) flags both its frames."""
    F, J = motion.n_frames, motion.skeleton.n_joints
    flags, speeds = np.zeros((F, J), bool), np.zeros((F, J))
    if F < 2:
        return flags, speeds
    sk, b = motion.skeleton, motion.skeleton.body_root
    if b == 0:  # the root's own channels: no kinematics (a 10-minute take's would be 0.5 GB)
        path = motion.root_positions + sk.offsets[0]
    else:
        path = joint_positions(sk, motion.root_positions, motion.angles_deg, motion.translations)[:, b]
    path_m = path * (sk.unit_cm / 100.0)
    speed = np.linalg.norm(np.diff(path_m, axis=0), axis=1) * motion.fps
    fast = np.flatnonzero(speed > JUMP_SPEED_M_S)  # NaN (a missing root) is not fast
    reach = int(JUMP_RETURN_S * motion.fps)
    i = 0
    while i < len(fast):
        out = fast[i]
        later = fast[i + 1 : np.searchsorted(fast, out + reach, side="right")]  # steps j with j + 1 - out <= reach
        away = np.linalg.norm(path_m[out + 1 : out + reach + 2] - path_m[out], axis=1)  # from frame out + 1 on
        k = later - out  # after step j the root is at frame out + 1 + k: away[k]; before, at most went[k - 1]
        went = np.maximum.accumulate(away)
        undone = np.flatnonzero((away[k] * motion.fps <= JUMP_SPEED_M_S * (k + 1)) & (away[k] <= 0.5 * went[k - 1]))
        first, last = (out + 1, int(later[undone[0]])) if undone.size else (out, out + 1)
        flags[first : last + 1, b] = True
        speeds[first : last + 1, b] = speed[out : (last if undone.size else out) + 1].max()
        i += 1 + (int(undone[0]) + 1 if undone.size else 0)
    return flags, speeds


def rejected_flags(skeleton: Skeleton, observed: np.ndarray, weight: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(flags (F, J) bool, 1 - the joint's smallest weight (F, J)) of the ``rejected``
    reason: observed samples a robust estimator weighted below :data:`REJECT_WEIGHT`
    (a column it left at 0 wherever observed, one it did not filter, is left out).
    ``weight`` is an engine's ``robust_weight``, (F, C) over the channel matrix's columns
    (joint angles) or (F, 3J) over the joints' root-relative positions; ``observed`` (F, J)."""
    F, J = observed.shape
    weight = np.asarray(weight, float)
    if weight.shape[1] == channel_count(skeleton):
        known = channel_mask(observed, skeleton)
        columns = channel_joints(skeleton)
    elif weight.shape[1] == 3 * J:
        known = np.repeat(~position_unknown(observed, skeleton.parents, skeleton.translated), 3, axis=1)
        columns = np.repeat(np.arange(J), 3)
    else:
        raise ValueError(f"robust weights of {weight.shape[1]} columns fit neither the channels nor the positions")
    weighted = (known & (weight > 0)).any(axis=0)  # a column at 0 wherever observed was not filtered
    lowest = np.ones((F, J))
    np.minimum.at(lowest, (slice(None), columns[weighted]), np.where(known, weight, 1.0)[:, weighted])
    return lowest < REJECT_WEIGHT, 1.0 - lowest


def disagreement_flags(points_cm: list[np.ndarray], skeleton: Skeleton) -> tuple[np.ndarray, np.ndarray]:
    """(flags (F, J) bool, spread (F, J) cm) of the ``disagree`` reason from two or more
    engines' joint positions ``points_cm`` ((F, J, 3) cm each): the spread is the
    distance of the farthest engine from their mean, root-aligned (the body root's
    position subtracted, as the scores are), and a joint is flagged where it exceeds
    :data:`DISAGREE_FLOOR_CM` and :data:`DISAGREE_SCALE` times its median over the take."""
    root = skeleton.body_root
    aligned = np.stack([p - p[:, root : root + 1] for p in points_cm])
    spread = np.linalg.norm(aligned - aligned.mean(0), axis=-1).max(0)
    return spread > np.maximum(DISAGREE_FLOOR_CM, DISAGREE_SCALE * np.median(spread, axis=0)), spread


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

    def with_evidence(
        self,
        observed: np.ndarray | None = None,
        robust_weights: Sequence[np.ndarray] = (),
        cleaned_points_cm: Sequence[np.ndarray] = (),
    ) -> Inspection:
        """This inspection with the reasons that need more than the motion, in place of
        any it had: ``missing`` where an ``observed`` mask (F, J) is given (the rules'
        flags on missing samples, which hold no data, are dropped), ``rejected`` for robust
        engines' ``robust_weights`` (:func:`rejected_flags`), ``disagree`` for two or more
        engines' cleaned joint positions (:func:`disagreement_flags`)."""
        flags = {r: f for r, f in self.flags.items() if r in RULES}
        scores = {r: s for r, s in self.scores.items() if r in RULES}
        shape = (self.motion.n_frames, self.motion.skeleton.n_joints)
        known = np.ones(shape, bool) if observed is None else np.asarray(observed, bool)
        found = {}
        if observed is not None:
            flags = {r: f & known for r, f in flags.items()}
            found["missing"] = ~known, (~known).astype(float)
        if len(robust_weights):
            each = [rejected_flags(self.motion.skeleton, known, w) for w in robust_weights]
            found["rejected"] = np.logical_or.reduce([f for f, _ in each]), np.maximum.reduce([s for _, s in each])
        if len(cleaned_points_cm) >= 2:
            found["disagree"] = disagreement_flags(list(cleaned_points_cm), self.motion.skeleton)
        return Inspection(
            self.motion, flags | {r: f for r, (f, _) in found.items()}, scores | {r: s for r, (_, s) in found.items()}
        )

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
RULES = {"spike": spike_flags, "turn": turn_flags, "jump": jump_flags, "linear": linear_flags, "bone": bone_flags}


#: the rules whose flags mark bad data, not bad motion: an engine should fill those samples
#: rather than trust them (``workbench clean --fill-suspects``); ``bone`` flags a stretch,
#: which is motion
FILL_REASONS = ("spike", "turn", "jump", "linear")


def suspects_missing(observation: Observation) -> Observation:
    """``observation`` with the samples the :data:`FILL_REASONS` rules flag on its
    observed samples missing too, so that an engine fills them rather than trusts them.
    The rules read the observation with its gaps bridged, as ``workbench inspect`` and the
    app do (a NaN would make a joint's median spike score NaN and hide its spikes)."""
    observed = observation.observed
    motion = observation.bridged() if observation.has_gaps else observation.motion
    suspects = np.logical_or.reduce([RULES[reason](motion)[0] for reason in FILL_REASONS]) & observed
    return Observation(observation.motion, observed & ~suspects, observation.capture_step)


def inspect_motion(
    motion: Motion,
    observed: np.ndarray | None = None,
    robust_weights: Sequence[np.ndarray] = (),
    cleaned_points_cm: Sequence[np.ndarray] = (),
) -> Inspection:
    """Run every rule on ``motion`` (a take as recorded: no ground truth needed), then add
    the reasons that need a mask or engines' results (:meth:`Inspection.with_evidence`)."""
    found = {reason: rule(motion) for reason, rule in RULES.items()}
    inspection = Inspection(motion, {r: f for r, (f, _) in found.items()}, {r: s for r, (_, s) in found.items()})
    return inspection.with_evidence(observed, robust_weights, cleaned_points_cm)
