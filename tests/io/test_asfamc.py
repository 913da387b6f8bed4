"""CMU ASF/AMC reader: the real kick clip, the pose against an independent textbook
evaluation of the ASF/AMC model, a BVH round trip, and bad input."""

from __future__ import annotations

import shutil
import time
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from workbench.io import read_bvh, read_motion, write_bvh
from workbench.io.asfamc import CMU_ASF_TO_BVH, find_asf, read_amc, read_asf
from workbench.io.errors import MotionFileError

DATA = Path("/work/shared/data/cmu")
KICK = DATA / "asfamc" / "kick"
ASF, AMC = KICK / "11.asf", KICK / "11_01.amc"
BVH_SAME_TREE = DATA / "jog" / "16_53.bvh"

needs_data = pytest.mark.skipif(not AMC.exists(), reason="CMU kick clip not available")


@pytest.fixture(scope="module")
def kick():
    return read_amc(AMC)


# -- an independent, textbook evaluation of the ASF/AMC model (scipy rotations) ---------
def _ref_parse_asf(path: Path):
    bones, children, root = {}, {}, {}
    section, bone = None, None
    for line in path.read_text().splitlines():
        w = line.split()
        if not w or w[0].startswith("#"):
            continue
        if w[0].startswith(":"):
            section = w[0]
            continue
        if section == ":root":
            root[w[0]] = w[1:]
        elif section == ":bonedata":
            if w[0] == "begin":
                bone = {"dof": []}
            elif w[0] == "end":
                bones[bone["name"]] = bone
            elif w[0] == "name":
                bone["name"] = w[1]
            elif w[0] == "direction":
                bone["dir"] = np.array(w[1:4], float)
            elif w[0] == "length":
                bone["len"] = float(w[1])
            elif w[0] == "axis":
                bone["axis"] = (np.array(w[1:4], float), w[4])
            elif w[0] == "dof":
                bone["dof"] = w[1:]
        elif section == ":hierarchy" and w[0] not in ("begin", "end"):
            children[w[0]] = w[1:]
    return bones, children, root


def _ref_parse_amc(path: Path):
    frames = []
    for line in path.read_text().splitlines():
        w = line.split()
        if not w or w[0].startswith(("#", ":")):
            continue
        if len(w) == 1 and w[0].isdigit():
            frames.append({})
        else:
            frames[-1][w[0]] = np.array(w[1:], float)
    return frames


def _axis_frame(angles_deg, order):
    # "XYZ": rotate about X first, then Y, then Z, about fixed axes (scipy: lower case).
    return Rotation.from_euler(order.lower(), angles_deg, degrees=True).as_matrix()


def _ref_pose(bones, children, root, frame):
    """Joint (bone start) and leaf end positions, per the CMU viewer's formula: a bone's
    frame is G_b = G_parent C_parent^-1 C_b M_b, its end is start + G_b C_b^-1 d_b l_b."""
    order = [t.lower() for t in root["order"]]
    values = dict(zip(order, frame["root"]))
    C_root = _axis_frame(np.array(root["orientation"], float), root["axis"][0])
    rot_dofs = [d for d in order if d.startswith("r")]
    M_root = Rotation.from_euler(
        "".join(d[1] for d in rot_dofs), [values[d] for d in rot_dofs], degrees=True
    ).as_matrix()
    root_pos = np.array([values["tx"], values["ty"], values["tz"]])
    starts, ends = {"root": root_pos}, {}

    def visit(name, parent_G, parent_C, start):
        bone = bones[name]
        C = _axis_frame(*bone["axis"])
        if bone["dof"]:
            M = Rotation.from_euler("".join(d[1] for d in bone["dof"]), frame[name], degrees=True).as_matrix()
        else:
            M = np.eye(3)
        G = parent_G @ parent_C.T @ C @ M
        end = start + G @ C.T @ (bone["dir"] * bone["len"])
        starts[name] = start
        ends[name] = end
        for child in children.get(name, []):
            visit(child, G, C, end)

    for child in children["root"]:
        visit(child, C_root @ M_root, C_root, root_pos)
    return starts, ends


