"""Operations on channel matrices (F, D) with missing samples, shared by the engines.

Time runs along axis 0 in frames. Angles are in degrees. ``observed`` masks are (F, D)
booleans (False = missing); missing samples may hold anything, usually NaN.
"""

from __future__ import annotations

import numpy as np


def forward_fill(X: np.ndarray, observed: np.ndarray) -> np.ndarray:
    """Each missing sample takes the last observed value before it (the first observed
    value before the first observation); columns with no observation become 0."""
    X = np.asarray(X, float)
    F = X.shape[0]
    idx = np.where(observed, np.arange(F)[:, None], -1)
    np.maximum.accumulate(idx, axis=0, out=idx)
    first = np.argmax(observed, axis=0)
    idx = np.where(idx < 0, first[None, :], idx)
    out = np.take_along_axis(X, idx, axis=0)
    out[:, ~observed.any(axis=0)] = 0.0
    return out


def unwrap_deg(X: np.ndarray, observed: np.ndarray | None = None) -> np.ndarray:
    """Unwrap angle columns (F, D) along time so consecutive observed samples differ by
    less than 180 degrees. Missing samples stay missing (NaN)."""
    X = np.asarray(X, float)
    if observed is None:
        observed = np.isfinite(X)
    filled = forward_fill(X, observed)
    out = np.unwrap(filled, period=360.0, axis=0)
    out[~observed] = np.nan
    return out


def interpolate_gaps(X: np.ndarray, observed: np.ndarray, kind: str = "linear") -> np.ndarray:
    """Fill missing samples of each column by interpolating the observed ones over time.

    kind: "linear" or "cubic" (natural cubic spline; linear where a column has fewer
    than 4 observations). Before the first and after the last observation the nearest
    observed value is held. Observed samples are returned unchanged. Columns with no
    observation become 0.
    """
    X = np.asarray(X, float)
    observed = np.asarray(observed, bool)
    out = np.where(observed, X, 0.0)
    F = X.shape[0]
    t = np.arange(F)
    missing_cols = np.flatnonzero((~observed).any(axis=0) & observed.any(axis=0))
    if kind == "linear":
        for c in missing_cols:
            o = observed[:, c]
            out[~o, c] = np.interp(t[~o], t[o], X[o, c])
        return out
    if kind != "cubic":
        raise ValueError(f"unknown interpolation kind {kind!r}: use 'linear' or 'cubic'")
    from scipy.interpolate import CubicSpline

    for c in missing_cols:
        o = observed[:, c]
        tt = t[~o]
        if o.sum() < 4:
            out[~o, c] = np.interp(tt, t[o], X[o, c])
            continue
        spline = CubicSpline(t[o], X[o, c], bc_type="natural")
        inside = (tt > t[o][0]) & (tt < t[o][-1])
        vals = np.interp(tt, t[o], X[o, c])  # holds the ends
        vals[inside] = spline(tt[inside])
        out[~o, c] = vals
    return out
