import numpy as np
import pytest

from workbench import metrics
from workbench.core import angle_columns


def test_zero_error_on_truth(walk):
    s = metrics.score(walk, walk)
    assert s["rms_angle_deg"] == 0 and s["mpjpe_cm"] == 0
    assert "gap_mpjpe_cm" not in s


def test_rms_angle_is_wrap_safe_and_per_frame(walk):
    X = walk.channels
    cols = angle_columns(walk.skeleton)
    X[:, cols] += 360.0  # the same angles
    assert metrics.rms_angle_deg(walk, walk.with_channels(X)) == pytest.approx(0, abs=1e-9)
    X = walk.channels
    X[:, cols[0]] += 358.0  # a 2 degree error across the wrap
    per_frame = metrics.rms_angle_deg_per_frame(walk, walk.with_channels(X))
    assert np.allclose(per_frame, np.sqrt(4.0 / len(cols)))


def test_root_channels_are_not_scored_as_angles(walk):
    X = walk.channels
    X[:, 3:6] += 10.0  # root orientation
    assert metrics.rms_angle_deg(walk, walk.with_channels(X)) == 0


def test_mpjpe_is_root_aligned_and_in_cm(walk):
    X = walk.channels
    X[:, :3] += 5.0  # moving the whole body is no joint error
    assert metrics.mpjpe_cm(walk, walk.with_channels(X)) == pytest.approx(0, abs=1e-9)
    est = walk.with_channels(walk.channels)
    P = walk.positions.copy()
    P[:, 5] += [1.0, 0, 0]  # one joint off by one unit
    err = np.linalg.norm((P - P[:, :1]) - (walk.positions - walk.positions[:, :1]), axis=2)
    assert err[:, 5].mean() * walk.skeleton.unit_cm == pytest.approx(5.64)
    del est


def test_gap_mpjpe_counts_the_positions_that_depend_on_missing_angles(walk):
    sk = walk.skeleton
    X = walk.channels
    j = sk.index("LeftForeArm")
    X[:, 3 + 3 * j] += 20.0
    est = walk.with_channels(X)
    observed = np.ones((walk.n_frames, sk.n_joints), bool)
    assert np.isnan(metrics.gap_mpjpe_cm(walk, est, observed))
    observed[10:20, j] = False  # the forearm's angles move the hand and the fingers, not the forearm
    below = [k for k in range(sk.n_joints) if k != j and j in _ancestors(sk.parents, k)]
    assert [sk.names[k] for k in below] == ["LeftHand", "LeftFingerBase", "LeftHandIndex1", "LThumb"]
    gap = metrics.gap_mpjpe_cm(walk, est, observed)
    assert gap == pytest.approx(metrics.joint_position_error_cm(walk, est)[10:20][:, below].mean())
    assert gap > 0
    observed[:] = True
    observed[5, 0] = False  # the root missing: every position in that frame depends on it
    assert metrics.gap_mpjpe_cm(walk, est, observed) == pytest.approx(
        metrics.joint_position_error_cm(walk, est)[5].mean()
    )
    observed[:] = True
    observed[:, sk.index("LThumb")] = False  # a leaf: no position depends on its angles
    assert np.isnan(metrics.gap_mpjpe_cm(walk, est, observed))


def _ancestors(parents, k):
    out = []
    while parents[k] >= 0:
        k = parents[k]
        out.append(k)
    return out


def test_root_error_is_the_trajectory_the_root_aligned_scores_ignore(walk):
    X = walk.channels
    X[:, 0] += 2.0  # the whole take moved 2 file units along x
    moved = walk.with_channels(X)
    assert metrics.mpjpe_cm(walk, moved) < 1e-9
    assert metrics.root_cm(walk, moved) == pytest.approx(2.0 * walk.skeleton.unit_cm)
    assert "root_cm" in metrics.score(walk, moved)


def test_bone_lengths_and_jitter(walk):
    stats = metrics.bone_length_stats_cm(walk.positions, walk)
    assert np.allclose(stats["std"], 0, atol=1e-9)
    assert np.allclose(stats["mean"], np.linalg.norm(walk.skeleton.offsets[1:], axis=1) * 5.64)
    rng = np.random.default_rng(0)
    X = walk.channels
    X[:, 6:] += rng.normal(size=X[:, 6:].shape)
    assert metrics.jitter_cm_s3(walk.with_channels(X)) > 3 * metrics.jitter_cm_s3(walk)


def test_layout_mismatch_is_an_error(walk, kick):
    with pytest.raises(ValueError, match="skeleton"):
        metrics.rms_angle_deg(walk, kick)
    with pytest.raises(ValueError, match="frame counts"):
        metrics.mpjpe_cm(walk, walk.slice(0, 10))


