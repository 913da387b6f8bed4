"""``butterworth``: zero-phase Butterworth low-pass of every channel over time.

The biomechanics default for smoothing marker and joint-angle trajectories (Winter,
*Biomechanics and Motor Control of Human Movement*, ch. 3: a 4th-order low-pass run
forward and backward, cut-off around 6 Hz for gait). Implementation: ``scipy.signal.butter``
in second-order sections and ``sosfiltfilt`` along time, with scipy's default odd-extension
padding of the ends. ``cutoff_hz`` is the -3 dB frequency of one pass; the forward-backward
pass doubles the order, has no phase lag, and is -6 dB there.

Every channel of the channel matrix is filtered (root position included; angles
unwrapped first); gaps are bridged by linear interpolation before filtering.
A clip must be longer than the filter's padding (3 x (2 x sections + 1) frames, 15
for order 4) and the cut-off below the Nyquist frequency fps / 2; otherwise
``clean`` raises EngineError.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.signal import butter, sosfiltfilt

from workbench.core.motion import Observation
from workbench.engine import CleanResult, Engine, EngineError, EngineInfo
from workbench.engine.signal import prepare


def _padlen(sos: np.ndarray) -> int:
    """scipy's default padding for sosfiltfilt."""
    return 3 * (2 * len(sos) + 1 - min(int((sos[:, 2] == 0).sum()), int((sos[:, 5] == 0).sum())))


class Butterworth(Engine):
    """Zero-phase Butterworth low-pass filter (biomechanics default: 4th order, 6 Hz)."""

    @dataclass(frozen=True)
    class Params:
        #: cut-off (-3 dB of a single pass) in hertz; must be below fps / 2
        cutoff_hz: float = 6.0
        #: filter order of one pass (the zero-phase double pass doubles it)
        order: int = 4

        def __post_init__(self) -> None:
            if not (math.isfinite(self.cutoff_hz) and self.cutoff_hz > 0):
                raise ValueError(f"cutoff_hz must be a positive frequency in Hz, got {self.cutoff_hz}")
            if not 1 <= self.order <= 20:
                raise ValueError(f"order must be an integer from 1 to 20, got {self.order}")

    info = EngineInfo(
        name="butterworth",
        summary="zero-phase Butterworth low-pass of each channel (gaps bridged linearly first)",
        tasks=frozenset({"denoise", "fill"}),
        citation="Winter, Biomechanics and Motor Control of Human Movement, ch. 3 "
        "(4th-order zero-lag Butterworth, ~6 Hz)",
    )

    def sos(self, fps: float) -> np.ndarray:
        nyquist = fps / 2.0
        if self.params.cutoff_hz >= nyquist:
            raise EngineError(
                f"engine 'butterworth': cutoff_hz={self.params.cutoff_hz} must be below the Nyquist "
                f"frequency of this take ({nyquist:g} Hz at {fps:g} fps)"
            )
        return butter(self.params.order, self.params.cutoff_hz, btype="low", fs=fps, output="sos")

    def clean(self, observation: Observation, /) -> CleanResult:
        motion = observation.motion
        sos = self.sos(motion.fps)
        pad = _padlen(sos)
        if motion.n_frames <= pad:
            raise EngineError(
                f"engine 'butterworth': the take has {motion.n_frames} frames; a zero-phase order-"
                f"{self.params.order} filter needs more than {pad} (its edge padding). Use a longer take "
                f"or a lower order."
            )
        p = prepare(observation)
        Y = sosfiltfilt(sos, p.bridged, axis=0, padlen=pad)
        return CleanResult(motion.with_channels(p.output(Y)))
