"""The view trained engines model a take in (workbench.engine.view): the body rooted at the
pelvis, at the weights' rate; and the committed weights picked by the take's skeleton."""

from __future__ import annotations

import numpy as np
import pytest

from workbench import metrics, registry
from workbench.core.motion import Observation
from workbench.core.rotations import wrap_deg
from workbench.corruption import parse_corruption
from workbench.engine import CleanResult, EngineError
from workbench.engine.view import ModelView, body_skeleton, from_body, resample, to_body


def test_a_reference_node_collapses_into_the_body_root(studio_take, walk):
    body = body_skeleton(studio_take.skeleton)
    assert body.names[0] == "Hips" and body.n_joints == studio_take.skeleton.n_joints - 1
    assert body.has_position[0] and body.has_rotation[0] and not body.translated
    assert body_skeleton(walk.skeleton) is walk.skeleton and to_body(walk) is walk
    view = to_body(studio_take)
    np.testing.assert_allclose(view.positions, studio_take.positions[:, 1:], atol=1e-9)
    assert from_body(view, studio_take).allclose(studio_take, atol=1e-9)


def test_a_moving_reference_node_is_kept_and_the_body_placed_under_it(studio_take):
    """joint_Root turned and carried: the body view is the body in the world, and back in
    the take's skeleton the reference node moves as it did."""
    F = studio_take.n_frames
    root = np.array([100.0, 0.0, -50.0]) + np.linspace(0, 30, F)[:, None]
    angles = studio_take.angles_deg.copy()
    angles[:, 0] = np.stack([np.linspace(0, 40, F), np.linspace(-20, 60, F), np.full(F, 10.0)], axis=1)
    take = studio_take.replace(root_positions=root, angles_deg=angles)
    view = to_body(take)
    np.testing.assert_allclose(view.positions, take.positions[:, 1:], atol=1e-8)
    back = from_body(view, take)
    np.testing.assert_allclose(back.positions, take.positions, atol=1e-8)
    np.testing.assert_allclose(back.root_positions, take.root_positions)


@pytest.mark.parametrize("spec", ["ebf", "cae", "mssa", "ebd>ebf"])
def test_a_stretchy_bone_is_modelled_rigid_and_keeps_its_translation(spec, stretchy_take):
    """A forearm that stretches by 10 % (Perception Neuron's displacement export does
    this on every joint): the engines clean the angles on a rigid bone of its median
    length, and the stretch comes back as observed, gaps bridged."""
    body = body_skeleton(stretchy_take.skeleton)
    k = stretchy_take.skeleton.index("LowerArm_L")
    assert (
        not body.translated and body.signature() == body_skeleton(without_stretch(stretchy_take).skeleton).signature()
    )
    obs = parse_corruption("angular:0.5+gaps:0.01").apply(stretchy_take, 0)
    cleaned = registry.create(spec).clean(obs).motion
    t = stretchy_take.skeleton.translated.index(k)
    assert cleaned.skeleton is obs.skeleton
    np.testing.assert_array_equal(cleaned.translations[:, t], obs.bridged().translations[:, t])
    assert np.isfinite(cleaned.channels).all()
    rigid = registry.create(spec).clean(
        parse_corruption("angular:0.5+gaps:0.01").apply(without_stretch(stretchy_take), 0)
    )
    assert metrics.rms_angle_deg(stretchy_take, cleaned) < 1.1 * metrics.rms_angle_deg(
        without_stretch(stretchy_take), rigid.motion
    )


def without_stretch(take):
    """The studio take the stretchy one was made from: its forearm rigid again."""
    sk = take.skeleton
    return take.replace(skeleton=sk.replace(translated=sk.translated[:-1]), translations=take.translations[:, :-1])


def test_a_30_fps_take_is_seen_at_120_and_comes_back_with_its_observed_samples(studio_take):
    obs = parse_corruption("block:1s").apply(studio_take, 0)
    view = ModelView.of(obs, 120.0)
    assert view.observation.motion.fps == 120.0 and view.observation.n_frames == 4 * (obs.n_frames - 1) + 1
    assert view.observation.skeleton.n_joints == 21 and view.observation.capture_step == 4.0
    assert ModelView.of(obs, 30.0).observation.capture_step == 1.0
    # a frame between two observed ones is observed; one next to the gap is not
    assert view.observation.observed[::4].tolist() == obs.observed[:, 1:].tolist()
    D = view.observation.motion.channels.shape[1]
    sigma = np.full((view.observation.n_frames, D), 8.0)
    result = view.restore(CleanResult(view.observation.bridged(), {"filter_sigma_frames": sigma}), keep_observed=True)
    mask = obs.channel_observed
    assert result.motion.n_frames == obs.n_frames and result.motion.skeleton is obs.skeleton
    np.testing.assert_array_equal(result.motion.channels[mask], obs.motion.channels[mask])
    assert np.isfinite(result.motion.channels).all()
    width = result.diagnostics["filter_sigma_frames"]
    assert width.shape == mask.shape and set(np.unique(width)) == {0.0, 2.0}  # 8 frames at 120 fps: 2 at 30
    assert not width[:, :6].any()  # the reference node: no counterpart


