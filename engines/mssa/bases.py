"""Filter bases by multichannel singular spectrum analysis (Lou and Chai 2010, §3.1).

A trajectory is an (F, L) array of L normalised channels over F frames. Its windows of
M consecutive frames, flattened channel-major (entry ``l * M + m`` is channel l at lag
m, the column order of the paper's D = (X_1 ... X_L), Eq. 2), are the rows of the
trajectory matrix D (S = F - M + 1 rows, L M columns). The grand lag-covariance matrix
C_D = D^T D / S (Eq. 3) pools the windows of every training clip; its eigenvectors
sorted by eigenvalue are the filter bases, and the first K keep the requested share
of the energy (the trace).
"""

from __future__ import annotations

from typing import Iterator, Sequence

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

#: windows per block of the trajectory matrix (bounds memory on long clips)
CHUNK_WINDOWS = 2048


def window_blocks(X: np.ndarray, window: int, chunk: int = CHUNK_WINDOWS) -> Iterator[tuple[int, np.ndarray]]:
    """(first window index, rows of D) for consecutive blocks of at most ``chunk``
    windows of ``X`` (F, L); each block is a (n, L * window) array, channel-major."""
    views = sliding_window_view(X, window, axis=0)  # (S, L, M), no copy
    for s0 in range(0, views.shape[0], chunk):
        block = views[s0 : s0 + chunk]
        yield s0, block.reshape(block.shape[0], -1)


def lag_covariance(trajectories: Sequence[np.ndarray], window: int) -> np.ndarray:
    """The grand lag-covariance matrix C_D (L M, L M) of Eq. 3 over all windows of all
    trajectories (each (F_i, L), F_i >= window; shorter ones are skipped)."""
    L = trajectories[0].shape[1]
    C = np.zeros((L * window, L * window))
    count = 0
    for X in trajectories:
        if X.shape[0] < window:
            continue
        for _, D in window_blocks(np.asarray(X, float), window):
            C += D.T @ D
            count += D.shape[0]
    if count == 0:
        raise ValueError(f"no training clip has the {window} frames a window needs")
    return C / count


def filter_bases(C: np.ndarray, energy_kept: float) -> tuple[np.ndarray, np.ndarray]:
    """Eigen-decomposition of C_D: (bases (L M, K), spectrum (L M,)). The spectrum holds
    every eigenvalue, largest first; K is the fewest leading eigenvectors whose
    eigenvalues sum to at least ``energy_kept`` of the total."""
    values, vectors = np.linalg.eigh(C)
    order = np.argsort(values)[::-1]
    spectrum = np.clip(values[order], 0.0, None)
    share = np.cumsum(spectrum) / spectrum.sum()
    K = min(int(np.searchsorted(share, energy_kept - 1e-12)) + 1, spectrum.size)
    return vectors[:, order[:K]], spectrum
