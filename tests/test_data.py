import json

import numpy as np
import pytest

from workbench.data import (
    DataNotFoundError,
    catalogue,
    find_clip,
    find_data_root,
    select,
    share,
    without_reference_frame,
)
from workbench.data.catalogue import SPLITS_DIR


def test_catalogue_reads_manifests(clips):
    ids = {c.id for c in clips}
    assert "cmu/walk/02_01" in ids and "cmu-daz/kick/10_01" in ids
    assert {c.category for c in clips if c.dataset == "cmu"} == {"walk", "jog", "run", "jump", "other"}


def test_split_holds_out_whole_subjects(clips):
    cmu = [c for c in clips if c.dataset == "cmu"]
    train, test = select(cmu, "train"), select(cmu, "test")
    assert train and test and len(train) + len(test) == len(cmu)
    assert not ({c.subject for c in train} & {c.subject for c in test})
    assert {c.category for c in test} == {"walk", "jog", "run", "jump", "other"}
    split = json.loads((SPLITS_DIR / "cmu.json").read_text())
    assert sorted(split["test"]) == sorted(c.id.removeprefix("cmu/") for c in test)


def test_a_share_of_the_training_clips_is_fixed_nested_and_rounded_up(clips):
    """Learning curves train on 25 and 50 % of a split: the same clips on every machine,
    the smaller share inside the larger, in catalogue order."""
    train = select(clips, "train", dataset="cmu")
    quarter, half = share(train, 25), share(train, 50)
    assert len(quarter) == -(-len(train) // 4) and len(half) == -(-len(train) // 2)
    assert {c.id for c in quarter} < {c.id for c in half} < {c.id for c in train}
    assert [c.id for c in half] == [c.id for c in train if c in half]
    assert share(list(reversed(train)), 25) == list(reversed(quarter))
    assert share(train, 100) == train and len(share(train, 0.1)) == 1
    for bad in (0, -5, 100.5):
        with pytest.raises(ValueError, match="percentage"):
            share(train, bad)


def test_reference_frame_is_dropped(clips):
    clip = find_clip("cmu/walk/02_01")
    assert clip.load().n_frames == clip.frames - 1
    assert clip.load(keep_reference=True).n_frames == clip.frames
    daz = find_clip("10_03")
    assert daz.load().n_frames == daz.frames - 1
    motion = clip.load()  # no T-pose left: nothing more is dropped
    assert without_reference_frame(motion) is motion
    raw = clip.load(keep_reference=True)
    channels = raw.channels.copy()
    channels[1, 10] = np.nan  # a missing sample in frame 1 does not hide the T-pose before it
    assert without_reference_frame(raw.with_channels(channels)).n_frames == clip.frames - 1
    channels[1:] = np.nan  # nor does a take missing everything after it
    assert without_reference_frame(raw.with_channels(channels)).n_frames == clip.frames - 1


def test_reference_glitches_are_turns_faster_than_a_body_can(walk):
    from workbench.data.quality import Glitch, reference_glitches

    assert reference_glitches(walk) == []  # a clean walk
    channels = walk.channels.copy()
    j = walk.skeleton.index("LeftForeArm")
    channels[100:103, 3 + 3 * j] += 170.0  # a flip about the Z axis for three frames, and back
    channels[200, 3 + 3 * j] += 50.0  # 6,000 degrees/s at 120 fps: fast, but not faster than a body
    found = reference_glitches(walk.with_channels(channels))
    assert found == [Glitch("LeftForeArm", 99, 103, pytest.approx(170.0, abs=2.0))]  # plus the walk's own turn
    assert str(found[0]) == "LeftForeArm turns 170 degrees in one frame (frames 99-103)"
    # degrees per second: the same frames 4x slower (30 fps) turn a quarter as fast
    assert reference_glitches(walk.with_channels(channels).replace(fps=30.0)) == []


def test_folder_of_bvh_files_without_manifest(tmp_path, data_root):
    (tmp_path / "dance").mkdir()
    src = data_root / "cmu" / "walk" / "02_01.bvh"
    (tmp_path / "dance" / "x_01.bvh").write_bytes(src.read_bytes())
    clips = catalogue(tmp_path)
    assert [(c.id, c.category, c.split) for c in clips] == [("dance/x_01", "dance", "")]
    (tmp_path / "dance" / "x_01.amc").write_text("")  # the same take in another format: ids keep the suffix
    assert [c.id for c in catalogue(tmp_path)] == ["dance/x_01.amc", "dance/x_01.bvh"]
    assert find_clip("x_01.bvh", tmp_path).path.suffix == ".bvh"
    with pytest.raises(KeyError, match="'x_01' is kept in two formats: name one, dance/x_01.amc or dance/x_01.bvh"):
        find_clip("x_01", tmp_path)


def test_a_manifest_that_cannot_be_read_is_named_with_its_row(tmp_path, data_root):
    folder = tmp_path / "mine"
    folder.mkdir()
    (folder / "a.bvh").write_bytes((data_root / "cmu" / "walk" / "02_01.bvh").read_bytes())
    for text, message in (
        ("file,frames\na.bvh,many\n", r"MANIFEST.csv:2: 'frames' or 'fps' is not a number"),
        ("name\na.bvh\n", r"MANIFEST.csv:2: no file named"),
        ("file,frames\n,12\n", r"MANIFEST.csv:2: no file named"),  # an empty cell
        ("frames,file\n12\n", r"MANIFEST.csv:2: no file named"),  # a short row
        (b"file\n\xff.bvh\n", r"MANIFEST.csv cannot be read"),
    ):
        (folder / "MANIFEST.csv").write_bytes(text if isinstance(text, bytes) else text.encode())
        with pytest.raises(DataNotFoundError, match=message):
            catalogue(folder)


def test_linked_folders_are_followed(tmp_path, data_root):
    (tmp_path / "takes").mkdir()
    (tmp_path / "takes" / "kick").symlink_to(data_root / "cmu-daz" / "kick", target_is_directory=True)
    (tmp_path / "takes" / "loop").symlink_to(tmp_path / "takes", target_is_directory=True)  # a cycle ends
    assert find_data_root(tmp_path / "takes") == (tmp_path / "takes").resolve()
    clips = catalogue(tmp_path / "takes")
    assert clips and {c.category for c in clips} == {"kick"}
    assert all(c.id.startswith("kick/") for c in clips)


def test_data_root_order_and_errors(tmp_path, monkeypatch):
    monkeypatch.setenv("WORKBENCH_DATA", str(tmp_path / "missing"))
    with pytest.raises(DataNotFoundError, match="WORKBENCH_DATA points at"):
        find_data_root()
    (tmp_path / "d").mkdir()
    (tmp_path / "d" / "a.bvh").write_text("x")
    monkeypatch.setenv("WORKBENCH_DATA", str(tmp_path / "d"))
    assert find_data_root() == (tmp_path / "d").resolve()
    assert find_data_root(tmp_path / "d") == (tmp_path / "d").resolve()
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "notes.txt").write_text("x")
    with pytest.raises(DataNotFoundError, match="--data points at .*empty, which holds no .bvh"):
        find_data_root(tmp_path / "empty")  # not silently replaced by the next root


