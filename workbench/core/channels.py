"""Operations on channel matrices (F, D) with missing samples, shared by the engines.

Time runs along axis 0 in frames. Angles are in degrees. ``observed`` masks are (F, D)
booleans (False = missing); missing samples may hold anything, usually NaN.
"""

from __future__ import annotations

import numpy as np

#: frames taken at a time where a whole-take temporary would be (F, D): 4096 frames of
#: a hundred channels are 3 MB, a long take's whole matrix 50 MB
_BLOCK_FRAMES = 4096


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


def hold_ends(X: np.ndarray, observed: np.ndarray) -> np.ndarray:
    """``X`` (F, D) with each column's samples before its first observation and after its
    last replaced by its values there (a new array); columns with no observation as they
    are. The frames between are untouched, gaps included."""
    F = X.shape[0]
    first = np.argmax(observed, axis=0)
    last = F - 1 - np.argmax(observed[::-1], axis=0)
    idx = np.clip(np.arange(F)[:, None], first, last)  # no observation: 0 and F - 1, every frame itself
    return np.take_along_axis(X, idx, axis=0)


def unwrap_deg(X: np.ndarray, observed: np.ndarray | None = None, *, robust: bool = False) -> np.ndarray:
    """Unwrap angle columns (F, D) along time: each sample is put within 180 degrees of
    the one before (``np.unwrap``) or, ``robust``, of the median of the three unwrapped
    samples before it (of the one before, in the first three frames). ``np.unwrap``
    follows every sample, so one outlier near 180 degrees away from its neighbours can
    leave a whole turn behind it for the rest of the take, which a smoother then blurs
    into up to 180 degrees of error around it; the robust rule keeps the take on its
    branch. Observations and the corruption models' channel statistics are unwrapped
    robustly; clean training takes with ``np.unwrap``. Columns whose consecutive
    samples all differ by less than 180 degrees come back as they are. Missing samples
    stay missing (NaN); the others are unwrapped as if each gap held the last observed
    value."""
    X = np.asarray(X, float)
    if observed is None:
        observed = np.isfinite(X)
    observed = np.asarray(observed, bool)
    complete = bool(observed.all())
    filled = X.copy() if complete else forward_fill(X, observed)
    steps = np.abs(np.diff(filled, axis=0)) >= 180.0
    cols = np.flatnonzero(steps.any(axis=0))
    if cols.size and robust:
        out = filled[:, cols]
        for t in range(1, out.shape[0]):
            out[t] = robust_unwrap_step(out[t], out[max(t - 3, 0) : t])
        filled[:, cols] = out
    elif cols.size:
        filled[:, cols] = np.unwrap(filled[:, cols], period=360.0, axis=0)
    if not complete:
        filled[~observed] = np.nan
    return filled


def robust_unwrap_step(sample: np.ndarray, before) -> np.ndarray:
    """``sample`` (C,) degrees, shifted by whole turns to within 180 degrees of the median
    of ``before``, the (up to) three unwrapped samples before it, oldest first (of the
    last one, when there are fewer than three): one step of :func:`unwrap_deg` with
    ``robust``, which a stream takes frame by frame."""
    if len(before) < 3:
        ref = before[-1]
    else:
        a, b, c = before[-3], before[-2], before[-1]
        ref = a + b + c - np.maximum(np.maximum(a, b), c) - np.minimum(np.minimum(a, b), c)
    return sample - 360.0 * np.round((sample - ref) / 360.0)


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
        # the columns missing exactly where the first one is (e.g. whole frames missing)
        # are bridged in one step at those frames, the others all together
        pattern = observed[:, missing_cols]
        shared = (pattern == pattern[:, :1]).all(axis=0)
        if shared.sum() > 1:
            o, cols = pattern[:, 0], missing_cols[shared]
            out[np.ix_(~o, cols)] = _bridge_linearly(t[o], X[np.ix_(o, cols)], t[~o])
            missing_cols = missing_cols[~shared]
        if missing_cols.size:
            _bridge_columns(X, observed, missing_cols, out)
        return out
    if kind != "cubic":
        raise ValueError(f"unknown interpolation kind {kind!r}: use 'linear' or 'cubic'")
    from scipy.interpolate import CubicSpline

    # one spline per group of columns sharing the same observed samples (the three
    # angles of a joint always do): same result as column by column, far fewer calls
    for cols in _same_mask_groups(observed, missing_cols):
        o = observed[:, cols[0]]
        tt = t[~o]
        vals = _bridge_linearly(t[o], X[np.ix_(o, cols)], tt)  # holds the ends
        if o.sum() >= 4:
            spline = CubicSpline(t[o], X[np.ix_(o, cols)], bc_type="natural", axis=0)
            inside = (tt > t[o][0]) & (tt < t[o][-1])
            vals[inside] = spline(tt[inside])
        out[np.ix_(~o, cols)] = vals
    return out


