"""``cae``, ``cae-vanilla`` and ``holden``: the motion image, inference with the committed
weights, keep_observed, constraints, skeleton checks, fitting, saving and loading."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from engines.cae import CAE, Holden
from engines.cae.engine import TrialMix, trial_blocks
from engines.cae.representation import (
    TAIL_ROWS,
    Layout,
    decode,
    encode,
    heading,
    image_mask,
    integrate,
    mirror_rows,
    pad_time,
    retime,
    reverse_time,
)
from workbench import metrics, registry
from workbench.core.channels import hole_length
from workbench.core.kinematics import forward_kinematics, joint_positions
from workbench.core.motion import Observation, joint_angle_columns, position_unknown
from workbench.core.rotations import wrap_deg
from workbench.corruption import parse_corruption
from workbench.data import select
from workbench.engine import EngineError, NotFittedError
from workbench.engine.signal import bridge_gaps

torch.set_num_threads(1)
NAMES = ("cae", "cae-vanilla", "holden")


@pytest.fixture(scope="module")
def test_clip(clips):
    """A held-out CMU walk (35_31, 421 frames)."""
    return next(c for c in clips if c.id == "cmu/walk/35_31").load()


@pytest.fixture(scope="module")
def trained():
    return {name: registry.create(name) for name in NAMES}


@pytest.fixture(scope="module")
def tiny_fit(clips):
    """A cae fitted for one short epoch on two short training clips."""
    motions = [c.load().slice(0, 200) for c in select(clips, "train", dataset="cmu")[:2]]
    params = CAE.Params(epochs=1, frames_per_epoch=512, window_frames=64, batch_size=4, time_scale_pct=0.0)
    return CAE(params).fit(motions), motions


def test_image_round_trip(walk):
    """Positions -> image -> positions, given the first frame's root, is exact."""
    layout = Layout.from_skeleton(walk.skeleton)
    P, R = forward_kinematics(walk.skeleton, walk.root_positions, walk.angles_deg)
    theta = heading(R[:, 0])
    image = encode(layout, P, theta)
    assert image.shape == (walk.n_frames, 64) and len(layout.joints) == 20
    ground, turn = integrate(image, P[0, 0] * [1, 0, 1], theta[0])
    np.testing.assert_allclose(decode(layout, image, ground, turn), P, atol=1e-9)


def test_image_is_heading_invariant_and_mirrors(walk):
    layout = Layout.from_skeleton(walk.skeleton)
    P, R = forward_kinematics(walk.skeleton, walk.root_positions, walk.angles_deg)
    turned = np.einsum("ij,fkj->fki", np.array([[0, 0, 1], [0, 1, 0], [-1, 0, 0.0]]), P)  # 90 deg about Y
    image = encode(layout, P, heading(R[:, 0]))
    np.testing.assert_allclose(encode(layout, turned, heading(R[:, 0]) + np.pi / 2), image, atol=1e-9)
    perm, sign = mirror_rows(layout, walk.skeleton.names)
    np.testing.assert_array_equal((image[:, perm] * sign)[:, perm] * sign, image)
    left, right = walk.skeleton.index("LeftHand"), walk.skeleton.index("RightHand")
    assert perm[layout.rows(left).start] == layout.rows(right).start


def test_known_positions_follow_the_tree(walk):
    sk = walk.skeleton
    observed = np.ones((2, sk.n_joints), bool)
    observed[0, sk.index("LeftForeArm")] = False
    observed[1, 0] = False
    known = ~position_unknown(observed, sk.parents)
    assert known[0, sk.index("LeftForeArm")] and not known[0, sk.index("LeftHand")]
    assert known[0, sk.index("RightHand")] and not known[1].any()


def test_time_padding_reflects_and_turns_velocities_round():
    image = np.arange(5 * 64, dtype=float).reshape(5, 64)
    padded, mask = pad_time(image, image > 10, 9)
    assert padded.shape == (9, 64)
    np.testing.assert_array_equal(padded[5, :10], image[3, :10])
    np.testing.assert_array_equal(padded[5, -3:], -image[3, -3:])
    np.testing.assert_array_equal(mask[5], image[3] > 10)


@pytest.mark.parametrize("frames", [1, 37, 101, 257])
def test_any_length(trained, test_clip, frames):
    motion = test_clip.slice(0, frames)
    for engine in trained.values():
        out = engine.clean(Observation(motion)).motion
        assert out.n_frames == frames and np.isfinite(out.channels).all()


@pytest.mark.parametrize("name", NAMES)
def test_gap_filling_with_committed_weights(trained, test_clip, name):
    obs = parse_corruption("block:60+joints:2").apply(test_clip, seed=3)
    res = trained[name].clean(obs)
    assert np.isfinite(res.motion.channels).all()
    assert res.diagnostics["raw_positions"].shape == (test_clip.n_frames, 31, 3)
    assert trained[name].spec == name, "committed weights must be trained with the default parameters"


def test_quality_beats_lerp_on_a_60_frame_gap(trained, test_clip):
    errors = {"cae": [], "lerp": []}
    lerp = registry.create("lerp")
    for seed in range(3):
        obs = parse_corruption("block:60").apply(test_clip, seed=seed)
        for name, engine in (("cae", trained["cae"]), ("lerp", lerp)):
            errors[name].append(metrics.gap_mpjpe_cm(test_clip, engine.clean(obs).motion, obs.observed))
    assert np.mean(errors["cae"]) < 0.9 * np.mean(errors["lerp"]), errors


@pytest.mark.parametrize("name", NAMES)
def test_a_filled_gap_is_no_jerkier_than_the_truth(trained, test_clip, name):
    """The upsampling layers' ripple (periods of 2, 4 and 8 frames) is smoothed away:
    over a 120-frame gap the jerk of the filled motion stays below 1.5 times the truth's
    (without ``output_sigma_frames`` it is 4.5-8 times), the gap error within 1 %."""
    obs = parse_corruption("block:120").apply(test_clip, seed=0)
    gap = np.flatnonzero(~obs.observed[:, 0])

    def gap_jerk(motion):
        return metrics.jitter_cm_s3(motion.slice(gap[0], gap[-1] + 1))

    out = {s: registry.create(f"{name}:output_sigma_frames={s}").clean(obs).motion for s in (0, 1.5)}
    assert gap_jerk(out[1.5]) < 1.5 * gap_jerk(test_clip) < gap_jerk(out[0])
    errors = {s: metrics.gap_mpjpe_cm(test_clip, m, obs.observed) for s, m in out.items()}
    assert errors[1.5] < 1.01 * errors[0], errors


