"""Rotation helpers: Euler angles (degrees, any Tait-Bryan order) <-> matrices <-> quaternions.

Conventions: an order string such as ``"ZYX"`` names the axes of a BVH joint's rotation
channels as they appear in the file; the rotation is the product of the elementary
rotations in that order, ``R = R_Z(a0) @ R_Y(a1) @ R_X(a2)`` (intrinsic rotations, which
scipy writes as the upper-case sequence ``"ZYX"``). Angles are in degrees, matrices act
on column vectors, quaternions are ``(w, x, y, z)``. Every function is vectorised over
leading axes and never imports anything but numpy.
"""

from __future__ import annotations

import numpy as np

AXES = {"X": 0, "Y": 1, "Z": 2}


def _check_order(order: str) -> tuple[int, int, int]:
    if len(order) != 3 or set(order) != {"X", "Y", "Z"}:
        raise ValueError(f"Euler order must be a permutation of 'XYZ', got {order!r}")
    return AXES[order[0]], AXES[order[1]], AXES[order[2]]


def axis_rotation(axis: int, angle_rad: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) about one coordinate axis (0=X, 1=Y, 2=Z)."""
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    R = np.zeros(np.shape(angle_rad) + (3, 3))
    i, j = (axis + 1) % 3, (axis + 2) % 3
    R[..., axis, axis] = 1.0
    R[..., i, i] = c
    R[..., j, j] = c
    R[..., i, j] = -s
    R[..., j, i] = s
    return R


#: rotations converted at a time: each block's temporaries stay in the CPU's cache (on a
#: 10-minute take, 2.2 million at once ran four times slower)
BLOCK = 1 << 14


def euler_to_matrix(angles_deg: np.ndarray, order: str) -> np.ndarray:
    """Euler angles (..., 3) in degrees, in ``order``, to rotation matrices (..., 3, 3)."""
    axes = _check_order(order)
    a = np.deg2rad(np.asarray(angles_deg, dtype=float))
    flat = a.reshape(-1, 3)
    out = np.empty((flat.shape[0], 3, 3))
    for start in range(0, flat.shape[0], BLOCK):
        _euler_block(flat[start : start + BLOCK], axes, out[start : start + BLOCK])
    return out.reshape(a.shape[:-1] + (3, 3))


def _euler_block(a: np.ndarray, axes: tuple[int, int, int], out: np.ndarray) -> None:
    """:func:`euler_to_matrix` of radians (N, 3) about ``axes``, written into ``out`` (N, 3, 3)."""
    # The nine entries as arrays of their own (contiguous, unlike a column of (N, 3, 3)):
    # the first axis's rotation, then R @ axis_rotation(axes[n], a[:, n]) for n = 1, 2,
    # which mixes two columns of R; written into the matrices once, at the end.
    c, s = np.cos(a[:, 0]), np.sin(a[:, 0])
    first, i, j = axes[0], (axes[0] + 1) % 3, (axes[0] + 2) % 3
    R: list[list] = [[0.0] * 3 for _ in range(3)]
    R[first][first], R[i][i], R[j][j], R[i][j], R[j][i] = 1.0, c, c, -s, s
    for n in (1, 2):
        c, s = np.cos(a[:, n]), np.sin(a[:, n])
        i, j = (axes[n] + 1) % 3, (axes[n] + 2) % 3
        for row in R:
            row[i], row[j] = row[i] * c + row[j] * s, row[j] * c - row[i] * s
    for r in range(3):
        for k in range(3):
            out[:, r, k] = R[r][k]


def matrix_to_euler(R: np.ndarray, order: str) -> np.ndarray:
    """Rotation matrices (..., 3, 3) to Euler angles (..., 3) in degrees, in ``order``.

    The middle angle lies in [-90, 90]; the others in (-180, 180]. At gimbal lock the
    third angle is set to zero.
    """
    i, j, k = _check_order(order)
    R = np.asarray(R, dtype=float)
    # Sign of the permutation (i, j, k): +1 for cyclic orders (XYZ, YZX, ZXY).
    sign = 1.0 if (j - i) % 3 == 1 else -1.0
    sin_b = np.clip(sign * R[..., i, k], -1.0, 1.0)
    b = np.arcsin(sin_b)
    a = np.arctan2(-sign * R[..., j, k], R[..., k, k])
    c = np.arctan2(-sign * R[..., i, j], R[..., i, i])
    locked = np.abs(sin_b) > 1.0 - 1e-9
    if np.any(locked):
        a_l = np.arctan2(sign * R[..., k, j], R[..., j, j])
        a = np.where(locked, a_l, a)
        c = np.where(locked, 0.0, c)
    return np.rad2deg(np.stack([a, b, c], axis=-1))


def alternative_euler(angles_deg: np.ndarray) -> np.ndarray:
    """The other Tait-Bryan triple (a+180, 180-b, c+180) giving the same rotation."""
    a = np.asarray(angles_deg, dtype=float)
    return np.stack([a[..., 0] + 180.0, 180.0 - a[..., 1], a[..., 2] + 180.0], axis=-1)


def euler_rates(angles_deg: np.ndarray, order: str, axis: np.ndarray) -> np.ndarray:
    """How fast Euler angles change as their rotation turns about an axis of its own frame.

    For ``R(phi) = R @ T(axis, phi)`` (a turn by ``phi`` about ``axis``, in the frame ``R``
    maps from), the derivative of ``R``'s Euler angles ``angles_deg`` in ``order`` at
    ``phi = 0``. With ``R = R_a(a) R_b(b) R_c(c)`` the frame's angular velocity is
    ``da R_c^T R_b^T e_a + db R_c^T e_b + dc e_c``, solved for the rates (Cramer's rule). At
    gimbal lock (middle angle +-90) the rates are unbounded; there they are large, not
    infinite.

    Parameters
    ----------
    angles_deg : ndarray, shape (..., 3)
        Euler angles in degrees, in ``order`` (any of a rotation's triples).
    order : str
        A permutation of "XYZ".
    axis : ndarray, shape (3,) or (..., 3)
        A unit vector in the rotation's own frame.

    Returns
    -------
    ndarray, shape (..., 3)
        The three angles' rates, in degrees per radian of turn.
    """
    first, middle, last = _check_order(order)
    a = np.deg2rad(np.asarray(angles_deg, dtype=float))
    Rc_t = axis_rotation(last, -a[..., 2])  # R_c^T
    columns = (
        (Rc_t @ axis_rotation(middle, -a[..., 1]))[..., :, first],
        Rc_t[..., :, middle],
        np.broadcast_to(np.eye(3)[last], a.shape),
    )
    omega = np.broadcast_to(axis, a.shape)
    det = np.einsum("...i,...i->...", columns[0], np.cross(columns[1], columns[2]))
    det = np.where(det < 0, -1.0, 1.0) * np.maximum(np.abs(det), 1e-12)  # finite at lock exactly
    rates = np.stack(
        [
            np.einsum("...i,...i->...", omega, np.cross(columns[1], columns[2])),
            np.einsum("...i,...i->...", columns[0], np.cross(omega, columns[2])),
            np.einsum("...i,...i->...", columns[0], np.cross(columns[1], omega)),
        ],
        axis=-1,
    )
    return np.rad2deg(rates / det[..., None])


def euler_axes(angles_deg: np.ndarray, order: str) -> np.ndarray:
    """The axes about which each Euler angle turns its rotation, in the frame the rotation maps to.

    With ``R = R_a(a) R_b(b) R_c(c)`` in ``order``, turning angle k by ``dk`` radians turns
    any vector ``R v`` by ``dk axis_k x R v``: ``axis_a = e_a``, ``axis_b = R_a e_b``,
    ``axis_c = R_a R_b e_c``. At gimbal lock (middle angle +-90) the first and the last
    coincide.

    Parameters
    ----------
    angles_deg : ndarray, shape (..., 3)
        Euler angles in degrees, in ``order``.
    order : str
        A permutation of "XYZ".

    Returns
    -------
    ndarray, shape (..., 3, 3)
        Unit axes, one per row, in the angles' order.
    """
    first, middle, last = _check_order(order)
    a = np.deg2rad(np.asarray(angles_deg, dtype=float))
    R_a = axis_rotation(first, a[..., 0])
    R_ab = R_a @ axis_rotation(middle, a[..., 1])
    return np.stack([np.broadcast_to(np.eye(3)[first], a.shape), R_a[..., :, middle], R_ab[..., :, last]], axis=-2)


def wrap_deg(angles_deg: np.ndarray) -> np.ndarray:
    """Wrap angles into [-180, 180) (to rounding: a sample an ulp below a multiple of 360
    may land an ulp below -180). By floor, not ``%``: numpy's float remainder is 6 times
    slower, and IK wraps every joint's angles several times a frame."""
    angles = np.asarray(angles_deg, float)
    return angles - 360.0 * np.floor((angles + 180.0) / 360.0)


def nearest_euler(angles_deg: np.ndarray, reference_deg: np.ndarray) -> np.ndarray:
    """Of the two Euler triples for each rotation, and all their 360-degree shifts, pick
    the one closest to ``reference_deg`` (same shape): keeps channels continuous in time."""
    angles = np.asarray(angles_deg, float)
    near = wrap_deg(angles - reference_deg)  # each triple's step from the reference
    far = wrap_deg(alternative_euler(angles) - reference_deg)
    first_nearer = np.einsum("...i,...i->...", near, near) <= np.einsum("...i,...i->...", far, far)
    return reference_deg + np.where(first_nearer[..., None], near, far)


def matrix_to_quaternion(R: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) to unit quaternions (..., 4) as (w, x, y, z), w >= 0."""
    R = np.asarray(R, dtype=float)
    m = R
    t = np.stack(
        [
            1 + m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2],
            1 + m[..., 0, 0] - m[..., 1, 1] - m[..., 2, 2],
            1 - m[..., 0, 0] + m[..., 1, 1] - m[..., 2, 2],
            1 - m[..., 0, 0] - m[..., 1, 1] + m[..., 2, 2],
        ],
        axis=-1,
    )
    best = np.argmax(t, axis=-1)
    q = np.empty(R.shape[:-2] + (4,))
    cands = [
        np.stack(
            [t[..., 0], m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]], -1
        ),
        np.stack(
            [m[..., 2, 1] - m[..., 1, 2], t[..., 1], m[..., 0, 1] + m[..., 1, 0], m[..., 0, 2] + m[..., 2, 0]], -1
        ),
        np.stack(
            [m[..., 0, 2] - m[..., 2, 0], m[..., 0, 1] + m[..., 1, 0], t[..., 2], m[..., 1, 2] + m[..., 2, 1]], -1
        ),
        np.stack(
            [m[..., 1, 0] - m[..., 0, 1], m[..., 0, 2] + m[..., 2, 0], m[..., 1, 2] + m[..., 2, 1], t[..., 3]], -1
        ),
    ]
    for n, cand in enumerate(cands):
        sel = best == n
        q[sel] = cand[sel] / (2.0 * np.sqrt(t[..., n][sel]))[..., None]
    q *= np.where(q[..., :1] < 0, -1.0, 1.0)
    return q


def quaternion_to_matrix(q: np.ndarray) -> np.ndarray:
    """Quaternions (..., 4) as (w, x, y, z), normalised here, to matrices (..., 3, 3)."""
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )


def rotation_angle_deg(R_a: np.ndarray, R_b: np.ndarray) -> np.ndarray:
    """Geodesic angle (...) in degrees between rotation matrices (..., 3, 3)."""
    trace = np.einsum("...ij,...ij->...", R_a, R_b)
    return np.rad2deg(np.arccos(np.clip((trace - 1.0) / 2.0, -1.0, 1.0)))


def vectors_to_rotation(source: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Smallest rotations (..., 3, 3) turning direction ``source`` (..., 3) onto ``target``."""
    a = source / np.maximum(np.sqrt(np.einsum("...i,...i->...", source, source)), 1e-12)[..., None]
    b = target / np.maximum(np.sqrt(np.einsum("...i,...i->...", target, target)), 1e-12)[..., None]
    ax, ay, az = a[..., 0], a[..., 1], a[..., 2]
    bx, by, bz = b[..., 0], b[..., 1], b[..., 2]
    vx, vy, vz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx  # v = a x b
    c = ax * bx + ay * by + az * bz
    # Rodrigues with cos c and sin-scaled axis v: R = c I + [v]x + v v' / (1 + c), by entries
    k = 1.0 / np.maximum(1.0 + c, 1e-12)
    xy, xz, yz = vx * vy * k, vx * vz * k, vy * vz * k
    R = np.empty(a.shape[:-1] + (3, 3))
    R[..., 0, 0], R[..., 1, 1], R[..., 2, 2] = c + vx * vx * k, c + vy * vy * k, c + vz * vz * k
    R[..., 0, 1], R[..., 1, 0] = xy - vz, xy + vz
    R[..., 0, 2], R[..., 2, 0] = xz + vy, xz - vy
    R[..., 1, 2], R[..., 2, 1] = yz - vx, yz + vx
    # Opposite vectors: rotate by 180 degrees about any axis perpendicular to a.
    opposite = c < -1.0 + 1e-9
    if np.any(opposite):
        ao = a[opposite]
        helper = np.where(np.abs(ao[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
        axis = np.cross(ao, helper)
        axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
        R[opposite] = 2.0 * axis[:, :, None] * axis[:, None, :] - np.eye(3)
    return R


def kabsch(source: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Rotations (..., 3, 3) best mapping vectors ``source`` (..., N, 3) onto ``target``
    (..., N, 3) in the least-squares sense (no translation, proper rotations)."""
    H = np.swapaxes(source, -1, -2) @ target  # (..., 3, 3)
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(np.swapaxes(Vt, -1, -2) @ np.swapaxes(U, -1, -2)))
    D = np.zeros(H.shape)
    D[..., 0, 0] = 1.0
    D[..., 1, 1] = 1.0
    D[..., 2, 2] = np.where(d == 0, 1.0, d)
    return np.swapaxes(Vt, -1, -2) @ D @ np.swapaxes(U, -1, -2)
