"""``lerp`` and ``spline``: gap filling by interpolating each channel over time.

``lerp`` is the linear interpolation Mall et al. (2017, §4.2) use to close gaps before a
Gaussian filter ("lerp + Gaussian": ``lerp>gaussian``); ``spline`` uses a natural cubic
spline through every observed sample of the channel instead (linear where a channel has
fewer than 4 observations). Both work on the channel matrix (root position included),
with the angles unwrapped before interpolating; observed samples come back exactly as
given and values before the first / after the last observation hold the nearest
observed one. Neither denoises.
"""

from __future__ import annotations

from workbench.core.motion import Observation
from workbench.engine import CleanResult, Engine, EngineInfo
from workbench.engine.signal import fill_gaps


class Lerp(Engine):
    """Linear interpolation across gaps (Mall et al. 2017's "lerp")."""

    info = EngineInfo(
        name="lerp",
        summary="fills gaps by linear interpolation of each channel; observed samples kept",
        tasks=frozenset({"fill"}),
        keeps_observed=True,
        citation="Mall et al. 2017, Deep recurrent mocap cleaning, §4.2 (lerp + Gaussian baseline)",
    )

    def clean(self, observation: Observation, /) -> CleanResult:
        return CleanResult(observation.motion.with_channels(fill_gaps(observation, "linear")))


class Spline(Engine):
    """Natural cubic spline interpolation across gaps."""

    info = EngineInfo(
        name="spline",
        summary="fills gaps with a natural cubic spline through each channel's observed samples",
        tasks=frozenset({"fill"}),
        keeps_observed=True,
        citation="cubic spline gap filling, the standard mocap-software fill (e.g. Vicon's spline fill)",
    )

    def clean(self, observation: Observation, /) -> CleanResult:
        return CleanResult(observation.motion.with_channels(fill_gaps(observation, "cubic")))