def test_keep_observed_returns_observed_entries_exactly(test_clip):
    engine = registry.create("cae:keep_observed=true")
    obs = parse_corruption("block:40+drop:0.1").apply(test_clip, seed=1)
    out = engine.clean(obs).motion.channels
    given = obs.channel_observed
    np.testing.assert_array_equal(out[given], obs.motion.channels[given])
    assert np.isfinite(out).all()


def test_constraints_pull_the_gap_towards_them(test_clip):
    """Tertiary blending: inside a 60-frame gap the right forearm, hand and finger are
    given over 15 frames where they were 40 frames later (in the body frame)."""
    sk = test_clip.skeleton
    layout = Layout.from_skeleton(sk)
    P, R = forward_kinematics(sk, test_clip.root_positions, test_clip.angles_deg)
    theta = heading(R[:, 0])
    image = encode(layout, P, theta)
    frames = np.arange(120, 135)
    joints = [sk.index(n) for n in ("RightForeArm", "RightHand", "RightHandIndex1")]
    for j in joints:
        image[frames, layout.rows(j)] = image[frames + 40, layout.rows(j)]
    target = decode(layout, image, P[:, 0] * [1, 0, 1], theta)[frames][:, joints]
    constraints = {j: (frames, target[:, i]) for i, j in enumerate(joints)}
    obs = parse_corruption("block:60,100").apply(test_clip, seed=0)

    def error_cm(engine, **kw):
        positions = engine.clean(obs, **kw).motion.positions[frames][:, joints]
        return np.linalg.norm(positions - target, axis=-1).mean() * sk.unit_cm

    for spec, bound in (("cae", 0.2), ("cae:keep_observed=true", 0.1)):
        engine = registry.create(spec)
        free, held = error_cm(engine), error_cm(engine, constraints=constraints)
        assert free > 10.0 and held < bound * free, (spec, free, held)
    with pytest.raises(EngineError, match="constrain"):
        engine.clean(obs, constraints={0: (frames, P[frames, 0])})


def test_weights_for_one_skeleton_refuse_another(kick):
    """Named weights are never swapped: CMU's cae weights refuse a Daz take (the plain
    ``cae`` would clean it with its universal weights: test_cae_universal.py)."""
    cmu = registry.create("cae").default_weights_dir() / "cmu"
    with pytest.raises(EngineError, match="skeleton"):
        registry.create(f"cae:weights={cmu}").clean(Observation(kick.slice(0, 50)))


@pytest.mark.parametrize("cls", [CAE, Holden])
def test_not_fitted(cls, walk):
    with pytest.raises(NotFittedError):
        cls().clean(Observation(walk.slice(0, 40)))


def test_fit_save_load_round_trip(tiny_fit, tmp_path, walk):
    engine, _ = tiny_fit
    assert engine.loss_log_.shape == (1,) and np.isfinite(engine.loss_log_).all()
    engine.save(tmp_path)
    again = CAE().load(tmp_path)
    assert again.spec == engine.spec
    obs = parse_corruption("block:30").apply(walk.slice(0, 120), seed=0)
    a, b = engine.clean(obs), again.clean(obs)
    np.testing.assert_array_equal(a.motion.channels, b.motion.channels)
    np.testing.assert_array_equal(a.diagnostics["raw_positions"], b.diagnostics["raw_positions"])


def test_training_goes_on_from_given_weights_and_refuses_weights_that_do_not_fit(tiny_fit, tmp_path):
    """``init_weights``: the network and image units of the named weights, trained further
    (at a learning rate of ~0 they come back as they were, where a fresh network does
    not); weights of another engine, version, skeleton or trained parameter, or none,
    refused with what to do."""
    import json

    from workbench.engine.torch_support import module_arrays
    from workbench.engine.weights import signed

    engine, motions = tiny_fit
    start = json.loads(engine.save(tmp_path / "start").read_text())
    tiny = {"epochs": 1, "frames_per_epoch": 512, "window_frames": 64, "batch_size": 4, "time_scale_pct": 0.0}
    still = {**tiny, "learning_rate": 1e-20, "ema_decay": 0.0, "seed": 1}  # another seed: another fresh network
    fresh = CAE(CAE.Params(**still)).fit(motions)
    on = CAE(CAE.Params(**still, init_weights=str(tmp_path / "start"))).fit(motions)
    np.testing.assert_array_equal(on.mean_, engine.mean_)
    np.testing.assert_array_equal(on.std_, engine.std_)
    before, after, other = (module_arrays(e.net_) for e in (engine, on, fresh))
    assert max(np.abs(after[k] - before[k]).max() for k in before) < 1e-6
    assert max(np.abs(other[k] - before[k]).max() for k in before) > 0.1
    saved = json.loads(on.save(tmp_path / "on").read_text())["started_from"]  # its provenance, licences with it
    assert saved == {"sha256": start["sha256"], "spec": start["spec"], "training": None}
    assert CAE().load(tmp_path / "on").training_record()["started_from"] == saved
    assert "started_from" not in fresh.training_record()
    committed = CAE().default_weights_dir().parent
    newer = tmp_path / "newer"  # weights of a version with a parameter this one lacks
    newer.mkdir()
    (newer / "weights.npz").write_bytes((tmp_path / "start" / "weights.npz").read_bytes())
    newer_manifest = signed({**start, "params": {**start["params"], "hole_loss_weight": 3.0}})
    (newer / "manifest.json").write_text(json.dumps(newer_manifest))
    refusals = [
        (newer, {}, r"parameters this engine lacks \(hole_loss_weight\)"),
        (tmp_path / "none", {}, "no weights manifest here"),
        (committed / "cae-vanilla" / "cmu", {}, "weights of engine 'cae-vanilla'"),
        (committed / "cae-universal" / "cmu+bandai", {}, "trained with universal=True"),
        (tmp_path / "start", {"input_fill": "zero"}, "trained with input_fill=linear"),
        (committed / "cae" / "bandai", {}, "other joints"),
        (committed / "cae" / "cmu", {}, "network runs at 120 fps, not 60"),
    ]
    for folder, params, why in refusals:
        with pytest.raises(EngineError, match=why):
            CAE(CAE.Params(**tiny, **params, init_weights=str(folder))).fit(motions)


