"""The plot tabs under the 3D views: error over time, filter widths, outlier weights,
bone lengths.

Each tab is a matplotlib canvas drawn by :mod:`workbench.app.figures`. A tab is redrawn
only when the take, the shown engines, their runs or the selection change, and only when
it is visible (hidden tabs are marked stale and drawn when shown); a frame change moves
the time cursor by blitting, never by redrawing the figure.
"""

from __future__ import annotations

from matplotlib.backends.backend_qtagg import FigureCanvasQTAgg
from matplotlib.figure import Figure
from PySide6.QtWidgets import QTabWidget

from ..plots import TimeCursor
from .figures import draw_bone_lengths, draw_data_weights, draw_errors, draw_filter_widths


class Canvas(FigureCanvasQTAgg):
    """A canvas whose blit asks for a repaint instead of repainting at once, so the
    cursor is painted with the 3D views in one pass of the window."""

    def blit(self, bbox=None) -> None:
        x, y, w, h = (int(v / self.device_pixel_ratio) for v in (bbox or self.figure.bbox).bounds)
        self.update(x, self.rect().height() - y - h, w, h)


TABS = (
    ("Error over time", draw_errors),
    ("Filter widths", draw_filter_widths),
    ("Outlier weights", draw_data_weights),
    ("Bone lengths", draw_bone_lengths),
)


class PlotTabs(QTabWidget):
    def __init__(self, session, parent=None) -> None:
        super().__init__(parent)
        self.session = session
        self.canvases: list[Canvas] = []
        self.cursors: list[TimeCursor | None] = [None] * len(TABS)
        self.stale = set(range(len(TABS)))
        self.drawn_for: list[tuple | None] = [None] * len(TABS)  # what each tab shows
        for title, _ in TABS:
            canvas = Canvas(Figure(layout="constrained"))
            canvas.setMinimumHeight(150)
            self.canvases.append(canvas)
            self.addTab(canvas, title)
        for signal in (session.takeChanged, session.runsChanged, session.viewChanged, session.selectionChanged):
            signal.connect(self.invalidate)
        session.frameChanged.connect(self.move_cursor)
        self.currentChanged.connect(self._shown)

    def invalidate(self) -> None:
        """Mark every tab stale and draw the visible one."""
        self.stale = set(range(len(TABS)))
        self._shown(self.currentIndex())

    def _shown(self, index: int) -> None:
        if index in self.stale:
            self.draw_tab(index)
        self.move_cursor(self.session.frame)

    def _key(self) -> tuple:
        s = self.session
        return s.take, tuple(map(id, s.shown_runs())), s.selected, len(s.shown)

    def draw_tab(self, index: int) -> None:
        """Draw tab ``index`` unless it already shows the session's take, runs and selection."""
        s = self.session
        self.stale.discard(index)
        if self.drawn_for[index] == self._key():
            return
        self.drawn_for[index] = self._key()
        canvas, draw = self.canvases[index], TABS[index][1]
        if self.cursors[index] is not None:
            self.cursors[index].remove()
            self.cursors[index] = None
        canvas.figure.clear()
        if s.take is not None:
            axes = draw(canvas.figure, s.take, s.shown_runs(), s.selected) or []
            if axes:
                self.cursors[index] = TimeCursor(axes, s.take.fps)
                self.cursors[index].move(s.frame, blit=False)
        canvas.draw_idle()

    def move_cursor(self, frame: int) -> None:
        cursor = self.cursors[self.currentIndex()]
        if cursor is not None:
            cursor.move(frame)
