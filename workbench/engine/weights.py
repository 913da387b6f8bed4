"""Fitted state on disk: ``weights.npz`` (plain arrays, never pickled) plus
``manifest.json`` holding its sha256 and whatever the engine needs to rebuild itself
(parameters, skeleton, training data, metrics, code version and git commit), and a
digest of its own content.

Torch engines store their state_dict as arrays too, so loading never unpickles a file
a user hands us; a weights file whose checksum does not match, or a manifest edited
after it was saved, is refused.
"""

from __future__ import annotations

import hashlib
import json
import subprocess
import time
import zipfile
from pathlib import Path
from typing import Mapping

import numpy as np

from ..io.atomic import atomic_path, atomic_write_text
from .base import EngineError

__all__ = [
    "WEIGHTS_FILE",
    "MANIFEST_FILE",
    "FORMAT_VERSION",
    "sha256_file",
    "manifest_digest",
    "signed",
    "code_commit",
    "save_weights",
    "load_weights",
]

WEIGHTS_FILE = "weights.npz"
MANIFEST_FILE = "manifest.json"
#: the manifest's layout: 3 adds ``manifest_sha256``; 2 records the variant, each
#: parameter under its current name only, the training's data sets and their terms, and
#: ``test_scores`` (1 had them as ``validation``)
FORMAT_VERSION = 3
#: the manifest's entry holding :func:`manifest_digest` of the rest
DIGEST_KEY = "manifest_sha256"


def sha256_file(path: Path) -> str:
    """The SHA-256 digest of a file's bytes, read in blocks of 1 MiB.

    Parameters
    ----------
    path : Path or str
        The file.

    Returns
    -------
    str
        The digest as 64 lowercase hexadecimal digits.

    Raises
    ------
    OSError
        The file cannot be read.
    """
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def manifest_digest(manifest: Mapping) -> str:
    """The SHA-256 of a manifest's entries other than :data:`DIGEST_KEY`, as canonical JSON
    (keys sorted, no spaces): what an edit of any entry changes."""
    rest = {k: v for k, v in manifest.items() if k != DIGEST_KEY}
    text = json.dumps(rest, sort_keys=True, separators=(",", ":"), allow_nan=True)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def signed(manifest: Mapping) -> dict:
    """``manifest`` with its :data:`DIGEST_KEY` entry set to :func:`manifest_digest`."""
    return {**manifest, DIGEST_KEY: manifest_digest(manifest)}


def code_commit() -> str | None:
    """The git commit of this checkout, so a manifest says which code trained its weights.

    Returns
    -------
    str or None
        The commit's full hash, with "+dirty" when tracked files differ from it; None
        outside a git checkout (or without git, or when git takes over 10 s).
    """
    root = Path(__file__).resolve().parents[2]

    def git(*args: str) -> str:
        return subprocess.run(
            ["git", "-C", str(root), *args], capture_output=True, text=True, check=True, timeout=10
        ).stdout.strip()

    try:
        commit = git("rev-parse", "HEAD")
        dirty = bool(git("status", "--porcelain", "--untracked-files=no"))
    except (OSError, subprocess.SubprocessError):
        return None
    return commit + ("+dirty" if dirty else "")


