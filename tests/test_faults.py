"""Faults other than bad input lose nothing: writing onto a full disk (a small tmpfs), into a
read-only folder, or onto the input take leaves the input and any earlier output as they
were, and the command says so in one line with exit status 2.

The full disk and the read-only folder are real file systems, mounted for the test, which
needs root (CI runs as root); a read-only folder without root is a folder without write
permission."""

from __future__ import annotations

import contextlib
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

from workbench.cli import main
from workbench.engine.weights import MANIFEST_FILE, WEIGHTS_FILE, load_weights, save_weights
from workbench.io import OutputFileError, read_bvh, write_bvh

TAKE = Path("cmu") / "walk" / "35_31.bvh"  # an embedded take: 421 frames, 277 KB of BVH


@contextlib.contextmanager
def tmpfs(where: Path, size_kb: int):
    """A tmpfs of ``size_kb`` mounted on ``where`` (skips the test without root or mount)."""
    where.mkdir()
    if os.geteuid() != 0:
        pytest.skip("mounting a small file system needs root")
    mounted = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", f"size={size_kb}k", "tmpfs", str(where)], capture_output=True
    )
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {mounted.stderr.decode().strip()}")
    try:
        yield where
    finally:
        subprocess.run(["umount", "-l", str(where)], check=True)


def make_read_only(folder: Path) -> None:
    """Remount ``folder``'s tmpfs read-only as root; otherwise take its write permission."""
    if os.geteuid() == 0:
        subprocess.run(["mount", "-o", "remount,ro", str(folder)], check=True)
    else:
        folder.chmod(0o555)


def snapshot(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in folder.iterdir()}


@pytest.fixture
def take(tmp_path, embedded_root):
    path = tmp_path / "take.bvh"
    path.write_bytes((embedded_root / TAKE).read_bytes())
    return path


def test_a_full_disk_keeps_the_earlier_output_and_leaves_no_partial_file(tmp_path, take, capsys):
    with tmpfs(tmp_path / "disk", 200) as disk:
        earlier = disk / "out.bvh"
        earlier.write_text("an earlier output\n")
        (disk / "filler").write_bytes(b"x" * 100_000)  # too little room left for the cleaned take
        before, raw = snapshot(disk), take.read_bytes()
        assert main(["clean", str(take), "-o", str(earlier), "--engine", "gaussian"]) == 2
        err = capsys.readouterr().err
        assert "cannot write it (No space left on device)" in err and str(earlier) in err
        assert "Traceback" not in err and err.count("\n") <= 2
        assert snapshot(disk) == before, "the earlier output is as it was, and no temporary file is left"
        assert take.read_bytes() == raw


def test_a_read_only_folder_keeps_the_earlier_output(tmp_path, take, capsys):
    with tmpfs(tmp_path / "disk", 1024) as disk:
        earlier = disk / "out.bvh"
        earlier.write_text("an earlier output\n")
        make_read_only(disk)
        before = snapshot(disk)
        for output in (earlier, disk / "new" / "out.bvh"):  # over a file, and in a folder to make
            assert main(["clean", str(take), "-o", str(output), "--engine", "gaussian"]) == 2
            err = capsys.readouterr().err
            assert f"{output}: cannot write it" in err and "Traceback" not in err
        with pytest.raises(OSError, match="cannot write it"):  # callers that catch OSError still do
            write_bvh(earlier, read_bvh(take))
        assert snapshot(disk) == before


def test_a_read_only_output_is_refused_and_a_link_is_written_through(tmp_path, take, capsys):
    """A file made read-only (mode 444) is kept, even for root; an output that is a link
    writes the file it names and stays a link."""
    earlier = tmp_path / "out.bvh"
    earlier.write_text("an earlier output\n")
    earlier.chmod(0o444)
    for argv in (["clean", str(take), "--engine", "lerp"], ["corrupt", str(take), "--corrupt", "gaps:0.01"]):
        assert main([*argv, "-o", str(earlier)]) == 2
        err = capsys.readouterr().err
        assert f"{earlier}: cannot write it (the file is read-only: make it writable or name another file)" in err
        assert earlier.read_text() == "an earlier output\n" and "Traceback" not in err
    target, link = tmp_path / "target.bvh", tmp_path / "link.bvh"
    target.write_text("old\n")
    link.symlink_to(target)
    assert main(["clean", str(take), "-o", str(link), "--engine", "lerp"]) == 0
    assert link.is_symlink() and read_bvh(target).n_frames == read_bvh(take).n_frames
    assert main(["corrupt", str(take), "-o", str(link), "--corrupt", "gaps:0.01"]) == 0
    assert (tmp_path / "target.bvh.mask.json").exists() and not (tmp_path / "link.bvh.mask.json").exists()
    target.chmod(0o444)  # found through the link before the clean, and named as given
    assert main(["clean", str(take), "-o", str(link), "--engine", "lerp"]) == 2
    assert f"{link}: cannot write it (the file is read-only" in capsys.readouterr().err


def test_checking_an_output_makes_no_folder(tmp_path):
    from workbench.io.atomic import check_writable

    check_writable(tmp_path / "new" / "deeper" / "out.bvh")
    (tmp_path / "link.bvh").symlink_to(tmp_path / "gone" / "out.bvh")
    check_writable(tmp_path / "link.bvh")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.bvh"]


