"""Motion, Observation and Case: the data every layer passes around.

Units: root positions in the skeleton's file unit (``skeleton.unit_cm`` cm each); joint
angles in degrees, per joint in that joint's Euler order (``skeleton.rotation_order(j)``);
time in frames at ``fps`` frames per second.

The *channel matrix* (``Motion.channels``) is the flat (F, D) view engines filter:
``D = 3 + 3 J``, the root position first, then each joint's three Euler angles in file
order. ``angle_columns`` selects the joint-angle channels the papers score (every joint
but the root, whose trajectory they treat as clean).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from .skeleton import Skeleton


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class Motion:
    """A take: skeleton, fps, root positions (F, 3) and joint Euler angles (F, J, 3) in degrees.

    Arrays are read-only copies. Compare with :meth:`allclose`. Missing values are NaN
    (only in an :class:`Observation`).
    """

    skeleton: Skeleton
    fps: float
    root_positions: np.ndarray
    angles_deg: np.ndarray
    name: str = ""

    def __post_init__(self) -> None:
        root = _frozen(self.root_positions)
        ang = _frozen(self.angles_deg)
        J = self.skeleton.n_joints
        if root.ndim != 2 or root.shape[1] != 3:
            raise ValueError(f"root_positions must be (F, 3), got {root.shape}")
        if ang.shape != (root.shape[0], J, 3):
            raise ValueError(f"angles_deg must be (F, {J}, 3) to match root_positions, got {ang.shape}")
        if not self.fps > 0:
            raise ValueError(f"fps must be positive, got {self.fps}")
        object.__setattr__(self, "root_positions", root)
        object.__setattr__(self, "angles_deg", ang)

    @property
    def n_frames(self) -> int:
        return self.root_positions.shape[0]

    @property
    def duration_s(self) -> float:
        return self.n_frames / self.fps

    # -- kinematics (cached) --------------------------------------------------------
    @cached_property
    def global_rotations(self) -> np.ndarray:
        """(F, J, 3, 3) world rotation of each joint."""
        from .kinematics import forward_kinematics

        return forward_kinematics(self.skeleton, self.root_positions, self.angles_deg)[1]

    @cached_property
    def positions(self) -> np.ndarray:
        """(F, J, 3) world joint positions in file units (forward kinematics, cached)."""
        from .kinematics import forward_kinematics

        pos = forward_kinematics(self.skeleton, self.root_positions, self.angles_deg)[0]
        pos.setflags(write=False)
        return pos

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
        """(F, 3 + 3J) root position then every joint's Euler angles (a copy)."""
        return np.concatenate([self.root_positions, self.angles_deg.reshape(self.n_frames, -1)], axis=1)

    def with_channels(self, channels: np.ndarray) -> "Motion":
        """A Motion with the same skeleton and fps from a (F', 3 + 3J) channel matrix."""
        channels = np.asarray(channels, dtype=float)
        F = channels.shape[0]
        return Motion(self.skeleton, self.fps, channels[:, :3], channels[:, 3:].reshape(F, -1, 3), self.name)

    def replace(self, **changes) -> "Motion":
        fields = dict(skeleton=self.skeleton, fps=self.fps, root_positions=self.root_positions,
                      angles_deg=self.angles_deg, name=self.name)
        fields.update(changes)
        return Motion(**fields)

    def slice(self, start: int, stop: int | None = None) -> "Motion":
        return self.replace(root_positions=self.root_positions[start:stop], angles_deg=self.angles_deg[start:stop])

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
            and np.all((np.abs(dang) <= atol) | (np.isnan(self.angles_deg) & np.isnan(other.angles_deg)))
        )


def channel_mask(observed: np.ndarray) -> np.ndarray:
    """Expand an observed mask (F, J) to the channel matrix layout (F, 3 + 3J): the root
    position is observed where the root joint is."""
    observed = np.asarray(observed, dtype=bool)
    return np.concatenate([np.repeat(observed[:, :1], 3, axis=1), np.repeat(observed, 3, axis=1)], axis=1)


def position_unknown(observed: np.ndarray, parents) -> np.ndarray:
    """(..., J) whether a joint's position depends on missing data, given an observed
    mask (..., J) and the skeleton's ``parents``: the root or a proper ancestor of the
    joint is missing. (A joint's own angles move its children, not the joint.)"""
    observed = np.asarray(observed, bool)
    chain = np.empty_like(observed)  # the joint and all its ancestors observed
    unknown = np.empty_like(observed)
    for j, p in enumerate(parents):
        unknown[..., j] = ~observed[..., 0] if p < 0 else ~chain[..., p]
        chain[..., j] = observed[..., j] & (True if p < 0 else chain[..., p])
    return unknown


def joint_angle_columns(joints) -> np.ndarray:
    """(3n,) column indices into the channel matrix of the angles of the n ``joints``
    (indices), three per joint in their order."""
    return (3 + 3 * np.asarray(joints, int)[:, None] + np.arange(3)).ravel()


def angle_joints(skeleton: Skeleton) -> np.ndarray:
    """Indices of the joints whose angles are the joint-angle channels: every joint with
    a rotation but the root."""
    return np.flatnonzero(skeleton.has_rotation[1:]) + 1


def angle_columns(skeleton: Skeleton) -> np.ndarray:
    """Column indices into the channel matrix of the scored joint-angle channels: the
    rotation channels of :func:`angle_joints`."""
    return joint_angle_columns(angle_joints(skeleton))


@dataclass(frozen=True, eq=False)
class Observation:
    """What an engine may see: a corrupted Motion and the observed mask (F, J).

    ``observed[f, j]`` False means joint j's angles at frame f are missing (NaN in
    ``motion``); the root position is missing where the root joint is. The ground truth
    is not part of this type.
    """

    motion: Motion
    observed: np.ndarray = field(default=None)  # type: ignore[assignment]

    def __post_init__(self) -> None:
        F, J = self.motion.n_frames, self.motion.skeleton.n_joints
        obs = np.ones((F, J), bool) if self.observed is None else np.array(self.observed, dtype=bool)
        if obs.shape != (F, J):
            raise ValueError(f"observed mask must be (F, J) = {(F, J)}, got {obs.shape}")
        # Missing entries hold NaN, and NaN entries count as missing.
        ch = self.motion.channels
        nan_joint = np.isnan(ch[:, 3:]).reshape(F, J, 3).any(axis=2)
        nan_joint[:, 0] |= np.isnan(ch[:, :3]).any(axis=1)
        obs &= ~nan_joint
        ch[~channel_mask(obs)] = np.nan
        obs.setflags(write=False)
        object.__setattr__(self, "observed", obs)
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

    def bridged(self) -> Motion:
        """The observed motion with its angles unwrapped robustly and its gaps bridged
        linearly (:func:`.channels.unwrap_deg`, :func:`.channels.interpolate_gaps`), so
        it is finite: what a BVH file of the observation or a drawing of it holds."""
        from .channels import interpolate_gaps, unwrap_deg

        mask = channel_mask(self.observed)
        X = self.motion.channels
        X[:, 3:] = unwrap_deg(X[:, 3:], mask[:, 3:], robust=True)
        return self.motion.with_channels(interpolate_gaps(X, mask))


@dataclass(frozen=True, eq=False)
class Case:
    """A benchmark case: the clean truth, what an engine sees, and how it was made."""

    truth: Motion
    observation: Observation
    corruption: str
    seed: int
