"""``identity``: the do-nothing reference. Returns the observation unchanged, with gaps
bridged by linear interpolation of each channel over time (angles unwrapped first)."""

from __future__ import annotations

from workbench.core.channels import interpolate_gaps, unwrap_deg
from workbench.core.motion import Observation, channel_mask
from workbench.engine import CleanResult, Engine, EngineInfo


def bridge_gaps(observation: Observation, kind: str = "linear"):
    """(F, D) channel matrix of the observation with gaps interpolated (``kind`` as in
    :func:`workbench.core.channels.interpolate_gaps`), angles unwrapped."""
    mask = channel_mask(observation.observed)
    X = observation.motion.channels
    X[:, 3:] = unwrap_deg(X[:, 3:], mask[:, 3:])
    return interpolate_gaps(X, mask, kind)


class Identity(Engine):
    info = EngineInfo(
        name="identity",
        summary="returns the observation; gaps bridged linearly",
        tasks=frozenset({"fill"}),
        keeps_observed=True,
    )

    def clean(self, observation: Observation, /) -> CleanResult:
        return CleanResult(observation.motion.with_channels(bridge_gaps(observation)))
