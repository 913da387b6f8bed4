"""The motion image of Kaufmann et al. (2020, §3.1): one column per frame, one row per
pose coordinate (numpy only).

Units: positions in the skeleton's file unit, headings and turning rates in radians
(per frame), velocities in file units per frame; Y is up, the floor is the XZ plane.

Rows of a frame's column (``Layout``; ``H = 1 + 3 K + 3`` rows):

* the height of the root (Hips) above the floor;
* the 3-D position of each of the K *image joints* relative to the root's floor point
  ``(x, 0, z)``, in the root's heading frame (rotated by minus the heading, so every pose
  faces +Z: the network sees canonical poses whichever way the actor walks);
* the root's floor velocity (x, z) from the previous frame, in this frame's heading
  frame, and its turning rate about the up axis (0 in frame 0).

Image joints are the non-root joints that do not sit on their parent: a joint whose
rest offset is zero (CMU: LHipJoint, RHipJoint, LowerBack, Neck, LeftShoulder,
RightShoulder, LeftFingerBase, LThumb, RightFingerBase, RThumb) is always exactly where
its parent is, so it is left out and put back at its parent on decoding (CMU: 20 image
joints, H = 64 rows).

The heading is the twist about the up axis of the root's world rotation,
``atan2(R02 - R20, R00 + R22)`` (the yaw part of a swing-twist split), defined for any
pose short of a half turn of swing.

Positions are known only where the observation fixes them: a joint's position depends
on the angles of its ancestors (root included), so it is *known* at a frame when the
root and every ancestor are observed there (:func:`workbench.core.motion.position_unknown`); unknown entries
are the holes the network fills.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from workbench.core.channels import interpolate_frames
from workbench.core.skeleton import Skeleton

#: rows before the joints (root height) and after them (vx, vz, turning rate)
HEAD_ROWS = 1
TAIL_ROWS = 3


@dataclass(frozen=True)
class Layout:
    """Which joints are rows of the image. ``joints``: the K image joints (indices into
    the skeleton); ``source``: (J,) for each joint the image joint (or the root, 0) whose
    position it shares; ``parents``: the skeleton's parent indices."""

    joints: tuple[int, ...]
    source: tuple[int, ...]
    parents: tuple[int, ...]

    @classmethod
    def from_skeleton(cls, skeleton: Skeleton) -> "Layout":
        moving = np.linalg.norm(skeleton.offsets, axis=1) > 1e-9
        source = []
        for j, p in enumerate(skeleton.parents):
            source.append(j if (p < 0 or moving[j]) else source[p])
        joints = tuple(j for j in range(1, skeleton.n_joints) if moving[j])
        return cls(joints, tuple(source), tuple(skeleton.parents))

    @property
    def n_joints(self) -> int:
        return len(self.parents)

    @property
    def n_rows(self) -> int:
        return HEAD_ROWS + 3 * len(self.joints) + TAIL_ROWS

    def rows(self, joint: int) -> slice:
        """The three rows (x, y, z) of image joint ``joint``."""
        k = self.joints.index(joint)
        return slice(HEAD_ROWS + 3 * k, HEAD_ROWS + 3 * k + 3)


