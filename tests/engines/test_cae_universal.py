"""The universal cae (``cae:universal=true``): the image of the canonical humanoid, trained on
several skeletons together, cleaning a skeleton it has never seen (engines/cae/bodies.py)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from engines.cae import CAE
from engines.cae.training import WindowSampler
from workbench.core.humanoid import map_humanoid
from workbench.core.kinematics import forward_kinematics
from workbench.corruption import parse_corruption
from workbench.engine import EngineError
from workbench.engine.canonical import CanonicalBody
from workbench.engine.signal import bridge_gaps
from workbench.engine.smoothing import ik_reference

torch.set_num_threads(1)


@pytest.fixture(scope="module")
def universal(walk, studio_take):
    """A universal cae fitted for one short epoch on a CMU walk and a Bandai walk."""
    params = CAE.Params(epochs=1, frames_per_epoch=512, window_frames=64, batch_size=4, time_scale_pct=0.0)
    return CAE(CAE.Params(**{**params.__dict__, "universal": True})).fit([walk.slice(0, 200), studio_take])


def test_trains_on_two_skeletons_and_cleans_a_third(universal, kick):
    assert universal.skeleton_description_ == "the canonical humanoid"
    obs = parse_corruption("block:30").apply(kick.slice(0, 150), seed=0)
    result = universal.clean(obs)
    out = result.motion
    assert out.skeleton is obs.skeleton and out.channels.shape == obs.motion.channels.shape
    assert np.isfinite(out.channels).all()
    assert result.diagnostics["raw_positions"].shape == (150, kick.skeleton.n_joints, 3)
    assert universal.weights_used_ is None  # fitted here


def test_unmapped_joints_keep_their_smoothed_angles_and_the_bones_their_lengths(universal, kick):
    """IK on the take's own skeleton: its offsets are untouched (bone lengths exact), and
    the joints with no canonical joint below them (fingers, eyes) come back at the IK
    reference, their own angles smoothed, not at the network's guess."""
    take = kick.slice(0, 150)
    obs = parse_corruption("angular:0.5").apply(take, seed=1)
    out = universal.clean(obs).motion
    np.testing.assert_array_equal(out.skeleton.offsets, take.skeleton.offsets)
    p = universal.params
    channels = bridge_gaps(obs)
    positions, _ = forward_kinematics(take.skeleton, channels[:, :3], channels[:, 3:].reshape(150, -1, 3))
    ref, _ = ik_reference(take.skeleton, channels, obs.observed, positions, p.short_lever_cm, p.angle_lever_cm)
    kept = CanonicalBody(map_humanoid(take.skeleton)).kept_joints
    kept = kept[take.skeleton.has_rotation[kept] & (kept > 0)]
    assert {"lIndex1", "rThumb2", "leftEye"} <= {take.skeleton.names[j] for j in kept}
    np.testing.assert_allclose(out.angles_deg[:, kept], ref[:, kept], atol=1e-6)
    noisy = np.abs(obs.motion.angles_deg[:, kept] - ref[:, kept]).mean()
    assert noisy > 0.1, "the reference is the smoothed observation, not the noisy one"


def test_constraints_on_a_mapped_joint_pull_the_gap_towards_them(universal, kick):
    take = kick.slice(0, 150)
    obs = parse_corruption("block:60").apply(take, seed=1)
    hand = map_humanoid(take.skeleton).joint("left_hand")
    frame = int(np.flatnonzero(~obs.observed[:, 0])[30])
    goal = take.positions[frame, hand] + np.array([0.0, 10.0, 0.0])
    free = universal.clean(obs).motion.positions[frame, hand]
    pulled = universal.clean(obs, constraints={hand: (np.array([frame]), goal[None])}).motion.positions[frame, hand]
    assert np.linalg.norm(pulled - goal) < 0.5 * np.linalg.norm(free - goal)
    unmapped = take.skeleton.names.index("lIndex1")
    with pytest.raises(EngineError, match="maps onto the canonical humanoid"):
        universal.clean(obs, constraints={unmapped: (np.array([frame]), goal[None])})


def test_training_needs_every_canonical_joint(walk, kick):
    """Daz has no toes: a universal variant cleans it (the network fills them) but does not
    train on it, since its images would hold placeholder toes as truth."""
    engine = CAE(CAE.Params(epochs=1, frames_per_epoch=512, window_frames=64, batch_size=4, universal=True))
    with pytest.raises(EngineError, match="left_toes, right_toes"):
        engine.fit([walk.slice(0, 200), kick.slice(0, 200)])


def test_a_plain_cae_names_the_universal_variant_for_mixed_skeletons(walk, kick):
    with pytest.raises(EngineError, match="cae:universal=true"):
        CAE(CAE.Params(epochs=1)).fit([walk, kick])


def test_a_skeleton_that_does_not_map_is_refused_naming_what_it_lacks(universal, walk):
    obs = parse_corruption("block:30").apply(walk.slice(0, 100), seed=0)
    universal.humanoid_overrides = {"left_thigh": None}  # as a mapping file dropping it
    try:
        with pytest.raises(EngineError, match="left_thigh"):
            universal.clean(obs)
    finally:
        universal.humanoid_overrides = None


def test_sampler_draws_each_skeleton_equally_often():
    """Two groups, of 1 and 9 images: with ``groups`` each is drawn half the time."""
    from engines.cae.representation import Layout

    layout = Layout(joints=(1,), source=(0, 1), parents=(-1, 0))
    H = layout.n_rows
    images = [np.full((80, H), float(i)) for i in range(10)]
    sampler = WindowSampler(
        images,
        np.zeros(H),
        np.ones(H),
        layout,
        None,
        np.array([1]),
        16,
        5.0,
        time_scale_pct=0.0,
        body_scale_pct=0.0,
        input_noise=0.0,
        input_fill="zero",
        sampling="clips",
        rng=np.random.default_rng(0),
        groups=[0] + [1] * 9,
    )
    first = sampler.windows(4000)[:, 0, 0] == 0.0
    assert abs(first.mean() - 0.5) < 0.03


def test_the_plain_cae_cleans_a_skeleton_without_weights_on_the_committed_universal_ones(kick, walk):
    """No Daz weights: ``cae`` uses ``cae:universal=true``'s committed weights, and says
    so; a CMU take still gets the CMU weights. ``holden`` and ``cae-vanilla`` have
    universal weights too; ``ebd``, which has none, refuses the Daz take, naming the skeleton."""
    from workbench import registry
    from workbench.core.motion import Observation

    engine = registry.create("cae")
    obs = parse_corruption("block:30").apply(kick.slice(0, 120), seed=0)
    result = engine.clean(obs)
    assert np.isfinite(result.motion.channels).all()
    assert engine.weights_used_.startswith("universal weights ") and "cae-universal" in engine.weights_used_
    universal = registry.create("cae:universal=true")
    assert engine.spec_used_ == universal.spec and "universal=True" in engine.spec_used_  # the weights' parameters
    np.testing.assert_array_equal(universal.clean(obs).motion.channels, result.motion.channels)
    engine.clean(Observation(walk.slice(0, 120)))
    assert engine.weights_used_.startswith("skeleton-specific weights ") and engine.weights_used_.endswith("cmu")
    assert engine.spec_used_ == engine.spec == "cae"
    for name in ("holden", "cae-vanilla"):
        other = registry.create(name)
        other.clean(obs)
        assert other.weights_used_.startswith("universal weights ") and f"{name}-universal" in other.weights_used_
    with pytest.raises(EngineError, match="no weights for this skeleton"):
        registry.create("ebd").clean(obs)
