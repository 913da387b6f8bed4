"""A few pictures compared with reference images, with a tolerance: the 3D scene
(pyvista.compare_images) and the plot figures (matplotlib's compare_images, tol 2).

Regenerate the references (on this machine kind: software rendering, matplotlib 3.11)
after an intended change of the pictures, then look at them::

    WORKBENCH_REGENERATE_REFERENCE=1 python -m pytest tests/app/test_reference_images.py

On a mismatch the picture and its diff are written to test-output/app/.
"""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from app_helpers import FRAME, REFERENCE, output_path, regenerate

from workbench.app.figures import draw_bone_lengths, draw_errors, draw_filter_widths
from workbench.app.take import scene_panes
from workbench.render import SkeletonScene, new_plotter

SCENE_THRESHOLD = 2.0  # pyvista.compare_images error (mean per-pixel difference)
FIGURE_TOL = 2.0


def check_figure(fig, name: str) -> None:
    from matplotlib.testing.compare import compare_images

    actual = output_path(f"{name}.png")
    fig.savefig(actual, dpi=80)
    reference = REFERENCE / f"{name}.png"
    if regenerate():
        REFERENCE.mkdir(exist_ok=True)
        shutil.copy(actual, reference)
        pytest.skip(f"regenerated {reference}")
    failure = compare_images(str(reference), str(actual), tol=FIGURE_TOL)  # writes a -failed-diff.png beside
    assert failure is None, failure
    actual.unlink()


def figure():
    from matplotlib.figure import Figure

    return Figure(figsize=(9, 3.2), layout="constrained")


def test_scene_matches_reference(take, runs):
    import pyvista as pv

    panes = scene_panes(take, [r.spec for r in runs], {r.spec: r for r in runs}, compare=True)
    plotter = new_plotter(len(panes), (900, 360))
    try:
        scene = SkeletonScene(
            plotter,
            panes,
            take.motion.skeleton,
            take.root,
            take.error_scale_cm(),
            selected=(take.motion.skeleton.index("LeftFoot"),),
        )
        scene.set_frame(FRAME)
        image = np.asarray(plotter.screenshot(return_img=True))
    finally:
        plotter.close()
    reference = REFERENCE / "scene.png"
    if regenerate():
        REFERENCE.mkdir(exist_ok=True)
        _save_png(image, reference)
        pytest.skip(f"regenerated {reference}")
    error = pv.compare_images(image, str(reference))
    if error > SCENE_THRESHOLD:
        _save_png(image, output_path("scene.png"))
        expected = _load_png(reference)
        diff = np.abs(image[..., :3].astype(int) - expected[..., :3].astype(int)).astype(np.uint8)
        _save_png(diff * 4, output_path("scene-diff.png"))
    assert error <= SCENE_THRESHOLD, f"3D scene differs from {reference} by {error:.2f}; see test-output/app/"


def _save_png(image: np.ndarray, path) -> None:
    from matplotlib.image import imsave

    imsave(path, np.asarray(image)[..., :3].astype(np.uint8))


def _load_png(path) -> np.ndarray:
    from matplotlib.image import imread

    return (imread(path)[..., :3] * 255).round().astype(np.uint8)


def test_error_plot_matches_reference(take, runs):
    fig = figure()
    draw_errors(fig, take, runs, (take.motion.skeleton.index("LeftFoot"),))
    check_figure(fig, "errors")


def test_filter_widths_match_reference(take, runs):
    fig = figure()
    draw_filter_widths(fig, take, runs, ())
    check_figure(fig, "filter_widths")


def test_bone_lengths_match_reference(take, runs):
    fig = figure()
    draw_bone_lengths(fig, take, runs, ())
    check_figure(fig, "bone_lengths")
