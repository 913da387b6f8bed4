"""Missing-data models: the observed mask (F, J) goes False and the values become NaN
(Mall et al. 2017 §4; Kaufmann et al. 2020 §3.3 and §4).

Units: lengths and positions in frames (0-based frame indices of the clip), or in
seconds where a spec says so (``block:2s``: :meth:`.base.Work.frames`); joints by
index into ``skeleton.names``. A joint missing at a frame means its three angles are
missing there (and its translation, for a translated joint); the root position is
missing only where the root joint is (``block``). "Non-root joints" are those outside
the root chain (``skeleton.root_chain``: the root, and the moving Hips a studio
export's reference node carries), whose motion is the trajectory.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .base import Model, Param, Seconds, Work
from .errors import CorruptionApplyError


@dataclass(frozen=True)
class Gaps(Model):
    """Mall et al.: at every (frame, non-root joint) a gap starts with probability P. Its
    length is drawn from the discrete exponential (geometric) distribution on 1, 2, 3, ...
    frames with mean MEAN, i.e. ``ceil`` of an exponential variable, and capped at MAX
    frames; a gap is cut at the end of the clip. Gaps may overlap."""

    name = "gaps"
    description = (
        "a gap starts at each (frame, non-root joint) with probability P; length exponential "
        "with mean MEAN frames (at least 1), capped at MAX frames"
    )
    params = (
        Param("P", "prob", "probability that a gap starts at a given frame and joint"),
        Param("MEAN", "mean-frames", "mean gap length, frames", 12.0),
        Param("MAX", "frames", "longest gap, frames", 600),
    )
    p: float
    mean: float | Seconds = 12.0
    max: int | Seconds = 600

    def events(self, work: Work, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Draw the gaps among ``work.gap_joints``: (start frames, joints, lengths
        (capped, not cut at the clip end)), in frame-major order."""
        joints = work.gap_joints
        starts = rng.random((work.n_frames, joints.size)) < self.p
        frames, cols = np.nonzero(starts)
        lengths = rng.geometric(1.0 / work.frames(self, "mean"), size=frames.size)
        return frames, joints[cols], np.minimum(lengths, work.frames(self, "max"))

    def corrupt(self, work: Work, rng: np.random.Generator) -> None:
        F, J = work.observed.shape
        frames, joints, lengths = self.events(work, rng)
        # +1 where a gap starts, -1 after it ends; the running sum counts open gaps.
        delta = np.zeros((F + 1, J), int)
        np.add.at(delta, (frames, joints), 1)
        np.add.at(delta, (np.minimum(frames + lengths, F), joints), -1)
        work.observed &= np.cumsum(delta[:F], axis=0) == 0


@dataclass(frozen=True)
class Block(Model):
    """Kaufmann et al.: N consecutive frames missing for every joint, the root included.
    The first missing frame is drawn uniformly among those that leave at least one
    observed frame before and after the block (1 .. F - N - 1), or fixed by START, which
    must obey the same rule. The clip needs at least N + 2 frames."""

    name = "block"
    description = (
        "N consecutive frames missing for all joints (root too), placed at random with an observed "
        "frame on each side, or starting at frame START"
    )
    params = (
        Param("N", "frame-count", "number of missing frames"),
        Param("START", "frame", "first missing frame (default: random)", None),
    )
    n: int | Seconds
    start: int | Seconds | None = None

    def first_frame(self, work: Work, rng: np.random.Generator) -> int:
        n_frames, n = work.n_frames, work.frames(self, "n")
        if n_frames < n + 2:
            raise CorruptionApplyError(
                f"{self} needs a clip of at least {n + 2} frames (the block plus one observed frame on "
                f"each side); this one has {n_frames}"
            )
        if self.start is None:
            return int(rng.integers(1, n_frames - n))
        start = work.frames(self, "start")
        if not 1 <= start <= n_frames - n - 1:
            raise CorruptionApplyError(
                f"{self}: START must leave an observed frame on each side of the block, i.e. lie in "
                f"1..{n_frames - n - 1} for this {n_frames}-frame clip; got {start}"
            )
        return start

    def corrupt(self, work: Work, rng: np.random.Generator) -> None:
        s = self.first_frame(work, rng)
        work.observed[s : s + work.frames(self, "n")] = False


@dataclass(frozen=True)
class Joints(Model):
    """Kaufmann et al.: N joints missing over the whole clip, drawn without replacement
    among the non-root joints whose angles are not constant in the clean clip."""

    name = "joints"
    description = "N joints missing for the whole clip, drawn among the non-root joints whose angles vary"
    params = (Param("N", "count", "number of missing joints"),)
    n: int

    def eligible(self, work: Work) -> np.ndarray:
        joints = (work.angle_cols - 3) // 3
        return np.unique(joints[work.angle_std > 0])

    def corrupt(self, work: Work, rng: np.random.Generator) -> None:
        eligible = self.eligible(work)
        if self.n > eligible.size and work.n_frames < 2:
            raise CorruptionApplyError(f"{self}: a take of one frame has no joint whose angles vary; use 2 or more")
        if self.n and not eligible.size:
            raise CorruptionApplyError(
                f"{self}: no non-root joint of this take moves (every angle is constant), so none can go missing; "
                "corrupt a take with motion"
            )
        if self.n > eligible.size:
            raise CorruptionApplyError(
                f"{self}: this skeleton has only {eligible.size} non-root joints whose angles vary; "
                f"N must be at most {eligible.size}"
            )
        chosen = rng.choice(eligible, size=self.n, replace=False)
        work.observed[:, chosen] = False


@dataclass(frozen=True)
class Drop(Model):
    """Each non-root joint is missing in each frame independently with probability P."""

    name = "drop"
    description = "each non-root joint missing in each frame independently with probability P"
    params = (Param("P", "prob", "probability that a joint is missing in a frame"),)
    p: float

    def corrupt(self, work: Work, rng: np.random.Generator) -> None:
        joints = work.gap_joints
        work.observed[:, joints] &= ~(rng.random((work.n_frames, joints.size)) < self.p)
