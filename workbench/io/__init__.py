"""Motion file formats: BVH read/write, CMU ASF/AMC read."""

from pathlib import Path

from ..core.motion import Motion
from .bvh import read_bvh, write_bvh
from .errors import MotionFileError, OutputFileError

#: file suffixes :func:`read_motion` reads (compared lower-case)
MOTION_SUFFIXES = (".bvh", ".amc")


def read_motion(path: str | Path) -> Motion:
    """Read a BVH file, or a CMU AMC file (its ASF skeleton beside it)."""
    path = Path(path)
    if path.suffix.lower() == ".amc":
        from .asfamc import read_amc

        return read_amc(path)
    return read_bvh(path)


__all__ = ["read_bvh", "write_bvh", "read_motion", "MotionFileError", "OutputFileError", "MOTION_SUFFIXES"]
