"""Statistics of the joint-angle noise models, measured on a long clean clip."""

from __future__ import annotations

import numpy as np
import pytest

from workbench.core.channels import unwrap_deg
from workbench.core.motion import angle_columns
from workbench.corruption import parse_corruption


@pytest.fixture(scope="module")
def clip(long_walk):
    """(motion, angle columns, clean std per angle column)."""
    cols = angle_columns(long_walk.skeleton)
    std = unwrap_deg(long_walk.channels[:, cols]).std(axis=0)
    std[std <= 1e-9] = 0.0
    assert (std == 0).sum() >= 6 and (std > 0).sum() >= 60  # CMU: constant LHipJoint, shoulders ...
    return long_walk, cols, std


def _noise(motion, text, seed=0):
    """(F, D) corrupted minus clean channels."""
    out = parse_corruption(text).apply(motion, seed=seed).motion.channels
    return out - motion.channels


def _root_untouched(motion, d, cols):
    assert np.array_equal(d[:, :6], np.zeros((motion.n_frames, 6)))  # root position and orientation
    others = np.setdiff1d(np.arange(d.shape[1]), cols)
    assert np.all(d[:, others] == 0)


@pytest.mark.parametrize("k", [0.1, 0.5])
def test_angular_std_per_channel(clip, k):
    motion, cols, std = clip
    d = _noise(motion, f"angular:{k}")
    _root_untouched(motion, d, cols)
    dn = d[:, cols]
    live = std > 0
    assert np.all(dn[:, ~live] == 0)  # constant channels get no noise
    ratio = dn[:, live].std(axis=0) / (k * std[live])
    assert np.all(np.abs(ratio - 1) < 0.05), ratio
    assert abs(np.mean(dn[:, live] / (k * std[live]))) < 0.01
    # Gaussian: about 4.6 % of samples beyond 2 sigma
    z = dn[:, live] / (k * std[live])
    assert abs(np.mean(np.abs(z) > 2) - 0.0455) < 0.005


def test_a_half_turn_capture_glitch_does_not_scale_a_channels_noise(long_walk):
    """A joint flipped by half a turn and back for a few frames (as in CMU 35_26's
    RightFingerBase) leaves np.unwrap a whole turn behind; the noise must follow the
    channel's real spread, not that turn."""
    cols = angle_columns(long_walk.skeleton)
    c = cols[10]
    motion = long_walk.slice(0, 400)
    channels = motion.channels.copy()
    channels[200:203, c] = [120.0, -178.0, -57.0]
    glitched = motion.with_channels(channels)
    assert unwrap_deg(channels[:, [c]]).std() > 100  # the whole turn a plain unwrap leaves
    spread = unwrap_deg(channels[:, [c]], robust=True).std()
    d = _noise(glitched, "angular:0.5")[:, c]
    assert spread < 20 and abs(d.std() / (0.5 * spread) - 1) < 0.15


def test_uniform_range_and_std(clip):
    motion, cols, std = clip
    k = 0.5
    d = _noise(motion, f"uniform:{k}")
    _root_untouched(motion, d, cols)
    live = std > 0
    dn = d[:, cols][:, live]
    a = np.sqrt(3) * k * std[live]
    assert np.all(np.abs(dn) <= a * (1 + 1e-12))
    assert np.all(dn.max(axis=0) > 0.99 * a) and np.all(dn.min(axis=0) < -0.99 * a)
    ratio = dn.std(axis=0) / (k * std[live])
    assert np.all(np.abs(ratio - 1) < 0.05), ratio
    # flat histogram: each quarter of the range holds about a quarter of the samples
    u = dn / a
    for lo in (-1, -0.5, 0, 0.5):
        assert abs(np.mean((u >= lo) & (u < lo + 0.5)) - 0.25) < 0.01
    assert np.all(d[:, cols][:, ~live] == 0)


