"""Plots over time: joint errors with the gaps shaded, and a time cursor that moves by
blitting (the figure is drawn once; moving the cursor restores the saved background
and draws one line per axes).

Units: time in seconds on the x axis (frame / fps); errors in cm.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from .style import CURSOR, ERROR_LABEL, GAP, TEXT


@dataclass(frozen=True)
class Series:
    """One line: values (F,) in cm, drawn with a colour, width, style and alpha."""

    label: str
    values: np.ndarray
    colour: str
    width: float = 1.2
    style: str = "-"
    alpha: float = 1.0


def gap_spans(missing: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) frame spans where ``missing`` (F,) bool is True."""
    m = np.concatenate([[0], np.asarray(missing, np.int8), [0]])
    edges = np.flatnonzero(np.diff(m))
    return [(int(a), int(b)) for a, b in edges.reshape(-1, 2)]


def shade_gaps(ax, missing: np.ndarray, fps: float, label: str = "gaps") -> None:
    """Shade the time spans where ``missing`` (F,) is True."""
    for k, (a, b) in enumerate(gap_spans(missing)):
        ax.axvspan(a / fps, b / fps, color=GAP, alpha=0.28, lw=0, label=label if k == 0 else None)


def plot_errors(
    ax, series: list[Series], fps: float, missing: np.ndarray | None = None, title: str = "", ylabel: str = ERROR_LABEL
) -> None:
    """Joint error over time (cm), one line per series, gap spans shaded where
    ``missing`` (F,) is True."""
    n = len(series[0].values)
    t = np.arange(n) / fps
    if missing is not None:
        shade_gaps(ax, missing, fps)
    for s in series:
        ax.plot(t, s.values, color=s.colour, lw=s.width, ls=s.style, alpha=s.alpha, label=s.label)
    ax.set_xlim(0, max(t[-1], 1 / fps))
    ax.set_ylim(0, None)
    ax.set_xlabel("time (s)")
    ax.set_ylabel(ylabel)
    ax.grid(True, color="#e3e6ea", lw=0.8)
    ax.set_axisbelow(True)
    if title:
        ax.set_title(title, loc="left", fontsize="medium")
    outside_legend(ax)


#: legend labels longer than this (characters) are wrapped, so a long engine spec does
#: not squeeze the axes
LEGEND_CHARS = 24


def wrap_label(text: str, width: int = LEGEND_CHARS) -> str:
    """``text`` on lines of at most ``width`` characters where it can be broken: after a
    space or a spec's separators (``:``, ``,``, ``>``); longer pieces stay whole."""
    lines = [""]
    for piece in re.split(r"(?<=[ :,>])", text):
        if lines[-1] and len(lines[-1] + piece.rstrip()) > width:
            lines.append("")
        lines[-1] += piece
    return "\n".join(line.rstrip() for line in lines)


def outside_legend(ax) -> None:
    """The legend to the right of the axes (a fixed place: "best" made images flaky),
    long labels wrapped (:func:`wrap_label`)."""
    handles, labels = ax.get_legend_handles_labels()
    ax.legend(
        handles,
        [wrap_label(label) for label in labels],
        loc="upper left",
        bbox_to_anchor=(1.01, 1.0),
        fontsize="small",
        frameon=False,
        borderaxespad=0,
    )


def plot_note(ax, text: str) -> None:
    """An empty axes that says why there is nothing to plot."""
    ax.set_axis_off()
    ax.text(0.5, 0.5, text, ha="center", va="center", transform=ax.transAxes, color=TEXT, fontsize="medium", wrap=True)


class TimeCursor:
    """A vertical line at the current time on each of ``axes`` (all of one figure),
    moved by blitting: :meth:`move` costs a background restore and a line per axes,
    never a figure redraw. ``animated=False`` draws an ordinary line (for a saved figure)."""

    def __init__(self, axes: list, fps: float, animated: bool = True) -> None:
        self.fps, self.animated = fps, animated
        self.lines = [ax.axvline(0.0, color=CURSOR, lw=1.4, animated=animated, zorder=5) for ax in axes]
        self.canvas = axes[0].figure.canvas if axes else None
        self.background = None
        self._cid = self.canvas.mpl_connect("draw_event", self._on_draw) if animated and axes else None

    @property
    def x(self) -> float:
        """The cursor's time (s)."""
        return float(self.lines[0].get_xdata()[0]) if self.lines else 0.0

    def _on_draw(self, _event) -> None:
        self.background = self.canvas.copy_from_bbox(self.canvas.figure.bbox)
        self._draw_lines()

    def _draw_lines(self) -> None:
        for line in self.lines:
            line.axes.draw_artist(line)

    def remove(self) -> None:
        """Stop listening to the canvas (before the figure is cleared)."""
        if self._cid is not None:
            self.canvas.mpl_disconnect(self._cid)

    def move(self, frame: int, blit: bool = True) -> None:
        """Put the cursor on ``frame``; blit it when asked and the figure has been drawn."""
        x = frame / self.fps
        for line in self.lines:
            line.set_xdata([x, x])
        if blit and self.animated and self.background is not None:
            self.canvas.restore_region(self.background)
            self._draw_lines()
            for line in self.lines:
                self.canvas.blit(line.axes.bbox)