def test_fit_refuses_mixed_skeletons(walk, kick):
    with pytest.raises(EngineError, match="skeleton"):
        CAE(CAE.Params(epochs=1)).fit([walk, kick])


def test_window_sampler_plays_windows_at_random_speeds_and_sizes(walk):
    """On an image whose rows grow linearly in time (velocity rows constant), a window's
    slope is speed x scale, its velocities are scaled as much and its turning rate by the
    speed only; both stay within their ranges."""
    from engines.cae.training import WindowSampler

    layout = Layout.from_skeleton(walk.skeleton)
    F, H = 300, layout.n_rows
    image = np.arange(F)[:, None] * np.linspace(1.0, 2.0, H)[None]
    image[:, -3:] = [0.5, 1.0, 0.1]
    sampler = WindowSampler(
        [image],
        np.zeros(H),
        np.ones(H),
        layout,
        None,
        np.array([2, 3]),
        64,
        5.0,
        time_scale_pct=50.0,
        body_scale_pct=5.0,
        input_noise=0.0,
        input_fill="zero",
        sampling="frames",
        rng=np.random.default_rng(0),
    )
    X, present = sampler.windows(32)
    assert X.shape == (32, 64, H) and present.shape == (32, H) and present.all()
    slope = np.diff(X[:, :, :-3], axis=1) / np.linspace(1.0, 2.0, H)[:-3]
    speed_scale = slope[:, 0, 0]
    np.testing.assert_allclose(slope, speed_scale[:, None, None] * np.ones_like(slope), rtol=1e-3)
    speed = X[:, 0, -1] / 0.1
    scale = speed_scale / speed
    np.testing.assert_allclose(X[:, :, -3] / 0.5, (speed * scale)[:, None] * np.ones((32, 64)), rtol=1e-3)
    assert speed.min() >= 1 / 1.5 - 1e-6 and speed.max() <= 1.5 + 1e-6 and speed.std() > 0.1
    assert scale.min() >= 0.95 - 1e-6 and scale.max() <= 1.05 + 1e-6 and scale.std() > 0.01


def test_anchor_keeps_the_slow_miss_and_drops_the_fast_one(trained):
    """The correction is the network's miss at the known entries, smoothed and bridged
    across holes: a slow miss comes back whole where known and, inside a hole, its departure
    from the row's mean miss over the known frames faded by exp(-d / miss_fade_s) at d
    seconds from its nearest known frame (whole with no fading), so a constant miss (a body
    the network pulls out of shape) stays whole; one that flips sign every frame (pure noise
    to the smoother) loses 90 % or more, ``exact`` entries get their own miss."""
    engine = trained["cae"]
    F, H = 120, 4
    mask = np.ones((F, H), bool)
    mask[40:70, [1, 3]] = False
    out = np.zeros((F, H))
    ramp = np.linspace(-1.0, 2.0, F)  # a miss that moves at constant speed: the smoother keeps it
    miss = np.stack([np.full(F, 1.0), ramp, np.full(F, 0.5), np.full(F, 3.0)], axis=1)
    corrected = engine.correction(out + miss, mask, out, np.zeros_like(mask))
    d = np.zeros(F)
    d[40:70] = np.minimum(np.arange(1, 31), np.arange(30, 0, -1)) / engine.fps_  # seconds to the hole's edges
    assert engine.params.miss_fade_s > 0 and d.max() == 15 / 120
    mean = ramp[mask[:, 1]].mean()
    np.testing.assert_allclose(
        corrected[:, 1], mean + (ramp - mean) * np.exp(-d / engine.params.miss_fade_s), atol=1e-7
    )
    np.testing.assert_allclose(corrected[:, [0, 2, 3]], miss[:, [0, 2, 3]], atol=1e-12)
    plain = registry.create("cae:anchor=false")  # the miss is the exact entries' alone: it fades to 0, not to a mean
    exact = np.zeros_like(mask)
    exact[39, 1] = True
    constrained = plain.correction(out + miss, mask, out, exact)
    assert constrained[39, 1] == ramp[39] and abs(constrained[55, 1]) < 0.5 * abs(ramp[39])  # (a mean kept: 0.54)
    unfaded = registry.create("cae:miss_fade_s=0")
    np.testing.assert_allclose(unfaded.correction(out + miss, mask, out, np.zeros_like(mask)), miss, atol=1e-7)
    flips = np.where(np.arange(F) % 2, 1.0, -1.0)[:, None] * np.ones(H)
    exact = np.zeros_like(mask)
    exact[10, 2] = True
    corrected = engine.correction(out + flips, mask, out, exact)
    assert corrected[10, 2] == flips[10, 2]
    corrected[10, 2] = 0.0
    assert np.abs(corrected).max() < 0.1


def test_anchor_brings_the_output_back_to_the_observation(test_clip):
    """On a clean take the network's own output is cm off (its bottleneck); anchored, it
    keeps the take (the smoother's noise level is the observation's, near 0). Under
    position noise the anchored result lies below the noise."""
    plain, anchored = registry.create("cae:anchor=false"), registry.create("cae")
    assert anchored.params.anchor
    clean = Observation(test_clip)
    assert metrics.mpjpe_cm(test_clip, plain.clean(clean).motion) > 1.0
    assert metrics.mpjpe_cm(test_clip, anchored.clean(clean).motion) < 0.05
    noisy = parse_corruption("spatial:1.5").apply(test_clip, seed=0)
    assert metrics.mpjpe_cm(test_clip, anchored.clean(noisy).motion) < metrics.mpjpe_cm(test_clip, noisy.motion)


