"""Channel helpers: retiming, gap distances, gap filling and unwrapping."""

from __future__ import annotations

import numpy as np
import pytest

from workbench.core.channels import (
    gap_distance,
    hold_ends,
    hole_length,
    interpolate_gaps,
    retime,
    rewrap_deg,
    unwrap_deg,
)
from workbench.core.rotations import wrap_deg


def test_retime_plays_faster_and_slower_by_linear_interpolation():
    X = np.stack([np.arange(11.0), np.arange(11.0) ** 2], axis=1)  # (11, 2)
    fast = retime(X, 2.0)
    assert fast.shape == (6, 2) and np.allclose(fast, X[::2])
    slow = retime(X, 0.5)
    assert slow.shape == (21, 2) and np.allclose(slow[::2], X)
    assert np.allclose(slow[1::2, 0], np.arange(10) + 0.5)  # halfway, linearly
    assert retime(np.zeros((1, 3, 3)), 1.5).shape == (1, 3, 3)
    with pytest.raises(ValueError):
        retime(X, 0.0)


def test_gap_distance_and_hole_length_count_frames_of_each_gap():
    missing = np.zeros((10, 3), bool)
    missing[2:7, 0] = True  # a gap inside the clip
    missing[:3, 1] = True  # a gap at the start
    missing[:, 2] = True  # never observed
    d = gap_distance(missing)
    assert d[:, 0].tolist() == [0, 0, 1, 2, 3, 2, 1, 0, 0, 0]
    assert d[:, 1].tolist() == [3, 2, 1, 0, 0, 0, 0, 0, 0, 0]
    assert np.isinf(d[:, 2]).all()
    h = hole_length(missing)
    assert h[:, 0].tolist() == [0, 0, 5, 5, 5, 5, 5, 0, 0, 0]
    assert np.isinf(h[:3, 1]).all() and not h[3:, 1].any()  # no observation before it
    assert np.isinf(h[:, 2]).all()


@pytest.mark.parametrize("missing", [[0, 1, 5, 6, 7, 19], [0], [4], list(range(19))])
def test_linear_gap_filling_of_whole_frames_matches_np_interp(missing):
    """Whole frames missing (one mask for most columns) are bridged all those columns at
    once; the result is np.interp's, ends held, in every column."""
    rng = np.random.default_rng(0)
    X = rng.normal(size=(20, 5))
    observed = np.ones((20, 5), bool)
    observed[missing] = False
    observed[3, 4] = False  # one column with a mask of its own
    out = interpolate_gaps(X, observed)
    t = np.arange(20)
    for c in range(5):
        o = observed[:, c]
        np.testing.assert_allclose(out[:, c], np.interp(t, t[o], X[o, c]), atol=1e-12)


