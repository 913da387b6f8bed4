"""The canonical humanoid found on the shipped skeletons and on the naming conventions of
other exporters (hierarchies written here from their published joint lists)."""

import json

import numpy as np
import pytest

from workbench.core.humanoid import (
    CANONICAL_JOINTS,
    CANONICAL_PARENTS,
    ESSENTIAL_JOINTS,
    HumanoidError,
    joint_side,
    map_humanoid,
)
from workbench.core.skeleton import Skeleton
from workbench.data import find_clip

ROT = ("Zrotation", "Xrotation", "Yrotation")
POS = ("Xposition", "Yposition", "Zposition")


def body(joints, translated_root=None) -> Skeleton:
    """A skeleton from (name, parent name, offset) rows, parents first; the root (and
    ``translated_root``, a reference node above it) with position channels."""
    names = [n for n, _, _ in joints]
    parents = [names.index(p) if p else -1 for _, p, _ in joints]
    moving = {0} | ({names.index(translated_root)} if translated_root else set())
    return Skeleton(
        names=tuple(names),
        parents=tuple(parents),
        offsets=np.array([(0, 0, 0) if j in moving else o for j, (_, _, o) in enumerate(joints)], float),
        channels=tuple(POS + ROT if j in moving else ROT for j in range(len(names))),
        translated=(names.index(translated_root),) if translated_root else (),
        unit_cm=1.0,
    )


def limbs(spine, chest, arm, leg, *, prefix="", sides=("Left", "Right"), fingers=()):
    """A biped facing +Z: ``spine`` names from the root up to the head and beyond, the arms
    hanging off ``chest``; ``arm``/``leg`` per-side names, ``{s}`` standing for the side."""
    rows = [(prefix + spine[0], None, (0, 0, 0))]
    for a, b in zip(spine, spine[1:]):
        rows.append((prefix + b, prefix + a, (0, 12, 0)))
    chest = prefix + chest
    for s, x in zip(sides, (1, -1)):
        parent = chest
        for k, part in enumerate(arm):
            rows.append((prefix + part.format(s=s), parent, (x * (6 if k == 0 else 25), 0, 0)))
            parent = prefix + part.format(s=s)
        for f in fingers:
            rows.append((prefix + f.format(s=s), parent, (x * 8, 0, 0)))
        parent = prefix + spine[0]
        for k, part in enumerate(leg):
            rows.append((prefix + part.format(s=s), parent, (x * 9, 0, 0) if k == 0 else (0, -40, 6 * (k == 3))))
            parent = prefix + part.format(s=s)
    return body(rows)


MIXAMO = limbs(
    ["Hips", "Spine", "Spine1", "Spine2", "Neck", "Head", "HeadTop_End"],
    "Spine2",
    ["{s}Shoulder", "{s}Arm", "{s}ForeArm", "{s}Hand"],
    ["{s}UpLeg", "{s}Leg", "{s}Foot", "{s}ToeBase", "{s}Toe_End"],
    prefix="mixamorig:",
    fingers=["{s}HandThumb1", "{s}HandIndex1", "{s}HandMiddle1"],
)
HUMANIK = limbs(
    ["Hips", "Spine", "Spine1", "Spine2", "Spine3", "Neck", "Neck1", "Head"],
    "Spine3",
    ["{s}Shoulder", "{s}Arm", "{s}ArmRoll", "{s}ForeArm", "{s}ForeArmRoll", "{s}Hand"],
    ["{s}UpLeg", "{s}UpLegRoll", "{s}Leg", "{s}LegRoll", "{s}Foot", "{s}ToeBase"],
    fingers=["{s}HandThumb1", "{s}HandIndex1"],
)
SMPL = limbs(
    ["Pelvis", "Spine1", "Spine2", "Spine3", "Neck", "Head"],
    "Spine3",
    ["{s}_Collar", "{s}_Shoulder", "{s}_Elbow", "{s}_Wrist", "{s}_Hand"],
    ["{s}_Hip", "{s}_Knee", "{s}_Ankle", "{s}_Foot"],
    sides=("L", "R"),
)
LAFAN1 = limbs(
    ["Hips", "Spine", "Spine1", "Spine2", "Neck", "Head"],
    "Spine2",
    ["{s}Shoulder", "{s}Arm", "{s}ForeArm", "{s}Hand"],
    ["{s}UpLeg", "{s}Leg", "{s}Foot", "{s}Toe"],
)

