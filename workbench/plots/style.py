"""Colours shared by the 3D scenes and the plots, so a source looks the same everywhere."""

from __future__ import annotations

import numpy as np

TRUTH = "#2e9d5b"
NOISY = "#8a9099"
PLAIN = "#3f74c9"  # joints when there is no error to show
MISSING = "#b4b8bf"  # joints missing from the observation
CURSOR = "#d62728"
GAP = "#8f9aa8"
TEXT = "#20242a"
ENGINES = ("#1f77b4", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf", "#bcbd22", "#d62728")
JOINTS = ("#e41a1c", "#377eb8", "#4daf4a", "#984ea3", "#ff7f00", "#a65628")
ENGINE_STYLES = ("-", "--", ":", "-.")
#: the suspicious-frames track: a colour per reason of :mod:`workbench.data.inspection`
REASON_COLOURS = {
    "spike": "#d62728",
    "turn": "#9467bd",
    "jump": "#2ca02c",
    "linear": "#ff7f0e",
    "bone": "#8c564b",
    "missing": "#8f9aa8",
    "rejected": "#e377c2",
    "disagree": "#1f77b4",
}


def engine_colour(i: int) -> str:
    return ENGINES[i % len(ENGINES)]


def error_cmap():
    """The joint-error colour map: plasma without its pale yellow end, which is
    unreadable on a light background."""
    from matplotlib import colormaps
    from matplotlib.colors import ListedColormap

    return ListedColormap(colormaps["plasma"](np.linspace(0.0, 0.85, 256)), name="joint-error")


ERROR_LABEL = "joint error (cm)"
#: the same scale on a take without a truth: how far cleaning moved each joint
MOVED_LABEL = "moved from the recording (cm)"
#: the same on the error plot's y axis, whose title says from what
MOVED_AXIS_LABEL = "moved (cm)"


def error_mappable(clim_cm: tuple[float, float]):
    """The joint-error colours over ``clim_cm`` (lo, hi) in cm, for a colour bar."""
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    return ScalarMappable(Normalize(*clim_cm), error_cmap())
