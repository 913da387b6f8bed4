"""Spatial noise: position noise in cm before IK, bone lengths kept after it."""

from __future__ import annotations

import numpy as np
import pytest

from workbench.core.kinematics import inverse_kinematics
from workbench.core.skeleton import Skeleton
from workbench.corruption import (
    CorruptionApplyError,
    Spatial,
    SpatialEnds,
    end_joints,
    parse_corruption,
    random_stream,
)
from workbench.corruption.base import Work
from workbench.corruption.spatial import noisy_positions


def _position_error_cm(motion, model, seed=0):
    """(F, J, 3) noise drawn by ``model`` as the first model of a chain, in cm, before IK."""
    work = Work(motion)
    rng = random_stream(seed, 0, model.name)
    noisy = noisy_positions(work, rng, model.sigmas_cm(motion.skeleton))
    return (noisy - motion.positions) * motion.skeleton.unit_cm


@pytest.mark.parametrize("s", [0.5, 3.0])
def test_position_noise_std_in_cm(long_walk, s):
    err = _position_error_cm(long_walk, Spatial(s))
    assert abs(err.std() / s - 1) < 0.05
    per_joint_axis = err.std(axis=0) / s
    assert np.all(np.abs(per_joint_axis - 1) < 0.05)
    assert np.all(np.abs(err.mean(axis=0)) < 0.1 * s)


def test_position_noise_in_cm_on_a_cm_skeleton(daz):
    assert daz.skeleton.unit_cm == 1.0
    err = _position_error_cm(daz, Spatial(1.0))
    assert abs(err.std() - 1.0) < 0.05


def test_spatial_keeps_bone_lengths_and_moves_joints(walk):
    s = 1.0
    seed = 3
    obs = parse_corruption(f"spatial:{s}").apply(walk, seed=seed)
    assert obs.observed.all() and np.isfinite(obs.motion.channels).all()
    # the result is the IK of the noisy positions, with the clean angles as reference
    noisy = noisy_positions(Work(walk), random_stream(seed, 0, "spatial"), np.full(walk.skeleton.n_joints, s))
    root, ang, _ = inverse_kinematics(walk.skeleton, noisy, reference_angles_deg=walk.angles_deg)
    assert np.array_equal(obs.motion.root_positions, root)  # the root takes its noisy value
    assert np.array_equal(obs.motion.angles_deg, ang)
    # bone lengths are exactly the skeleton's
    P = obs.motion.positions
    for p, j in walk.skeleton.bones:
        length = np.linalg.norm(P[:, j] - P[:, p], axis=1)
        assert np.allclose(length, np.linalg.norm(walk.skeleton.offsets[j]), rtol=0, atol=1e-9)
    # and the joints moved, by about the noise level
    moved_cm = np.linalg.norm(P - walk.positions, axis=2) * walk.skeleton.unit_cm
    assert moved_cm.mean() > 0.3 * s
    assert moved_cm.mean() < 5 * s
    root_moved = np.linalg.norm(obs.motion.root_positions - walk.root_positions, axis=1) * walk.skeleton.unit_cm
    assert abs(root_moved.mean() / (s * np.sqrt(8 / np.pi)) - 1) < 0.15  # Maxwell mean, 3-D std s


def test_end_joints_found_on_both_skeletons(walk, daz):
    names = lambda m: sorted(m.skeleton.names[j] for j in end_joints(m.skeleton))  # noqa: E731
    assert names(walk) == ["LeftFoot", "LeftHand", "RightFoot", "RightHand"]
    assert names(daz) == ["lFoot", "lHand", "rFoot", "rHand"]


def test_end_joint_name_rule():
    from workbench.corruption import END_JOINT_PATTERN as pat

    for ok in ("LeftHand", "rFoot", "left_wrist", "R_Ankle", "hand_l", "Foot.R", "RIGHTHAND"):
        assert pat.match(ok), ok
    for bad in ("LeftHandIndex1", "LeftFootEnd", "Hand", "lThumb1", "LeftToeBase", "Handle"):
        assert not pat.match(bad), bad


def test_spatial_ends_levels(long_walk):
    a, b = 2.0, 0.5
    model = SpatialEnds(a, b)
    err = _position_error_cm(long_walk, model, seed=1)
    ends = end_joints(long_walk.skeleton)
    rest = np.setdiff1d(np.arange(long_walk.skeleton.n_joints), ends)
    assert abs(err[:, ends].std() / a - 1) < 0.05
    assert abs(err[:, rest].std() / b - 1) < 0.05


def test_spatial_ends_runs_on_the_daz_skeleton(daz):
    clip = daz.slice(0, 120)
    obs = parse_corruption("spatial-ends:0.5,0.1").apply(clip, seed=0)
    P = obs.motion.positions
    for p, j in clip.skeleton.bones:
        assert np.allclose(np.linalg.norm(P[:, j] - P[:, p], axis=1), np.linalg.norm(clip.skeleton.offsets[j]))
    assert not np.array_equal(P, clip.positions)


def test_spatial_ends_needs_wrists_and_ankles(walk):
    sk = walk.skeleton
    renamed = Skeleton(
        tuple(f"joint{j}" for j in range(sk.n_joints)), sk.parents, sk.offsets, sk.channels, sk.end_sites, sk.unit_cm
    )
    clip = walk.slice(0, 10).replace(skeleton=renamed)
    with pytest.raises(CorruptionApplyError, match="spatial-ends.*wrist or ankle"):
        parse_corruption("spatial-ends:0.5,0.1").apply(clip)
    parse_corruption("spatial:0.5").apply(clip)  # plain spatial does not care about names


def test_spatial_after_gaps_keeps_the_mask(walk):
    obs = parse_corruption("drop:0.2+spatial:0.5").apply(walk, seed=2)
    drop = parse_corruption("drop:0.2").apply(walk, seed=2)
    assert np.array_equal(obs.observed, drop.observed)
    # missing joints do not spread NaN to their children
    assert np.isfinite(obs.motion.angles_deg[obs.observed]).all()