EXPECTED = {
    "mixamo": (MIXAMO, {"chest": "Spine2", "spine": "Spine", "neck": "Neck", "head": "Head",
                        "left_shoulder": "LeftShoulder", "left_upper_arm": "LeftArm", "left_hand": "LeftHand",
                        "right_thigh": "RightUpLeg", "right_toes": "RightToeBase"}),
    "humanik": (HUMANIK, {"chest": "Spine3", "neck": "Neck", "left_forearm": "LeftForeArm",
                          "left_upper_arm": "LeftArm", "right_shin": "RightLeg", "right_thigh": "RightUpLeg",
                          "left_toes": "LeftToeBase"}),
    "smpl": (SMPL, {"hips": "Pelvis", "spine": "Spine1", "chest": "Spine3", "neck": "Neck",
                    "left_shoulder": "L_Collar", "left_upper_arm": "L_Shoulder", "left_forearm": "L_Elbow",
                    "left_hand": "L_Wrist", "right_thigh": "R_Hip", "right_shin": "R_Knee",
                    "right_foot": "R_Ankle", "right_toes": "R_Foot"}),
    "lafan1": (LAFAN1, {"chest": "Spine2", "left_toes": "LeftToe", "right_hand": "RightHand"}),
}  # fmt: skip


@pytest.mark.parametrize("convention", sorted(EXPECTED))
def test_other_exporters_map_by_their_own_naming(convention):
    skeleton, expected = EXPECTED[convention]
    mapping = map_humanoid(skeleton)
    names = {c: skeleton.names[j].split(":")[-1] for c, j in zip(CANONICAL_JOINTS, mapping.joints) if j >= 0}
    assert {c: names.get(c) for c in expected} == expected
    assert set(ESSENTIAL_JOINTS) <= set(names)
    # nothing of a finger, a roll joint or an end joint is taken
    assert not any(w in n for n in names.values() for w in ("Thumb", "Index", "Roll", "_End", "L_Hand"))


SHIPPED = {
    "cmu/walk/02_01": {"spine": "Spine", "chest": "Spine1", "neck": "Neck1", "left_shoulder": "LeftShoulder",
                       "left_thigh": "LeftUpLeg", "left_toes": "LeftToeBase"},
    "cmu-daz/kick/10_01": {"hips": "hip", "spine": "abdomen", "left_shoulder": "lCollar",
                           "left_upper_arm": "lShldr", "left_thigh": "lThigh", "left_toes": None},
    "bandai/walk/dataset-1_walk_normal_001": {"hips": "Hips", "chest": "Chest", "left_forearm": "LowerArm_L",
                                              "right_thigh": "UpperLeg_R", "right_toes": "Toes_R"},
}  # fmt: skip


@pytest.mark.parametrize("clip", sorted(SHIPPED))
def test_shipped_skeletons_map_and_their_canonical_joints_are_their_own_joints(clip, data_root):
    """FK of the canonical joints of a take is the take's own joints' positions, exactly."""
    motion = find_clip(clip).load()
    mapping = map_humanoid(motion.skeleton)
    names = {c: motion.skeleton.names[j] if j >= 0 else None for c, j in zip(CANONICAL_JOINTS, mapping.joints)}
    assert {c: names[c] for c in SHIPPED[clip]} == SHIPPED[clip]
    positions = motion.positions
    canonical = mapping.canonical_positions(positions)
    for c, j in zip(CANONICAL_JOINTS, mapping.joints):
        if j >= 0:
            assert np.array_equal(canonical[:, CANONICAL_JOINTS.index(c)], positions[:, j])
        else:
            assert np.isnan(canonical[:, CANONICAL_JOINTS.index(c)]).all()
    assert 110 < mapping.body_size_cm() < 170
    assert motion.skeleton.body_root not in mapping.unmapped_joints()


def test_a_reference_node_above_the_hips_is_left_out():
    rows = [("Reference", None, (0, 0, 0))] + [
        (n, LAFAN1.names[p] if p >= 0 else "Reference", o)
        for n, p, o in zip(LAFAN1.names, LAFAN1.parents, LAFAN1.offsets)
    ]
    skeleton = body(rows, translated_root="Hips")
    m = map_humanoid(skeleton)
    assert skeleton.names[m.joint("hips")] == "Hips" and m.unmapped_joints()[0] == 0
    assert "above the body root (1, kept as observed): Reference" in m.describe()
    assert "(1, aimed along the chain): Spine1\n" in m.describe() and 0 not in m.kept_joints()


