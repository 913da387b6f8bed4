import glob

import bvhio  # an independent reader with per-joint translations, from PyPI
import numpy as np
import pytest
from bvh import Bvh  # an independent reader from PyPI
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from workbench.io import MotionFileError, read_bvh, write_bvh
from workbench.io.bvh import _frames_line_by_line, format_bvh, significant
from workbench.io.limits import MAX_ABS_VALUE
from workbench.testing.takes import chain_bvh


def all_bvh(data_root):
    return sorted(glob.glob(str(data_root / "*" / "*" / "*.bvh")))


@pytest.fixture(scope="module")
def shared_takes(data_root):
    """(path, Motion) of every BVH take of the three shared sets, read once."""
    return [(f, read_bvh(f)) for f in all_bvh(data_root)]


@pytest.mark.slow
def test_reads_every_shared_clip(shared_takes):
    assert len(shared_takes) >= 600
    layouts = set()
    for f, m in shared_takes:
        assert np.isfinite(m.channels).all(), f
        sk = m.skeleton
        translated = tuple(sk.names[j] for j in sk.translated)
        layouts.add((m.fps, sk.n_joints, sk.rotation_orders[1], translated, sk.root_chain, sk.unit_cm))
    assert layouts == {  # the unit too: one Bandai take's rest pose is 37.6 units deep, 212 cm in CMU's units
        (120.0, 31, "ZYX", (), (0,), 5.64),
        (120.0, 43, "ZXY", (), (0,), 1.0),
        (30.0, 22, "ZXY", ("Hips",), (0, 1), 1.0),
    }


@pytest.mark.slow
def test_every_shared_take_writes_back_exactly(shared_takes, tmp_path):
    """Read, write, read: the same numbers, offsets, OFFSET lines and layout, bit for bit."""
    path = tmp_path / "again.bvh"
    for f, m in shared_takes:
        write_bvh(path, m)
        back = read_bvh(path)
        assert back.skeleton.signature() == m.skeleton.signature(), f
        assert np.array_equal(back.channels, m.channels), f
        assert np.array_equal(back.skeleton.offsets, m.skeleton.offsets), f
        assert np.array_equal(back.skeleton.file_offsets, m.skeleton.file_offsets), f
        assert back.fps == m.fps and back.skeleton.end_sites == m.skeleton.end_sites, f


def _excerpt(path, frames) -> str:
    """The file with only the given frames: its own header and frame lines, verbatim."""
    lines = open(path, encoding="utf-8").read().splitlines()
    start = next(i for i, line in enumerate(lines) if line.strip().upper() == "MOTION")
    body = [line for line in lines[start + 3 :] if line.strip()]
    return (
        "\n".join(lines[: start + 1] + [f"Frames: {len(frames)}", lines[start + 2]] + [body[i] for i in frames]) + "\n"
    )


def _bvhio_positions(text: str, tmp_path, n_frames: int) -> tuple[list[str], np.ndarray]:
    """Joint names and world joint positions (n_frames, J, 3) as bvhio computes them."""
    p = tmp_path / "excerpt.bvh"
    p.write_text(text)
    root = bvhio.readAsHierarchy(str(p))
    joints = [j for j, _, _ in root.layout()]
    out = []
    for k in range(n_frames):
        root.loadPose(k)
        out.append([list(j.PositionWorld) for j in joints])
    return [j.Name for j in joints], np.array(out)


