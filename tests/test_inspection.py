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


def test_a_reference_node_the_exporter_moves_in_a_line_is_no_linear_fill(clips):
    take = next(c for c in clips if c.id == "bandai/walk/dataset-1_walk_normal_002").load()
    assert take.skeleton.root_chain == (0, 1)  # joint_Root carries the Hips, in a straight line here
    assert np.ptp(take.root_positions, axis=0).max() > 10 / take.skeleton.unit_cm
    assert not inspect_motion(take).flags["linear"].any()


def test_a_flip_is_a_turn(embedded_walk):
    angles = embedded_walk.angles_deg.copy()
    j = embedded_walk.skeleton.index("LeftForeArm")
    angles[100:102, j, 0] += 170.0
    intervals = inspect_motion(embedded_walk.replace(angles_deg=angles)).intervals()
    turns = [i for i in intervals if i.reason == "turn"]
    assert [(i.first, i.last, i.joints) for i in turns] == [(99, 102, ("LeftForeArm",))]
    assert "frames 99-102: turn" in str(turns[0])


def test_a_body_that_leaves_its_path_is_a_jump(embedded_walk, studio_take):
    """Three frames of the walk put 1 m off (a marker swap on the pelvis, stray frames of
    an exporter): the steps out and back are faster than a body moves; the clean walk
    and the studio take (its Hips carried under a reference node) have none."""
    root = embedded_walk.root_positions.copy()
    root[100:103, 0] += 100.0 / embedded_walk.skeleton.unit_cm
    intervals = inspect_motion(embedded_walk.replace(root_positions=root)).intervals()
    jumps = [i for i in intervals if i.reason == "jump"]
    assert [(i.first, i.last, i.joints) for i in jumps] == [(100, 102, ("Hips",))]  # the frames off the path
    assert jumps[0].score == pytest.approx(120.0, rel=0.01)  # m/s: 1 m (and a step) in a 120th of a second
    assert not inspect_motion(embedded_walk).flags["jump"].any() and not inspect_motion(studio_take).flags["jump"].any()


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
    assert "frames 77-77: spike" in out and "--fill-suspects` cleans what spike, turn, jump, linear flag" in err
    assert main(["inspect", take, "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["frames"] == 421 and report["reference_frames_dropped"] == 1
    assert all({"reason", "first", "last", "joints", "score"} <= set(i) for i in report["intervals"])
    assert main(["inspect", str(embedded_root / "missing.bvh")]) == 2


def test_inspect_checks_a_mapping_file_against_the_take_as_clean_does(embedded_root, tmp_path, capsys):
    take = str(embedded_root / "cmu" / "walk" / "35_31.bvh")
    mapping = tmp_path / "map.json"
    mapping.write_bytes(b"\xef\xbb\xbf" + json.dumps({"neck": "NoSuchJoint"}).encode())  # with a BOM: read past
    assert main(["inspect", take, "--mapping", str(mapping)]) == 2
    assert "mapping: neck = 'NoSuchJoint', but the take has no joint 'NoSuchJoint'" in capsys.readouterr().err


def test_the_samples_a_robust_engine_rejects_are_the_spikes(embedded_walk):
    observation = parse_corruption("outliers:0.01").apply(embedded_walk, seed=1)
    truth = _pose_error_deg(embedded_walk, observation.motion) > 10.0
    weight = registry.create("mssa").clean(observation).diagnostics["robust_weight"]
    flags = inspect_motion(observation.motion, robust_weights=[weight]).flags["rejected"]
    assert (flags & truth).sum() / truth.sum() >= 0.95 and (flags & truth).sum() / flags.sum() >= 0.8
    # the weights of the joints' positions (mssa in positions) map to the joints too
    positions = registry.create("mssa:space=positions").clean(observation).diagnostics["robust_weight"]
    assert positions.shape[1] == 3 * embedded_walk.skeleton.n_joints
    assert inspect_motion(observation.motion, robust_weights=[positions]).flags["rejected"].any()
    with pytest.raises(ValueError, match="fit neither"):
        inspect_motion(observation.motion, robust_weights=[weight[:, :5]])


def test_a_reference_node_take_s_position_weights_reach_its_own_joints(clips):
    take = next(c for c in clips if c.id == "bandai/walk/dataset-1_walk_active_001").load()  # under joint_Root
    observation = parse_corruption("outliers:0.01").apply(take, seed=1)
    weight = registry.create("mssa:space=positions").clean(observation).diagnostics["robust_weight"]
    assert weight.shape[1] == 3 * take.skeleton.n_joints and not weight[:, :3].any()  # joint_Root: not filtered
    assert inspect_motion(observation.motion, robust_weights=[weight]).flags["rejected"].any()


def test_engines_that_disagree_and_missing_samples_are_intervals(embedded_walk):
    sk = embedded_walk.skeleton
    points = embedded_walk.positions * sk.unit_cm
    moved = points.copy()
    hand = sk.index("LeftHand")
    moved[200:211, hand] += [0.0, 8.0, 0.0]  # one engine puts the hand 8 cm higher for 11 frames
    observed = np.ones((embedded_walk.n_frames, sk.n_joints), bool)
    observed[50:60, sk.index("RightFoot")] = False
    found = inspect_motion(embedded_walk, observed, cleaned_points_cm=[points, moved])
    disagree = [(i.first, i.last, i.joints) for i in found.intervals() if i.reason == "disagree"]
    assert disagree == [(200, 210, ("LeftHand",))]
    assert [(i.first, i.last, i.joints) for i in found.intervals() if i.reason == "missing"] == [
        (50, 59, ("RightFoot",))
    ]
    assert "disagree" not in inspect_motion(embedded_walk, cleaned_points_cm=[points]).flags  # needs two


def test_inspect_reads_the_mask_sidecar_and_runs_engines(embedded_walk, tmp_path, capsys):
    take = tmp_path / "take.bvh"
    assert main(["corrupt", str(_write(embedded_walk, tmp_path)), "-o", str(take), "--corrupt", "outliers:0.01"]) == 0
    capsys.readouterr()
    assert main(["inspect", str(take), "--engine", "mssa", "--engine", "kalman", "--json"]) == 0
    reasons = {i["reason"] for i in json.loads(capsys.readouterr().out)["intervals"]}
    assert {"spike", "rejected", "disagree"} <= reasons
    assert main(["inspect", str(take), "--mask", str(tmp_path / "nope.json")]) == 2
    assert main(["inspect"]) == 2 and "needs a TAKE" in capsys.readouterr().err
    assert main(["inspect", str(take), "--measure"]) == 2 and f"leave out {take}" in capsys.readouterr().err
    assert main(["inspect", "--measure", "--json", "--unit", "cm"]) == 2
    assert "leave out --unit, --json" in capsys.readouterr().err
    assert main(["inspect", str(take)]) == 0
    assert f"the missing samples are those {take}.mask.json lists" in capsys.readouterr().err
    assert main(["inspect", str(_write(embedded_walk, tmp_path))]) == 0  # no mask: no note of one
    assert "missing samples are those" not in capsys.readouterr().err


def _write(motion, folder):
    path = folder / "clean.bvh"
    write_bvh(path, motion)
    return path


def test_inspect_measures_its_flags_on_corrupted_clips(embedded_root, capsys):
    argv = ["inspect", "--measure", "--data", str(embedded_root), "--clips", "cmu/walk/*", "--engine", "mssa"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    rows = {tuple(c.strip() for c in line.split("|")[1:3]): line for line in out.splitlines() if line.startswith("| ")}
    assert {("spikes", "spike"), ("spikes", "rejected"), ("linear fills", "linear"), ("glitches", "any")} <= set(rows)
    recall, precision = (float(v) for v in rows[("spikes", "spike")].split("|")[3:5])
    assert recall >= 0.9 and precision >= 0.8
    recall, precision = (float(v) for v in rows[("jumps", "jump")].split("|")[3:5])
    assert recall >= 0.9 and precision >= 0.9


def test_inspect_reads_a_mask_of_the_file_s_frames_t_pose_included(embedded_root, tmp_path, capsys):
    from workbench.io.mask import sidecar_path, write_mask

    take = tmp_path / "walk.bvh"
    take.write_bytes((embedded_root / "cmu" / "walk" / "35_31.bvh").read_bytes())  # frame 0 is a T-pose
    recorded = read_bvh(take)
    observed = np.ones((recorded.n_frames, recorded.skeleton.n_joints), bool)
    observed[51:61, recorded.skeleton.index("RightFoot")] = False  # file frames 51-60
    write_mask(sidecar_path(take), observed, recorded.skeleton)
    assert main(["inspect", str(take), "--json"]) == 0
    missing = [i for i in json.loads(capsys.readouterr().out)["intervals"] if i["reason"] == "missing"]
    assert [(i["first"], i["last"], i["joints"]) for i in missing] == [(50, 59, ["RightFoot"])]  # counted after it


def test_clean_and_bench_can_fill_what_inspect_flags_instead_of_trusting_it(embedded_walk, tmp_path, capsys):
    """A take with outliers and three frames 1 m off its path: with --fill-suspects the
    engine fills the flagged samples, and kalman's output follows the truth."""
    from workbench import metrics
    from workbench.evaluate import run_benchmark

    root = embedded_walk.root_positions.copy()
    root[100:103, 0] += 100.0 / embedded_walk.skeleton.unit_cm
    broken = parse_corruption("outliers:0.01").apply(embedded_walk.replace(root_positions=root), seed=3).motion
    write_bvh(tmp_path / "broken.bvh", broken)
    errors = {}
    for flag in ([], ["--fill-suspects"]):
        out = tmp_path / f"out{len(flag)}.bvh"
        assert main(["clean", str(tmp_path / "broken.bvh"), "-o", str(out), "--engine", "kalman", *flag]) == 0
        errors[bool(flag)] = (
            metrics.mpjpe_cm(embedded_walk, read_bvh(out)),
            metrics.root_cm(embedded_walk, read_bvh(out)),
        )
    assert "flagged as bad data (spike, turn, jump, linear) cleaned as gaps" in capsys.readouterr().err
    assert errors[True][0] < 0.2 < 1.0 < errors[False][0] and errors[True][1] < 0.05 < 0.5 < errors[False][1]
    plain, filled = (
        run_benchmark(["kalman"], "outliers:0.01", [("walk", embedded_walk)], fill_suspects=fill)
        for fill in (False, True)
    )
    assert filled.to_json()["fill_suspects"] and not plain.to_json()["fill_suspects"]
    assert filled.summary["kalman"]["rms_angle_deg"] < 0.5 * plain.summary["kalman"]["rms_angle_deg"]


def test_suspects_are_found_on_joints_with_gaps_too(embedded_walk):
    """The rules read the observation bridged: a joint with a gap still has its spikes
    found (a NaN once made its median score NaN, and no spike of it was flagged)."""
    from workbench.data.inspection import suspects_missing

    obs = parse_corruption("outliers:0.01+gaps:0.01").apply(embedded_walk, seed=5)
    truth = (_pose_error_deg(embedded_walk, obs.bridged()) > 10.0) & obs.observed
    filled = suspects_missing(obs)
    found = obs.observed & ~filled.observed
    assert truth.sum() > 100 and (found & truth).sum() >= 0.9 * truth.sum()
    assert np.array_equal(np.isnan(filled.motion.channels), ~filled.channel_observed)