def test_sides_from_names_of_every_convention():
    left = ["LeftArm", "lThigh", "LHipJoint", "L_Knee", "Hand_L", "Bip01 L Thigh", "mixamorig:LeftHand", "thigh.l"]
    right = ["RightArm", "rShin", "RThumb", "R_Ankle", "Foot_R", "m_avg_R_Hip"]
    assert [joint_side(n) for n in left] == ["left"] * len(left)
    assert [joint_side(n) for n in right] == ["right"] * len(right)
    assert [joint_side(n) for n in ("LowerBack", "Root", "Head", "Spine1", "Reference", "RibCage")] == [None] * 6


def test_unsided_names_take_their_side_from_the_rest_pose():
    """Left is +X of a body facing +Z: names that say no side are placed by the rest pose."""
    renamed = {"Left": "A", "Right": "B"}
    rows = []
    for n, p, o in zip(LAFAN1.names, LAFAN1.parents, LAFAN1.offsets):
        rename = lambda s: next((s.replace(k, v) for k, v in renamed.items() if s.startswith(k)), s)  # noqa: E731
        rows.append((rename(n), rename(LAFAN1.names[p]) if p >= 0 else None, o))
    m = map_humanoid(body(rows))
    names = m.skeleton.names
    assert names[m.joint("left_hand")] == "AHand" and names[m.joint("right_foot")] == "BFoot"


def test_the_canonical_tree_is_a_tree_over_its_own_joints():
    assert list(CANONICAL_PARENTS) == list(CANONICAL_JOINTS) and len(CANONICAL_JOINTS) == 21
    for c, p in CANONICAL_PARENTS.items():
        assert p is None or CANONICAL_JOINTS.index(p) < CANONICAL_JOINTS.index(c)


def test_a_skeleton_without_arms_is_refused_naming_what_it_lacks():
    snake = body([("seg0", None, (0, 0, 0))] + [(f"seg{i}", f"seg{i - 1}", (0, 0, 5)) for i in range(1, 50)])
    with pytest.raises(HumanoidError, match=r"no joint for chest, head, left_upper_arm.*--mapping") as err:
        map_humanoid(snake)
    assert "classical engine" in str(err.value)


def test_a_mapping_pins_drops_and_is_checked(data_root):
    cmu = find_clip("cmu/walk/02_01").load().skeleton
    m = map_humanoid(cmu, {"neck": "Neck", "left_toes": None})
    assert cmu.names[m.joint("neck")] == "Neck" and m.joint("left_toes") == -1 and "neck" in m.pinned
    assert "neck             Neck (mapping file)" in m.describe()
    with pytest.raises(HumanoidError, match="not a canonical joint"):
        map_humanoid(cmu, {"pelvis": "Hips"})
    with pytest.raises(HumanoidError, match="no joint 'Chest'"):
        map_humanoid(cmu, {"chest": "Chest"})
    with pytest.raises(HumanoidError, match="both"):
        map_humanoid(cmu, {"left_hand": "RightHand"})
    with pytest.raises(HumanoidError, match=r"'Neck1' is both neck and left_shin.*the mapping pins left_foot = 'Head'"):
        map_humanoid(cmu, {"left_foot": "Head"})  # the shin found above the foot pinned: the message names the pin
    with pytest.raises(HumanoidError, match="left_toes = 'RightToeBase' is not below left_foot = 'LeftFoot'"):
        map_humanoid(cmu, {"left_toes": "RightToeBase"})