def _bridge_linearly(known: np.ndarray, values: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Values (len(at), C) at the times ``at`` interpolated linearly from ``values`` (K, C)
    at the increasing times ``known`` (K,), the end values held outside them: what
    ``np.interp`` does per column, for all columns at once."""
    if len(known) == 1:
        return np.repeat(values, len(at), axis=0)
    right = np.clip(np.searchsorted(known, at), 1, len(known) - 1)
    left = right - 1
    w = np.clip((at - known[left]) / (known[right] - known[left]), 0.0, 1.0)[:, None]
    return values[left] * (1.0 - w) + values[right] * w


def _bridge_columns(X: np.ndarray, observed: np.ndarray, cols: np.ndarray, out: np.ndarray) -> None:
    """Set the missing samples of the columns ``cols`` of ``out`` (F, D) to those of ``X``
    (F, D) interpolated linearly between the observed samples around them, the end
    values held outside them, each column on its own ``observed`` mask (F, D) and
    observed at least once: what ``np.interp`` does per column, for all at once, in time
    and memory proportional to the missing samples (a tenth of a take with gaps)."""
    F = X.shape[0]
    c, f = np.nonzero(~observed[:, cols].T)  # the missing samples by column, then frame
    key = c * (F + 1) + f  # consecutive within a gap only: columns are F + 1 apart
    step = np.diff(key) != 1
    starts, ends = np.r_[True, step], np.r_[step, True]
    gap = np.cumsum(starts) - 1
    before, after = f[starts][gap] - 1, f[ends][gap] + 1  # the observed frames around each gap
    before = np.where(before < 0, after, before)  # before the first observation: hold it
    after = np.where(after >= F, before, after)  # after the last: hold it
    col = cols[c]
    a, b = X[before, col], X[after, col]
    span = after - before
    out[f, col] = a + (b - a) * ((f - before) / np.where(span > 0, span, 1))


def _same_mask_groups(observed: np.ndarray, cols: np.ndarray) -> list[np.ndarray]:
    """``cols`` grouped by identical columns of ``observed``."""
    if not len(cols):
        return []
    packed = np.packbits(observed[:, cols], axis=0).T
    _, inverse = np.unique(packed, axis=0, return_inverse=True)
    inverse = np.ravel(inverse)
    return [cols[inverse == g] for g in range(inverse.max() + 1)]


def rewrap_deg(Y: np.ndarray, reference: np.ndarray, observed: np.ndarray, *, copy: bool = True) -> np.ndarray:
    """Put unwrapped angle columns ``Y`` (F, D) back on the branch of ``reference``.

    ``reference`` holds the original (wrapped) angles at the ``observed`` samples; each
    observed sample's whole-turn offset ``reference - Y`` (rounded to a multiple of
    360) is added to ``Y`` there, and missing samples take the offset of the last
    observed sample before them (of the first one, before the first observation). The
    result equals ``Y`` modulo 360 everywhere; where ``Y`` is the unwrapped reference,
    it is the reference again. Columns with no observation are returned unchanged.
    ``copy=False``: ``Y`` (a writable float64 array, a view included) is shifted in place
    and returned, sparing a long take's (F, D) copy; any other ``Y`` raises ValueError
    (a converted copy would be shifted instead, silently).
    """
    if not copy and not (isinstance(Y, np.ndarray) and Y.dtype == np.float64):
        raise ValueError("rewrap_deg(copy=False) shifts a float64 array in place; this Y would be converted first")
    Y, reference = np.asarray(Y, float), np.asarray(reference, float)
    out = Y.copy() if copy else Y
    observed = np.asarray(observed, bool)
    off_branch = np.zeros(Y.shape[1], bool)
    with np.errstate(invalid="ignore"):
        for i in range(0, Y.shape[0], _BLOCK_FRAMES):  # in blocks of frames: no (F, D) temporaries
            rows = slice(i, i + _BLOCK_FRAMES)
            off_branch |= (np.abs(reference[rows] - Y[rows]) >= 180.0).any(axis=0)  # NaN compares False
        cols = np.flatnonzero(off_branch)
        if cols.size:
            obs = observed[:, cols]
            turns = np.where(obs, np.round((reference[:, cols] - Y[:, cols]) / 360.0), 0.0)
            out[:, cols] += 360.0 * forward_fill(turns, obs)
    return out


def interpolate_frames(X: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Samples (F, ...) at fractional frame times ``t`` (any shape, within [0, F - 1]) by
    linear interpolation: shape ``t.shape + X.shape[1:]``. Needs F >= 2."""
    t = np.asarray(t, float)
    i = np.minimum(np.floor(t).astype(int), X.shape[0] - 2)
    w = (t - i).reshape(t.shape + (1,) * (X.ndim - 1))
    return X[i] * (1 - w) + X[i + 1] * w


