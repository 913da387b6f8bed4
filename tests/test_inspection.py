"""``workbench inspect``: the broken frames of a take, found without ground truth."""

import json

import numpy as np
import pytest

from workbench import registry
from workbench.cli import main
from workbench.corruption import parse_corruption
from workbench.data import find_clip
from workbench.data.inspection import inspect_motion
from workbench.io import read_bvh, write_bvh


@pytest.fixture(scope="module")
def embedded_walk(embedded_root):
    return find_clip("cmu/walk/35_31", embedded_root).load()


def _pose_error_deg(a, b):
    from workbench.core.kinematics import local_rotations
    from workbench.core.rotations import rotation_angle_deg

    joints = np.arange(a.skeleton.n_joints)
    ra = local_rotations(a.skeleton, a.angles_deg, joints)
    rb = local_rotations(b.skeleton, b.angles_deg, joints)
    return rotation_angle_deg(ra, rb)


def test_spikes_are_found_with_high_recall_and_precision(embedded_walk):
    noisy = parse_corruption("outliers:0.01").apply(embedded_walk, seed=1).motion
    truth = _pose_error_deg(embedded_walk, noisy) > 10.0  # every outlier is at least 30 degrees
    flags = inspect_motion(noisy).flags["spike"]
    recall = (flags & truth).sum() / truth.sum()
    precision = (flags & truth).sum() / flags.sum()
    assert truth.sum() > 200 and recall >= 0.95 and precision >= 0.9
    # the clean walk: hardly anything
    assert inspect_motion(embedded_walk).flags["spike"].sum() < 5


def test_gaps_filled_linearly_in_the_file_are_found(embedded_walk, tmp_path):
    obs = parse_corruption("gaps:0.01").apply(embedded_walk, seed=2)
    filled = registry.create("lerp").clean(obs).motion
    write_bvh(tmp_path / "filled.bvh", filled, digits=6)  # as an exporter prints it
    found = inspect_motion(read_bvh(tmp_path / "filled.bvh"))
    moved = np.abs(filled.angles_deg - embedded_walk.angles_deg).max(-1) > 0.1  # fills that differ from the truth
    truth = ~obs.observed & moved
    flags = found.flags["linear"]
    # the misses: one-frame fills, and holds at the take's ends
    assert (flags & truth).sum() / truth.sum() >= 0.8 and (flags & ~obs.observed).sum() / flags.sum() >= 0.95
    assert not inspect_motion(embedded_walk).flags["linear"].any()


def test_a_flip_is_a_turn(embedded_walk):
    angles = embedded_walk.angles_deg.copy()
    j = embedded_walk.skeleton.index("LeftForeArm")
    angles[100:102, j, 0] += 170.0
    intervals = inspect_motion(embedded_walk.replace(angles_deg=angles)).intervals()
    turns = [i for i in intervals if i.reason == "turn"]
    assert [(i.first, i.last, i.joints) for i in turns] == [(99, 102, ("LeftForeArm",))]
    assert "frames 99-102: turn" in str(turns[0])


def test_bone_lengths_that_vary_are_flagged(stretchy_take, studio_take):
    found = inspect_motion(stretchy_take)
    bones = [i for i in found.intervals() if i.reason == "bone"]
    assert bones and all(i.joints == ("LowerArm_L",) for i in bones)
    assert not inspect_motion(studio_take).flags["bone"].any()


def test_inspect_prints_the_intervals_and_writes_json(embedded_root, capsys):
    take = str(embedded_root / "cmu" / "walk" / "35_31.bvh")
    assert main(["inspect", take]) == 0
    out, err = capsys.readouterr()
    assert "421 frames at 120 fps" in out and "dropped frame 0" in err
    assert main(["inspect", take, "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["frames"] == 421 and report["reference_frames_dropped"] == 1
    assert all({"reason", "first", "last", "joints", "score"} <= set(i) for i in report["intervals"])
    assert main(["inspect", str(embedded_root / "missing.bvh")]) == 2
