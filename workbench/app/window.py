"""The main window: controls on the left; the 3D panes, the transport bar (with the
joint-error colour scale and the suspicious-frames track) and the plot tabs on the right;
messages and worker progress in the status bar. Keys: left/right step a frame, space
plays or pauses, N and Shift+N jump to the next and previous suspicious interval, R aims
the 3D cameras afresh, Ctrl+B hides or shows the control panel, Ctrl+S saves the cleaned
take.
"""

from __future__ import annotations

from matplotlib.backends.backend_qtagg import FigureCanvasQTAgg
from matplotlib.figure import Figure
from PySide6.QtCore import QRectF, Qt
from PySide6.QtGui import QColor, QFont, QKeySequence, QPainter, QPixmap, QShortcut
from PySide6.QtWidgets import (
    QComboBox,
    QGridLayout,
    QLabel,
    QMainWindow,
    QProgressBar,
    QPushButton,
    QSizePolicy,
    QSlider,
    QSplitter,
    QStyle,
    QStyleOptionSlider,
    QToolTip,
    QVBoxLayout,
    QWidget,
)

from ..data.inspection import REASONS
from ..plots.style import CURSOR, REASON_COLOURS, TEXT, error_mappable
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
        # 260 px where the window has room, down to 140 where the timeline slider needs it
        self.setMinimumSize(140, 46)
        self.setMaximumSize(260, 46)
        self.setSizePolicy(QSizePolicy.Preferred, QSizePolicy.Fixed)
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