def test_anchor_sheds_the_position_noise_that_angle_noise_makes(test_clip):
    """Angle noise moves the joints with heavy tails; the anchor's smoother must be told
    its full variance, or it keeps the noise (the median estimate left the output twice
    as jerky as the truth and less accurate than kalman's)."""
    obs = parse_corruption("angular:0.5").apply(test_clip, seed=0)
    out = registry.create("cae").clean(obs).motion
    assert metrics.jitter_cm_s3(out) < metrics.jitter_cm_s3(test_clip)
    assert metrics.mpjpe_cm(test_clip, out) < metrics.mpjpe_cm(test_clip, registry.create("kalman").clean(obs).motion)


def test_feet_keep_their_smoothed_angles_where_the_noise_is_in_the_angles(test_clip):
    """Under angle noise the feet keep their observed angles, smoothed: aimed at the toe
    (13 cm away), whose position carries the noise of the whole leg, they were off by
    several times more, and weighed against that aim (angle_lever_cm=0) still by 1.6
    times. Under position noise they are aimed, as with angle_lever_cm=0."""
    feet = [test_clip.skeleton.index(n) for n in ("LeftFoot", "RightFoot")]

    def feet_error(m):
        return np.sqrt(np.mean((m.angles_deg[:, feet] - test_clip.angles_deg[:, feet]) ** 2))

    noisy = parse_corruption("angular:0.5").apply(test_clip, seed=0)
    kept, aimed = (registry.create(s).clean(noisy).motion for s in ("cae", "cae:angle_lever_cm=0"))
    assert feet_error(kept) < 0.75 * feet_error(aimed)
    assert feet_error(kept) < 0.5 * feet_error(noisy.motion)
    assert metrics.rms_angle_deg(test_clip, kept) < metrics.rms_angle_deg(test_clip, aimed)
    assert metrics.mpjpe_cm(test_clip, kept) < metrics.mpjpe_cm(test_clip, aimed)
    marker = parse_corruption("spatial:1").apply(test_clip, seed=0)
    np.testing.assert_array_equal(
        *(registry.create(s).clean(marker).motion.angles_deg[:, feet] for s in ("cae", "cae:angle_lever_cm=0"))
    )


def test_chest_and_arms_keep_their_smoothed_angles_where_the_noise_is_in_the_angles(studio_take):
    """Under angle noise a studio take's chest (aimed at the neck and both shoulders, 16 cm
    at most) and forearms (22 cm) keep their observed angles, smoothed, within the
    30-cm angle lever: aimed at the network's joints they were turned by its errors, the
    chest further than the noise itself had turned it. Beyond a 13.5-cm lever the
    forearms weigh their angles against that aim, and come out further off (7 % with the
    Bandai weights of a 60-fps network, 20 % with those before)."""
    sk = studio_take.skeleton

    def error(m, names):
        joints = [sk.index(n) for n in names]
        return np.sqrt(np.mean(wrap_deg(m.angles_deg[:, joints] - studio_take.angles_deg[:, joints]) ** 2))

    noisy = parse_corruption("angular:0.5").apply(studio_take, seed=0)
    kept, aimed = (registry.create(s).clean(noisy).motion for s in ("cae", "cae:angle_lever_cm=13.5"))
    chest, arms = ["Chest"], ["LowerArm_L", "LowerArm_R"]
    assert error(kept, chest) < 0.6 * min(error(aimed, chest), error(noisy.motion, chest))  # 0.98, 3.89, 2.20
    assert error(kept, arms) < 0.95 * error(aimed, arms) < 0.5 * error(noisy.motion, arms)  # 1.50, 1.61, 3.47
    assert metrics.rms_angle_deg(studio_take, kept) < metrics.rms_angle_deg(studio_take, aimed)


def test_anchor_sheds_the_noise_of_the_root_track(test_clip):
    """Under position noise the root's floor track and heading are smoothed before the
    (root-relative) image is built, so neither the root nor the pose keeps its noise."""
    noisy = parse_corruption("spatial:1.5").apply(test_clip, seed=0)
    out = registry.create("cae").clean(noisy).motion

    def root_error(m):
        return np.linalg.norm(m.root_positions - test_clip.root_positions, axis=1).mean()

    assert root_error(out) < 0.5 * root_error(noisy.motion)
    assert metrics.mpjpe_cm(test_clip, out) < 0.5 * metrics.mpjpe_cm(test_clip, noisy.motion)


def test_network_input_bridges_unknown_entries_and_clips_are_drawn_alike(walk):
    from engines.cae.training import WindowSampler, network_input

    X = np.tile(np.arange(6.0)[:, None], (1, 3))[None]  # (1, T=6, H=3): every row is t
    mask = np.ones_like(X, bool)
    mask[0, 1:4, 0] = False  # a hole in row 0, bridged exactly as the row is linear
    mask[0, :, 2] = False  # row 2 never known
    linear, zero = network_input(X, mask, "linear")[0], network_input(X, mask, "zero")[0]
    np.testing.assert_array_equal(linear[0].T, X[0] * [1, 1, 0])
    np.testing.assert_array_equal(zero[0].T, np.where(mask[0], X[0], 0.0))
    np.testing.assert_array_equal(linear[1].T, mask[0])
    layout = Layout.from_skeleton(walk.skeleton)
    images = [np.zeros((n, layout.n_rows)) for n in (100, 900)]
    for sampling, weights in (("clips", [0.5, 0.5]), ("frames", [0.1, 0.9])):
        sampler = WindowSampler(
            images,
            np.zeros(layout.n_rows),
            np.ones(layout.n_rows),
            layout,
            None,
            np.array([2]),
            64,
            5.0,
            10.0,
            0.0,
            0.0,
            "linear",
            sampling,
            np.random.default_rng(0),
        )
        np.testing.assert_allclose(sampler.weights, weights)


