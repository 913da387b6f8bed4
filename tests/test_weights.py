"""Weights on disk (workbench.engine.weights): the round trip, the manifest's provenance, and a
clear refusal of every kind of bad file, never an unpickled one."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from workbench.engine import EngineError, weights
from workbench.engine.weights import MANIFEST_FILE, WEIGHTS_FILE, code_commit, load_weights, save_weights


@pytest.fixture
def saved(tmp_path):
    save_weights(
        tmp_path, {"w": np.arange(6.0).reshape(2, 3)}, {"engine": "demo", "params": {"k": 1}, "skeleton_signature": "x"}
    )
    return tmp_path


def test_round_trip_and_provenance(saved):
    arrays, manifest = load_weights(saved)
    assert np.array_equal(arrays["w"], np.arange(6.0).reshape(2, 3))
    assert manifest["engine"] == "demo" and manifest["params"] == {"k": 1}
    assert manifest["file"] == WEIGHTS_FILE and len(manifest["sha256"]) == 64
    head = subprocess.run(
        ["git", "rev-parse", "HEAD"], capture_output=True, text=True, cwd=Path(weights.__file__).resolve().parents[2]
    )
    if head.returncode == 0:  # a git checkout, as in CI
        assert manifest["code_commit"].split("+")[0] == head.stdout.strip()


def test_no_commit_outside_a_git_checkout(monkeypatch):
    def no_git(*args, **kwargs):
        raise FileNotFoundError("git")

    monkeypatch.setattr(subprocess, "run", no_git)
    assert code_commit() is None


def test_a_changed_weights_file_is_refused(saved):
    with np.load(saved / WEIGHTS_FILE) as data:
        w = data["w"]
    np.savez(saved / WEIGHTS_FILE, w=w + 1.0)
    with pytest.raises(EngineError, match="checksum does not match"):
        load_weights(saved)


def test_missing_or_malformed_files_are_refused(saved, tmp_path_factory):
    with pytest.raises(EngineError, match="no weights manifest"):
        load_weights(tmp_path_factory.mktemp("empty"))
    (saved / WEIGHTS_FILE).rename(saved / "moved.npz")
    with pytest.raises(EngineError, match="weights file named by the manifest is missing"):
        load_weights(saved)
    (saved / MANIFEST_FILE).write_text("{not json", encoding="utf-8")
    with pytest.raises(EngineError, match="unreadable weights manifest"):
        load_weights(saved)


def test_pickled_arrays_are_never_unpickled(saved):
    np.savez(saved / WEIGHTS_FILE, w=np.array([{"payload": 1}], dtype=object))
    manifest = json.loads((saved / MANIFEST_FILE).read_text(encoding="utf-8"))
    manifest["sha256"] = weights.sha256_file(saved / WEIGHTS_FILE)  # a matching checksum
    (saved / MANIFEST_FILE).write_text(json.dumps(weights.signed(manifest)), encoding="utf-8")
    with pytest.raises(EngineError, match="unreadable weights .it holds objects that only unpickling would read"):
        load_weights(saved)


def _resigned(folder: Path) -> None:
    """The manifest in ``folder`` made to match its weights file again (checksum, digest)."""
    manifest = json.loads((folder / MANIFEST_FILE).read_text(encoding="utf-8"))
    manifest["sha256"] = weights.sha256_file(folder / WEIGHTS_FILE)
    (folder / MANIFEST_FILE).write_text(json.dumps(weights.signed(manifest)), encoding="utf-8")


def test_bytes_that_are_no_archive_are_refused_without_advice_to_unpickle(saved):
    (saved / WEIGHTS_FILE).write_bytes(b"hello")
    _resigned(saved)
    with pytest.raises(EngineError, match=r"not a .npz archive of arrays\); retrain the engine or restore") as info:
        load_weights(saved)
    assert "pickle" not in str(info.value)


def test_a_weights_file_that_cannot_be_read_or_a_file_named_as_the_folder_is_refused(saved):
    (saved / WEIGHTS_FILE).unlink()
    (saved / WEIGHTS_FILE).mkdir()  # a folder where the file should be
    with pytest.raises(EngineError, match="unreadable weights file .a folder where a file should be"):
        load_weights(saved)
    with pytest.raises(EngineError, match="a file; weights are a folder .the one holding manifest.json.: name that"):
        load_weights(saved / MANIFEST_FILE)


def test_a_manifest_that_cannot_be_written_leaves_the_old_weights_as_they_were(saved):
    before = {name: (saved / name).read_bytes() for name in (WEIGHTS_FILE, MANIFEST_FILE)}
    with pytest.raises(TypeError):
        save_weights(saved, {"w": np.zeros(3)}, {"engine": "demo", "skeleton_signature": "x", "bad": object()})
    assert {name: (saved / name).read_bytes() for name in before} == before
    load_weights(saved)  # still a matching pair


def test_a_manifest_that_is_not_one_is_refused_by_name(tmp_path):
    save_weights(tmp_path, {"w": np.zeros(3)}, {"engine": "demo", "skeleton_signature": "x"})
    (tmp_path / MANIFEST_FILE).write_text("[1, 2]")
    with pytest.raises(EngineError, match="not a weights manifest"):
        load_weights(tmp_path)
    save_weights(tmp_path, {"w": np.zeros(3)}, {"engine": "demo"})
    with pytest.raises(EngineError, match="not a weights manifest"):
        load_weights(tmp_path)


def test_weights_that_do_not_say_their_frame_rate_are_refused(tmp_path):
    import shutil

    from workbench import registry

    folder = tmp_path / "w"
    shutil.copytree(registry.create("mssa").default_weights_dir() / "cmu", folder)
    manifest = json.loads((folder / "manifest.json").read_text())
    del manifest["fps"]
    (folder / "manifest.json").write_text(json.dumps(weights.signed(manifest)))
    with pytest.raises(EngineError, match="does not say the frame rate they were trained at; retrain them"):
        registry.create(f"mssa:weights={folder}")


@pytest.mark.parametrize("name", ["../weights.npz", "/etc/passwd", "sub/weights.npz", "", 7])
def test_a_manifest_cannot_name_a_file_out_of_its_folder(tmp_path, name):
    """A weights file elsewhere, with the checksum the manifest holds, is still refused."""
    folder = tmp_path / "weights"
    save_weights(folder, {"w": np.zeros(3)}, {"engine": "demo", "skeleton_signature": "x"})
    (tmp_path / WEIGHTS_FILE).write_bytes((folder / WEIGHTS_FILE).read_bytes())  # ../weights.npz
    manifest = json.loads((folder / MANIFEST_FILE).read_text(encoding="utf-8"))
    manifest["file"] = name
    (folder / MANIFEST_FILE).write_text(json.dumps(weights.signed(manifest)), encoding="utf-8")
    with pytest.raises(EngineError, match="plain file name in the manifest's folder"):
        load_weights(folder)


def test_a_truncated_weights_file_or_manifest_is_refused_by_name(saved):
    data = (saved / WEIGHTS_FILE).read_bytes()
    (saved / WEIGHTS_FILE).write_bytes(data[: len(data) // 2])
    with pytest.raises(EngineError, match=f"{saved / WEIGHTS_FILE}: checksum does not match"):
        load_weights(saved)
    (saved / WEIGHTS_FILE).write_bytes(data)
    text = (saved / MANIFEST_FILE).read_text(encoding="utf-8")
    (saved / MANIFEST_FILE).write_text(text[: len(text) // 2], encoding="utf-8")
    with pytest.raises(EngineError, match=f"{saved / MANIFEST_FILE}: unreadable weights manifest"):
        load_weights(saved)


@pytest.mark.parametrize(
    "edit",
    [
        lambda m: m["params"].update(k=2),  # another parameter value
        lambda m: m.update(skeleton_signature="y"),  # weights passed off for another skeleton
        lambda m: m.update(sha256="0" * 64),
        lambda m: m.pop("manifest_sha256"),
    ],
)
def test_a_manifest_edited_after_it_was_saved_is_refused(saved, edit):
    manifest = json.loads((saved / MANIFEST_FILE).read_text(encoding="utf-8"))
    edit(manifest)
    (saved / MANIFEST_FILE).write_text(json.dumps(manifest), encoding="utf-8")
    with pytest.raises(EngineError, match=f"{saved / MANIFEST_FILE}: the manifest was changed after it was saved"):
        load_weights(saved)


@pytest.mark.parametrize(
    ("version", "remedy"), [(weights.FORMAT_VERSION + 1, "saved by a newer workbench: update it"), (1, "retrain")]
)
def test_a_manifest_of_another_format_version_is_refused_with_what_to_do(saved, version, remedy):
    manifest = json.loads((saved / MANIFEST_FILE).read_text(encoding="utf-8"))
    manifest["format_version"] = version
    (saved / MANIFEST_FILE).write_text(json.dumps(weights.signed(manifest)), encoding="utf-8")
    with pytest.raises(EngineError, match=f"manifest format {version}, and this workbench reads format 3; .*{remedy}"):
        load_weights(saved)


def test_weights_swapped_for_another_engines_are_refused(tmp_path):
    """Each trained engine's committed weights, copied into another's folder whole."""
    import shutil

    from workbench import registry

    folder = tmp_path / "w"
    shutil.copytree(registry.create("kalman-learned").default_weights_dir() / "cmu", folder)
    for spec in ("mssa", "cae", "ebf"):
        with pytest.raises(EngineError, match=f"these weights are for engine 'kalman-learned', not '{spec}'"):
            registry.create(f"{spec}:weights={folder}")


def test_a_signed_manifest_with_a_parameter_of_the_wrong_kind_is_refused(tmp_path):
    import shutil

    from workbench import registry

    folder = tmp_path / "w"
    shutil.copytree(registry.create("ebf").default_weights_dir() / "cmu", folder)
    manifest = json.loads((folder / MANIFEST_FILE).read_text(encoding="utf-8"))
    manifest["params"]["lstm_units"] = "many"
    (folder / MANIFEST_FILE).write_text(json.dumps(weights.signed(manifest)), encoding="utf-8")
    with pytest.raises(EngineError, match=r"parameters of the wrong kind \(lstm_units='many'\)"):
        registry.create(f"ebf:weights={folder}")


def test_no_code_of_the_package_can_unpickle_a_file():
    """The one loader of arrays is load_weights, with allow_pickle=False; nothing calls
    torch.load, pickle or np.load otherwise (a source scan, so a new call site fails here)."""
    import re

    root = Path(weights.__file__).resolve().parents[2]
    calls = re.compile(r"\b(torch\.load|pickle\.loads?|cPickle|dill|joblib\.load|np\.load|numpy\.load)\s*\(")
    found = {
        f"{path.relative_to(root)}: {line.strip()}"
        for folder in ("workbench", "engines")
        for path in (root / folder).rglob("*.py")
        for line in path.read_text(encoding="utf-8").splitlines()
        if calls.search(line)
    }
    assert found == {"workbench/engine/weights.py: with np.load(path, allow_pickle=False) as data:"}


def test_weights_with_nan_are_never_saved_nor_loaded_and_an_empty_file_is_refused(saved, tmp_path_factory):
    empty = tmp_path_factory.mktemp("nan")
    manifest = {"engine": "demo", "skeleton_signature": "x"}
    with pytest.raises(EngineError, match="state_arrays gives arrays of numbers only"):  # a plugin's mistakes
        save_weights(empty, {"w": np.zeros(2), "name": "text"}, manifest)
    with pytest.raises(EngineError, match="are a list: state_arrays gives a dict of arrays"):
        save_weights(empty, [np.zeros(2)], manifest)
    with pytest.raises(EngineError, match="NaN or infinite values"):
        save_weights(empty, {"w": np.array([1.0, np.nan])}, {"engine": "demo", "skeleton_signature": "x"})
    assert not any(empty.iterdir())
    folder = tmp_path_factory.mktemp("bad_files")
    np.savez(folder / "nan.npz", w=np.array([np.inf]))
    np.savez(folder / "text.npz", w=np.array(["1"]))
    np.savez(folder / "complex.npz", w=np.array([1j]))
    files = [(b"", "unreadable weights"), ((folder / "nan.npz").read_bytes(), "NaN or infinite")]
    files += [
        ((folder / f"{k}.npz").read_bytes(), rf"other than real numbers \(w \({t}")
        for k, t in (("text", "<U1"), ("complex", "complex"))
    ]
    for content, needle in files:
        (saved / WEIGHTS_FILE).write_bytes(content)  # re-signed: passes the checksums
        manifest = json.loads((saved / MANIFEST_FILE).read_text(encoding="utf-8"))
        manifest["sha256"] = weights.sha256_file(saved / WEIGHTS_FILE)
        (saved / MANIFEST_FILE).write_text(json.dumps(weights.signed(manifest)), encoding="utf-8")
        with pytest.raises(EngineError, match=needle):
            load_weights(saved)
