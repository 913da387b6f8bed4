"""The clip catalogue: every clip under a data root, with its category, subject and split.

A dataset folder with a ``MANIFEST.csv`` (columns file, category, subject, trial, ...)
is read from it; any other folder of BVH or AMC files is catalogued by walking it
(linked folders followed), the category being the parent folder's name. Clip ids are ``dataset/relative/path`` without
the suffix, e.g. ``cmu/walk/02_01``.

Reference frames: the cgspeed conversions put a T-pose (rest) frame in frame 0 that was
never captured. :meth:`Clip.load` drops it when frame 0 looks like one: the body root's
rotation is exactly zero and its joint angles are on average less than half of
frame 1's (of the first later frame with any angle observed, missing ones left out).
``Clip.load(keep_reference=True)`` keeps every frame.

Splits: ``workbench/data/splits/<dataset>.json`` lists the test clips of a dataset
(whole subjects held out); every other clip of that dataset is training data. Clips of
datasets without a split file are in neither (split ``""``), so they are never trained on
by accident.
"""

from __future__ import annotations

import csv
import dataclasses
import fnmatch
import hashlib
import json
import math
from collections import Counter
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..core.motion import Motion, angle_joints
from ..errors import NameNotFoundError
from ..io import MOTION_SUFFIXES, read_motion
from .roots import DataNotFoundError, files_under, find_data_root

SPLITS_DIR = Path(__file__).resolve().parent / "splits"
#: the terms of the team's data sets (their READMEs); weights trained on one inherit them
DATASET_TERMS = {
    "cmu": "CMU Graphics Lab Motion Capture Database terms: free for research and commercial use, the raw data "
    "not for resale; credit mocap.cs.cmu.edu (NSF EIA-0196217)",
    "cmu-daz": "CMU Graphics Lab Motion Capture Database terms (a conversion of CMU takes): free for research and "
    "commercial use, the raw data not for resale; credit mocap.cs.cmu.edu (NSF EIA-0196217)",
    "bandai": "CC BY-NC 4.0, non-commercial: Bandai-Namco-Research-Motiondataset, Bandai Namco Research Inc.",
}


def dataset_terms(dataset: str) -> str:
    """The licence of a data set by name; for one the team does not know, a line saying
    so (a user's own data: its terms are the user's)."""
    return DATASET_TERMS.get(dataset, "unknown: the terms of this data set are its owner's")


#: the splits a clip can be in, in listing order ("" for a dataset without a split file)
SPLITS = ("train", "validation", "test")


@dataclass(frozen=True)
class Clip:
    """One take in the catalogue. ``split`` is one of :data:`SPLITS` or ""; ``style`` the
    performance style of a set that records one (Bandai's happy, old, ...), else "";
    ``frames`` counts the file's frames (reference frame included) when known, else 0;
    ``unit_cm`` the size of the file's length unit in cm where the user gave it (``--unit``),
    else None: guessed from the rest pose (:func:`workbench.io.read_motion`)."""

    id: str
    path: Path
    dataset: str
    category: str
    subject: str
    split: str
    frames: int = 0
    fps: float = 0.0
    style: str = ""
    unit_cm: float | None = None

    def load(self, keep_reference: bool = False) -> Motion:
        motion = read_motion(self.path, self.unit_cm)
        return (motion if keep_reference else without_reference_frame(motion)).replace(name=self.id)


def has_reference_frame(motion: Motion) -> bool:
    """True when frame 0 is a rest/T-pose frame added by a converter (see module doc)."""
    a, body = motion.angles_deg, angle_joints(motion.skeleton)
    if motion.n_frames < 3 or not len(body):  # (a lone root has no body pose to tell by)
        return False
    if not np.all(a[0, motion.skeleton.body_root] == 0.0):
        return False
    for frame in range(1, motion.n_frames):  # the first with an angle observed: missing ones (NaN) tell nothing
        later = np.abs(a[frame, body])
        if np.isfinite(later).any():
            return bool(np.nanmean(np.abs(a[0, body])) < 0.5 * np.nanmean(later))
    return True  # nothing after it: frame 0 is all there is, and not motion


def without_reference_frame(motion: Motion) -> Motion:
    """``motion`` without its frame 0 when that is a T-pose reference frame, else as it is."""
    return motion.slice(1) if has_reference_frame(motion) else motion


@lru_cache(maxsize=None)
def load_split(dataset: str) -> dict:
    path = SPLITS_DIR / f"{dataset}.json"
    if not path.exists():
        return {}
    return json.loads(path.read_text(encoding="utf-8"))


def _split_of(dataset: str, clip_file: str) -> str:
    split = load_split(dataset)
    if not split:
        return ""
    stem = Path(clip_file).with_suffix("").as_posix()
    return next((name for name in ("test", "validation") if stem in split.get(name, ())), "train")


def _dataset_clips(folder: Path, dataset: str) -> list[Clip]:
    manifest = folder / "MANIFEST.csv"
    clips = []
    if manifest.exists():
        return _manifest_clips(manifest, dataset)
    for path in files_under(folder):
        if path.suffix.lower() not in MOTION_SUFFIXES:
            continue
        rel = path.relative_to(folder).as_posix()
        clips.append(
            Clip(
                id=f"{dataset}/{Path(rel).with_suffix('').as_posix()}"
                if dataset
                else Path(rel).with_suffix("").as_posix(),
                path=path,
                dataset=dataset,
                category=path.parent.name if path.parent != folder else "",
                subject=path.stem.split("_")[0],
                split=_split_of(dataset, rel) if dataset else "",
            )
        )
    ids = Counter(c.id for c in clips)  # a take in two formats (11_01.bvh, 11_01.amc): each id keeps its suffix
    return [dataclasses.replace(c, id=c.id + c.path.suffix) if ids[c.id] > 1 else c for c in clips]


