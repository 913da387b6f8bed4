"""Which body the motion image holds, and the way back to the take's skeleton.

The image of Kaufmann et al. holds the take's own joints (:class:`OwnJoints`): its weights
know one skeleton. A universal variant (``cae:universal=true``) holds the canonical
humanoid's 21 joints instead (:class:`CanonicalJoints`, :mod:`workbench.engine.canonical`):
one network for every skeleton that maps onto it, trained on several data sets together.
Both give the engine the same things: the image's layout and joint names (for the
mirror), image positions and their heading from the take's world positions (file units),
which image entries are known, and IK back onto the take's skeleton.

Units: image positions are file units for :class:`OwnJoints` and canonical cm (every
body scaled to :data:`workbench.engine.canonical.CANONICAL_BODY_CM`) for
:class:`CanonicalJoints`; headings in radians.
"""

from __future__ import annotations

import numpy as np

from workbench.core.humanoid import CANONICAL_JOINTS, CANONICAL_PARENTS, HumanoidMapping
from workbench.core.kinematics import inverse_kinematics
from workbench.core.skeleton import Skeleton
from workbench.engine.canonical import CanonicalBody, facing

from .representation import Layout, heading

#: the image layout of the canonical humanoid: every joint but the hips is a row
CANONICAL_LAYOUT = Layout(
    joints=tuple(range(1, len(CANONICAL_JOINTS))),
    source=tuple(range(len(CANONICAL_JOINTS))),
    parents=tuple(-1 if p is None else CANONICAL_JOINTS.index(p) for p in CANONICAL_PARENTS.values()),
)


class OwnJoints:
    """The image of the take's own joints (the paper's)."""

    def __init__(self, skeleton: Skeleton, layout: Layout) -> None:
        self.skeleton, self.layout, self.names = skeleton, layout, skeleton.names
        self.scale = 1.0

    def positions(self, positions: np.ndarray) -> np.ndarray:
        """Image positions (F, J, 3) of the take's world positions (F, J, 3)."""
        return positions

    def heading(self, image_positions: np.ndarray, root_rotations: np.ndarray) -> np.ndarray:
        """(F,) radians: the twist about the up axis of the root's world rotations (F, 3, 3)."""
        return heading(root_rotations)

    def known(self, known: np.ndarray) -> np.ndarray:
        """(F, J) where an image joint's position is known, from where the take joints' are (F, J)."""
        return known

    def image_joint(self, j: int) -> int:
        """The image joint whose rows hold take joint ``j`` (-1: none)."""
        return self.layout.source[j] if 0 <= j < self.layout.n_joints else -1

    def targets(self, image_positions: np.ndarray, reference: np.ndarray) -> np.ndarray:
        """IK targets (F, J, 3) on the take's skeleton of decoded image positions."""
        return image_positions

    def solve(
        self, image_positions: np.ndarray, root_positions: np.ndarray, reference_angles: np.ndarray, **ik
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Root positions (F, 3), angles (F, J, 3, degrees) and translations putting the
        take's joints at the decoded image positions (F, J, 3), the IK reference the
        angles (F, J, 3) on the reference root positions (F, 3); ``ik``: further arguments
        of :func:`~workbench.core.kinematics.inverse_kinematics`."""
        return inverse_kinematics(self.skeleton, image_positions, reference_angles, **ik)


class CanonicalJoints:
    """The image of the canonical humanoid (module docstring), for one take's skeleton."""

    layout = CANONICAL_LAYOUT
    names = CANONICAL_JOINTS

    def __init__(self, mapping: HumanoidMapping) -> None:
        self.body = CanonicalBody(mapping)
        self.skeleton, self.scale = mapping.skeleton, self.body.scale

    def positions(self, positions: np.ndarray) -> np.ndarray:
        """Canonical positions (F, 21, 3) in canonical cm; a joint the take lacks at the
        hips (never known, so the network fills it)."""
        P = self.body.positions(positions)
        return np.where(np.isnan(P), P[:, :1], P)

    def heading(self, image_positions: np.ndarray, root_rotations: np.ndarray) -> np.ndarray:
        """(F,) radians: the body's facing from its across direction (roots' rest frames
        differ between exporters)."""
        return facing(image_positions)

    def known(self, known: np.ndarray) -> np.ndarray:
        """(F, 21) from the take joints' (F, J); never for a canonical joint the take lacks."""
        return self.body.known(known)

    def image_joint(self, j: int) -> int:
        """The canonical joint take joint ``j`` maps to (-1: none)."""
        joints = self.body.mapping.joints
        return joints.index(j) if j in joints else -1

    def targets(self, image_positions: np.ndarray, reference: np.ndarray) -> np.ndarray:
        """IK targets (F, J, 3, file units) of decoded canonical positions (F, 21, 3), the
        take's other joints placed by their offsets in the ``reference`` positions (F, J, 3)."""
        return self.body.targets(image_positions, reference)

    def solve(
        self, image_positions: np.ndarray, root_positions: np.ndarray, reference_angles: np.ndarray, **ik
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """As :meth:`OwnJoints.solve`, from decoded canonical positions (F, 21, 3)
        (:meth:`workbench.engine.canonical.CanonicalBody.solve`)."""
        return self.body.solve(image_positions, root_positions, reference_angles, **ik)
