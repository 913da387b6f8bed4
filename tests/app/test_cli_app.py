"""The app's commands: ``workbench`` (no arguments) opens the GUI, ``workbench gui``
checks its corruption spec first, ``workbench report`` writes one figure atomically,
and the screenshots are made."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np

from workbench import cli
from workbench.app.defaults import DEFAULT_CLIP

PNG = b"\x89PNG\r\n\x1a\n"


def test_no_arguments_opens_the_gui_on_the_last_or_the_default_take(monkeypatch):
    import workbench.app.main

    calls = []
    monkeypatch.setattr(workbench.app.main, "run_gui", lambda *args: calls.append(args) or 0)
    assert cli.main([]) == 0
    assert calls == [(None,) * 5]  # run_gui: the last session's take, else the defaults


def test_gui_takes_a_clip_corruption_seed_engines_and_the_fill(monkeypatch):
    import workbench.app.main

    calls = []
    monkeypatch.setattr(workbench.app.main, "run_gui", lambda *args: calls.append(args) or 0)
    cli.main(["gui", "take.bvh", "--corrupt", "none", "--seed", "3", "--engine", "identity,lerp>gaussian"])
    cli.main(["gui", "take.bvh", "--fill-suspects"])
    assert calls == [("take.bvh", "none", 3, ["identity", "lerp>gaussian"], None), ("take.bvh", None, None, None, True)]


def test_gui_stops_on_a_bad_corruption_spec(capsys):
    assert cli.main(["gui", "--corrupt", "wobble:3"]) == 2
    err = capsys.readouterr().err
    assert "workbench gui: error:" in err and "wobble" in err


def test_report_writes_a_png_and_a_pdf(tmp_path):
    for name in ("report.png", "report.pdf"):
        out = tmp_path / name
        assert (
            cli.main(
                [
                    "report",
                    DEFAULT_CLIP,
                    "--engine",
                    "identity",
                    "--engine",
                    "test-widths",
                    "--frame",
                    "30",
                    "-o",
                    str(out),
                ]
            )
            == 0
        )
        head = out.read_bytes()[:8]
        assert head == PNG if name.endswith(".png") else head.startswith(b"%PDF")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report.pdf", "report.png"], "no temporary files left"


def test_a_report_of_a_skeleton_with_few_bones_or_none(tmp_path):
    from workbench.app.take import bone_choice
    from workbench.io import read_bvh
    from workbench.testing.takes import chain_bvh

    for joints, bones in ((4, [1, 2, 3]), (1, [])):  # fewer bones than the plot shows; a lone root
        take = tmp_path / f"chain{joints}.bvh"
        take.write_text(chain_bvh(joints, frames=5, wave_deg=10.0))
        assert bone_choice(read_bvh(take).skeleton) == bones
        assert (
            cli.main(["report", str(take), "--corrupt", "none", "--engine", "lerp", "-o", str(tmp_path / "r.png")]) == 0
        )


def test_a_failing_report_leaves_the_old_file_untouched(tmp_path, capsys):
    out = tmp_path / "report.png"
    out.write_bytes(b"old")
    assert cli.main(["report", DEFAULT_CLIP, "--engine", "test-boom", "-o", str(out)]) == 2
    assert "boom" in capsys.readouterr().err
    assert out.read_bytes() == b"old" and [p.name for p in tmp_path.iterdir()] == ["report.png"]
    assert cli.main(["report", DEFAULT_CLIP, "-o", str(tmp_path / "report.jpg")]) == 2
    assert cli.main(["report", DEFAULT_CLIP, "--engine", "identity", "--frame", "-1", "-o", str(out)]) == 2
    assert "--frame -1: the take's frames are 0 to" in capsys.readouterr().err and out.read_bytes() == b"old"
    assert cli.main(["report", DEFAULT_CLIP, "--engine", "lerp,lerp", "-o", str(out)]) == 2
    assert "lerp named twice: name each engine once" in capsys.readouterr().err and out.read_bytes() == b"old"


def test_screenshots_of_every_main_state(tmp_path, tiny_walk, clips):
    from workbench.app.main import STUDIO_CLIP, SUSPECTS_CLIP, UNSEEN_CLIP
    from workbench.io import write_bvh

    take = tmp_path / "walk.bvh"
    write_bvh(take, tiny_walk)
    code = (
        "import sys\nfrom workbench.app.main import make_screenshots\n"
        "make_screenshots(sys.argv[1], source=sys.argv[2], frame=60, specs=['identity'])\n"
    )
    env = dict(os.environ, OMP_NUM_THREADS="1")
    run = subprocess.run(
        [sys.executable, "-c", code, str(tmp_path / "shots"), str(take)],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 0, run.stderr[-2000:]
    names = sorted(p.name for p in (tmp_path / "shots").iterdir())
    studio = ["studio.png"] if any(c.id == STUDIO_CLIP for c in clips) else []  # a Bandai take by its id
    unseen = ["unseen.png"] if any(c.id == UNSEEN_CLIP for c in clips) else []
    suspects = ["suspects.png"] if any(c.id == SUSPECTS_CLIP for c in clips) else []
    assert names == [
        "compare.png",
        "default.png",
        "heatmap.png",
        "joint.png",
        "laptop.png",
        "outliers.png",
        "recorded.png",
        "report.png",
        *studio,
        *suspects,
        *unseen,
        "video.png",
    ]
    assert all((tmp_path / "shots" / n).read_bytes()[:8] == PNG for n in names)
    assert "Traceback" not in run.stderr


def test_the_report_adds_the_outlier_weights_when_an_engine_reports_them(take):
    from workbench.app.report import report_figure
    from workbench.app.take import run_engine

    def titles(specs):
        fig = report_figure(take, [run_engine(s, take) for s in specs], 10)
        return [ax.get_title(loc="left").split(" · ")[0] for ax in fig.axes if ax.get_title(loc="left")]

    assert {"filter widths", "data weights"} <= set(titles(["test-widths", "test-weights"]))
    only_weights = titles(["test-weights"])
    assert "data weights" in only_weights and "filter widths" not in only_weights
    assert "data weights" not in titles(["test-widths"])


def test_a_take_opened_by_path_drops_a_t_pose_frame_0_as_the_catalogue_does(data_root):
    from workbench.app.take import load_motion
    from workbench.io import read_bvh

    path = data_root / "cmu" / "walk" / "35_31.bvh"
    by_path, by_id = load_motion(str(path)), load_motion("cmu/walk/35_31")
    assert by_path.n_frames == read_bvh(path).n_frames - 1 == by_id.n_frames
    assert np.array_equal(by_path.channels, by_id.channels)


def test_an_engines_time_is_its_clean_not_its_loading(take, monkeypatch):
    """As ``workbench clean`` reports it: the first torch engine of a session spends
    seconds importing torch, which is not the engine's speed."""
    import time as clock

    from workbench import registry
    from workbench.app.take import run_engine

    make = registry.create
    monkeypatch.setattr(registry, "create", lambda spec: (clock.sleep(0.5), make(spec))[1])
    assert run_engine("identity", take).seconds < 0.25


