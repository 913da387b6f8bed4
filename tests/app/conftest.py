"""Fixtures for the app tests: a tiny take (120 frames of a CMU walk), fast test
engines, the main window on it, and image helpers (pixel probes, reference images).

The tests run under Xvfb when pytest-xvfb finds it and without it (Qt's offscreen
platform); the 3D views are off-screen-rendered images either way.
Reference images: see ``test_reference_images.py`` for the command that regenerates them.
"""

from __future__ import annotations

import numpy as np
import pytest
from app_helpers import FRAME, FRAMES, settle

from workbench import registry
from workbench.app.main import configure_headless
from workbench.app.take import make_take
from workbench.core.motion import Observation
from workbench.engine import CleanResult, Engine, EngineError, EngineInfo


@pytest.hookimpl(trylast=True)
def pytest_configure(config):
    """Qt's offscreen platform unless pytest-xvfb (configured before) started an X
    server; before Qt and VTK load (this conftest may load before pytest-xvfb starts)."""
    configure_headless()


class Widths(Engine):
    """Bridges gaps and reports made-up filter widths (F, C) that grow over time."""

    info = EngineInfo(name="test-widths", summary="test: bridge gaps, report widths", tasks=frozenset({"fill"}))

    def clean(self, observation: Observation, /) -> CleanResult:
        motion = observation.bridged()
        F, C = motion.channels.shape
        widths = 1.0 + np.outer(np.linspace(0, 4, F), np.ones(C)) + np.arange(C) % 3
        return CleanResult(motion, {"filter_sigma_frames": widths})


class Weights(Engine):
    """Bridges gaps and reports made-up robust data weights (F, C): every 7th entry an
    outlier (0.02), the rest 1."""

    info = EngineInfo(name="test-weights", summary="test: bridge gaps, report data weights", tasks=frozenset({"fill"}))

    def clean(self, observation: Observation, /) -> CleanResult:
        motion = observation.bridged()
        weights = np.ones(motion.channels.shape)
        weights.flat[::7] = 0.02
        return CleanResult(motion, {"robust_weight": weights})


class Boom(Engine):
    info = EngineInfo(name="test-boom", summary="test: always fails", tasks=frozenset({"fill"}))

    def clean(self, observation: Observation, /) -> CleanResult:
        raise EngineError("boom: this engine always fails")


class Crash(Engine):
    info = EngineInfo(name="test-crash", summary="test: a bug", tasks=frozenset({"fill"}))

    def clean(self, observation: Observation, /) -> CleanResult:
        return 1 / 0


@pytest.fixture(scope="module", autouse=True)
def test_engines():
    """The test engines, registered for the app tests only (other test folders list
    every registered engine)."""
    with pytest.MonkeyPatch.context() as mp:
        for cls in (Widths, Weights, Boom, Crash):
            mp.setitem(registry._registered, cls.info.name, cls)
        yield


@pytest.fixture(scope="session")
def tiny_walk(embedded_root):
    """CMU walk 35_31 (test split, embedded in the package, so the app's tests run on a
    machine without the team's data), first 120 frames after the T-pose frame."""
    from workbench.data import find_clip

    return find_clip("cmu/walk/35_31", embedded_root).load().slice(0, FRAMES)


@pytest.fixture(scope="session")
def take(tiny_walk):
    return make_take(tiny_walk, "angular:0.5+gaps:0.01", seed=0, source="cmu/walk/35_31 (120 frames)")


@pytest.fixture(scope="session")
def clean_take(tiny_walk):
    """The walk shown as recorded: no corruption, no ground truth."""
    return make_take(tiny_walk, "none", seed=0, source="as recorded")


@pytest.fixture(scope="module")
def runs(take, test_engines):
    from workbench.app.take import run_engine

    return [run_engine("identity", take), run_engine("test-widths", take)]


@pytest.fixture(scope="session")
def app_window(qapp):
    """One main window for the whole session (a second window in one process renders
    its OpenGL panes wrongly under Xvfb; the app only ever makes one)."""
    from PySide6.QtTest import QTest

    from workbench.app.window import MainWindow

    win = MainWindow()
    win.resize(1200, 800)
    win.show()
    QTest.qWaitForWindowExposed(win)
    win.activateWindow()  # keyboard shortcuts need the active window
    QTest.qWaitForWindowActive(win)
    yield win
    win.session.set_playing(False)
    win.session.wait()
    win.close()


@pytest.fixture
def window(app_window, qtbot, take):
    """The main window reset to the tiny take with identity and test-widths, results in,
    at FRAME, nothing selected, not comparing, the error tab shown."""
    s = app_window.session
    s.set_playing(False)
    s.set_compare(False)
    s.set_follow(True)
    s.select_joint(None)
    app_window.plots.setCurrentIndex(0)
    s.set_specs(["identity", "test-widths"], "identity")
    s.set_take(take)
    settle(qtbot, app_window)
    s.set_frame(FRAME)
    app_window.scene.setFocus()
    settle(qtbot, app_window)
    yield app_window
    s.set_playing(False)
    s.wait()
