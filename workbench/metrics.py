"""Pure metric functions comparing a cleaned (or noisy) Motion with the truth.

Units are in the names: ``_deg`` degrees, ``_cm`` centimetres (file units times
``skeleton.unit_cm``). Angle errors are wrap-safe (differences taken modulo 360).
"Joint-angle channels" are the rotation channels of every joint but the root
(:func:`workbench.core.motion.angle_columns`), as scored by Mall et al.; position errors
are root-aligned (the root position is subtracted from every joint, per frame), as in
Kaufmann et al. "The root" is the body's: ``skeleton.body_root``, the joint the root
chain ends at, which is the file's root in the CMU sets and the Hips that a studio
export's reference node ``joint_Root`` carries. The root chain's rotations are not
joint-angle channels, and the position scores average over the body (:func:`body_joints`:
the body root and the joints below it), not over a reference node above it, whose
root-aligned position is only the trajectory turned round. Translations are scored
through the positions they move.
"""

from __future__ import annotations

import numpy as np

from .core.motion import Motion, angle_columns, angle_joints, position_unknown
from .core.rotations import wrap_deg


def _check(truth: Motion, estimate: Motion) -> None:
    if not truth.skeleton.same_layout(estimate.skeleton):
        raise ValueError("metrics need two motions of the same skeleton layout")
    if truth.n_frames != estimate.n_frames:
        raise ValueError(f"frame counts differ: truth {truth.n_frames}, estimate {estimate.n_frames}")


def angle_error_deg(truth: Motion, estimate: Motion) -> np.ndarray:
    """(F, C) signed wrap-safe errors of the joint-angle channels, in degrees."""
    _check(truth, estimate)
    cols = angle_columns(truth.skeleton)
    return wrap_deg(estimate.channels[:, cols] - truth.channels[:, cols])


def rms_angle_deg_per_frame(truth: Motion, estimate: Motion) -> np.ndarray:
    """(F,) RMS over all joint-angle channels at each frame (Mall et al.'s Fig. 4 curve)."""
    return np.sqrt(np.mean(angle_error_deg(truth, estimate) ** 2, axis=1))


def rms_angle_deg(truth: Motion, estimate: Motion) -> float:
    """Mean over frames of the per-frame RMS joint-angle error (Mall et al.'s figure)."""
    return float(np.mean(rms_angle_deg_per_frame(truth, estimate)))


def body_joints(skeleton) -> np.ndarray:
    """Indices of the joints the position scores average over: all but those of the root
    chain above the body root (every joint in the CMU sets)."""
    return np.setdiff1d(np.arange(skeleton.n_joints), skeleton.root_chain[:-1])


def joint_position_error_cm(truth: Motion, estimate: Motion) -> np.ndarray:
    """(F, J) Euclidean joint position errors in cm: root-aligned for the body joints, in
    world space for the root chain's joints above the body root (a reference node)."""
    _check(truth, estimate)
    root, above = truth.skeleton.body_root, list(truth.skeleton.root_chain[:-1])
    t = truth.positions - truth.positions[:, root : root + 1]
    e = estimate.positions - estimate.positions[:, root : root + 1]
    t[:, above], e[:, above] = truth.positions[:, above], estimate.positions[:, above]
    return np.linalg.norm(e - t, axis=2) * truth.skeleton.unit_cm


def mpjpe_cm(truth: Motion, estimate: Motion) -> float:
    """Mean per-joint position error over the body joints, root-aligned, in cm (Kaufmann
    et al.)."""
    return float(np.mean(joint_position_error_cm(truth, estimate)[:, body_joints(truth.skeleton)]))


def root_cm(truth: Motion, estimate: Motion) -> float:
    """Mean distance of the (body's) root joint from the truth's, in cm, in world space:
    the trajectory, which the root-aligned scores do not see."""
    _check(truth, estimate)
    root = truth.skeleton.body_root
    return float(
        np.mean(np.linalg.norm(estimate.positions[:, root] - truth.positions[:, root], axis=1)) * truth.skeleton.unit_cm
    )


def gap_mpjpe_cm(truth: Motion, estimate: Motion, observed: np.ndarray) -> float:
    """Root-aligned mean joint position error, in cm, over the positions that depend on
    missing data (observed (F, J) False): each (frame, joint) whose root or ancestor is
    missing there, or itself when it is translated
    (:func:`~workbench.core.motion.position_unknown`), among the body joints. A joint's
    missing angles move its children, so those are the positions that test a fill. NaN when
    nothing is missing or no position depends on what is (a missing leaf joint: see
    ``rms_angle_deg``)."""
    unknown = position_unknown(observed, truth.skeleton.parents, truth.skeleton.translated)
    unknown[:, list(truth.skeleton.root_chain[:-1])] = False
    if not unknown.any():
        return float("nan")
    return float(np.mean(joint_position_error_cm(truth, estimate)[unknown]))


