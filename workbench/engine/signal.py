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
  Unwrapping also follows a joint through gimbal lock (:func:`euler_flips`): there its
  exporter's Euler triple jumps to the other triple of the same rotation (a, b, c) ->
  (a + 180, 180 - b, c + 180), which a filter of each channel would smooth into a
  rotation 100 degrees and more off; the filter sees the triple continued, and the
  output is put back on the jumping one.
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
from ..core.rotations import alternative_euler, wrap_deg
from .smoothing import measurement_variance

__all__ = [
    "EulerFlips",
    "euler_flips",
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
class EulerFlips:
    """Where a take's joints pass through gimbal lock and their Euler triples jump to the
    other triple of the same rotation (made by :func:`euler_flips`).

    Attributes
    ----------
    joints : ndarray of int, shape (K,)
        The joints whose triples jump.
    other : ndarray of bool, shape (F, K)
        True where a frame's triple is read as the other one to continue the one before
        (:func:`workbench.core.rotations.alternative_euler`); a missing frame as the
        observed frame before it.
    """

    joints: np.ndarray
    other: np.ndarray

    def onto(self, channels: np.ndarray, reference: np.ndarray, observed: np.ndarray) -> None:
        """Put the joints' triples of a channel matrix (F, D) on the triples of
        ``reference`` (F, D, the take's channels; ``observed`` (F, D) where they are
        known, the last known one standing for a missing frame), in place: at each frame
        the one of the two triples of its rotation nearer the reference's (whole turns
        left to :func:`workbench.core.channels.rewrap_deg`). Unlike :meth:`swap` it can
        be applied twice (an engine's own output, then its model view's)."""
        for j in self.joints:
            cols = slice(3 + 3 * j, 6 + 3 * j)
            near = forward_fill(reference[:, cols], observed[:, cols])
            mine = channels[:, cols]
            other = alternative_euler(mine)
            closer = np.sum(wrap_deg(other - near) ** 2, axis=1) < np.sum(wrap_deg(mine - near) ** 2, axis=1)
            channels[closer, cols] = other[closer]

    def swap(self, channels: np.ndarray) -> None:
        """Replace the flagged frames' triples of a channel matrix (F, D) by their other
        triples, in place: from the take's to the continued ones and back (the same
        rotations; equal to the originals modulo 360)."""
        for k, j in enumerate(self.joints):
            cols = slice(3 + 3 * j, 6 + 3 * j)  # joint j's angles (angle_slice: after the root position)
            rows = self.other[:, k]
            channels[rows, cols] = alternative_euler(channels[rows, cols])


#: how near gimbal lock (degrees of the middle angle) a joint's triple may jump to the other one
LOCK_DEG = 60.0
#: the most white noise (std, degrees, from the median second difference) a joint's angles
#: may carry for its jumps to be told from noise: the two triples lie 250 degrees and more
#: apart, and noise near that would flip the reading at random frames (Bandai's spine near
#: lock under ``angular:0.5``: 15-50 degrees a channel)
NOISE_LIMIT_DEG = 10.0


def euler_flips(observation: Observation) -> EulerFlips | None:
    """The joints of ``observation`` whose Euler triple jumps, between observed frames, to
    the other triple of the same rotation (nearer to the frame before than its own, both
    middle angles beyond :data:`LOCK_DEG` on one side), and where; None where none does
    (most takes). Joints noisier than :data:`NOISE_LIMIT_DEG` are left out, and so are jumps
    across a gap. A joint can only jump where its first and third angles both span 180
    degrees or more, so only those are looked at."""
    skeleton, F = observation.skeleton, observation.n_frames
    angles = observation.motion.channels[:, angle_slice(skeleton)]
    if F < 2:
        return None
    with np.errstate(invalid="ignore"):
        span = (np.fmax.reduce(angles, axis=0) - np.fmin.reduce(angles, axis=0)).reshape(-1, 3)  # NaN-ignoring
    candidates = np.flatnonzero((span[:, 0] >= 180.0) & (span[:, 2] >= 180.0))
    if not candidates.size:
        return None
    seen = observation.observed[:, candidates]
    triples = angles.reshape(F, -1, 3)[:, candidates].reshape(F, -1)
    filled = forward_fill(triples, np.repeat(seen, 3, axis=1)).reshape(F, -1, 3)  # a gap: no jump inside it
    # a joint as noisy as a lock's two triples are near is left as it is (noise would flip
    # it), and so is one with no three frames observed in a row to measure its noise on;
    # the measure is robust (a median) to the jumps themselves
    noise = measurement_variance(filled.reshape(F, -1), np.repeat(seen, 3, axis=1)).reshape(-1, 3)
    runs = (seen[:-2] & seen[1:-1] & seen[2:]).any(axis=0)
    quiet = runs & (np.sqrt(noise.max(axis=1)) <= NOISE_LIMIT_DEG)
    if not quiet.any():
        return None
    candidates, filled, seen = candidates[quiet], filled[:, quiet], seen[:, quiet]
    before, now = filled[:-1], filled[1:]
    own = np.sum(wrap_deg(now - before) ** 2, axis=-1)
    other = np.sum(wrap_deg(alternative_euler(now) - before) ** 2, axis=-1)
    # both middle angles near the same lock (+-90), where the two triples meet: an outlier,
    # which may also lie nearer the other triple, is no reason to read the take otherwise
    locked = (np.abs(before[..., 1]) > LOCK_DEG) & (np.abs(now[..., 1]) > LOCK_DEG) & (before[..., 1] * now[..., 1] > 0)
    # between frames observed one after the other: across a gap the motion may have turned
    # the other triple's way on its own
    jumps = (other < own) & locked & seen[:-1] & seen[1:]  # (F - 1, K)
    jumping = jumps.any(axis=0)
    if not jumping.any():
        return None
    flags = np.zeros((F, int(jumping.sum())), bool)
    flags[1:] = np.cumsum(jumps[:, jumping], axis=0) % 2 == 1  # each jump switches the triple read
    return EulerFlips(candidates[jumping], flags)


@dataclass(frozen=True)
class Prepared:
    """An observation's channel matrix, ready for filtering (made by :func:`prepare`).

    Attributes
    ----------
    raw : ndarray, shape (F, D)
        The channels as observed, NaN where missing.
    mask : ndarray of bool, shape (F, D)
        True where observed.
    bridged : ndarray, shape (F, D)
        Angles unwrapped along time, gaps interpolated. Treat as read-only: it may be
        ``raw`` itself when there is nothing to unwrap or fill.
    wrapped : ndarray of int
        The columns whose unwrapping changed something.
    complete : bool
        Nothing is missing.
    flips : EulerFlips or None
        The joints whose triples :attr:`bridged` continues through gimbal lock.
    """

    raw: np.ndarray
    mask: np.ndarray
    bridged: np.ndarray
    wrapped: np.ndarray
    complete: bool
    flips: EulerFlips | None = None

    def output(self, Y: np.ndarray) -> np.ndarray:
        """Put a filtered matrix of unwrapped angles back on the input's angle branch.

        Parameters
        ----------
        Y : ndarray, shape (F, D)
            A filter's output of :attr:`bridged`: degrees and file units.

        Returns
        -------
        ndarray, shape (F, D)
            ``Y`` with the unwrapped angle columns shifted by whole turns to follow the
            raw angles (:func:`workbench.core.channels.rewrap_deg`): equal to ``Y``
            modulo 360; the :attr:`flips` joints' triples on the raw ones' (the same
            rotations).
        """
        if not self.wrapped.size:
            return Y
        Y = np.array(Y, dtype=float)
        if self.flips is not None:
            self.flips.swap(Y)
        w = self.wrapped
        Y[:, w] = rewrap_deg(Y[:, w], self.raw[:, w], self.mask[:, w])
        return Y


def prepare(observation: Observation, kind: str = "linear", *, through_lock: bool = True) -> Prepared:
    """Unwrap and bridge an observation's channel matrix for a filter.

    Only the columns that need it are touched (most takes have no angle wrapping and
    no gaps). Angles are unwrapped robustly to outliers
    (:func:`workbench.core.channels.unwrap_deg`).

    Parameters
    ----------
    observation : Observation
        The take as an engine sees it (NaN where missing).
    kind : {"linear", "cubic"}
        How gaps are bridged (:func:`workbench.core.channels.interpolate_gaps`).
    through_lock : bool
        Continue the triples of joints that pass through gimbal lock (:func:`euler_flips`);
        False: keep the take's own triples, jumps and all (as a network trained on them
        saw them).

    Returns
    -------
    Prepared
        The raw matrix, its mask and the bridged matrix; ``output`` puts a result back.
    """
    mask = observation.channel_observed
    raw = source = observation.motion.channels
    complete = bool(observation.observed.all())
    flips = euler_flips(observation) if through_lock else None
    if flips is not None:  # the triples continued through gimbal lock, then unwrapped as any
        source = raw.copy()
        flips.swap(source)
    # only a column spanning 180 degrees or more can step by that much between samples
    first = angle_slice(observation.skeleton).start
    angles = source[:, angle_slice(observation.skeleton)]
    span = np.fmax.reduce(angles, axis=0) - np.fmin.reduce(angles, axis=0)  # NaN-ignoring
    wide = np.flatnonzero(span >= 180.0)
    wrapped = np.zeros(0, int)
    if wide.size:
        a = angles[:, wide] if complete else forward_fill(angles[:, wide], mask[:, first + wide])
        wrapped = first + wide[(np.abs(np.diff(a, axis=0)) >= 180.0).any(axis=0)]
    X = source
    if wrapped.size:
        X = source.copy() if source is raw else source
        X[:, wrapped] = unwrap_deg(source[:, wrapped], mask[:, wrapped], robust=True)
    if flips is not None:  # put back on the raw triples by output(), with the columns they touch
        touched = (first + 3 * flips.joints[:, None] + np.arange(3)).ravel()
        wrapped = np.union1d(wrapped, touched)
    if not complete:
        X = interpolate_gaps(X, mask, kind)
    return Prepared(raw, mask, X, wrapped, complete, flips)


def bridge_gaps(observation: Observation, kind: str = "linear", *, through_lock: bool = True) -> np.ndarray:
    """The observation's channel matrix, angles unwrapped and gaps interpolated.

    Parameters
    ----------
    observation : Observation
    kind : {"linear", "cubic"}
        As in :func:`prepare`.
    through_lock : bool
        As in :func:`prepare`.

    Returns
    -------
    ndarray, shape (F, D)
        A new array (degrees and file units), finite everywhere.
    """
    p = prepare(observation, kind, through_lock=through_lock)
    return p.bridged.copy() if p.bridged is p.raw else p.bridged


def rewrap_angles(Y: np.ndarray, observation: Observation, *, copy: bool = True) -> np.ndarray:
    """Shift the angle channels of ``Y`` by whole turns onto the observation's branch
    (and a joint's triples continued through gimbal lock back onto the observation's,
    :func:`euler_flips`).

    Parameters
    ----------
    Y : ndarray, shape (F, D)
        A channel matrix of unwrapped angles, e.g. a filtered :func:`bridge_gaps`.
    observation : Observation
        The input whose angle branch the output follows.
    copy : bool
        False: shift ``Y`` (a writable float64 array) in place and return it, sparing a
        long take's (F, D) copy.

    Returns
    -------
    ndarray, shape (F, D)
        An array equal to ``Y`` modulo 360 that reads like the input (a new one unless
        ``copy=False``).
    """
    mask, angles, motion = observation.channel_observed, angle_slice(observation.skeleton), observation.motion
    out = np.array(Y, dtype=float, copy=copy)
    if (flips := euler_flips(observation)) is not None:  # onto the take's own triples first
        flips.onto(out, motion.channels, mask)
    rewrap_deg(out[:, angles], motion.angles_deg.reshape(motion.n_frames, -1), mask[:, angles], copy=False)
    return out


def fill_gaps(observation: Observation, kind: str = "linear") -> np.ndarray:
    """Fill only the gaps of an observation's channel matrix.

    Parameters
    ----------
    observation : Observation
    kind : {"linear", "cubic"}
        How gaps are bridged, on unwrapped angles.

    Returns
    -------
    ndarray, shape (F, D)
        Observed samples exactly as given; missing ones interpolated over time and put
        on the branch of the observed sample before them.
    """
    p = prepare(observation, kind)
    if p.complete:
        return p.raw
    return np.where(p.mask, p.raw, p.output(p.bridged))


#: kernel radius in sigmas
TRUNCATE = 4.0


def gaussian_kernel(sigma_frames: float, max_radius: int | None = None) -> np.ndarray:
    """A sampled zero-mean Gaussian kernel, normalised to sum 1.

    Parameters
    ----------
    sigma_frames : float
        Its standard deviation, in frames (> 0).
    max_radius : int, optional
        The most frames it may reach each way (a filter of a clip of F frames never
        reaches further than F - 1).

    Returns
    -------
    ndarray, shape (2 r + 1,)
        The kernel, of radius ``r = round(TRUNCATE * sigma_frames)`` frames (at most
        ``max_radius``).
    """
    radius = int(TRUNCATE * sigma_frames + 0.5)
    if max_radius is not None:
        radius = min(radius, max_radius)
    i = np.arange(-radius, radius + 1, dtype=float)
    k = np.exp(-0.5 * (i / sigma_frames) ** 2)
    return k / k.sum()


def convolve_time(A: np.ndarray, kernel: np.ndarray) -> np.ndarray:
    """Convolve every column with a centred kernel along time, zero outside the clip.

    Parameters
    ----------
    A : ndarray, shape (F, D)
    kernel : ndarray, shape (K,)
        Odd length, centred.

    Returns
    -------
    ndarray, shape (F, D)
        By FFT, exact up to rounding.
    """
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
    """Gaussian smoothing along time that lets missing samples and the ends not count.

    The normalised convolution of Knutsson and Westin (1993), ``G*(c X) / G*c``, zero
    padded outside the clip.

    Parameters
    ----------
    X : ndarray, shape (F, D)
    certainty : ndarray, shape (F, K) or (F,)
        The weight of each sample, positive wherever the result is wanted (0: ignored).
    sigma_frames : float
        The Gaussian's standard deviation, in frames.
    columns : ndarray of int, shape (D,), optional
        Column ``columns[d]`` of ``certainty`` is the certainty of column ``d`` of ``X``
        (default: ``d``; with K = 1, one certainty for all columns).

    Returns
    -------
    ndarray, shape (F, D)
    """
    X = np.asarray(X, float)
    c = np.asarray(certainty, float)
    if c.ndim == 1:
        c = c[:, None]
    if columns is None:
        columns = np.zeros(X.shape[1], int) if c.shape[1] == 1 else np.arange(X.shape[1])
    k = gaussian_kernel(sigma_frames, max_radius=X.shape[0] - 1)  # zero beyond: the ratio is the same
    if np.all(c == 1.0):  # fully observed: one normaliser for every column
        num = convolve_time(X, k)
        den = convolve_time(np.ones((X.shape[0], 1)), k)
        return num / den
    num = convolve_time(c[:, columns] * X, k)
    den = convolve_time(c, k)
    return num / den[:, columns]
