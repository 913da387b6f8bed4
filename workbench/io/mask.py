"""The observed-mask sidecar written next to a corrupted BVH: JSON listing, per joint,
the missing frame spans ``[start, stop)`` (frame indices of the BVH's motion section)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..core.motion import Motion, Observation
from ..core.skeleton import Skeleton
from .atomic import atomic_write_text
from .errors import MotionFileError, read_json_file

FORMAT = "mocap-workbench observed mask v1"


def mask_to_json(observed: np.ndarray, skeleton: Skeleton) -> str:
    missing = {}
    for j, name in enumerate(skeleton.names):
        m = ~observed[:, j]
        if m.any():
            edges = np.flatnonzero(np.diff(np.concatenate([[0], m.astype(np.int8), [0]])))
            missing[name] = edges.reshape(-1, 2).tolist()
    doc = {"format": FORMAT, "frames": int(observed.shape[0]), "joints": list(skeleton.names), "missing": missing}
    return json.dumps(doc, indent=1) + "\n"


def sidecar_path(take: str | Path) -> Path:
    """Where the observed mask of ``take`` is kept: ``TAKE.mask.json`` beside it."""
    return Path(f"{take}.mask.json")


def take_mask(take: str | Path, skeleton: Skeleton, n_frames: int, mask: str | Path | None = None):
    """(observed (F, J) or None, the file it came from or None): the mask ``mask`` names,
    else ``take``'s sidecar where there is one, checked against the take's ``skeleton``
    and its ``n_frames`` frames as in the file."""
    path = Path(mask) if mask else sidecar_path(take)
    if mask:
        return read_mask(path, skeleton, n_frames), path
    if not path.exists():
        return None, None
    try:
        return read_mask(path, skeleton, n_frames), path
    except MotionFileError as err:  # found, not named: say so, and how to be rid of it
        raise MotionFileError(
            path,
            f"{err.reason}; it was found beside the take and read as its mask: rename or delete it if it is "
            "another take's, or name the take's own mask with --mask",
            err.line,
        ) from None


def observed_take(path: str | Path, motion: Motion, observed: np.ndarray | None = None) -> Observation:
    """The take ``motion`` read from ``path`` as an observation with its mask ``observed``
    (F, J) if any; MotionFileError where no sample of it is observed (every value NaN,
    or masked out): there is nothing to clean or inspect, and engines would make it up."""
    observation = Observation(motion, observed)
    if not observation.observed.any():
        raise MotionFileError(path, "no sample of the take is observed (every value is NaN or masked as missing)")
    return observation


def write_mask(path: str | Path, observed: np.ndarray, skeleton: Skeleton) -> None:
    atomic_write_text(path, mask_to_json(np.asarray(observed, bool), skeleton))


def read_mask(path: str | Path, skeleton: Skeleton, n_frames: int) -> np.ndarray:
    """The observed mask (F, J) from a sidecar; checked against the take it belongs to."""
    doc = read_json_file(path, "mask")
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise MotionFileError(path, f"not a mask sidecar: expected format {FORMAT!r}")
    if doc.get("frames") != n_frames:
        raise MotionFileError(path, f"the mask is for {doc.get('frames')} frames, the take has {n_frames}")
    observed = np.ones((n_frames, skeleton.n_joints), bool)
    missing = doc.get("missing", {})
    if not isinstance(missing, dict):
        raise MotionFileError(path, "'missing' must map joint names to lists of [start, stop) frame spans")
    for name, spans in missing.items():
        if name not in skeleton.names:
            raise MotionFileError(path, f"the mask names joint {name!r}, which the take's skeleton lacks")
        j = skeleton.names.index(name)
        for span in spans if isinstance(spans, list) else [spans]:
            if not (
                isinstance(span, list)
                and len(span) == 2
                and all(type(frame) is int for frame in span)  # (not a bool, a float or null)
                and 0 <= span[0] < span[1] <= n_frames
            ):
                raise MotionFileError(path, f"joint {name!r}: bad span {span!r} (want [start, stop) within the take)")
            observed[span[0] : span[1], j] = False
    return observed