def known_at(known: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Which entries of a mask (F, ...) hold at fractional frame times ``t`` (n,), within
    [0, F - 1]: where both frames around a time are known (at a whole time, that frame).
    Needs F >= 2."""
    return interpolate_frames(known.astype(float), t) > 1 - 1e-9


def retime(X: np.ndarray, speed: float) -> np.ndarray:
    """Samples (F, ...) played ``speed`` times as fast: linear interpolation in time at
    frames 0, speed, 2 speed, ... up to F - 1, giving (floor((F - 1) / speed) + 1, ...).
    Angle columns must be unwrapped first."""
    X = np.asarray(X, float)
    if not speed > 0:
        raise ValueError(f"speed must be positive, got {speed}")
    if X.shape[0] < 2:
        return X.copy()
    return interpolate_frames(X, np.arange(0.0, X.shape[0] - 1 + 1e-9, speed))


def _observed_around(missing: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Frame numbers (F, C) of each sample, of the last observed sample at or before it
    (-inf if none) and of the first at or after it (inf if none), per column."""
    missing = np.asarray(missing, bool)
    frame = np.arange(missing.shape[0], dtype=float)
    by_column = np.ascontiguousarray(missing.T)  # (C, F): each column's frames adjacent for the scans
    last = np.where(by_column, -np.inf, frame)
    np.maximum.accumulate(last, axis=1, out=last)
    following = np.where(by_column[:, ::-1], np.inf, frame[::-1])
    np.minimum.accumulate(following, axis=1, out=following)
    return np.broadcast_to(frame[:, None], missing.shape), last.T, following[:, ::-1].T


def gap_distance(missing: np.ndarray) -> np.ndarray:
    """(F, C) frames from each sample to the nearest observed sample of its column, for a
    missing mask (F, C); 0 where observed, inf in a column with no observed sample."""
    frame, last, following = _observed_around(missing)
    return np.minimum(frame - last, following - frame)


def hole_length(missing: np.ndarray) -> np.ndarray:
    """(F, C) length in frames of the run of missing samples each sample lies in, for a
    missing mask (F, C); 0 where observed, inf where the run touches the start or the end
    of the take (nothing observed on one side)."""
    _, last, following = _observed_around(missing)
    return np.where(missing, following - last - 1.0, 0.0)
