"""The linked 3D panes, drawn by :class:`workbench.render.SkeletonScene`.

An off-screen plotter renders the panes and a widget shows the image, on a display and
without one (Qt's offscreen platform) alike. The mouse moves the camera through a VTK
interactor that is fed the label's mouse events (left drag turns, right drag or the
wheel zooms, middle or Shift+left drag pans; the panes' cameras are linked; R aims them
afresh). A click on a joint selects it. A frame change updates points in place and renders once.

Why not pyvistaqt's ``QtInteractor``: it is a QOpenGLWidget, and a window holding one is
composited through OpenGL on every repaint of any widget; on this project's software
renderer that made a frame of the 1200 x 800 window cost about twice what rendering the
panes off-screen and showing the image does (45 against 63 frames per second of
playback, ``workbench gui --measure-fps``).
"""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import QEvent, QPoint, Qt
from PySide6.QtGui import QImage, QPainter
from PySide6.QtWidgets import QSizePolicy, QVBoxLayout, QWidget

from ..render import SkeletonScene
from ..render.scene import new_plotter
from .take import scene_panes

CLICK_SLOP_PX = 4
DEFAULT_PANES = 3  # noisy | cleaned | truth


class ImageSurface(QWidget):
    """Shows one image, repainted in place: a new image is no new size hint, so the
    window is not laid out again per frame (as a QLabel's ``setPixmap`` would)."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.image: QImage | None = None
        self.setAttribute(Qt.WA_OpaquePaintEvent)  # the image covers the widget: no background to paint first
        self.setSizePolicy(QSizePolicy.Ignored, QSizePolicy.Ignored)

    def show_image(self, image: QImage) -> None:
        self.image = image
        self.update()

    def paintEvent(self, _event) -> None:
        painter = QPainter(self)
        if self.image is None:
            painter.fillRect(self.rect(), self.palette().window())
        else:
            painter.drawImage(0, 0, self.image)
        painter.end()


class SceneView(QWidget):
    """The session's 3D panes."""

    def __init__(self, session, parent: QWidget | None = None) -> None:
        super().__init__(parent)
        self.session = session
        self.plotter = None
        self.interactor = None  # the VTK interactor the mouse events are fed to
        self.scene: SkeletonScene | None = None
        self._built_for = None  # (take, follow, pane count) the camera was aimed for
        self._panes_key = None  # what the panes show, to skip rebuilds that change nothing
        self._press: QPoint | None = None
        self.surface = ImageSurface(self)
        self.surface.setFocusPolicy(Qt.ClickFocus)  # a click takes the focus from text fields
        self.surface.installEventFilter(self)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addWidget(self.surface)
        self.setMinimumSize(300, 200)
        self.setFocusPolicy(Qt.StrongFocus)
        self._new_plotter(DEFAULT_PANES)
        session.takeChanged.connect(self.rebuild)
        session.runsChanged.connect(self.rebuild)
        session.viewChanged.connect(self.rebuild)
        session.frameChanged.connect(self.show_frame)
        session.selectionChanged.connect(self.show_selection)

    # -- building -------------------------------------------------------------------
    def _new_plotter(self, n_panes: int) -> None:
        from vtkmodules.vtkInteractionStyle import vtkInteractorStyleTrackballCamera
        from vtkmodules.vtkRenderingUI import vtkGenericRenderWindowInteractor

        if self.plotter is not None:
            self.plotter.close()
        self.plotter = new_plotter(n_panes, self._pixels())
        self.interactor = vtkGenericRenderWindowInteractor()
        self.interactor.SetRenderWindow(self.plotter.ren_win)
        self.interactor.SetInteractorStyle(vtkInteractorStyleTrackballCamera())
        self.interactor.SetEnableRender(False)  # the style moves the camera; show_frame renders once
        self.interactor.Initialize()

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
            self._new_plotter(len(panes))
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

    def reset_camera(self) -> None:
        """Aim the cameras afresh, as for a new take (the R key)."""
        self._built_for = self._panes_key = None
        self.rebuild()

    def show_selection(self) -> None:
        if self.scene is not None:
            self.scene.set_selection(self.session.selected)
            self.show_frame(self.session.frame)

    # -- drawing --------------------------------------------------------------------
    def show_frame(self, frame: int) -> None:
        if self.scene is None:
            return
        self.scene.set_frame(frame)
        self._present()

    def _present(self) -> None:
        """Render the panes and show the image."""
        self.plotter.render()
        self.surface.show_image(self._image())

    def _image(self) -> QImage:
        img = np.ascontiguousarray(self.plotter.screenshot(return_img=True)[..., :3])
        h, w = img.shape[:2]
        qimage = QImage(img.data, w, h, 3 * w, QImage.Format_RGB888).copy()
        qimage.setDevicePixelRatio(self.devicePixelRatioF())
        return qimage

    def grab_panes(self) -> np.ndarray:
        """(H, W, 3) uint8 image of the panes as last drawn."""
        return np.asarray(self.plotter.image)[..., :3]

    def resizeEvent(self, event) -> None:
        super().resizeEvent(event)
        self.plotter.window_size = list(self._pixels())
        self.show_frame(self.session.frame)

    # -- the mouse ------------------------------------------------------------------
    #: Qt's mouse buttons and the VTK interactor's (press, release) events for them;
    #: Shift+left pans, as in VTK's own windows
    BUTTONS = {
        Qt.LeftButton: ("LeftButtonPressEvent", "LeftButtonReleaseEvent"),
        Qt.MiddleButton: ("MiddleButtonPressEvent", "MiddleButtonReleaseEvent"),
        Qt.RightButton: ("RightButtonPressEvent", "RightButtonReleaseEvent"),
    }

    def eventFilter(self, obj, event) -> bool:
        kind = event.type()
        if kind in (QEvent.MouseButtonPress, QEvent.MouseButtonRelease, QEvent.MouseMove) and obj is self.surface:
            self._camera(event)
            if kind == QEvent.MouseButtonPress and event.button() == Qt.LeftButton:
                self._press = event.position().toPoint()
            elif kind == QEvent.MouseButtonRelease and event.button() == Qt.LeftButton and self._press is not None:
                pos = event.position().toPoint()
                if (pos - self._press).manhattanLength() <= CLICK_SLOP_PX:
                    self.click(pos.x(), pos.y(), bool(event.modifiers() & (Qt.ControlModifier | Qt.ShiftModifier)))
                self._press = None
        elif kind == QEvent.Wheel and obj is self.surface:
            self._feed(event, "MouseWheelForwardEvent" if event.angleDelta().y() > 0 else "MouseWheelBackwardEvent")
        return False

    def _camera(self, event) -> None:
        """Feed a mouse press, release or move to the VTK interactor."""
        kind = event.type()
        if kind == QEvent.MouseMove:
            if event.buttons() & (Qt.LeftButton | Qt.MiddleButton | Qt.RightButton):
                self._feed(event, "MouseMoveEvent")
        elif event.button() in self.BUTTONS:
            press, release = self.BUTTONS[event.button()]
            self._feed(event, press if kind == QEvent.MouseButtonPress else release)

    def _feed(self, event, name: str) -> None:
        ratio = self.devicePixelRatioF()
        pos = event.position()
        modifiers = event.modifiers()
        self.interactor.SetEventInformationFlipY(
            round(pos.x() * ratio),
            round(pos.y() * ratio),
            int(bool(modifiers & Qt.ControlModifier)),
            int(bool(modifiers & Qt.ShiftModifier)),
        )
        getattr(self.interactor, name)()
        self.show_frame(self.session.frame)  # the selection's halos follow the camera

    def click(self, x: float, y: float, add: bool = False) -> None:
        """Select the joint drawn at widget position (x, y); a click on nothing clears."""
        if self.scene is None:
            return
        ratio = self.devicePixelRatioF()
        self.session.select_joint(self.scene.pick(x * ratio, y * ratio), add)
