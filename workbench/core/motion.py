"""Motion, Observation and Case: the data every layer passes around.

Units: root positions and translations in the skeleton's file unit (``skeleton.unit_cm``
cm each); joint angles in degrees, per joint in that joint's Euler order
(``skeleton.rotation_order(j)``); time in frames at ``fps`` frames per second.

The *channel matrix* (``Motion.channels``) is the flat (F, D) view engines filter:
``D = 3 + 3 J + 3 T``, the root position first, then each joint's three Euler angles in
file order (:func:`angle_slice`), then the local translation of each of the T
``skeleton.translated`` joints (none in the CMU sets; a studio export's moving Hips).
``angle_columns`` selects the joint-angle channels the papers score (every joint but those
of the root chain, whose motion, the body's trajectory, they treat as clean).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from .skeleton import Skeleton


def _frozen(a: np.ndarray) -> np.ndarray:
    """``a`` as a read-only float array of its own: ``a`` itself where it already is one
    (another Motion's: motions made from one share what they do not change, a long
    take's 50 MB channels are not copied for each view of it), else a copy."""
    if isinstance(a, np.ndarray) and a.dtype == np.float64 and a.base is None and not a.flags.writeable:
        return a
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class Motion:
    """A take: skeleton, fps, root positions (F, 3), joint Euler angles (F, J, 3) in
    degrees and the local translations (F, T, 3) of the skeleton's T ``translated`` joints
    (default: none, for a skeleton without them).

    Arrays are read-only (shared, not copied, where they already are read-only float64
    arrays of their own). Compare with :meth:`allclose`. Missing values are NaN
    (only in an :class:`Observation`).
    """

    skeleton: Skeleton
    fps: float
    root_positions: np.ndarray
    angles_deg: np.ndarray
    name: str = ""
    translations: np.ndarray | None = None

    def __post_init__(self) -> None:
        root = _frozen(self.root_positions)
        ang = _frozen(self.angles_deg)
        J, T = self.skeleton.n_joints, len(self.skeleton.translated)
        if root.ndim != 2 or root.shape[1] != 3:
            raise ValueError(f"root_positions must be (F, 3), got {root.shape}")
        if ang.shape != (root.shape[0], J, 3):
            raise ValueError(f"angles_deg must be (F, {J}, 3) to match root_positions, got {ang.shape}")
        if self.translations is None and T:
            raise ValueError(f"the skeleton has {T} translated joints: translations (F, {T}, 3) are needed")
        trans = _frozen(np.zeros((root.shape[0], 0, 3)) if self.translations is None else self.translations)
        if trans.shape != (root.shape[0], T, 3):
            raise ValueError(f"translations must be (F, {T}, 3) to match root_positions, got {trans.shape}")
        if not self.fps > 0:
            raise ValueError(f"fps must be positive, got {self.fps}")
        object.__setattr__(self, "root_positions", root)
        object.__setattr__(self, "angles_deg", ang)
        object.__setattr__(self, "translations", trans)

    @property
    def n_frames(self) -> int:
        return self.root_positions.shape[0]

    @property
    def duration_s(self) -> float:
        return self.n_frames / self.fps

    # -- kinematics (cached) --------------------------------------------------------
    @cached_property
    def _kinematics(self) -> tuple[np.ndarray, np.ndarray]:
        """Forward kinematics, once per motion: (positions, world rotations), read-only."""
        from .kinematics import forward_kinematics

        P, R = forward_kinematics(self.skeleton, self.root_positions, self.angles_deg, self.translations)
        for a in (P, R):
            a.setflags(write=False)
        return P, R

    @property
    def global_rotations(self) -> np.ndarray:
        """(F, J, 3, 3) world rotation of each joint (read-only)."""
        return self._kinematics[1]

    @property
    def positions(self) -> np.ndarray:
        """(F, J, 3) world joint positions in file units (read-only)."""
        return self._kinematics[0]

    def end_site_positions(self) -> np.ndarray:
        """(F, E, 3) world positions of the End Sites."""
        if not self.skeleton.end_sites:
            return np.zeros((self.n_frames, 0, 3))
        parents = [p for p, _ in self.skeleton.end_sites]
        offs = np.array([o for _, o in self.skeleton.end_sites])
        R = self.global_rotations[:, parents]
        return self.positions[:, parents] + np.einsum("feij,ej->fei", R, offs)

    # -- the channel matrix ---------------------------------------------------------
    @property
    def channels(self) -> np.ndarray:
        """(F, 3 + 3J + 3T) root position, every joint's Euler angles, then the
        translations (a copy)."""
        return channel_matrix(self.root_positions, self.angles_deg, self.translations)

    def with_channels(self, channels: np.ndarray) -> "Motion":
        """A Motion with the same skeleton and fps from a (F', 3 + 3J + 3T) channel matrix."""
        channels = np.asarray(channels, dtype=float)
        F, angles = channels.shape[0], angle_slice(self.skeleton)
        if channels.ndim != 2 or channels.shape[1] != channel_count(self.skeleton):
            raise ValueError(
                f"a channel matrix of this skeleton is (F, {channel_count(self.skeleton)}), got {channels.shape}"
            )
        return Motion(
            self.skeleton,
            self.fps,
            channels[:, :3],
            channels[:, angles].reshape(F, -1, 3),
            self.name,
            channels[:, angles.stop :].reshape(F, -1, 3),
        )

    def replace(self, **changes) -> "Motion":
        fields = dict(
            skeleton=self.skeleton,
            fps=self.fps,
            root_positions=self.root_positions,
            angles_deg=self.angles_deg,
            name=self.name,
            translations=self.translations,
        )
        fields.update(changes)
        return Motion(**fields)

    def slice(self, start: int, stop: int | None = None) -> "Motion":
        return self.replace(
            root_positions=self.root_positions[start:stop],
            angles_deg=self.angles_deg[start:stop],
            translations=self.translations[start:stop],
        )

    def allclose(self, other: "Motion", atol: float = 1e-4) -> bool:
        """Same skeleton layout and fps, and every value equal within ``atol`` (angles
        compared modulo 360)."""
        if not self.skeleton.allclose(other.skeleton, atol=atol) or abs(self.fps - other.fps) > 1e-6:
            return False
        if self.angles_deg.shape != other.angles_deg.shape:
            return False
        dang = (self.angles_deg - other.angles_deg + 180.0) % 360.0 - 180.0
        return bool(
            np.allclose(self.root_positions, other.root_positions, atol=atol, equal_nan=True)
            and np.allclose(self.translations, other.translations, atol=atol, equal_nan=True)
            and np.all((np.abs(dang) <= atol) | (np.isnan(self.angles_deg) & np.isnan(other.angles_deg)))
        )


def blended(a: Motion, b: Motion, share: float) -> Motion:
    """``a`` moved ``share`` (0 to 1) of the way towards ``b``, a take of the same skeleton,
    rate and frames (two engines' cleans of one take): root positions and translations
    linearly; each joint's rotation by normalised quaternion interpolation along the
    shorter arc (within a hair of slerp for the few degrees two cleans differ by), written
    as the Euler triple in the joint's order nearest to ``a``'s. A value (a root
    coordinate, a translation, a joint's triple) that is the same in both, as kept observed
    samples are, is ``a``'s bit for bit.

    Raises
    ------
    ValueError
        ``share`` outside 0 to 1, or takes of different skeletons, rates or lengths.
    """
    from .rotations import euler_to_matrix, matrix_to_euler, matrix_to_quaternion, nearest_euler, quaternion_to_matrix

    if not 0.0 <= share <= 1.0:
        raise ValueError(f"share must be 0 to 1, got {share}")
    if a.skeleton.names != b.skeleton.names or a.fps != b.fps or a.n_frames != b.n_frames:
        raise ValueError("only two takes of one skeleton, rate and length can be blended")
    angles = a.angles_deg.copy()
    for order in dict.fromkeys(a.skeleton.rotation_orders):
        joints = [j for j, o in enumerate(a.skeleton.rotation_orders) if o == order]
        qa, qb = (matrix_to_quaternion(euler_to_matrix(m.angles_deg[:, joints], order)) for m in (a, b))
        qb *= np.where(np.sum(qa * qb, axis=-1, keepdims=True) < 0, -1.0, 1.0)  # the shorter arc
        mixed = matrix_to_euler(quaternion_to_matrix((1.0 - share) * qa + share * qb), order)
        angles[:, joints] = nearest_euler(mixed, a.angles_deg[:, joints])
    same = np.all(a.angles_deg == b.angles_deg, axis=-1, keepdims=True)

    def linear(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        return np.where(x == y, x, (1.0 - share) * x + share * y)

    return a.replace(
        root_positions=linear(a.root_positions, b.root_positions),
        angles_deg=np.where(same, a.angles_deg, angles),
        translations=linear(a.translations, b.translations),
    )


def channel_matrix(root_positions: np.ndarray, angles_deg: np.ndarray, translations: np.ndarray) -> np.ndarray:
    """The (F, 3 + 3J + 3T) channel matrix (a new array) of root positions (F, 3), Euler
    angles (F, J, 3) and translations (F, T, 3): :attr:`Motion.channels` without making
    a Motion (which would copy a writable array first)."""
    F = len(root_positions)
    return np.concatenate([root_positions, np.reshape(angles_deg, (F, -1)), np.reshape(translations, (F, -1))], axis=1)


def channel_count(skeleton: Skeleton) -> int:
    """D, the width of the skeleton's channel matrix: 3 + 3J + 3T."""
    return 3 + 3 * skeleton.n_joints + 3 * len(skeleton.translated)


def angle_slice(skeleton: Skeleton) -> slice:
    """The channel-matrix columns of every joint's Euler angles: ``3 : 3 + 3J``."""
    return slice(3, 3 + 3 * skeleton.n_joints)


def body_position_column(skeleton: Skeleton) -> int:
    """The first of the channel matrix's three columns that place the body root: the
    root position's, or, under a reference node, the body root's translation."""
    b = skeleton.body_root
    return 0 if b == 0 else angle_slice(skeleton).stop + 3 * skeleton.translated.index(b)


def length_columns(skeleton: Skeleton) -> np.ndarray:
    """Column indices into the channel matrix of the channels in file units, not degrees:
    the root position and the translations."""
    return np.r_[0:3, 3 + 3 * skeleton.n_joints : channel_count(skeleton)]


def channel_joints(skeleton: Skeleton) -> np.ndarray:
    """(D,) the joint each channel-matrix column belongs to: the root for the root
    position, each joint for its angles, each translated joint for its translation."""
    J = skeleton.n_joints
    return np.concatenate([np.zeros(3, int), np.repeat(np.arange(J), 3), np.repeat(skeleton.translated, 3)]).astype(int)


def joint_any(mask: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """(F, J) whether any of a joint's channels is set in a channel-matrix mask (F, D),
    the channels assigned as :func:`channel_joints` assigns them (the reverse of
    :func:`channel_mask`; a tenth of the time ``np.logical_or.at`` takes)."""
    F, J = len(mask), skeleton.n_joints
    angles = mask[:, angle_slice(skeleton)].reshape(F, J, 3)
    out = angles[..., 0] | angles[..., 1] | angles[..., 2]  # 8x faster than any(axis=2) over 3
    out[:, 0] |= mask[:, :3].any(axis=1)
    for t, j in enumerate(skeleton.translated):
        out[:, j] |= mask[:, 3 + 3 * (J + t) : 6 + 3 * (J + t)].any(axis=1)
    return out


def channel_mask(observed: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """Expand an observed mask (F, J) to the channel matrix layout (F, D): a joint's
    angles, and its translation if it has one, are observed where it is; the root
    position where the root is."""
    return np.asarray(observed, dtype=bool)[:, channel_joints(skeleton)]


def position_unknown(observed: np.ndarray, parents, translated=()) -> np.ndarray:
    """(..., J) whether a joint's position depends on missing data, given an observed
    mask (..., J), the skeleton's ``parents`` and ``translated`` joints: the root or a
    proper ancestor of the joint is missing, or the joint itself when it is translated.
    (A joint's own angles move its children, not the joint.)"""
    observed = np.asarray(observed, bool)
    chain = np.empty_like(observed)  # the joint and all its ancestors observed
    unknown = np.empty_like(observed)
    for j, p in enumerate(parents):
        unknown[..., j] = ~observed[..., 0] if p < 0 else ~chain[..., p]
        if j in translated:  # its own translation places it
            unknown[..., j] |= ~observed[..., j]
        chain[..., j] = observed[..., j] & (True if p < 0 else chain[..., p])
    return unknown


def joint_angle_columns(joints) -> np.ndarray:
    """(3n,) column indices into the channel matrix of the angles of the n ``joints``
    (indices), three per joint in their order."""
    return (3 + 3 * np.asarray(joints, int)[:, None] + np.arange(3)).ravel()


def angle_joints(skeleton: Skeleton) -> np.ndarray:
    """Indices of the joints whose angles are the joint-angle channels: every joint with
    a rotation but those of the root chain (``skeleton.root_chain``: the root, and a
    moving Hips under a reference root)."""
    body = skeleton.has_rotation.copy()
    body[list(skeleton.root_chain)] = False
    return np.flatnonzero(body)


def angle_columns(skeleton: Skeleton) -> np.ndarray:
    """Column indices into the channel matrix of the scored joint-angle channels: the
    rotation channels of :func:`angle_joints`."""
    return joint_angle_columns(angle_joints(skeleton))


@dataclass(frozen=True, eq=False)
class Observation:
    """What an engine may see: a corrupted Motion and the observed mask (F, J).

    ``observed[f, j]`` False means joint j's angles at frame f are missing (NaN in
    ``motion``), and its translation if it is a translated joint; the root position is
    missing where the root joint is. The ground truth is not part of this type.

    ``capture_step``: frames of ``motion`` per captured frame. 1 for a take as captured;
    above 1 for one resampled up from its capture rate by linear interpolation (an
    engine's view of a 30-fps take at 120 fps has 4): its frames between the captured
    ones are interpolated, not measured, so noise is measured on the captured ones
    (:func:`workbench.engine.smoothing.measurement_variance`).
    """

    motion: Motion
    observed: np.ndarray = field(default=None)  # type: ignore[assignment]
    capture_step: float = 1.0

    def __post_init__(self) -> None:
        if not self.capture_step >= 1.0:
            raise ValueError(f"capture_step must be at least 1 (frames per captured frame), got {self.capture_step}")
        F, J = self.motion.n_frames, self.motion.skeleton.n_joints
        obs = np.ones((F, J), bool) if self.observed is None else np.array(self.observed, dtype=bool)
        if obs.shape != (F, J):
            raise ValueError(f"observed mask must be (F, J) = {(F, J)}, got {obs.shape}")
        # Missing entries hold NaN, and NaN entries count as missing.
        ch = self.motion.channels
        nan = np.isnan(ch)
        obs &= ~joint_any(nan, self.skeleton)
        unmarked = ~channel_mask(obs, self.skeleton) & ~nan
        obs.setflags(write=False)
        object.__setattr__(self, "observed", obs)
        if unmarked.any():  # else the motion is kept as it is: it is read-only
            ch[unmarked] = np.nan
            object.__setattr__(self, "motion", self.motion.with_channels(ch))

    @property
    def skeleton(self) -> Skeleton:
        return self.motion.skeleton

    @property
    def n_frames(self) -> int:
        return self.motion.n_frames

    @property
    def has_gaps(self) -> bool:
        return not bool(self.observed.all())

    @property
    def channel_observed(self) -> np.ndarray:
        """(F, D) the observed mask in the channel matrix layout (:func:`channel_mask`)."""
        return channel_mask(self.observed, self.skeleton)

    def bridged(self) -> Motion:
        """The observed motion with its angles unwrapped robustly and its gaps bridged
        linearly (:func:`.channels.unwrap_deg`, :func:`.channels.interpolate_gaps`), so
        it is finite: what a BVH file of the observation or a drawing of it holds."""
        from .channels import interpolate_gaps, unwrap_deg

        mask, angles = self.channel_observed, angle_slice(self.skeleton)
        X = self.motion.channels
        X[:, angles] = unwrap_deg(X[:, angles], mask[:, angles], robust=True)
        return self.motion.with_channels(interpolate_gaps(X, mask))


@dataclass(frozen=True, eq=False)
class Case:
    """A benchmark case: the clean truth, what an engine sees, and how it was made."""

    truth: Motion
    observation: Observation
    corruption: str
    seed: int