def test_bias_is_constant_over_time(clip):
    motion, cols, std = clip
    k = 0.5
    d = _noise(motion, f"bias:{k}", seed=3)
    _root_untouched(motion, d, cols)
    live = std > 0
    z = d[:, cols][:, live] / (k * std[live])  # offset + N(0, 1), in units of K std
    F = z.shape[0]
    halves = z[: F // 2].mean(axis=0), z[F // 2 :].mean(axis=0)
    # constant offset: the two halves agree to the noise of a mean (1 / sqrt(F / 2))
    assert np.all(np.abs(halves[0] - halves[1]) < 5 * np.sqrt(4 / F))
    offsets = z.mean(axis=0)
    assert 0.7 < offsets.std() < 1.3  # offsets ~ N(0, 1) over ~80 channels
    resid = z - offsets
    assert np.all(np.abs(resid.std(axis=0) - 1) < 0.05)
    # a different seed gives different offsets
    z2 = _noise(motion, f"bias:{k}", seed=4)[:, cols][:, live] / (k * std[live])
    assert np.corrcoef(offsets, z2.mean(axis=0))[0, 1] < 0.5


def test_sine_is_one_slow_sinusoid_plus_noise(clip):
    motion, cols, std = clip
    k = 0.5
    d = _noise(motion, f"sine:{k}", seed=2)
    _root_untouched(motion, d, cols)
    live = std > 0
    z = d[:, cols][:, live] / (k * std[live])  # sin(2 pi f t + phase) + N(0, 1)
    F = z.shape[0]
    t = np.arange(F) / motion.fps
    freqs = np.arange(0.1, 1.1, 0.001)
    arg = 2 * np.pi * freqs[:, None] * t[None, :]
    c, s = np.cos(arg) @ z, np.sin(arg) @ z  # (n_freq, channels)
    amp = 2 / F * np.hypot(c, s)
    best = amp.argmax(axis=0)
    f_best = freqs[best]
    assert np.all((f_best > 0.2 - 0.005) & (f_best < 1.0 + 0.005)), f_best
    assert np.all(np.abs(amp[best, np.arange(z.shape[1])] - 1) < 0.1)
    # the frequencies spread over the band
    assert f_best.min() < 0.35 and f_best.max() > 0.85
    # removing the fitted sinusoid leaves white noise of std K std
    for ch in range(z.shape[1]):
        A = np.stack([np.sin(2 * np.pi * f_best[ch] * t), np.cos(2 * np.pi * f_best[ch] * t), np.ones(F)], 1)
        coef, *_ = np.linalg.lstsq(A, z[:, ch], rcond=None)
        resid = z[:, ch] - A @ coef
        assert abs(resid.std() - 1) < 0.05
        assert abs(np.hypot(coef[0], coef[1]) - 1) < 0.1
        # periodic: the smoothed difference repeats after one period
        period = int(round(motion.fps / f_best[ch]))
        smooth = np.convolve(z[:, ch], np.ones(60) / 60, mode="valid")
        assert np.corrcoef(smooth[:-period], smooth[period:])[0, 1] > 0.9


def test_outliers_fraction_and_size(clip):
    motion, cols, std = clip
    p = 0.05
    d = _noise(motion, f"outliers:{p}", seed=1)
    _root_untouched(motion, d, cols)
    live = std > 0
    dn = d[:, cols]
    assert np.all(dn[:, ~live] == 0)
    hit = dn[:, live] != 0
    assert abs(hit.mean() / p - 1) < 0.05
    size = np.abs(dn[:, live]) / np.maximum(std[live], 10.0)
    assert np.all((size[hit] >= 3 - 1e-9) & (size[hit] <= 6 + 1e-9))
    assert abs(np.mean(dn[:, live][hit] > 0) - 0.5) < 0.03
    assert abs(size[hit].mean() - 4.5) < 0.05
    assert np.all(_noise(motion, "outliers:0") == 0)


@pytest.mark.parametrize("text", ["angular:0.5", "uniform:0.5", "bias:0.5", "sine:0.5", "outliers:0.1"])
def test_noise_models_leave_root_and_mask_alone(walk, text):
    obs = parse_corruption(text).apply(walk, seed=9)
    assert obs.observed.all()
    assert np.array_equal(obs.motion.root_positions, walk.root_positions)
    assert np.array_equal(obs.motion.angles_deg[:, 0], walk.angles_deg[:, 0])
    assert not np.array_equal(obs.motion.angles_deg, walk.angles_deg)


def test_zero_level_is_identity(walk):
    for text in (
        "angular:0",
        "uniform:0",
        "bias:0",
        "sine:0",
        "spatial:0",
        "spatial-ends:0,0",
        "outliers:0",
        "gaps:0",
        "block:0",
        "joints:0",
        "drop:0",
    ):
        obs = parse_corruption(text).apply(walk, seed=1)
        assert obs.observed.all(), text
        assert np.array_equal(obs.motion.channels, walk.channels), text


def test_other_skeleton(daz):
    obs = parse_corruption("angular:0.5+outliers:0.01+sine:0.2").apply(daz, seed=0)
    assert obs.observed.all() and np.isfinite(obs.motion.channels).all()
    assert np.array_equal(obs.motion.root_positions, daz.root_positions)


@pytest.mark.parametrize("take", ["walk", "studio_take"])
def test_jumps_move_the_body_off_its_path_and_back(take, request):
    """Only the body root's position channels move (a studio take's Hips translation
    under its reference node), by 0.5-2 m for 1 to 5 frames, the rest of the body with it."""
    motion = request.getfixturevalue(take)
    obs = parse_corruption("jumps:0.02").apply(motion, seed=4)
    assert obs.observed.all() and np.array_equal(obs.motion.angles_deg, motion.angles_deg)
    b = motion.skeleton.body_root
    moved_m = (
        np.linalg.norm(obs.motion.positions[:, b] - motion.positions[:, b], axis=1) * motion.skeleton.unit_cm / 100
    )
    away = moved_m > 0
    runs = np.diff(np.flatnonzero(np.diff(np.r_[0, away.astype(int), 0])))[::2]  # lengths of the runs off the path
    assert away.sum() >= 5 and runs.max() <= 2 * 5  # two jumps that meet add up
    assert moved_m[away].min() > 0.05 and moved_m[away].max() < 2 * 2.0 + 1e-9
    offset = (obs.motion.positions - motion.positions)[away, b:]  # the whole body moves with its root
    np.testing.assert_allclose(offset, np.broadcast_to(offset[:, :1], offset.shape), atol=1e-6)
    assert (obs.motion.positions[:, :b] == motion.positions[:, :b]).all()  # a reference node above it stays
    assert np.array_equal(parse_corruption("jumps:0.02").apply(motion, seed=4).motion.channels, obs.motion.channels)