def turn_y(vectors: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Vectors (..., 3) rotated by ``theta`` (radians, broadcast against the leading axes)
    about the up (Y) axis: x' = c x + s z, z' = c z - s x (by entries, 8x faster than a
    stack of matrices)."""
    c, s = np.cos(theta), np.sin(theta)
    x, z = vectors[..., 0], vectors[..., 2]
    out = np.empty(np.broadcast_shapes(np.shape(vectors), np.shape(theta) + (3,)))
    out[..., 0] = c * x + s * z
    out[..., 1] = vectors[..., 1]
    out[..., 2] = c * z - s * x
    return out


def heading(root_rotations: np.ndarray) -> np.ndarray:
    """(F,) heading in radians: the twist about Y of the root's world rotations (F, 3, 3)."""
    R = root_rotations
    return np.arctan2(R[..., 0, 2] - R[..., 2, 0], R[..., 0, 0] + R[..., 2, 2])


def wrap(angle: np.ndarray) -> np.ndarray:
    """Angles (radians) wrapped to [-pi, pi)."""
    return (angle + np.pi) % (2.0 * np.pi) - np.pi


def encode(layout: Layout, positions: np.ndarray, theta: np.ndarray, ground: np.ndarray | None = None) -> np.ndarray:
    """The image (F, H) of world joint positions (F, J, 3) with root headings (F,) on the
    root's floor points ``ground`` (F, 3) (default: under the root joint)."""
    F = positions.shape[0]
    hips = positions[:, 0]
    if ground is None:
        ground = hips * np.array([1.0, 0.0, 1.0])
    local = turn_y(positions[:, list(layout.joints)] - ground[:, None], -theta[:, None])  # heading frame
    step = np.zeros((F, 3))
    step[1:] = turn_y(ground[1:] - ground[:-1], -theta[1:])
    turn = np.zeros(F)
    turn[1:] = wrap(np.diff(theta))
    return np.concatenate([hips[:, 1:2], local.reshape(F, -1), step[:, [0, 2]], turn[:, None]], axis=1)


def integrate(image: np.ndarray, ground0: np.ndarray, theta0: float) -> tuple[np.ndarray, np.ndarray]:
    """Root floor points (F, 3) and headings (F,) from an image's velocity rows, starting
    at ``ground0`` (3,) and ``theta0`` in frame 0."""
    theta = theta0 + np.concatenate([[0.0], np.cumsum(image[1:, -1])])
    step = np.zeros((image.shape[0], 3))
    step[:, [0, 2]] = image[:, -3:-1]
    step[0] = 0.0
    world = turn_y(step, theta)
    return np.asarray(ground0, float) + np.cumsum(world, axis=0), theta


def decode(layout: Layout, image: np.ndarray, ground: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """World joint positions (F, J, 3) of an image (F, H) placed on the root trajectory
    (floor points (F, 3), headings (F,)); zero-offset joints sit on their source joint."""
    F = image.shape[0]
    local = np.zeros((F, layout.n_joints, 3))
    local[:, 0, 1] = image[:, 0]
    local[:, list(layout.joints)] = image[:, HEAD_ROWS:-TAIL_ROWS].reshape(F, -1, 3)
    local = local[:, list(layout.source)]
    return ground[:, None] + turn_y(local, theta[:, None])


def trajectory(
    image: np.ndarray, root_known: np.ndarray, ground: np.ndarray, theta: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The root trajectory for decoding: the observed floor points (F, 3) and headings
    (F,) where ``root_known`` (F,), and across each stretch of unknown frames the path
    integrated from the image's velocity rows, rigidly attached to the observed frame
    before it and to the one after it and blended linearly between the two (so it meets
    both ends); from frame 0 at the origin facing +Z when the root is never known."""
    F = image.shape[0]
    path, turn = integrate(image, np.zeros(3), 0.0)
    if not root_known.any():
        return path, turn
    out_g = np.where(root_known[:, None], ground, 0.0)
    out_t = np.where(root_known, theta, 0.0)
    missing = np.flatnonzero(~root_known)
    if missing.size == 0:
        return out_g, out_t
    runs = np.split(missing, np.flatnonzero(np.diff(missing) > 1) + 1)
    for run in runs:
        a, b = run[0] - 1, run[-1] + 1  # the known frames around the run (may be outside)
        ends = [e for e in (a, b) if 0 <= e < F]
        g_paths, t_paths = [], []
        for e in ends:  # the integrated path attached rigidly at known frame e
            d = wrap(theta[e] - turn[e])
            g_paths.append(ground[e] + turn_y(path[run] - path[e], d))
            t_paths.append(theta[e] + turn[run] - turn[e])
        if len(ends) == 2:
            w = ((run - a) / (b - a))[:, None]
            out_g[run] = (1 - w) * g_paths[0] + w * g_paths[1]
            out_t[run] = t_paths[0] + w[:, 0] * wrap(t_paths[1] - t_paths[0])
        else:
            out_g[run], out_t[run] = g_paths[0], t_paths[0]
    return out_g, out_t


def image_mask(layout: Layout, known: np.ndarray) -> np.ndarray:
    """(..., F, H) which entries of the image are known, from known joint positions
    (..., F, J): the root rows where the root is known (a velocity needs this frame's and
    the previous frame's root), each joint's rows where it is."""
    root = known[..., 0]
    moved = root.copy()
    moved[..., 1:] &= root[..., :-1]
    joints = np.repeat(known[..., list(layout.joints)], 3, axis=-1)
    tail = np.repeat(moved[..., None], TAIL_ROWS, axis=-1)
    return np.concatenate([root[..., None], joints, tail], axis=-1)


def mirror_name(name: str) -> str:
    """The joint name of the other side: Left/Right, left/right, a leading L/R or l/r
    before a capital (LThumb, lHand); other names are their own mirror."""
    for a, b in (("Left", "Right"), ("left", "right")):
        if a in name:
            return name.replace(a, b)
        if b in name:
            return name.replace(b, a)
    m = re.match(r"^([LRlr])(?=[A-Z])", name)
    if m:
        swap = {"L": "R", "R": "L", "l": "r", "r": "l"}[m.group(1)]
        return swap + name[1:]
    return name


def mirror_rows(layout: Layout, names) -> tuple[np.ndarray, np.ndarray]:
    """Row permutation (H,) and signs (H,) that mirror an image left to right: joints
    swap with their other-side twins (by name), lateral (x) coordinates, the sideways
    velocity and the turning rate change sign. ``image[..., perm] * sign`` is the mirror."""
    index = {n: j for j, n in enumerate(names)}
    perm = np.arange(layout.n_rows)
    sign = np.ones(layout.n_rows)
    for j in layout.joints:
        twin = index.get(mirror_name(names[j]), j)
        if twin not in layout.joints:
            twin = j
        perm[layout.rows(j)] = np.arange(layout.n_rows)[layout.rows(twin)]
        sign[layout.rows(j).start] = -1.0
    sign[-3] = -1.0
    sign[-1] = -1.0
    return perm, sign


def reverse_time(image: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The image (F, H) and mask (F, H) of the take played backwards, exactly: frames in
    reverse order; a frame's floor step and turn are those of the original's next frame
    negated, the step turned into this frame's heading (frame 0 gets none). Its own
    inverse."""
    out, m = image[::-1].copy(), mask[::-1].copy()
    nxt = image[:0:-1, -TAIL_ROWS:]  # original frames F-1 .. 1
    step = np.zeros((len(nxt), 3))
    step[:, [0, 2]] = nxt[:, :2]
    out[0, -TAIL_ROWS:] = 0.0
    out[1:, -3:-1] = -turn_y(step, nxt[:, 2])[:, [0, 2]]
    out[1:, -1] = -nxt[:, 2]
    m[0, -TAIL_ROWS:] = m[0, 0]
    m[1:, -TAIL_ROWS:] = mask[:0:-1, -TAIL_ROWS:]
    return out, m


def retime(image: np.ndarray, times: np.ndarray) -> np.ndarray:
    """The image (F, H) at increasing fractional frame times ``times`` (n,), within
    [0, F - 1], as a take played at that rate encodes: the rows linearly interpolated, but
    the velocity and turning-rate rows the steps of their running sums so interpolated
    (the root's path between two new frames is the image's between those times, each
    frame's step in its own heading: exact for the turns, to first order in a frame's turn
    for the floor steps); the first new frame's step the image's there times the first
    time step."""
    out = interpolate_frames(image, times)
    path = interpolate_frames(np.cumsum(image[:, -TAIL_ROWS:], axis=0), times)
    out[0, -TAIL_ROWS:] *= times[1] - times[0] if len(times) > 1 else 1.0
    out[1:, -TAIL_ROWS:] = np.diff(path, axis=0)
    return out


def pad_time(image: np.ndarray, mask: np.ndarray, frames: int) -> tuple[np.ndarray, np.ndarray]:
    """Image (F, H) and mask (F, H) extended to ``frames`` frames by reflecting the clip
    at its end (time runs backwards there, so the velocity rows change sign)."""
    F = image.shape[0]
    if frames <= F:
        return image, mask
    idx = np.arange(frames)
    period = 2 * (F - 1) if F > 1 else 1
    r = idx % period
    back = r >= F
    src = np.where(back, period - r, r)
    out = image[src].copy()
    out[back, -TAIL_ROWS:] *= -1.0
    return out, mask[src]
