"""The command line, end to end, in-process (fast) and once as a real subprocess."""

import json
import subprocess
import sys

import numpy as np
import pytest

from workbench.cli import main, split_engine_specs
from workbench.io import read_bvh, write_bvh
from workbench.io.mask import read_mask
from workbench.testing.takes import chain_bvh


def test_split_engine_specs():
    assert split_engine_specs(["ebf:bias=true,free=1,gaussian", "lerp>gaussian:sigma_ms=58"]) == [
        "ebf:bias=true,free=1",
        "gaussian",
        "lerp>gaussian:sigma_ms=58",
    ]


def test_engines_and_data_listing(capsys):
    assert main(["engines"]) == 0
    out = capsys.readouterr().out
    assert "identity" in out and "source: Lou and Chai 2010" in out  # each engine's paper
    assert main(["data", "--split", "test"]) == 0
    out = capsys.readouterr().out
    assert "cmu/walk/35_31" in out and "cmu/walk/02_01" not in out


def test_corruption_models_are_listed_and_a_bad_spec_is_refused_before_any_take_is_read(tmp_path, capsys):
    from workbench.corruption import MODELS

    for command in ("corrupt", "bench"):
        with pytest.raises(SystemExit):
            main([command, "--help"])
        out = capsys.readouterr().out
        assert all(cls.signature() in out for cls in MODELS.values())
    for command in (["corrupt", "no-such-take.bvh", "-o", str(tmp_path / "out.bvh")], ["bench", "--engines", "lerp"]):
        assert main([*command, "--corrupt", "gaps:0.01,-3"]) == 2  # before any take is read (there is none)
        assert "MEAN (mean gap length, frames) must be a number of frames >= 1" in capsys.readouterr().err


def test_corrupt_then_clean(tmp_path, data_root, capsys):
    src = data_root / "cmu" / "walk" / "02_01.bvh"
    noisy = tmp_path / "noisy.bvh"
    assert main(["corrupt", str(src), "-o", str(noisy), "--corrupt", "angular:0.5+gaps:0.01", "--seed", "3"]) == 0
    m = read_bvh(noisy)
    mask = read_mask(str(noisy) + ".mask.json", m.skeleton, m.n_frames)
    assert m.n_frames == 343 and np.isfinite(m.channels).all() and 0 < (~mask).sum()
    out = tmp_path / "clean.bvh"
    assert main(["clean", str(noisy), "-o", str(out), "--engine", "identity"]) == 0
    assert read_bvh(out).n_frames == 343
    assert "mask sidecar" in capsys.readouterr().err
    # same seed, same file
    again = tmp_path / "again.bvh"
    main(["corrupt", str(src), "-o", str(again), "--corrupt", "angular:0.5+gaps:0.01", "--seed", "3"])
    assert again.read_text() == noisy.read_text()


def test_a_sidecar_of_another_take_says_it_was_found_and_how_to_be_rid_of_it(tmp_path, data_root, capsys):
    src = data_root / "cmu" / "walk" / "02_01.bvh"
    noisy = tmp_path / "noisy.bvh"
    assert main(["corrupt", str(src), "-o", str(noisy), "--corrupt", "gaps:0.01", "--seed", "3"]) == 0
    short = tmp_path / "short.bvh"
    write_bvh(short, read_bvh(noisy).slice(0, 20))
    (tmp_path / "short.bvh.mask.json").write_bytes((tmp_path / "noisy.bvh.mask.json").read_bytes())
    capsys.readouterr()
    assert main(["clean", str(short), "-o", str(tmp_path / "out.bvh"), "--engine", "lerp"]) == 2
    err = capsys.readouterr().err
    assert "the mask is for 343 frames, the take has 20; it was found beside the take and read as its mask" in err
    assert "--mask" in err and not (tmp_path / "out.bvh").exists()


def test_clean_treats_nan_as_missing(tmp_path, walk):
    from workbench.io.bvh import format_bvh

    text = format_bvh(walk.slice(0, 30)).splitlines()
    vals = text[-10].split()
    vals[20] = "nan"
    text[-10] = " ".join(vals)
    src = tmp_path / "nan.bvh"
    src.write_text("\n".join(text) + "\n")
    out = tmp_path / "out.bvh"
    assert main(["clean", str(src), "-o", str(out), "--engine", "identity"]) == 0
    assert np.isfinite(read_bvh(out).channels).all()


@pytest.mark.parametrize(
    "args,needle",
    [
        (["clean", "missing.bvh", "-o", "{tmp}/o.bvh", "--engine", "identity"], "missing.bvh: no such file or folder"),
        (["clean", "{bad}", "-o", "{tmp}/o.bvh", "--engine", "identity"], "truncated"),
        (["clean", "{good}", "-o", "{tmp}/o.bvh", "--engine", "nope"], "unknown engine"),
        (["corrupt", "{good}", "-o", "{tmp}/o.bvh", "--corrupt", "wobble:1"], "wobble"),
        (["clean", "{good}", "-o", "{tmp}/o.amc", "--engine", "identity"], "the .bvh suffix"),
        (["clean", "{good}", "-o", "{bad}/o.bvh", "--engine", "identity"], "bad.bvh is a file, not a folder"),
        (["corrupt", "{good}", "-o", "{tmp}", "--corrupt", "gaps:0.01"], "is a folder: name the .bvh file to write"),
        (["clean", "{good}", "-o", "{tmp}/o.bvh", "--engine", "cae:window_frames=0"], "window_frames must be"),
        (["data", "--dataset", "nosuch"], "no clips of split='all' dataset='nosuch'"),
        (["bench", "--engines", ",", "--corrupt", "angular:0.5"], "no engine named in ','"),
        (["bench", "--engines", "identity", "--corrupt", "angular:0.5", "--data", "{tmp}/none"], "not a folder"),
    ],
)
def test_user_errors_are_one_line_and_leave_no_output(args, needle, tmp_path, data_root, capsys):
    good = data_root / "cmu" / "walk" / "02_01.bvh"
    bad = tmp_path / "bad.bvh"
    bad.write_text("\n".join(good.read_text().splitlines()[:-5]) + "\n")
    args = [a.format(tmp=tmp_path, bad=bad, good=good) for a in args]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err and err.count("\n") <= 3
    assert not (tmp_path / "o.bvh").exists()