@pytest.mark.slow
def test_forward_kinematics_matches_an_independent_reader(shared_takes, tmp_path):
    """FK of every shared take, on its first, middle and last frames, agrees with bvhio's
    (which, as Blender, lets a joint's position channels replace its OFFSET) to float32
    precision: bvhio computes in single precision."""
    for f, m in shared_takes:
        frames = sorted({0, m.n_frames // 2, m.n_frames - 1})
        names, theirs = _bvhio_positions(_excerpt(f, frames), tmp_path, len(frames))
        assert names == list(m.skeleton.names), f
        scale = m.skeleton.rest_height()
        np.testing.assert_allclose(theirs, m.positions[frames], atol=2e-5 * scale, rtol=0, err_msg=f)


ROOT_WITH_OFFSET = """HIERARCHY
ROOT base
{
  OFFSET 10 20 30
  CHANNELS 6 Yrotation Xposition Zrotation Yposition Xrotation Zposition
  JOINT hip
  {
    OFFSET 5 0 0
    CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
    JOINT knee
    {
      OFFSET 0.5 -40 0.000001
      CHANNELS 6 Zrotation Xposition Xrotation Yposition Yrotation Zposition
      End Site
      {
        OFFSET 0 -40 0
      }
    }
    JOINT spine
    {
      OFFSET 0 30 0
      CHANNELS 3 Xrotation Zrotation Yrotation
    }
  }
}
MOTION
Frames: 3
Frame Time: 0.0333333
90 1 0 2 3 4   7 100 -5 10 20 30   15 0.5 -20 -40 5 0   45 0 0
0 1 10 2 3 4   7 110 -5 10 20 30   -15 0.5 -20 -40 5 0   0 30 0
-90 1 20 2 3 4   7 120 -5 10 20 30   30 0.5 -10 -40 5 0   0 0 60
"""


def test_position_channels_replace_the_offset_on_any_joint(tmp_path):
    """As Blender and bvhio read it: the root's OFFSET is not added to its position
    channels; the hip's channels are its translation (the OFFSET 5 0 0 is ignored); the
    knee's (0.5, -40, 0 in a mixed channel order) repeat its OFFSET as printed and are
    folded into its offset; and the file writes back with its OFFSET lines and layout."""
    p = tmp_path / "any.bvh"
    p.write_text(ROOT_WITH_OFFSET)
    m = read_bvh(p)
    sk = m.skeleton
    assert sk.translated == (1,) and sk.root_chain == (0, 1)
    np.testing.assert_array_equal(m.root_positions, [[1, 2, 4]] * 3)
    np.testing.assert_array_equal(m.translations[:, 0], [[7, 100, -5], [7, 110, -5], [7, 120, -5]])
    np.testing.assert_array_equal(sk.offsets[[0, 2, 3]], [[0, 0, 0], [0.5, -40, 0], [0, 30, 0]])
    np.testing.assert_array_equal(sk.file_offsets[:3], [[10, 20, 30], [5, 0, 0], [0.5, -40, 1e-6]])
    np.testing.assert_array_equal(m.angles_deg[1, 0], [0, 10, 3])  # base: Y Z X order, as in the file
    np.testing.assert_array_equal(m.angles_deg[2, 2], [30, -10, 5])  # knee: Z X Y
    np.testing.assert_allclose(m.positions[0, 0], [1, 2, 4])  # no OFFSET added
    names, theirs = _bvhio_positions(ROOT_WITH_OFFSET, tmp_path, 3)
    assert names == list(sk.names)
    np.testing.assert_allclose(theirs, m.positions, atol=1e-4)
    out = tmp_path / "out.bvh"
    write_bvh(out, m)
    text = out.read_text()
    assert "OFFSET 10 20 30" in text and "OFFSET 5 0 0" in text and "OFFSET 0.5 -40 1e-06" in text
    assert "CHANNELS 6 Zrotation Xposition Xrotation Yposition Yrotation Zposition" in text
    back = read_bvh(out)
    assert np.array_equal(back.channels, m.channels) and back.skeleton.signature() == sk.signature()


def test_a_hips_that_stands_still_is_still_translated(studio_take, tmp_path):
    """The layout does not hang on the motion: a take whose Hips holds one place (a pose)
    still has it translated, as its channels are not its OFFSET line."""
    path = tmp_path / "pose.bvh"
    write_bvh(
        path,
        studio_take.replace(translations=np.broadcast_to(studio_take.translations[:1], studio_take.translations.shape)),
    )
    pose = read_bvh(path)
    assert pose.skeleton.signature() == studio_take.skeleton.signature() and pose.skeleton.root_chain == (0, 1)


def test_a_studio_take_loads_in_the_other_reader(studio_take, tmp_path):
    path = tmp_path / "studio.bvh"
    write_bvh(path, studio_take)
    other = Bvh(path.read_text())
    assert other.nframes == studio_take.n_frames and other.get_joints_names() == list(studio_take.skeleton.names)
    hips = studio_take.skeleton.translated[0]
    assert np.allclose(
        other.frame_joint_channels(5, "Hips", ["Xposition", "Yposition", "Zposition"]),
        studio_take.translations[5, 0],
        atol=1e-6,
    )
    assert np.allclose(other.joint_offset("Hips"), studio_take.skeleton.file_offsets[hips], atol=1e-6)


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
    lines = text.splitlines()
    n_frames = int(next(line for line in lines if line.startswith("Frames:")).split()[1])
    assert f"only {n_frames - 2} whole frame lines follow" in str(err)
    assert f"copy it again, else set 'Frames:' to {n_frames - 2}" in str(err) and "cut-off" not in str(err)
    cut = lines[:-2] + [lines[-2][: len(lines[-2]) // 2]]  # the last line cut off halfway
    err = _expect(tmp_path, "\n".join(cut) + "\n", "truncated")
    assert f"only {n_frames - 2} whole frame lines follow" in str(err)
    assert f"set 'Frames:' to {n_frames - 2} and delete the cut-off line after them" in str(err)


def test_lines_after_the_frames_that_are_no_frames_are_named(walk, tmp_path):
    text = _small(walk)
    n_lines = len(text.splitlines())
    err = _expect(tmp_path, text + "foo bar\n", "a line that is no frame of", line=n_lines + 1)
    assert "delete it" in str(err) and "set 'Frames:'" not in str(err)


def test_wrong_number_of_values(walk, tmp_path):
    lines = _small(walk).splitlines()
    lines[-2] = lines[-2] + " 1.0"
    _expect(tmp_path, "\n".join(lines), "frame 3 has 97 values, the hierarchy has 96", line=len(lines) - 1)


def test_not_a_number(walk, tmp_path):
    lines = _small(walk).splitlines()
    words = lines[-1].split()
    lines[-1] = " ".join(words[:7] + ["abc"] + words[8:])
    _expect(tmp_path, "\n".join(lines), "'abc' is not a number", line=len(lines))


@pytest.mark.parametrize("word", ["inf", "-1e308", "2e9"])
def test_a_value_beyond_any_position_or_angle_is_refused_with_its_frame(walk, tmp_path, word):
    """An infinite or absurd value (squared, 1e308 overflows every engine's arithmetic) is
    refused, naming its frame, channel and line, and how to mark it missing instead."""
    lines = _small(walk).splitlines()
    words = lines[-1].split()
    lines[-1] = " ".join(words[:7] + [word] + words[8:])
    err = _expect(tmp_path, "\n".join(lines), "channel 8, beyond the \\+-1e\\+09", line=len(lines))
    assert "write nan there to mark it missing" in str(err)


@pytest.mark.parametrize("word", ["nan", "inf", "-inf"])
def test_an_offset_that_is_not_a_finite_number(walk, tmp_path, word):
    lines = _small(walk).splitlines()
    at = next(i for i, line in enumerate(lines) if line.strip().startswith("OFFSET") and i > 3)
    lines[at] = lines[at].replace("OFFSET", f"OFFSET {word}", 1).rsplit(" ", 1)[0]
    _expect(tmp_path, "\n".join(lines), f"expected a number for OFFSET x, found '{word}'", line=at + 1)


def test_fewer_channel_names_than_the_count_says(walk, tmp_path):
    text = _small(walk).replace("CHANNELS 3 Zrotation Yrotation Xrotation", "CHANNELS 3 Zrotation Yrotation", 1)
    _expect(tmp_path, text, "CHANNELS says 3 but names 2, then")


@pytest.mark.parametrize("char", ["\x00", "\x01", "\x7f"])
def test_a_joint_name_with_a_control_character_is_refused(walk, tmp_path, char):
    text = _small(walk)
    name = walk.skeleton.names[1]
    _expect(tmp_path, text.replace(f"JOINT {name}", f"JOINT {name[:2]}{char}{name[2:]}", 1), "control character")


def test_a_unit_that_is_no_size_is_refused(walk, tmp_path):
    path = tmp_path / "walk.bvh"
    write_bvh(path, walk.slice(0, 5))
    for unit in (0, -1.0, float("nan"), float("inf"), "cm", True):
        with pytest.raises(ValueError, match="unit_cm is the length unit's size in cm, a number above 0"):
            read_bvh(path, unit_cm=unit)
    assert read_bvh(path, unit_cm=np.float32(2.54)).skeleton.unit_cm == pytest.approx(2.54)


def test_unknown_channel(walk, tmp_path):
    text = _small(walk).replace("Zrotation Yrotation Xrotation", "Zrotation Yrotation Wrotation", 1)
    _expect(tmp_path, text, "unknown channel name 'Wrotation'")


def test_a_frame_time_faster_than_any_capture_is_a_damaged_line(walk, tmp_path):
    text = _small(walk)
    old = next(line for line in text.splitlines() if line.startswith("Frame Time:"))
    _expect(tmp_path, text.replace(old, "Frame Time: 1e-300"), "1e\\+300 frames a second, faster than any capture")


def test_a_blank_line_among_the_frames_is_named_before_the_frame_count(walk, tmp_path):
    lines = _small(walk).splitlines()
    first = lines.index(next(line for line in lines if line.startswith("Frame Time:"))) + 2  # 1-based
    lines.insert(first + 1, "")  # after frame 1
    _expect(tmp_path, "\n".join(lines) + "\n", "a blank line among the frame lines: delete it", line=first + 2)


def test_what_other_exporters_write_reads_and_names_keep_their_bytes(walk, tmp_path):
    text = _small(walk)
    p = tmp_path / "bom.bvh"
    p.write_bytes(b"\xef\xbb\xbf" + text.encode())  # a byte order mark
    assert np.allclose(read_bvh(p).channels, read_bvh_text(tmp_path, text).channels)
    p.write_text(text.replace("Zrotation Yrotation Xrotation", "ZROTATION yrotation Xrotation"))
    assert read_bvh(p).skeleton.channels == read_bvh_text(tmp_path, text).skeleton.channels
    name = walk.skeleton.names[1]
    for other, encoding in (("\xe9", "latin-1"), ("\u2026", "cp1252"), ("\u3042\u30e5", "cp932")):  # é; …; あュ
        joint = f"JOINT {name}{other}".encode(encoding)  # not UTF-8: 0x85 and 0xA0 are no line end nor space
        p.write_bytes(text.encode().replace(f"JOINT {name}".encode(), joint))
        motion = read_bvh(p)
        assert motion.skeleton.text_encoding == "latin-1" and motion.skeleton.names[1].encode("latin-1") == joint[6:]
        write_bvh(tmp_path / "out.bvh", motion)
        assert joint + b"\n" in (tmp_path / "out.bvh").read_bytes()


def read_bvh_text(tmp_path, text):
    p = tmp_path / "plain.bvh"
    p.write_text(text)
    return read_bvh(p)


def test_zero_frames(walk, tmp_path):
    text = _small(walk)
    head = text[: text.index("MOTION")]
    _expect(tmp_path, head + "MOTION\nFrames: 0\nFrame Time: 0.0083333\n", "'Frames:' must be at least 1, found '0'")
    _expect(tmp_path, head + "MOTION\nFrames: -5\nFrame Time: 0.0083333\n", "'Frames:' must be at least 1, found '-5'")


def test_tabs_between_the_words_of_the_motion_header(walk, tmp_path):
    text = _small(walk)
    tabbed = text.replace("Frame Time:", "Frame\tTime:\t").replace("Frames:", "Frames:\t")
    assert np.array_equal(read_bvh_text(tmp_path, tabbed).channels, read_bvh_text(tmp_path, text).channels)


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


#: words a frame line may hold, well formed or not
_FRAME_WORDS = ["0", "-0", "12.5", "-3.25e-07", "1E5", "+.5", "5.", "nan", "NaN", "-nan", "inf", "Infinity", "1e308"]
_FRAME_WORDS += ["1e", "x", "0x10", "1_0", '"3"', "1,5", "--1", ".", "1e400", "9" * 30]


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_the_compiled_frame_reader_agrees_with_the_line_parser(tmp_path, data):
    """Property: whatever frame lines follow the hierarchy (the words of every exporter and
    broken ones, runs of spaces, tabs, a space before the end, CRLF, blank lines), the
    reader gives exactly the line parser's values, or both refuse them."""
    n_frames = data.draw(st.integers(1, 4))
    rows = data.draw(st.lists(st.lists(st.sampled_from(_FRAME_WORDS), min_size=2, max_size=4), min_size=1, max_size=5))
    gap = data.draw(st.sampled_from([" ", " ", "  ", "\t"]))
    end = data.draw(st.sampled_from(["\n", "\r\n", " \n", " \r\n", "\n\n"]))
    body = "".join(gap.join(row) + end for row in rows)
    p = tmp_path / "frames.bvh"
    p.write_text(
        f"HIERARCHY\nROOT a\n{{\nOFFSET 0 0 0\nCHANNELS 3 Xrotation Yrotation Zrotation\n}}\n"
        f"MOTION\nFrames: {n_frames}\nFrame Time: 0.1\n{body}",
        newline="",
    )
    try:
        expected = _frames_line_by_line(body.splitlines(), 10, n_frames, 3, str(p))
        expected = None if (np.abs(expected) > MAX_ABS_VALUE).any() else expected
    except MotionFileError:
        expected = None
    try:
        got = read_bvh(p).angles_deg[:, 0]
    except MotionFileError:
        got = None
    if expected is None or got is None:
        assert expected is None and got is None, (body, expected, got)
    else:
        assert np.array_equal(got, expected, equal_nan=True), body


@pytest.mark.parametrize(
    "take", ["bandai/walk/dataset-1_walk_active_001.bvh", "cmu/jog/16_35.bvh", "cmu/jog/02_03.bvh"]
)
def test_exporters_frame_lines_take_the_compiled_reader(data_root, take, monkeypatch):
    """The shared takes' frame lines (Bandai's end in a space, CMU's in CRLF or in LF) are
    read by the compiled reader, not the line parser."""
    import workbench.io.bvh as bvh

    def refused(*args):
        raise AssertionError("the line parser read these frames")

    monkeypatch.setattr(bvh, "_frames_line_by_line", refused)
    assert read_bvh(data_root / take).n_frames > 0


def test_significant_digits_are_printf_s():
    """significant(x, d) is the double nearest f"{x:.{d}g}" at every magnitude, so a file's
    numbers of up to DIGITS digits are written back as they were."""
    rng = np.random.default_rng(0)
    x = rng.normal(0, 1, 20000) * 10.0 ** rng.integers(-320, 300, 20000)
    x = np.concatenate([x, [0.0, -0.0, 5e-324, 1e-310, 12345678.125, 0.5, 99999.999995, 1.5]])
    for digits in (1, 6, 10, 17):
        expected = np.array([float(f"{v:.{digits}g}") for v in x])
        got = significant(x.reshape(-1, 8), digits).ravel()
        assert np.array_equal(np.signbit(got), np.signbit(expected)) and np.array_equal(got, expected), digits
        in_place = np.asfortranarray(x.reshape(-1, 8))
        assert significant(in_place, digits, out=in_place) is in_place
        assert np.array_equal(in_place.ravel(), expected) and np.array_equal(
            np.signbit(in_place.ravel()), np.signbit(expected)
        )
    decimals = np.array([float(f"{v:.10g}") for v in x])
    assert np.array_equal(significant(decimals, 10), decimals)
    assert significant(np.asfortranarray(x.reshape(-1, 8)), 10).flags.f_contiguous
    with pytest.raises(ValueError, match="strides"):
        significant(x.reshape(-1, 8), 10, out=np.empty((x.size // 8, 8), order="F"))


def test_write_is_atomic(walk, tmp_path):
    p = tmp_path / "keep.bvh"
    p.write_text("precious")
    X = walk.slice(0, 5).channels
    X[2, 10] = np.nan
    with pytest.raises(ValueError, match="missing"):
        write_bvh(p, walk.slice(0, 5).with_channels(X))
    assert p.read_text() == "precious"
    assert [f.name for f in tmp_path.iterdir()] == ["keep.bvh"]


def test_a_hierarchy_nested_ten_thousand_deep_reads_and_writes_back(tmp_path):
    """The parser and the writer walk the tree with a stack, not recursion: a chain of
    10,000 joints (Python's recursion limit is 1,000) reads, and writes back the same."""
    n = 10_000
    path = tmp_path / "deep.bvh"
    path.write_text(chain_bvh(n, frame_time="0.0083333"))
    motion = read_bvh(path)
    assert motion.skeleton.n_joints == n and motion.skeleton.parents[-1] == n - 2
    write_bvh(tmp_path / "again.bvh", motion)
    again = read_bvh(tmp_path / "again.bvh")
    assert again.skeleton.signature() == motion.skeleton.signature() and again.allclose(motion)


SIX_DECIMALS_IN_METRES = """HIERARCHY
ROOT pelvis
{
  OFFSET 0.000000 0.000000 0.000000
  CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
  JOINT spine
  {
    OFFSET 0.000000 0.400000 0.000000
    CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
    JOINT jaw
    {
      OFFSET 0.000000 0.016750 0.000000
      CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
      End Site
      {
        OFFSET 0.000000 0.010000 0.000000
      }
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.041667
0.1 0.9 0.0 0 0 0 0.000000 0.400000 0.000000 0 0 0 0.000000 0.016750 0.000000 0 0 0
0.1 0.9 0.0 0 0 0 0.000000 0.400000 0.000000 0 0 0 0.000001 0.016751 0.000000 0 0 0
"""


def test_translations_that_differ_in_the_last_printed_decimal_are_folded(tmp_path):
    """An SMPL-X export in metres, 6 decimals: float32 rounding flips a 1.7-cm bone's last
    digit between frames (6e-5 of its length, but 3e-6 of the skeleton's longest OFFSET);
    it is one translation as printed, so no trained engine refuses the take."""
    path = tmp_path / "smplx.bvh"
    path.write_text(SIX_DECIMALS_IN_METRES)
    m = read_bvh(path)
    assert m.skeleton.translated == ()
    np.testing.assert_array_equal(m.skeleton.offsets[2], [0.0, 0.01675, 0.0])


def test_more_frame_lines_than_frames_says_which_line_to_fix(tmp_path):
    """An export whose 'Frames:' line counts one frame fewer than it wrote (assimp's
    Boxing_Toes.bvh): refused, naming both ways to mend it."""
    path = tmp_path / "extra.bvh"
    path.write_text(ROOT_WITH_OFFSET + ROOT_WITH_OFFSET.splitlines()[-1] + "\n")
    with pytest.raises(MotionFileError, match=r"says 3 but 4 frame lines follow; .* set 'Frames:' to 4, else delete"):
        read_bvh(path)


@pytest.mark.parametrize(
    "frame_time, fps",
    [("0.0083333", 120), ("0.008333", 120), ("0.0333", 30), ("0.0166833", 60 / 1.001), ("0.0417083", 24 / 1.001),
     ("0.0417", 24), ("0.0167", 60),
     ("0.0333667", 30 / 1.001), ("0.033", 1 / 0.033)],
)  # fmt: skip
def test_a_rounded_frame_time_is_a_whole_or_ntsc_rate_and_written_back_as_one(frame_time, fps, tmp_path):
    """59.94 fps kept at 60 would drift from the take's video by 0.1 %."""
    path = tmp_path / "take.bvh"
    path.write_text(chain_bvh(2, frame_time=frame_time))
    motion = read_bvh(path)
    assert motion.fps == pytest.approx(fps, rel=1e-12)
    write_bvh(tmp_path / "again.bvh", motion)
    assert read_bvh(tmp_path / "again.bvh").fps == motion.fps


def test_joint_names_with_spaces_are_read_and_written_back(walk, tmp_path):
    """3ds Max's Biped names its joints ``Bip01 L Thigh``: the rest of the line is the name
    (up to a brace on the same line)."""
    path = tmp_path / "walk.bvh"
    write_bvh(path, walk)
    text = path.read_text().replace("ROOT Hips\n", "ROOT Bip01 Pelvis\n")
    text = text.replace("JOINT LeftUpLeg\n\t\t{", "JOINT Bip01 L Thigh {").replace(
        "JOINT RightUpLeg\n", "JOINT Bip01 R Thigh\n"
    )
    path.write_text(text)
    motion = read_bvh(path)
    names = motion.skeleton.names
    assert names[0] == "Bip01 Pelvis" and "Bip01 L Thigh" in names and "Bip01 R Thigh" in names
    np.testing.assert_array_equal(motion.channels, walk.channels)
    write_bvh(tmp_path / "again.bvh", motion)
    assert read_bvh(tmp_path / "again.bvh").skeleton.names == names


def test_an_empty_a_motion_only_a_utf16_and_a_dos_terminated_file(walk, tmp_path):
    """Each gets the message that says what it is, or opens: a Windows "Unicode" save is
    UTF-16, a DOS editor ends a file with Ctrl-Z (0x1A), some writers pad it with NULs."""
    _expect(tmp_path, "", "the file is empty")
    _expect(tmp_path, "MOTION\nFrames: 1\nFrame Time: 0.1\n0 0 0\n", "no HIERARCHY section")
    path = tmp_path / "walk.bvh"
    write_bvh(path, walk)
    text = path.read_text()
    for name, data in (("utf16.bvh", text.encode("utf-16")), ("dos.bvh", text.encode() + b"\x1a"),
                       ("padded.bvh", text.encode() + b"\x00" * 7)):  # fmt: skip
        (tmp_path / name).write_bytes(data)
        np.testing.assert_array_equal(read_bvh(tmp_path / name).channels, walk.channels)
