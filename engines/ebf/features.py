"""Per-frame network inputs and window geometry shared by EBF, EBD, BF and NN (numpy only).

Units: angles in degrees, root angular velocity in degrees per second, time in frames.
``C`` is the number of joint-angle channels (``workbench.core.motion.angle_columns``: the
rotation channels of every joint but the root); the networks see those ``C`` channels,
unwrapped and normalised (or, for ``ebf:step_inputs=true``, their steps from the frame
before), plus the root's 3 angular velocities.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.core.motion import Motion, Observation, angle_columns
from workbench.core.rotations import euler_to_matrix
from workbench.core.skeleton import Skeleton
from workbench.engine.signal import bridge_gaps, euler_flips
from workbench.engine.smoothing import measurement_variance, smoothing_ratio

#: frames of look-back and of look-ahead of every window (Mall et al. §3, at 120 fps)
RADIUS = 15
#: the frame rate the family's settings counted in frames were chosen at (CMU's, Mall et
#: al.'s). The networks' window and velocity baseline are learnt at the weights' own rate
#: (the Bandai weights run at 30) and stay frame counts; the root's filter
#: (:func:`.root.filter_limits`) and ebd's ``smooth_hole_frames`` carry over by duration
REFERENCE_FPS = 120.0
#: frames over which the root's angular velocity is measured (1/15 s at 120 fps)
VELOCITY_BASELINE = 8
#: smallest per-feature std used for normalisation (degrees, or degrees per second)
STD_FLOOR = 1.0
#: frames normalised at a time by :func:`frame_data`: its temporaries stay in cache
FEATURE_BLOCK = 4096
#: range of :func:`noise_context` (natural log of a noise std in training stds)
NOISE_CONTEXT_RANGE = (-8.0, 2.0)
#: smallest std of a channel's frame-to-frame steps used for step inputs (degrees)
STEP_STD_FLOOR = 0.05
#: step inputs are clipped to this many step stds either way (a wrap or a flip at gimbal
#: lock, or a glitch, stays one bounded input; noise seldom reaches it: 0.2 % of the steps
#: of every third Bandai validation take under ``angular:0.5``, 0.9 % under ``angular:0.9``)
STEP_CLIP = 20.0


def root_angular_velocity_dps(
    root_angles_deg: np.ndarray, order: str, fps: float, baseline: int = VELOCITY_BASELINE
) -> np.ndarray:
    """(F, 3) angular velocity of the root in its own frame, degrees per second, averaged
    over the last ``baseline`` frames: :func:`rotation_rate_dps` from frame s = max(0, t -
    baseline) to t (0 at frame 0). Invariant to heading; the baseline keeps
    frame-to-frame jitter of a noisy root (spatial noise) from dominating."""
    R = euler_to_matrix(np.asarray(root_angles_deg, float), order)
    t = np.arange(R.shape[0])
    s = np.maximum(t - baseline, 0)
    return rotation_rate_dps(R[s], R, t - s, fps)


def rotation_rate_dps(R_from: np.ndarray, R_to: np.ndarray, frames: np.ndarray, fps: float) -> np.ndarray:
    """(..., 3) the rotation vector of ``R_from^T R_to`` (rotation matrices (..., 3, 3))
    in degrees, per second over ``frames`` (...) frames at ``fps`` (0 where ``frames`` is 0)."""
    R = np.einsum("...ji,...jk->...ik", R_from, R_to)
    twice_sin_axis = R[..., [2, 0, 1], [1, 2, 0]] - R[..., [1, 2, 0], [2, 0, 1]]
    twice_sin = np.linalg.norm(twice_sin_axis, axis=-1)
    angle = np.arctan2(twice_sin, np.trace(R, axis1=-2, axis2=-1) - 1.0)
    scale = np.where(twice_sin > 1e-12, angle / np.maximum(twice_sin, 1e-12), 0.5)
    return np.rad2deg(twice_sin_axis * scale[..., None]) * fps / np.maximum(frames, 1)[..., None]


@dataclass(frozen=True)
class Layout:
    """Where the networks' channels live in a skeleton's channel matrix (F, 3 + 3J)."""

    columns: np.ndarray  # (C,) angle columns
    root_order: str

    @classmethod
    def of(cls, skeleton: Skeleton) -> "Layout":
        return cls(angle_columns(skeleton), skeleton.rotation_order(0))

    @property
    def n_channels(self) -> int:
        return int(self.columns.size)

    def root_velocity(self, X: np.ndarray, fps: float) -> np.ndarray:
        """(F, 3) root angular velocity (deg/s) of a channel matrix X (F, D)."""
        return root_angular_velocity_dps(X[:, 3:6], self.root_order, fps)


def anchor_turns(angles_deg: np.ndarray, reference_deg: np.ndarray) -> np.ndarray:
    """Shift each unwrapped column of ``angles_deg`` (F, C) by the whole turns that bring
    its first frame nearest to ``reference_deg`` (C,), so a channel reads alike in every
    clip (and in a stream, which knows the first frame only)."""
    return angles_deg + 360.0 * np.round((reference_deg - angles_deg[:1]) / 360.0)


def circular_mean_deg(angles_deg: np.ndarray) -> np.ndarray:
    """(C,) circular mean of the columns of ``angles_deg`` (N, C), degrees."""
    a = np.deg2rad(angles_deg)
    return np.rad2deg(np.arctan2(np.sin(a).mean(axis=0), np.cos(a).mean(axis=0)))


@dataclass
class Normaliser:
    """Per-feature mean and std (floored at STD_FLOOR) of the clean training frames:
    C angle channels (degrees) then 3 root angular velocities (deg/s); and, for step
    inputs, ``step_std`` (C,): the std of each angle channel's frame-to-frame steps
    (degrees a frame at the training motions' rate, floored at STEP_STD_FLOOR), else None."""

    mean: np.ndarray
    std: np.ndarray
    step_std: np.ndarray | None = None

    @classmethod
    def fit(cls, motions: list[Motion], layout: Layout, steps: bool = False) -> "Normaliser":
        """The statistics of ``motions``; ``steps``: also their steps' ``step_std``."""
        X = [m.channels for m in motions]
        reference = circular_mean_deg(np.concatenate([x[:, layout.columns] for x in X]))
        feats = []
        for m, x in zip(motions, X):
            x[:, 3:] = np.unwrap(x[:, 3:], period=360.0, axis=0)
            ang = anchor_turns(x[:, layout.columns], reference)
            feats.append(np.concatenate([ang, layout.root_velocity(x, m.fps)], axis=1))
        F = np.concatenate(feats)
        step_std = None
        if steps:
            angle_steps = np.concatenate([np.diff(f[:, :-3], axis=0) for f in feats])
            step_std = np.maximum(angle_steps.std(axis=0), STEP_STD_FLOOR)
        return cls(F.mean(axis=0), np.maximum(F.std(axis=0), STD_FLOOR), step_std)

    @property
    def angle_mean(self) -> np.ndarray:
        return self.mean[:-3]

    @property
    def angle_std(self) -> np.ndarray:
        return self.std[:-3]

    def __call__(self, angles: np.ndarray, velocity: np.ndarray, before: np.ndarray) -> np.ndarray:
        """(N, C + 3) network inputs of N consecutive frames' ``angles`` (N, C) degrees and
        root ``velocity`` (N, 3) deg/s, given the angles of the frame ``before`` them (C,)
        (the first frame's own at a take's start; unused without ``step_std``): the angles
        normalised, or with ``step_std`` their steps from the frame before in step stds
        (clipped to ±STEP_CLIP), which do not depend on the pose; the velocity normalised."""
        if self.step_std is None:
            angle_inputs = (angles - self.angle_mean) / self.angle_std
        else:
            steps = np.diff(angles, axis=0, prepend=before[None])
            angle_inputs = np.clip(steps / self.step_std, -STEP_CLIP, STEP_CLIP)
        return np.concatenate([angle_inputs, (velocity - self.mean[-3:]) / self.std[-3:]], axis=1)


@dataclass
class FrameData:
    """An observation made ready for a network. X: (F, D) channel matrix, gaps bridged
    linearly, angles unwrapped and anchored; values: (F, C) its angle channels (degrees);
    inputs: (F, n_in) normalised network inputs; missing: (F, C) missing angle samples."""

    X: np.ndarray
    values: np.ndarray
    inputs: np.ndarray
    missing: np.ndarray

    @property
    def n_frames(self) -> int:
        return self.X.shape[0]


def noise_context(
    values: np.ndarray, observed: np.ndarray, norm: Normaliser, variance: np.ndarray | None = None
) -> np.ndarray:
    """(C,) the take's own noise level per angle channel: the natural log of its white-noise
    std (``variance`` (C,) deg^2, by default
    :func:`workbench.engine.smoothing.measurement_variance`, from the observed samples'
    second differences over the whole take) in training stds of the channel, clipped to
    :data:`NOISE_CONTEXT_RANGE`. ``values`` (F, C) degrees, ``observed`` (F, C)."""
    r = measurement_variance(values, observed) if variance is None else variance
    return np.clip(np.log(np.sqrt(r) / norm.angle_std), *NOISE_CONTEXT_RANGE)


def smoothing_context(values: np.ndarray, observed: np.ndarray, variance: np.ndarray) -> np.ndarray:
    """(C,) how much the take wants smoothing per angle channel: the natural log of the
    width in frames, ``lambda^(1/4)``, of the constant-velocity smoother whose
    ``lambda = r / q`` kalman would choose for the whole channel
    (:func:`workbench.engine.smoothing.smoothing_ratio`: Stein's risk estimate on its
    periodogram, given its noise ``variance`` (C,) deg^2). Fast motion under little noise
    wants a narrow filter, slow motion under much noise a wide one; a 31-frame window
    cannot tell which it sees, the whole take can. ``values`` (F, C) degrees (gaps
    bridged), ``observed`` (F, C)."""
    return np.log(smoothing_ratio(values, variance, observed.mean(axis=0))) / 4.0


def frame_data(
    observation: Observation,
    layout: Layout,
    norm: Normaliser,
    with_mask: bool,
    with_noise: bool = False,
    with_smoothing: bool = False,
) -> FrameData:
    """Network inputs of an observation: its angle channels and root angular velocity as
    ``norm`` makes them inputs (:meth:`Normaliser.__call__`), plus (``with_mask``, EBD) the
    observed mask of the angle channels (0/1), plus (``with_noise``) the take's
    :func:`noise_context` and (``with_smoothing``) its :func:`smoothing_context`, each the
    same on every frame."""
    X = bridge_gaps(observation)
    values = anchor_turns(X[:, layout.columns], norm.angle_mean)
    X[:, layout.columns] = values
    seen = values  # what the network sees: the take's own triples, as it learnt them (jumps at gimbal lock too)
    if euler_flips(observation) is not None:  # the values filtered are continued through the lock
        seen = anchor_turns(bridge_gaps(observation, through_lock=False)[:, layout.columns], norm.angle_mean)
    missing = ~observation.channel_observed[:, layout.columns]
    F, C = values.shape
    n_context = (C if with_noise else 0) + (C if with_smoothing else 0)
    inputs = np.empty((F, C + 3 + (C if with_mask else 0) + n_context), np.float32)
    velocity = layout.root_velocity(X, observation.motion.fps)
    for start in range(0, F, FEATURE_BLOCK):  # float64 arithmetic, float32 kept: no whole-take temporaries
        block = slice(start, start + FEATURE_BLOCK)
        inputs[block, : C + 3] = norm(seen[block], velocity[block], seen[max(start - 1, 0)])
    if with_mask:
        inputs[:, C + 3 : 2 * C + 3] = ~missing
    if n_context:
        r = measurement_variance(values, ~missing)
        contexts = [noise_context(values, ~missing, norm, r)] if with_noise else []
        contexts += [smoothing_context(values, ~missing, r)] if with_smoothing else []
        inputs[:, -n_context:] = np.concatenate(contexts)
    return FrameData(X, values, inputs, missing)


def window_offsets(radius: int = RADIUS, stride: int = 1) -> np.ndarray:
    """(2 radius + 1,) frame offsets of a window's frames from its centre frame."""
    return stride * np.arange(-radius, radius + 1)


def window_index(
    centres: np.ndarray, n_frames: int, radius: int = RADIUS, stride: int = 1
) -> tuple[np.ndarray, np.ndarray]:
    """Frame indices (N, L) of the windows around ``centres`` (N,), clamped into the clip
    (edge frames repeat: the padding used for network inputs), and ``valid`` (N, L):
    the window frame exists (only those enter a filter)."""
    idx = np.asarray(centres)[:, None] + window_offsets(radius, stride)[None, :]
    valid = (idx >= 0) & (idx < n_frames)
    return np.clip(idx, 0, n_frames - 1), valid
