"""The humanoid mapping file a user passes with ``--mapping``: a JSON object from canonical
joint names to the take's joint names (``null``: the take has none), e.g.
``{"neck": "Neck", "left_toes": null}``; entries pin what the rules of
:mod:`workbench.core.humanoid` would otherwise find."""

from __future__ import annotations

from pathlib import Path

from .errors import MotionFileError, read_json_file


def read_mapping(path: str | Path) -> dict[str, str | None]:
    """The pinned joints of a mapping file. Raises MotionFileError, naming the file, for one
    that cannot be read, is not JSON, is not an object of names (or nulls), or names a
    canonical joint there is not (whatever the take: before any engine is asked)."""
    from ..core.humanoid import unknown_canonical

    doc = read_json_file(path, "mapping")
    if not isinstance(doc, dict) or not all(isinstance(v, str) or v is None for v in doc.values()):
        raise MotionFileError(
            path, 'a mapping file is one JSON object of canonical joint to joint name, e.g. {"neck": "Neck1"}'
        )
    if (problem := unknown_canonical(doc)) is not None:
        raise MotionFileError(path, problem)
    return doc
