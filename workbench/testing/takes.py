"""Synthetic takes for tests of the edges: a chain of joints, no humanoid at all."""

from __future__ import annotations

import numpy as np


def chain_bvh(
    n_joints: int, frames: int = 1, bone: float = 1.0, frame_time: str = "0.0333333", wave_deg: float = 0.0
) -> str:
    """BVH text of a chain of ``n_joints`` joints ``bone`` units apart (the root with six
    channels, the others three), ``frames`` frames of it waving by ``wave_deg`` degrees
    (0: still)."""
    lines = [
        "HIERARCHY",
        "ROOT j0",
        "{",
        "OFFSET 0 0 0",
        "CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation",
    ]
    for i in range(1, n_joints):
        lines += [f"JOINT j{i}", "{", f"OFFSET 0 {bone:g} 0", "CHANNELS 3 Zrotation Xrotation Yrotation"]
    lines += ["End Site", "{", f"OFFSET 0 {bone:g} 0", "}"] + ["}"] * n_joints
    values = np.zeros((frames, 6 + 3 * (n_joints - 1)))
    t = np.arange(frames)[:, None] / 30.0
    values[:, 6::3] = wave_deg * np.sin(t + np.arange(1, n_joints) / 5)
    rows = [" ".join(f"{v:.4f}" if v else "0" for v in row) for row in values]
    return "\n".join([*lines, "MOTION", f"Frames: {frames}", f"Frame Time: {frame_time}", *rows]) + "\n"
