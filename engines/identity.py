"""``identity``: the do-nothing reference. Returns the observation unchanged, with gaps
bridged by linear interpolation of each channel over time (angles unwrapped first,
robust to outliers: :func:`workbench.core.channels.unwrap_deg`).
"""

from __future__ import annotations

from workbench.core.motion import Observation
from workbench.engine import CleanResult, Engine, EngineInfo
from workbench.engine.signal import fill_gaps


class Identity(Engine):
    info = EngineInfo(
        name="identity",
        summary="returns the observation; gaps bridged linearly",
        tasks=frozenset({"fill"}),
        keeps_observed=True,
    )

    def clean(self, observation: Observation, /) -> CleanResult:
        return CleanResult(observation.motion.with_channels(fill_gaps(observation)))
