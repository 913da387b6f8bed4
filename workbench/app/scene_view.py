"""The linked 3D panes, drawn by :class:`workbench.render.SkeletonScene`.

With a real display the panes live in a pyvistaqt ``QtInteractor`` (mouse camera);
with Qt's offscreen platform (no X server) an off-screen plotter renders each frame and
a label shows the image (no mouse camera). Either way a click on a joint selects it, and
a frame change updates points in place and renders once (``auto_update`` off; the
interactor renders in its paint event, so asking it to repaint, not to render, avoids
rendering twice).
"""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import QEvent, QPoint, Qt
from PySide6.QtGui import QImage, QPixmap
from PySide6.QtWidgets import QLabel, QSizePolicy, QVBoxLayout, QWidget

from ..render import SkeletonScene
from ..render.scene import PLOTTER_OPTIONS, new_plotter, plain_theme
from .take import scene_panes

CLICK_SLOP_PX = 4
DEFAULT_PANES = 3  # noisy | cleaned | truth


def interactive_display() -> bool:
    """True when Qt draws on a real display, where a QtInteractor works."""
    from PySide6.QtGui import QGuiApplication

    return QGuiApplication.platformName() not in ("offscreen", "minimal")


class SceneView(QWidget):
    """The session's 3D panes."""

    def __init__(self, session, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.session = session
        self.interactive = interactive_display()
        self.plotter = None
        self.scene: SkeletonScene | None = None
        self.surface: QWidget | None = None  # the widget showing the panes
        self._built_for = None  # (take, follow, pane count) the camera was aimed for
        self._panes_key = None  # what the panes show, to skip rebuilds that change nothing
        self._press: QPoint | None = None
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        self.setMinimumSize(300, 200)
        self.setFocusPolicy(Qt.StrongFocus)
        # The surface exists before the window shows: adding the first OpenGL widget to a
        # shown window re-creates its native window (it flickers and loses the focus).
        self._new_surface(DEFAULT_PANES)
        session.takeChanged.connect(self.rebuild)
        session.runsChanged.connect(self.rebuild)
        session.viewChanged.connect(self.rebuild)
        session.frameChanged.connect(self.show_frame)
        session.selectionChanged.connect(self.show_selection)

    # -- building -------------------------------------------------------------------
    def _new_surface(self, n_panes: int) -> None:
        if self.surface is not None:
            self.layout().removeWidget(self.surface)
            self.plotter.close()
            self.surface.deleteLater()
        if self.interactive:
            from pyvistaqt import QtInteractor

            self.plotter = QtInteractor(
                self,
                shape=(1, n_panes),
                auto_update=False,
                multi_samples=0,
                off_screen=False,
                theme=plain_theme(),
                **PLOTTER_OPTIONS,
            )
            self.plotter.window_size = list(self._pixels())  # aim the camera for the size it will have
            self.surface = self.plotter
        else:
            self.plotter = new_plotter(n_panes, self._pixels())
            self.surface = QLabel(self)
            self.surface.setAlignment(Qt.AlignLeft | Qt.AlignTop)
            self.surface.setSizePolicy(QSizePolicy.Ignored, QSizePolicy.Ignored)
        self.surface.setFocusPolicy(Qt.ClickFocus)  # a click takes the focus from text fields
        self.surface.installEventFilter(self)
        self.layout().addWidget(self.surface)

    def _pixels(self) -> tuple[int, int]:
        ratio = self.devicePixelRatioF()
        return max(int(self.width() * ratio), 1), max(int(self.height() * ratio), 1)

    def rebuild(self) -> None:
        """Rebuild the panes for the session's take, shown engines and runs."""
        s = self.session
        if s.take is None:
            return
        panes = scene_panes(s.take, s.shown, s.runs, s.compare)
        panes_key = (s.take, s.follow, tuple((p.title, id(p.points), p.note) for p in panes))
        if panes_key == self._panes_key:
            return
        self._panes_key = panes_key
        if len(self.plotter.renderers) != len(panes):
            self._new_surface(len(panes))
        key = (s.take, s.follow, len(panes))
        self.scene = SkeletonScene(
            self.plotter,
            panes,
            s.take.motion.skeleton,
            s.take.root,
            s.take.error_scale_cm(),
            follow=s.follow,
            keep_camera=key == self._built_for,
            selected=s.selected,
        )
        self._built_for = key
        self.show_frame(s.frame)

    def show_selection(self) -> None:
        if self.scene is not None:
            self.scene.set_selection(self.session.selected)
            self.show_frame(self.session.frame)

    # -- drawing --------------------------------------------------------------------
    def show_frame(self, frame: int) -> None:
        if self.scene is None:
            return
        self.scene.set_frame(frame)
        if self.interactive:
            self.surface.update()  # renders once, in paintGL, with the rest of the window
        else:
            self.plotter.render()
            self.surface.setPixmap(QPixmap.fromImage(self._image()))

    def _image(self) -> QImage:
        img = np.ascontiguousarray(self.plotter.screenshot(return_img=True)[..., :3])
        h, w = img.shape[:2]
        qimage = QImage(img.data, w, h, 3 * w, QImage.Format_RGB888).copy()
        qimage.setDevicePixelRatio(self.devicePixelRatioF())
        return qimage

    def grab_panes(self) -> np.ndarray:
        """(H, W, 3) uint8 image of the panes as last drawn."""
        if self.interactive:
            return np.asarray(self.plotter.screenshot(return_img=True))[..., :3]
        return np.asarray(self.plotter.image)[..., :3]

    def resizeEvent(self, event) -> None:
        super().resizeEvent(event)
        if not self.interactive:
            self.plotter.window_size = list(self._pixels())
            self.show_frame(self.session.frame)

    # -- picking --------------------------------------------------------------------
    def eventFilter(self, obj, event) -> bool:
        kind = event.type()
        if kind == QEvent.MouseButtonPress and event.button() == Qt.LeftButton:
            self._press = event.position().toPoint()
        elif kind == QEvent.MouseButtonRelease and event.button() == Qt.LeftButton and self._press is not None:
            pos = event.position().toPoint()
            if (pos - self._press).manhattanLength() <= CLICK_SLOP_PX:
                self.click(pos.x(), pos.y(), bool(event.modifiers() & (Qt.ControlModifier | Qt.ShiftModifier)))
            self._press = None
        return False

    def click(self, x: float, y: float, add: bool = False) -> None:
        """Select the joint drawn at widget position (x, y); a click on nothing clears."""
        if self.scene is None:
            return
        ratio = self.devicePixelRatioF()
        self.session.select_joint(self.scene.pick(x * ratio, y * ratio), add)
