"""The root's trajectory in EBF's 31-frame window (our addition). Mall et al. pass the
root through: their noise leaves it clean. Joint-position noise solved back to angles
(``spatial``) reaches it, and a noisy root orientation turns the whole cleaned body, so
``ebf`` left such takes worse than it got them (test split, 5 seeds, ``spatial:1``:
mpjpe 2.93 cm, the input 1.81; with this filter 1.59).

So each window's root position and rotation get a Gaussian of width ``max_sigma * n^2 /
(n^2 + gate^2)`` frames, with n the noise found in the window: 1.4826 / sqrt 6 times the
median absolute second difference of the positions (cm) and of the rotation's frame
to frame steps (degrees), over the window's inner 29 frames. At 120 fps a clean CMU
root's median second differences are a few hundredths of a centimetre and about a
tenth of a degree (walk 02_01: 0.02-0.035 cm, 0.09-0.27 degrees); under ``spatial:1``
n is about 1 cm and 3.6 degrees, under ``spatial-ends:0.5,0.1`` 0.11 cm and 0.37
degrees. The gates (:data:`GATES`, 0.17 cm and 0.3 degrees) sit between: a clean root
is barely touched (a filter of about a third of a frame), a noisy one gets nearly
``max_sigma``. Rotations are averaged as matrices and projected back onto rotations
(the chordal mean; Euler channels swing wildly near gimbal lock). Everything comes
from the window, so a stream gives what offline cleaning gives.

A frame's root is kept as 12 numbers (:func:`root_frames`): its position (file units)
and its rotation matrix, row-major.
"""

from __future__ import annotations

import numpy as np

from workbench.core.rotations import euler_to_matrix, matrix_to_euler, nearest_euler

from .features import RADIUS, window_index

#: noise stds (cm of position, degrees of rotation) at which the filter gets half of
#: ``max_sigma``
GATES = np.array([0.17, 0.3])
#: a Gaussian narrower than this (frames) gives its neighbours under 1e-5 of the
#: weight: the centre frame is kept as it is
NARROW_FRAMES = 0.2


def root_frames(root: np.ndarray, order: str) -> np.ndarray:
    """(F, 12) position and row-major rotation matrix of root channels (F, 6): position
    (file units) and Euler angles (degrees, in ``order``)."""
    return np.concatenate([root[:, :3], euler_to_matrix(root[:, 3:], order).reshape(-1, 9)], axis=1)


def roughness(frames: np.ndarray, unit_cm: float) -> np.ndarray:
    """(F - 2, 2, 3) absolute second differences at the inner frames of F consecutive
    :func:`root_frames` (F, 12): of the root's position, cm, and of its rotation's steps
    between frames (the rotation vector of R[t]^T R[t+1], small-angle, degrees)."""
    R = frames[:, 3:].reshape(-1, 3, 3)
    step = np.einsum("fji,fjk->fik", R[:-1], R[1:])
    vector = np.rad2deg(0.5 * (step[:, [2, 0, 1], [1, 2, 0]] - step[:, [1, 2, 0], [2, 0, 1]]))
    position = frames[:, :3] * unit_cm
    return np.abs(np.stack([position[2:] - 2.0 * position[1:-1] + position[:-2], vector[1:] - vector[:-1]], axis=1))


def _median_of_numbers(a: np.ndarray) -> np.ndarray:
    """(...) median of ``a`` (..., M) along its last axis over the non-NaN entries (0 for none)."""
    M = a.shape[-1]
    s = np.sort(a.reshape(-1, M), axis=-1)  # NaN last
    if not np.isnan(s[:, -1]).any():  # all numbers (windows inside the take)
        return (0.5 * (s[:, (M - 1) // 2] + s[:, M // 2])).reshape(a.shape[:-1])
    k = np.maximum(M - np.count_nonzero(np.isnan(s), axis=-1), 1)
    rows = np.arange(s.shape[0])
    return np.nan_to_num(0.5 * (s[rows, (k - 1) // 2] + s[rows, k // 2])).reshape(a.shape[:-1])


def smooth_root(
    frames: np.ndarray, rough: np.ndarray, valid: np.ndarray, centre_euler: np.ndarray, max_sigma: float, order: str
) -> tuple[np.ndarray, np.ndarray]:
    """Root channels (N, 6), position in file units and Euler angles in degrees in
    ``order`` (the triple nearest ``centre_euler`` (N, 3)), at the centres of N windows
    of L :func:`root_frames` (N, L, 12), given their :func:`roughness` (N, L, 2, 3) (NaN
    where not known, and for frames outside the take) and ``valid`` (N, L), the window
    frame exists (only those enter). Also the filter widths (N, 2), frames, of the
    position and the rotation."""
    N, L = valid.shape
    c = L // 2
    noise = _median_of_numbers(rough[:, 1:-1].transpose(0, 2, 1, 3).reshape(N, 2, -1)) * (1.4826 / np.sqrt(6.0))
    sigma = max_sigma * noise**2 / (noise**2 + GATES**2)
    out = np.concatenate([frames[:, c, :3], centre_euler], axis=1)
    wide = sigma >= NARROW_FRAMES
    if wide.any():
        w = np.exp(-0.5 * ((np.arange(L) - c) / np.maximum(sigma, NARROW_FRAMES)[..., None]) ** 2) * valid[:, None]
        mean = np.einsum("ngl,nlc->ngc", w / w.sum(axis=-1, keepdims=True), frames)  # (N, 2, 12)
        out[:, :3] = np.where(wide[:, :1], mean[:, 0, :3], out[:, :3])
        i = np.flatnonzero(wide[:, 1])
        if i.size:
            M = mean[i, 1, 3:].reshape(-1, 3, 3)
            U, _, Vt = np.linalg.svd(M)
            flip = np.linalg.det(M) < 0  # nearest is a reflection (rotations spread past 90 degrees)
            if flip.any():
                U[flip, :, 2] *= -1.0
            out[i, 3:] = nearest_euler(matrix_to_euler(U @ Vt, order), centre_euler[i])
    return out, sigma


def clean_root(
    root: np.ndarray, max_sigma: float, unit_cm: float, order: str, chunk: int = 4096
) -> tuple[np.ndarray, np.ndarray]:
    """A take's root channels (F, 6) (position in file units, Euler angles in degrees in
    ``order``, no gaps) smoothed in every frame's window; and the filter widths (F, 2)."""
    F = root.shape[0]
    frames = root_frames(root, order)
    rough = np.full((F + 1, 2, 3), np.nan)  # the last row: for window frames outside the take
    rough[1 : F - 1] = roughness(frames, unit_cm)
    out, sigma = np.empty_like(root), np.empty((F, 2))
    for i in range(0, F, chunk):
        centres = np.arange(i, min(i + chunk, F))
        idx, valid = window_index(centres, F, RADIUS)
        out[centres], sigma[centres] = smooth_root(
            frames[idx], rough[np.where(valid, idx, F)], valid, root[centres, 3:], max_sigma, order
        )
    return out, sigma
