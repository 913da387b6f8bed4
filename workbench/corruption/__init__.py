"""Corrupt clean motion reproducibly, to benchmark cleaning methods (numpy only).

Units: angles in degrees, positions in the skeleton's file unit (``skeleton.unit_cm`` cm
each), spatial noise levels in cm, gap lengths in frames.

>>> spec = parse_corruption("angular:0.5+gaps:0.01")
>>> obs = spec.apply(motion, seed=0)          # Observation: corrupted Motion + mask (F, J)
>>> case = make_case(motion, "angular:0.5", seed=0)

Models (``MODELS``; ``models_help()`` prints them): angular, uniform, bias, sine,
spatial, spatial-ends, outliers, jumps (noise) and gaps, block, joints, drop (missing data).
"""

from .base import Model, Param, Seconds, format_number, random_stream
from .errors import CorruptionApplyError, CorruptionSpecError
from .gaps import Block, Drop, Gaps, Joints
from .noise import Angular, Bias, Jumps, Outliers, Sine, Uniform
from .spatial import END_JOINT_PATTERN, Spatial, SpatialEnds, end_joints
from .spec import MODELS, Corruption, make_case, models_help, parse_corruption

__all__ = [
    "parse_corruption",
    "make_case",
    "Corruption",
    "MODELS",
    "models_help",
    "CorruptionApplyError",
    "CorruptionSpecError",
    "Model",
    "Param",
    "Seconds",
    "random_stream",
    "format_number",
    "Angular",
    "Uniform",
    "Bias",
    "Sine",
    "Outliers",
    "Jumps",
    "Spatial",
    "SpatialEnds",
    "Gaps",
    "Block",
    "Joints",
    "Drop",
    "end_joints",
    "END_JOINT_PATTERN",
]