def test_without_data_the_embedded_takes_are_the_root_of_last_resort(tmp_path, monkeypatch):
    import workbench.data.roots as roots

    monkeypatch.delenv("WORKBENCH_DATA", raising=False)
    monkeypatch.setattr(roots, "REPO_ROOT", tmp_path / "repo")
    assert roots.find_data_root() == roots.EMBEDDED_ROOT and roots.is_embedded(roots.EMBEDDED_ROOT)
    monkeypatch.setattr(roots, "EMBEDDED_ROOT", tmp_path / "no-embedded")
    with pytest.raises(DataNotFoundError) as info:
        roots.find_data_root()
    msg = str(info.value)
    assert "--data" in msg and "WORKBENCH_DATA" in msg and "mocap.cs.cmu.edu" in msg
    # the clips the splits use, not a package that holds none of them
    assert "16, 35 and 127" in msg and "splits/cmu.json" in msg and "01-09" not in msg


def test_the_embedded_takes_are_the_default_take_and_a_jump_of_the_test_split(embedded_root):
    clips = catalogue(embedded_root)
    assert [(c.id, c.split, c.frames) for c in clips] == [
        ("cmu/jump/16_06", "test", 408),
        ("cmu/walk/35_31", "test", 422),
    ]
    walk = clips[1].load()
    assert walk.n_frames == 421 and walk.fps == 120.0 and walk.skeleton.n_joints == 31
    assert (embedded_root / "cmu" / "README.md").read_text().count("mocap.cs.cmu.edu") >= 1


def test_find_clip_errors():
    with pytest.raises(KeyError, match="workbench data"):
        find_clip("nope_99")


def test_the_studio_set_is_catalogued_with_its_styles_and_frames(clips):
    bandai = select(clips, dataset="bandai")
    assert len(bandai) == 594 and sum(c.frames for c in bandai) == 98_589
    assert {c.fps for c in bandai} == {30.0} and all(c.style and not c.subject for c in bandai)
    assert len({c.category for c in bandai}) == 24  # 16 contents and 10, walk and run in both
    for c in bandai[::97]:  # frame 0 is motion, not a T-pose: nothing is dropped
        assert c.load().n_frames == c.frames


def test_the_studio_split_holds_out_whole_styles_and_validates_on_training_styles(clips):
    bandai = select(clips, dataset="bandai")
    split = json.loads((SPLITS_DIR / "bandai.json").read_text())
    by = {name: select(bandai, name) for name in ("train", "validation", "test")}
    assert sum(map(len, by.values())) == len(bandai) and all(by.values())
    for name in ("validation", "test"):
        assert sorted(split[name]) == sorted(c.id.removeprefix("bandai/") for c in by[name])
    for subset, held in split["test_styles"].items():
        mine = {name: {c.style for c in group if f"/{subset}_" in c.id} for name, group in by.items()}
        assert mine["test"] == set(held) and not (mine["test"] & (mine["train"] | mine["validation"]))
        assert mine["validation"] <= mine["train"]
        total = len({c.style for c in bandai if f"/{subset}_" in c.id})
        assert 1 <= len(held) <= round(total / 5) + 1  # about one style in five
    # every content and style pair of the training styles is still trained on
    pairs = lambda group: {(c.category, c.style) for c in group}  # noqa: E731
    assert pairs(by["validation"]) <= pairs(by["train"])


def test_several_datasets_are_selected_by_names_joined_with_commas(clips):
    pooled = select(clips, "train", dataset="cmu, bandai")
    assert pooled == [c for c in select(clips, "train") if c.dataset in ("cmu", "bandai")]
    assert {c.dataset for c in pooled} == {"cmu", "bandai"}
