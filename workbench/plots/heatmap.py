"""The filter widths a filter-predicting engine chose: a heatmap of channels x time.

Units: widths (the Gaussian kernel's standard deviation) in frames; time in seconds.
The colour scale is logarithmic: widths span a fraction of a frame (a channel kept as it
is) to hundreds (a channel averaged flat over the filter's whole reach), and both ends
matter.
"""

from __future__ import annotations

import numpy as np

LABEL_PX = 11  # vertical room one row label needs
#: the narrowest width on the colour scale, frames: narrower ones (0 for a channel passed
#: through) take its colour, a Gaussian that leaves its neighbours under 1e-5 of the weight
NARROWEST_FRAMES = 0.2


def channel_groups(names, n_channels: int) -> list[tuple[str, int, int]]:
    """(label, first row, stop row) of each joint's channels when the matrix is the
    channel layout (root position, then three angles per joint), else one group."""
    if n_channels != 3 + 3 * len(names):
        return [("channels", 0, n_channels)]
    return [("root position", 0, 3)] + [(name, 3 + 3 * j, 6 + 3 * j) for j, name in enumerate(names)]


def label_rows(n: int, first: set[int], room: float) -> list[int]:
    """Rows to label out of ``n``: those in ``first``, then every other row that keeps
    about ``n / room`` rows away from the labelled ones."""
    gap = max(1.0, n / max(room, 1.0))
    keep = sorted(first)
    for i in range(n):
        if all(abs(i - k) >= gap for k in keep):
            keep.append(i)
    return sorted(keep)


def plot_filter_widths(ax, sigma_frames: np.ndarray, fps: float, names=(), title: str = "",
                       vmax: float | None = None, highlight=()) -> None:
    """Heatmap of ``sigma_frames`` (F, C) over time (s) with a logarithmic colour bar from
    :data:`NARROWEST_FRAMES` to ``vmax`` (default: the widest); rows labelled by joint
    when C matches the channel layout of the joints ``names``; the rows of the joints in
    ``highlight`` (indices) are labelled in bold."""
    from matplotlib.colors import LogNorm

    F, C = sigma_frames.shape
    top = vmax or float(np.nanmax(sigma_frames, initial=0.0))
    norm = LogNorm(NARROWEST_FRAMES, max(top, 10 * NARROWEST_FRAMES), clip=True)
    im = ax.imshow(sigma_frames.T, aspect="auto", interpolation="nearest", cmap="viridis",
                   extent=(0, F / fps, C, 0), norm=norm)
    bar = ax.figure.colorbar(im, ax=ax, pad=0.01, fraction=0.04)
    bar.set_ticks([t for t in (0.2, 0.5, 1, 2, 5, 10, 20, 50, 100, 200, 500) if norm.vmin <= t <= norm.vmax],
                  labels=None, minor=False)
    bar.ax.yaxis.set_major_formatter("{x:g}")
    bar.ax.yaxis.set_minor_formatter("")
    bar.set_label("σ (frames)")
    groups = channel_groups(names, C)
    bold = {j + 1 for j in highlight} if len(groups) > 1 else set()  # group i is joint i - 1
    keep = label_rows(len(groups), bold, ax.get_window_extent().height / LABEL_PX)
    ax.set_yticks([(groups[i][1] + groups[i][2]) / 2 for i in keep], [groups[i][0] for i in keep],
                  fontsize="x-small")
    for tick, i in zip(ax.get_yticklabels(), keep, strict=True):
        tick.set_fontweight("bold" if i in bold else "normal")
    ax.set_xlabel("time (s)")
    if title:
        ax.set_title(title, loc="left", fontsize="medium")
