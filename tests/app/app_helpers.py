"""Helpers of the app tests: waiting for the worker, pixel probes, reference images.

Reference images live in tests/app/reference/; ``WORKBENCH_REGENERATE_REFERENCE=1``
rewrites them (see test_reference_images.py). Failing images and their diffs are
written to test-output/app/ (gitignored).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

OUTPUT = Path(__file__).resolve().parents[2] / "test-output" / "app"
REFERENCE = Path(__file__).resolve().parent / "reference"
FRAMES = 120
FRAME = 60  # the frame the pictures are taken at


def settle(qtbot, win, timeout: int = 20000) -> None:
    """Wait until the worker is idle and its results are drawn."""
    qtbot.waitUntil(lambda: not win.session.busy, timeout=timeout)
    qtbot.wait(30)


# -- pixels -----------------------------------------------------------------------------
def rgb(colour: str) -> np.ndarray:
    from matplotlib.colors import to_rgb

    return np.round(np.array(to_rgb(colour)) * 255)


def pixel(image: np.ndarray, xy) -> np.ndarray:
    """The median colour of the 3x3 pixels around (x, y)."""
    x, y = int(round(xy[0])), int(round(xy[1]))
    return np.median(image[y - 1 : y + 2, x - 1 : x + 2, :3].reshape(-1, 3), axis=0)


def assert_colour(image: np.ndarray, xy, colour, tol: float = 12, what: str = "") -> None:
    want = rgb(colour) if isinstance(colour, str) else np.asarray(colour, float)
    got = pixel(image, xy)
    assert np.abs(got - want).max() <= tol, f"{what}: pixel at {xy} is {got}, want {want}"


def error_colour(error_cm: float, clim) -> np.ndarray:
    """The colour a joint with ``error_cm`` is drawn in (0-255 RGB)."""
    from workbench.plots.style import error_cmap

    t = np.clip((error_cm - clim[0]) / (clim[1] - clim[0]), 0, 1)
    return np.round(np.array(error_cmap()(t)[:3]) * 255)


def output_path(name: str) -> Path:
    """A path in test-output/app for a failing image or its diff."""
    OUTPUT.mkdir(parents=True, exist_ok=True)
    return OUTPUT / name


def regenerate() -> bool:
    return os.environ.get("WORKBENCH_REGENERATE_REFERENCE") == "1"