class SuspectTrack(QWidget):
    """The suspicious intervals of the take (:meth:`Session.suspects`) under the timeline
    slider, a row per reason found, in the reason's colour, with the current frame
    marked; hovering names the intervals under the mouse, a click shows the first frame
    of one."""

    ROW_PX = 9

    def __init__(self, session: Session, slider: QSlider, parent=None) -> None:
        super().__init__(parent)
        self.session, self.slider = session, slider
        self.setMouseTracking(True)
        self.setToolTip("suspicious frames: N jumps to the next interval, Shift+N to the one before")
        for signal in (session.takeChanged, session.runsChanged):
            signal.connect(self.refresh)
        session.frameChanged.connect(self._moved)
        self._picture: QPixmap | None = None
        self._cursor_x = 0
        self.refresh()

    def refresh(self) -> None:
        self.intervals = self.session.suspects()
        self.reasons = [r for r in REASONS if any(i.reason == r for i in self.intervals)]
        self.setFixedHeight(max(1, len(self.reasons)) * self.ROW_PX + 4)
        self._picture = None
        self.update()

    def resizeEvent(self, event) -> None:
        self._picture = None
        super().resizeEvent(event)

    def _span(self) -> tuple[float, float]:
        """The x range (pixels, this widget's) of the slider's frames, from its handle's
        centre at frame 0 to its centre at the last frame."""
        option = QStyleOptionSlider()
        self.slider.initStyleOption(option)
        handle = self.slider.style().pixelMetric(QStyle.PM_SliderLength, option, self.slider)
        left = self.slider.x() - self.x() + handle / 2  # the slider is a sibling
        return left, left + self.slider.width() - handle

    def _x(self, frame: float, span: tuple[float, float] | None = None) -> float:
        """The x (pixels) of ``frame`` under the slider (``span``: :meth:`_span`, if known)."""
        left, right = span or self._span()
        return left + (right - left) * frame / max(self.session.n_frames - 1, 1)

    def _draw_intervals(self) -> QPixmap:
        """The labels and intervals, drawn once per take, run or size (playback only
        moves the cursor over them)."""
        picture = QPixmap(self.size() * self.devicePixelRatioF())
        picture.setDevicePixelRatio(self.devicePixelRatioF())
        picture.fill(Qt.transparent)
        painter = QPainter(picture)
        font = QFont(self.font())
        font.setPointSizeF(7.0)
        painter.setFont(font)
        span = self._span()
        left = span[0]
        painter.setPen(QColor(TEXT))
        if not self.reasons:
            note = "no suspects" if self.session.inspection() is not None else "inspecting…"
            painter.drawText(QRectF(0, 0, left - 6, self.height()), Qt.AlignRight | Qt.AlignVCenter, note)
        for row, reason in enumerate(self.reasons):
            y = 2 + row * self.ROW_PX
            painter.drawText(QRectF(0, y - 1, left - 6, self.ROW_PX + 2), Qt.AlignRight | Qt.AlignVCenter, reason)
            colour = QColor(REASON_COLOURS[reason])
            for i in self.intervals:
                if i.reason == reason:
                    x0, x1 = self._x(i.first - 0.5, span), self._x(i.last + 0.5, span)
                    painter.fillRect(QRectF(x0, y, max(x1 - x0, 2.0), self.ROW_PX - 2), colour)
        painter.end()
        return picture

    def _moved(self, frame: int) -> None:
        """Repaint the cursor's old and new columns only."""
        x = round(self._x(frame))
        for column in {self._cursor_x, x}:
            self.update(column - 2, 0, 5, self.height())
        self._cursor_x = x

    def paintEvent(self, event) -> None:
        if self.session.take is None:
            return
        if self._picture is None or self._picture.size() != self.size() * self.devicePixelRatioF():
            self._picture = self._draw_intervals()
        painter = QPainter(self)
        painter.drawPixmap(0, 0, self._picture)  # clipped to the region to repaint
        self._cursor_x = round(self._x(self.session.frame))
        painter.setPen(QColor(CURSOR))
        painter.drawLine(self._cursor_x, 0, self._cursor_x, self.height())
        painter.end()

    def _under(self, x: float, y: float) -> list:
        row = int((y - 2) // self.ROW_PX)
        if not 0 <= row < len(self.reasons):
            return []
        slack = 3.0  # pixels: a one-frame interval stays easy to hit
        return [
            i
            for i in self.intervals
            if i.reason == self.reasons[row] and self._x(i.first - 0.5) - slack <= x <= self._x(i.last + 0.5) + slack
        ]

    def mouseMoveEvent(self, event) -> None:
        under = self._under(event.position().x(), event.position().y())
        text = "\n".join(str(i) for i in under[:6]) if under else self.toolTip()
        QToolTip.showText(event.globalPosition().toPoint(), text, self)

    def mousePressEvent(self, event) -> None:
        under = self._under(event.position().x(), event.position().y())
        if under:
            self.session.step(under[0].first - self.session.frame)
            self.session.message.emit(str(under[0]))


class Transport(QWidget):
    """Play/pause, the timeline slider and the suspicious-frames track under it, the
    frame and time, the playback speed, the joint-error colour scale."""

    def __init__(self, session: Session, parent=None) -> None:
        super().__init__(parent)
        self.session = session
        self.play = QPushButton("Play")
        self.play.setFocusPolicy(Qt.NoFocus)
        self.play.clicked.connect(session.toggle_playing)
        self.slider = QSlider(Qt.Horizontal)
        self.slider.setMinimumWidth(160)  # in a narrow window the colour scale gives way, not the timeline
        self.slider.valueChanged.connect(session.set_frame)
        self.label = QLabel()
        # a fixed size: a new text then repaints the label without laying the window out again
        self.label.setFixedSize(self.label.fontMetrics().horizontalAdvance("frame 00000 / 00000   0000.00 s") + 8, 22)
        self.speed = QComboBox()
        self.speed.addItems([f"{s:g}×" for s in SPEEDS])
        self.speed.setCurrentIndex(SPEEDS.index(1.0))
        self.speed.currentIndexChanged.connect(lambda i: session.set_speed(SPEEDS[i]))
        self.speed.setToolTip("playback speed")
        self.suspects = SuspectTrack(session, self.slider)
        layout = QGridLayout(self)
        layout.setContentsMargins(6, 2, 6, 2)
        layout.setVerticalSpacing(0)
        for column, w in enumerate((self.play, self.slider, self.label, self.speed, ErrorScale(session))):
            layout.addWidget(w, 0, column)
        layout.setColumnStretch(1, 1)
        layout.addWidget(self.suspects, 1, 0, 1, 3)  # under the play button (its labels) and the slider
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
    """The window; with ``settings`` (a QSettings) it saves its state there on closing
    (:func:`workbench.app.main.save_state`)."""

    def __init__(self, session: Session | None = None, settings=None) -> None:
        super().__init__()
        self.session = session or Session(self)
        self.settings = settings
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
        split.setCollapsible(1, False)
        self.split = split
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
            (Qt.Key_N, lambda: s.jump_to_suspect(1)),
            (Qt.SHIFT | Qt.Key_N, lambda: s.jump_to_suspect(-1)),
            (Qt.Key_R, self.scene.reset_camera),
        ):
            QShortcut(QKeySequence(key), self, action)
        QShortcut(QKeySequence.Save, self, self.controls.engines.save.click)  # Ctrl+S
        QShortcut(QKeySequence("Ctrl+B"), self, self.toggle_panel)
        self.scene.setFocus()  # not a text field, which would take the keys for itself

    def toggle_panel(self) -> None:
        """Collapse the control panel (Ctrl+B, or drag the splitter to the left), or
        bring it back."""
        left, right = self.split.sizes()
        hint = self.controls.minimumWidth()
        self.split.setSizes([0, left + right] if left else [hint, max(left + right - hint, 1)])

    def closeEvent(self, event) -> None:
        self.session.shutdown()
        if self.settings is not None:
            from .main import save_state

            save_state(self, self.settings)
        super().closeEvent(event)

    def show_busy(self, text: str) -> None:
        self.busy.setText(text)
        self.progress.setVisible(bool(text))
