"""``workbench clean DIR -o OUT`` on Dask distributed: the same bytes whatever the
workers, weights loaded once per worker, failures reported, --resume, an existing
cluster, interrupts."""

import json
import os
import sys
import time

import numpy as np
import pytest

from workbench import batch
from workbench.cli import main


@pytest.fixture
def library(tmp_path, embedded_root):
    """Three takes: the embedded walk and jump, and the walk again in a subfolder."""
    takes = tmp_path / "takes"
    (takes / "again").mkdir(parents=True)
    walk = (embedded_root / "cmu" / "walk" / "35_31.bvh").read_bytes()
    (takes / "walk.bvh").write_bytes(walk)
    (takes / "jump.bvh").write_bytes((embedded_root / "cmu" / "jump" / "16_06.bvh").read_bytes())
    (takes / "again" / "walk.bvh").write_bytes(walk)
    return takes


def _outputs(folder):
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*.bvh"))}


@pytest.mark.slow
def test_the_result_is_the_same_bit_for_bit_on_one_worker_or_two(library, tmp_path, capsys):
    # mssa: its BLAS sums differ in the last bits with two threads, so each task runs with one
    for workers in (1, 2):
        assert main(["clean", str(library), "-o", str(tmp_path / f"out{workers}"), "--engine", "mssa",
                     "--workers", str(workers)]) == 0  # fmt: skip
    one, two = _outputs(tmp_path / "out1"), _outputs(tmp_path / "out2")
    assert sorted(one) == ["again/walk.bvh", "jump.bvh", "walk.bvh"] and one == two
    out = capsys.readouterr().out
    assert out.count("wrote ") == 6 and "frames cleaned by mssa" in out


def test_a_worker_loads_an_engine_once_and_reports_failures_as_text(library, tmp_path, monkeypatch):
    from workbench import registry

    made = []
    create = registry.create
    monkeypatch.setattr(registry, "create", lambda spec: made.append(spec) or create(spec))
    monkeypatch.setattr(batch, "_ENGINES", {})  # a fresh worker
    for name in ("walk.bvh", "jump.bvh"):
        report = batch.clean_task("kalman", None, str(library / name), str(tmp_path / name), False)
        assert report.error is None and report.frames > 0
    assert made == ["kalman"], "the weights are loaded once per worker"
    (library / "bad.bvh").write_text("HIERARCHY\nROOT Hips\n{\n")
    report = batch.clean_task("kalman", None, str(library / "bad.bvh"), str(tmp_path / "bad.bvh"), False)
    assert "bad.bvh" in report.error and not (tmp_path / "bad.bvh").exists()


