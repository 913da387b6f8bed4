"""The main window, driven through pytest-qt: its main states checked on the picture
(pixel probes of joints projected through the camera) and on the Session's state;
playing, stepping, scrubbing, picking a joint, changing engines (run by the worker),
and an engine that fails."""

from __future__ import annotations

import dataclasses
import subprocess
import sys

import numpy as np
from app_helpers import FRAME, assert_colour, error_colour, rgb, settle
from PySide6.QtCore import QPoint, QPointF, Qt
from PySide6.QtGui import QWheelEvent
from PySide6.QtWidgets import QApplication

from workbench.app.take import EngineRun
from workbench.core.motion import channel_mask
from workbench.plots.style import CURSOR, TRUTH


def panes_image(win) -> np.ndarray:
    return win.scene.grab_panes()


def joint_xy(win, pane: int, joint: int):
    scene = win.scene.scene
    return scene.project(pane, scene.panes[pane].points[scene.frame, [joint]])[0]


def head(take) -> int:
    return take.motion.skeleton.index("Head")


def test_default_state_shows_noisy_cleaned_and_truth(window, take):
    s = window.session
    assert [p.title.split("\n")[0] for p in window.scene.scene.panes] == ["noisy", "cleaned", "ground truth"]
    assert isinstance(s.runs["identity"], EngineRun) and isinstance(s.runs["test-widths"], EngineRun)
    img = panes_image(window)
    j = head(take)
    assert_colour(img, joint_xy(window, 2, j), TRUTH, what="truth pane Head")
    err = s.runs["identity"].track.errors_cm[FRAME, j]
    assert_colour(img, joint_xy(window, 1, j), error_colour(err, take.error_scale_cm()), what="cleaned Head")


def test_the_window_grab_shows_the_3d_views(window, take):
    """What the user sees (the whole window) holds the 3D panes, not a blank widget."""
    grab = window.grab().toImage()
    origin = window.scene.mapTo(window, QPoint(0, 0))
    ratio = window.scene.devicePixelRatioF()
    x, y = joint_xy(window, 2, head(take)) / ratio
    colour = grab.pixelColor(origin.x() + int(round(x)), origin.y() + int(round(y)))
    assert np.abs(np.array([colour.red(), colour.green(), colour.blue()]) - rgb(TRUTH)).max() <= 12


def test_compare_mode_shows_every_engine_side_by_side(window, qtbot):
    window.session.set_compare(True)
    settle(qtbot, window)
    titles = [p.title for p in window.scene.scene.panes]
    assert titles == ["noisy\nangular:0.5\n+gaps:0.01", "cleaned\nidentity", "cleaned\ntest-widths"]
    assert len(window.plots.canvases[0].figure.axes[0].get_lines()) >= 3, "an RMS line per engine and the noisy"


def test_play_advances_frames_and_redraws(window, qtbot):
    s = window.session
    before = panes_image(window).copy()
    window.controls.take.corruption.setFocus()
    qtbot.mouseClick(window.scene.surface, Qt.LeftButton, pos=QPoint(5, 5))  # takes the focus from the text
    qtbot.keyClick(window.focusWidget(), Qt.Key_Space)
    assert s.playing
    qtbot.waitUntil(lambda: s.frame > FRAME + 5, timeout=5000)
    qtbot.keyClick(window.focusWidget(), Qt.Key_Space)
    assert not s.playing
    qtbot.wait(30)
    assert window.transport.slider.value() == s.frame
    assert np.abs(panes_image(window).astype(int) - before).max() > 50, "the skeletons moved"


def test_arrow_keys_step_one_frame(window, qtbot):
    s = window.session
    focus = window.focusWidget()
    assert focus is window.scene, "the 3D view has the keyboard at the start"
    qtbot.keyClick(focus, Qt.Key_Right)
    assert s.frame == FRAME + 1
    qtbot.keyClick(focus, Qt.Key_Left)
    qtbot.keyClick(focus, Qt.Key_Left)
    assert s.frame == FRAME - 1


