"""Where motion data lives.

Data roots, first found wins: an explicit ``--data`` folder, the ``WORKBENCH_DATA``
environment variable, ``datasets/`` in the repository (user data, gitignored), and
``../shared/data`` beside the repository (the team's data, used by CI). A root is a
folder of datasets (``cmu/``, ``cmu-daz/``, each with a MANIFEST.csv), one dataset, or
any folder of BVH files.
"""

from __future__ import annotations

import os
from pathlib import Path

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


def _has_motion_files(folder: Path) -> bool:
    return folder.is_dir() and any(
        p.suffix.lower() in (".bvh", ".amc") or p.name == "MANIFEST.csv" for p in folder.rglob("*")
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
    environment variable) that is missing is an error, not silently skipped."""
    looked = []
    for origin, folder in candidate_roots(explicit):
        if origin in ("--data", ENV_VAR) and not folder.is_dir():
            raise DataNotFoundError(f"{origin} points at {folder}, which is not a folder")
        if _has_motion_files(folder):
            return folder.resolve()
        looked.append(f"  {origin:15s} {folder}")
    raise DataNotFoundError(HOW_TO_GET_DATA.format(looked="\n".join(looked), env=ENV_VAR))