def test_loaded_weights_bring_their_trained_and_training_parameters_not_the_inference_ones(tiny_fit, tmp_path):
    """The one rule of Engine.load: the weights' trained and training parameters, the
    spec's inference ones; a parameter newer than the weights at its default; one the
    engine no longer has, or a manifest of an older format, refused by name."""
    import json

    from workbench.engine.weights import signed

    engine, _ = tiny_fit
    manifest = engine.save(tmp_path)
    loaded = CAE(CAE.Params(views=4, hole_blend_frames=0)).load(tmp_path).params
    assert (loaded.views, loaded.hole_blend_frames) == (4, 0)  # inference: as asked
    assert (loaded.epochs, loaded.window_frames) == (1, 64)  # training: how these weights were made
    data = json.loads(manifest.read_text())
    del data["params"]["input_fill"]  # saved before the parameter existed: at its default
    manifest.write_text(json.dumps(signed(data)))
    assert CAE().load(tmp_path).params.input_fill == CAE.Params().input_fill
    data["params"]["mirror_average"] = True  # a parameter the engine no longer has
    manifest.write_text(json.dumps(signed(data)))
    with pytest.raises(EngineError, match=r"parameters engine 'cae' does not have \(mirror_average\)"):
        CAE().load(tmp_path)
    del data["format_version"]
    manifest.write_text(json.dumps(signed(data)))
    with pytest.raises(EngineError, match="weights of manifest format 1, and this workbench reads format 3"):
        CAE().load(tmp_path)
    with pytest.raises(ValueError, match="views"):
        CAE.Params(views=5)
    with pytest.raises(ValueError, match="miss_fade_s"):
        CAE.Params(miss_fade_s=-1.0)


def test_ema_keeps_the_average_of_the_steps_weights():
    """With ema_decay, training ends on the moving average of the weights, not the last
    step's; the average starts at the first step, so a decay near 1 stays there."""
    from engines.cae.networks import VanillaNet
    from engines.cae.training import train

    class Sampler:
        def __init__(self):
            self.rng = np.random.default_rng(0)

        def batch(self, size, gap):
            X = self.rng.normal(size=(size, 32, 8)).astype(np.float32)
            x = torch.from_numpy(np.stack([X, np.ones_like(X)], axis=1).transpose(0, 1, 3, 2).copy())
            return X, x, np.ones((size, 8), bool)

    start = VanillaNet(bf16=False).state_dict()

    def trained(steps, decay):
        net = VanillaNet(bf16=False)
        net.load_state_dict(start)
        train(net, Sampler(), 1, steps, 2, 1e-2, 75.0, 1, decay, desc="test")
        return net.state_dict()

    first, last, averaged = trained(1, 0.0), trained(6, 0.0), trained(6, 1.0 - 1e-9)
    assert max((last[k] - first[k]).abs().max().item() for k in start) > 1e-2
    assert max((averaged[k] - first[k]).abs().max().item() for k in start) < 1e-6


def test_learning_rate_is_held_then_annealed_to_a_tenth():
    """Held for the first anneal_from_pct per cent of the epochs, then falling (cosine)
    towards a tenth; a percentage outside 0-100 is refused."""
    from engines.cae.training import learning_rate_at

    rates = [learning_rate_at(e, 10, 1e-3, 40.0) for e in range(10)]
    assert rates[:5] == [1e-3] * 5  # the first annealed epoch starts from the full rate
    assert all(a > b for a, b in zip(rates[4:], rates[5:]))
    assert 1e-4 < rates[-1] < 2e-4
    assert [learning_rate_at(e, 8, 1e-3, 75.0) for e in range(8)][:6] == [1e-3] * 6
    with pytest.raises(ValueError, match="anneal_from_pct"):
        CAE.Params(anneal_from_pct=120)


def test_short_levers_keep_their_observed_angles(test_clip):
    """The hands and finger bases (children within 5 cm) come back as observed, bridged
    linearly across a hole (IK would aim them at finger positions a few mm off); with
    the anchor the observed angles are smoothed first (their noise is the observation's)."""
    from workbench.core.kinematics import short_lever_joints
    from workbench.engine.smoothing import smooth_observed

    sk = test_clip.skeleton
    short = short_lever_joints(sk, 5.0)
    assert [sk.names[j] for j in short] == ["LeftHand", "LeftFingerBase", "RightHand", "RightFingerBase"]
    obs = parse_corruption("block:30,200").apply(test_clip, seed=0)
    seen = obs.observed[:, short[0]]
    raw = registry.create("cae:anchor=false").clean(obs).motion.angles_deg[:, short]
    np.testing.assert_allclose(raw[seen], test_clip.angles_deg[:, short][seen], atol=1e-6)
    np.testing.assert_allclose(
        raw[~seen], registry.create("lerp").clean(obs).motion.angles_deg[:, short][~seen], atol=1e-6
    )
    cols = joint_angle_columns(short)
    anchored = registry.create("cae").clean(obs).motion.channels[:, cols]
    np.testing.assert_allclose(
        anchored, smooth_observed(obs.motion.channels[:, cols], np.isfinite(obs.motion.channels[:, cols])), atol=1e-6
    )
    free = registry.create("cae:short_lever_cm=0,angle_lever_cm=0").clean(obs).motion.angles_deg[:, short]
    assert np.abs(free[seen] - test_clip.angles_deg[:, short][seen]).max() > 0.5
    noisy = parse_corruption("spatial:1").apply(test_clip, seed=0)
    out = registry.create("cae").clean(noisy).motion.angles_deg[:, short]
    assert np.sqrt(np.mean((out - test_clip.angles_deg[:, short]) ** 2)) < 0.5 * np.sqrt(
        np.mean((noisy.motion.angles_deg[:, short] - test_clip.angles_deg[:, short]) ** 2)
    )


def test_short_holes_are_bridged_as_observed(test_clip):
    """Scattered drop-outs hide every position below a missing joint; bridging holes of
    a few frames in angle space (along the constant-velocity smoother's path) keeps those
    positions instead of leaving them to the network, and beats lerp's line."""
    truth = test_clip.slice(0, 200)
    obs = parse_corruption("drop:0.5").apply(truth, seed=0)
    lerp = _gap_error("lerp", truth, obs)
    assert _gap_error("cae", truth, obs) < 0.9 * lerp  # linear bridges: 0.93
    assert _gap_error("cae:short_hole_frames=0,partial_hole_frames=0", truth, obs) > 2.0 * lerp  # 2.41