def test_scrubbing_moves_the_time_cursor_without_redrawing(window, qtbot):
    canvas = window.plots.canvases[0]
    draws = []
    canvas.mpl_connect("draw_event", draws.append)
    window.transport.slider.setValue(90)
    qtbot.wait(50)
    assert window.session.frame == 90
    cursor = window.plots.cursors[0]
    assert cursor.x == 90 / window.session.take.fps
    assert not draws, "the cursor moves by blitting, not by redrawing the figure"
    ax = canvas.figure.axes[0]
    x, _ = ax.transData.transform((cursor.x, 0))
    _, y = ax.transAxes.transform((0, 0.5))
    img = np.asarray(canvas.buffer_rgba())
    row = int(img.shape[0] - y)
    near = img[row, int(x) - 2 : int(x) + 3, :3].astype(int)
    assert (np.abs(near - rgb(CURSOR)).max(axis=1) < 40).any(), "the red cursor is drawn at frame 90"


def test_clicking_a_joint_selects_it_in_the_plots(window, qtbot, take):
    foot = take.motion.skeleton.index("RightFoot")
    x, y = joint_xy(window, 1, foot) / window.scene.devicePixelRatioF()
    qtbot.mouseClick(window.scene.surface, Qt.LeftButton, pos=QPoint(int(round(x)), int(round(y))))
    assert window.session.selected == (foot,)
    labels = [line.get_label() for line in window.plots.canvases[0].figure.axes[0].get_lines()]
    assert "RightFoot · identity" in labels
    bones = tab(window, "Bone lengths")
    window.plots.setCurrentIndex(bones)
    ticks = [t.get_text() for t in window.plots.canvases[bones].figure.axes[0].get_xticklabels()]
    assert ticks == ["RightLeg →\nRightFoot"], "the bone plot shows the selected joint's bone"


def test_a_selected_joint_is_kept_by_name_across_takes(window, qtbot, take):
    from workbench.app.take import open_take

    s = window.session
    foot = take.motion.skeleton.index("RightFoot")
    s.select_joint(foot)
    s.set_take(take)
    assert s.selected == (foot,), "the same skeleton: the same joint"
    s.set_take(open_take("bandai/walk/dataset-1_walk_happy_001", "none", 0))
    assert s.selected == (), "another skeleton's joint of that index is another joint"
    settle(qtbot, window)


def test_an_engine_ticked_again_while_it_runs_runs_once(window, qtbot, monkeypatch):
    import time

    from workbench import registry
    from workbench.engine import CleanResult, Engine, EngineInfo

    calls = []

    class Slow(Engine):
        info = EngineInfo(name="test-slow", summary="test: a slow clean", tasks=frozenset({"fill"}))

        def clean(self, observation, /):
            calls.append(1)
            time.sleep(0.4)
            return CleanResult(observation.bridged())

    monkeypatch.setitem(registry._registered, "test-slow", Slow)
    s = window.session
    for _ in range(4):  # ticked, unticked and ticked again while it runs or waits
        s.set_specs(["identity", "test-widths", "test-slow"])
        qtbot.wait(30)
        s.set_specs(["identity", "test-widths"])
        qtbot.wait(30)
    s.set_specs(["identity", "test-widths", "test-slow"])
    settle(qtbot, window)
    assert len(calls) == 1 and isinstance(s.runs["test-slow"], EngineRun) and not s.running
    # unticked while it waits, so the worker skips it, and ticked again before the skip is
    # heard: it runs after all (it was left with an empty failure)
    s.set_take(s.take)
    qtbot.waitUntil(lambda: "test-slow" in s.running, timeout=5000)
    s.set_specs(["identity", "test-widths", "test-slow", "lerp"])
    s.set_specs(["identity", "test-widths", "test-slow"])
    time.sleep(0.8)  # the worker ends the slow run and skips lerp's; no event is handled meanwhile
    s.set_specs(["identity", "test-widths", "test-slow", "lerp"])
    settle(qtbot, window)
    assert isinstance(s.runs.get("lerp"), EngineRun) and not s.running


def test_changing_the_engine_recomputes_on_the_worker(window, qtbot):
    s = window.session
    with qtbot.waitSignal(s.busyChanged, timeout=5000):
        s.set_specs(["identity", "test-widths", "lerp"], "lerp")
    assert s.busy or "lerp" in s.runs, "the run was queued on the worker"
    settle(qtbot, window)
    assert isinstance(s.runs["lerp"], EngineRun)
    assert window.scene.scene.panes[1].title == "cleaned\nlerp"
    assert window.plots.canvases[0].figure.axes[0].get_legend_handles_labels()[1][-1] == "lerp (RMS)"