def _manifest_clips(manifest: Path, dataset: str) -> list[Clip]:
    """The clips a data set's ``MANIFEST.csv`` lists (``file`` column; ``category``,
    ``subject``, ``frames``, ``fps``, ``style`` optional); DataNotFoundError naming the
    file and row where it cannot be read."""
    folder, clips = manifest.parent, []
    try:
        with open(manifest, newline="", encoding="utf-8") as fh:
            for n, row in enumerate(csv.DictReader(fh), start=2):  # line 1: the header
                rel = row.get("file")
                try:
                    frames, fps = int(row.get("frames") or 0), float(row.get("fps") or 0.0)
                except (TypeError, ValueError) as err:
                    what = f"'frames' or 'fps' is not a number ({err})"
                else:
                    what = "" if rel and Path(rel).name else "no file named (a 'file' column, filled in every row)"
                if what:
                    raise DataNotFoundError(
                        f"{manifest}:{n}: {what}; mend the file, or move it away to list the folder's takes"
                    ) from None
                clips.append(
                    Clip(
                        id=f"{dataset}/{Path(rel).with_suffix('').as_posix()}",
                        path=folder / rel,
                        dataset=dataset,
                        category=row.get("category", "") or Path(rel).parent.name,
                        subject=row.get("subject", ""),
                        split=_split_of(dataset, rel),
                        frames=frames,
                        fps=fps,
                        style=row.get("style", ""),
                    )
                )
    except DataNotFoundError:
        raise
    except (OSError, UnicodeDecodeError, csv.Error) as err:
        raise DataNotFoundError(
            f"{manifest} cannot be read ({err}); mend it, or move it away to list the folder's takes"
        ) from None
    return clips


def catalogue(root: str | Path | None = None) -> list[Clip]:
    """Every clip under a data root (found as in :func:`find_data_root` when ``root`` is
    None), sorted by id."""
    root = find_data_root(root) if root is None or not Path(root).is_dir() else Path(root)
    if (root / "MANIFEST.csv").exists():
        clips = _dataset_clips(root, root.name)
    else:
        clips = []
        subdirs = [d for d in sorted(root.iterdir()) if d.is_dir() and (d / "MANIFEST.csv").exists()]
        for d in subdirs:
            clips += _dataset_clips(d, d.name)
        if not subdirs:
            clips = _dataset_clips(root, "")
    return sorted(clips, key=lambda c: c.id)


def select(
    clips: list[Clip], split: str | None = None, dataset: str | None = None, pattern: str | None = None
) -> list[Clip]:
    """Filter clips: ``split`` one of :data:`SPLITS` or "all", ``dataset`` a name or
    several joined by commas (``cmu,bandai``), ``pattern`` a glob on the clip id or a part
    of it (``cmu/walk/*``; ``walk``: every clip with "walk" in its id)."""
    out = clips
    if split and split != "all":
        out = [c for c in out if c.split == split]
    if dataset:
        names = {name.strip() for name in dataset.split(",")}
        out = [c for c in out if c.dataset in names]
    if pattern:
        out = [c for c in out if fnmatch.fnmatch(c.id, pattern) or fnmatch.fnmatch(c.id, f"*{pattern}*")]
    return out


def share(clips: list[Clip], percent: float) -> list[Clip]:
    """``percent`` (0-100] of ``clips``, rounded up to whole clips, in catalogue order. The
    choice is fixed by the clip ids alone (the clips whose SHA-256 of the id is smallest), so it
    is the same on every machine and nested: a 25 % share lies inside the 50 % share."""
    if not 0 < percent <= 100:
        raise ValueError(f"a share is a percentage in (0, 100], not {percent:g}")
    n = math.ceil(len(clips) * percent / 100 - 1e-9)
    chosen = set(sorted((c.id for c in clips), key=lambda i: hashlib.sha256(i.encode()).hexdigest())[:n])
    return [c for c in clips if c.id in chosen]


def find_clip(name: str, root: str | Path | None = None) -> Clip:
    """A clip by id (``cmu/walk/02_01``) or unique suffix (``02_01``)."""
    clips = catalogue(root)
    exact = [c for c in clips if c.id == name]
    if exact:
        return exact[0]
    hits = [c for c in clips if c.id.endswith("/" + name) or c.id.endswith(name)]
    if len(hits) == 1:
        return hits[0]
    if not hits:
        stems = {c.id: c.id[: -len(c.path.suffix)] for c in clips if c.id.endswith(c.path.suffix)}
        formats = [i for i, stem in stems.items() if stem == name or stem.endswith("/" + name)]
        if formats:  # a take kept in two formats: its ids keep their suffixes
            raise NameNotFoundError(f"{name!r} is kept in two formats: name one, {' or '.join(formats[:2])}")
        raise NameNotFoundError(f"no clip named {name!r} in the catalogue; `workbench data` lists them")
    raise NameNotFoundError(f"{name!r} is ambiguous: {', '.join(c.id for c in hits[:6])}")
