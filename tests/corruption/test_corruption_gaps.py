"""Missing-data models: gaps, block, joints, drop."""

from __future__ import annotations

import numpy as np
import pytest

from workbench.corruption import Gaps, parse_corruption, random_stream
from workbench.corruption.base import Work


def _runs(column: np.ndarray) -> list[tuple[int, int]]:
    """(start, length) of each run of False in a boolean column."""
    missing = np.concatenate([[False], ~column, [False]]).astype(int)
    edges = np.diff(missing)
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    return list(zip(starts, ends - starts))


def _check_nan_matches_mask(obs):
    assert np.array_equal(np.isnan(obs.motion.channels), ~obs.channel_observed)


def test_gaps_start_rate_and_mean_length(long_walk):
    F, J = long_walk.n_frames, long_walk.skeleton.n_joints
    model = Gaps(0.01, 12.0, 10**6)  # uncapped
    frames, joints, lengths = model.events(Work(long_walk), random_stream(0, 0, "gaps"))
    assert abs(frames.size / (F * (J - 1)) / 0.01 - 1) < 0.1
    assert joints.min() >= 1
    assert lengths.min() >= 1
    assert abs(lengths.mean() / 12 - 1) < 0.1
    # exponential decay: P(L > 24) = (1 - 1/12)^24 for the discrete exponential
    assert abs(np.mean(lengths > 24) - (11 / 12) ** 24) < 0.03


def test_gaps_mask_is_the_union_of_the_events(walk):
    F, J = walk.n_frames, walk.skeleton.n_joints
    seed = 5
    obs = parse_corruption("gaps:0.02,8,20").apply(walk, seed=seed)
    frames, joints, lengths = Gaps(0.02, 8, 20).events(Work(walk), random_stream(seed, 0, "gaps"))
    expect = np.ones((F, J), bool)
    for f, j, n in zip(frames, joints, lengths):
        expect[f : f + n, j] = False
    assert np.array_equal(obs.observed, expect)
    assert obs.observed[:, 0].all()  # never the root
    assert lengths.max() <= 20
    _check_nan_matches_mask(obs)


def test_gaps_measured_from_the_mask(long_walk):
    """With rare gaps (little overlap) the runs in the mask show the start rate and mean
    length directly."""
    F, J = long_walk.n_frames, long_walk.skeleton.n_joints
    p, mean = 0.003, 10
    runs = []
    for seed in range(3):
        obs = parse_corruption(f"gaps:{p},{mean},100000").apply(long_walk, seed=seed)
        assert obs.observed[:, 0].all()
        for j in range(1, J):
            runs += [n for s, n in _runs(obs.observed[:, j]) if s + n < F]  # not cut by the clip end
    rate = len(runs) / (3 * F * (J - 1))
    # overlapping gaps merge: expect a few per cent fewer, longer runs
    assert 0.85 < rate / p < 1.08
    assert 0.9 < np.mean(runs) / mean < 1.15


def test_gaps_cap(long_walk):
    J = long_walk.skeleton.n_joints
    _, _, lengths = Gaps(0.01, 50, 7).events(Work(long_walk), random_stream(1, 0, "gaps"))
    assert lengths.max() == 7 and lengths.min() >= 1
    # with rare gaps, runs in the mask respect the cap too (unless two overlap)
    obs = parse_corruption("gaps:0.0005,50,7").apply(long_walk, seed=1)
    runs = [n for j in range(J) for _, n in _runs(obs.observed[:, j])]
    assert runs and np.mean(np.array(runs) <= 7) > 0.95


def test_gaps_longer_than_the_clip_are_cut(walk):
    obs = parse_corruption("gaps:0.01,1000,100000").apply(walk, seed=0)
    assert obs.observed.shape == (walk.n_frames, walk.skeleton.n_joints)
    assert not obs.observed.all()


@pytest.mark.parametrize("n", [1, 30, 120])
def test_block_length_and_placement(walk, n):
    F = walk.n_frames
    for seed in range(5):
        obs = parse_corruption(f"block:{n}").apply(walk, seed=seed)
        missing_frames = np.flatnonzero(~obs.observed.all(axis=1))
        assert missing_frames.size == n
        assert np.all(np.diff(missing_frames) == 1)  # one block
        s = missing_frames[0]
        assert 1 <= s and s + n <= F - 1  # an observed frame on each side
        assert not obs.observed[s : s + n].any()  # all joints, root too
        assert obs.observed[:s].all() and obs.observed[s + n :].all()
        assert np.isnan(obs.motion.root_positions[s : s + n]).all()
        _check_nan_matches_mask(obs)


def test_block_start_is_uniform_over_the_allowed_range(walk):
    clip = walk.slice(0, 24)
    n = 20  # starts 1, 2, 3 allowed
    starts = [int(np.argmin(parse_corruption(f"block:{n}").apply(clip, seed=s).observed[:, 0])) for s in range(120)]
    counts = np.bincount(starts, minlength=5)
    assert counts[0] == 0 and counts[4] == 0
    assert np.all(counts[1:4] > 20)


def test_block_fixed_start(walk):
    obs = parse_corruption("block:40,100").apply(walk, seed=3)
    missing = np.flatnonzero(~obs.observed[:, 0])
    assert missing[0] == 100 and missing[-1] == 139 and missing.size == 40
    same = parse_corruption("block:40,100").apply(walk, seed=4)
    assert np.array_equal(obs.observed, same.observed)
    parse_corruption(f"block:40,{walk.n_frames - 41}").apply(walk)  # last allowed start


def test_joints_missing_for_the_whole_clip(walk):
    constant = {"LHipJoint", "RHipJoint", "LeftShoulder", "RightShoulder"}
    seen = set()
    for seed in range(30):
        obs = parse_corruption("joints:3").apply(walk, seed=seed)
        missing = np.flatnonzero(~obs.observed.all(axis=0))
        assert missing.size == 3
        assert 0 not in missing  # never the root
        assert not obs.observed[:, missing].any()  # whole clip
        assert obs.observed[:, np.setdiff1d(np.arange(walk.skeleton.n_joints), missing)].all()
        names = {walk.skeleton.names[j] for j in missing}
        assert not names & constant
        seen |= names
        _check_nan_matches_mask(obs)
    assert len(seen) > 15  # drawn among many joints
    obs = parse_corruption("joints:24").apply(walk, seed=0)  # all varying joints
    assert (~obs.observed.all(axis=0)).sum() == 24


def test_drop_fraction(long_walk):
    p = 0.2
    obs = parse_corruption(f"drop:{p}").apply(long_walk, seed=0)
    assert obs.observed[:, 0].all()
    frac = 1 - obs.observed[:, 1:].mean()
    assert abs(frac / p - 1) < 0.05
    # independent over joints and frames: per-joint fractions agree
    per_joint = 1 - obs.observed[:, 1:].mean(axis=0)
    assert np.all(np.abs(per_joint - p) < 0.04)
    assert parse_corruption("drop:1").apply(long_walk.slice(0, 10)).observed[:, 1:].sum() == 0


def test_gap_models_do_not_change_observed_values(walk):
    for text in ("gaps:0.02", "block:30", "joints:4", "drop:0.3"):
        obs = parse_corruption(text).apply(walk, seed=1)
        m = obs.channel_observed
        assert np.array_equal(obs.motion.channels[m], walk.channels[m]), text
        assert obs.observed[:, 0].all() or text.startswith("block")