def save_weights(folder: str | Path, arrays: Mapping[str, np.ndarray], manifest: Mapping) -> Path:
    """Write arrays and manifest atomically into ``folder``.

    Each file is written atomically (:func:`workbench.io.atomic.atomic_path`), and the
    weights replace the old ones only once their manifest is ready: ``weights.npz`` by
    ``np.savez`` (plain arrays, never pickled), then ``manifest.json`` with ``manifest``
    and the entries this function adds, which
    override any of the same name: ``format_version`` (:data:`FORMAT_VERSION`),
    ``file``, ``sha256`` (of the weights file), ``code_version``, ``code_commit``
    (:func:`code_commit`), ``saved_utc`` and, last, ``manifest_sha256``
    (:func:`manifest_digest`).

    Parameters
    ----------
    folder : str or Path
        Created if missing; its ``weights.npz`` and ``manifest.json`` are replaced.
    arrays : Mapping[str, ndarray]
        Named numeric arrays (object arrays could only be read back by unpickling, which
        :func:`load_weights` refuses).
    manifest : Mapping
        JSON values: whatever the engine needs to rebuild itself.

    Returns
    -------
    Path
        The manifest's path, ``folder / "manifest.json"``.

    Raises
    ------
    EngineError
        Arrays that hold NaN or infinite values (a training that diverged, or had no
        data), before any file is written.
    TypeError
        A manifest value that is not JSON serialisable.
    OSError
        The folder or its files cannot be written.
    """
    from .. import __version__

    if not isinstance(arrays, Mapping):
        raise EngineError(f"the trained weights are a {type(arrays).__name__}: state_arrays gives a dict of arrays")
    arrays = {k: np.asarray(v) for k, v in arrays.items()}
    _refuse_non_finite(arrays, "the trained weights", "the engine's state_arrays gives arrays of numbers only")
    folder = Path(folder)
    with atomic_path(folder / WEIGHTS_FILE) as tmp:  # (it makes the folder)
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)
        full = {
            **manifest,
            "format_version": FORMAT_VERSION,
            "file": WEIGHTS_FILE,
            "sha256": sha256_file(tmp),
            "code_version": __version__,
            "code_commit": code_commit(),
            "saved_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        }
        text = json.dumps(signed(full), indent=2, sort_keys=True) + "\n"  # a value JSON cannot hold fails here, first
    atomic_write_text(folder / MANIFEST_FILE, text)
    return folder / MANIFEST_FILE


def load_weights(folder: str | Path) -> tuple[dict[str, np.ndarray], dict]:
    """Read and verify weights saved by :func:`save_weights`.

    The manifest must match its own digest and the weights file the checksum the manifest
    records; the weights are read without unpickling anything.

    Parameters
    ----------
    folder : str or Path
        The folder holding ``manifest.json`` and the weights file it names.

    Returns
    -------
    arrays : dict of str to ndarray
        The named arrays.
    manifest : dict
        The manifest as saved, with the entries :func:`save_weights` added.

    Raises
    ------
    EngineError
        With a message naming the file and what is wrong, for a missing, corrupt or
        tampered file: no manifest, an unreadable (a truncated) one, one of an older or
        a newer :data:`FORMAT_VERSION`, one edited after it was saved, a weights file
        named by a path out of the folder, a missing weights file, a checksum that does
        not match (a truncated or changed file), unreadable weights, or weights that
        hold NaN or infinite values.
    """
    folder = Path(folder)
    manifest_path = folder / MANIFEST_FILE
    if folder.is_file():
        raise EngineError(f"{folder}: a file; weights are a folder (the one holding {MANIFEST_FILE}): name that")
    try:
        manifest = json.loads(manifest_path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise EngineError(f"{manifest_path}: no weights manifest here; train the engine first") from None
    except (OSError, ValueError) as err:
        raise EngineError(f"{manifest_path}: unreadable weights manifest ({_reason(err)})") from None
    if not isinstance(manifest, dict) or not isinstance(manifest.get("skeleton_signature"), str):
        raise EngineError(f"{manifest_path}: not a weights manifest (an object with the skeleton it was trained for)")
    version = manifest.get("format_version", 1)
    if version != FORMAT_VERSION:
        if isinstance(version, int) and version > FORMAT_VERSION:
            remedy = "they were saved by a newer workbench: update it to use them"
        else:
            remedy = "retrain the engine (`workbench train SPEC --out FOLDER`)"
        raise EngineError(
            f"{manifest_path}: weights of manifest format {version}, and this workbench reads format "
            f"{FORMAT_VERSION}; {remedy}"
        )
    if manifest.get(DIGEST_KEY) != manifest_digest(manifest):
        raise EngineError(
            f"{manifest_path}: the manifest was changed after it was saved (its {DIGEST_KEY} does not match "
            "its content); restore it or retrain the engine"
        )
    name = manifest.get("file", WEIGHTS_FILE)
    if not isinstance(name, str) or Path(name).name != name or name in ("", ".", ".."):
        raise EngineError(
            f"{manifest_path}: the weights file must be named by a plain file name in the manifest's "
            f"folder, not {name!r}; retrain the engine or restore the manifest"
        )
    path = folder / name
    if not path.exists():
        raise EngineError(f"{path}: the weights file named by the manifest is missing")
    try:
        digest = sha256_file(path)
    except OSError as err:
        raise EngineError(f"{path}: unreadable weights file ({_reason(err)})") from None
    if digest != manifest.get("sha256"):
        raise EngineError(
            f"{path}: checksum does not match its manifest; the file is corrupt or was changed. "
            "Retrain the engine or restore the file."
        )
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
        if not_arrays := [k for k, a in arrays.items() if not isinstance(a, np.ndarray)]:
            raise ValueError(f"its member {not_arrays[0]!r} is no array")
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as err:
        # np.load's refusals of pickles say to allow them: the wrong advice for weights
        if "allow_pickle" not in str(err):
            reason = _reason(err)
        elif zipfile.is_zipfile(path):
            reason = "it holds objects that only unpickling would read, and weights are never unpickled"
        else:
            reason = "not a .npz archive of arrays"
        raise EngineError(f"{path}: unreadable weights ({reason}); retrain the engine or restore the file") from None
    _refuse_non_finite(arrays, str(path))
    return arrays, manifest


def _reason(err: BaseException) -> str:
    """Why a file could not be read, in words: a permission or a folder named as the file
    by name, else the error's own text (its type where it has none)."""
    if isinstance(err, PermissionError):
        return "no permission to read it: check its owner and mode"
    if isinstance(err, IsADirectoryError):
        return "a folder where a file should be"
    return str(err) or type(err).__name__


def _refuse_non_finite(
    arrays: Mapping[str, np.ndarray], what: str, remedy: str = "they are damaged or not this project's; train again"
) -> None:
    """Raise EngineError where an array holds other than real numbers (text, complex
    numbers, objects; the message ends with ``remedy``) or NaN or infinite values: such
    weights would clean every take into NaN, or fail with a message about something else."""
    other = [f"{k} ({a.dtype})" for k, a in arrays.items() if a.dtype.kind not in "biuf"]
    if other:
        raise EngineError(
            f"{what}: the weights hold arrays of other than real numbers ({', '.join(other[:3])}): {remedy}"
        )
    broken = [k for k, a in arrays.items() if a.dtype.kind == "f" and not np.isfinite(a).all()]
    if broken:
        raise EngineError(
            f"{what}: the weights hold NaN or infinite values (in {', '.join(broken[:3])}): the training "
            "diverged or had no data; train the engine again on clean takes"
        )
