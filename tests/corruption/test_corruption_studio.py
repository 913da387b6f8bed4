"""Corruption of studio takes: six channels on every joint, a moving Hips under a
reference root, 30 fps; and time spans given in seconds."""

from __future__ import annotations

import numpy as np
import pytest

from workbench.core.motion import angle_slice
from workbench.corruption import CorruptionApplyError, Gaps, parse_corruption, random_stream
from workbench.corruption.base import Work
from workbench.metrics import bone_lengths


def test_angle_noise_leaves_the_trajectory_and_the_translations_alone(studio_take, stretchy_take):
    for take in (studio_take, stretchy_take):
        obs = parse_corruption("angular:0.5+outliers:0.05").apply(take, seed=1)
        noisy = obs.motion
        np.testing.assert_array_equal(noisy.root_positions, take.root_positions)
        np.testing.assert_array_equal(noisy.translations, take.translations)  # the Hips, a stretchy forearm
        np.testing.assert_array_equal(noisy.angles_deg[:, :2], take.angles_deg[:, :2])  # joint_Root, Hips
        changed = np.abs(noisy.angles_deg[:, 2:] - take.angles_deg[:, 2:]).max(axis=(0, 2))
        assert (changed > 0).all()


def test_missing_data_models_hide_body_joints_and_their_translations(studio_take, stretchy_take):
    for spec in ("gaps:0.05", "drop:0.2", "joints:4"):
        obs = parse_corruption(spec).apply(studio_take, seed=2)
        assert obs.observed[:, :2].all(), spec  # never the trajectory's joints
        assert not obs.observed.all(), spec
    obs = parse_corruption("block:1s").apply(stretchy_take, seed=2)
    hidden = ~obs.observed.all(axis=1)
    assert hidden.sum() == 30 and (~obs.observed[hidden]).all()  # 1 s at 30 fps, every joint
    assert np.isnan(obs.motion.translations[hidden]).all() and np.isfinite(obs.motion.translations[~hidden]).all()
    assert np.array_equal(np.isnan(obs.motion.channels), ~obs.channel_observed)


def test_spatial_noise_moves_the_hips_keeps_the_bones_and_the_stretch(studio_take, stretchy_take):
    sk = studio_take.skeleton
    obs = parse_corruption("spatial:1").apply(studio_take, seed=3)
    rigid = [j for j in range(2, sk.n_joints)]  # every bone below the Hips
    lengths = bone_lengths(obs.motion.positions, sk.parents)[:, [j - 1 for j in rigid]]
    assert np.allclose(lengths, np.linalg.norm(sk.offsets[rigid], axis=1)[None], rtol=0, atol=1e-9)
    hips = obs.motion.positions[:, 1] - studio_take.positions[:, 1]
    assert 0.5 < np.linalg.norm(hips, axis=1).mean() < 3.0  # noise of 1 cm per axis, about 1.6 cm
    stretched = parse_corruption("spatial:1").apply(stretchy_take, seed=3).motion
    length = np.linalg.norm(stretched.translations[:, 1], axis=1)
    true = np.linalg.norm(stretchy_take.translations[:, 1], axis=1)
    assert np.abs(length - true).mean() < 2.5 and np.ptp(true) > 3.0  # it stretches still, with the noise


def test_a_span_in_seconds_is_the_same_time_at_30_and_120_fps(studio_take, walk):
    for take, fps in ((studio_take, 30), (walk, 120)):
        obs = parse_corruption("block:0.5s").apply(take, seed=0)
        assert (~obs.observed.all(axis=1)).sum() == fps // 2
        _, _, lengths = Gaps(0.05, parse_corruption("gaps:0.05,0.2s").models[0].mean).events(
            Work(take), random_stream(0, 0, "gaps")
        )
        assert lengths.mean() == pytest.approx(0.2 * fps, rel=0.15)
    fixed = parse_corruption("block:10,1s").apply(studio_take, seed=0)
    assert np.flatnonzero(~fixed.observed[:, 5])[0] == 30  # START in seconds too
    assert str(parse_corruption("gaps:0.0003,2s,4S")) == "gaps:0.0003,2s,4s"


def test_a_span_shorter_than_a_frame_or_a_take_is_refused_clearly(studio_take):
    with pytest.raises(CorruptionApplyError, match=r"MEAN = 0.01s is 0.3 frames at 30 fps; it must be at least 1"):
        parse_corruption("gaps:0.1,0.01s").apply(studio_take)
    with pytest.raises(CorruptionApplyError, match="block:10s needs a clip of at least 302 frames"):
        parse_corruption("block:10s").apply(studio_take)
    with pytest.raises(CorruptionApplyError, match=r"N = 0.01s is 0 frames at 30 fps; it must be at least 1"):
        parse_corruption("block:0.01s").apply(studio_take)
    assert parse_corruption("block:0s").apply(studio_take).observed.all()  # no block, as block:0


def test_a_studio_take_s_channel_matrix(studio_take):
    """Root position, 22 joints' angles, then the Hips' translation: 72 columns."""
    sk = studio_take.skeleton
    assert studio_take.channels.shape == (studio_take.n_frames, 3 + 3 * 22 + 3)
    assert angle_slice(sk) == slice(3, 69)
    np.testing.assert_array_equal(studio_take.channels[:, 69:], studio_take.translations[:, 0])
    assert studio_take.with_channels(studio_take.channels).allclose(studio_take, atol=0)