def test_resume_skips_the_takes_done_and_refuses_another_engine(library, tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["clean", str(library), "-o", str(out), "--engine", "kalman", "--workers", "1"]
    assert main(argv) == 0
    capsys.readouterr()
    before = _outputs(out)
    earlier = (library / "jump.bvh").stat().st_mtime - 60
    with (library / "jump.bvh").open("a") as f:  # the jump was edited since, and given an old time (cp -p)
        f.write("\n")
    os.utime(library / "jump.bvh", (earlier, earlier))
    later = time.time() + 5
    os.utime(library / "walk.bvh", (later, later))  # the walk touched, not changed
    stale = out / ".walk.bvh.k3j2.tmp"  # left by a worker killed mid-write
    stale.write_text("half a take")
    assert main([*argv, "--resume"]) == 0
    captured = capsys.readouterr()
    assert (
        captured.out.count("kept ") == 2
        and captured.out.count("wrote ") == 1
        and "wrote " + str(out / "jump.bvh") in captured.out
    )
    assert "2 takes were up to date" in captured.err and _outputs(out) == before
    assert stale.exists(), "a take kept is not written again"
    (out / "again" / "walk.bvh").write_bytes(b"edited by hand")  # an output that is not what the clean wrote
    (out / "walk.bvh").unlink()
    (out / "walk.bvh").mkdir()  # a folder where an output goes
    assert main([*argv, "--resume"]) == 2
    captured = capsys.readouterr()
    assert (
        "wrote " + str(out / "again" / "walk.bvh") in captured.out and "kept " + str(out / "jump.bvh") in captured.out
    )
    assert (
        f"{library / 'walk.bvh'}" in captured.err
        and "1 of 3 takes failed (the others were written or kept)" in captured.err
    )
    (out / "walk.bvh").rmdir()
    assert main(["clean", str(library), "-o", str(out), "--engine", "kalman", "--workers", "1"]) == 0
    assert not stale.exists(), "a batch removes what a killed one left"
    assert _outputs(out) == before
    assert main(["clean", str(library), "-o", str(out), "--engine", "gaussian", "--resume"]) == 2
    assert "--resume would mix the two" in capsys.readouterr().err
    mapping = tmp_path / "map.json"  # a mapping file is known by what it pins, not by its path
    mapping.write_text('{"head": "Head"}')
    assert main([*argv, "--mapping", str(mapping)]) == 0
    capsys.readouterr()
    mapping.write_text('{"head": "Neck1"}')
    assert main([*argv, "--mapping", str(mapping), "--resume"]) == 2
    assert "--resume would mix the two" in capsys.readouterr().err
    (out / ".workbench-clean.json").write_text("{ not json")
    assert main([*argv, "--resume"]) == 2
    assert "cannot be read, so what" in capsys.readouterr().err


def test_an_existing_cluster_runs_the_same_code_path(library, tmp_path, capsys):
    from distributed import LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as cluster:
        argv = ["clean", str(library), "-o", str(tmp_path / "out"), "--engine", "kalman"]
        assert main([*argv, "--scheduler", cluster.scheduler_address]) == 0
    assert main(["clean", str(library), "-o", str(tmp_path / "local"), "--engine", "kalman", "--workers", "1"]) == 0
    assert _outputs(tmp_path / "out") == _outputs(tmp_path / "local")


def test_paths_reach_the_workers_absolute_and_a_take_that_cannot_be_read_fails_alone(
    library, tmp_path, monkeypatch, capsys
):
    """A worker of an existing cluster runs in its own folder: relative paths would read
    and write there. A dangling link or a pipe among the takes fails as a take does."""
    from distributed import LocalCluster

    log = tmp_path / "tasks.txt"  # (the task runs on a copy of this function)
    task = batch.clean_task

    def recorded(spec, mapping, source, output, *options):
        with open(log, "a") as f:
            f.write(f"{source}\t{output}\n")
        return task(spec, mapping, source, output, *options)

    monkeypatch.setattr(batch, "clean_task", recorded)
    (library / "gone.bvh").symlink_to(tmp_path / "no-such.bvh")
    os.mkfifo(library / "pipe.bvh")
    monkeypatch.chdir(tmp_path)
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as cluster:
        argv = ["clean", "takes", "-o", "out", "--engine", "kalman", "--scheduler", cluster.scheduler_address]
        assert main(argv) == 2
    seen = [line.split("\t") for line in log.read_text().splitlines()]
    assert len(seen) == 5 and all(os.path.isabs(s) and os.path.isabs(o) for s, o in seen)
    err = capsys.readouterr().err
    assert (
        "2 of 5 takes failed" in err
        and "takes/gone.bvh: cannot read the file" in err
        and "takes/pipe.bvh: not a file" in err
    )
    assert sorted(_outputs(tmp_path / "out")) == ["again/walk.bvh", "jump.bvh", "walk.bvh"]


def test_an_interrupted_batch_says_what_is_done_and_how_to_go_on(library, tmp_path, monkeypatch, capsys):
    def interrupted(spec, jobs, *options, **named):
        on_report = options[-1]
        on_report(batch.TakeReport(jobs[0][0], jobs[0][1], frames=10, engine=spec))
        raise KeyboardInterrupt

    monkeypatch.setattr(batch, "clean_library", interrupted)
    assert main(["clean", str(library), "-o", str(tmp_path / "out"), "--engine", "kalman"]) == 130
    err = capsys.readouterr().err
    assert "interrupted: 1 takes written, 2 not done" in err and "--resume" in err


def test_a_folder_clean_writing_nothing_leaves_no_folder_and_one_it_cannot_make_is_a_clear_error(tmp_path, capsys):
    takes = tmp_path / "takes"
    takes.mkdir()
    (takes / "bad.bvh").write_text("HIERARCHY\nROOT Hips\n{\n")
    out = tmp_path / "made" / "out"
    assert main(["clean", str(takes), "-o", str(out), "--engine", "lerp", "--workers", "1"]) == 2
    assert "1 of 1 takes failed (none was written)" in capsys.readouterr().err
    assert not (tmp_path / "made").exists(), "the folders the command made are removed again"
    kept = tmp_path / "kept"
    (kept / "other.txt").parent.mkdir()
    (kept / "other.txt").write_text("mine")
    assert main(["clean", str(takes), "-o", str(kept), "--engine", "lerp", "--workers", "1"]) == 2
    assert sorted(p.name for p in kept.iterdir()) == [".workbench-clean.json", "other.txt"]
    capsys.readouterr()
    assert main(["clean", str(takes), "-o", str(takes / "bad.bvh" / "sub"), "--engine", "lerp"]) == 2
    err = capsys.readouterr().err
    assert "bad.bvh/sub: cannot write it (Not a directory); nothing was written there" in err
    assert "Traceback" not in err


def test_a_record_whose_folder_holds_a_take_it_did_not_hear_of_is_kept_for_resume(tmp_path):
    """A take written but not reported (an interrupt between the two): the folder, the
    take and the record stay, so --resume goes on; an empty folder goes."""
    out = tmp_path / "new" / "out"
    record = batch.FolderRecord(out, {"engine": "lerp"}, resume=False)
    (out / "sub").mkdir()
    (out / "sub" / "take.bvh").write_text("a take\n")
    record.discard_if_unused()
    assert (out / batch.MANIFEST).exists() and (out / "sub" / "take.bvh").exists()
    (out / "sub" / "take.bvh").unlink()
    record.discard_if_unused()
    assert not (tmp_path / "new").exists()


@pytest.mark.slow
def test_bench_on_one_worker_or_two_scores_the_same(embedded_root, tmp_path):
    import json

    runs = {}
    for workers in (1, 2):
        out = tmp_path / f"bench{workers}.json"
        argv = ["bench", "--data", str(embedded_root), "--engines", "mssa,kalman", "--corrupt", "angular:0.5",
                "--seeds", "2", "--workers", str(workers), "--json", str(out)]  # fmt: skip
        assert main(argv) == 0
        runs[workers] = json.loads(out.read_text())
    timing = ("seconds", "frames_per_s", "peak_mb")

    def scores(report):
        return [{k: v for k, v in row.items() if k not in timing} for row in report["rows"]]

    assert scores(runs[1]) == scores(runs[2]) and len(runs[1]["rows"]) == 2 * 2 * 2
    assert all(runs[w]["summary"]["mssa"]["peak_mb"] > 0 for w in runs)


def test_the_long_take_plays_forwards_and_backwards(embedded_root):
    from workbench.data import find_clip
    from workbench.evaluate import long_take

    walk = find_clip("cmu/walk/35_31", embedded_root).load()
    long = long_take(walk, minutes=0.25)  # 1,800 frames at 120 fps: two round trips and more
    assert long.n_frames == 1800 and long.skeleton is walk.skeleton
    F = walk.n_frames
    assert (long.channels[:F] == walk.channels).all()
    assert (long.channels[F - 1 : 2 * F - 1] == walk.channels[::-1]).all(), "back again, the turn not repeated"
    assert (long.channels[2 * F - 2] == walk.channels[0]).all()


@pytest.mark.slow
def test_the_long_benchmark_times_a_clean_command_per_engine(embedded_root):
    from workbench.data import find_clip
    from workbench.evaluate import long_take, run_long_benchmark

    long = long_take(find_clip("cmu/walk/35_31", embedded_root).load(), minutes=0.1)
    result = run_long_benchmark(long, ["kalman", "no-such-engine", "ebf"], "angular:0.5+gaps:0.01")
    assert result.frames == 720 and result.io["read_frames_per_s"] > 0 and result.io["megabytes"] > 0
    kalman, bad, ebf = result.rows
    assert kalman["engine"] == "kalman" and kalman["frames_per_s"] > 0 and 0.05 < kalman["peak_gb"] < 4
    assert kalman["command_s"] > kalman["clean_s"] and "no-such-engine" in bad["error"]
    assert ebf["frames_per_s"] > 0
    (stream,) = result.streams  # kalman does not stream
    assert stream["engine"] == "ebf" and stream["ms_per_frame"] > 0
    table = result.markdown()
    assert "| kalman |" in table and "failed:" in table and "frames/s" in table and "ms per pushed frame" in table


def test_a_folder_cleaned_with_its_suspects_filled_says_so_and_resumes_only_so(library, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["clean", str(library), "-o", str(out), "--engine", "kalman", "--fill-suspects", "--workers", "1"]) == 0
    assert capsys.readouterr().err.count("flagged as bad data") == 3  # a note per take
    assert json.loads((out / batch.MANIFEST).read_text().splitlines()[0])["settings"]["fill_suspects"] is True
    assert main(["clean", str(library), "-o", str(out), "--engine", "kalman", "--resume"]) == 2
    assert "--resume would mix the two" in capsys.readouterr().err


def test_the_allocator_keeps_freed_arrays_where_glibc_runs_it():
    """On Linux with glibc (this project's CI) mallopt accepts both thresholds; elsewhere
    nothing is changed and the call says so."""
    import platform

    from workbench.allocator import keep_freed_arrays

    assert keep_freed_arrays() is (sys.platform.startswith("linux") and platform.libc_ver()[0] == "glibc")


def test_a_take_at_1_or_1200_frames_a_second_is_cleaned_with_a_note_on_its_frame_time(embedded_root, tmp_path):
    from workbench.data import find_clip
    from workbench.io import write_bvh
    from workbench.registry import create

    walk = find_clip("cmu/walk/35_31", embedded_root).load().slice(0, 40)
    take = tmp_path / "posed.bvh"
    write_bvh(take, walk.replace(fps=1.0))  # as a Blender export that left its frame time at 1 s
    report = batch.clean_file(create("kalman"), take, tmp_path / "out.bvh")
    (note,) = report.notes
    assert "runs at 1 fps (Frame Time 1 s), far below" in note and "mend that line" in note and "4,681 frames" in note
    write_bvh(take, walk.replace(fps=1200.0))  # a digit too many: 0.00083333
    note, *more = batch.clean_file(create("kalman"), take, tmp_path / "out.bvh").notes
    assert "runs at 1200 fps" in note and "far above" in note and "to 5 frames" in note
    assert all("jump faster than a body can" in n for n in more)  # ten times too fast, the walk is
    write_bvh(take, walk)
    assert batch.clean_file(create("kalman"), take, tmp_path / "out.bvh").notes == ()


def test_a_folder_clean_refuses_two_takes_for_one_file_and_files_no_clean_wrote(library, tmp_path, capsys):
    (library / "WALK.bvh").write_bytes((library / "walk.bvh").read_bytes())  # one file where names ignore case
    with pytest.raises(ValueError, match=r"WALK\.bvh and .*walk\.bvh would both be cleaned to .*: move or rename"):
        batch.library_jobs(library, tmp_path / "out")
    (library / "WALK.bvh").unlink()
    inside = library / "cleaned"  # an output folder inside the takes' folder, holding a raw take
    inside.mkdir()
    raw = (library / "jump.bvh").read_bytes()
    (inside / "walk.bvh").write_bytes(raw)
    assert main(["clean", str(library), "-o", str(inside), "--engine", "lerp"]) == 2
    assert "holds " + str(inside / "walk.bvh") + ", which would not be cleaned" in capsys.readouterr().err
    assert (inside / "walk.bvh").read_bytes() == raw
    assert main(["clean", str(library), "-o", str(tmp_path), "--engine", "lerp"]) == 2  # the takes inside the output
    assert (
        f"{library} lies inside the output folder {tmp_path}: name an output folder outside it"
        in capsys.readouterr().err
    )
    assert main(["clean", str(tmp_path / "no-such"), "-o", str(tmp_path / "out"), "--engine", "lerp"]) == 2
    assert f"{tmp_path / 'no-such'}: no such file or folder" in capsys.readouterr().err
    (inside / "walk.bvh").unlink()  # what a clean wrote there before is its own to write again
    batch.FolderRecord(inside, {"engine": "lerp"}, resume=False)
    (inside / "walk.bvh").write_bytes(raw)
    jobs = batch.library_jobs(library, inside)
    assert sorted(p.relative_to(library).as_posix() for p, _ in jobs) == ["again/walk.bvh", "jump.bvh", "walk.bvh"]


def test_a_joint_flagged_in_every_frame_is_kept_as_observed_with_a_note(embedded_root, tmp_path):
    """A take whose root seems to move faster than a body can in every frame (its unit
    or frame time wrong) is not bad data everywhere: --fill-suspects would erase its path."""
    from workbench.data import find_clip
    from workbench.io import read_bvh, write_bvh
    from workbench.registry import create

    walk = find_clip("cmu/walk/35_31", embedded_root).load().slice(1, 200)
    channels = walk.channels.copy()
    channels[:, :3] *= 40.0  # the root's path forty times too long
    take = tmp_path / "fast.bvh"
    write_bvh(take, walk.with_channels(channels))
    report = batch.clean_file(create("identity"), take, tmp_path / "out.bvh", fill_suspects=True)
    assert any("flagged as bad data in every frame it was observed, so kept as observed" in n for n in report.notes)
    assert read_bvh(tmp_path / "out.bvh").channels[:, :3] == pytest.approx(channels[:, :3], abs=1e-3)


def test_a_record_of_the_old_layout_or_cut_short_resumes_again_and_again(library, tmp_path, capsys):
    """The record is written whole when a resume opens it: lines appended to an old
    record (one JSON object over several lines) or to a line cut short stay readable."""
    out = tmp_path / "out"
    argv = ["clean", str(library), "-o", str(out), "--engine", "kalman", "--workers", "1"]
    assert main(argv) == 0
    record = out / batch.MANIFEST
    settings = json.loads(record.read_text().splitlines()[0])["settings"]
    record.write_text(json.dumps(settings, indent=1) + "\n")  # as a clean before this layout wrote it
    for _ in range(3):  # the first cleans all again (the old record vouches for none), then keeps them
        assert main([*argv, "--resume"]) == 0
    assert capsys.readouterr().out.count("kept ") == 6
    with record.open("a") as f:
        f.write('{"output": "walk.bvh", "sta')  # a killed process's last line
    for _ in range(2):
        assert main([*argv, "--resume"]) == 0
    assert capsys.readouterr().out.count("kept ") == 6


def test_an_amc_take_is_cleaned_again_when_its_asf_skeleton_changes(tmp_path, data_root):
    asf = next(data_root.glob("cmu/asfamc/*/*.asf"))
    takes = tmp_path / "takes"
    takes.mkdir()
    amc = next(asf.parent.glob("*.amc"))
    (takes / asf.name).write_bytes(asf.read_bytes())
    (takes / amc.name).write_bytes(amc.read_bytes())
    record = batch.FolderRecord(tmp_path / "out", {"engine": "identity"}, resume=False)
    output = tmp_path / "out" / amc.with_suffix(".bvh").name
    report = batch.clean_task("identity", None, str(takes / amc.name), str(output), False)
    assert report.error is None and report.stamp["skeleton"]
    record.add(report)
    assert record.up_to_date(takes / amc.name, output)
    (takes / asf.name).write_text((takes / asf.name).read_text().replace("\n", "\n ", 1))  # an edit
    assert not record.up_to_date(takes / amc.name, output)


def test_clean_says_where_a_take_has_broken_frames_and_what_a_robust_engine_set_aside(embedded_root, tmp_path):
    """A network trusts broken frames and spreads them over the take; a robust engine
    replaces what it takes for outliers, on a clean take fast motion: both are said."""
    from workbench.corruption import parse_corruption
    from workbench.data import find_clip
    from workbench.io import write_bvh
    from workbench.registry import create

    walk = find_clip("cmu/walk/35_31", embedded_root).load().slice(1, 300)
    channels = walk.channels.copy()
    channels[100:103, 0] += 20000.0  # the body a kilometre off for three frames (CMU units)
    take = tmp_path / "broken.bvh"
    write_bvh(take, walk.with_channels(channels))
    (note,) = batch.clean_file(create("kalman"), take, tmp_path / "out.bvh").notes
    assert note.startswith("3 frames (from 100) jump faster than a body can") and "--fill-suspects" in note
    assert not any(
        "jump faster" in n
        for n in batch.clean_file(create("kalman"), take, tmp_path / "o.bvh", fill_suspects=True).notes
    )
    write_bvh(take, parse_corruption("outliers:0.05").apply(walk, 0).motion)
    notes = batch.clean_file(create("mssa"), take, tmp_path / "out.bvh").notes
    assert any(n.startswith("mssa set aside") and "`robust=false` keeps it" in n for n in notes)
    write_bvh(take, walk)
    assert batch.clean_file(create("mssa"), take, tmp_path / "out.bvh").notes == ()


def test_clean_says_where_an_autoencoder_left_a_long_hole_partly_to_lerp(embedded_root, tmp_path):
    """A network that misses every joint it must guess by 20 cm: trials beside a 1-s hole
    find lerp nearer, and the note says so and how to keep the network's fill."""
    from workbench.cli import main
    from workbench.data import find_clip
    from workbench.registry import create

    walk = find_clip("cmu/walk/35_31", embedded_root)
    take = tmp_path / "holed.bvh"
    assert main(["corrupt", str(walk.path), "-o", str(take), "--corrupt", "block:1s", "--seed", "0"]) == 0
    engine = create("cae")
    complete = engine.complete

    def off(image, mask, *args):
        out = complete(image, mask, *args)
        out[:, :-3] += np.where(mask[:, :-3], 0.0, 20.0)  # the body's rows, not the root's path
        return out

    engine.complete = off
    notes = batch.clean_file(engine, take, tmp_path / "out.bvh").notes
    assert any(n.startswith("cae filled 120 frames of long holes partly by linear") for n in notes)
    quiet = batch.clean_file(create("cae:trial_holes=false"), take, tmp_path / "o.bvh").notes
    assert not any("linear" in n for n in quiet)


def test_a_reference_frame_with_a_missing_value_is_refused_before_the_clean_or_cleaned_with_the_motion(
    embedded_root, tmp_path
):
    from workbench.data import find_clip, has_reference_frame
    from workbench.io import read_bvh
    from workbench.io.bvh import format_bvh
    from workbench.io.errors import MotionFileError
    from workbench.registry import create

    walk = find_clip("cmu/walk/35_31", embedded_root).load(keep_reference=True).slice(0, 40)
    assert has_reference_frame(walk)
    lines = format_bvh(walk).splitlines()
    first = lines.index(next(line for line in lines if line.startswith("Frame Time:"))) + 1
    values = lines[first].split()
    values[11] = "nan"  # a converter's rest frame, damaged: written back as it is, it would stop the write
    lines[first] = " ".join(values)
    take = tmp_path / "damaged.bvh"
    take.write_text("\n".join(lines) + "\n")
    assert has_reference_frame(read_bvh(take))  # still one: corrupt and inspect drop it as before
    with pytest.raises(MotionFileError, match=r"damaged.bvh: frame 0, a T-pose reference .* \(--keep-reference\)"):
        batch.clean_file(create("lerp"), take, tmp_path / "out.bvh")  # (written back, it would stop the write)
    assert not (tmp_path / "out.bvh").exists()
    batch.clean_file(create("lerp"), take, tmp_path / "out.bvh", keep_reference=True)
    assert np.isfinite(read_bvh(tmp_path / "out.bvh").channels).all()
