"""The 3D scene builder rendered off-screen (no Qt): joints are where the camera
projects them, in the colour of their error, missing joints grey, the truth green;
picking finds the joint under a pixel; the camera follows the root."""

from __future__ import annotations

import numpy as np
import pytest
from app_helpers import FRAME, assert_colour, error_colour, rgb

from workbench.app.take import scene_panes
from workbench.plots.style import JOINTS, MISSING, TRUTH
from workbench.render import SkeletonScene, new_plotter

SIZE = (900, 420)


@pytest.fixture
def scene(take, runs):
    panes = scene_panes(take, ["identity"], {r.spec: r for r in runs}, compare=False)
    plotter = new_plotter(len(panes), SIZE)
    scene = SkeletonScene(plotter, panes, take.motion.skeleton, take.root, take.error_scale_cm())
    scene.set_frame(FRAME)
    yield scene
    plotter.close()


def image(scene) -> np.ndarray:
    scene.plotter.render()
    return np.asarray(scene.plotter.screenshot(return_img=True))


def joint_xy(scene, pane: int, joint: int):
    return scene.project(pane, scene.panes[pane].points[scene.frame, [joint]])[0]


def test_panes_are_noisy_cleaned_truth(scene):
    assert [p.title.split("\n")[0] for p in scene.panes] == ["noisy", "cleaned", "ground truth"]
    assert scene.panes[1].ghost is not None, "the truth is faded into the cleaned pane"


def test_joints_are_drawn_where_the_camera_projects_them_in_their_error_colour(scene, take):
    img = image(scene)
    names = take.motion.skeleton.names
    head = names.index("Head")
    clim = take.error_scale_cm()
    assert_colour(img, joint_xy(scene, 2, head), TRUTH, what="truth pane Head")
    assert_colour(
        img, joint_xy(scene, 0, head), error_colour(take.noisy.errors_cm[FRAME, head], clim), what="noisy pane Head"
    )
    foot = names.index("LeftToeBase")  # far off in the noisy take: the top of the scale
    assert take.noisy.errors_cm[FRAME, foot] > clim[1]
    assert_colour(img, joint_xy(scene, 0, foot), error_colour(clim[1], clim), what="noisy pane LeftToeBase")


def test_missing_joints_are_grey(scene, take):
    knee = take.motion.skeleton.names.index("LeftLeg")
    assert take.missing[FRAME, knee], "the fixture's take misses LeftLeg at FRAME"
    assert_colour(image(scene), joint_xy(scene, 0, knee), MISSING, what="missing LeftLeg")


def test_a_selected_joint_is_ringed_in_its_plot_colour(scene, take):
    head = take.motion.skeleton.names.index("Head")
    scene.set_selection((head,))
    img = image(scene)
    xy = joint_xy(scene, 2, head)
    assert_colour(img, xy, TRUTH, what="the joint stays on top")
    ring = [xy + np.array([dx, dy]) for dx, dy in ((9, 0), (-9, 0), (0, 9), (0, -9))]
    hits = [np.abs(img[int(y), int(x), :3] - rgb(JOINTS[0])).max() < 20 for x, y in ring]
    assert sum(hits) >= 2, "a ring in the first joint colour around the selected joint"


def test_pick_finds_the_joint_under_the_pixel(scene, take):
    image(scene)
    names = take.motion.skeleton.names
    for name in ("Head", "LeftHand", "RightFoot"):
        j = names.index(name)
        x, y = joint_xy(scene, 1, j)
        assert scene.pick(x + 2, y - 1) == j, name
    assert scene.pick(5, SIZE[1] - 5) is None, "nothing in a corner"


def test_the_camera_follows_the_root(scene, take):
    image(scene)
    xy0 = joint_xy(scene, 2, 0)
    scene.set_frame(FRAME + 40)
    xy1 = joint_xy(scene, 2, 0)
    assert np.abs(xy1 - xy0).max() < 25, "the root stays put on screen while following"
    scene.set_follow(False)
    scene.set_frame(FRAME)
    a = joint_xy(scene, 2, 0)
    scene.set_frame(FRAME + 40)
    b = joint_xy(scene, 2, 0)
    assert np.abs(b - a).max() > 3, "a fixed camera sees the walker move"


def test_no_ground_truth_says_so(clean_take):
    panes = scene_panes(clean_take, ["identity"], {}, compare=False)
    assert panes[-1].points is None and "no ground truth" in panes[-1].note
    assert panes[1].note == "running...", "an engine without a result yet"


def test_frames_a_kilometre_off_are_shown_but_not_framed(take):
    """An exporter's stray frames put the body 1.5 km off, and an engine thrown by them
    puts joints tens of metres off elsewhere: the floor and camera fit the body where it
    is, and the floor stays a few metres of grid (it once tried to cover 3 km by the metre,
    and the app ran out of memory)."""
    from workbench.render import Pane, skeleton_points

    motion = take.motion
    root = motion.root_positions.copy()
    root[:5] += 150_000.0 / motion.skeleton.unit_cm  # 1.5 km
    stray = motion.replace(root_positions=root)
    thrown = skeleton_points(motion).copy()
    thrown[10:20, 3] += 4_000.0 / motion.skeleton.unit_cm  # a joint 40 m off the body
    panes = [Pane("stray", skeleton_points(stray)), Pane("thrown", thrown)]
    plotter = new_plotter(2, SIZE)
    try:
        scene = SkeletonScene(plotter, panes, motion.skeleton, skeleton_points(stray)[:, 0], (0.0, 5.0))
        body = skeleton_points(motion)[..., 1]
        assert scene.floor_y == pytest.approx(np.min(body)) and scene.height == pytest.approx(np.ptp(body))
        floor = plotter.renderers[0].actors  # the floor's plane and its grid
        assert max(a.GetMapper().GetInput().GetNumberOfCells() for a in floor.values()) < 10_000
    finally:
        plotter.close()
