import glob

import numpy as np
import pytest
from bvh import Bvh  # an independent reader from PyPI
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from workbench.io import MotionFileError, read_bvh, write_bvh
from workbench.io.bvh import format_bvh


def all_bvh(data_root):
    return sorted(glob.glob(str(data_root / "*" / "*" / "*.bvh")))


def test_reads_every_shared_clip(data_root):
    files = all_bvh(data_root)
    assert len(files) >= 50
    layouts = set()
    for f in files:
        m = read_bvh(f)
        assert m.fps == 120.0 and np.isfinite(m.channels).all()
        layouts.add((m.skeleton.n_joints, m.skeleton.rotation_orders[1]))
    assert layouts == {(31, "ZYX"), (43, "ZXY")}


def test_units(walk, kick):
    assert walk.skeleton.unit_cm == pytest.approx(5.64)
    assert kick.skeleton.unit_cm == 1.0


@pytest.mark.parametrize("fixture", ["walk", "kick"])
def test_round_trip(fixture, request, tmp_path):
    m = request.getfixturevalue(fixture)
    path = tmp_path / "out.bvh"
    write_bvh(path, m)
    back = read_bvh(path)
    assert back.allclose(m, atol=1e-4)
    assert back.skeleton.channels == m.skeleton.channels
    assert [p for p, _ in back.skeleton.end_sites] == [p for p, _ in m.skeleton.end_sites]
    assert np.allclose([o for _, o in back.skeleton.end_sites], [o for _, o in m.skeleton.end_sites], atol=1e-6)
    assert np.allclose(back.positions, m.positions, atol=1e-4)


@pytest.mark.parametrize("fixture", ["walk", "kick"])
def test_written_files_load_in_an_independent_reader(fixture, request, tmp_path):
    m = request.getfixturevalue(fixture)
    path = tmp_path / "out.bvh"
    write_bvh(path, m)
    other = Bvh(path.read_text())
    assert other.nframes == m.n_frames
    assert other.frame_time == pytest.approx(1 / 120, rel=1e-5)
    names = other.get_joints_names()
    assert names == list(m.skeleton.names)
    for j in (0, 5, len(names) - 1):
        chans = other.joint_channels(names[j])
        assert tuple(chans) == m.skeleton.channels[j]
        assert np.allclose(other.joint_offset(names[j]), m.skeleton.offsets[j], atol=1e-6)
    f = m.n_frames // 2
    rot_names = [c for c in m.skeleton.channels[3] if c.endswith("rotation")]
    vals = other.frame_joint_channels(f, names[3], rot_names)
    assert np.allclose(vals, m.angles_deg[f, 3], atol=1e-5)


def test_mixed_line_endings(data_root, tmp_path):
    text = (data_root / "cmu" / "walk" / "02_01.bvh").read_bytes().decode()
    lines = text.splitlines()
    mixed = "".join(line + ("\r\n" if i % 3 else "\n") for i, line in enumerate(lines))
    p = tmp_path / "mixed.bvh"
    p.write_bytes(mixed.encode())
    assert read_bvh(p).allclose(read_bvh(data_root / "cmu" / "walk" / "02_01.bvh"), atol=0)


def _small(walk):
    return format_bvh(walk.slice(0, 5))


def _expect(tmp_path, text, match, line=None):
    p = tmp_path / "bad.bvh"
    p.write_text(text)
    with pytest.raises(MotionFileError, match=match) as info:
        read_bvh(p)
    assert str(p) in str(info.value)
    if line is not None:
        assert info.value.line == line, str(info.value)
    return info.value


def test_truncated_motion_section(walk, tmp_path):
    text = _small(walk)
    err = _expect(tmp_path, "\n".join(text.splitlines()[:-2]) + "\n", "truncated")
    assert err.line is not None


def test_wrong_number_of_values(walk, tmp_path):
    lines = _small(walk).splitlines()
    lines[-2] = lines[-2] + " 1.0"
    _expect(tmp_path, "\n".join(lines), "frame 3 has 97 values, the hierarchy has 96", line=len(lines) - 1)


def test_not_a_number(walk, tmp_path):
    lines = _small(walk).splitlines()
    lines[-1] = lines[-1].replace(lines[-1].split()[7], "abc", 1)
    _expect(tmp_path, "\n".join(lines), "'abc' is not a number", line=len(lines))


def test_unknown_channel(walk, tmp_path):
    text = _small(walk).replace("Zrotation Yrotation Xrotation", "Zrotation Yrotation Wrotation", 1)
    _expect(tmp_path, text, "unknown channel name 'Wrotation'")


def test_zero_frames(walk, tmp_path):
    text = _small(walk)
    head = text[: text.index("MOTION")]
    _expect(tmp_path, head + "MOTION\nFrames: 0\nFrame Time: 0.0083333\n", "0 frames")


def test_no_motion_section(walk, tmp_path):
    text = _small(walk)
    _expect(tmp_path, text[: text.index("MOTION")], "no MOTION section")


def test_not_bvh_and_unreadable(tmp_path):
    _expect(tmp_path, "hello world\n", "not a BVH file", line=1)
    with pytest.raises(MotionFileError, match="cannot read"):
        read_bvh(tmp_path / "missing.bvh")


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_parser_never_crashes_on_mangled_files(walk, tmp_path, data):
    """Property: any mangling of a valid file either reads or raises MotionFileError."""
    text = _small(walk)
    start = data.draw(st.integers(0, len(text) - 1))
    stop = data.draw(st.integers(start, min(len(text), start + 40)))
    junk = data.draw(st.text(alphabet="0123456789 .-\n{}abcXYZ", max_size=10))
    p = tmp_path / "mangled.bvh"
    p.write_text(text[:start] + junk + text[stop:])
    try:
        read_bvh(p)
    except MotionFileError:
        pass


def test_write_is_atomic(walk, tmp_path):
    p = tmp_path / "keep.bvh"
    p.write_text("precious")
    X = walk.slice(0, 5).channels
    X[2, 10] = np.nan
    with pytest.raises(ValueError, match="missing"):
        write_bvh(p, walk.slice(0, 5).with_channels(X))
    assert p.read_text() == "precious"
    assert [f.name for f in tmp_path.iterdir()] == ["keep.bvh"]