def test_resampling_keeps_both_ends_at_a_ratio_that_is_not_whole(walk):
    slow = resample(walk, 50.0)
    assert slow.n_frames == int(np.ceil((walk.n_frames - 1) * 50 / 120)) + 1
    np.testing.assert_allclose(slow.positions[[0, -1]], walk.positions[[0, -1]], atol=1e-9)
    view = ModelView.of(Observation(walk), 50.0)
    assert view.observation.capture_step == 1.0  # resampled down: each frame still measured
    back = view.restore(CleanResult(view.observation.motion)).motion
    assert back.n_frames == walk.n_frames
    np.testing.assert_allclose(back.positions[[0, -1]], walk.positions[[0, -1]], atol=1e-9)


@pytest.mark.parametrize("spec", ["cae", "mssa:space=positions,universal=true"])
def test_an_engine_that_sees_a_30_fps_take_at_120_measures_its_noise_on_the_captured_frames(spec, studio_take):
    """Measured on every frame of the view, the noise of a 30-fps take seen at 120 fps is
    next to none (three frames in four are interpolated): these engines left angular noise
    in (cae 0.92 of the noisy take's angle error, universal mssa 1.1); measured on the
    captured frames they remove most of it (0.60, 0.62; kalman at 30 fps 0.50)."""
    from workbench.core.motion import angle_columns

    obs = parse_corruption("angular:0.5").apply(studio_take, 0)
    cols = angle_columns(studio_take.skeleton)

    def error(m):
        return np.sqrt(np.mean(wrap_deg(m.channels[:, cols] - studio_take.channels[:, cols]) ** 2))

    assert error(registry.create(spec).clean(obs).motion) < 0.7 * error(obs.motion)


def test_training_takes_are_shown_as_the_engine_models_them(studio_take, walk):
    cae, mssa = registry.create("cae", pretrained=False), registry.create("mssa", pretrained=False)
    (seen,) = cae.training_motions([studio_take])
    assert seen.fps == cae.MODEL_FPS == 120.0 and seen.skeleton.names[0] == "Hips"
    assert mssa.training_motions([studio_take])[0].fps == 30.0  # mssa trains at the takes' rate
    with pytest.raises(EngineError, match="mix frame rates"):
        mssa.training_motions([walk, walk.replace(fps=60.0)])


def test_committed_weights_are_picked_by_the_take_s_skeleton(studio_take, walk):
    engine = registry.create("mssa")
    folders = engine.committed_weights()
    assert {f.name for f in folders.values()} >= {"bandai", "cmu"}
    for take in (walk.slice(0, 100), studio_take, walk.slice(0, 100)):
        out = engine.clean(Observation(take)).motion
        assert out.skeleton is take.skeleton and np.isfinite(out.channels).all()
        assert engine.loaded_from_ == folders[body_skeleton(take.skeleton).signature()]
    named = registry.create(f"mssa:weights={folders[walk.skeleton.signature()]}")
    with pytest.raises(EngineError, match="has no weights for this skeleton"):  # a folder named: kept
        named.clean(Observation(studio_take))


def test_a_one_frame_take_comes_back_at_its_own_rate(walk, studio_take):
    for take in (walk.slice(0, 1), studio_take.slice(0, 1)):
        view = ModelView.of(Observation(take), 50.0)
        assert view.observation.motion.fps == 50.0 and view.observation.n_frames == 1
        back = view.restore(CleanResult(view.observation.motion)).motion
        assert back.fps == take.fps and back.skeleton is take.skeleton and back.allclose(take, atol=1e-9)


def test_a_joint_is_missing_where_any_of_its_channels_is_nan(walk, stretchy_take):
    from workbench.core.motion import channel_joints, joint_any

    rng = np.random.default_rng(4)
    for take in (walk.slice(0, 40), stretchy_take):
        channels = take.channels
        holes = rng.random(channels.shape) < 0.02  # single channels, not whole joints
        expected = np.zeros((take.n_frames, take.skeleton.n_joints), bool)
        np.logical_or.at(expected, (slice(None), channel_joints(take.skeleton)), holes)
        assert np.array_equal(joint_any(holes, take.skeleton), expected)
        channels[holes] = np.nan
        assert np.array_equal(Observation(take.with_channels(channels)).observed, ~expected)


def test_a_take_whose_frame_time_is_far_off_is_not_resampled_into_the_memory():
    from workbench.engine.view import frame_times

    assert frame_times(300, 30.0, 120.0).size == 1197
    assert frame_times(300, 1.0, 120.0).size == 35881  # a Blender export's 1 s frame time: resampled
    for fps in (0.001, 0.01):  # 1,000 and 100 s a frame: 36 million frames, and 3.6 million at 2.5 GB an array
        with pytest.raises(EngineError, match=rf"Frame Time \({1 / fps:g} s\) is\s+wrong"):
            frame_times(300, fps, 120.0)


def test_takes_that_teach_nothing_are_refused_for_training_by_name(walk):
    from workbench import registry

    engine = registry.create("kalman-learned", pretrained=False)
    nan = walk.slice(0, 50).channels
    nan[20, 5] = np.nan
    for take, trouble in (
        (walk.slice(0, 1), "has 1 frames"),
        (walk.slice(0, 50).with_channels(nan), r"\(NaN\) or infinite values in 1 frames, first frame 20"),
        (walk.slice(0, 50).with_channels(np.repeat(walk.channels[:1], 50, axis=0)), "never moves"),
    ):
        with pytest.raises(EngineError, match=f"training take .*{trouble}"):
            engine.fit([walk.slice(0, 100), take])