# -- the real clip ------------------------------------------------------------------
@needs_data
def test_reads_the_kick_clip(kick):
    sk = kick.skeleton
    assert kick.n_frames == 597 and sk.n_joints == 31 and kick.fps == 120.0
    assert kick.name == "11_01"
    assert sk.names[0] == "root" and sk.names[1:3] == ("lhipjoint", "lfemur")
    assert len(sk.end_sites) == 7
    assert np.isfinite(kick.root_positions).all() and np.isfinite(kick.angles_deg).all()
    assert np.isfinite(kick.positions).all()
    # Bones without dofs (the hip joints) get zero angles; the root's ZYX angles are the
    # AMC's RZ RY RX (root axis is the identity).
    assert np.all(kick.angles_deg[:, sk.index("lhipjoint")] == 0.0)
    np.testing.assert_allclose(kick.root_positions[0], [12.2047, 17.4653, -40.3148])
    np.testing.assert_allclose(kick.angles_deg[0, 0], [3.92364, -39.9965, -9.79949], atol=1e-9)
    # read_motion dispatches .amc paths here
    assert read_motion(AMC).allclose(kick)


@needs_data
def test_reads_fast():
    start = time.perf_counter()
    read_amc(AMC)
    assert time.perf_counter() - start < 1.0


@needs_data
def test_units_and_standing_height(kick):
    sk = kick.skeleton
    # CMU: lengths are inches * 0.45, so one unit = 2.54 / 0.45 cm (= the cgspeed BVH unit).
    assert sk.unit_cm == pytest.approx(2.54 / 0.45)
    assert read_asf(ASF).unit_cm == pytest.approx(2.54 / 0.45)
    assert 150.0 <= sk.rest_height() * sk.unit_cm <= 190.0


@needs_data
def test_plausible_positions(kick):
    sk = kick.skeleton
    pos, ends = kick.positions, kick.end_site_positions()
    cm = sk.unit_cm
    # The toe tips (first two End Sites) touch the floor (y = 0) but never sink far below.
    toe_tips = ends[:, :2, 1] * cm
    assert -3.0 < toe_tips.min() < 5.0
    for foot in ("lfoot", "rfoot"):
        ankle = pos[:, sk.index(foot), 1] * cm
        assert 3.0 < ankle.min() < 15.0  # ankle height while standing
    head = ends[:, 2, 1] * cm
    assert np.median(head) == pytest.approx(sk.rest_height() * cm, abs=20.0)
    # Rigid bones: every joint-to-parent distance equals its offset in every frame.
    for p, j in sk.bones:
        dist = np.linalg.norm(pos[:, j] - pos[:, p], axis=1)
        np.testing.assert_allclose(dist, np.linalg.norm(sk.offsets[j]), atol=1e-9)
    # Feet point the way the body faces (root +Z, the ASF's forward) nearly all the time.
    fwd = kick.global_rotations[:, 0] @ np.array([0.0, 0.0, 1.0])
    for foot, toes in (("lfoot", "ltoes"), ("rfoot", "rtoes")):
        v = pos[:, sk.index(toes)] - pos[:, sk.index(foot)]
        assert np.mean(np.sum(v[:, [0, 2]] * fwd[:, [0, 2]], axis=1) > 0) > 0.9
    # Channels are continuous in time (no 360 or Euler-flip jumps).
    assert np.abs(np.diff(kick.angles_deg, axis=0)).max() < 90.0


@needs_data
def test_pose_matches_textbook_evaluation(kick):
    bones, children, root = _ref_parse_asf(ASF)
    frames = _ref_parse_amc(AMC)
    assert len(frames) == kick.n_frames
    sk = kick.skeleton
    pos, ends = kick.positions, kick.end_site_positions()
    for k in (0, 1, 150, 300, 389, 450, 596):
        starts, bone_ends = _ref_pose(bones, children, root, frames[k])
        expected = np.array([starts[n] for n in sk.names])
        np.testing.assert_allclose(pos[k], expected, atol=1e-6, rtol=0)
        expected_ends = np.array([bone_ends[sk.names[j]] for j, _ in sk.end_sites])
        np.testing.assert_allclose(ends[k], expected_ends, atol=1e-6, rtol=0)


@needs_data
def test_knee_angle_is_the_tibia_dof(kick):
    # ltibia has the single dof rx about an axis perpendicular to the (straight) leg.
    frames = _ref_parse_amc(AMC)
    rx = np.array([f["ltibia"][0] for f in frames])
    sk, pos = kick.skeleton, kick.positions
    thigh = pos[:, sk.index("ltibia")] - pos[:, sk.index("lfemur")]
    shin = pos[:, sk.index("lfoot")] - pos[:, sk.index("ltibia")]
    cos = np.sum(thigh * shin, 1) / np.linalg.norm(thigh, axis=1) / np.linalg.norm(shin, axis=1)
    np.testing.assert_allclose(np.degrees(np.arccos(np.clip(cos, -1, 1))), np.abs(rx), atol=1e-4)


