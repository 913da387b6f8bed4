"""Signal numerics every channel-matrix engine shares: preparing an observation's channel
matrix for a filter and putting the result back, and Gaussian smoothing along time.

Units: time in frames; angle channels in degrees, length channels (the root position,
any translations) in the file's unit; a channel matrix is (F, D), the layout of
:attr:`workbench.core.motion.Motion.channels`; an observed mask (F, D) is True where a
sample was observed.

* :func:`prepare` returns the observation's channel matrix as given, its mask, and the
  matrix with angles unwrapped (robust to outliers,
  :func:`workbench.core.channels.unwrap_deg`) and gaps interpolated;
  :meth:`Prepared.output` puts a filtered result back on the input's angle branch.
  :func:`bridge_gaps`, :func:`rewrap_angles` and :func:`fill_gaps` are its short forms.
* :func:`normalized_gaussian`: the normalised convolution of Knutsson and Westin (1993),
  ``G*(c x) / G*c`` with certainty ``c``, zero padded outside the clip, so missing
  samples and the clip's ends do not pull the signal towards 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.fft as sfft

from ..core.channels import forward_fill, interpolate_gaps, rewrap_deg, unwrap_deg
from ..core.motion import Observation, angle_slice

__all__ = [
    "Prepared",
    "prepare",
    "bridge_gaps",
    "rewrap_angles",
    "fill_gaps",
    "TRUNCATE",
    "gaussian_kernel",
    "convolve_time",
    "normalized_gaussian",
]


@dataclass(frozen=True)
class Prepared:
    """An observation's channel matrix, ready for filtering.

    raw: (F, D) channels as observed (NaN where missing); mask: (F, D) observed;
    bridged: (F, D) angles unwrapped along time, gaps interpolated (treat as read-only:
    it may be ``raw`` itself when there is nothing to unwrap or fill); wrapped: the
    columns whose unwrapping changed something.
    """

    raw: np.ndarray
    mask: np.ndarray
    bridged: np.ndarray
    wrapped: np.ndarray
    complete: bool

    def output(self, Y: np.ndarray) -> np.ndarray:
        """A filtered (F, D) matrix of unwrapped angles put back on the input's branch:
        angle columns that were unwrapped are shifted by whole turns to follow the raw
        angles (:func:`workbench.core.channels.rewrap_deg`); equal to ``Y`` modulo 360."""
        if not self.wrapped.size:
            return Y
        Y = np.array(Y, dtype=float)
        w = self.wrapped
        Y[:, w] = rewrap_deg(Y[:, w], self.raw[:, w], self.mask[:, w])
        return Y


def prepare(observation: Observation, kind: str = "linear") -> Prepared:
    """Unwrap and bridge an observation (``kind`` as in
    :func:`workbench.core.channels.interpolate_gaps`), touching only the columns that
    need it (most takes have no angle wrapping and no gaps)."""
    mask = observation.channel_observed
    raw = observation.motion.channels
    complete = bool(observation.observed.all())
    # only a column spanning 180 degrees or more can step by that much between samples
    first = angle_slice(observation.skeleton).start
    angles = raw[:, angle_slice(observation.skeleton)]
    span = np.fmax.reduce(angles, axis=0) - np.fmin.reduce(angles, axis=0)  # NaN-ignoring
    wide = np.flatnonzero(span >= 180.0)
    wrapped = np.zeros(0, int)
    if wide.size:
        a = angles[:, wide] if complete else forward_fill(angles[:, wide], mask[:, first + wide])
        wrapped = first + wide[(np.abs(np.diff(a, axis=0)) >= 180.0).any(axis=0)]
    X = raw
    if wrapped.size:
        X = raw.copy()
        X[:, wrapped] = unwrap_deg(raw[:, wrapped], mask[:, wrapped], robust=True)
    if not complete:
        X = interpolate_gaps(X, mask, kind)
    return Prepared(raw, mask, X, wrapped, complete)


def bridge_gaps(observation: Observation, kind: str = "linear") -> np.ndarray:
    """(F, D) channel matrix of the observation with gaps interpolated (``kind`` as in
    :func:`workbench.core.channels.interpolate_gaps`), angles unwrapped."""
    p = prepare(observation, kind)
    return p.bridged.copy() if p.bridged is p.raw else p.bridged


def rewrap_angles(Y: np.ndarray, observation: Observation) -> np.ndarray:
    """Channel matrix ``Y`` (unwrapped angles, e.g. a filtered :func:`bridge_gaps`) with
    its angle channels shifted by whole turns onto the observation's own branch, so the
    output reads like the input (equal to ``Y`` modulo 360)."""
    mask, angles = observation.channel_observed, angle_slice(observation.skeleton)
    out = np.array(Y, dtype=float)
    out[:, angles] = rewrap_deg(out[:, angles], observation.motion.channels[:, angles], mask[:, angles])
    return out


def fill_gaps(observation: Observation, kind: str = "linear") -> np.ndarray:
    """(F, D) channel matrix with only the gaps filled: observed samples exactly as given,
    missing ones interpolated over time (``kind``: "linear" or "cubic") on unwrapped
    angles and placed on the branch of the observed sample before them."""
    p = prepare(observation, kind)
    if p.complete:
        return p.raw
    return np.where(p.mask, p.raw, p.output(p.bridged))


#: kernel radius in sigmas
TRUNCATE = 4.0


def gaussian_kernel(sigma_frames: float) -> np.ndarray:
    """Sampled zero-mean Gaussian of std ``sigma_frames``, radius ``TRUNCATE`` sigma
    (rounded), normalised to sum 1."""
    radius = int(TRUNCATE * sigma_frames + 0.5)
    i = np.arange(-radius, radius + 1, dtype=float)
    k = np.exp(-0.5 * (i / sigma_frames) ** 2)
    return k / k.sum()


def convolve_time(A: np.ndarray, kernel: np.ndarray) -> np.ndarray:
    """Convolve every column of ``A`` (F, D) with a centred odd-length ``kernel`` along
    time, zero outside the clip (FFT, exact up to rounding)."""
    F = A.shape[0]
    radius = kernel.size // 2
    if radius == 0:
        return A * kernel[0]
    n = sfft.next_fast_len(F + 2 * radius, real=True)
    spec = sfft.rfft(A, n=n, axis=0) * sfft.rfft(kernel, n=n)[:, None]
    return sfft.irfft(spec, n=n, axis=0)[radius : radius + F]


def normalized_gaussian(
    X: np.ndarray, certainty: np.ndarray, sigma_frames: float, columns: np.ndarray | None = None
) -> np.ndarray:
    """Normalised convolution of the columns of ``X`` (F, D) with a Gaussian of std
    ``sigma_frames``: ``G*(c X) / G*c``, zero padded outside the clip. ``certainty`` is
    (F, K): column ``columns[d]`` of it (default: d) is the certainty of column d of X;
    K = 1 with ``columns`` None means one certainty for all columns. It must be
    positive wherever the result is wanted."""
    X = np.asarray(X, float)
    c = np.asarray(certainty, float)
    if c.ndim == 1:
        c = c[:, None]
    if columns is None:
        columns = np.zeros(X.shape[1], int) if c.shape[1] == 1 else np.arange(X.shape[1])
    k = gaussian_kernel(sigma_frames)
    if np.all(c == 1.0):  # fully observed: one normaliser for every column
        num = convolve_time(X, k)
        den = convolve_time(np.ones((X.shape[0], 1)), k)
        return num / den
    num = convolve_time(c[:, columns] * X, k)
    den = convolve_time(c, k)
    return num / den[:, columns]
