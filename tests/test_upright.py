"""Takes that stand on another axis than Y (workbench.core.upright): read, cleaned and
shown as the same take standing on Y."""

from __future__ import annotations

import numpy as np
import pytest

from workbench import registry
from workbench.core.motion import Motion, Observation
from workbench.core.rotations import axis_rotation
from workbench.core.skeleton import Skeleton
from workbench.core.upright import turn_motion, turn_skeleton, turn_vectors, up_turn
from workbench.corruption import make_case
from workbench.render.scene import skeleton_points

#: every quarter and half turn about X or Z: Y-up takes turned to stand on -Y, Z, -Z, X, -X
TURNS = [np.round(axis_rotation(axis, np.radians(deg))) for axis in (0, 2) for deg in (90, 180, -90)]
TURN_IDS = ["Z", "-Y about X", "-Z", "-X", "-Y about Z", "X"]


@pytest.mark.parametrize("turn", TURNS, ids=TURN_IDS)
def test_turning_a_take_turns_its_world_and_turning_back_gives_it_bit_for_bit(turn, walk, studio_take):
    for take in (walk, studio_take):
        turned = turn_motion(take, turn)
        assert np.allclose(turned.positions, turn_vectors(take.positions, turn), atol=1e-9)
        assert np.allclose(turn_vectors(take.positions, turn), take.positions @ turn.T, atol=0)
        back = turn_motion(turned, turn.T, take.skeleton)
        assert np.array_equal(back.channels, take.channels)
        again = turn_skeleton(turned.skeleton, turn.T)
        assert again.signature() == take.skeleton.signature()
        assert np.array_equal(again.offsets, take.skeleton.offsets) and again.end_sites == take.skeleton.end_sites


@pytest.mark.parametrize("turn", TURNS, ids=TURN_IDS)
def test_a_take_s_up_is_read_from_its_motion_and_its_unit_from_its_rest_pose(turn, walk):
    """A CMU walk exported standing on another axis (rest pose, offsets and channels as
    such an exporter writes them) is turned back onto Y, and its unit guessed as CMU's."""
    turned = turn_motion(walk, turn)
    upright = up_turn(turned)
    assert np.array_equal(upright @ turn @ [0, 1, 0], [0, 1, 0]) and np.linalg.det(upright) == pytest.approx(1)
    assert up_turn(turn_motion(turned, upright)) is None
    assert turned.skeleton.replace(unit_cm=0.0).unit_cm == walk.skeleton.unit_cm == 5.64


def test_takes_standing_on_y_are_left_as_they_are(walk, kick, studio_take):
    """Bandai's rest pose lies along X, in a world whose up is Y: the motion says so."""
    for take in (walk, kick, studio_take):
        assert up_turn(take) is None
    rotations = ("Zrotation", "Xrotation", "Yrotation")
    stick = Skeleton(
        ("Hips", "Head"),
        (-1, 0),
        [[0, 0, 0], [0, 0, 50.0]],
        (("Xposition", "Yposition", "Zposition") + rotations, rotations),
    )
    assert up_turn(Motion(stick, 30.0, np.zeros((2, 3)), np.zeros((2, 2, 3)))) is None  # no humanoid: BVH's Y


@pytest.mark.parametrize("spec", ["ebf", "cae"])
def test_a_take_standing_on_z_is_cleaned_exactly_as_the_same_take_standing_on_y(spec, walk):
    """The engine sees the very same view of both (the turn only relabels axes, exactly),
    so the results agree once turned, to the last bits (a new skeleton's arrays sit
    elsewhere in memory, which can change a sum's last bit); the CMU weights serve the
    Z-up export."""
    case = make_case(walk.slice(0, 200), "angular:0.5+gaps:0.01", 0)
    turn = TURNS[0]
    turned = Observation(turn_motion(case.observation.motion, turn), case.observation.observed)
    engine = registry.create(spec)
    upright, standing_on_z = engine.clean(case.observation), engine.clean(turned)
    assert standing_on_z.motion.skeleton is turned.skeleton
    assert engine.weights_used_.startswith("skeleton-specific")
    back = turn_motion(standing_on_z.motion, turn.T, walk.skeleton)
    np.testing.assert_allclose(back.channels, upright.motion.channels, atol=1e-9)
    for name, value in upright.diagnostics.items():  # in the take's own axes
        other = standing_on_z.diagnostics[name]
        if name == "raw_positions":  # cae's network's positions, before IK
            np.testing.assert_allclose(other, turn_vectors(value, turn), atol=1e-9)
        elif value.ndim == 1:  # one value a frame (cae's network_share)
            np.testing.assert_array_equal(other, value)
        else:  # ebf's filter widths per channel: the root's position columns follow their axes
            np.testing.assert_allclose(other[:, 3:], value[:, 3:], atol=1e-9)
            np.testing.assert_allclose(other[:, :3], turn_vectors(value[:, :3], np.abs(turn)), atol=1e-9)


def test_the_app_shows_a_take_standing_on_z_upright(walk):
    turned = turn_motion(walk, TURNS[0])
    assert np.allclose(skeleton_points(turned), skeleton_points(walk), atol=1e-9)


def test_a_z_up_file_reads_back_as_written_and_the_skeleton_command_says_where_up_is(walk, tmp_path, capsys):
    from workbench.cli import main
    from workbench.io import read_bvh, write_bvh

    path = tmp_path / "z_up.bvh"
    write_bvh(path, turn_motion(walk, TURNS[0]))
    read = read_bvh(path)
    assert read.skeleton.unit_cm == 5.64 and read.allclose(turn_motion(walk, TURNS[0]), atol=1e-6)
    assert main(["skeleton", str(path)]) == 0
    assert "unit: 5.64 cm; up: +Z (turned onto +Y" in capsys.readouterr().out


def test_a_mapping_that_does_not_fit_the_take_is_said_not_dropped_with_its_turn(walk):
    from workbench.core.humanoid import HumanoidError

    assert (
        up_turn(
            Motion(
                Skeleton(("root",), (-1,), np.zeros((1, 3)), (("Xrotation", "Yrotation", "Zrotation"),)),
                walk.fps,
                np.zeros((3, 3)),
                np.zeros((3, 1, 3)),
            )
        )
        is None
    )  # no humanoid: as it stands
    with pytest.raises(HumanoidError, match="Nope"):
        up_turn(walk, {"neck": "Nope"})
