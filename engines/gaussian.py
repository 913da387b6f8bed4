"""``gaussian``: zero-mean Gaussian smoothing of every channel over time, gap-aware.

The standard denoising baseline of Lou and Chai (2010, §4.2: "a standard Gaussian filter
applied to every degree of freedom independently") and of Mall et al. (2017, §4.1:
Gaussians with a standard deviation of 58 ms and 125 ms at 120 fps; ``gaussian`` is the
58 ms one, ``gaussian:sigma_ms=125`` the other). With ``lerp>gaussian`` it is Mall's
"lerp + Gaussian" gap-filling baseline.

Method, per channel of the channel matrix (root position included; angles unwrapped
first), sigma in frames = ``sigma_ms / 1000 * fps``, kernel truncated at 4 sigma:

* **normalised convolution** (Knutsson and Westin 1993): with certainty c (1 where
  observed) the output is ``G*(c x) / G*c``. Missing samples therefore do not count,
  and at the clip's ends, where the kernel runs off the data (zero padded), dividing by
  ``G*c`` renormalises the truncated kernel instead of pulling the signal towards 0.
* **long gaps**: missing samples are first bridged by linear interpolation and enter
  with certainty ``GAP_CERTAINTY`` = 1e-3 instead of 0. Wherever observed samples lie
  under the kernel they dominate (the interpolant's relative weight is at most 1e-3
  per sample), so the result is the normalised convolution of the observed samples;
  inside gaps wider than the kernel, where no observation reaches, the result becomes
  the smoothed interpolant, so every sample is defined and the transition is smooth.

Diagnostics: ``filter_sigma_frames`` (F, C), the kernel's std in frames for every
sample of every channel (constant).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from workbench.core.motion import Observation, channel_joints
from workbench.engine import CleanResult, Engine, EngineInfo
from workbench.engine.signal import normalized_gaussian, prepare

#: certainty of the linearly bridged samples of a gap (observed samples have 1)
GAP_CERTAINTY = 1e-3


class Gaussian(Engine):
    """Gap-aware Gaussian smoothing (Lou and Chai 2010; Mall et al. 2017's 58/125 ms)."""

    @dataclass(frozen=True)
    class Params:
        #: standard deviation of the Gaussian kernel, in milliseconds (58 and 125 in Mall et al.)
        sigma_ms: float = 58.0

        def __post_init__(self) -> None:
            if not (math.isfinite(self.sigma_ms) and self.sigma_ms > 0):
                raise ValueError(f"sigma_ms must be a positive number of milliseconds, got {self.sigma_ms}")

    info = EngineInfo(
        name="gaussian",
        summary="Gaussian smoothing of each channel over time (normalised convolution across gaps)",
        tasks=frozenset({"denoise", "fill"}),
        citation="Lou and Chai 2010 §4.2 (Gaussian filter baseline); "
        "Mall et al. 2017 §4.1 (sigma 58 ms and 125 ms at 120 fps)",
    )

    def sigma_frames(self, fps: float) -> float:
        """The kernel's std in frames at ``fps``."""
        return self.params.sigma_ms / 1000.0 * fps

    def clean(self, observation: Observation, /) -> CleanResult:
        motion = observation.motion
        sigma = self.sigma_frames(motion.fps)
        p = prepare(observation)
        # certainty per joint (the root position shares the root joint's), then per column
        cert = np.where(observation.observed, 1.0, GAP_CERTAINTY)
        Y = normalized_gaussian(p.bridged, cert, sigma, channel_joints(observation.skeleton))
        diag = {"filter_sigma_frames": np.full(Y.shape, sigma)}
        return CleanResult(motion.with_channels(p.output(Y)), diag)