def test_checking_an_engine_in_the_list_runs_it(window, qtbot):
    panel = window.controls.engines
    item = next(panel.list.item(i) for i in range(panel.list.count()) if panel.list.item(i).data(Qt.UserRole) == "lerp")
    item.setCheckState(Qt.Checked)
    settle(qtbot, window)
    assert window.session.specs[-1] == "lerp" and isinstance(window.session.runs["lerp"], EngineRun)


def tab(window, title: str) -> int:
    """The index of the plot tab called ``title``."""
    return [window.plots.tabText(i) for i in range(window.plots.count())].index(title)


def test_the_outlier_tab_shows_reported_weights_with_missing_samples_grey(window, qtbot, take):
    s = window.session
    s.set_specs(["identity", "test-weights"], "test-weights")
    settle(qtbot, window)
    index = tab(window, "Outlier weights")
    window.plots.setCurrentIndex(index)
    qtbot.wait(50)
    (image,) = window.plots.canvases[index].figure.axes[0].get_images()
    shown = image.get_array().T  # (F, C), masked where missing
    unknown = ~channel_mask(~take.missing, take.motion.skeleton)
    assert unknown.any() and np.array_equal(np.ma.getmaskarray(shown), unknown), "missing samples are grey"
    expected = np.ones(shown.shape)
    expected.flat[::7] = 0.02
    assert np.array_equal(shown.compressed(), expected[~unknown]), "the reported weights, as they are"
    s.set_current("identity")
    qtbot.wait(50)
    texts = [t.get_text() for t in window.plots.canvases[index].figure.axes[0].texts]
    assert texts == ["this engine reports no outlier weights"]


def test_the_heatmap_tab_shows_reported_widths_or_says_there_are_none(window, qtbot):
    s = window.session
    window.plots.setCurrentIndex(1)
    s.set_current("test-widths")
    qtbot.wait(50)
    fig = window.plots.canvases[1].figure
    assert fig.axes[0].get_images(), "a heatmap for an engine that reports widths"
    s.set_current("identity")
    qtbot.wait(50)
    texts = [t.get_text() for t in window.plots.canvases[1].figure.axes[0].texts]
    assert texts == ["this engine reports no filter widths"]


def test_an_engine_error_shows_in_the_window_not_on_the_console(window, qtbot, capfd):
    s = window.session
    s.set_specs(["test-boom", "test-crash"], "test-boom")
    settle(qtbot, window)
    assert "boom: this engine always fails" in s.runs["test-boom"]
    assert s.runs["test-crash"].startswith("ZeroDivisionError")
    log = [window.controls.log.item(i).text() for i in range(window.controls.log.count())]
    assert any("test-boom failed: boom" in line for line in log)
    assert any("test-crash failed: ZeroDivisionError" in line for line in log)
    assert "failed" in window.statusBar().currentMessage()
    assert window.scene.scene.panes[1].note.startswith("failed:")
    assert "Traceback" not in capfd.readouterr().err


