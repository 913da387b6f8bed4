"""``identity``: the do-nothing reference. Returns the observation unchanged, with gaps
bridged by linear interpolation of each channel over time (angles unwrapped first,
robust to outliers: :func:`workbench.core.channels.unwrap_deg`).

Shared helpers for the channel-matrix engines live here too: :func:`prepare` (the
observation's channel matrix as given, its channel mask, and the matrix with angles
unwrapped and gaps interpolated, plus :meth:`Prepared.output` to put a filtered result
back on the input's angle branch), :func:`bridge_gaps`, :func:`rewrap_angles` and
:func:`fill_gaps`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.core.channels import forward_fill, interpolate_gaps, rewrap_deg, unwrap_deg
from workbench.core.motion import Observation, angle_slice
from workbench.engine import CleanResult, Engine, EngineInfo


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
    span = np.fmax.reduce(angles, axis=0) - np.fmin.reduce(angles, axis=0)    # NaN-ignoring
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


class Identity(Engine):
    info = EngineInfo(
        name="identity",
        summary="returns the observation; gaps bridged linearly",
        tasks=frozenset({"fill"}),
        keeps_observed=True,
    )

    def clean(self, observation: Observation, /) -> CleanResult:
        return CleanResult(observation.motion.with_channels(fill_gaps(observation)))
