"""Where motion data lives.

Data roots, first found wins: an explicit ``--data`` folder, the ``WORKBENCH_DATA``
environment variable, ``datasets/`` in the repository (user data, gitignored), and
``../shared/data`` beside the repository (the team's data, used by CI). A root is a
folder of datasets (``cmu/``, ``cmu-daz/``, each with a MANIFEST.csv), one dataset, or
any folder of BVH (or AMC) files; linked folders inside a root are followed.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

from ..io import MOTION_SUFFIXES

REPO_ROOT = Path(__file__).resolve().parents[2]
ENV_VAR = "WORKBENCH_DATA"

HOW_TO_GET_DATA = """\
No motion data found. Looked in:
{looked}
Point the workbench at a folder of BVH files with --data DIR or the {env} environment
variable, or put clips under datasets/ in the repository (see datasets/README.md).
The CMU clips this project uses are the cgspeed BVH conversion of the CMU Graphics Lab
Motion Capture Database (http://mocap.cs.cmu.edu): download the BVH files of subjects
02-09 there (cmuconvert-mb2-01-09) and unpack them under datasets/cmu/<category>/."""


class DataNotFoundError(FileNotFoundError):
    """No data root could be found; the message says where we looked and what to do."""


def files_under(folder: Path) -> Iterator[Path]:
    """Every file below ``folder``, sorted within each folder, following linked folders
    (each real folder is visited once, so a link cycle ends)."""
    visited: set[str] = set()
    for top, dirs, files in os.walk(folder, followlinks=True):
        real = os.path.realpath(top)
        if real in visited:
            dirs.clear()
            continue
        visited.add(real)
        dirs.sort()
        yield from (Path(top) / name for name in sorted(files))


def _has_motion_files(folder: Path) -> bool:
    return folder.is_dir() and any(
        p.suffix.lower() in MOTION_SUFFIXES or p.name == "MANIFEST.csv" for p in files_under(folder)
    )


def candidate_roots(explicit: str | Path | None = None) -> list[tuple[str, Path]]:
    """(origin, folder) pairs in the order they are tried."""
    out: list[tuple[str, Path]] = []
    if explicit:
        out.append(("--data", Path(explicit)))
    if os.environ.get(ENV_VAR):
        out.append((ENV_VAR, Path(os.environ[ENV_VAR])))
    out.append(("datasets/", REPO_ROOT / "datasets"))
    out.append(("../shared/data", REPO_ROOT.parent / "shared" / "data"))
    return out


def find_data_root(explicit: str | Path | None = None) -> Path:
    """The first candidate root holding motion data. An explicit root (``--data`` or the
    environment variable) that is missing or holds no motion file is an error, not
    silently skipped."""
    looked = []
    for origin, folder in candidate_roots(explicit):
        if origin in ("--data", ENV_VAR):
            if not folder.is_dir():
                raise DataNotFoundError(f"{origin} points at {folder}, which is not a folder")
            if not _has_motion_files(folder):
                raise DataNotFoundError(
                    f"{origin} points at {folder}, which holds no .bvh or .amc file "
                    "(nor a MANIFEST.csv); point it at a folder of motion files"
                )
        if _has_motion_files(folder):
            return folder.resolve()
        looked.append(f"  {origin:15s} {folder}")
    raise DataNotFoundError(HOW_TO_GET_DATA.format(looked="\n".join(looked), env=ENV_VAR))