@needs_data
def test_bvh_round_trip(kick, tmp_path):
    out = tmp_path / "11_01.bvh"
    write_bvh(out, kick)
    back = read_bvh(out)
    assert back.n_frames == kick.n_frames and back.fps == kick.fps
    assert back.skeleton.names == kick.skeleton.names
    np.testing.assert_allclose(back.positions, kick.positions, atol=1e-4, rtol=0)
    np.testing.assert_allclose(back.end_site_positions(), kick.end_site_positions(), atol=1e-4, rtol=0)


@needs_data
def test_mapping_to_cgspeed_bvh_names(kick):
    assert set(CMU_ASF_TO_BVH) == set(kick.skeleton.names)
    bvh = read_bvh(BVH_SAME_TREE).skeleton
    assert tuple(CMU_ASF_TO_BVH[n] for n in kick.skeleton.names) == bvh.names
    assert kick.skeleton.parents == bvh.parents
    assert [p for p, _ in kick.skeleton.end_sites] == [p for p, _ in bvh.end_sites]
    assert kick.skeleton.channels[1:] == bvh.channels[1:]


@needs_data
def test_finds_the_asf(tmp_path):
    # By subject prefix among several .asf files; the only one otherwise; or explicitly.
    shutil.copy(AMC, tmp_path / "11_01.amc")
    shutil.copy(ASF, tmp_path / "11.asf")
    shutil.copy(ASF, tmp_path / "10.asf")
    assert find_asf(tmp_path / "11_01.amc") == tmp_path / "11.asf"
    other = tmp_path / "other"
    other.mkdir()
    shutil.copy(AMC, other / "11_01.amc")
    shutil.copy(ASF, other / "subject.asf")
    assert find_asf(other / "11_01.amc") == other / "subject.asf"
    assert read_amc(other / "11_01.amc", asf_path=tmp_path / "10.asf").n_frames == 597


# -- a tiny model with a known answer, and bad input ------------------------------------
TINY_ASF = """\
# tiny test skeleton
:version 1.10
:name TINY
:units
  mass 1.0
  length 0.45
  angle deg
:documentation
  two bones
:root
   order TX TY TZ RX RY RZ
   axis XYZ
   position 0 0 0
   orientation 0 0 0
:bonedata
  begin
     id 1
     name hip
     direction 0 -1 0
     length 2
     axis 0 0 0 XYZ
  end
  begin
     id 2
     name leg
     direction 1 0 0
     length 3
     axis 0 0 90 XYZ
    dof rx
    limits (-180.0 180.0)
  end
:hierarchy
  begin
    root hip
    hip leg
  end
"""

TINY_AMC = """\
:FULLY-SPECIFIED
:DEGREES
1
root 0 10 0 0 0 0
leg 90
2
root 1 10 0 0 90 0
leg -90
"""


def _write(folder: Path, asf: str = TINY_ASF, amc: str = TINY_AMC) -> tuple[Path, Path]:
    (folder / "7.asf").write_text(asf)
    (folder / "7_01.amc").write_text(amc)
    return folder / "7.asf", folder / "7_01.amc"


def _line(text: str, needle: str, nth: int = 1) -> int:
    hits = [n for n, line in enumerate(text.splitlines(), start=1) if line.strip() == needle]
    return hits[nth - 1]


def test_tiny_model_known_pose(tmp_path):
    _, amc = _write(tmp_path)
    m = read_amc(amc)
    assert m.skeleton.names == ("root", "hip", "leg") and m.fps == 120.0
    # Frame 1: leg frame C = Rz(90), so rx turns the leg about world +Y: +X -> -Z.
    np.testing.assert_allclose(m.positions[0], [[0, 10, 0], [0, 10, 0], [0, 8, 0]], atol=1e-12)
    np.testing.assert_allclose(m.end_site_positions()[0], [[0, 8, -3]], atol=1e-12)
    # Frame 2: root yaw +90 undone by leg rx -90.
    np.testing.assert_allclose(m.end_site_positions()[1], [[4, 8, 0]], atol=1e-12)
    np.testing.assert_allclose(m.angles_deg[0, 2], [0, 90, 0], atol=1e-9)


def _bad_asf(tmp_path, old, new):
    assert old in TINY_ASF
    return _write(tmp_path, asf=TINY_ASF.replace(old, new, 1))


def _bad_amc(tmp_path, old, new):
    assert old in TINY_AMC
    return _write(tmp_path, amc=TINY_AMC.replace(old, new, 1))


