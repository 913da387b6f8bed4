"""Heatmaps of channels x time: what an engine chose for every channel and frame.

Two kinds, drawn by one function (:func:`plot_channel_map`):

* filter widths (:func:`plot_filter_widths`), the Gaussian kernel's standard deviation
  in frames, on a logarithmic colour scale: widths span a fraction of a frame (a channel
  kept as it is) to hundreds (a channel averaged flat over the filter's whole reach),
  and both ends matter;
* data weights (:func:`plot_data_weights`) of a robust estimator, 0 to 1: 1 for a
  sample taken at face value, near 0 for one treated as an outlier; missing samples
  (NaN) grey.

Time in seconds. Rows are labelled by joint when the matrix is the channel layout (root
position, then three angles per joint) or three coordinates per joint.
"""

from __future__ import annotations

import numpy as np

LABEL_PX = 11  # vertical room one row label needs
#: the narrowest width on the colour scale, frames: narrower ones (0 for a channel passed
#: through) take its colour, a Gaussian that leaves its neighbours under 1e-5 of the weight
NARROWEST_FRAMES = 0.2
#: colour of missing samples in the data-weight map
MISSING_COLOUR = "#cfcfcf"


def channel_groups(names, n_channels: int, translated=()) -> list[tuple[str, int, int, int | None]]:
    """(label, first row, stop row, joint index or None) of each group of rows: the root
    position, each joint's three angles, then the translation of each ``translated``
    joint (indices) when the matrix is the channel layout (3 + 3J + 3T), each joint's
    three coordinates when it has 3J rows, else one group."""
    J, T = len(names), len(translated)
    if n_channels == 3 + 3 * J + 3 * T:
        return (
            [("root position", 0, 3, None)]
            + [(n, 3 + 3 * j, 6 + 3 * j, j) for j, n in enumerate(names)]
            + [(f"{names[j]} translation", 3 + 3 * (J + k), 6 + 3 * (J + k), j) for k, j in enumerate(translated)]
        )
    if n_channels == 3 * J and J:
        return [(n, 3 * j, 3 + 3 * j, j) for j, n in enumerate(names)]
    return [("channels", 0, n_channels, None)]


def label_rows(n: int, first: set[int], room: float) -> list[int]:
    """Rows to label out of ``n``: those in ``first``, then every other row that keeps
    about ``n / room`` rows away from the labelled ones."""
    gap = max(1.0, n / max(room, 1.0))
    keep = sorted(first)
    for i in range(n):
        if all(abs(i - k) >= gap for k in keep):
            keep.append(i)
    return sorted(keep)


def plot_channel_map(
    ax,
    values: np.ndarray,
    fps: float,
    norm,
    cmap,
    bar_label: str,
    bar_ticks,
    names=(),
    title: str = "",
    highlight=(),
    translated=(),
) -> None:
    """Heatmap of ``values`` (F, C) over time (s) with a colour bar (``norm``, ``cmap``,
    ticks at ``bar_ticks``, plain numbers); rows labelled by joint (:func:`channel_groups`
    of the joints ``names`` and the ``translated`` ones), those of the joints in
    ``highlight`` (indices) in bold."""
    F, C = values.shape
    im = ax.imshow(values.T, aspect="auto", interpolation="nearest", cmap=cmap, extent=(0, F / fps, C, 0), norm=norm)
    bar = ax.figure.colorbar(im, ax=ax, pad=0.01, fraction=0.04)
    bar.set_ticks(bar_ticks)
    bar.ax.yaxis.set_major_formatter("{x:g}")
    bar.ax.yaxis.set_minor_formatter("")
    bar.set_label(bar_label)
    groups = channel_groups(names, C, translated)
    chosen = set(highlight)
    bold = {i for i, g in enumerate(groups) if g[3] in chosen}
    keep = label_rows(len(groups), bold, ax.get_window_extent().height / LABEL_PX)
    ax.set_yticks([(groups[i][1] + groups[i][2]) / 2 for i in keep], [groups[i][0] for i in keep], fontsize="x-small")
    for tick, i in zip(ax.get_yticklabels(), keep, strict=True):
        tick.set_fontweight("bold" if i in bold else "normal")
    ax.set_xlabel("time (s)")
    if title:
        ax.set_title(title, loc="left", fontsize="medium")


def plot_filter_widths(
    ax,
    sigma_frames: np.ndarray,
    fps: float,
    names=(),
    title: str = "",
    vmax: float | None = None,
    highlight=(),
    translated=(),
) -> None:
    """Heatmap of ``sigma_frames`` (F, C) with a logarithmic colour bar from
    :data:`NARROWEST_FRAMES` to ``vmax`` (default: the widest)."""
    from matplotlib.colors import LogNorm

    top = vmax or float(np.nanmax(sigma_frames, initial=0.0))
    norm = LogNorm(NARROWEST_FRAMES, max(top, 10 * NARROWEST_FRAMES), clip=True)
    ticks = [t for t in (0.2, 0.5, 1, 2, 5, 10, 20, 50, 100, 200, 500) if norm.vmin <= t <= norm.vmax]
    plot_channel_map(ax, sigma_frames, fps, norm, "viridis", "σ (frames)", ticks, names, title, highlight, translated)


def plot_data_weights(
    ax, weights: np.ndarray, fps: float, names=(), title: str = "", highlight=(), translated=()
) -> None:
    """Heatmap of a robust estimator's data ``weights`` (F, C), 0 (dark red: an outlier)
    to 1 (white: taken at face value); NaN (missing) in :data:`MISSING_COLOUR`."""
    import matplotlib
    from matplotlib.colors import Normalize

    cmap = matplotlib.colormaps["Reds_r"].with_extremes(bad=MISSING_COLOUR)
    plot_channel_map(
        ax,
        np.ma.masked_invalid(weights),
        fps,
        Normalize(0.0, 1.0),
        cmap,
        "data weight",
        [0, 0.5, 1],
        names,
        title,
        highlight,
        translated,
    )
