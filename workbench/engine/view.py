"""A take as a trained engine sees it: rooted at the body, at the rate its model runs at.

Trained engines model a body whose first joint is its root (the pelvis, with the take's
trajectory in its position channels), sampled at one frame rate. Studio takes differ in
both ways: a MotionBuilder export carries the body on a reference node (``joint_Root``
moves the translated ``Hips``), and Bandai's are 30 fps where CMU's are 120. Rather
than teach every engine both, the engine layer shows each one the same kind of take and
puts the result back (:class:`ModelView`):

- **Body view** (:func:`body_skeleton`, :func:`to_body`): the joints of the skeleton's
  :attr:`~workbench.core.skeleton.Skeleton.root_chain` collapse into its last, the body
  root, which becomes the root: its world position and rotation are the root channels.
  The result is back in the take's skeleton with the reference joints above the body
  root as observed (gaps bridged) and the body root's local transform under them
  (:func:`from_body`). A skeleton whose root is the body root is its own body view.
- **Rigid bones** (:func:`stretchy_joints`): a joint below the body root whose position
  channels vary (Perception Neuron's displacement export, a stretchy rig) is modelled
  as a rigid bone of its median length over the take, and its translation comes back
  as observed (gaps bridged): the engines clean the angles, not the stretch.
- **Upright** (:mod:`workbench.core.upright`): a take whose head stands above its feet
  along another axis than +Y (a Z-up export) is turned onto +Y by relabelling axes,
  exactly, and turned back after: the models' headings and floors are about Y.
- **Rate** (:func:`resample`): channels are resampled linearly in time (angles
  unwrapped) to the model's rate, and the result back to the take's frames. A resampled
  frame is observed where both take frames around it are. At a whole ratio (30 to 120
  fps) every take frame is a model frame, so nothing observed is blurred. The frames in
  between are interpolated, not measured: the view's ``capture_step`` (4 from 30 to 120
  fps) has the engines measure the take's noise on the captured frames (an estimate from
  all of them would find next to none, and a 30-fps take would not be smoothed at all).

Units: frame rates in frames per second; diagnostics whose names end in ``_frames``
count frames and are rescaled to the take's frames on the way back.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..core.channels import interpolate_frames, known_at, unwrap_deg
from ..core.motion import Motion, Observation, angle_slice, body_position_column, channel_count
from ..core.rotations import euler_to_matrix, matrix_to_euler, nearest_euler
from ..core.skeleton import POSITION_CHANNELS, Skeleton
from ..core.upright import turn_motion, turn_skeleton, turn_vectors
from .base import CleanResult, EngineError
from .signal import rewrap_angles

__all__ = [
    "body_skeleton",
    "body_joints",
    "stretchy_joints",
    "to_body",
    "from_body",
    "model_skeleton",
    "model_motion",
    "resample",
    "ModelView",
]

#: frame rates closer than this are the same rate
SAME_FPS = 1e-6
#: the body root's rotation channels where the skeleton turns the body above it only
ZYX_ROTATION = ("Zrotation", "Yrotation", "Xrotation")


def body_joints(skeleton: Skeleton) -> np.ndarray:
    """(J_b,) the joints of the body view, in the skeleton's order: the body root and
    every joint below it (all joints when the root is the body root). They are the
    joints from the body root on: each joint of the chain above has one child, and
    parents come before their children."""
    return np.arange(skeleton.body_root, skeleton.n_joints)


def stretchy_joints(skeleton: Skeleton) -> tuple[int, ...]:
    """The translated joints below the body root: bones whose length the take animates."""
    return tuple(j for j in skeleton.translated if j > skeleton.body_root)


def body_skeleton(skeleton: Skeleton) -> Skeleton:
    """The skeleton a trained engine models: the body root as root, with position and
    rotation channels, and every bone rigid (:func:`stretchy_joints` untranslated, at
    their OFFSET lines until :func:`to_body` gives them a take's median); the skeleton
    itself when its root is its body root and no bone stretches."""
    b, stretchy = skeleton.body_root, stretchy_joints(skeleton)
    if b == 0:
        if not stretchy:
            return skeleton
        offsets = skeleton.offsets.copy()
        offsets[list(stretchy)] = skeleton.file_offsets[list(stretchy)]
        return skeleton.replace(offsets=offsets, translated=())
    keep = body_joints(skeleton)
    rotations = tuple(c for c in skeleton.channels[b] if c not in POSITION_CHANNELS) or ZYX_ROTATION
    offsets = np.where(
        np.isin(np.arange(skeleton.n_joints), stretchy)[:, None], skeleton.file_offsets, skeleton.offsets
    )
    offsets = offsets[keep]
    offsets[0] = 0.0
    return Skeleton(
        names=tuple(skeleton.names[j] for j in keep),
        parents=(-1,) + tuple(skeleton.parents[j] - b for j in keep[1:]),
        offsets=offsets,
        channels=(POSITION_CHANNELS + rotations,) + tuple(skeleton.channels[j] for j in keep[1:]),
        end_sites=tuple((p - b, off) for p, off in skeleton.end_sites if p >= b),
        unit_cm=skeleton.unit_cm,
    )


def to_body(motion: Motion, body: Skeleton | None = None) -> Motion:
    """``motion`` in its :func:`body_skeleton` (given as ``body`` if the caller has it):
    the body root's world position and rotation as root channels, the other joints'
    angles as they are, each stretchy bone rigid at its median translation over the
    take. NaN where the chain above is NaN. The motion itself when it is its own body
    view."""
    skeleton = motion.skeleton
    b, stretchy = skeleton.body_root, stretchy_joints(skeleton)
    body = body_skeleton(skeleton) if body is None else body
    if body is skeleton:
        return motion
    if stretchy:
        offsets = body.offsets.copy()
        moving = [skeleton.translated.index(j) for j in stretchy]
        offsets[np.array(stretchy) - b] = np.nan_to_num(np.nanmedian(motion.translations[:, moving], axis=0))
        body = body.replace(offsets=offsets)
    if b == 0:
        return Motion(body, motion.fps, motion.root_positions, motion.angles_deg, motion.name)
    P, R = motion.positions[:, b], motion.global_rotations[:, b]  # the body root in the world
    angles = motion.angles_deg[:, body_joints(skeleton)].copy()
    finite = np.isfinite(R).all(axis=(1, 2))
    world = np.full((motion.n_frames, 3), np.nan)
    world[finite] = matrix_to_euler(R[finite], body.rotation_order(0))
    angles[:, 0] = np.where(np.isfinite(angles[:, 0]), nearest_euler(world, np.nan_to_num(angles[:, 0])), world)
    return Motion(body, motion.fps, P, angles, motion.name)


def from_body(motion: Motion, carrier: Motion) -> Motion:
    """A body-view motion back in the take's skeleton: the joints above the body root and
    the stretchy bones' translations as in ``carrier`` (the take's motion, finite: an
    observation bridged), the body root's local rotation and translation placing it
    where ``motion`` has it, the other joints' angles from ``motion``. ``motion`` itself
    when the take is its own body view."""
    skeleton = carrier.skeleton
    b = skeleton.body_root
    if motion.skeleton is skeleton:
        return motion
    if b == 0:
        return carrier.replace(root_positions=motion.root_positions, angles_deg=motion.angles_deg)
    parent = skeleton.parents[b]
    P_parent, R_parent = carrier.positions[:, parent], carrier.global_rotations[:, parent]
    R_body = euler_to_matrix(motion.angles_deg[:, 0], motion.skeleton.rotation_order(0))
    local = np.swapaxes(R_parent, 1, 2) @ R_body
    translation = np.einsum("fji,fj->fi", R_parent, motion.root_positions - P_parent)
    angles = carrier.angles_deg.copy()
    angles[:, b] = nearest_euler(matrix_to_euler(local, skeleton.rotation_order(b)), carrier.angles_deg[:, b])
    angles[:, b + 1 :] = motion.angles_deg[:, 1:]
    translations = carrier.translations.copy()
    translations[:, skeleton.translated.index(b)] = translation
    return carrier.replace(angles_deg=angles, translations=translations)


def model_skeleton(skeleton: Skeleton, turn: np.ndarray | None) -> Skeleton:
    """The skeleton a trained engine models a take of ``skeleton`` in: its
    :func:`body_skeleton`, turned by ``turn`` (:func:`workbench.core.upright.up_turn`)
    where the take is not upright."""
    body = body_skeleton(skeleton)
    return body if turn is None else turn_skeleton(body, turn)


def model_motion(motion: Motion, turn: np.ndarray | None) -> Motion:
    """A training take as a trained engine models it: in its body view, upright (turned
    by ``turn``, :func:`workbench.core.upright.up_turn`), at its own rate (the caller
    resamples)."""
    body = to_body(motion)
    return body if turn is None else turn_motion(body, turn)


def _unwrapped(motion: Motion) -> np.ndarray:
    X = motion.channels
    angles = angle_slice(motion.skeleton)
    X[:, angles] = unwrap_deg(X[:, angles])
    return X


#: the most frames a take may be resampled to (9 hours at 120 fps), and the most a rate
#: may be raised (a take at 1 fps, as a Blender export that left its frame time at 1 s,
#: into a 120-fps engine): a take whose frame time is off by orders of magnitude (100 s a
#: frame) would fill the memory instead
MAX_RESAMPLED_FRAMES, MAX_RATE_RAISE = 4_000_000, 120.0


def resampled_frames(n_from: int, fps_from: float, fps_to: float) -> int:
    """How many frames ``n_from`` frames at ``fps_from`` become at ``fps_to`` (:func:`frame_times`)."""
    return int(np.ceil((n_from - 1) * fps_to / fps_from - 1e-9)) + 1


def frame_times(n_from: int, fps_from: float, fps_to: float) -> np.ndarray:
    """Times of the frames of a take resampled from ``fps_from`` to ``fps_to``, in frames
    of the original: every ``fps_from / fps_to`` frames from its first, and one at its
    last frame where that step does not land on it (so the end is kept). Raises
    EngineError for more than :data:`MAX_RESAMPLED_FRAMES`, or a rate raised more than
    :data:`MAX_RATE_RAISE` times."""
    n = resampled_frames(n_from, fps_from, fps_to)
    if n > MAX_RESAMPLED_FRAMES or (n > n_from and fps_to > MAX_RATE_RAISE * fps_from):
        raise EngineError(
            f"resampling the take's {n_from:,} frames from {fps_from:g} to {fps_to:g} fps would make {n:,} "
            f"(at most {MAX_RESAMPLED_FRAMES:,}, at a rate raised at most {MAX_RATE_RAISE:g}-fold): if its "
            f"Frame Time ({1 / fps_from:g} s) is wrong, mend that line"
        )
    return np.minimum(np.arange(n) * (fps_from / fps_to), n_from - 1)


def resample(motion: Motion, fps: float) -> Motion:
    """A finite ``motion`` resampled linearly to ``fps`` (angles unwrapped first), from its
    first frame to its last: ``ceil((F - 1) fps / motion.fps) + 1`` frames, the last one
    nearer its neighbour where the rates' ratio is not whole. The motion itself at its
    own rate or with one frame."""
    if abs(motion.fps - fps) <= SAME_FPS:
        return motion
    if motion.n_frames < 2:
        return motion.replace(fps=fps)
    t = frame_times(motion.n_frames, motion.fps, fps)
    return motion.replace(fps=fps).with_channels(interpolate_frames(_unwrapped(motion), t))


def _resample_frames(A: np.ndarray, t: np.ndarray) -> np.ndarray:
    return A[np.round(t).astype(int)] if A.shape[0] < 2 else interpolate_frames(A, t)


@dataclass(frozen=True)
class ModelView:
    """An observation as a trained engine sees it, and the way back (:meth:`restore`).

    Attributes
    ----------
    source : Observation
        The take as given.
    observation : Observation
        The take in its body view (:func:`body_skeleton`), upright, at the model's rate
        ``fps``; resampled up, its ``capture_step`` says how many of its frames a
        captured one spans.
    bridged : Motion or None
        The take with its gaps bridged (:meth:`Observation.bridged`), made once where a
        way needs it (resampling there, the joints above the body root and the stretchy
        bones' translations back); else None.
    turn : numpy.ndarray or None
        The turn (3, 3) that stood the take on +Y (:func:`workbench.core.upright.up_turn`);
        None for a take standing on +Y.
    """

    source: Observation
    observation: Observation
    bridged: Motion | None = field(default=None, repr=False)
    turn: np.ndarray | None = field(default=None, repr=False)

    @classmethod
    def of(cls, source: Observation, fps: float, turn: np.ndarray | None = None) -> "ModelView":
        """The view of ``source`` at ``fps``, turned by ``turn`` (the take's
        :func:`~workbench.core.upright.up_turn`, which the caller has found; None: upright)."""
        skeleton = source.skeleton
        body = body_skeleton(skeleton)
        interpolated = abs(source.motion.fps - fps) > SAME_FPS and source.n_frames >= 2
        bridged = source.bridged() if interpolated or body is not skeleton else None
        observed = source.observed[:, body_joints(skeleton)].copy()
        observed[:, 0] = source.observed[:, list(skeleton.root_chain)].all(axis=1)
        step = max(source.capture_step * fps / source.motion.fps, 1.0) if interpolated else source.capture_step
        view = to_body(bridged if interpolated else source.motion, body)
        if turn is not None:
            view = turn_motion(view, turn)
        if interpolated:
            t = frame_times(source.n_frames, source.motion.fps, fps)
            observed = known_at(observed, t)
        view = resample(view, fps)  # without interpolation, at most a new rate for one frame
        return cls(source, Observation(view, observed, step), bridged, turn)

    def joint(self, j: int) -> int:
        """The view's index of the take's joint ``j`` (the body root or below it)."""
        b = self.source.skeleton.body_root
        if j < b:
            raise EngineError(f"joint {self.source.skeleton.names[j]!r} is above the body root; no engine models it")
        return j - b

    def frames(self, frames: np.ndarray) -> np.ndarray:
        """The view's frames (n,) nearest the take's ``frames`` (n,)."""
        scale = self.observation.motion.fps / self.source.motion.fps
        return np.minimum(np.round(np.asarray(frames) * scale).astype(int), self.observation.n_frames - 1)

    @property
    def changed(self) -> bool:
        """The view differs from the take: another skeleton (its body view, or turned
        upright) or another rate."""
        view, source = self.observation, self.source
        return view.skeleton is not source.skeleton or abs(view.motion.fps - source.motion.fps) > SAME_FPS

    def restore(self, result: CleanResult, keep_observed: bool = False) -> CleanResult:
        """A result on the view back on the take: its frames, its skeleton, its rate.

        The motion is resampled to the take's frames and put back in its skeleton
        (:func:`from_body`, the joints above the body root as observed, gaps bridged);
        with ``keep_observed`` the take's observed samples are put back exactly (angles
        on the result's branch), as an engine that keeps them promises. Each diagnostic
        (F_view, ...) is resampled along frames; one over the view's channel matrix
        (F, D_view) or its joints (F, J_view, ...) is spread over the take's, zero where
        the view has no counterpart; one named ``*_frames`` is rescaled to take frames,
        and one of a view turned upright is turned back (:meth:`_unturned`).
        """
        if not self.changed:
            return result
        source, view = self.source, self.observation
        fps_view, fps_take = view.motion.fps, source.motion.fps
        motion, t = result.motion.replace(fps=fps_take), None  # t: the take's frames in view frames
        if view.n_frames != source.n_frames:  # else the same frames: no resampling, no roundoff
            t = np.interp(
                np.arange(source.n_frames), frame_times(source.n_frames, fps_take, fps_view), np.arange(view.n_frames)
            )
            motion = motion.with_channels(_resample_frames(_unwrapped(result.motion), t))
        if self.turn is not None:
            motion = turn_motion(motion, self.turn.T, body_skeleton(source.skeleton))
        if self.bridged is not None:  # (the motion as it is where the take is its own body view)
            motion = from_body(motion, self.bridged)
        X = rewrap_angles(motion.channels, source, copy=False)
        if keep_observed:
            mask = source.channel_observed
            X[mask] = source.motion.channels[mask]
        motion = motion.with_channels(X)
        diagnostics = {}
        for name, value in result.diagnostics.items():
            value = np.asarray(value, float)
            value = self._unturned(name, value if t is None else _resample_frames(value, t))
            if name.endswith("_frames"):
                value = value * (fps_take / fps_view)
            diagnostics[name] = self._spread(value)
        return CleanResult(motion, diagnostics)

    def _unturned(self, name: str, value: np.ndarray) -> np.ndarray:
        """A diagnostic of the upright view in the take's axes: one named ``*_positions``
        (world positions (..., 3)) turned back; one over the view's channel matrix (F, D)
        with the columns of its lengths (root position, translations) put back in the
        take's axes, unsigned (a width or a weight per channel); any other as it is
        (joints and angles keep their places when turned)."""
        if self.turn is None:
            return value
        if name.endswith("_positions"):
            return turn_vectors(value, self.turn.T)
        body = self.observation.skeleton
        if value.ndim != 2 or value.shape[1] != channel_count(body):
            return value
        value = value.copy()
        for c in np.r_[0:3, angle_slice(body).stop : value.shape[1]].reshape(-1, 3):
            value[:, c] = turn_vectors(value[:, c], np.abs(self.turn.T))
        return value

    def _spread(self, value: np.ndarray) -> np.ndarray:
        """A diagnostic over the view's channels, joints or joints' positions (F, 3J'), over
        the take's (zero for the joints above the body root and the stretchy bones'
        translations)."""
        skeleton, body = self.source.skeleton, self.observation.skeleton
        b, F = skeleton.body_root, value.shape[0]
        if b == 0 and channel_count(body) == channel_count(skeleton):  # the take's joints and channels, in place
            return value
        if value.ndim >= 2 and value.shape[1] == body.n_joints:
            out = np.zeros((F, skeleton.n_joints) + value.shape[2:])
            out[:, body_joints(skeleton)] = value
            return out
        if value.ndim == 2 and value.shape[1] == 3 * body.n_joints:  # x, y, z of each joint
            out = np.zeros((F, skeleton.n_joints, 3))
            out[:, body_joints(skeleton)] = value.reshape(F, body.n_joints, 3)
            return out.reshape(F, -1)
        if value.ndim == 2 and value.shape[1] == channel_count(body):
            out = np.zeros((F, channel_count(skeleton)))
            t0 = body_position_column(skeleton)
            out[:, t0 : t0 + 3] = value[:, :3]
            out[:, 3 + 3 * b : 3 + 3 * skeleton.n_joints] = value[:, 3 : 3 + 3 * body.n_joints]
            return out
        return value
