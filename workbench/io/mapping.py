"""The humanoid mapping file a user passes with ``--mapping``: a JSON object from canonical
joint names to the take's joint names (``null``: the take has none), e.g.
``{"neck": "Neck", "left_toes": null}``; entries pin what the rules of
:mod:`workbench.core.humanoid` would otherwise find."""

from __future__ import annotations

import json
from pathlib import Path

from .errors import MotionFileError


def read_mapping(path: str | Path) -> dict[str, str | None]:
    """The pinned joints of a mapping file. Raises MotionFileError, naming the file, for one
    that cannot be read, is not JSON, or is not an object of names (or nulls)."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except OSError as err:
        raise MotionFileError(path, f"cannot read the mapping file ({err.strerror or err})") from None
    except ValueError as err:
        raise MotionFileError(path, f"not a JSON mapping file ({err})") from None
    if not isinstance(doc, dict) or not all(isinstance(v, str) or v is None for v in doc.values()):
        raise MotionFileError(
            path, 'a mapping file is one JSON object of canonical joint to joint name, e.g. {"neck": "Neck1"}'
        )
    return doc