def test_a_benchmark_whose_json_cannot_be_written_says_so_before_it_runs(tmp_path, monkeypatch, capsys):
    import workbench.evaluate

    def run_benchmark(*args, **kwargs):
        raise AssertionError("the benchmark ran")

    monkeypatch.setattr(workbench.evaluate, "run_benchmark", run_benchmark)
    (tmp_path / "file").write_text("")
    for bad in (tmp_path, tmp_path / "file" / "scores.json"):  # a folder; a file where a folder should be
        assert main(["bench", "--engines", "lerp", "--corrupt", "gaps:0.01", "--seeds", "1", "--json", str(bad)]) == 2
        err = capsys.readouterr().err
        assert f"{bad}: cannot write it" in err and "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"], "no temporary file is left"


def test_an_in_place_clean_whose_backup_does_not_fit_leaves_the_take_as_it_was(tmp_path, take, capsys):
    with tmpfs(tmp_path / "disk", 400) as disk:
        raw = take.read_bytes()
        on_disk = disk / take.name
        on_disk.write_bytes(raw)  # 277 KB on a 400 KB disk: no room for TAKE.orig beside it
        assert main(["clean", str(on_disk), "--in-place", "--engine", "gaussian"]) == 2
        err = capsys.readouterr().err
        assert f"{on_disk}.orig: cannot write it (No space left on device)" in err
        assert snapshot(disk) == {take.name: raw}


def test_an_output_that_is_the_input_by_another_name_is_refused(tmp_path, take, capsys):
    raw = take.read_bytes()
    (tmp_path / "hard.bvh").hardlink_to(take)
    (tmp_path / "soft.bvh").symlink_to(take)
    for other in ("hard.bvh", "soft.bvh"):
        assert main(["clean", str(take), "-o", str(tmp_path / other), "--engine", "lerp"]) == 2
        assert "is the input take: writing it would overwrite" in capsys.readouterr().err
    assert take.read_bytes() == raw


def test_a_corrupted_take_and_its_mask_are_written_both_or_neither(tmp_path, take, capsys, monkeypatch):
    """A mask that cannot be written (here: a full disk, simulated) leaves the earlier take
    and mask as they were: never a new take beside an old mask, or beside none."""
    import errno

    import workbench.io.mask

    out = tmp_path / "noisy.bvh"
    assert main(["corrupt", str(take), "-o", str(out), "--corrupt", "gaps:0.01", "--seed", "2"]) == 0
    before = snapshot(tmp_path)

    def full_disk(path, *args):
        raise OutputFileError(path, OSError(errno.ENOSPC, "No space left on device"))

    monkeypatch.setattr(workbench.io.mask, "write_mask", full_disk)
    assert main(["corrupt", str(take), "-o", str(out), "--corrupt", "gaps:0.01", "--seed", "1"]) == 2
    assert "No space left on device" in capsys.readouterr().err
    assert snapshot(tmp_path) == before


def test_a_folder_clean_onto_a_full_disk_reports_each_take_and_keeps_the_rest(tmp_path, take, capsys):
    library = tmp_path / "library"
    library.mkdir()
    for name in ("a.bvh", "b.bvh", "c.bvh"):
        (library / name).write_bytes(take.read_bytes())
    assert main(["clean", str(take), "-o", str(tmp_path / "one.bvh"), "--engine", "gaussian"]) == 0
    size_kb = (tmp_path / "one.bvh").stat().st_size / 1024
    with tmpfs(tmp_path / "disk", int(2.5 * size_kb)) as disk:  # room for two cleaned takes, not three
        args = ["clean", str(library), "-o", str(disk / "out"), "--engine", "gaussian", "--workers", "1"]
        assert main(args) == 2
        err = capsys.readouterr().err
        assert "No space left on device" in err and "Traceback" not in err
        written = sorted(p.name for p in (disk / "out").glob("*.bvh"))
        assert len(written) == 2 and not list((disk / "out").glob(".*.tmp"))


def test_weights_that_do_not_fit_on_the_disk_leave_the_earlier_weights_loadable(tmp_path):
    with tmpfs(tmp_path / "disk", 64) as disk:
        folder = disk / "weights"
        save_weights(folder, {"w": np.zeros(100)}, {"engine": "demo", "skeleton_signature": "x"})
        before = snapshot(folder)
        with pytest.raises(OutputFileError, match=f"{folder / WEIGHTS_FILE}: cannot write it"):
            save_weights(folder, {"w": np.zeros(20_000)}, {"engine": "demo", "skeleton_signature": "x"})
        assert snapshot(folder) == before and sorted(before) == [MANIFEST_FILE, WEIGHTS_FILE]
        load_weights(folder)


def test_a_missing_input_with_an_existing_output_is_one_clear_line(tmp_path, capsys):
    """The check that -o is not the input must not stat an input that is not there."""
    (tmp_path / "out.bvh").write_text("an earlier output\n")
    missing = tmp_path / "missing.bvh"
    assert main(["clean", str(missing), "-o", str(tmp_path / "out.bvh"), "--engine", "lerp"]) == 2
    err = capsys.readouterr().err
    assert f"{missing}: no such file or folder" in err and "Traceback" not in err
    assert (tmp_path / "out.bvh").read_text() == "an earlier output\n"