def test_a_take_without_ground_truth_says_so_and_plots_how_far_each_engine_moved_it(window, qtbot, clean_take):
    from workbench.app.window import ErrorScale
    from workbench.metrics import joint_position_error_cm
    from workbench.plots.style import MOVED_LABEL

    window.session.set_specs(["identity", "gaussian"], "gaussian")
    window.session.set_take(clean_take)
    settle(qtbot, window)
    panes = window.scene.scene.panes
    assert panes[-1].points is None and "no ground truth" in panes[-1].note
    # the cleaned joints are coloured by how far the engine moved them, on the scale so labelled
    (scale,) = window.transport.findChildren(ErrorScale)
    assert scale.figure.axes[0].get_xlabel() == MOVED_LABEL
    j = head(clean_take)
    moved_head = joint_position_error_cm(clean_take.observation.motion, window.session.runs["gaussian"].track.motion)
    assert_colour(
        panes_image(window),
        joint_xy(window, 1, j),
        error_colour(moved_head[FRAME, j], clean_take.error_scale_cm()),
        what="cleaned Head",
    )
    window.session.set_compare(True)  # a line per engine
    settle(qtbot, window)
    ax = window.plots.canvases[0].figure.axes[0]
    assert "no ground truth" in ax.get_title(loc="left") and "moved" in ax.get_ylabel()
    lines = {line.get_label(): np.asarray(line.get_ydata()) for line in ax.get_lines()}
    assert "noisy (RMS)" not in lines
    np.testing.assert_allclose(lines["identity (RMS)"], 0.0, atol=1e-9)  # identity keeps the recording
    smoothed = window.session.runs["gaussian"].track.motion
    moved = np.sqrt(np.mean(joint_position_error_cm(clean_take.observation.motion, smoothed) ** 2, axis=1))
    assert moved.max() > 0.01
    np.testing.assert_allclose(lines["gaussian (RMS)"], moved)


def test_without_ground_truth_a_selected_joint_gets_a_line_per_engine_and_no_noisy_line(clean_take):
    from workbench.app.figures import error_series
    from workbench.app.take import run_engine
    from workbench.metrics import joint_position_error_cm

    run = run_engine("gaussian", clean_take)
    j = head(clean_take)
    series = error_series(clean_take, [run], (j,))
    assert [s.label for s in series] == ["gaussian (RMS)", "Head · gaussian"]
    moved = joint_position_error_cm(clean_take.observation.motion, run.track.motion)[:, j]
    assert moved.max() > 0.01
    np.testing.assert_allclose(series[1].values, moved)


def test_a_take_without_ground_truth_and_no_run_yet_says_what_the_plot_will_show(clean_take):
    from matplotlib.figure import Figure

    from workbench.app.figures import draw_errors

    fig = Figure()
    draw_errors(fig, clean_take, [], ())
    (note,) = fig.axes[0].texts
    assert "no ground truth" in note.get_text() and "how far it moved the recording" in note.get_text()


def test_opening_a_bad_take_reports_it_and_the_panel_shows_the_take_that_stays(window, qtbot):
    panel, shown = window.controls.take, window.session.take
    panel.clip.setCurrentText("no/such/clip")
    panel.seed.setValue(shown.seed + 5)
    with qtbot.waitSignal(window.session.message, timeout=10000) as blocker:
        panel.apply()
    assert "cannot open no/such/clip" in blocker.args[0]
    assert window.session.take is shown, "the previous take stays"
    qtbot.waitUntil(lambda: panel.clip.currentText() == shown.source, timeout=5000)
    assert panel.seed.value() == shown.seed, "a later edit is not of the take that failed"


