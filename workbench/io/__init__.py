"""Motion file formats: BVH read/write, CMU ASF/AMC read."""

from pathlib import Path

from ..core.motion import Motion
from ..core.skeleton import given_unit_cm
from .bvh import read_bvh, write_bvh
from .errors import MotionFileError, OutputFileError

#: file suffixes :func:`read_motion` reads (compared lower-case)
MOTION_SUFFIXES = (".bvh", ".amc")


def read_motion(path: str | Path, unit_cm: float | None = None) -> Motion:
    """Read a BVH file, or a CMU AMC file (its ASF skeleton beside it); ``unit_cm``: the
    size of its length unit in cm, where the one guessed from its rest pose is wrong."""
    path, unit_cm = Path(path), given_unit_cm(unit_cm)
    if path.suffix.lower() == ".asf":
        raise MotionFileError(
            path, "an ASF file is a skeleton, with no motion: pass the take's .amc file (its .asf is found beside it)"
        )
    if path.suffix.lower() == ".amc":
        from .asfamc import read_amc

        motion = read_amc(path)
        return motion if unit_cm is None else motion.replace(skeleton=motion.skeleton.replace(unit_cm=unit_cm))
    return read_bvh(path, unit_cm=unit_cm)


__all__ = ["read_bvh", "write_bvh", "read_motion", "MotionFileError", "OutputFileError", "MOTION_SUFFIXES"]