ASF_CASES = {
    # name: (old, new, (needle in the bad text, which occurrence), words in the message)
    "missing bonedata": (TINY_ASF[TINY_ASF.index(":bonedata") :], "", ("orientation 0 0 0", 1), "no :bonedata"),
    "no direction": ("     direction 1 0 0\n", "", ("begin", 2), "no 'direction'"),
    "non-number length": ("length 3", "length three", ("length three", 1), "'three' is not a number"),
    "control character": ("name hip", "name h\x01ip", ("name h\x01ip", 1), "holds the control character 0x01"),
    "short axis": ("axis 0 0 90 XYZ", "axis 0 0", ("axis 0 0", 1), "needs 3 numbers"),
    "unknown bone in hierarchy": ("hip leg", "hip arm", ("hip arm", 1), "'arm'"),
    "bone not attached": ("    hip leg\n", "", ("begin", 2), "'leg' is not attached"),
    "unterminated bone": ("  end\n:hierarchy", ":hierarchy", (":hierarchy", 1), "has no 'end'"),
    "translation dof": ("dof rx", "dof rx tx", ("dof rx tx", 1), "not supported"),
}


@pytest.mark.parametrize("case", sorted(ASF_CASES))
def test_bad_asf(tmp_path, case):
    old, new, (needle, nth), words = ASF_CASES[case]
    asf, amc = _bad_asf(tmp_path, old, new)
    line = _line(asf.read_text(), needle, nth)
    for read in (lambda: read_asf(asf), lambda: read_amc(amc)):
        with pytest.raises(MotionFileError) as info:
            read()
        err = info.value
        assert err.path == str(asf) and err.line == line
        assert str(err).startswith(f"{asf}:{line}: ") and words in str(err)


AMC_CASES = {
    "too many values": ("leg 90", "leg 90 0", ("leg 90 0", 1), "has 2 values"),
    "too few values": ("root 1 10 0 0 90 0", "root 1 10 0 0 90", ("root 1 10 0 0 90", 1), "has 5 values"),
    "non-number": ("leg -90", "leg abc", ("leg abc", 1), "'abc' is not a number"),
    "NaN": ("leg -90", "leg nan", ("leg nan", 1), "nan is no position or angle"),
    "absurd value": ("leg -90", "leg 1e308", ("leg 1e308", 1), "1e+308 is no position or angle"),
    "unknown bone": ("leg 90", "arm 90", ("arm 90", 1), "unknown bone 'arm'"),
    "zero frames": (TINY_AMC[TINY_AMC.index("1\n") :], "", (":DEGREES", 1), "no frames"),
    "truncated last frame": ("leg -90\n", "", ("root 1 10 0 0 90 0", 1), "has no values for leg"),
    "frame numbers skip": ("\n2\n", "\n5\n", ("5", 1), "does not follow"),
    "bone before any frame": ("1\nroot", "root", ("root 0 10 0 0 0 0", 1), "before the first frame"),
}


@pytest.mark.parametrize("case", sorted(AMC_CASES))
def test_bad_amc(tmp_path, case):
    old, new, (needle, nth), words = AMC_CASES[case]
    _, amc = _bad_amc(tmp_path, old, new)
    line = _line(amc.read_text(), needle, nth)
    with pytest.raises(MotionFileError) as info:
        read_amc(amc)
    err = info.value
    assert err.path == str(amc) and err.line == line
    assert str(err).startswith(f"{amc}:{line}: ") and words in str(err)


def test_an_asf_given_as_the_take_says_to_pass_the_amc(tmp_path):
    asf, _ = _write(tmp_path)
    with pytest.raises(MotionFileError, match="an ASF file is a skeleton, with no motion: pass the take's .amc"):
        read_motion(asf)


def test_unreadable_and_missing_files(tmp_path):
    missing = tmp_path / "nope_01.amc"
    with pytest.raises(MotionFileError, match="cannot read") as info:
        read_amc(missing)
    assert info.value.path == str(missing)
    _, amc = _write(tmp_path)
    with pytest.raises(MotionFileError, match="cannot read") as info:
        read_amc(amc, asf_path=tmp_path / "gone.asf")
    assert info.value.path == str(tmp_path / "gone.asf")
    lone = tmp_path / "lone"
    lone.mkdir()
    (lone / "7_01.amc").write_text(TINY_AMC)
    with pytest.raises(MotionFileError, match="no .asf") as info:
        read_amc(lone / "7_01.amc")
    assert info.value.path == str(lone / "7_01.amc")