def test_dragging_in_the_3d_views_turns_and_zooms_the_linked_cameras(window, qtbot):
    scene = window.scene
    cameras = [r.camera for r in scene.plotter.renderers]
    before = [c.position for c in cameras]
    surface = scene.surface
    start = QPoint(surface.width() // 6, surface.height() // 2)
    qtbot.mousePress(surface, Qt.LeftButton, pos=start)
    for dx in range(10, 80, 10):
        qtbot.mouseMove(surface, start + QPoint(dx, 0))
    qtbot.mouseRelease(surface, Qt.LeftButton, pos=start + QPoint(80, 0))
    turned = [c.position for c in cameras]
    assert turned[0] != before[0] and all(p == turned[0] for p in turned), "turned, and every pane with it"
    assert window.session.selected == (), "a drag is no click"
    image = scene.grab_panes().copy()
    distance = np.linalg.norm(np.subtract(cameras[0].position, cameras[0].focal_point))
    wheel = QWheelEvent(
        QPointF(start),
        QPointF(surface.mapToGlobal(start)),
        QPoint(),
        QPoint(0, 120),
        Qt.NoButton,
        Qt.NoModifier,
        Qt.NoScrollPhase,
        False,
    )
    QApplication.sendEvent(surface, wheel)
    assert np.linalg.norm(np.subtract(cameras[0].position, cameras[0].focal_point)) < distance
    assert not np.array_equal(scene.grab_panes(), image), "the image shows the new view"
    qtbot.keyClick(window.focusWidget(), Qt.Key_R)  # aims the cameras afresh
    np.testing.assert_allclose(scene.plotter.renderers[0].camera.position, before[0], rtol=1e-6)


def test_save_writes_the_highlighted_engines_cleaned_take_as_bvh(window, qtbot, tmp_path, monkeypatch):
    from PySide6.QtWidgets import QFileDialog

    from workbench.io import read_bvh

    s, panel = window.session, window.controls.engines
    s.set_current("test-widths")
    assert panel.save.isEnabled()
    out = tmp_path / "cleaned.bvh"
    asked = []
    monkeypatch.setattr(QFileDialog, "getSaveFileName", lambda *args: (asked.append(args[2]), (str(out), ""))[1])
    qtbot.keyClick(window.focusWidget(), Qt.Key_S, Qt.ControlModifier)
    assert asked == ["35_31_120_frames_test-widths.bvh"]  # the take's name and the engine's, safe characters
    saved, cleaned = read_bvh(out), s.runs["test-widths"].track.motion
    assert saved.n_frames == cleaned.n_frames and saved.skeleton.names == cleaned.skeleton.names
    np.testing.assert_allclose(saved.channels, cleaned.channels, atol=1e-4)
    assert f"saved test-widths's cleaned take to {out}" in window.controls.log.item(0).text()


def test_save_says_why_it_cannot_and_leaves_no_file(window, qtbot, tmp_path):
    s = window.session
    (tmp_path / "a-file").write_text("not a folder")
    target = tmp_path / "a-file" / "x.bvh"
    assert not s.save_current(str(target))
    assert not target.exists() and "cannot save" in window.controls.log.item(0).text()
    s.set_specs(["test-boom"], "test-boom")
    settle(qtbot, window)
    assert not window.controls.engines.save.isEnabled()
    assert not s.save_current(str(tmp_path / "y.bvh"))
    assert not (tmp_path / "y.bvh").exists() and "nothing to save" in window.controls.log.item(0).text()


def test_the_parameter_panel_keeps_a_trained_engines_weights_folder(window, qtbot):
    from engines.mssa import MSSA

    folder = MSSA().default_weights_dir() / "cmu"
    spec = f"mssa:weights={folder}"
    s, panel = window.session, window.controls.engines
    s.set_specs(["identity", spec], spec)
    settle(qtbot, window)
    assert isinstance(s.runs[spec], EngineRun)
    ((name, fields, kept),) = panel.edits
    assert name == "mssa" and fields["weights"].text() == str(folder)
    assert "prior_weight" in fields and "energy_kept" in kept  # energy_kept: fixed by the weights
    fields["prior_weight"].setText("2")
    panel._apply_params()
    assert s.current == f"mssa:prior_weight=2.0,weights={folder}" and s.current in s.specs
    settle(qtbot, window)
    assert isinstance(s.runs[s.current], EngineRun)
    panel.edits[0][1]["weights"].setText("")  # empty: back to the committed weights
    panel._apply_params()
    assert s.current == "mssa:prior_weight=2.0"


def test_the_suspicious_track_marks_intervals_and_n_jumps_to_them(window, qtbot, tiny_walk):
    from workbench.app.take import make_take

    s, track = window.session, window.transport.suspects
    s.set_specs(["identity", "test-weights"], "identity")
    s.set_take(make_take(tiny_walk, "outliers:0.02+gaps:0.01", seed=3, source="spiky walk"))
    settle(qtbot, window)
    reasons = {i.reason for i in track.intervals}
    # the rules' spikes, the mask's gaps, the test engine's "outliers" and the two engines' spread
    assert {"spike", "missing", "rejected"} <= reasons and track.reasons == [r for r in track.reasons]
    assert track.height() == len(track.reasons) * track.ROW_PX + 4
    s.set_frame(0)
    starts = sorted({i.first for i in track.intervals if i.first > 0})
    qtbot.keyClick(window.focusWidget(), Qt.Key_N)
    assert s.frame == starts[0] and not s.playing and str(starts[0]) in window.controls.log.item(0).text()
    qtbot.keyClick(window.focusWidget(), Qt.Key_N)
    assert s.frame == starts[1]
    qtbot.keyClick(window.focusWidget(), Qt.Key_N, Qt.ShiftModifier)
    assert s.frame == starts[0]
    # a click on an interval shows its first frame
    spike = next(i for i in track.intervals if i.reason == "spike")
    row = track.reasons.index("spike")
    x = (track._x(spike.first) + track._x(spike.last)) / 2
    qtbot.mouseClick(track, Qt.LeftButton, pos=QPoint(round(x), 2 + row * track.ROW_PX + 3))
    assert s.frame == spike.first


def test_a_take_without_suspects_says_so(window, qtbot, tiny_walk):
    from workbench.app.take import make_take

    s = window.session
    s.set_specs([])
    still = tiny_walk.replace(angles_deg=np.zeros_like(tiny_walk.angles_deg))  # a pose held: nothing to flag
    s.set_take(make_take(still, "none", source="still"))
    assert s.jump_to_suspect(1) is None  # before the worker has inspected it: not "none found"
    assert window.controls.log.item(0).text() == "the take is still being inspected"
    settle(qtbot, window)
    assert window.transport.suspects.intervals == [] and s.jump_to_suspect(1) is None
    assert window.controls.log.item(0).text() == "no suspicious frames in this take"
    s._inspection_failed(s.take, "a fault")  # as when the rules raise on the worker
    assert s.jump_to_suspect(1) is None
    assert window.controls.log.item(0).text() == "the take could not be inspected: no suspicious frames to show"


def test_the_window_fits_a_laptop_screen_and_the_panel_collapses(window, qtbot):
    from workbench.app.main import fit_to_screen

    hint = window.minimumSizeHint()
    assert hint.width() <= 1366 and hint.height() <= 700  # 768 less a title bar and a task bar
    fit_to_screen(window, (10000, 10000))
    area = window.screen().availableGeometry()
    assert window.frameGeometry().width() <= area.width() and window.frameGeometry().height() <= area.height()
    qtbot.keyClick(window.focusWidget(), Qt.Key_B, Qt.ControlModifier)
    assert window.split.sizes()[0] == 0
    qtbot.keyClick(window.focusWidget(), Qt.Key_B, Qt.ControlModifier)
    assert window.split.sizes()[0] > 0
    window.resize(1200, 800)


def test_the_parameters_are_the_inference_ones_collapsed_per_stage(window, qtbot):
    from workbench.app.controls import Collapsible

    s, panel = window.session, window.controls.engines
    s.set_specs(["identity", "lerp>gaussian", "ebf"], "ebf")
    ((name, fields, kept),) = panel.edits
    assert name == "ebf" and "weights" in fields
    assert not {"epochs", "learning_rate", "batch_windows", "dropout"} & set(fields) and "epochs" in kept
    groups = panel.params_box.findChildren(Collapsible)
    assert len(groups) == 1 and groups[0].body.isHidden()
    groups[0].button.click()
    assert not groups[0].body.isHidden()
    s.set_current("lerp>gaussian")
    panel.refresh()
    assert [name for name, _, _ in panel.edits] == ["lerp", "gaussian"]


def test_the_window_keeps_its_state_between_runs(window, tmp_path):
    from PySide6.QtCore import QSettings

    from workbench.app.main import GEOMETRY_KEY, save_state, saved_take

    path = tmp_path / "workbench.ini"
    settings = QSettings(str(path), QSettings.IniFormat)
    assert saved_take(settings) is None
    s = window.session
    s.set_specs(["identity"])  # one engine: a settings file would give a lone item back as a string
    save_state(window, settings)
    assert QSettings(str(path), QSettings.IniFormat).value(GEOMETRY_KEY) is not None
    code = (
        "import sys\nfrom PySide6.QtCore import QSettings\nfrom workbench.app.main import saved_take\n"
        "print(repr(saved_take(QSettings(sys.argv[1], QSettings.IniFormat))))\n"
    )
    run = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True, text=True, timeout=60)
    assert run.stdout.strip() == repr((s.take.source, s.take.corruption, s.take.seed, ["identity"], False)), run.stderr
    given = s.take
    s.take = dataclasses.replace(given, fill_suspects=True)  # as the ticked box leaves it
    try:
        save_state(window, settings)
    finally:
        s.take = given
    assert saved_take(QSettings(str(path), QSettings.IniFormat))[-1] is True
    (path).write_text("[take]\nsource=x.bvh\ncorruption=none\nseed=zero\n")  # edited by hand: ignored
    assert saved_take(QSettings(str(path), QSettings.IniFormat)) is None


