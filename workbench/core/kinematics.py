"""Forward and inverse kinematics, vectorised over frames.

Units: positions in the skeleton's file unit, angles in degrees. FK loops over joints
(J <= ~60) and is vectorised over frames. IK solves joint angles from joint positions
with the skeleton's bone lengths kept exactly: each joint's world rotation is the
rotation that best maps its rest child offsets onto the target child directions
(Kabsch); where a joint has a single child, the twist about that bone cannot be seen in
positions and is taken from a reference motion (its twist, or the turn whose Euler angles
are nearest its own), or zero. A translated joint
(``skeleton.translated``) is no bone: its translation is solved from its target, so it
reaches it, as the root does.
"""

from __future__ import annotations

import numpy as np

from .channels import interpolate_gaps
from .rotations import (
    euler_axes,
    euler_rates,
    euler_to_matrix,
    kabsch,
    matrix_to_euler,
    matrix_to_quaternion,
    nearest_euler,
    quaternion_to_matrix,
    vectors_to_rotation,
)
from .skeleton import Skeleton


def local_rotations(skeleton: Skeleton, angles_deg: np.ndarray, joints=None) -> np.ndarray:
    """(F, n, 3, 3) local rotation matrices of ``joints`` (n indices; default all J) from
    the Euler angles (F, J, 3)."""
    joints = np.arange(skeleton.n_joints) if joints is None else np.asarray(joints, int)
    out = np.empty((angles_deg.shape[0], len(joints), 3, 3))
    orders = skeleton.rotation_orders
    for order in set(orders[j] for j in joints):
        k = [i for i, j in enumerate(joints) if orders[j] == order]
        out[:, k] = euler_to_matrix(angles_deg[:, joints[k]], order)
    return out


#: frames whose kinematics are computed together: a 10-minute take's 72,000 at once ran
#: four times slower, every joint's (F, 3, 3) matrices out of the cache
FK_BLOCK_FRAMES = 1024