def _bridged_with_positions(obs):
    """``bridged_holes``' arguments: the observation's channels, gaps bridged, and their joint positions."""
    channels = bridge_gaps(obs)
    return channels, joint_positions(obs.skeleton, channels[:, :3], channels[:, 3:].reshape(obs.n_frames, -1, 3))


def test_partial_holes_are_bridged_where_the_noise_allows(test_clip):
    """Holes of a few dozen frames in part of the body: the angles' smoother bridges them
    better than the network fills them, on a clean take; under position noise (and
    outliers) they are left to the network."""
    truth = test_clip.slice(0, 300)
    obs = parse_corruption("gaps:0.01,20").apply(truth, seed=0)
    engine = registry.create("cae")
    missing = ~obs.observed
    assert (engine.bridged_holes(obs, *_bridged_with_positions(obs)) == missing & (hole_length(missing) <= 60)).all()
    assert (hole_length(missing)[missing] > 6).mean() > 0.5
    assert _gap_error("cae", truth, obs) < 0.8 * _gap_error("cae:partial_hole_frames=0", truth, obs)
    noisy = parse_corruption("spatial:1+gaps:0.01,20").apply(truth, seed=0)
    missing = ~noisy.observed
    assert (engine.bridged_holes(noisy, *_bridged_with_positions(noisy)) == missing & (hole_length(missing) <= 6)).all()


def test_short_gaps_blend_in_the_smoothers_fill(test_clip):
    """A 15-frame gap: the constant-velocity smoother's fill is better than the network's
    there (the network fills long gaps), so cae blends the two by the gap's length."""
    obs = parse_corruption("block:15").apply(test_clip, seed=0)
    blended = _gap_error("cae", test_clip, obs)
    assert blended < 0.7 * _gap_error("cae:hole_blend_frames=0", test_clip, obs)
    assert blended < 1.2 * _gap_error("kalman", test_clip, obs)


def _gap_error(spec: str, truth, obs) -> float:
    """``gap_mpjpe_cm`` of engine ``spec`` cleaning ``obs`` of ``truth``."""
    return metrics.gap_mpjpe_cm(truth, registry.create(spec).clean(obs).motion, obs.observed)


def test_the_root_path_across_a_long_gap_leans_on_the_smoother(clips):
    """Across a gap inside the take the floor path is mostly the constant-velocity
    smoother's fill, a quarter the network's integrated velocities; on a jog the
    network's path alone drifts further (held-out jog 16_35, 120-frame gaps, 4 seeds)."""
    jog = next(c for c in clips if c.id == "cmu/jog/16_35").load()

    def root_error(spec):
        errors = []
        for seed in range(4):
            obs = parse_corruption("block:120").apply(jog, seed=seed)
            gap = ~obs.observed[:, 0]
            out = registry.create(spec).clean(obs).motion
            errors.append(np.linalg.norm((out.root_positions - jog.root_positions)[gap], axis=1).mean())
        return np.mean(errors)

    assert root_error("cae") < 0.72 * root_error("cae:anchor=false")  # 0.70; an even mean: 0.74


def test_view_averages_are_symmetric(trained, test_clip):
    """Averaged over the mirrored and the reversed views, the completion of a mirrored
    (or reversed) image is the mirrored (reversed) completion; a single pass is not (the
    network only learnt the symmetries). Exact but for the floor steps, which reversal
    turns by the (predicted) turn of each frame: a second-order difference there."""
    engine = trained["cae"]
    layout = engine.layout_
    P, R = forward_kinematics(test_clip.skeleton, test_clip.root_positions, test_clip.angles_deg)
    image = encode(layout, P, heading(R[:, 0]))
    mask = np.ones_like(image, bool)
    mask[100:160] = False
    perm, sign = mirror = mirror_rows(layout, test_clip.skeleton.names)
    for views, symmetric in ((4, True), (3, False), (1, False)):
        direct = engine.complete(image, mask, mirror, views)
        via_mirror = engine.complete(image[:, perm] * sign, mask[:, perm], mirror, views)[:, perm] * sign
        assert np.allclose(direct, via_mirror, atol=1e-9) == symmetric
        back, back_mask = reverse_time(image, mask)
        via_reverse = reverse_time(engine.complete(back, back_mask, mirror, views), back_mask)[0]
        assert np.allclose(direct[:, :-3], via_reverse[:, :-3], atol=1e-9) == symmetric
        assert np.allclose(direct[1:, -3:], via_reverse[1:, -3:], atol=1e-3) or not symmetric
    with pytest.raises(ValueError, match="mirror"):
        engine.complete(image, mask, None, 2)


def test_time_reversal_is_the_image_of_the_take_played_backwards(walk):
    layout = Layout.from_skeleton(walk.skeleton)
    P, R = forward_kinematics(walk.skeleton, walk.root_positions, walk.angles_deg)
    theta = heading(R[:, 0])
    known = np.ones((walk.n_frames, walk.skeleton.n_joints), bool)
    known[40:70] = False
    image, mask = encode(layout, P, theta), image_mask(layout, known)
    back, back_mask = reverse_time(image, mask)
    np.testing.assert_allclose(back, encode(layout, P[::-1], theta[::-1]), atol=1e-9)
    np.testing.assert_array_equal(back_mask, image_mask(layout, known[::-1]))
    again, again_mask = reverse_time(back, back_mask)
    np.testing.assert_allclose(again, image, atol=1e-12)
    np.testing.assert_array_equal(again_mask, mask)