def test_export_video_writes_the_shown_playback(window, qtbot, tmp_path, monkeypatch):
    import imageio_ffmpeg
    from PySide6.QtWidgets import QFileDialog

    out = tmp_path / "walk.mp4"
    monkeypatch.setattr(QFileDialog, "getSaveFileName", lambda *args: (str(out), ""))
    window.controls.engines.video.click()
    assert imageio_ffmpeg.count_frames_and_secs(str(out))[0] == 30  # 120 frames at 120 fps, shown at 30
    assert f"wrote the video of identity to {out}" in window.controls.log.item(0).text()
    assert not window.session.export_video(str(tmp_path / "walk.gif"))
    assert "cannot write" in window.controls.log.item(0).text() and not (tmp_path / "walk.gif").exists()
    cancelled = tmp_path / "cancelled.mp4"
    assert not window.session.export_video(str(cancelled), progress=lambda done, total: done < 3)
    assert f"video cancelled: {cancelled} not written" in window.controls.log.item(0).text()
    assert not cancelled.exists()
    window.session.set_specs(["identity", "test-boom"], "test-boom")  # the shown engine has no result
    settle(qtbot, window)
    assert window.session.export_video(str(out))
    assert "(test-boom left out: failed)" in window.controls.log.item(0).text()


def test_measure_playback_counts_the_frames_shown(window):
    from workbench.app.main import measure_playback

    rates = measure_playback(window, 0.5)
    assert 0.45 <= rates["seconds"] < 1.5 and rates["rendered_fps"] > 5  # a rate, not a timing test
    assert abs(rates["rendered_fps"] - rates["advanced_fps"]) <= 2 / rates["seconds"]  # a render per frame shown
    assert not window.session.playing