def test_linear_gap_filling_of_scattered_masks_matches_np_interp():
    """Every column on a mask of its own (dropped samples, ends missing, a column never
    observed, one observed once): np.interp's result per column, ends held, 0 where
    never observed, NaNs in the missing samples never leak."""
    rng = np.random.default_rng(1)
    for F, D, keep in ((30, 6, 0.5), (7, 4, 0.2), (50, 9, 0.9)):
        X = rng.normal(size=(F, D))
        observed = rng.random((F, D)) < keep
        observed[:, 0] = False
        observed[:, 1] = False
        observed[F // 2, 1] = True
        observed[:, 2] = True
        observed[F // 3 + 1 :, 3] = False
        X[~observed] = np.nan
        out = interpolate_gaps(X, observed)
        t = np.arange(F)
        assert np.all(out[:, 0] == 0.0)
        for c in range(1, D):
            o = observed[:, c]
            expected = np.interp(t, t[o], X[o, c]) if o.any() else np.zeros(F)
            np.testing.assert_allclose(out[:, c], expected, atol=1e-12)


def test_a_gap_that_ends_one_column_and_one_that_starts_the_next_are_two_gaps():
    """The missing samples are bridged gap by gap over all columns at once: a gap that
    runs to the last frame of one column and one from the first frame of the next hold
    their own column's end values."""
    X = np.arange(12.0).reshape(4, 3) ** 2
    observed = np.ones((4, 3), bool)
    observed[2:, 0] = False  # to the end of column 0
    observed[:2, 1] = False  # from the start of column 1
    observed[1:3, 2] = False  # inside column 2
    out = interpolate_gaps(X, observed)
    assert out[:, 0].tolist() == [0.0, 9.0, 9.0, 9.0]
    assert out[:, 1].tolist() == [49.0, 49.0, 49.0, 100.0]
    np.testing.assert_allclose(out[:, 2], [4.0, 4.0 + (121.0 - 4.0) / 3, 4.0 + 2 * (121.0 - 4.0) / 3, 121.0])


def test_robust_unwrap_keeps_the_branch_after_an_outlier_near_half_a_turn():
    """A channel turning slowly through +-180 degrees; one sample 179.5 degrees off
    (wrapped), with a gap after it. np.unwrap follows the outlier and the rest of the
    take lands a whole turn away; the robust rule keeps it on its branch."""
    truth = np.linspace(150.0, 230.0, 60)[:, None]  # (60, 1), continuous
    X = wrap_deg(truth)  # wrapped to [-180, 180)
    X[30] = wrap_deg(X[30] - 179.5)  # the outlier
    observed = np.ones_like(X, bool)
    observed[40:45] = False
    plain = unwrap_deg(np.where(observed, X, np.nan), observed)
    robust = unwrap_deg(np.where(observed, X, np.nan), observed, robust=True)
    after = observed[:, 0] & (np.arange(60) > 30)
    assert np.allclose(np.abs(plain[after] - truth[after]), 360.0)
    assert np.allclose(robust[after] - truth[after], 0.0)
    assert np.all(np.isnan(robust[~observed]))
    clean = wrap_deg(truth)  # without the outlier: as np.unwrap
    assert np.array_equal(unwrap_deg(clean, robust=True), np.unwrap(clean, period=360.0, axis=0))


def test_rewrap_puts_unwrapped_angles_back_on_the_reference_s_branch_in_place_or_not():
    """Each column follows its observed reference's turn, a missing sample its last
    observed one's; ``copy=False`` shifts a view of a larger array in place, the same."""
    rng = np.random.default_rng(0)
    reference = rng.uniform(-180.0, 180.0, (50, 4))
    turns = rng.integers(-2, 3, (1, 4)) * 360.0
    Y = reference - turns + rng.normal(0.0, 1.0, reference.shape)
    observed = rng.random(reference.shape) > 0.2
    observed[0] = True
    expected = Y + turns
    copied = rewrap_deg(Y, reference, observed)
    np.testing.assert_allclose(copied, expected)
    channels = np.concatenate([np.zeros((50, 3)), Y], axis=1)
    view = channels[:, 3:]
    assert rewrap_deg(view, reference, observed, copy=False) is view
    np.testing.assert_array_equal(channels[:, 3:], copied)
    assert not np.array_equal(Y, copied)  # the default leaves its input as it was
    with pytest.raises(ValueError, match="float64"):  # a converted copy would be shifted, silently
        rewrap_deg(Y.astype(np.float32), reference, observed, copy=False)


def test_hold_ends_holds_each_columns_first_and_last_observation_and_keeps_the_rest():
    X = np.arange(24.0).reshape(6, 4)
    observed = np.ones((6, 4), bool)
    observed[:2, 0] = observed[-1, 0] = False  # held at both ends
    observed[2:4, 1] = False  # a gap inside: untouched
    observed[:, 2] = False  # no observation: as it is
    observed[:, 3] = np.arange(6) == 4  # one observation: everywhere
    out = hold_ends(X, observed)
    np.testing.assert_array_equal(out[:, 0], [8.0, 8.0, 8.0, 12.0, 16.0, 16.0])
    np.testing.assert_array_equal(out[:, 1:3], X[:, 1:3])
    np.testing.assert_array_equal(out[:, 3], 19.0)
    np.testing.assert_array_equal(hold_ends(X[:1], observed[:1]), X[:1])
