"""``median``: a running median of every channel over time, robust to outliers, as a
third-party engine would write it with the public ``workbench`` API alone.

Units: ``window_ms`` in milliseconds, turned into an odd number of frames at the take's
rate; channels as in :attr:`workbench.core.motion.Motion.channels` (angles in degrees,
lengths in file units). Angles are unwrapped and gaps bridged linearly first
(:func:`workbench.engine.signal.prepare`), and the result is put back on the input's
angle branch.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from scipy.ndimage import median_filter

from workbench.core.motion import Observation
from workbench.engine import CleanResult, Engine, EngineInfo
from workbench.engine.signal import prepare


class Median(Engine):
    """Running median of each channel over ``window_ms``."""

    @dataclass(frozen=True)
    class Params:
        #: the median's window, in milliseconds
        window_ms: float = 100.0

        def __post_init__(self) -> None:
            if not (math.isfinite(self.window_ms) and self.window_ms > 0):
                raise ValueError(f"window_ms must be a positive number of milliseconds, got {self.window_ms}")

    info = EngineInfo(
        name="median",
        summary="running median of each channel over time (a third-party example)",
        tasks=frozenset({"denoise", "fill"}),
    )

    def window_frames(self, fps: float) -> int:
        """The window at ``fps``: an odd number of frames, at least 1."""
        return 2 * int(round(self.params.window_ms / 1000.0 * fps / 2.0)) + 1

    def clean(self, observation: Observation, /) -> CleanResult:
        p = prepare(observation)
        size = (self.window_frames(observation.motion.fps), 1)
        return CleanResult(
            observation.motion.with_channels(p.output(median_filter(p.bridged, size=size, mode="nearest")))
        )
