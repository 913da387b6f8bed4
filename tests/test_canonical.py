"""A take as the canonical humanoid and back onto its own skeleton (workbench.engine.canonical)."""

import numpy as np
import pytest

from workbench.core.humanoid import CANONICAL_JOINTS, map_humanoid
from workbench.core.kinematics import forward_kinematics
from workbench.core.rotations import euler_to_matrix, matrix_to_euler
from workbench.data import find_clip
from workbench.engine.canonical import CANONICAL_BODY_CM, CanonicalBody, facing
from workbench.engine.view import body_skeleton, to_body

TAKES = ["cmu/walk/02_01", "cmu-daz/kick/10_01", "bandai/walk/dataset-1_walk_normal_001"]


def body_take(clip: str):
    """The take in its body view (the Hips as root), as an engine gets it."""
    motion = find_clip(clip).load()
    return to_body(motion, body_skeleton(motion.skeleton))


@pytest.mark.parametrize("clip", TAKES)
def test_every_body_is_scaled_to_one_size_and_faces_its_heading(clip, data_root):
    motion = body_take(clip)
    body = CanonicalBody(map_humanoid(motion.skeleton))
    assert body.mapping.body_size_cm() * body.scale / motion.skeleton.unit_cm == pytest.approx(CANONICAL_BODY_CM)
    P = body.positions(motion.positions)
    assert P.shape == (motion.n_frames, 21, 3)
    # turning the take about the up axis turns its facing by as much
    turn = euler_to_matrix(np.array([[0.0, 70.0, 0.0]]), "XYZ")[0]
    R0 = euler_to_matrix(motion.angles_deg[:, 0], motion.skeleton.rotation_order(0))
    turned = motion.replace(
        root_positions=motion.root_positions @ turn.T,
        angles_deg=np.concatenate(
            [matrix_to_euler(turn @ R0, motion.skeleton.rotation_order(0))[:, None], motion.angles_deg[:, 1:]], axis=1
        ),
    )
    delta = np.angle(np.exp(1j * (facing(body.positions(turned.positions)) - facing(P))))
    assert np.allclose(delta, np.radians(70.0), atol=1e-9)


def test_a_body_in_its_rest_pose_faces_plus_z(data_root):
    motion = body_take("cmu/walk/02_01")
    zero = {"angles_deg": np.zeros_like(motion.angles_deg[:1]), "root_positions": np.zeros((1, 3))}
    rest = motion.replace(**zero, translations=np.zeros((1, 0, 3)))
    body = CanonicalBody(map_humanoid(motion.skeleton))
    assert abs(facing(body.positions(rest.positions))[0]) < 0.05


@pytest.mark.parametrize("clip", TAKES)
def test_the_truth_comes_back_exactly(clip, data_root):
    """Canonical positions of a take, solved back with the take as reference: the take."""
    motion = body_take(clip)
    body = CanonicalBody(map_humanoid(motion.skeleton))
    root, angles, _ = body.solve(body.positions(motion.positions), motion.root_positions, motion.angles_deg)
    P, _ = forward_kinematics(motion.skeleton, root, angles)
    assert np.abs(P - motion.positions).max() * motion.skeleton.unit_cm < 1e-6


@pytest.mark.parametrize("clip", TAKES)
def test_another_pose_is_reached_with_the_unmapped_joints_as_the_reference(clip, data_root):
    """Targets from frames 30 later, the reference from these: the mapped joints reach the
    later pose (bone lengths are the skeleton's, by FK), the joints IK keeps hold the
    reference's angles exactly."""
    motion = body_take(clip)
    body = CanonicalBody(map_humanoid(motion.skeleton))
    now, later = slice(0, motion.n_frames - 30), slice(30, None)
    goal = body.positions(motion.positions[later])
    root, angles, _ = body.solve(goal, motion.root_positions[now], motion.angles_deg[now])
    P, _ = forward_kinematics(motion.skeleton, root, angles)
    reached = body.positions(P)
    mapped = body.mapping.mapped
    error_cm = np.linalg.norm(reached[:, mapped] - goal[:, mapped], axis=-1)
    assert np.median(error_cm) < 0.5 and np.percentile(error_cm, 99) < 6.0
    kept = body.kept_joints
    assert np.array_equal(angles[:, kept], motion.angles_deg[now][:, kept])
    names = {motion.skeleton.names[j] for j in kept}
    hand = motion.skeleton.names[body.mapping.joint("left_hand")]
    assert hand in names and motion.skeleton.names[body.mapping.joint("left_forearm")] not in names


def test_a_canonical_joint_the_take_lacks_is_never_known(data_root):
    motion = body_take("cmu-daz/kick/10_01")
    body = CanonicalBody(map_humanoid(motion.skeleton))
    toes = CANONICAL_JOINTS.index("left_toes")
    assert np.isnan(body.positions(motion.positions)[:, toes]).all()
    known = body.known(np.ones((5, motion.skeleton.n_joints), bool))
    assert not known[:, toes].any() and known.sum() == 5 * 19