def test_skeleton_command_prints_the_mapping_and_reads_a_mapping_file(tmp_path, data_root, capsys):
    from workbench.cli import main

    take = find_clip("cmu-daz/kick/10_01").path
    assert main(["skeleton", str(take)]) == 0
    out = capsys.readouterr().out
    assert "43 joints" in out and "left_toes        -  (optional)" in out
    # the buttocks lie between the hips and the thighs: aimed, not kept; the fingers and eyes kept
    assert "unmapped above mapped joints (2, aimed along the chain): rButtock, lButtock" in out
    assert "unmapped (22, keep their own angles): leftEye, rightEye, rThumb1" in out
    mapping = tmp_path / "map.json"
    mapping.write_text(json.dumps({"neck": None}))
    assert main(["skeleton", str(take), "--mapping", str(mapping)]) == 0
    assert "neck             - (mapping file)  (optional)" in capsys.readouterr().out
    mapping.write_text("[1, 2]")
    assert main(["skeleton", str(take), "--mapping", str(mapping)]) == 2
    assert "map.json: a mapping file is one JSON object" in capsys.readouterr().err
    mapping.write_text(json.dumps({"necc": "Neck1"}))  # refused whatever the engine, kalman too
    for command in (["skeleton", str(take)], ["clean", str(take), "-o", str(tmp_path / "o.bvh"), "--engine", "kalman"]):
        assert main([*command, "--mapping", str(mapping)]) == 2
        assert "map.json: necc: not a canonical joint" in capsys.readouterr().err
    studio = find_clip("bandai/walk/dataset-1_walk_active_001").path  # Hips under the reference node joint_Root
    mapping.write_text(json.dumps({"hips": "joint_Root"}))  # refused as the engines refuse it: they map the body
    for command in (["skeleton", str(studio)], ["inspect", str(studio), "--engine", "cae:universal=true"]):
        assert main([*command, "--mapping", str(mapping)]) == 2
        assert "hips = 'joint_Root', but the take has no joint 'joint_Root'" in capsys.readouterr().err


def test_a_long_spine_bends_about_its_mapped_joint():
    """HumanIK's Spine1 and Spine2 lie between the mapped spine and chest. Poses that bend
    the spine joint alone come back from their canonical positions as that bend, the
    unmapped joints at the reference's angles: their targets follow the reference chain
    turned about the spine (moved with the chest instead, they aim the spine at Spine1,
    one 12-cm bone away, and zigzag the chain: Spine bent 44.6 degrees for a lean of 16.7,
    Spine1 36.8 back)."""
    from workbench.core.kinematics import forward_kinematics
    from workbench.core.rotations import euler_to_matrix, matrix_to_euler, vectors_to_rotation
    from workbench.engine.canonical import CanonicalBody

    body = CanonicalBody(map_humanoid(HUMANIK))
    spine = HUMANIK.names.index("Spine")
    assert body.mapping.joint("spine") == spine and HUMANIK.names[body.mapping.joint("chest")] == "Spine3"
    reference = np.zeros((3, HUMANIK.n_joints, 3))
    up = np.array([0.0, 1.0, 0.0])
    leans = np.array([[0.3, 1.0, 0.0], [0.0, 1.0, -0.4], [-0.5, 1.0, 0.5]])
    bent = reference.copy()  # a bend with no twist about the bone: the aim alone cannot tell one
    bent[:, spine] = matrix_to_euler(
        vectors_to_rotation(np.broadcast_to(up, leans.shape), leans), HUMANIK.rotation_order(spine)
    )
    positions, _ = forward_kinematics(HUMANIK, np.zeros((3, 3)), bent)
    root, angles, _ = body.solve(body.positions(positions), np.zeros((3, 3)), reference)
    assert np.allclose(root, 0.0, atol=1e-9)
    solved = euler_to_matrix(angles[:, spine], HUMANIK.rotation_order(spine))
    truth = euler_to_matrix(bent[:, spine], HUMANIK.rotation_order(spine))
    assert np.allclose(solved, truth, atol=1e-9)
    others = np.arange(HUMANIK.n_joints) != spine
    assert np.allclose(angles[:, others], 0.0, atol=1e-7)


def test_a_head_no_name_gives_is_named_as_the_one_to_map_and_skeleton_shows_the_rest(tmp_path, capsys):
    """The chest and arms are found from the head and the hands: with the head's name in
    another language they are missing too, and the message names the head to map."""
    from workbench.cli import main

    take = tmp_path / "kopf.bvh"
    text = find_clip("cmu/walk/02_01").path.read_text()
    take.write_text(text.replace("JOINT Head\n", "JOINT Kopf\n"))
    assert main(["skeleton", str(take)]) == 2
    captured = capsys.readouterr()
    assert "left_hand        LeftHand" in captured.out and "head             -  (essential)" in captured.out
    assert "(chest, left_upper_arm, left_forearm, right_upper_arm, right_forearm are found from head, which no " in (
        captured.err
    )
    assert '{"head": "JointName"}' in captured.err
    (tmp_path / "map.json").write_text('{"head": "Kopf"}')
    assert main(["skeleton", str(take), "--mapping", str(tmp_path / "map.json")]) == 0
    assert "chest            Spine1" in capsys.readouterr().out