def test_engines_run_shown_first_then_fastest_and_say_whether_queued_or_running(window, qtbot, monkeypatch):
    s, panel = window.session, window.controls.engines
    queued = []
    monkeypatch.setattr(s, "_submit", lambda what, *args: queued.append(what.removeprefix("cleaning with ")))
    monkeypatch.setattr(s, "_seconds_per_frame", {})  # no engine's speed measured yet (earlier tests ran some)
    s.set_specs(["mssa", "cae", "kalman", "identity", "test-widths"], "cae")
    # cae is shown; the classical engines have no measured speed yet and go first; identity and
    # test-widths ran on this take already (the fixture)
    assert queued == ["cae", "kalman", "mssa"]
    assert panel._status("kalman") == "queued"
    s.running.add("kalman")
    assert panel._status("kalman") == "running…"
    s._seconds_per_frame.update({"mssa": 1e-4, "cae": 1e-3})  # measured on an earlier take
    queued.clear()
    s.set_current("identity")
    s._run(["cae", "mssa", "kalman", "identity"])
    assert queued == ["identity", "kalman", "mssa", "cae"]


def test_fill_suspects_makes_the_flagged_samples_gaps_the_engines_fill(window, qtbot):
    """The take panel's box reopens the take with what the rules flag as bad data
    missing: the outliers become gaps on the track, and unticking it brings them back."""
    s, panel = window.session, window.controls.take
    s.set_specs(["identity"], "identity")
    s.open("cmu/walk/35_31", "outliers:0.02", 3)
    settle(qtbot, window)
    assert not s.take.fill_suspects and s.take.observation.observed.all() and not panel.fill.isChecked()
    panel.fill.setChecked(True)
    settle(qtbot, window)
    filled = s.take
    assert filled.fill_suspects and filled.corruption == "outliers:0.02" and filled.seed == 3
    assert (~filled.observation.observed).sum() > 50 and "missing" in {i.reason for i in s.suspects()}
    panel.fill.setChecked(False)
    settle(qtbot, window)
    assert not s.take.fill_suspects and s.take.observation.observed.all()