def forward_kinematics(
    skeleton: Skeleton,
    root_positions: np.ndarray,
    angles_deg: np.ndarray,
    translations: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """World joint positions (F, J, 3) and world rotations (F, J, 3, 3) from the root
    positions (F, 3), the angles (F, J, 3) and the translations (F, T, 3) of the
    skeleton's translated joints, which take the place of their offsets (needed when it
    has any)."""
    angles_deg = np.asarray(angles_deg, float)
    R = np.empty(angles_deg.shape + (3,))
    return _forward(skeleton, root_positions, angles_deg, translations, R), R


def joint_positions(
    skeleton: Skeleton,
    root_positions: np.ndarray,
    angles_deg: np.ndarray,
    translations: np.ndarray | None = None,
) -> np.ndarray:
    """The positions (F, J, 3) of :func:`forward_kinematics`, the same bits, without
    keeping its world rotations: a block of frames' at a time (a 10-minute take's are
    150 MB)."""
    return _forward(skeleton, root_positions, np.asarray(angles_deg, float), translations, None)


def _forward(
    skeleton: Skeleton,
    root_positions: np.ndarray,
    angles_deg: np.ndarray,
    translations: np.ndarray | None,
    R: np.ndarray | None,
) -> np.ndarray:
    """FK's positions (F, J, 3); the world rotations into ``R`` (F, J, 3, 3), or into a
    buffer of one block when it is None."""
    if skeleton.translated and translations is None:
        raise ValueError(
            f"the skeleton has {len(skeleton.translated)} translated joints: FK needs their translations (F, T, 3)"
        )
    F, J = angles_deg.shape[:2]
    P = np.empty((F, J, 3))
    scratch = np.empty((min(F, FK_BLOCK_FRAMES), J, 3, 3)) if R is None else None
    offsets = skeleton.offsets
    moving = {j: k for k, j in enumerate(skeleton.translated)}
    for f0 in range(0, F, FK_BLOCK_FRAMES):  # a block at a time: its joints' matrices stay in the cache
        block = slice(f0, f0 + FK_BLOCK_FRAMES)
        R_local = local_rotations(skeleton, angles_deg[block])
        Pb, n = P[block], R_local.shape[0]
        Rb = scratch[:n] if R is None else R[block]
        for j, p in enumerate(skeleton.parents):
            if p < 0:
                Rb[:, j] = R_local[:, j]
                Pb[:, j] = root_positions[block] + offsets[j]
            else:
                Rb[:, j] = Rb[:, p] @ R_local[:, j]
                local_translation = offsets[j] if j not in moving else translations[block, moving[j], :, None]
                Pb[:, j] = Pb[:, p] + (Rb[:, p] @ local_translation).reshape(n, 3)
    return P


def _effective_children(skeleton: Skeleton, j: int, reference_local) -> tuple[list[int], np.ndarray]:
    """``skeleton.aimed_descendants[j]`` and their offsets in j's frame, the looked-through
    joints at their reference local rotations (``reference_local(v)``: (F, 3, 3)): (n, 3),
    or (F, n, 3) when a child was looked through (they vary over frames)."""
    aimed = skeleton.aimed_descendants[j]
    ids = [c for c, _ in aimed]
    if not any(via for _, via in aimed):  # the common case: the children's own offsets
        return ids, skeleton.offsets[ids]
    vecs = []
    for c, via in aimed:
        vec = skeleton.offsets[c]
        for v in reversed(via):
            vec = (reference_local(v) @ vec[..., None])[..., 0]
        vecs.append(vec)
    return ids, np.stack(np.broadcast_arrays(*vecs), axis=-2)


def _bridged_departure(R_aimed: np.ndarray, R_ref: np.ndarray, kept: np.ndarray) -> np.ndarray:
    """(F, 3, 3) rotations D with ``R_aimed @ D = R_ref`` in the ``kept`` frames (F,),
    bridged linearly as quaternions across the other frames (held before the first kept
    frame and after the last)."""
    q = matrix_to_quaternion(np.swapaxes(R_aimed, -1, -2) @ R_ref)
    return quaternion_to_matrix(interpolate_gaps(q, np.repeat(kept[:, None], 4, axis=1)))


#: Gauss-Newton steps of the turn about a bone aimed at one direction (:func:`_nearest_euler_turn`):
#: IK of the true positions on Bandai validation takes under ``angular:0.5``, 0 / 1 / 2 / 3 / 5 steps:
#: 2.62 / 1.95 / 1.84 / 1.83 / 1.83 degrees
TURN_STEPS = 2
#: a frame whose next step would turn it by less (radians, 0.06 degrees) is left where it is: on
#: a 2-minute CMU take, 60 % of the joints' frames at the first step
TURN_TOLERANCE = 1e-3


def _nearest_euler_turn(
    R: np.ndarray, bone: np.ndarray, reference_deg: np.ndarray, order: str, frames: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Local rotations ``R`` (F, 3, 3) turned about their ``bone`` (3,) or (F, 3) (the aimed
    child's offset in the joint's frame, which the turn leaves where ``R`` put it) in the
    ``frames`` (F,) bool so that their Euler angles in ``order`` come nearest
    ``reference_deg`` (F, 3), in the sum of squared degrees; and the angles of all frames
    (F, 3; :func:`nearest_euler` of the reference).

    :data:`TURN_STEPS` Gauss-Newton steps on the turn angle (the slope from
    :func:`~workbench.core.rotations.euler_rates`), each kept only where it lowers that
    sum, taken in the frames where it is at least :data:`TURN_TOLERANCE`.
    """
    F = R.shape[0]
    axis = np.broadcast_to(bone / np.linalg.norm(bone, axis=-1, keepdims=True), (F, 3))

    def turned(frames: np.ndarray, phi: np.ndarray) -> np.ndarray:
        """R in ``frames`` turned by ``phi`` radians about the bone (as a quaternion)."""
        half = 0.5 * phi[:, None]
        return R[frames] @ quaternion_to_matrix(np.concatenate([np.cos(half), np.sin(half) * axis[frames]], axis=1))

    def euler(frames: np.ndarray, phi: np.ndarray) -> np.ndarray:
        return nearest_euler(matrix_to_euler(turned(frames, phi), order), reference_deg[frames])

    e = nearest_euler(matrix_to_euler(R, order), reference_deg)
    phi = np.zeros(F)
    live = np.flatnonzero(frames)  # the frames still turning
    for _ in range(TURN_STEPS):
        miss = e[live] - reference_deg[live]
        slope = euler_rates(e[live], order, axis[live])  # degrees per radian
        step = np.einsum("fi,fi->f", slope, miss) / np.maximum(np.einsum("fi,fi->f", slope, slope), 1e-12)
        moving = np.abs(step) >= TURN_TOLERANCE
        live, miss, step = live[moving], miss[moving], step[moving]
        if not live.size:
            break
        trial = phi[live] - np.clip(step, -0.5, 0.5)
        e_trial = euler(live, trial)
        miss_trial = e_trial - reference_deg[live]
        better = np.einsum("fi,fi->f", miss_trial, miss_trial) < np.einsum("fi,fi->f", miss, miss)
        live = live[better]
        phi[live], e[live] = trial[better], e_trial[better]
    moved = np.flatnonzero(phi)
    out = R.copy()
    out[moved] = turned(moved, phi[moved])
    return out, e


#: Gauss-Newton steps of the Euler angles that weigh a reference against an aim
#: (:func:`_weighed_euler`): Bandai validation under ``angular:0.5``, ``cae``, 1 / 2 / 5 steps:
#: 2.300 / 2.291 / 2.291 degrees. Where the aim is far surer than the reference (100 times, in
#: ``tests/core/test_kinematics.py``) near gimbal lock, two steps leave the aim up to 2 degrees
#: off in a few frames: each step turns the bone's twist by the reference's pull, tilting it
#: a little off the aim, which the next step straightens
WEIGH_STEPS = 2
#: the least variance (degrees^2) a reference angle is taken to have: a constant channel,
#: which angle noise leaves alone, keeps its reference
REFERENCE_VARIANCE_FLOOR = 1e-6
#: the least variance an aim is taken to have, as a turn of its bone (radians^2, 0.006
#: degrees): a descendant that never moves from its joint (an aim variance of 0) is aimed at
AIM_VARIANCE_FLOOR = 1e-8


def _weighed_euler(
    R: np.ndarray,
    bone: np.ndarray,
    target: np.ndarray,
    reference_deg: np.ndarray,
    reference_variance: np.ndarray,
    aim_variance: float,
    order: str,
    frames: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Local rotations ``R`` (F, 3, 3) whose Euler angles in ``order`` weigh the reference's
    against the aim in the ``frames`` (F,) bool, each by its variance; and the angles of all
    frames (F, 3; :func:`nearest_euler` of the reference).

    In those frames the angles e minimise ``sum_k (e_k - reference_k)^2 /
    reference_variance_k + |R(e) bone - target'|^2 / aim_variance``, where ``target'`` is
    the ``target`` direction at the bone's length: the likeliest rotation given two
    independent Gaussian measurements of it, the reference's angles (``reference_deg``
    (F, 3); variances (3,), degrees^2) and the aimed descendant's position (``bone`` (3,)
    or (F, 3), its offset in the joint's frame; ``target`` (F, 3) in the parent's, file
    units; variance in file units^2). :data:`WEIGH_STEPS` Gauss-Newton steps from ``R``,
    the slope of the aim from :func:`~workbench.core.rotations.euler_axes`. Where the aim
    cannot tell an angle (the twist about the bone; near gimbal lock, the first and last
    angles' difference) the reference decides it; elsewhere the smaller variance.
    """
    e_all = nearest_euler(matrix_to_euler(R, order), reference_deg)
    bone = np.broadcast_to(bone, target.shape)[frames]
    target = target[frames]
    reference_deg = reference_deg[frames]
    reach = np.maximum(np.linalg.norm(target, axis=-1, keepdims=True), 1e-300)  # a target at the joint: no pull
    target = target * (np.linalg.norm(bone, axis=-1, keepdims=True) / reach)
    w_ref = 1.0 / np.maximum(reference_variance, REFERENCE_VARIANCE_FLOOR)  # (3,)
    aim_variance = np.maximum(aim_variance, AIM_VARIANCE_FLOOR * np.sum(bone**2, axis=-1))[:, None]  # (n, 1)
    e = e_all[frames]
    for _ in range(WEIGH_STEPS):
        reached = (euler_to_matrix(e, order) @ bone[..., None])[..., 0]
        slope = np.deg2rad(np.cross(euler_axes(e, order), reached[:, None, :]))  # (n, angle, xyz) per degree
        hessian = np.einsum("nix,njx->nij", slope, slope) / aim_variance[..., None] + np.diag(w_ref)
        gradient = np.einsum("nix,nx->ni", slope, reached - target) / aim_variance + w_ref * (e - reference_deg)
        e -= np.linalg.solve(hessian, gradient[..., None])[..., 0]
    e_all[frames] = e
    out = R.copy()
    out[frames] = euler_to_matrix(e, order)
    return out, e_all


def inverse_kinematics(
    skeleton: Skeleton,
    positions: np.ndarray,
    reference_angles_deg: np.ndarray | None = None,
    *,
    reference_joints=(),
    reference_frames: np.ndarray | None = None,
    reference_measured: np.ndarray | None = None,
    reference_variance: np.ndarray | None = None,
    aim_variance: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Joint angles that place the skeleton's joints at ``positions`` (F, J, 3) as well as
    its fixed bone lengths allow.

    Returns (root_positions (F, 3), angles_deg (F, J, 3), translations (F, T, 3) of the
    translated joints, which reach their targets). With ``reference_angles_deg``
    (F, J, 3), the twist about single-child bones and the rotations of leaf joints come
    from it, and every Euler triple is the representation nearest to it (continuous in
    time); without it they are zero. A joint aimed at one direction takes the smallest
    rotation from the reference that aims it (the reference's own twist), but where
    ``reference_measured`` (F, J) says the reference's Euler angles are measured, each
    with noise of its own (an observation's under angle noise, smoothed; not bridged
    across a gap, nor solved from noisy positions): there it takes the turn about its bone
    whose Euler angles are nearest the reference's (:func:`_nearest_euler_turn`), the
    likeliest under such noise. Near gimbal lock a fraction of a degree of twist moves two
    Euler angles by many degrees (Bandai's spine joints sit there), so the reference's
    twist kept the rotation near but its angles far (IK of the true positions, Bandai
    validation takes under ``angular:0.5``: 2.62 degrees rms, against 2.35 for kalman on
    the same noisy angles; with the nearest turn 1.84). Exact when ``positions`` come from
    FK of this skeleton and the reference is the true motion.
    ``reference_joints``:
    joints that keep the reference's angles instead of being aimed at their children.
    ``reference_frames`` (F, J) bool: the frames in which each joint keeps the
    reference's angles; in its other frames it is aimed, then turned by the reference's
    departure from the aim, bridged across them from the kept frames around
    (:func:`_bridged_departure`), so that it joins the kept frames without a jump.
    ``aim_variance`` (J,) file units^2 and ``reference_variance`` (J, 3) degrees^2: where a
    joint aimed at one direction has a finite aim variance, in its ``reference_measured``
    frames its Euler angles weigh the reference's against the aim instead of taking the
    aim exactly (:func:`_weighed_euler`): the variances of the reference's angles and of
    its aimed descendant's target seen from it. Two measurements of one rotation, each
    noisy where the other is sure: under angle noise, the positions tell a bone's
    direction, the angles its twist and, near gimbal lock, the split between the first
    and last angle.

    Memory: the joints are solved one by one, each joint's rotations (F, 3, 3) kept only
    until its last child is solved, so a long take needs a few (F, J, 3) arrays, not
    (F, J, 3, 3) ones.
    """
    positions = np.asarray(positions, float)
    F, J = positions.shape[:2]
    if J != skeleton.n_joints:
        raise ValueError(f"positions have {J} joints, the skeleton {skeleton.n_joints}")
    ref = np.zeros((F, J, 3)) if reference_angles_deg is None else np.asarray(reference_angles_deg, float)

    def reference_local(j: int) -> np.ndarray:
        return local_rotations(skeleton, ref, [j])[:, 0]

    last_child = {p: j for j, p in enumerate(skeleton.parents) if p >= 0}
    R_world: dict[int, np.ndarray] = {}  # of the joints whose children are still to solve
    P = np.empty((F, J, 3))  # positions actually reached (bone lengths kept)
    kept = np.zeros((F, J), bool) if reference_frames is None else np.array(reference_frames, bool)
    kept[:, list(reference_joints)] = True
    turn = np.zeros((F, J), bool) if reference_measured is None else np.asarray(reference_measured, bool)
    aim = np.full(J, np.nan) if aim_variance is None else np.asarray(aim_variance, float)
    aimed = skeleton.has_rotation & ~kept.all(axis=0)
    root_positions = positions[:, 0] - skeleton.offsets[0]
    translations = np.empty((F, len(skeleton.translated), 3))
    moving = {j: k for k, j in enumerate(skeleton.translated)}
    angles = ref.copy()  # the joints not aimed at children keep the reference's angles
    orders = skeleton.rotation_orders
    for j, p in enumerate(skeleton.parents):
        R_parent = None if p < 0 else R_world[p]
        if j in moving:  # a translation, not a bone: it reaches the target
            P[:, j] = positions[:, j]
            translations[:, moving[j]] = np.einsum("fji,fj->fi", R_parent, positions[:, j] - P[:, p])
        else:
            P[:, j] = positions[:, 0] if p < 0 else P[:, p] + np.einsum("fij,j->fi", R_parent, skeleton.offsets[j])
        R_ref = reference_local(j)
        ids, vecs = _effective_children(skeleton, j, reference_local) if aimed[j] else ([], None)
        if not ids:
            R_j = R_ref
        else:  # solved in the parent's frame: the reference is R_ref, the targets turned back
            targets = positions[:, ids] - P[:, j][:, None]
            if R_parent is not None:
                targets = np.einsum("fji,fnj->fni", R_parent, targets)
            spread = np.zeros(F, bool)  # some child off the line of the first (sine of the angle > 1e-6)
            if len(ids) > 1:
                lengths = np.linalg.norm(vecs, axis=-1)
                sines = np.linalg.norm(np.cross(vecs[..., :1, :], vecs[..., 1:, :]), axis=-1)
                spread |= (sines > 1e-6 * lengths[..., :1] * lengths[..., 1:]).any(axis=-1)
            R_j, turned = np.empty((F, 3, 3)), None  # turned: R_j's Euler angles, where known
            if not spread.all():  # one direction, or collinear ones: the twist is free
                current = (R_ref @ vecs[..., 0, :, None])[..., 0]
                R_j = vectors_to_rotation(current, targets[:, 0]) @ R_ref
                free = turn[:, j] & ~kept[:, j].any()  # (kept: the departure from the smallest carries over)
                if free.any() and np.isfinite(aim[j]):
                    R_j, turned = _weighed_euler(
                        R_j, vecs[..., 0, :], targets[:, 0], ref[:, j], reference_variance[j], aim[j], orders[j], free
                    )
                elif free.any():
                    R_j, turned = _nearest_euler_turn(R_j, vecs[..., 0, :], ref[:, j], orders[j], free)
            if spread.any():
                R_j, turned = np.where(spread[:, None, None], kabsch(vecs, targets), R_j), None
            if kept[:, j].any():
                R_j = R_j @ _bridged_departure(R_j, R_ref, kept[:, j])
            angles[:, j] = nearest_euler(matrix_to_euler(R_j, orders[j]), ref[:, j]) if turned is None else turned
        if j in last_child:  # a parent: its children turn in its world frame
            R_world[j] = R_j if R_parent is None else R_parent @ R_j
        if p >= 0 and last_child[p] == j:
            del R_world[p]
    return root_positions, angles, translations


def short_lever_joints(skeleton: Skeleton, lever_cm: float, observed: np.ndarray | None = None) -> np.ndarray:
    """Indices of the joints with a rotation whose ``skeleton.aimed_descendants`` (the
    nearest descendants off their own position) all lie within ``lever_cm``; with
    ``observed`` (F, J), only those observed in some frame (the ones IK can keep at an
    observed reference)."""
    out = []
    for j in np.flatnonzero(skeleton.has_rotation):
        reach = [np.linalg.norm(skeleton.offsets[c]) * skeleton.unit_cm for c, _ in skeleton.aimed_descendants[j]]
        if reach and max(reach) < lever_cm:
            out.append(int(j))
    out = np.array(out, int)
    return out if observed is None else out[np.asarray(observed, bool)[:, out].any(axis=0)]
