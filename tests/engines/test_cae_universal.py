"""The universal cae (``cae:universal=true``): the image of the canonical humanoid, trained on
several skeletons together, cleaning a skeleton it has never seen (engines/cae/bodies.py)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from engines.cae import CAE
from engines.cae.training import WindowSampler
from workbench.app.take import EngineRun
from workbench.core.humanoid import map_humanoid
from workbench.core.kinematics import forward_kinematics
from workbench.corruption import parse_corruption
from workbench.engine import EngineError
from workbench.engine.base import HUMANOID_SIGNATURE
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
    assert universal.skeleton_signature_ == HUMANOID_SIGNATURE
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


def test_trains_on_a_skeleton_without_toes_from_the_rows_it_has(walk, kick):
    """Daz has no toes: its images hold placeholders there (the hips' position). A universal
    cae trains on it all the same, and what it learns does not depend on them: they are
    never known in its input, out of the loss and out of the image units."""
    from engines.cae.bodies import CANONICAL_LAYOUT, CanonicalJoints
    from engines.cae.representation import image_mask, mirror_rows
    from engines.cae.training import image_units, train

    params = CAE.Params(epochs=1, frames_per_epoch=512, window_frames=64, batch_size=4, universal=True)
    assert CAE(params).fit([walk.slice(0, 200), kick.slice(0, 200)]).skeleton_signature_ == HUMANOID_SIGNATURE

    layout, imaging = CANONICAL_LAYOUT, CanonicalJoints(map_humanoid(kick.skeleton))
    has = image_mask(layout, imaging.known(np.ones((1, kick.skeleton.n_joints), bool)))[0]
    toes = np.zeros_like(has)
    for name in ("left_toes", "right_toes"):
        toes[layout.rows(imaging.names.index(name))] = True
    np.testing.assert_array_equal(has, ~toes)
    rng = np.random.default_rng(0)
    image = rng.normal(size=(200, layout.n_rows))
    other = np.where(toes, 1e3, image)  # other placeholders
    mirror = mirror_rows(layout, imaging.names)
    units = image_units([image], [has], mirror)
    for a, b in zip(units, image_units([other], [has], mirror)):
        np.testing.assert_array_equal(a, b)
    whole = np.concatenate([image, image[:, mirror[0]] * mirror[1]])
    plain = image_units([image], [np.ones_like(has)], mirror)
    np.testing.assert_array_equal(plain[0], whole.mean(axis=0).astype(np.float32))
    np.testing.assert_array_equal(plain[1], whole.std(axis=0).astype(np.float32))

    def learnt(images):
        torch.manual_seed(0)
        net = torch.nn.Sequential(torch.nn.Conv2d(2, 1, 3, padding=1), torch.nn.Flatten(1, 2))
        sampler = WindowSampler(
            images, *units, layout, mirror, np.arange(1, layout.n_joints), 32, 5.0, 10.0, 5.0, 0.1, "linear",
            "clips", np.random.default_rng(1), present=[has],
        )  # fmt: skip
        X, x, present = sampler.batch(16, 10)
        assert not x[:, 1].numpy()[:, toes].any() and (present == has).all()
        loss = train(net, sampler, 2, 3, 4, 1e-2, 100.0, 1, 0.0, "test")
        return loss, [t.detach().numpy() for t in net.parameters()]

    one_side = has.copy()  # a skeleton with a right toe only: mirrored windows lack the other toe
    one_side[layout.rows(imaging.names.index("right_toes"))] = True
    sampler = WindowSampler(
        [image], *units, layout, mirror, np.arange(1, layout.n_joints), 32, 5.0, 10.0, 5.0, 0.1, "linear",
        "clips", np.random.default_rng(2), present=[one_side],
    )  # fmt: skip
    _, x, present = sampler.batch(64, 10)
    flipped = (present == one_side[mirror[0]]).all(axis=1)
    assert flipped.any() and (flipped | (present == one_side).all(axis=1)).all()
    assert not ((x[:, 1].numpy() > 0) & ~present[:, :, None]).any()

    (loss, weights), (loss_other, weights_other) = learnt([image]), learnt([other])
    assert loss == loss_other
    for a, b in zip(weights, weights_other):
        np.testing.assert_array_equal(a, b)


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
    first = sampler.windows(4000)[0][:, 0, 0] == 0.0
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


def test_universal_share_blends_the_own_weights_clean_towards_the_universal_one(walk):
    """``cae:universal_share=0.3`` on a CMU take: the CMU weights' clean moved 0.3 of the
    way towards the universal weights' clean, both named in its weights line; observed
    samples kept exactly with keep_observed; constraints, which a blend would not keep,
    are the own weights' alone; refused where no universal weights are at hand."""
    from workbench import registry
    from workbench.core.motion import blended

    obs = parse_corruption("block:30").apply(walk.slice(0, 120), seed=0)
    engine = registry.create("cae:universal_share=0.3")
    result = engine.clean(obs)
    own, universal = (registry.create(spec).clean(obs).motion for spec in ("cae", "cae:universal=true"))
    np.testing.assert_array_equal(result.motion.channels, blended(own, universal, 0.3).channels)
    assert not np.allclose(own.channels, universal.channels, atol=0.1)  # a blend of two different cleans
    assert engine.weights_used_.startswith("skeleton-specific weights ")
    assert "blended 0.3 towards universal weights " in engine.weights_used_
    assert ", " not in engine.weights_used_  # a pipeline's output line separates its stages so
    assert EngineRun("cae", None, weights=engine.weights_used_).weights_kind == "own and universal weights"

    kept = registry.create("cae:universal_share=0.3,keep_observed=true").clean(obs).motion.channels
    seen = obs.channel_observed
    np.testing.assert_array_equal(kept[seen], obs.motion.channels[seen])

    hand = walk.skeleton.index("LeftHand")
    frame = int(np.flatnonzero(~obs.observed[:, 0])[10])
    guide = {hand: (np.array([frame]), walk.positions[frame, hand][None] + 5.0)}
    np.testing.assert_array_equal(
        engine.clean(obs, constraints=guide).motion.channels,
        registry.create("cae").clean(obs, constraints=guide).motion.channels,
    )

    engine.committed_universal = lambda: None  # as for weights whose trained parameters no universal ones have
    with pytest.raises(EngineError, match="universal_share blends with the committed weights of cae:universal=true"):
        engine.clean(obs)
    for spec, message in (
        ("cae:universal_share=2", "0 \\(off\\) to 1"),
        ("cae:universal=true,universal_share=0.3", "not"),
    ):
        with pytest.raises(EngineError, match=message):
            registry.create(spec)
