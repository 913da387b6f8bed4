"""Noise on the joint-angle channels (Mall et al. 2017 §4, Lou and Chai 2010 §4.2).

Units: angles in degrees; every level ``K`` is relative to the std of the channel in the
clean clip being corrupted (computed on unwrapped angles). Only the joint-angle channels
(the 3 rotation channels of every joint but the root) are touched: the root trajectory,
position and orientation, stays clean, as the papers assume; ``jumps`` alone moves the
body's path, as a marker swap on the pelvis or an exporter's stray frames do. Channels whose clean std is
0 (always-constant channels such as CMU's LHipJoint) get no noise from the std-relative
models and no outliers. Noise is added to the raw angles (no re-wrapping), so
``noisy - clean`` is exactly the drawn noise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.motion import body_position_column
from .base import Model, Param, Work

_K = Param("K", "scale", "noise level, in multiples of each channel's std")


def _add(work: Work, noise: np.ndarray) -> None:
    work.channels[:, work.angle_cols] += noise


@dataclass(frozen=True)
class Angular(Model):
    name = "angular"
    description = "Gaussian noise per joint-angle channel, std K x the channel's std (Mall: '0.5 noise')"
    params = (_K,)
    k: float

    def corrupt(self, work: Work, rng: np.random.Generator) -> None:
        sigma = self.k * work.angle_std
        _add(work, rng.standard_normal((work.n_frames, sigma.size)) * sigma)


@dataclass(frozen=True)
class Uniform(Model):
    name = "uniform"
    description = "uniform noise U(-a, a) per joint-angle channel with the std of angular:K (a = sqrt(3) K std)"
    params = (_K,)
    k: float

    def corrupt(self, work: Work, rng: np.random.Generator) -> None:
        a = np.sqrt(3.0) * self.k * work.angle_std
        _add(work, rng.uniform(-1.0, 1.0, (work.n_frames, a.size)) * a)


@dataclass(frozen=True)
class Bias(Model):
    name = "bias"
    description = "constant per-channel offset ~ N(0, (K std)^2) plus Gaussian noise of std K std"
    params = (_K,)
    k: float

    def corrupt(self, work: Work, rng: np.random.Generator) -> None:
        sigma = self.k * work.angle_std
        offset = rng.standard_normal(sigma.size) * sigma
        _add(work, offset + rng.standard_normal((work.n_frames, sigma.size)) * sigma)


@dataclass(frozen=True)
class Sine(Model):
    """Bias ``K std sin(2 pi f t + phase)`` per channel, t = frame / fps seconds, f drawn
    uniformly in [0.2, 1.0] Hz and the phase in [0, 2 pi), plus Gaussian noise K std."""

    name = "sine"
    description = "sinusoidal per-channel bias, amplitude K std, 0.2-1.0 Hz, random phase, plus Gaussian noise K std"
    params = (_K,)
    k: float

    F_MIN_HZ = 0.2
    F_MAX_HZ = 1.0

    def corrupt(self, work: Work, rng: np.random.Generator) -> None:
        sigma = self.k * work.angle_std
        freq = rng.uniform(self.F_MIN_HZ, self.F_MAX_HZ, sigma.size)
        phase = rng.uniform(0.0, 2.0 * np.pi, sigma.size)
        t = np.arange(work.n_frames)[:, None] / work.clean.fps
        bias = np.sin(2.0 * np.pi * freq * t + phase) * sigma
        _add(work, bias + rng.standard_normal((work.n_frames, sigma.size)) * sigma)


@dataclass(frozen=True)
class Outliers(Model):
    """Each joint-angle entry (frame, channel) whose channel has a non-zero clean std is,
    independently with probability P, an outlier: it gets ``sign * U(3, 6) * max(std,
    10 deg)`` added (sign +1 or -1 with equal chance), i.e. an error of 3 to 6 channel
    stds, and at least 30 degrees, so it is far outside the noise. Lou and Chai (2010,
    §4.2) corrupt a percentage of the entries this way."""

    name = "outliers"
    description = "a fraction P of the joint-angle entries get an error of sign x U(3, 6) x max(std, 10 deg)"
    params = (Param("P", "prob", "probability that an entry (frame, channel) is an outlier"),)
    p: float

    LOW = 3.0
    HIGH = 6.0
    FLOOR_DEG = 10.0

    def corrupt(self, work: Work, rng: np.random.Generator) -> None:
        std = work.angle_std
        shape = (work.n_frames, std.size)
        hit = (rng.random(shape) < self.p) & (std > 0)
        sign = np.where(rng.random(shape) < 0.5, -1.0, 1.0)
        size = rng.uniform(self.LOW, self.HIGH, shape) * np.maximum(std, self.FLOOR_DEG)
        _add(work, np.where(hit, sign * size, 0.0))


@dataclass(frozen=True)
class Jumps(Model):
    """At each frame, with probability P, the body leaves its path: its root (the body
    root, under a reference node) is moved by U(0.5, 2) m in a random direction for 1 to
    5 frames, the whole body with it, and is then back, as after a marker swap on the
    pelvis or an exporter's stray frames. Jumps that meet add up."""

    name = "jumps"
    description = "with probability P per frame the body jumps U(0.5, 2) m off its path for 1-5 frames"
    params = (Param("P", "prob", "probability that a jump starts at a frame"),)
    p: float

    LOW_M = 0.5
    HIGH_M = 2.0
    MAX_FRAMES = 5

    def corrupt(self, work: Work, rng: np.random.Generator) -> None:
        sk = work.skeleton
        col = body_position_column(sk)
        for start in np.flatnonzero(rng.random(work.n_frames) < self.p):
            direction = rng.standard_normal(3)
            metres = rng.uniform(self.LOW_M, self.HIGH_M)
            frames = int(rng.integers(1, self.MAX_FRAMES + 1))
            move = direction / np.linalg.norm(direction) * metres * 100.0 / sk.unit_cm
            work.channels[start : start + frames, col : col + 3] += move
