"""The root's trajectory in EBF's 31-frame window (our addition). Mall et al. pass the
root through: their noise leaves it clean. Joint-position noise solved back to angles
(``spatial``) reaches it, and a noisy root orientation turns the whole cleaned body, so
``ebf`` left such takes worse than it got them (test split, 5 seeds, ``spatial:1``:
mpjpe 2.93 cm, the input 1.81; with this filter 1.59).

So each window's root position and rotation get a Gaussian of width ``widest * n^2 /
(n^2 + gate^2)`` frames, with n the noise found in the window: 1.4826 times the median
of :func:`roughness` (third differences of the position, cm, and differences of the
rotation's frame to frame steps, second differences of the orientation, degrees, each
scaled to a white noise's std) over the 28 frames whose differences lie within the
window. A clean CMU root reads about a hundredth of a centimetre and a tenth of a degree
at 120 fps (walk 02_01: 0.007-0.015 cm, 0.05-0.17 degrees; taken at 30 fps, 0.06-0.07 cm
and 0.17-0.38 degrees); under ``spatial:1`` n is about 1 cm and 3.6 degrees, under
``spatial-ends:0.5,0.1`` 0.11 cm and 0.37 degrees. The gates (:data:`GATES`, 0.17 cm and
0.3 degrees at 120 fps) sit between: a clean root is barely touched, a noisy one gets
nearly ``widest``, ``max_sigma`` frames at 120 fps. Rotations are averaged as matrices
and projected back onto rotations (the chordal mean; Euler channels swing wildly near
gimbal lock). Everything comes from the window, so a stream gives what offline cleaning
gives.

At other frame rates (:func:`filter_limits`) the position's widest filter keeps its
duration (5 frames at 120 fps, 1.25 at 30) and the rotation's gate grows with the frame
interval (1.2 degrees at 30 fps): at a quarter of the rate a body's motion changes four
times as much from frame to frame. With the 120-fps settings, and the position's second
differences for its n, a 30-fps take's clean root was moved by 0.46 cm under
``angular:0.5`` (a clean CMU run taken at 30 fps by 5.7 cm on average), and under
``spatial:1`` its position came out further off than it went in (Bandai validation:
1.79 cm, 1.68 unfiltered); see ``docs/studio-data.md``, *The root's filter at 30 fps*.

A frame's root is kept as 12 numbers (:func:`root_frames`): its position (file units)
and its rotation matrix, row-major.
"""

from __future__ import annotations

import numpy as np

from workbench.core.rotations import euler_to_matrix, matrix_to_euler, nearest_euler

from .features import RADIUS, REFERENCE_FPS, window_index

#: noise stds (cm of position, degrees of rotation) at which the filter gets half of its
#: widest width, at :data:`~.features.REFERENCE_FPS`
GATES = np.array([0.17, 0.3])
#: a Gaussian narrower than this (frames) gives its neighbours under 1e-5 of the
#: weight: the centre frame is kept as it is
NARROW_FRAMES = 0.2


def root_frames(root: np.ndarray, order: str) -> np.ndarray:
    """(F, 12) position and row-major rotation matrix of root channels (F, 6): position
    (file units) and Euler angles (degrees, in ``order``)."""
    return np.concatenate([root[:, :3], euler_to_matrix(root[:, 3:], order).reshape(-1, 9)], axis=1)


def roughness(frames: np.ndarray, unit_cm: float) -> np.ndarray:
    """(F - 3, 2, 3) the noise frames 1 .. F - 3 of F consecutive :func:`root_frames`
    (F, 12) show, in stds of white noise: the root position's absolute third differences
    (cm, over the frames t - 1 .. t + 2) over sqrt 20, and the absolute differences of
    its rotation's steps between frames (the rotation vector of R[t]^T R[t+1],
    small-angle, degrees), second differences of the orientation over t - 1 .. t + 1,
    over sqrt 6. A third difference
    leaves out the position's acceleration, which a body's translation is full of (at 30
    fps 16 times what it is at 120); for the rotation it was level at 30 fps and a little
    worse at 120 (Bandai validation, CMU train; ``docs/studio-data.md``)."""
    R = frames[:, 3:].reshape(-1, 3, 3)
    step = np.einsum("fji,fjk->fik", R[:-1], R[1:])
    vector = np.rad2deg(0.5 * (step[:, [2, 0, 1], [1, 2, 0]] - step[:, [1, 2, 0], [2, 0, 1]]))
    p = frames[:, :3] * unit_cm
    position = (p[3:] - 3.0 * p[2:-1] + 3.0 * p[1:-2] - p[:-3]) / np.sqrt(20.0)
    rotation = (vector[1:-1] - vector[:-2]) / np.sqrt(6.0)
    return np.abs(np.stack([position, rotation], axis=1))


def filter_limits(max_sigma: float, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """The widest widths (2,) in frames and the gates (2,) (cm, degrees) of the position
    and the rotation filters for a take at ``fps``, given ``max_sigma`` frames at
    :data:`~.features.REFERENCE_FPS`: the position's widest filter lasts as long at every
    rate, the rotation's is as many frames, and its gate scales with the frame interval
    (chosen on Bandai's 30-fps validation takes; at 120 fps both are as given)."""
    scale = fps / REFERENCE_FPS
    return np.array([max_sigma * scale, max_sigma]), GATES * np.array([1.0, 1.0 / scale])


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
    frames: np.ndarray,
    rough: np.ndarray,
    valid: np.ndarray,
    centre_euler: np.ndarray,
    max_sigma: float,
    order: str,
    fps: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Root channels (N, 6), position in file units and Euler angles in degrees in
    ``order`` (the triple nearest ``centre_euler`` (N, 3)), at the centres of N windows
    of L :func:`root_frames` (N, L, 12) of a take at ``fps``, given their
    :func:`roughness` (N, L, 2, 3) (NaN where not known, and for frames outside the take)
    and ``valid`` (N, L), the window frame exists (only those enter); ``max_sigma``:
    frames at :data:`~.features.REFERENCE_FPS` (:func:`filter_limits`). Also the filter
    widths (N, 2), frames, of the position and the rotation."""
    N, L = valid.shape
    c = L // 2
    noise = _median_of_numbers(rough[:, 1:-2].transpose(0, 2, 1, 3).reshape(N, 2, -1)) * 1.4826
    widest, gates = filter_limits(max_sigma, fps)
    sigma = widest * noise**2 / (noise**2 + gates**2)
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
    root: np.ndarray, max_sigma: float, unit_cm: float, order: str, fps: float, chunk: int = 4096
) -> tuple[np.ndarray, np.ndarray]:
    """A take's root channels (F, 6) at ``fps`` (position in file units, Euler angles in
    degrees in ``order``, no gaps) smoothed in every frame's window (:func:`smooth_root`);
    and the filter widths (F, 2)."""
    F = root.shape[0]
    frames = root_frames(root, order)
    rough = np.full((F + 1, 2, 3), np.nan)  # the last row: for window frames outside the take
    rough[1 : F - 2] = roughness(frames, unit_cm)
    out, sigma = np.empty_like(root), np.empty((F, 2))
    for i in range(0, F, chunk):
        centres = np.arange(i, min(i + chunk, F))
        idx, valid = window_index(centres, F, RADIUS)
        out[centres], sigma[centres] = smooth_root(
            frames[idx], rough[np.where(valid, idx, F)], valid, root[centres, 3:], max_sigma, order, fps
        )
    return out, sigma
