"""Bone-length spread (Kaufmann et al. 2020, Fig. 5): for a few bones, a box per source
(noisy, each engine) of that bone's length over all frames, the truth as a dot; a source
that is a network's raw output can be marked with the length its IK'd result has (a bar:
IK keeps the skeleton's bones exact).

Units: cm (file-unit lengths times ``unit_cm``).
"""

from __future__ import annotations

import numpy as np

from ..metrics import bone_lengths
from .style import TRUTH
from .timeline import outside_legend

#: the mark of a bone's length after IK beside the raw output's box
EXACT_MARK = dict(s=90, marker="_", linewidths=2.2, color="black")


def plot_bone_lengths(
    ax,
    sources: list[tuple[str, np.ndarray, str]],
    skeleton,
    bones: list[int],
    truth: np.ndarray | None = None,
    exact: dict[int, np.ndarray] | None = None,
) -> None:
    """Box plots of bone lengths in cm. sources: (label, positions (F, J, 3) in file
    units, colour); bones: child joint index of each bone shown; truth: (F, J, 3);
    exact: by source index, the positions (F, J, 3) of that source after IK, whose median
    lengths are marked beside its boxes."""
    if not bones:  # a lone root, or a root chain alone
        ax.text(0.5, 0.5, "no bones: the skeleton is its root alone", ha="center", va="center", transform=ax.transAxes)
        ax.set_axis_off()
        return
    column = {j: k for k, j in enumerate(j for j, p in enumerate(skeleton.parents) if p >= 0)}
    cols = [column[j] for j in bones]
    n = len(sources)
    width = 0.8 / max(n, 1)
    for i, (label, positions, colour) in enumerate(sources):
        lengths = bone_lengths(positions, skeleton.parents)[:, cols] * skeleton.unit_cm
        x = np.arange(len(bones)) + (i - (n - 1) / 2) * width
        ax.boxplot(
            lengths,
            positions=x,
            widths=width * 0.85,
            patch_artist=True,
            showfliers=False,
            boxprops=dict(facecolor=colour, alpha=0.55, edgecolor=colour),
            medianprops=dict(color=colour, lw=2),
            whiskerprops=dict(color=colour),
            capprops=dict(color=colour),
        )
        ax.plot([], [], color=colour, lw=6, alpha=0.55, label=label)
        if exact is not None and i in exact:
            after = np.median(bone_lengths(exact[i], skeleton.parents)[:, cols] * skeleton.unit_cm, axis=0)
            ax.scatter(x, after, zorder=5, **EXACT_MARK)
    if exact:
        ax.scatter([], [], label="after IK (exact)", **EXACT_MARK)
    if truth is not None:
        median = np.median(bone_lengths(truth, skeleton.parents)[:, cols] * skeleton.unit_cm, axis=0)
        ax.scatter(np.arange(len(bones)), median, s=40, color=TRUTH, edgecolor="white", zorder=4, label="truth")
    labels = [f"{skeleton.names[skeleton.parents[j]]} →\n{skeleton.names[j]}" for j in bones]  # narrow: no overlap
    ax.set_xticks(np.arange(len(bones)), labels, fontsize="x-small")
    ax.set_xlim(-0.6, len(bones) - 0.4)
    ax.set_ylabel("bone length (cm)")
    ax.grid(True, axis="y", color="#e3e6ea", lw=0.8)
    ax.set_axisbelow(True)
    outside_legend(ax)