@pytest.mark.parametrize(
    "missing", [{"Hips": [None]}, {"Hips": [["a", "b"]]}, {"Hips": [[1.5, 3.0]]}, {"Hips": [[True, 3]]}, ["Hips"]]
)
def test_a_malformed_mask_is_one_line(missing, tmp_path, walk, capsys):
    from workbench.io import write_bvh

    take = tmp_path / "t.bvh"
    write_bvh(take, walk)
    mask = {"format": "mocap-workbench observed mask v1", "frames": walk.n_frames, "missing": missing}
    (tmp_path / "m.json").write_text(json.dumps(mask))
    assert (
        main(
            ["clean", str(take), "-o", str(tmp_path / "o.bvh"), "--engine", "lerp", "--mask", str(tmp_path / "m.json")]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert "m.json" in err and "span" in err and "Traceback" not in err and err.count("\n") == 1


def test_a_take_with_nothing_observed_is_refused_not_made_up(tmp_path, walk, capsys):
    from workbench.io.bvh import format_bvh

    lines = format_bvh(walk.slice(0, 20)).splitlines()
    frames = lines.index("MOTION") + 3
    lines[frames:] = [" ".join(["nan"] * len(line.split())) for line in lines[frames:]]
    take = tmp_path / "nan.bvh"
    take.write_text("\n".join(lines) + "\n")
    for args in (["clean", str(take), "-o", str(tmp_path / "o.bvh"), "--engine", "gaussian"], ["inspect", str(take)]):
        assert main(args) == 2
        assert "no sample of the take is observed" in capsys.readouterr().err
    assert not (tmp_path / "o.bvh").exists()


@pytest.mark.parametrize(
    "args, needle",
    [
        (
            ["bench", "--engines", "gaussian", "--corrupt", "angular:0.5", "--seeds", "0"],
            "--seeds: want a whole number",
        ),
        (["bench", "--long", "--minutes", "nan", "--engines", "gaussian", "--corrupt", "none"], "above 0, got nan"),
        (
            ["clean", "x", "-o", "y", "--engine", "lerp", "--workers", "0"],
            "--workers: want a whole number of at least 1",
        ),
        (["train", "kalman-learned", "--epochs", "two"], "--epochs: want a whole number, got 'two'"),
    ],
)
def test_counts_and_lengths_out_of_range_are_refused_before_any_work(args, needle, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(args)
    assert exit_.value.code == 2 and needle in capsys.readouterr().err


def test_a_joint_never_observed_is_said_to_be_made_up(tmp_path, walk, capsys):
    from workbench.io import write_bvh

    take = tmp_path / "t.bvh"
    write_bvh(take, walk)
    mask = {"format": "mocap-workbench observed mask v1", "frames": walk.n_frames, "missing": {"Head": [[0, 343]]}}
    (tmp_path / "t.bvh.mask.json").write_text(json.dumps(mask))
    assert main(["clean", str(take), "-o", str(tmp_path / "o.bvh"), "--engine", "lerp"]) == 0
    assert "Head: never observed in the take, so the engine could only make it up" in capsys.readouterr().err


def test_train_into_a_file_is_refused_before_training(tmp_path, data_root, capsys):
    out = tmp_path / "weights"
    out.write_text("a file")
    for where in (out, out / "sub"):
        assert main(["train", "kalman-learned", "--dataset", "cmu", "--out", str(where)]) == 2
        assert f"{out} is a file; the weights go into a folder" in capsys.readouterr().err
    assert out.read_text() == "a file"


@pytest.mark.usefixtures("data_root")
def test_bench_takes_the_clips_of_a_dataset_without_a_split_by_pattern(tmp_path, capsys):
    js = tmp_path / "b.json"
    assert (
        main(
            [
                "bench",
                "--engines",
                "identity",
                "--corrupt",
                "angular:0.5",
                "--clips",
                "cmu-daz/kick/10_0*",
                "--json",
                str(js),
            ]
        )
        == 0
    )
    assert "no train/validation/test split; benchmarking all" in capsys.readouterr().err
    clips = json.loads(js.read_text())["clips"]
    assert clips and all(c.startswith("cmu-daz/kick/10_0") for c in clips)


def test_the_embedded_takes_bench_out_of_the_box_and_are_never_trained_on(embedded_root, tmp_path, capsys):
    js = tmp_path / "b.json"
    args = ["--data", str(embedded_root)]
    assert main(["bench", *args, "--engines", "kalman", "--corrupt", "angular:0.5", "--json", str(js)]) == 0
    assert "using the two CMU takes embedded in the package" in capsys.readouterr().err
    assert json.loads(js.read_text())["clips"] == ["cmu/jump/16_06", "cmu/walk/35_31"]
    assert main(["train", "kalman-learned", *args, "--out", str(tmp_path / "w")]) == 2
    err = capsys.readouterr().err
    assert "test clips, never trained on" in err and "subjects 02, 03, 05, 06, 07 and 09" in err
    assert not (tmp_path / "w").exists()


def test_bench_refuses_what_would_overwrite_a_take_or_score_nothing(tmp_path, data_root, capsys):
    take = tmp_path / "take.bvh"
    take.write_bytes((data_root / "cmu" / "walk" / "02_01.bvh").read_bytes())
    raw = take.read_bytes()
    base = [
        "bench",
        "--engines",
        "lerp",
        "--corrupt",
        "gaps:0.01",
        "--data",
        str(data_root),
        "--clips",
        "cmu/walk/35_31",
    ]
    refusals = [
        ([*base, "--json", str(take)], "the scores are written as JSON; name the file with the .json suffix"),
        ([*base, "--long", "--json", str(tmp_path / "a.json")], "--long prints its table: leave out --json"),
        (
            [*base[:2], "mssa:weights=" + str(tmp_path / "none"), *base[3:]],
            "no weights manifest here",
        ),
    ]
    for argv, message in refusals:
        assert main(argv) == 2
        assert message in capsys.readouterr().err
    assert take.read_bytes() == raw and not (tmp_path / "a.json").exists()
    with pytest.raises(SystemExit):
        main([*base, "--long", "--minutes", "0.05"])
    assert "want 0.1 to 600 minutes, got '0.05'" in capsys.readouterr().err
    from workbench import registry

    bandai = [
        "--data",
        str(data_root),
        "--clips",
        "bandai/bow/dataset-1_bow_happy_001",
        "--json",
        str(tmp_path / "s.json"),
    ]
    cmu_weights = f"kalman-learned:weights={registry.create('kalman-learned').default_weights_dir() / 'cmu'}"
    assert main(["bench", "--engines", cmu_weights, "--corrupt", "gaps:0.01", *bandai]) == 2
    err = capsys.readouterr().err
    assert "has no weights for this skeleton" in err and "no engine cleaned any clip" in err
    assert not (tmp_path / "s.json").exists()


def test_a_long_bench_whose_engine_failed_and_an_interrupted_train_say_so_in_their_status(
    tmp_path, data_root, monkeypatch, capsys
):
    import workbench.evaluate
    import workbench.training
    from workbench.evaluate import LongResult

    def failed(motion, specs, *args):
        io = {"megabytes": 1.0, "read_frames_per_s": 1.0, "write_frames_per_s": 1.0}
        return LongResult(motion.n_frames, motion.fps, io, [{"engine": specs[0], "error": "it broke"}])

    monkeypatch.setattr(workbench.evaluate, "run_long_benchmark", failed)
    argv = ["bench", "--long", "--minutes", "0.1", "--engines", "lerp", "--corrupt", "gaps:0.01"]
    assert main([*argv, "--data", str(data_root)]) == 2
    captured = capsys.readouterr()
    assert "failed: it broke" in captured.out and "lerp did not clean the long take" in captured.err

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(workbench.training, "train_engine", interrupted)
    takes = tmp_path / "takes"
    takes.mkdir()
    (takes / "a.bvh").write_bytes((data_root / "cmu" / "walk" / "02_01.bvh").read_bytes())
    assert main(["train", "kalman-learned", "--data", str(takes), "--out", str(tmp_path / "w")]) == 130
    assert "interrupted; nothing was saved" in capsys.readouterr().err and not (tmp_path / "w").exists()


def test_train_out_refuses_a_package_s_weights_folder_only(tmp_path):
    from workbench import registry
    from workbench.cli import UserError, _weights_out

    engine = registry.create("kalman-learned", pretrained=False)
    package = tmp_path / "plugin"
    (package / "weights").mkdir(parents=True)
    (package / "__init__.py").write_text("")
    with pytest.raises(UserError, match=f"is among the committed weights \\({package / 'weights'}\\)"):
        _weights_out(str(package / "weights" / "v2" / "cmu"), engine)
    assert _weights_out(str(tmp_path / "runs" / "weights" / "v2"), engine) == tmp_path / "runs" / "weights" / "v2"


@pytest.mark.usefixtures("data_root")
def test_bench_prints_a_table_and_writes_json(tmp_path, capsys):
    js = tmp_path / "b.json"
    assert (
        main(
            [
                "bench",
                "--engines",
                "identity,gaussian",
                "--corrupt",
                "angular:0.5",
                "--split",
                "test",
                "--clips",
                "cmu/run/*",
                "--seeds",
                "2",
                "--per-clip",
                "rms_angle_deg",
                "--per-joint",
                "mpjpe_cm",
                "--json",
                str(js),
            ]
        )
        == 0
    )
    out, err = capsys.readouterr()
    assert out.splitlines()[0].startswith("| engine | rms_angle_deg | mpjpe_cm")
    doc = json.loads(js.read_text())
    s = doc["summary"]["identity"]
    assert s["rms_angle_deg"] > 0 and s["frames_per_s"] > 0 and "gap_mpjpe_cm" not in s
    assert len(doc["rows"]) == 4 * len(doc["clips"]) and all(c.startswith("cmu/run/") for c in doc["clips"])
    # the per-clip table: a row per clip with each engine's mean over the two seeds, then the mean row
    table = out.split("\n\n")[1].splitlines()
    assert table[0] == "| clip (rms_angle_deg) | frames | identity | gaussian |"
    assert [line.split(" | ")[0][2:] for line in table[2:-1]] == doc["clips"]
    for line, clip in zip(table[2:-1], doc["clips"]):
        cells = line.strip("| ").split(" | ")
        for spec, cell in zip(("identity", "gaussian"), cells[2:]):
            seeds = [r["rms_angle_deg"] for r in doc["rows"] if r["clip"] == clip and r["engine"] == spec]
            assert len(seeds) == 2 and float(cell) == pytest.approx(np.mean(seeds), abs=6e-4)
    means = [f"{doc['summary'][spec]['rms_angle_deg']:.3f}" for spec in ("identity", "gaussian")]
    assert table[-1] == "| **mean** | | " + " | ".join(means) + " |"
    # the per-joint table: a row per joint but the root, each engine's mean over the rows
    table = out.split("\n\n")[2].splitlines()
    assert table[0] == "| joint (mpjpe_cm) | identity | gaussian |"
    first = doc["rows"][0]["per_joint"]["mpjpe_cm"]
    assert [line.split(" | ")[0][2:] for line in table[2:]] == list(first) and "root" not in first
    for line in table[2:]:
        joint, *cells = line.strip("| ").split(" | ")
        for spec, cell in zip(("identity", "gaussian"), cells):
            values = [r["per_joint"]["mpjpe_cm"][joint] for r in doc["rows"] if r["engine"] == spec]
            assert len(values) == 2 * len(doc["clips"]) and float(cell) == pytest.approx(np.mean(values), abs=6e-4)
    # the reference's capture glitches are named, on stderr and in the JSON
    assert "2 of the clean clips have capture glitches" in err
    assert "cmu/run/35_26: RightFingerBase turns 170 degrees in one frame (frames 64-67)" in err
    assert doc["reference_glitches"]["cmu/run/35_26"] == [
        {"joint": "RightFingerBase", "first": 64, "last": 67, "turn_deg": pytest.approx(169.74, abs=0.01)}
    ]
    assert set(doc["reference_glitches"]) == {"cmu/run/35_26", "cmu/run/16_46"}


@pytest.mark.usefixtures("data_root")
def test_data_lists_a_dataset_with_its_styles_and_splits(capsys):
    assert main(["data", "--dataset", "bandai", "--split", "validation"]) == 0
    out = capsys.readouterr().out
    assert "bandai/walk/dataset-2_walk_normal_006" in out and "cmu/" not in out
    assert out.splitlines()[-1] == "bandai: 75 clips (75 validation), 13,338 frames at 30 fps"


@pytest.mark.usefixtures("data_root")
def test_bench_covers_every_dataset_s_test_split_skips_short_takes_and_names_refusals(tmp_path, capsys):
    """Every dataset's test split, a table each; a take too short for the block (Bandai's
    135-frame walk_happy_002) is left out with a note, not the run; a trained engine
    that refuses a skeleton (weights named for CMU's only) is named."""
    from engines.kalman import LearnedKalman

    js, cmu_only = tmp_path / "b.json", f"kalman-learned:weights={LearnedKalman().default_weights_dir() / 'cmu'}"
    assert (
        main(
            [
                "bench",
                "--engines",
                f"kalman,{cmu_only}",
                "--corrupt",
                "block:150",
                "--clips",
                "*/walk/*",
                "--json",
                str(js),
            ]
        )
        == 0
    )
    out, err = capsys.readouterr()
    doc = json.loads(js.read_text())
    assert set(doc["summary_by_dataset"]) == {"bandai", "cmu"} and "\nbandai (" in "\n" + out and "\ncmu (" in out
    assert doc["skipped"] == {
        "bandai/walk/dataset-1_walk_happy_002": "block:150 needs a clip of at least 152 frames "
        "(the block plus one observed frame on each side); this one has 135"
    }
    assert "bandai/walk/dataset-1_walk_happy_002" not in doc["clips"] and "could not be corrupted with block:150" in err
    assert set(doc["refused"][cmu_only]) == {c for c in doc["clips"] if c.startswith("bandai/")}
    assert f"{cmu_only} did not clean" in err and "has no weights for this skeleton" in err
    assert "mpjpe_cm" in doc["summary_by_dataset"]["bandai"]["kalman"]
    assert "mpjpe_cm" not in doc["summary_by_dataset"]["bandai"][cmu_only]
    assert (
        main(
            [
                "bench",
                "--engines",
                "kalman",
                "--corrupt",
                "angular:0.5",
                "--dataset",
                "bandai",
                "--clips",
                "*/walk/*",
                "--json",
                str(js),
            ]
        )
        == 0
    )
    out, _ = capsys.readouterr()
    clips = json.loads(js.read_text())["clips"]
    assert clips and all(c.startswith("bandai/") for c in clips) and out.startswith("| engine |")


@pytest.mark.slow
@pytest.mark.usefixtures("data_root")
def test_train_on_the_studio_takes_records_their_rate_skeleton_and_terms(tmp_path):
    """Bandai's Hips under joint_Root trains as the body view rooted at the Hips, at the
    takes' 30 fps; the manifest carries the data set's non-commercial terms."""
    out = tmp_path / "kl"
    assert main(["train", "kalman-learned", "--dataset", "bandai", "--out", str(out)]) == 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["fps"] == 30.0 and manifest["skeleton_signature"].startswith("Hips<-1>")
    assert [d["name"] for d in manifest["training"]["datasets"]] == ["bandai"]
    assert "CC BY-NC" in json.dumps(manifest["training"]["datasets"])


def test_train_on_a_share_of_the_split_records_the_clips_it_used(tmp_path, clips, capsys):
    from workbench.data import select, share

    out = tmp_path / "kl"
    assert main(["train", "kalman-learned", "--dataset", "cmu", "--share", "25", "--out", str(out)]) == 0
    used = json.loads((out / "manifest.json").read_text())["training"]["clips"]
    assert used == [c.id for c in share(select(clips, "train", dataset="cmu"), 25)]
    assert main(["train", "kalman-learned", "--share", "0", "--out", str(tmp_path / "x")]) == 2
    assert "--share is a percentage in (0, 100]" in capsys.readouterr().err and not (tmp_path / "x").exists()


def test_per_clip_marks_a_metric_no_seed_defines():
    from workbench.evaluate import BenchResult

    result = BenchResult(
        "angular:0.5",
        [0, 1],
        ["a", "b"],
        rows=[
            {"engine": "x", "clip": "a", "seed": 0, "frames": 10, "gap_mpjpe_cm": 1.0},
            {"engine": "x", "clip": "a", "seed": 1, "frames": 10, "gap_mpjpe_cm": float("nan")},
            {"engine": "x", "clip": "b", "seed": 0, "frames": 20},
        ],
        summary={"x": {"gap_mpjpe_cm": 1.0}},
    )
    assert result.per_clip("gap_mpjpe_cm") == {"a": {"x": 1.0}, "b": {"x": pytest.approx(float("nan"), nan_ok=True)}}
    assert result.per_clip_markdown("gap_mpjpe_cm").splitlines()[2:] == [
        "| a | 10 | 1.000 |",
        "| b | 20 | – |",
        "| **mean** | | 1.000 |",
    ]
    with pytest.raises(ValueError, match="unknown metric"):
        result.per_clip("speed")


def test_per_joint_is_by_dataset_skips_undefined_values_and_refuses_other_metrics():
    from workbench.evaluate import BenchResult

    def row(clip, value):
        return {"engine": "x", "clip": clip, "per_joint": {"rms_angle_deg": {f"{clip}-joint": value}, "mpjpe_cm": {}}}

    result = BenchResult(
        "angular:0.5",
        [0, 1],
        ["a", "b"],
        rows=[row("a", 1.0), row("a", 3.0), row("a", float("nan")), row("b", 5.0), {"engine": "x", "clip": "b"}],
        summary={"x": {}, "y": {}},
        dataset_of={"a": "one", "b": "two"},
    )
    nan = pytest.approx(float("nan"), nan_ok=True)
    assert result.per_joint("rms_angle_deg", "one") == {"a-joint": {"x": 2.0, "y": nan}}
    assert result.per_joint("rms_angle_deg") == {"a-joint": {"x": 2.0, "y": nan}, "b-joint": {"x": 5.0, "y": nan}}
    assert result.per_joint_markdown("rms_angle_deg", "two").splitlines()[2:] == ["| b-joint | 5.000 | – |"]
    with pytest.raises(ValueError, match="unknown per-joint metric"):
        result.per_joint("jitter_cm_s3")


def test_module_entry_point_runs():
    out = subprocess.run([sys.executable, "-m", "workbench", "engines"], capture_output=True, text=True)
    assert out.returncode == 0 and "identity" in out.stdout


def test_a_reader_that_stops_early_gets_no_traceback():
    """`workbench engines | head -1`: the pipe closes before the listing is written."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "workbench", "engines"], stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    proc.stdout.close()  # before the child has imported anything, so every write fails
    err = proc.stderr.read().decode()
    assert proc.wait() == 0 and "Traceback" not in err, err


@pytest.mark.slow
def test_train_on_another_skeleton_then_clean_with_its_weights(tmp_path, data_root, capsys):
    """The route the foreign-skeleton error names: train on takes of that skeleton into a
    folder, clean with ``ENGINE:weights=FOLDER``; the committed weights stay untouched."""
    takes = tmp_path / "takes"
    takes.mkdir()
    (takes / "kick").symlink_to(data_root / "cmu-daz" / "kick", target_is_directory=True)
    take = data_root / "cmu-daz" / "jump" / "13_11.bvh"
    assert main(["clean", str(take), "-o", str(tmp_path / "no.bvh"), "--engine", "mssa"]) == 2
    err = capsys.readouterr().err
    assert "mssa:weights=FOLDER" in err and not (tmp_path / "no.bvh").exists()
    out = tmp_path / "mssa-daz"
    assert main(["train", "mssa", "--data", str(takes), "--out", str(out)]) == 0
    assert f"--engine 'mssa:weights={out}'" in capsys.readouterr().out
    training = json.loads((out / "manifest.json").read_text())["training"]
    assert "minutes" in training and training.get("peak_mb", 1) > 0  # peak_mb: Linux only
    cleaned = tmp_path / "clean.bvh"
    assert main(["clean", str(take), "-o", str(cleaned), "--engine", f"mssa:weights={out}"]) == 0
    assert read_bvh(cleaned).skeleton.n_joints == 43
    assert main(["train", f"mssa:weights={out}"]) == 2
    assert "to train, leave it out" in capsys.readouterr().err


def test_train_keeps_the_skeleton_most_takes_have_not_the_first_one(tmp_path, data_root, capsys):
    takes = tmp_path / "takes"
    takes.mkdir()
    (takes / "a-stray.bvh").write_bytes((data_root / "cmu-daz" / "jump" / "13_11.bvh").read_bytes())  # listed first
    for name in ("02_01", "35_31"):
        (takes / f"{name}.bvh").write_bytes((data_root / "cmu" / "walk" / f"{name}.bvh").read_bytes())
    out = tmp_path / "w"
    assert main(["train", "kalman-learned", "--data", str(takes), "--out", str(out)]) == 0
    assert "the 2 clips of the skeleton most have, leaving out 1 of other skeletons" in capsys.readouterr().err
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["skeleton_signature"] == read_bvh(takes / "02_01.bvh").skeleton.signature()


def test_train_refuses_before_training_what_would_lose_weights(tmp_path, data_root, monkeypatch, capsys):
    from workbench import registry

    takes = tmp_path / "takes"
    takes.mkdir()
    (takes / "a.bvh").write_bytes((data_root / "cmu" / "walk" / "02_01.bvh").read_bytes())
    data = ["--data", str(takes)]
    committed = registry.create("kalman-learned").default_weights_dir() / "cmu"
    before = {p.name: p.read_bytes() for p in committed.iterdir()}
    ebf_committed = registry.create("ebf").default_weights_dir() / "cmu"
    refusals = [
        (["kalman", *data], "engine 'kalman' has nothing to train"),
        (["kalman-learned", "--epochs", "1", *data], "fitted in closed form, not in epochs: leave out --epochs"),
        (["kalman-learned", *data, "--out", str(committed)], "is among the committed weights"),
        (["kalman-learned", *data, "--out", str(ebf_committed), "--overwrite"], "is among the committed weights"),
        (["kalman-learned", *data, "--promote"], "--promote replaces the committed weights of a data set"),
        (["lerp>ebf", "--epochs", "1", *data], "lerp>ebf is a pipeline: train its stages one at a time"),
        ([f"ebf:weights={ebf_committed}", "--epochs", "1", *data], "names weights to clean with"),
        (["workbench.io:read_motion", *data], "'workbench.io:read_motion' is no engine class"),
        (["kalman-learned", *data, "--share", "1e-9"], "--share 1e-09 keeps no clip of the training split"),
    ]
    for args, message in refusals:
        assert main(["train", *args]) == 2
        assert message in capsys.readouterr().err
    assert {p.name: p.read_bytes() for p in committed.iterdir()} == before
    monkeypatch.chdir(tmp_path)
    for folder in ("kalman-learned", "kalman-learned-2"):  # the default folder, numbered where one is there
        assert main(["train", "kalman-learned", *data]) == 0
        assert f"weights=runs/{folder}'" in capsys.readouterr().out
    manifest = (tmp_path / "runs" / "kalman-learned" / "manifest.json").read_bytes()
    assert main(["train", "kalman-learned", *data, "--out", "runs/kalman-learned"]) == 2
    assert "holds weights already: name another folder, or pass --overwrite" in capsys.readouterr().err
    assert (tmp_path / "runs" / "kalman-learned" / "manifest.json").read_bytes() == manifest
    assert main(["train", "kalman-learned", *data, "--out", "runs/kalman-learned", "--overwrite"]) == 0


def test_clean_picks_the_weights_of_the_take_s_skeleton_with_no_flag(tmp_path, data_root):
    """A Bandai take (30 fps, Hips under joint_Root) cleaned by a trained engine uses its
    Bandai weights, and comes back in its own skeleton and rate, the reference node kept."""
    take = data_root / "bandai" / "walk" / "dataset-1_walk_active_001.bvh"
    raw = read_bvh(take)
    out = tmp_path / "clean.bvh"
    assert main(["clean", str(take), "-o", str(out), "--engine", "kalman-learned"]) == 0
    cleaned = read_bvh(out)
    assert cleaned.skeleton.signature() == raw.skeleton.signature() and cleaned.n_frames == raw.n_frames
    assert cleaned.fps == raw.fps and np.allclose(cleaned.channels[:, :6], raw.channels[:, :6])
    assert 0 < np.abs(cleaned.channels - raw.channels).max() < 30


def test_clean_says_which_weights_it_used(tmp_path, data_root, capsys):
    take = data_root / "bandai" / "walk" / "dataset-1_walk_active_001.bvh"
    assert main(["clean", str(take), "-o", str(tmp_path / "a.bvh"), "--engine", "kalman-learned"]) == 0
    line = capsys.readouterr().out
    assert "(skeleton-specific weights " in line and "kalman-learned/bandai)" in line, line


def test_train_pools_the_skeletons_a_universal_variant_maps_and_records_both_terms(tmp_path, data_root, capsys):
    """cae:universal=true trains on the CMU and Bandai train splits together (one tiny
    epoch here); the plain cae keeps the skeleton most of the takes have, and says how to pool."""
    out = tmp_path / "u"
    spec = "cae:universal=true,frames_per_epoch=512,window_frames=64,batch_size=4,pose_copies=0"
    assert main(["train", spec, "--dataset", "cmu,bandai", "--share", "5", "--epochs", "1", "--out", str(out)]) == 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["skeleton_signature"] == "canonical humanoid" and manifest["fps"] == 120.0
    assert [d["name"] for d in manifest["training"]["datasets"]] == ["bandai", "cmu"]
    assert "CC BY-NC" in json.dumps(manifest["training"]["datasets"])
    kick, cleaned = data_root / "cmu-daz" / "kick" / "10_03.bvh", tmp_path / "k.bvh"  # the unseen skeleton
    engine = f"{spec},weights={out}"
    assert main(["clean", str(kick), "-o", str(cleaned), "--engine", engine]) == 0
    assert f"(universal weights {out.resolve()})" in capsys.readouterr().out
    assert read_bvh(cleaned).skeleton.signature() == read_bvh(kick).skeleton.signature()
    mapping = tmp_path / "map.json"
    mapping.write_text('{"left_thigh": null}')
    refused = tmp_path / "no.bvh"
    assert main(["clean", str(kick), "-o", str(refused), "--engine", engine, "--mapping", str(mapping)]) == 2
    assert "left_thigh" in capsys.readouterr().err and not refused.exists()
    plain = "cae:frames_per_epoch=512,window_frames=64,batch_size=4,pose_copies=0"
    plain_out = str(tmp_path / "plain")
    assert main(["train", plain, "--dataset", "cmu,bandai", "--share", "5", "--epochs", "1", "--out", plain_out]) == 0
    assert "`cae:universal=true` trains on several" in capsys.readouterr().err


def test_clean_writes_a_t_pose_frame_0_back_untouched(tmp_path, data_root, capsys):
    from workbench import registry
    from workbench.core.motion import Observation

    src = data_root / "cmu" / "walk" / "02_01.bvh"  # cgspeed: frame 0 is the T-pose
    raw = read_bvh(src)
    out = tmp_path / "clean.bvh"
    assert main(["clean", str(src), "-o", str(out), "--engine", "gaussian"]) == 0
    assert "02_01.bvh is a T-pose reference frame: written back" in capsys.readouterr().err
    cleaned = read_bvh(out)
    assert cleaned.n_frames == raw.n_frames
    assert np.allclose(cleaned.channels[0], raw.channels[0], atol=1e-5)
    alone = registry.create("gaussian").clean(Observation(raw.slice(1))).motion
    assert np.allclose(cleaned.channels[1:], alone.channels, atol=1e-5)  # the T-pose did not leak in
    assert main(["clean", str(src), "-o", str(out), "--engine", "gaussian", "--keep-reference"]) == 0
    assert not np.allclose(read_bvh(out).channels[1], alone.channels[0], atol=1e-3)


def test_clean_a_folder_of_takes_into_another(tmp_path, data_root, capsys):
    takes, out = tmp_path / "takes", tmp_path / "out"
    (takes / "walks").mkdir(parents=True)
    (takes / "walks" / "02_01.bvh").write_bytes((data_root / "cmu" / "walk" / "02_01.bvh").read_bytes())
    (takes / "kick.bvh").write_bytes((data_root / "cmu-daz" / "kick" / "10_04.bvh").read_bytes())
    (takes / "broken.bvh").write_text("HIERARCHY\nROOT Hips\n{\n")
    assert main(["clean", str(takes), "-o", str(out), "--engine", "gaussian"]) == 2  # one take is broken
    err = capsys.readouterr().err
    assert "broken.bvh" in err and "1 of 3 takes failed" in err
    assert sorted(p.relative_to(out).as_posix() for p in out.rglob("*")) == [
        ".workbench-clean.json",
        "kick.bvh",
        "walks",
        "walks/02_01.bvh",
    ]
    assert read_bvh(out / "kick.bvh").skeleton.n_joints == 43
    assert read_bvh(out / "walks" / "02_01.bvh").n_frames == read_bvh(takes / "walks" / "02_01.bvh").n_frames
    assert main(["clean", str(takes), "-o", str(takes), "--engine", "gaussian"]) == 2  # never over the recordings
    assert "name another folder" in capsys.readouterr().err


def test_bench_reports_the_memory_an_engines_cleans_add(walk):
    from workbench.engine import CleanResult, Engine, EngineInfo
    from workbench.evaluate import resident_mb, run_benchmark

    if np.isnan(resident_mb()):
        pytest.skip("resident memory is read from /proc (Linux)")

    class Hungry(Engine):
        info = EngineInfo(name="test-hungry", summary="test: 200 MB of scratch", tasks=frozenset({"denoise"}))

        def clean(self, observation, /):
            scratch = np.ones(200 * 2**20 // 8)  # touched, so resident
            return CleanResult(observation.motion.with_channels(observation.motion.channels + 0 * scratch[0]))

    clip = [("walk", walk.slice(0, 300))]
    summary = run_benchmark([Hungry(), "identity"], "angular:0.5", clip).summary
    assert summary["test-hungry"]["peak_mb"] > 150
    assert summary["identity"]["peak_mb"] < 50  # what the hungry engine freed is not counted again


def test_the_readme_python_api_runs_as_it_stands(tmp_path, monkeypatch, capsys):
    from pathlib import Path

    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text(encoding="utf-8")
    section = readme.split("## Python API", 1)[1]
    code = section.split("```python\n", 1)[1].split("```", 1)[0]
    monkeypatch.chdir(tmp_path)
    exec(compile(code, "README.md", "exec"), {})
    out = capsys.readouterr().out.splitlines()
    assert [line.split(" ")[0] for line in out] == ["lerp>gaussian", "kalman"] and "mpjpe_cm" in out[1]
    assert read_bvh(tmp_path / "cleaned.bvh").n_frames == 421


def test_clean_never_overwrites_its_input_unless_told_and_then_keeps_the_raw_take(tmp_path, data_root, capsys):
    take = tmp_path / "take.bvh"
    take.write_bytes((data_root / "cmu" / "walk" / "02_01.bvh").read_bytes())
    raw = take.read_bytes()
    assert main(["clean", str(take), "-o", str(take), "--engine", "lerp"]) == 2
    assert "is the input take: writing it would overwrite" in capsys.readouterr().err and take.read_bytes() == raw
    assert main(["corrupt", str(take), "-o", str(take), "--corrupt", "angular:0.5"]) == 2
    assert "is the input take" in capsys.readouterr().err and take.read_bytes() == raw
    assert main(["corrupt", str(take), "-o", str(tmp_path / "noisy.bvh"), "--corrupt", "gaps:0.01"]) == 0
    mask = (tmp_path / "noisy.bvh.mask.json").read_bytes()
    assert (
        main(["clean", str(tmp_path / "noisy.bvh"), "-o", str(tmp_path / "noisy.bvh.mask.json"), "--engine", "lerp"])
        == 2
    )
    assert "is the mask of" in capsys.readouterr().err and (tmp_path / "noisy.bvh.mask.json").read_bytes() == mask
    assert main(["clean", str(take), "--engine", "lerp"]) == 2
    assert "-o" in capsys.readouterr().err
    assert main(["clean", str(take), "--in-place", "--engine", "gaussian"]) == 0
    backup = tmp_path / "take.bvh.orig"
    assert backup.read_bytes() == raw and take.read_bytes() != raw
    once = take.read_bytes()
    assert main(["clean", str(take), "--in-place", "--engine", "gaussian"]) == 0
    assert backup.read_bytes() == raw, "a second in-place clean keeps the first backup: the raw take"
    assert take.read_bytes() != once
    assert main(["clean", str(tmp_path), "--in-place", "--engine", "lerp"]) == 2
    broken = tmp_path / "broken.bvh"
    broken.write_bytes(raw[: len(raw) // 2])
    assert main(["clean", str(broken), "--in-place", "--engine", "gaussian"]) == 2
    assert not (tmp_path / "broken.bvh.orig").exists(), "a failed in-place clean leaves no backup to mislead the next"
    other = (data_root / "cmu" / "walk" / "02_02.bvh").read_bytes()  # another raw take copied over the cleaned one
    alike = raw.replace(b"-", b"+", 1)  # and one of the same skeleton and length
    for new in (other, alike):
        take.write_bytes(new)
        assert main(["clean", str(take), "--in-place", "--engine", "gaussian"]) == 2
        assert "is not the take its last in-place clean wrote" in capsys.readouterr().err and take.read_bytes() == new


def test_corrupt_names_the_file_frame_of_a_missing_value(tmp_path, data_root, capsys):
    lines = (data_root / "cmu" / "walk" / "02_01.bvh").read_text().splitlines()  # frame 0 a T-pose, dropped
    frame_12 = next(n for n, line in enumerate(lines) if line.startswith("Frame Time")) + 13
    lines[frame_12] = "nan " + lines[frame_12].split(" ", 1)[1]
    (tmp_path / "gappy.bvh").write_text("\n".join(lines) + "\n")
    assert main(["corrupt", str(tmp_path / "gappy.bvh"), "-o", str(tmp_path / "x.bvh"), "--corrupt", "angular:1"]) == 2
    assert "gappy.bvh has missing values (NaN) in 1 frame(s), first in frame 12 of the file" in capsys.readouterr().err
    assert not (tmp_path / "x.bvh").exists()


def test_an_in_place_clean_moves_the_mask_it_filled_to_the_raw_take(tmp_path, data_root, capsys):
    clean = tmp_path / "clean.bvh"
    clean.write_bytes((data_root / "cmu" / "walk" / "02_01.bvh").read_bytes())
    take = tmp_path / "take.bvh"
    assert main(["corrupt", str(clean), "-o", str(take), "--corrupt", "gaps:0.01"]) == 0
    mask = (tmp_path / "take.bvh.mask.json").read_bytes()
    assert main(["clean", str(take), "--in-place", "--engine", "lerp", "--resume"]) == 0
    err = capsys.readouterr().err
    assert "--resume: for a folder of takes" in err and "the mask moved with the raw take" in err
    assert not (tmp_path / "take.bvh.mask.json").exists(), "it would mark the filled samples missing"
    assert (tmp_path / "take.bvh.orig.mask.json").read_bytes() == mask
    (tmp_path / "take.bvh.mask.json").write_bytes(mask)  # a mask put back beside the cleaned take stays, with a note
    assert main(["clean", str(take), "--in-place", "--engine", "lerp"]) == 0
    assert "names the gaps this clean filled" in capsys.readouterr().err
    assert (tmp_path / "take.bvh.mask.json").exists() and (tmp_path / "take.bvh.orig.mask.json").read_bytes() == mask


def test_a_pipeline_says_which_weights_its_stages_used(tmp_path, data_root, capsys):
    take = data_root / "cmu" / "walk" / "02_01.bvh"
    assert main(["clean", str(take), "-o", str(tmp_path / "a.bvh"), "--engine", "ebd>ebf"]) == 0
    line = capsys.readouterr().out
    assert "(skeleton-specific weights ebd " in line and ", ebf " in line and line.count("/cmu") == 2, line


def test_json_written_for_other_tools_holds_no_nan():
    from workbench.cli import _strict_json

    def refuse(name):
        raise ValueError(f"{name} is not JSON")

    text = _strict_json({"gap_mpjpe_cm": float("nan"), "rows": [np.float32(1.5), np.int64(2), -np.inf]})
    assert json.loads(text, parse_constant=refuse) == {"gap_mpjpe_cm": None, "rows": [1.5, 2, None]}


@pytest.mark.usefixtures("data_root")
def test_bench_names_what_stops_it_before_it_runs(capsys):
    assert main(["bench", "--engines", "kalman,lerp,kalman", "--corrupt", "angular:0.5", "--seeds", "1"]) == 2
    assert "kalman named twice: name each engine once" in capsys.readouterr().err
    assert main(["bench", "--engines", "kalman", "--corrupt", "angular:0.5", "--clips", "cmu/walk/02_01"]) == 2
    assert "the 1 that match are in train: --split NAME or all" in capsys.readouterr().err


def test_a_take_s_unit_can_be_given_where_its_rest_pose_guesses_wrong(tmp_path, walk, capsys):
    """A short character in metres reads as centimetres (no unit makes it 120-220 cm):
    --unit says what the file's lengths are, for skeleton, inspect, corrupt and clean."""
    from workbench.io import read_bvh, write_bvh

    take = tmp_path / "walk.bvh"
    write_bvh(take, walk.slice(1, 100))
    assert main(["skeleton", str(take)]) == 0
    assert "unit: 5.64 cm; up" in capsys.readouterr().out
    assert main(["skeleton", str(take), "--unit", "m"]) == 0
    assert "unit: 100 cm (--unit); up" in capsys.readouterr().out
    giant = tmp_path / "giant.bvh"  # 300 units tall: no unit makes it a body
    giant.write_text(chain_bvh(2, bone=150.0))
    main(["skeleton", str(giant)])  # (refused as a humanoid, after its unit)
    assert "unit: 1 cm (no unit makes the rest pose 120-220 cm tall: cm is a guess; --unit says it)" in (
        capsys.readouterr().out
    )
    assert main(["inspect", str(take), "--unit", "2.5"]) == 0
    capsys.readouterr()
    with pytest.raises(SystemExit):
        main(["skeleton", str(take), "--unit", "furlong"])
    assert "want mm, cm, m, in, cmu or the unit's size in cm (1e-4 to 1e4), got 'furlong'" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["skeleton", str(take), "--unit", "1e308"])
    assert "(1e-4 to 1e4), got '1e308'" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["skeleton", str(take), "--unit", "1e-5"])
    assert "(1e-4 to 1e4), got '1e-5'" in capsys.readouterr().err
    assert main(["corrupt", str(take), "-o", str(tmp_path / "n.bvh"), "--corrupt", "spatial:1", "--unit", "cm"]) == 0
    by_cm = read_bvh(tmp_path / "n.bvh").channels
    assert main(["corrupt", str(take), "-o", str(tmp_path / "n.bvh"), "--corrupt", "spatial:1"]) == 0
    assert not np.allclose(read_bvh(tmp_path / "n.bvh").channels, by_cm)  # 1 cm of noise is 1 unit, or 1/5.64
    folder = tmp_path / "takes"
    folder.mkdir()
    take.rename(folder / "walk.bvh")
    argv = ["clean", str(folder), "-o", str(tmp_path / "out"), "--engine", "kalman", "--workers", "1"]
    assert main([*argv, "--unit", "cm"]) == 0
    assert main([*argv, "--resume"]) == 2  # a folder cleaned with another unit
    assert "--unit 1, not --engine 'kalman'" in capsys.readouterr().err
    assert main([*argv, "--unit", "cm", "--resume"]) == 0


def test_bench_and_train_read_a_folder_of_takes_in_the_unit_given(tmp_path, walk, capsys, monkeypatch):
    """--unit with --data: every clip is read in that unit, so lerp's gap error in cm grows
    with the unit's size; train loads its clips in it too."""
    folder = tmp_path / "takes"
    folder.mkdir()
    write_bvh(folder / "walk.bvh", walk.slice(1, 300))
    errors = {}
    for unit in ("cm", "10"):
        out = tmp_path / f"bench-{unit}.json"
        argv = ["bench", "--data", str(folder), "--split", "all", "--engines", "lerp", "--corrupt", "block:30"]
        assert main([*argv, "--seeds", "1", "--unit", unit, "--json", str(out)]) == 0
        errors[unit] = json.loads(out.read_text())["summary"]["lerp"]["gap_mpjpe_cm"]
    assert errors["10"] == pytest.approx(10 * errors["cm"])
    units = []

    def units_then_stop(self, motions):  # the clips train loads, then no training
        units.extend(m.skeleton.unit_cm for m in motions)
        raise KeyboardInterrupt

    monkeypatch.setattr("workbench.engine.Engine.training_motions", units_then_stop)
    assert main(["train", "kalman-learned", "--data", str(folder), "--unit", "in", "--out", str(tmp_path / "w")]) == 130
    assert units == [2.54]


@pytest.mark.parametrize(
    "argv",
    [
        ["train", "kalman-learned", "--out", ""],
        ["bench", "--engines", "lerp", "--corrupt", "gaps:0.01", "--clips", " "],
        ["bench", "--engines", "lerp", "--corrupt", "gaps:0.01", "--json", ""],
        ["clean", "take.bvh", "-o", "", "--engine", "lerp"],
        ["data", "--data", ""],
    ],
)
def test_an_empty_option_value_is_refused_not_read_as_its_default(argv, capsys):
    """An unset shell variable ("--out $OUT") would otherwise write into the current
    folder, or filter nothing."""
    with pytest.raises(SystemExit) as stop:
        main(argv)
    assert stop.value.code == 2 and "empty: give a value, or leave the option out" in capsys.readouterr().err


def test_an_empty_corruption_or_a_mapping_that_does_not_fit_the_take_stops_the_command(tmp_path, data_root, capsys):
    src = data_root / "cmu" / "walk" / "02_01.bvh"
    with pytest.raises(SystemExit) as stop:  # an empty shell variable: the clean take scored, every error 0
        main(["bench", "--data", str(src.parent), "--engines", "lerp", "--corrupt", " "])
    assert stop.value.code == 2 and "--corrupt: empty: give a spec such as" in capsys.readouterr().err
    mapping = tmp_path / "mapping.json"
    mapping.write_text('{"neck": "NoSuchJoint"}')
    out = tmp_path / "out.bvh"
    for engine in ("lerp", "gaussian>kalman"):  # engines that never map the take check the file all the same
        assert main(["clean", str(src), "-o", str(out), "--engine", engine, "--mapping", str(mapping)]) == 2
        assert "neck = 'NoSuchJoint', but the take has no joint 'NoSuchJoint'" in capsys.readouterr().err
        assert not out.exists()
