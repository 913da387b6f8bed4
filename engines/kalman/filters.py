"""``kalman``: per-channel constant-velocity Kalman filter with a Rauch-Tung-Striebel
smoother that skips missing samples.

Lou and Chai (2010, §4.2)'s "general Kalman filter" baseline (after Welch and Bishop's
introduction to the Kalman filter): every degree of freedom filtered independently with
a fixed, hand-chosen motion model. Theirs is a random walk (``z(t+1) = z(t) + N(0, s)``);
ours is the constant-velocity model (velocity a random walk), which follows smooth
motion at 120 fps without lag; see :mod:`workbench.engine.smoothing` for the model and
the exact banded solver of its RTS smoother.

Noise variances, per channel (channel units: degrees for angles, the file unit for the
root position and any translations):

* measurement variance ``r`` [deg^2]: from the median absolute second difference of the
  observed samples, ``r = (1.4826 median|d2|)^2 / 6`` (white noise of variance r gives
  second differences of variance 6 r; the smooth signal adds little at 120 fps);
* process variance ``q`` [deg^2 / frame^4, the variance of the per-frame change of
  velocity]: ``q = r / lambda`` with ``lambda`` minimising Stein's unbiased risk
  estimate of the smoother's output error, computed from the channel's periodogram
  (:func:`~workbench.engine.smoothing.smoothing_ratio`).

On CMU test clips with Gaussian noise of 0.1, 0.5 and 0.9 x each channel's std, the
estimated noise std is within ~10 % of the true one and the smoothed error is within
~3-10 % of the best per-channel choice of q found with the ground truth.

``measurement_noise_deg2`` / ``process_noise_deg2_per_frame4`` > 0 fix ``r`` / ``q`` for
every joint-angle channel (root rotation included) instead; the root position and
translation channels, in other units, always use the estimates. Gaps are bridged by the smoother itself;
before an angle channel's first observation and after its last, its smoothed value there is
held (:func:`hold_angle_ends`: Lou and Chai's random walk's prediction), where the
constant-velocity model's path, run on at the end's velocity, is 1.4 to 3.4 times further
off over 0.25-2 s; the root's position keeps that path, which follows a walker 2-6 times
nearer than a held one (docs/engines/kalman.md, *A take's ends*).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from workbench.core.channels import hold_ends
from workbench.core.motion import Observation, angle_slice, length_columns
from workbench.core.skeleton import Skeleton
from workbench.engine import CleanResult, Engine, EngineInfo
from workbench.engine.signal import bridge_gaps, prepare
from workbench.engine.smoothing import cv_smooth, estimate_noise, measurement_variance, smoothing_ratio


def smooth_channels(X: np.ndarray, mask: np.ndarray, r_angles: float = 0.0, q_angles: float = 0.0, lengths=(0, 1, 2)):
    """Kalman-smooth a bridged channel matrix ``X`` (F, D) (unwrapped angles, gaps
    interpolated linearly) with its observed ``mask`` (F, D); constant channels stay.
    Returns the smoothed matrix and the ``(q, r)`` (D,) variances used. ``r_angles`` /
    ``q_angles`` > 0 override the estimates on the angle channels: all but the
    ``lengths`` columns (the root position and any translations, in file units:
    :func:`workbench.core.motion.length_columns`)."""
    Y = X.copy()
    const = X.max(axis=0) == X.min(axis=0)  # linear bridging stays within the observed range
    active = np.flatnonzero(~const)
    D = X.shape[1]
    q = np.zeros(D)
    r = np.full(D, np.nan)
    if active.size:
        Xa, Ma = X[:, active], mask[:, active]
        angle = ~np.isin(active, lengths)
        ra = measurement_variance(Xa, Ma)
        if r_angles > 0:
            ra[angle] = r_angles
        qa = ra / smoothing_ratio(Xa, ra, Ma.mean(axis=0))
        if q_angles > 0:
            qa[angle] = q_angles
        Y[:, active] = cv_smooth(Xa, Ma, qa, ra)
        q[active], r[active] = qa, ra
    return Y, (q, r)


def hold_angle_ends(Y: np.ndarray, mask: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """A smoothed channel matrix ``Y`` (F, D) of ``skeleton`` with each angle channel
    (:func:`workbench.core.motion.angle_slice`) held at its value at its first and last
    observed frame of ``mask`` (F, D) beyond them (:func:`workbench.core.channels.hold_ends`);
    ``Y`` itself where nothing is missing, else a new array."""
    if mask.all():
        return Y
    angles = angle_slice(skeleton)
    out = Y.copy()
    out[:, angles] = hold_ends(Y[:, angles], mask[:, angles])
    return out


class Kalman(Engine):
    """Constant-velocity Kalman filter + RTS smoother per channel (Lou and Chai's general
    Kalman filter baseline), noise estimated from the data unless given."""

    @dataclass(frozen=True)
    class Params:
        #: measurement noise variance of the joint-angle channels in deg^2; 0 = estimate per channel
        measurement_noise_deg2: float = 0.0
        #: process noise: variance of the per-frame velocity change in deg^2/frame^4; 0 = estimate
        process_noise_deg2_per_frame4: float = 0.0

        def __post_init__(self) -> None:
            for name in ("measurement_noise_deg2", "process_noise_deg2_per_frame4"):
                value = getattr(self, name)
                if not (math.isfinite(value) and value >= 0):
                    raise ValueError(f"{name} must be >= 0 (0 = estimate from the data), got {value}")

    info = EngineInfo(
        name="kalman",
        summary="constant-velocity Kalman filter + RTS smoother per channel; noise estimated from the data",
        tasks=frozenset({"denoise", "fill"}),
        citation="Lou and Chai 2010 §4.2 (general Kalman filter baseline); "
        "Welch and Bishop 2001, An introduction to the Kalman filter; "
        "Rauch, Tung and Striebel 1965",
    )

    def clean(self, observation: Observation, /) -> CleanResult:
        p = prepare(observation)
        Y, _ = smooth_channels(
            p.bridged,
            p.mask,
            self.params.measurement_noise_deg2,
            self.params.process_noise_deg2_per_frame4,
            length_columns(observation.skeleton),
        )
        return CleanResult(observation.motion.with_channels(p.output(hold_angle_ends(Y, p.mask, observation.skeleton))))

    @staticmethod
    def estimate_noise(observation: Observation) -> tuple[np.ndarray, np.ndarray]:
        """The ``(q, r)`` (C,) variances the estimator gives for every channel."""
        return estimate_noise(bridge_gaps(observation), observation.channel_observed)
