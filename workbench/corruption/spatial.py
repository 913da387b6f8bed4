"""Spatial noise: 3-D Gaussian noise on joint positions, then inverse kinematics that
keeps the bone lengths (Mall et al. 2017 §4, "spatial" noise).

Units: noise std in centimetres per axis, converted to the skeleton's file unit with
``skeleton.unit_cm``; positions in file units; angles in degrees. Every joint, the root
included, gets position noise; the IK re-solves every joint's angles and the root
position takes its noisy value (so unlike the angle-noise models, spatial noise moves
the root). The IK's reference (for the twist about single-child bones and the rotations
of leaf joints, and the Euler branch) is the motion as it stands when this model runs:
the clean angles when it is first in the chain. A translated joint (a studio export's
moving Hips) takes its noisy position, as the root does.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from ..core.kinematics import inverse_kinematics
from ..core.skeleton import Skeleton
from .base import Model, Param, Work
from .errors import CorruptionApplyError

#: Wrist and ankle joints, matched on the whole name, case-insensitively: a side
#: (left/right/l/r) and a part (hand/wrist/foot/ankle), either order, optionally joined
#: by "_", "-", "." or " ". CMU: LeftHand, RightHand, LeftFoot, RightFoot; cmu-daz:
#: lHand, rHand, lFoot, rFoot; also e.g. Left_Wrist, r_ankle, hand_l, Foot.R. Names
#: with more after the part (LeftHandIndex1, LeftFootEnd, lHandThumb) do not match.
END_JOINT_PATTERN = re.compile(
    r"^(?:(?:left|right|l|r)[_\-. ]?(?:hand|wrist|foot|ankle)|(?:hand|wrist|foot|ankle)[_\-. ]?(?:left|right|l|r))$",
    re.IGNORECASE,
)


def end_joints(skeleton: Skeleton) -> list[int]:
    """Indices of the wrist and ankle joints (see ``END_JOINT_PATTERN``)."""
    return [j for j, name in enumerate(skeleton.names) if END_JOINT_PATTERN.match(name)]


def _spatial(work: Work, rng: np.random.Generator, sigma_cm: np.ndarray) -> None:
    """Add N(0, sigma_cm[j]^2) per axis to joint j's positions and re-solve by IK."""
    positions = noisy_positions(work, rng, sigma_cm)
    if not np.any(sigma_cm > 0):
        return  # no noise: keep the angles exactly
    current = work.motion()
    root, angles, translations = inverse_kinematics(work.skeleton, positions, reference_angles_deg=current.angles_deg)
    work.channels = current.replace(root_positions=root, angles_deg=angles, translations=translations).channels


def noisy_positions(work: Work, rng: np.random.Generator, sigma_cm: np.ndarray) -> np.ndarray:
    """(F, J, 3) current joint positions plus the drawn noise, in file units (before IK)."""
    sigma = np.asarray(sigma_cm, float) / work.skeleton.unit_cm
    noise = rng.standard_normal((work.n_frames, work.skeleton.n_joints, 3)) * sigma[None, :, None]
    return work.motion().positions + noise


@dataclass(frozen=True)
class Spatial(Model):
    name = "spatial"
    description = "3-D Gaussian noise of std S cm per axis on every joint position, then IK keeping bone lengths"
    params = (Param("S", "cm", "position noise std per axis, cm"),)
    s: float

    def sigmas_cm(self, skeleton: Skeleton) -> np.ndarray:
        return np.full(skeleton.n_joints, self.s)

    def corrupt(self, work: Work, rng: np.random.Generator) -> None:
        _spatial(work, rng, self.sigmas_cm(work.skeleton))


@dataclass(frozen=True)
class SpatialEnds(Model):
    name = "spatial-ends"
    description = (
        "spatial noise with std A cm at the wrists and ankles (joints named like LeftHand, rFoot) "
        "and B cm at every other joint"
    )
    params = (
        Param("A", "cm", "position noise std at wrists and ankles, cm"),
        Param("B", "cm", "position noise std at the other joints, cm"),
    )
    a: float
    b: float

    def sigmas_cm(self, skeleton: Skeleton) -> np.ndarray:
        ends = end_joints(skeleton)
        if not ends:
            raise CorruptionApplyError(
                f"{self.name}: the skeleton has no wrist or ankle joint (names such as LeftHand, RightFoot, "
                f"lHand, rFoot, Left_Wrist, r_ankle); its joints are {', '.join(skeleton.names)}"
            )
        sigma = np.full(skeleton.n_joints, self.b)
        sigma[ends] = self.a
        return sigma

    def corrupt(self, work: Work, rng: np.random.Generator) -> None:
        _spatial(work, rng, self.sigmas_cm(work.skeleton))
