"""Where motion data lives.

Data roots, first found wins: an explicit ``--data`` folder, the ``WORKBENCH_DATA``
environment variable, ``datasets/`` in the repository (user data, gitignored), and
``../shared/data`` beside the repository (the team's data, used by CI), and last the two
CMU takes embedded in the package (:data:`EMBEDDED_ROOT`), so that the app and the
benchmark run on a machine with no data at all. A root is a
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
#: two short CMU takes of the test split shipped with the package (README.md there)
EMBEDDED_ROOT = Path(__file__).resolve().parent / "embedded"

HOW_TO_GET_DATA = """\
No motion data found. Looked in:
{looked}
Point the workbench at a folder of BVH files with --data DIR or the {env} environment
variable, or put clips under datasets/ in the repository (see datasets/README.md).
{clips}"""

#: which CMU clips the splits use and where to get them, for the messages about missing data
CMU_CLIPS = """\
The CMU clips this project's splits use are the cgspeed BVH conversion of the CMU Graphics
Lab Motion Capture Database (http://mocap.cs.cmu.edu, files SS_TT.bvh): for training,
subjects 02, 03, 05, 06, 07 and 09; for testing, subjects 16, 35 and 127; the clip list is
workbench/data/splits/cmu.json. Put them under datasets/cmu/<category>/ (walk, jog, run,
jump, other) with the MANIFEST.csv of workbench/data/embedded/cmu/ extended to them."""


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
    out.append(("embedded", EMBEDDED_ROOT))
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
    raise DataNotFoundError(HOW_TO_GET_DATA.format(looked="\n".join(looked), env=ENV_VAR, clips=CMU_CLIPS))


def is_embedded(root: str | Path) -> bool:
    """True when ``root`` is the package's embedded takes, not a data folder of the user's."""
    return Path(root).resolve() == EMBEDDED_ROOT
