"""Exact smoothing with small coupled linear-Gaussian models, many at once.

Each group g (e.g. a joint's three Euler angles, ``b`` channels) follows its own
second-order linear dynamics, in frames::

    x_{t+1} = A1 x_t + A2 x_{t-1} + c + w_t,   w_t ~ N(0, Q)       (b-vectors)
    y_t     = x_t + e_t,   e_t ~ N(0, diag r),  skipped where missing

which is a Kalman state-space model with state ``s_t = (x_t, x_{t-1})`` (2b) and
transition ``[[A1, A2], [I, 0]]``. Its Rauch-Tung-Striebel smoothed means minimise

    sum_obs (y - x)^2 / r + sum_t (x_{t+1} - A1 x_t - A2 x_{t-1} - c)' Q^-1 (...)

(flat prior on the first two states), a block-pentadiagonal system in time that
:func:`coupled_smooth` solves exactly with one banded Cholesky solve (LAPACK ``pbsv``,
bandwidth ``3 b - 1``) for all groups stacked (uncoupled). Tests check it against the
forward Kalman filter / backward RTS recursion.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import solveh_banded


def coupled_smooth(
    Y: np.ndarray, observed: np.ndarray, r: np.ndarray, A1: np.ndarray, A2: np.ndarray, c: np.ndarray, Qinv: np.ndarray
) -> np.ndarray:
    """Smoothed (G, F, b) trajectories of G groups of b channels.

    Y, observed: (G, F, b) measurements and mask; r: (G, b) measurement variances;
    A1, A2, Qinv: (G, b, b) dynamics and inverse process covariance; c: (G, b) offset.
    Every channel needs at least two observations (or the model must pin it down).
    """
    G, F, b = Y.shape
    if F < 3:
        raise ValueError("coupled_smooth needs at least 3 frames")
    eye = np.broadcast_to(np.eye(b), (G, b, b))
    K = [-A2, -A1, eye]  # residual_t = sum_i K_i x_{t-1+i} - c
    KtQ = [np.swapaxes(k, 1, 2) @ Qinv for k in K]
    blocks = np.zeros((3, G, F, b, b))  # lag 0, 1, 2: H[frame + lag, frame]
    rhs = np.where(observed, Y, 0.0) / r[:, None, :]
    n = F - 2
    for i in range(3):
        for j in range(i, 3):
            M = KtQ[j] @ K[i]  # block (frame t-1+j, frame t-1+i)
            blocks[j - i][:, i : i + n] += M[:, None]
        rhs[:, i : i + n] += (KtQ[i] @ c[:, :, None])[:, None, :, 0]
    diag = np.arange(b)
    blocks[0][:, :, diag, diag] += observed / r[:, None, :]
    kd = 3 * b - 1
    ab = np.zeros((kd + 1, G, F, b))
    for lag in range(3):
        B = blocks[lag]
        for ci in range(b):  # column channel (earlier frame)
            for cj in range(b):  # row channel (frame + lag)
                k = lag * b + cj - ci
                if k < 0 or (lag == 0 and cj < ci):
                    continue
                if lag == 0:
                    ab[k, :, :, ci] = B[:, :, cj, ci]
                else:
                    ab[k, :, : F - lag, ci] = B[:, : F - lag, cj, ci]
    x = solveh_banded(ab.reshape(kd + 1, -1), rhs.reshape(-1), lower=True, check_finite=False)
    return x.reshape(G, F, b)