def test_a_studio_take_is_aligned_at_its_hips_and_its_root_chain_is_the_trajectory(studio_take):
    """joint_Root carries the moving Hips: together they are the trajectory. Moving the
    Hips and turning both is no joint error, it is root error, and their rotations are
    no joint-angle channels."""
    sk = studio_take.skeleton
    assert sk.root_chain == (0, 1) and sk.body_root == 1
    moved = studio_take.replace(translations=studio_take.translations + [3.0, 0.0, 4.0])
    assert metrics.mpjpe_cm(studio_take, moved) == pytest.approx(0, abs=1e-9)
    X = moved.channels
    X[:, 6:9] += 10.0  # the Hips' rotation
    turned = moved.with_channels(X)
    assert metrics.rms_angle_deg(studio_take, turned) == 0
    assert metrics.root_cm(studio_take, turned) == pytest.approx(5.0)  # the Hips, 5 cm off
    X[:, 3:6] += 10.0  # joint_Root's, which swings the Hips about the origin: no joint angle either
    assert metrics.rms_angle_deg(studio_take, moved.with_channels(X)) == 0


def test_a_stretching_bone_is_scored_in_positions(stretchy_take):
    """A translated joint's translation is no angle: getting its stretch wrong shows in
    the joint positions it moves, not in the angles."""
    rigid = stretchy_take.replace(
        translations=np.concatenate(
            [
                stretchy_take.translations[:, :1],
                np.broadcast_to(
                    stretchy_take.skeleton.offsets[stretchy_take.skeleton.translated[1]],
                    stretchy_take.translations[:, 1:].shape,
                ),
            ],
            axis=1,
        )
    )
    assert metrics.rms_angle_deg(stretchy_take, rigid) == 0
    err = metrics.joint_position_error_cm(stretchy_take, rigid)
    arm = [stretchy_take.skeleton.index(n) for n in ("LowerArm_L", "Hand_L")]
    assert err[:, arm].max() > 2.0 and np.delete(err, arm, axis=1).max() == pytest.approx(0, abs=1e-9)
    observed = np.ones(err.shape, bool)
    observed[10:20, arm[0]] = False  # a translated joint missing: its own position is unknown
    assert metrics.gap_mpjpe_cm(stretchy_take, rigid, observed) == pytest.approx(err[10:20, arm].mean())


def _descendant_names(skeleton, joint: int) -> set[str]:
    below = {joint}
    for k in range(joint + 1, skeleton.n_joints):  # parents come first
        if skeleton.parents[k] in below:
            below.add(k)
    return {skeleton.names[k] for k in below - {joint}}


@pytest.mark.parametrize("take", ["walk", "studio_take"])
def test_per_joint_scores_add_up_to_the_headline_numbers(take, request):
    """The joints' mean squared angle errors average to the frames' mean square, and their
    position errors (with the body root's 0) to mpjpe; one joint turned is one joint's
    error, and its descendants' positions."""
    truth = request.getfixturevalue(take)
    sk = truth.skeleton
    rng = np.random.default_rng(0)
    X = truth.channels
    cols = angle_columns(sk)
    X[:, cols] += rng.normal(0.0, 2.0, (truth.n_frames, cols.size))
    noisy = truth.with_channels(X)
    by_joint = metrics.per_joint(truth, noisy)
    angles = np.array(list(by_joint["rms_angle_deg"].values()))
    assert list(by_joint["rms_angle_deg"]) == [sk.names[j] for j in metrics.angle_joints(sk)]
    per_frame = metrics.rms_angle_deg_per_frame(truth, noisy)
    assert np.mean(angles**2) == pytest.approx(np.mean(per_frame**2), rel=1e-12)
    positions = np.array(list(by_joint["mpjpe_cm"].values()))
    assert sk.names[sk.body_root] not in by_joint["mpjpe_cm"]
    assert np.sum(positions) / metrics.body_joints(sk).size == pytest.approx(metrics.mpjpe_cm(truth, noisy), rel=1e-12)
    j = next(int(j) for j in metrics.angle_joints(sk) if any(np.any(sk.offsets[c]) for c in sk.children[j]))
    X = truth.channels
    X[:, 3 + 3 * j] += 5.0
    one = metrics.per_joint(truth, truth.with_channels(X))
    wrong = {name for name, v in one["rms_angle_deg"].items() if v > 0}
    assert wrong == {sk.names[j]} and one["rms_angle_deg"][sk.names[j]] == pytest.approx(5.0 / np.sqrt(3.0))
    assert "gap_mpjpe_cm" not in by_joint and "gap_mpjpe_cm" not in one
    moved = {name for name, v in one["mpjpe_cm"].items() if v > 1e-9}
    assert moved and moved <= _descendant_names(sk, j)


def test_per_joint_gap_error_is_over_the_positions_that_depend_on_missing_data(walk):
    sk = walk.skeleton
    j = next(int(j) for j in metrics.angle_joints(sk) if sk.children[j])
    observed = np.ones((walk.n_frames, sk.n_joints), bool)
    observed[10:20, j] = False
    X = walk.channels
    X[10:20, 3 + 3 * j] += 5.0  # the gap filled 5 degrees off
    estimate = walk.with_channels(X)
    gaps = metrics.per_joint(walk, estimate, observed)["gap_mpjpe_cm"]
    below = _descendant_names(sk, j)
    assert all(np.isnan(v) for name, v in gaps.items() if name not in below | {sk.names[j]})
    assert np.isnan(gaps[sk.names[j]])  # its own position does not depend on its angles
    errors = metrics.joint_position_error_cm(walk, estimate)
    for name in below:
        assert gaps[name] == pytest.approx(errors[10:20, sk.names.index(name)].mean())