def test_an_image_retimed_is_the_image_of_the_take_at_that_rate(walk):
    """Every other frame of a 120-fps image, its steps summed in pairs, is the image of the
    take at 60 fps (the floor steps to a frame's turn); and back, the positions again and
    the path at every other frame."""
    layout = Layout.from_skeleton(walk.skeleton)
    P, R = forward_kinematics(walk.skeleton, walk.root_positions, walk.angles_deg)
    theta = heading(R[:, 0])
    image = encode(layout, P, theta)
    half = retime(image, np.arange(0, walk.n_frames, 2.0))
    at_60 = encode(layout, P[::2], theta[::2])
    np.testing.assert_allclose(half[:, :-1], at_60[:, :-1], atol=0.02 * np.abs(at_60[:, -3:-1]).max())
    np.testing.assert_allclose(half[:, -1], at_60[:, -1], atol=1e-12)
    back = retime(half, np.arange(walk.n_frames - 1) / 2.0)
    np.testing.assert_allclose(back[::2, :-3], image[: walk.n_frames - 1 : 2, :-3], atol=1e-12)
    np.testing.assert_allclose(np.cumsum(back[:, -3:], axis=0)[::2], np.cumsum(image[:-1, -3:], axis=0)[::2], atol=1e-9)


def test_the_network_sees_the_take_at_its_own_rate(tiny_fit, tmp_path, monkeypatch):
    """Weights trained now run their network at 60 fps on a 120-fps view and say so in
    their arrays; weights saved before that (CMU's committed ones) run it at the model's
    rate; a rate that is none is refused. Unless asked for others, the first runs two
    views (the take and its mirror), the second three."""
    engine, motions = tiny_fit
    assert (engine.fps_, engine.network_fps_) == (120.0, CAE.NETWORK_FPS) == (120.0, 60.0)
    before = CAE().load(CAE().default_weights_dir() / "cmu")
    assert before.network_fps_ == before.fps_ == 120.0
    engine.save(tmp_path)
    again = CAE().load(tmp_path)
    assert again.network_fps_ == 60.0
    seen = []
    predict = again.net_.predict
    monkeypatch.setattr(again.net_, "predict", lambda x, *a: seen.append(x.shape) or predict(x, *a))
    obs = parse_corruption("block:30").apply(motions[0].slice(0, 161), seed=0)
    out = again.clean(obs)
    assert seen and seen[0][-1] == 96  # 81 frames at 60 fps, padded to a multiple of 32
    assert seen[0][0] == again.views_used() == 2 and before.views_used() == 3
    assert CAE(CAE.Params(views=3)).load(tmp_path).views_used() == 3
    assert out.motion.n_frames == 161 and np.isfinite(out.motion.channels).all()
    again.network_fps_ = 0.0
    again.save(tmp_path / "broken")
    with pytest.raises(EngineError, match="network.fps .* is not a frame rate; retrain"):
        CAE().load(tmp_path / "broken")


def test_eval_forward_casts_the_weights_once_and_follows_new_ones(monkeypatch):
    """In eval mode the bf16 body is a cached copy: same output as autocast, and rebuilt
    when weights are loaded or training resumes (bf16 forced on a CPU that emulates it)."""
    import engines.cae.networks as networks

    monkeypatch.setattr(networks, "bf16_is_native", lambda: True)
    net = networks.KaufmannNet().eval()
    assert net.bf16
    x = torch.randn(2, 2, 64, 64)

    def autocast_forward():
        with torch.autocast("cpu", dtype=torch.bfloat16):
            h = net.body(x.contiguous(memory_format=torch.channels_last))
        return net.head(h.float())[:, 0]

    with torch.inference_mode():
        torch.testing.assert_close(net(x), autocast_forward(), rtol=0, atol=0)
    net.load_state_dict({k: v * 1.5 for k, v in net.state_dict().items()})
    with torch.inference_mode():
        torch.testing.assert_close(net(x), autocast_forward(), rtol=0, atol=0)
    assert not any("bf16" in k for k in net.state_dict())


def test_networks_run_float32_where_bf16_is_emulated(monkeypatch):
    """On a CPU without native bf16 (AVX2 only) the body runs in float32, bf16 asked or
    not: emulated bf16 is many times slower there."""
    import engines.cae.networks as networks

    monkeypatch.setattr(networks, "bf16_is_native", lambda: False)
    asked, plain = networks.KaufmannNet(bf16=True).eval(), networks.KaufmannNet(bf16=False).eval()
    assert not asked.bf16
    plain.load_state_dict(asked.state_dict())
    x = torch.randn(2, 2, 64, 64)
    with torch.inference_mode():
        torch.testing.assert_close(asked(x), plain(x), rtol=0, atol=0)
        assert asked.body(x.contiguous(memory_format=torch.channels_last)).dtype == torch.float32


def test_a_bfloat16_pass_that_returns_nan_is_redone_in_float32():
    """oneDNN's bfloat16 convolutions now and then return NaN from a first call: the
    network's output is then the float32 body's."""
    from engines.cae.networks import VanillaNet

    torch.manual_seed(0)
    net = VanillaNet(base=4, top=8, bf16=False).eval()
    x = torch.randn(1, 2, 32, 32)
    with torch.inference_mode():
        expected = net(x)
        net.bf16 = True
        net.__dict__["_bf16_body"] = lambda h: net.body(h.float()).to(torch.bfloat16) * float("nan")
        assert torch.equal(net(x), expected)


def _networks():
    from engines.cae.networks import HoldenNet, KaufmannNet, VanillaNet

    torch.manual_seed(0)
    return [KaufmannNet(base=4, top=8, bf16=False), VanillaNet(base=4, top=8, bf16=False), HoldenNet(rows=6, hidden=8)]


