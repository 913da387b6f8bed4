"""matplotlib functions that draw onto a given Axes, with no Qt: the app's plot tabs,
the report figure and the tests use the same ones."""

from .bones import plot_bone_lengths
from .heatmap import plot_data_weights, plot_filter_widths
from .timeline import TimeCursor, gap_spans, plot_errors, plot_note

__all__ = [
    "plot_errors",
    "plot_filter_widths",
    "plot_data_weights",
    "plot_bone_lengths",
    "plot_note",
    "gap_spans",
    "TimeCursor",
]