def bone_lengths(positions: np.ndarray, parents) -> np.ndarray:
    """(F, J-1) length of every bone (parent to child, in joint order after the root),
    in the units of ``positions`` (F, J, 3). Works on raw network output too."""
    pairs = [(p, j) for j, p in enumerate(parents) if p >= 0]
    par = np.array([p for p, _ in pairs])
    child = np.array([j for _, j in pairs])
    return np.linalg.norm(positions[:, child] - positions[:, par], axis=2)


def bone_length_stats_cm(positions: np.ndarray, motion_like: Motion) -> dict[str, np.ndarray]:
    """Per-bone mean and standard deviation (cm) over time of bone lengths measured on
    ``positions`` (F, J, 3) in ``motion_like``'s skeleton units. Keys: ``mean``, ``std``
    (each (J-1,)), ``bones`` (J-1, 2) parent/child indices."""
    lengths = bone_lengths(positions, motion_like.skeleton.parents) * motion_like.skeleton.unit_cm
    return {
        "mean": lengths.mean(axis=0),
        "std": lengths.std(axis=0),
        "bones": np.array(motion_like.skeleton.bones),
    }


def jitter_cm_s3(motion: Motion) -> float:
    """Mean magnitude of the jerk (third time derivative) of the body joints' root-aligned
    positions, in cm/s^3: high for jittery motion, low for smooth motion."""
    if motion.n_frames < 4:
        return float("nan")
    root, body = motion.skeleton.body_root, body_joints(motion.skeleton)
    p = (motion.positions[:, body] - motion.positions[:, root : root + 1]) * motion.skeleton.unit_cm
    jerk = np.diff(p, n=3, axis=0) * motion.fps**3
    return float(np.mean(np.linalg.norm(jerk, axis=2)))


#: the names :func:`score` returns, in the order of the benchmark's tables
METRICS = ("rms_angle_deg", "mpjpe_cm", "gap_mpjpe_cm", "root_cm", "jitter_cm_s3")
#: the metrics :func:`per_joint` splits by joint
JOINT_METRICS = ("rms_angle_deg", "mpjpe_cm", "gap_mpjpe_cm")


def score(truth: Motion, estimate: Motion, observed: np.ndarray | None = None) -> dict[str, float]:
    """The headline numbers of one result: rms_angle_deg, mpjpe_cm, gap_mpjpe_cm (only
    when ``observed`` has missing entries), root_cm and jitter_cm_s3."""
    out = {
        "rms_angle_deg": rms_angle_deg(truth, estimate),
        "mpjpe_cm": mpjpe_cm(truth, estimate),
        "root_cm": root_cm(truth, estimate),
        "jitter_cm_s3": jitter_cm_s3(estimate),
    }
    if observed is not None and not np.asarray(observed, bool).all():
        out["gap_mpjpe_cm"] = gap_mpjpe_cm(truth, estimate, observed)
    return out


def per_joint(truth: Motion, estimate: Motion, observed: np.ndarray | None = None) -> dict[str, dict[str, float]]:
    """The :data:`JOINT_METRICS` of one result by joint name: ``rms_angle_deg``, the RMS
    error of the joint's joint-angle channels over all frames (the joints of
    :func:`~workbench.core.motion.angle_joints`); ``mpjpe_cm``, the joint's mean
    root-aligned position error (the :func:`body_joints` but the body root, which is
    always 0); and, when ``observed`` (F, J) has missing entries, ``gap_mpjpe_cm``, that
    error over the frames where the joint's position depends on missing data (as
    :func:`gap_mpjpe_cm` counts them; NaN for a joint with none). Shows where the
    headline numbers come from: a joint near gimbal lock, a hand on a short lever."""
    names = truth.skeleton.names
    joints = angle_joints(truth.skeleton)
    square = angle_error_deg(truth, estimate).reshape(truth.n_frames, joints.size, 3) ** 2
    error = joint_position_error_cm(truth, estimate)
    moving = [j for j in body_joints(truth.skeleton) if j != truth.skeleton.body_root]
    out = {
        "rms_angle_deg": {names[j]: float(v) for j, v in zip(joints, np.sqrt(square.mean(axis=(0, 2))))},
        "mpjpe_cm": {names[j]: float(error[:, j].mean()) for j in moving},
    }
    if observed is not None and not np.asarray(observed, bool).all():
        unknown = position_unknown(observed, truth.skeleton.parents, truth.skeleton.translated)
        out["gap_mpjpe_cm"] = {
            names[j]: float(error[unknown[:, j], j].mean()) if unknown[:, j].any() else float("nan") for j in moving
        }
    return out
