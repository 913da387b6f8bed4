"""Starting the app: the headless set-up, the window on a take, and screenshots of the
window in its main states.

Without a display (no DISPLAY or WAYLAND_DISPLAY on Linux) Qt uses its offscreen
platform and VTK its EGL off-screen window, so the app, ``workbench screenshots`` and the
tests run on CI; the 3D panes then show off-screen-rendered images (see
:mod:`workbench.app.scene_view`). These settings must be made before Qt or VTK load.
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import numpy as np

from .defaults import DEFAULT_CLIP, DEFAULT_CORRUPTION
from .take import EngineRun, default_engines, loadable

WINDOW_SIZE = (1200, 800)
#: the outliers screenshot: a robust engine on a take with outliers
OUTLIER_ENGINE = "mssa"
OUTLIER_CORRUPTION = "angular:0.5+outliers:0.05"
#: the studio screenshot: a held-out-style take of the Bandai studio set (22 joints with six
#: channels each, 30 fps) by its catalogue id, with the default's corruption in seconds
#: (gaps of 0.1 s starting 1.2 times a second per joint, as gaps:0.01 at 120 fps); the
#: trained engines clean it with their Bandai weights
STUDIO_CLIP = "bandai/walk/dataset-1_walk_happy_001"
STUDIO_CORRUPTION = "angular:0.5+gaps:0.04,0.1s"
#: the unseen screenshot: a take of a skeleton no engine has weights of its own for (CMU
#: Daz, 43 joints) with a 1-s block, filled by the plain ``cae`` on its universal weights
UNSEEN_CLIP = "cmu-daz/kick/10_03"
UNSEEN_CORRUPTION = "block:1s"
UNSEEN_ENGINES = ["lerp", "kalman", "cae"]
#: the suspects screenshot: a real take as recorded with capture glitches (spikes, turns
#: faster than a body can), the robust engine's rejections and the engines' disagreement
SUSPECTS_CLIP = "cmu/other/06_14"
SUSPECTS_ENGINES = ["mssa", "kalman", "lerp>gaussian"]
#: the laptop screenshot: the default window on the smallest screen it is made for
LAPTOP_SIZE = (1366, 768)


def has_display() -> bool:
    return not sys.platform.startswith("linux") or bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def configure_headless() -> None:
    """With no display: Qt's offscreen platform and VTK's EGL off-screen window."""
    if not has_display():
        os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
        os.environ.setdefault("PYVISTA_OFF_SCREEN", "true")


def application():
    """The QApplication (made once)."""
    configure_headless()
    from PySide6.QtWidgets import QApplication

    return QApplication.instance() or QApplication(["workbench"])


def open_window(
    source: str = DEFAULT_CLIP,
    corruption: str = DEFAULT_CORRUPTION,
    seed: int = 0,
    specs: list[str] | None = None,
    size: tuple[int, int] = WINDOW_SIZE,
    settings=None,
    fill_suspects: bool = False,
):
    """A shown main window loading ``source`` (with ``fill_suspects``, its suspects made
    gaps: the **fill suspects** box), its engines queued to run, ``size`` pixels or the
    screen's available area where that is smaller. The take loads on the worker while
    the window is being built. With ``settings`` (a QSettings) the window takes the
    geometry saved there and saves its state there when it closes."""
    application()
    from .session import Session
    from .window import MainWindow

    session = Session()
    session.set_specs(default_engines() if specs is None else specs)
    session.open(source, corruption, seed, fill_suspects)
    window = MainWindow(session, settings)
    session.setParent(window)
    fit_to_screen(window, size)
    if settings is not None and settings.value(GEOMETRY_KEY) is not None:
        window.restoreGeometry(settings.value(GEOMETRY_KEY))
    window.show()
    return window


def fit_to_screen(window, size: tuple[int, int]) -> None:
    """Resize ``window`` to ``size`` (pixels, frame included) within its screen's
    available area, and place it inside that area."""
    area = window.screen().availableGeometry()
    frame = window.frameGeometry().size() - window.geometry().size()  # the title bar and borders
    width = min(size[0], area.width() - frame.width())
    height = min(size[1], area.height() - frame.height())
    window.resize(width, height)
    window.move(area.left() + (area.width() - width - frame.width()) // 2, area.top())


#: where the app keeps its state between runs (QSettings: organisation, application)
SETTINGS_NAME = ("mocap-workbench", "workbench")
GEOMETRY_KEY = "window/geometry"
TAKE_KEYS = ("take/source", "take/corruption", "take/seed", "engines/specs", "take/fill_suspects")


def save_state(window, settings) -> None:
    """Keep the window's geometry, its take (source, corruption, seed, whether its
    suspects are filled) and its engines."""
    s = window.session
    settings.setValue(GEOMETRY_KEY, window.saveGeometry())
    if s.take is not None:
        # the engines and the flag as JSON: a settings file gives a one-item list back as
        # a string, and a bool as "true"
        values = (s.take.source, s.take.corruption, s.take.seed, json.dumps(s.specs), json.dumps(s.take.fill_suspects))
        for key, value in zip(TAKE_KEYS, values):
            settings.setValue(key, value)
    settings.sync()


def saved_take(settings) -> tuple[str, str, int, list[str], bool] | None:
    """The take, engines and fill-suspects flag :func:`save_state` kept (the flag False
    where an older run kept none), None when there are none (or they cannot be read back)."""
    source, corruption, seed, specs, fill = (settings.value(key) for key in TAKE_KEYS)
    if not source or corruption is None:
        return None
    try:
        specs, fill = json.loads(specs), json.loads(fill or "false")
        if not isinstance(specs, list) or not isinstance(fill, bool):
            return None
        return str(source), str(corruption), int(seed), [str(x) for x in specs], fill
    except (TypeError, ValueError):
        return None


def run_gui(
    source: str | None = None,
    corruption: str | None = None,
    seed: int | None = None,
    specs: list[str] | None = None,
    fill_suspects: bool | None = None,
) -> int:
    """Open the window and run the event loop until it closes. What is not given is taken
    from the last session (:func:`saved_take`) when nothing is given, else the defaults
    (:data:`DEFAULT_CLIP`, :data:`DEFAULT_CORRUPTION`, seed 0, :func:`default_engines`,
    suspects not filled)."""
    app = application()
    from PySide6.QtCore import QSettings

    settings = QSettings(*SETTINGS_NAME)
    last = saved_take(settings) if (source, corruption, seed, specs, fill_suspects) == (None,) * 5 else None
    if last is not None:
        source, corruption, seed, specs, fill_suspects = last
    window = open_window(  # noqa: F841 (kept alive while the loop runs)
        source or DEFAULT_CLIP,
        DEFAULT_CORRUPTION if corruption is None else corruption,
        seed or 0,
        specs,
        settings=settings,
        fill_suspects=bool(fill_suspects),
    )
    return app.exec()


def measure_playback(window, seconds: float = 10.0) -> dict[str, float]:
    """Play ``window``'s take at normal speed for ``seconds`` (once its engines are done)
    and count what was shown: ``rendered_fps``, the 3D views' renders per second (every
    pane together is one render), and ``advanced_fps``, the frames the playback moved on
    per second (the take's frame rate at most)."""
    import time

    from PySide6.QtCore import QEventLoop, QTimer

    settle(window)
    s = window.session
    renders, frames = [0], [0]
    observer = window.scene.plotter.ren_win.AddObserver("EndEvent", lambda *_: renders.__setitem__(0, renders[0] + 1))
    s.frameChanged.connect(count := lambda _: frames.__setitem__(0, frames[0] + 1))
    s.set_frame(0)
    s.set_playing(True)
    loop = QEventLoop()
    QTimer.singleShot(round(seconds * 1000), loop.quit)
    t0 = time.perf_counter()
    loop.exec()  # the app's own event loop: no busy waiting for the cores to share
    elapsed = time.perf_counter() - t0
    s.set_playing(False)
    s.frameChanged.disconnect(count)
    window.scene.plotter.ren_win.RemoveObserver(observer)
    return {"rendered_fps": renders[0] / elapsed, "advanced_fps": frames[0] / elapsed, "seconds": elapsed}


def _in_catalogue(clip: str) -> bool:
    from ..data import DataNotFoundError, catalogue

    try:
        return any(c.id == clip for c in catalogue())
    except DataNotFoundError:
        return False


def settle(window) -> None:
    """Process events until the worker is idle and everything it posted is drawn (as long
    as the engines take: a screenshot of a result waits for it)."""
    from PySide6.QtWidgets import QApplication

    session = window.session
    while True:
        QApplication.processEvents()
        if not session.busy:
            break
        session.wait(50)
    for _ in range(3):
        QApplication.processEvents()


def make_screenshots(
    out_dir: str | Path,
    source: str = DEFAULT_CLIP,
    corruption: str = DEFAULT_CORRUPTION,
    frame: int = 150,
    joint: str = "LeftFoot",
    specs: list[str] | None = None,
) -> list[Path]:
    """The window in its main states, and the report figure, as PNG files in ``out_dir``:
    default, compare, joint (a selected joint), heatmap (the filter-width tab, of the
    engine whose widths vary most), outliers (the outlier-weight tab of
    :data:`OUTLIER_ENGINE` on :data:`OUTLIER_CORRUPTION`), recorded (the take as
    recorded, no ground truth, every engine compared), studio (:data:`STUDIO_CLIP`
    compared, where the data root has it), unseen (:data:`UNSEEN_CLIP` compared, by
    :data:`UNSEEN_ENGINES`, where the data root has it), suspects (:data:`SUSPECTS_CLIP`
    as recorded at its largest spike, where the data root has it), laptop
    (the default state in a :data:`LAPTOP_SIZE` window), report, and video (a frame of
    ``workbench report --video`` of the default state, read back from the MP4).
    ``specs``: the engines (default: :func:`default_engines`)."""
    from .report import clean_take, write_report

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    specs = default_engines() if specs is None else specs
    window = open_window(source, corruption, 0, specs)
    s = window.session
    settle(window)
    s.set_frame(frame)
    paths = []

    def shoot(name: str, message: str = "") -> None:
        """The window as PNG, its messages only ``message`` (earlier shots' takes' would mislead)."""
        settle(window)
        window.controls.log.clear()
        window.statusBar().clearMessage()
        if message:
            s.message.emit(message)
        path = out / f"{name}.png"
        window.grab().save(str(path))
        paths.append(path)

    shoot("default")
    s.set_compare(True)
    shoot("compare")
    s.set_compare(False)
    s.select_joint(s.take.motion.skeleton.index(joint))
    shoot("joint")
    widths = {
        spec: np.ptp(r.filter_sigma_frames)
        for spec, r in s.runs.items()
        if isinstance(r, EngineRun) and r.filter_sigma_frames is not None
    }
    if widths:  # the engine whose widths vary most
        s.set_current(max(widths, key=widths.get))
    window.plots.setCurrentIndex(1)
    shoot("heatmap")
    if loadable(OUTLIER_ENGINE):  # a robust engine on outliers: the samples it rejected
        s.set_specs([OUTLIER_ENGINE])
        s.open(source, OUTLIER_CORRUPTION, 0)
        settle(window)
        s.set_frame(frame)
        window.plots.setCurrentIndex(2)
        shoot("outliers")
    window.plots.setCurrentIndex(0)
    s.set_specs(specs)
    s.open(source, "none", 0)  # a real take: how far each engine moves it
    s.select_joint(None)
    s.set_compare(True)
    settle(window)
    s.set_frame(frame)
    shoot("recorded")
    if _in_catalogue(STUDIO_CLIP):
        s.set_specs(specs)  # the trained engines pick their studio weights
        s.open(STUDIO_CLIP, STUDIO_CORRUPTION, 0)
        settle(window)
        s.set_frame(s.take.n_frames // 2)
        shoot("studio")
    if _in_catalogue(UNSEEN_CLIP):
        s.set_specs([spec for spec in UNSEEN_ENGINES if loadable(spec)])
        s.open(UNSEEN_CLIP, UNSEEN_CORRUPTION, 0)
        settle(window)
        s.set_frame(int(np.flatnonzero(~s.take.observation.observed[:, 0]).mean()))  # inside the block
        shoot("unseen")
    if _in_catalogue(SUSPECTS_CLIP):
        s.set_compare(False)
        s.set_specs([spec for spec in SUSPECTS_ENGINES if loadable(spec)])
        s.open(SUSPECTS_CLIP, "none", 0)
        settle(window)
        spikes = [i for i in s.suspects() if i.reason == "spike"]
        found = max(spikes, key=lambda i: i.score, default=None)  # the worst capture glitch
        s.set_frame(found.first if found else 0)
        s.select_joint(s.take.motion.skeleton.index(found.joints[0]) if found else None)
        shoot("suspects", str(found) if found else "")
        s.select_joint(None)
    s.set_specs(specs)
    s.open(source, corruption, 0)
    s.set_compare(False)
    window.plots.setCurrentIndex(0)
    settle(window)
    s.set_frame(frame)
    window.resize(*LAPTOP_SIZE)
    shoot("laptop")
    take, runs = clean_take(source, corruption, 0, specs)
    paths.append(write_report(out / "report.png", take, runs, frame=frame))
    paths.append(_video_still(out / "video.png", take, runs, frame))
    window.close()
    return paths


def _video_still(path: Path, take, runs, frame: int) -> Path:
    """The video frame nearest ``frame`` of ``workbench report --video``, read back
    from the MP4 file and written as PNG."""
    import tempfile

    import imageio_ffmpeg
    from PySide6.QtGui import QImage

    from .video import video_frames, write_video

    wanted = int(np.argmin(np.abs(video_frames(take) - frame)))
    with tempfile.TemporaryDirectory() as tmp:
        video = write_video(Path(tmp) / "take.mp4", take, runs)
        reader = imageio_ffmpeg.read_frames(str(video))
        width, height = next(reader)["size"]
        for k, data in enumerate(reader):
            if k == wanted:
                break
        reader.close()
    image = np.frombuffer(data, np.uint8).reshape(height, width, 3)
    QImage(image.data, width, height, 3 * width, QImage.Format_RGB888).save(str(path))
    return path