@pytest.mark.parametrize("index", range(3), ids=["cae", "cae-vanilla", "holden"])
def test_time_reach_is_the_farthest_frame_an_output_depends_on(index):
    """Measured by NaN propagation from one frame, at every phase of the pooling grid:
    ``time_reach`` covers it, rounded up to ``time_multiple`` and no further."""
    net = _networks()[index].eval()
    T, reach = 1024, 0
    for t0 in range(T // 2, T // 2 + net.time_multiple):
        x = torch.randn(1, 2, 6, T)
        x[..., t0] = float("nan")
        with torch.inference_mode():
            hit = torch.isnan(net(x)).any(dim=(0, 1)).nonzero()[:, 0]
        reach = max(reach, t0 - int(hit.min()), int(hit.max()) - t0)
    assert net.time_reach % net.time_multiple == 0
    assert reach <= net.time_reach < reach + net.time_multiple


@pytest.mark.parametrize("index", range(3), ids=["cae", "cae-vanilla", "holden"])
def test_a_long_image_predicted_a_window_at_a_time_gives_the_whole_image_s_values(index):
    """Windows of frames, each with its reach either side, on a 3-view image longer than
    several windows: the values of one call on the whole image (to float32 rounding)."""
    net = _networks()[index].eval()
    x = torch.randn(3, 2, 6, 64 * 41)
    x[:, 1] = (x[:, 1] > 0).float()
    with torch.inference_mode():
        whole = net.predict(x, max_columns=10**9)
        windowed = net.predict(x, max_columns=2 * net.time_reach + 320)
    assert windowed.shape == whole.shape == (3, 6, 64 * 41)
    np.testing.assert_allclose(windowed, whole, rtol=0, atol=1e-5)


def test_trial_blocks_sit_beside_their_holes_where_the_take_is_observed():
    """Blocks as long as the hole, a quarter of its length away (at least 2 frames), on each
    side where the root is known in and around them."""
    long_holes = np.zeros(100, bool)
    long_holes[20:40] = True
    assert trial_blocks(long_holes, ~long_holes) == [((20, 40), (45, 65))]  # no room before it
    long_holes[:] = False
    long_holes[50:70] = True
    root_known = ~long_holes
    assert trial_blocks(long_holes, root_known) == [((50, 70), (25, 45)), ((50, 70), (75, 95))]
    root_known[30] = False  # the root missing there too: after it alone
    assert trial_blocks(long_holes, root_known) == [((50, 70), (75, 95))]
    root_known[80] = False
    assert trial_blocks(long_holes, root_known) == []


def test_a_network_that_misses_the_trial_leaves_the_long_hole_to_lerp(test_clip):
    """A network that puts every joint it must guess 20 cm off (its root's path and heading
    right): the trial beside a 1-s hole finds linear interpolation nearer, and the hole is
    filled as lerp fills it (to IK's accuracy); without the trial it keeps the miss."""
    obs = parse_corruption("block:120").apply(test_clip, seed=0)

    def missing_by_20(engine):
        complete = engine.complete

        def off(image, mask, *args):
            out = complete(image, mask, *args)
            out[:, :-TAIL_ROWS] += np.where(mask[:, :-TAIL_ROWS], 0.0, 20.0)  # not the root's path rows
            return out

        engine.complete = off
        return engine

    def gap_error(engine):
        return metrics.gap_mpjpe_cm(test_clip, engine.clean(obs).motion, obs.observed)

    lerp = _gap_error("lerp", test_clip, obs)
    assert gap_error(missing_by_20(registry.create("cae"))) < 1.05 * lerp
    share = missing_by_20(registry.create("cae")).clean(obs).diagnostics["network_share"]
    hole = ~obs.observed[:, 0]
    assert share.shape == (test_clip.n_frames,) and (share[hole] < 0.5).all() and (share[~hole] == 1).all()
    assert gap_error(missing_by_20(registry.create("cae:trial_holes=false"))) > 2 * lerp


def test_a_network_that_fills_the_trial_well_keeps_its_fill(test_clip):
    """On a held-out walk the network fills the trials beside a 1-s hole better than lerp
    for most joints, so the hole is filled about as without the trial, well below lerp."""
    obs = parse_corruption("block:120").apply(test_clip, seed=0)
    with_trial = _gap_error("cae", test_clip, obs)
    assert with_trial < 1.03 * _gap_error("cae:trial_holes=false", test_clip, obs)
    assert with_trial < 0.7 * _gap_error("lerp", test_clip, obs)


def test_a_mix_of_none_of_the_network_s_fill_is_lerp_s_fill(clips, monkeypatch):
    """The linear fill a trial mixes in is lerp's own pose and heading (root-aligned: the
    root's floor path stays the engine's), also where the smoothed root path the network's
    image is built on leaves lerp's (a Daz kick)."""
    kick = next(c for c in clips if c.id == "cmu-daz/kick/10_03").load()
    obs = parse_corruption("block:1s").apply(kick, seed=0)
    applied = TrialMix.applied
    none = lambda self, out, theta: applied(  # noqa: E731
        dataclasses.replace(self, shares=0 * self.shares, turn_share=0.0), out, theta
    )
    monkeypatch.setattr(TrialMix, "applied", none)
    filled, lerp = registry.create("cae").clean(obs).motion, registry.create("lerp").clean(obs).motion
    assert metrics.joint_position_error_cm(lerp, filled)[~obs.observed[:, 0]].max() < 0.05


def test_a_long_hole_without_room_for_a_trial_keeps_the_network_s_fill(test_clip):
    """Two long holes: the first has room for a trial after it, the second none on either
    side; a network missing by 20 cm gives the first to lerp and leaves the second alone."""
    observed = np.ones((test_clip.n_frames, test_clip.skeleton.n_joints), bool)
    observed[40:100] = observed[200:320] = False
    channels = test_clip.channels.copy()
    channels[~observed.any(axis=1)] = np.nan
    obs = Observation(test_clip.with_channels(channels), observed)

    def missing_by_20(engine):
        complete = engine.complete

        def off(image, mask, *args):
            out = complete(image, mask, *args)
            out[:, :-TAIL_ROWS] += np.where(mask[:, :-TAIL_ROWS], 0.0, 20.0)
            return out

        engine.complete = off
        return engine

    with_trial = missing_by_20(registry.create("cae")).clean(obs)
    without = missing_by_20(registry.create("cae:trial_holes=false")).clean(obs).motion
    share = with_trial.diagnostics["network_share"]
    assert (share[40:100] < 0.5).all() and (share[200:320] == 1).all()
    apart = metrics.joint_position_error_cm(without, with_trial.motion)
    assert apart[40:100].mean() > 5 and apart[200:320].max() < 1e-6