def test_report_writes_a_real_time_video_of_the_playback(tmp_path, tiny_walk):
    import imageio_ffmpeg

    from workbench.io import write_bvh

    take = tmp_path / "walk.bvh"
    write_bvh(take, tiny_walk)  # 120 frames at 120 fps: one second
    out = tmp_path / "walk.mp4"
    argv = ["report", str(take), "--engine", "identity", "--engine", "test-widths", "--video", str(out)]
    assert cli.main(argv) == 0
    assert out.read_bytes()[4:8] == b"ftyp"  # an MP4 file
    frames, seconds = imageio_ffmpeg.count_frames_and_secs(str(out))
    assert frames == 30 and abs(seconds - 1.0) < 0.05  # 30 fps, in real time
    reader = imageio_ffmpeg.read_frames(str(out))
    assert next(reader)["size"] == (4 * 400, 440 + 300)  # noisy | identity | test-widths | truth, the plot below
    reader.close()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["walk.bvh", "walk.mp4"], "no temporary files left"
    assert cli.main(["report", str(take), "--video", str(tmp_path / "walk.avi")]) == 2
    assert cli.main(["report", str(take)]) == 2


def test_a_cancelled_video_leaves_no_file(tmp_path, take):
    from workbench.app.video import video_frames, write_video

    assert write_video(tmp_path / "v.mp4", take, [], progress=lambda done, total: done < 5) is None
    assert list(tmp_path.iterdir()) == []
    np.testing.assert_array_equal(video_frames(take)[:4], [0, 4, 8, 12])  # 120 fps shown at 30


def test_a_report_can_fill_the_suspects_first(tmp_path, monkeypatch):
    from workbench.app import report
    from workbench.app.take import open_take

    asked = []
    monkeypatch.setattr(report, "open_take", lambda *args: asked.append(args) or open_take(*args))
    out = tmp_path / "filled.png"
    argv = ["report", DEFAULT_CLIP, "--corrupt", "outliers:0.02", "--engine", "identity", "--fill-suspects"]
    assert cli.main([*argv, "-o", str(out)]) == 0
    assert out.read_bytes()[:8] == PNG and asked == [(DEFAULT_CLIP, "outliers:0.02", 0, True)]
