"""The main window: controls on the left; the 3D panes, the transport bar (with the
joint-error colour scale) and the plot tabs on the right; messages and worker progress
in the status bar. Keys: left/right step a frame, space plays or pauses, Ctrl+S saves
the cleaned take.
"""

from __future__ import annotations

from matplotlib.backends.backend_qtagg import FigureCanvasQTAgg
from matplotlib.figure import Figure
from PySide6.QtCore import Qt
from PySide6.QtGui import QKeySequence, QShortcut
from PySide6.QtWidgets import (
    QComboBox,
    QHBoxLayout,
    QLabel,
    QMainWindow,
    QProgressBar,
    QPushButton,
    QSlider,
    QSplitter,
    QVBoxLayout,
    QWidget,
)

from ..plots.style import error_mappable
from .controls import ControlPanel
from .plot_view import PlotTabs
from .scene_view import SceneView
from .session import Session

SPEEDS = (0.1, 0.25, 0.5, 1.0, 2.0)
MESSAGE_MS = 20000


class ErrorScale(FigureCanvasQTAgg):
    """The colour scale of the joints' errors in the 3D views (cm), redrawn per take."""

    def __init__(self, session: Session) -> None:
        super().__init__(Figure(figsize=(2.6, 0.5), layout="constrained"))
        self.session = session
        self.setFixedSize(260, 46)
        session.takeChanged.connect(self.redraw)

    def redraw(self) -> None:
        fig = self.figure
        fig.clear()
        cbar = fig.colorbar(
            error_mappable(self.session.take.error_scale_cm()), cax=fig.subplots(), orientation="horizontal"
        )
        cbar.ax.tick_params(labelsize=7, length=2, pad=1)
        cbar.set_label(self.session.take.error_label, fontsize=7, labelpad=1)
        self.draw_idle()


class Transport(QWidget):
    """Play/pause, the timeline slider, the frame and time, the playback speed, the
    joint-error colour scale."""

    def __init__(self, session: Session, parent=None) -> None:
        super().__init__(parent)
        self.session = session
        self.play = QPushButton("Play")
        self.play.setFocusPolicy(Qt.NoFocus)
        self.play.clicked.connect(session.toggle_playing)
        self.slider = QSlider(Qt.Horizontal)
        self.slider.valueChanged.connect(session.set_frame)
        self.label = QLabel()
        self.label.setMinimumWidth(150)
        self.speed = QComboBox()
        self.speed.addItems([f"{s:g}×" for s in SPEEDS])
        self.speed.setCurrentIndex(SPEEDS.index(1.0))
        self.speed.currentIndexChanged.connect(lambda i: session.set_speed(SPEEDS[i]))
        self.speed.setToolTip("playback speed")
        layout = QHBoxLayout(self)
        layout.setContentsMargins(6, 2, 6, 2)
        for w in (self.play, self.slider, self.label, self.speed, ErrorScale(session)):
            layout.addWidget(w, 1 if w is self.slider else 0)
        session.takeChanged.connect(self.show_take)
        session.frameChanged.connect(self.show_frame)
        session.playingChanged.connect(lambda on: self.play.setText("Pause" if on else "Play"))

    def show_take(self) -> None:
        self.slider.blockSignals(True)
        self.slider.setRange(0, max(self.session.n_frames - 1, 0))
        self.slider.blockSignals(False)
        self.show_frame(self.session.frame)

    def show_frame(self, frame: int) -> None:
        self.slider.blockSignals(True)
        self.slider.setValue(frame)
        self.slider.blockSignals(False)
        take = self.session.take
        self.label.setText(f"frame {frame} / {take.n_frames - 1}   {frame / take.fps:5.2f} s")


class MainWindow(QMainWindow):
    def __init__(self, session: Session | None = None) -> None:
        super().__init__()
        self.session = session or Session(self)
        s = self.session
        self.scene = SceneView(s)
        self.transport = Transport(s)
        self.plots = PlotTabs(s)
        self.controls = ControlPanel(s)
        top = QWidget()
        column = QVBoxLayout(top)
        column.setContentsMargins(0, 0, 0, 0)
        column.addWidget(self.scene, 1)
        column.addWidget(self.transport)
        right = QSplitter(Qt.Vertical)
        right.addWidget(top)
        right.addWidget(self.plots)
        right.setSizes([520, 330])
        split = QSplitter(Qt.Horizontal)
        split.addWidget(self.controls)
        split.addWidget(right)
        split.setStretchFactor(1, 1)
        split.setSizes([290, 910])
        self.setCentralWidget(split)
        self.progress = QProgressBar()
        self.progress.setRange(0, 0)
        self.progress.setMaximumWidth(120)
        self.busy = QLabel()
        self.statusBar().addPermanentWidget(self.busy)
        self.statusBar().addPermanentWidget(self.progress)
        self.show_busy("")
        s.busyChanged.connect(self.show_busy)
        s.message.connect(lambda text: self.statusBar().showMessage(text, MESSAGE_MS))
        s.takeChanged.connect(lambda: self.setWindowTitle(f"mocap workbench · {s.take.source}"))
        self.setWindowTitle("mocap workbench")
        for key, action in (
            (Qt.Key_Left, lambda: s.step(-1)),
            (Qt.Key_Right, lambda: s.step(1)),
            (Qt.Key_Space, s.toggle_playing),
        ):
            QShortcut(QKeySequence(key), self, action)
        QShortcut(QKeySequence.Save, self, self.controls.engines.save.click)  # Ctrl+S
        self.scene.setFocus()  # not a text field, which would take the keys for itself

    def closeEvent(self, event) -> None:
        self.session.shutdown()
        super().closeEvent(event)

    def show_busy(self, text: str) -> None:
        self.busy.setText(text)
        self.progress.setVisible(bool(text))
