"""Core types and kinematics (numpy only)."""

from .kinematics import forward_kinematics, inverse_kinematics
from .motion import Case, Motion, Observation, angle_columns, channel_mask
from .skeleton import Skeleton

__all__ = [
    "Skeleton",
    "Motion",
    "Observation",
    "Case",
    "forward_kinematics",
    "inverse_kinematics",
    "angle_columns",
    "channel_mask",
]
