"""A take as a skeleton-agnostic engine models it: the canonical humanoid's joint positions,
at one body size, and the way back onto the take's own skeleton.

:class:`CanonicalBody` carries a take's :class:`~workbench.core.humanoid.HumanoidMapping`
both ways:

- **There** (:meth:`CanonicalBody.positions`): the positions (F, 21, 3) of the canonical
  joints, each the position of the take joint it maps to, scaled so that every body has
  the body size :data:`CANONICAL_BODY_CM` (the rest-pose head-to-feet chain of
  :meth:`~workbench.core.humanoid.HumanoidMapping.body_size_cm`; units: canonical cm).
  An engine makes them root-relative and heading-normalised as it does for its own
  skeleton (the heading here from the body's across direction, :func:`facing`, since the
  rest orientation of a root differs between exporters). A canonical joint the take lacks
  is NaN and never known (:meth:`CanonicalBody.known`): the engine fills it and it is
  dropped on the way back.
- **Back** (:meth:`CanonicalBody.solve`): predicted canonical positions become IK targets
  on the take's skeleton, whose bone lengths IK keeps exactly. The joints with no mapped
  joint below them keep the reference's angles (the observation smoothed, as the
  engine's IK reference gives it): the unmapped ends (fingers, eyes, toes' ends) and the
  canonical ends (hands, head, feet or toes), whose turn positions cannot show. An
  unmapped joint between two mapped ones (CMU's ``Neck``, Daz's buttocks, a third spine
  joint) is aimed like the mapped ones, its target on the reference chain between the two,
  turned and stretched about the one above so that the one below lands on its own
  (:meth:`CanonicalBody.targets`): held at the reference's angles instead, it would make
  every mapped joint below it miss its target.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..core.humanoid import CANONICAL_JOINTS, HumanoidMapping
from ..core.kinematics import inverse_kinematics, joint_positions
from ..core.rotations import vectors_to_rotation

__all__ = ["CANONICAL_BODY_CM", "CanonicalBody", "facing"]

#: the body size every canonical body is scaled to (cm; CMU's is 124.7, Bandai's 127.6)
CANONICAL_BODY_CM = 125.0
_ACROSS = [(CANONICAL_JOINTS.index(f"left_{p}"), CANONICAL_JOINTS.index(f"right_{p}")) for p in ("thigh", "upper_arm")]


def facing(canonical: np.ndarray) -> np.ndarray:
    """(F,) the heading (radians) of canonical positions (F, 21, 3): the turn about the up
    axis (Y) from +Z to the body's forward direction, the horizontal perpendicular of its
    across direction (left thigh minus right thigh plus left upper arm minus right upper
    arm; left is +X of a body facing +Z, as BVH has it). 0 for a body in its rest pose."""
    across = sum(canonical[:, left] - canonical[:, right] for left, right in _ACROSS)
    return np.arctan2(-across[:, 2], across[:, 0])


@dataclass(frozen=True)
class CanonicalBody:
    """A take's skeleton seen as the canonical humanoid (module docstring)."""

    mapping: HumanoidMapping

    @property
    def skeleton(self):
        return self.mapping.skeleton

    @cached_property
    def scale(self) -> float:
        """Canonical cm per file unit of the take."""
        return self.skeleton.unit_cm * CANONICAL_BODY_CM / self.mapping.body_size_cm()

    @cached_property
    def _mapped(self) -> tuple[np.ndarray, np.ndarray]:
        """The mapped canonical joints (indices into :data:`CANONICAL_JOINTS`) and their take joints."""
        joints = np.array(self.mapping.joints)
        c = np.flatnonzero(joints >= 0)
        return c, joints[c]

    def positions(self, positions: np.ndarray) -> np.ndarray:
        """(F, 21, 3) canonical positions (canonical cm, NaN where the take has no joint)
        of the take's joint positions (F, J, 3, file units)."""
        return self.mapping.canonical_positions(positions) * self.scale

    def known(self, known: np.ndarray) -> np.ndarray:
        """(F, 21) where a canonical joint's position is known, from where the take's
        joints' are (F, J); never for one the take lacks."""
        out = np.zeros(known.shape[:-1] + (len(CANONICAL_JOINTS),), bool)
        c, j = self._mapped
        out[..., c] = known[..., j]
        return out

    @cached_property
    def kept_joints(self) -> np.ndarray:
        """The take's joints that keep the reference's angles: those with no mapped joint
        strictly below them (:meth:`~workbench.core.humanoid.HumanoidMapping.kept_joints`)."""
        return np.array(self.mapping.kept_joints(), int)

    def targets(self, canonical: np.ndarray, reference: np.ndarray) -> np.ndarray:
        """IK targets (F, J, 3, file units) on the take's skeleton, from the canonical
        positions (F, 21, 3, canonical cm) and the reference positions (F, J, 3):

        - a mapped joint at its canonical position;
        - an unmapped joint between the nearest mapped joints above and below it, a and d
          (a third spine joint), where the reference chain from a to d puts it once turned
          (the smallest turn) and stretched about a's target so that d lands on its own.
          a then aims along the a-to-d lever: were the chain only moved so that d lands (as
          for the next case), a would aim at its first unmapped child, one short bone away,
          and turn by d's error over that bone (a 7-cm spine joint under a 35-cm spine);
        - one with a mapped joint below and none above (a reference node above the hips),
          or whose a and d coincide in the reference, at d's target less their reference
          offset;
        - one with none below at its parent's target plus their reference offset (IK keeps
          such joints' reference angles: the target only steers their parents)."""
        skeleton = self.skeleton
        out = np.array(reference, float, copy=True)
        c, j = self._mapped
        out[:, j] = canonical[:, c] / self.scale
        mapped = self.mapping.mapped_joints()
        below = {}  # joint -> nearest mapped descendant (shallowest, first in the tree's order)
        for k in range(skeleton.n_joints - 1, -1, -1):
            for child in skeleton.children[k]:
                d = child if mapped[child] else below.get(child)
                if d is not None and (k not in below or _depth(skeleton, d) <= _depth(skeleton, below[k])):
                    below[k] = d
        above = {}  # joint -> nearest mapped ancestor
        for k, parent in enumerate(skeleton.parents):
            if parent >= 0:
                above[k] = parent if mapped[parent] else above.get(parent)
        for k in np.flatnonzero(~mapped):
            if k in below:
                d, a = below[k], above.get(k)
                out[:, k] = out[:, d] - (reference[:, d] - reference[:, k])
                if a is not None:
                    out[:, k] = _along_chain(
                        out[:, a], out[:, d], reference[:, a], reference[:, d], reference[:, k], out[:, k]
                    )
            elif skeleton.parents[k] >= 0:
                a = skeleton.parents[k]
                out[:, k] = out[:, a] + (reference[:, k] - reference[:, a])
        return out

    def solve(
        self, canonical: np.ndarray, root_positions: np.ndarray, reference_angles_deg: np.ndarray, **ik
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Root positions (F, 3), angles (F, J, 3, degrees) and translations of the take's
        skeleton that put its mapped joints at ``canonical`` (F, 21, 3) as far as its bone
        lengths allow, the :attr:`kept_joints` at the reference's angles (F, J, 3), whose
        positions (the other joints' targets: :meth:`targets`) are their FK on
        ``root_positions`` (F, 3, file units). ``ik``: further arguments of
        :func:`~workbench.core.kinematics.inverse_kinematics` (``reference_joints`` are
        added to the kept ones)."""
        kept = np.union1d(self.kept_joints, np.asarray(ik.pop("reference_joints", ()), int))
        reference = joint_positions(self.skeleton, root_positions, reference_angles_deg)
        return inverse_kinematics(
            self.skeleton,
            self.targets(canonical, reference),
            reference_angles_deg,
            reference_joints=kept,
            **ik,
        )


def _along_chain(
    top: np.ndarray,
    bottom: np.ndarray,
    reference_top: np.ndarray,
    reference_bottom: np.ndarray,
    point: np.ndarray,
    fallback: np.ndarray,
) -> np.ndarray:
    """(F, 3) ``point`` (F, 3) of a reference chain from ``reference_top`` to
    ``reference_bottom`` (F, 3 each), turned by the smallest rotation and scaled about the
    top so that the chain runs from ``top`` to ``bottom`` (F, 3 each); ``fallback`` (F, 3)
    in frames whose reference chain has no length."""
    chord = reference_bottom - reference_top
    goal = bottom - top
    length = np.linalg.norm(chord, axis=-1)
    has_length = length > 1e-9 * (1.0 + np.linalg.norm(reference_top, axis=-1))
    stretch = np.linalg.norm(goal, axis=-1) / np.where(has_length, length, 1.0)
    turned = np.einsum("fij,fj->fi", vectors_to_rotation(chord, goal), point - reference_top)
    return np.where(has_length[:, None], top + stretch[:, None] * turned, fallback)


def _depth(skeleton, j: int) -> int:
    depth = 0
    while (j := skeleton.parents[j]) >= 0:
        depth += 1
    return depth
