"""The control panel: the take (catalogue clip or file, corruption spec, seed), the
engines (every registered one, checkable, with the inference parameters of the
highlighted one, a collapsed group per stage; any spec can be added), compare mode and
follow-root, and the message log. Every control calls a Session setter. The panel
scrolls when the window is too short for it.
"""

from __future__ import annotations

import re
from pathlib import Path

from PySide6.QtCore import Qt
from PySide6.QtWidgets import (
    QApplication,
    QCheckBox,
    QComboBox,
    QFileDialog,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QListWidget,
    QListWidgetItem,
    QProgressDialog,
    QPushButton,
    QScrollArea,
    QSpinBox,
    QToolButton,
    QVBoxLayout,
    QWidget,
)

from .. import registry
from ..engine import INFERENCE, WEIGHTS_OPTION, param_roles
from .defaults import DEFAULT_CORRUPTION
from .take import EngineRun

SPEC_ROLE = Qt.UserRole
MAX_MESSAGES = 100


#: the characters of a clip id the clip box is sized for
CLIP_CHARS = 16


class TakePanel(QGroupBox):
    """Clip picker (catalogue or file), corruption spec, seed, and whether the samples the
    suspicious-frames rules flag as bad data are cleaned as gaps."""

    def __init__(self, session, parent=None) -> None:
        super().__init__("Take", parent)
        self.session = session
        self.clip = QComboBox()
        self.clip.setEditable(True)
        self.clip.setInsertPolicy(QComboBox.NoInsert)
        self.clip.setToolTip("a catalogue clip id, or a BVH/AMC path")
        self.clip.addItems(self._catalogue())
        # sized for ids like cmu/walk/35_31, not for the longest (a studio set's run to 60
        # characters and would widen the whole panel); the list drops down as wide as they need
        self.clip.setSizeAdjustPolicy(QComboBox.AdjustToMinimumContentsLengthWithIcon)
        self.clip.setMinimumContentsLength(CLIP_CHARS)
        self.clip.view().setMinimumWidth(self.clip.view().sizeHintForColumn(0) + 24)
        self.clip.activated.connect(lambda _: self.apply())
        self.clip.lineEdit().returnPressed.connect(self.apply)
        browse = QPushButton("Open file…")
        browse.clicked.connect(self.browse)
        self.corruption = QLineEdit(DEFAULT_CORRUPTION)
        self.corruption.setToolTip(
            "models joined by '+', e.g. angular:0.5+gaps:0.01; 'none' shows the take as recorded (no ground truth)"
        )
        self.corruption.returnPressed.connect(self.apply)
        self.seed = QSpinBox()
        self.seed.setRange(0, 2**31 - 1)
        self.seed.editingFinished.connect(self.apply)
        apply = QPushButton("Apply")
        apply.clicked.connect(self.apply)
        self.fill = QCheckBox("fill suspects")
        self.fill.setToolTip(
            "clean the samples the suspicious-frames track flags as bad data (spike, turn, jump, linear) as gaps: "
            "the engines fill them instead of trusting them"
        )
        self.fill.toggled.connect(lambda _: self.apply())
        form = QFormLayout(self)
        form.addRow("clip", self.clip)
        form.addRow("", browse)
        form.addRow("corruption", self.corruption)
        row = QHBoxLayout()
        row.addWidget(self.seed, 1)
        row.addWidget(apply)
        form.addRow("seed", row)
        form.addRow("", self.fill)
        session.takeChanged.connect(self.show_take)
        session.openFailed.connect(self.show_take)  # back to the take shown: a later edit is not of the failed one

    def _catalogue(self) -> list[str]:
        from ..data import catalogue

        try:
            return [c.id for c in catalogue()]
        except Exception as err:  # no data root: files can still be opened
            self.session.message.emit(f"no clip catalogue: {err}")
            return []

    def show_take(self) -> None:
        take = self.session.take
        if take is None:
            return
        self.clip.setCurrentText(take.source)
        self.clip.lineEdit().setCursorPosition(0)  # the dataset and category, where a long id is cut
        self.corruption.setText(take.corruption)
        self.seed.setValue(take.seed)
        self.fill.blockSignals(True)  # showing the take is not asking for another
        self.fill.setChecked(take.fill_suspects)
        self.fill.blockSignals(False)

    def browse(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Open a take", "", "Motion files (*.bvh *.amc);;All files (*)")
        if path:
            self.clip.setCurrentText(path)
            self.apply()

    def apply(self) -> None:
        if not self.isVisible():  # focus-out signals while the window is torn down
            return
        take = self.session.take
        chosen = self.clip.currentText().strip(), self.corruption.text(), self.seed.value(), self.fill.isChecked()
        if take is None or chosen != (take.source, take.corruption, take.seed, take.fill_suspects):
            self.session.open(*chosen)


class Collapsible(QWidget):
    """A titled section whose body shows when its arrow button is pressed (collapsed
    when made)."""

    def __init__(self, title: str, parent=None) -> None:
        super().__init__(parent)
        self.button = QToolButton(text=title, checkable=True, checked=False)
        self.button.setToolButtonStyle(Qt.ToolButtonTextBesideIcon)
        self.button.setArrowType(Qt.RightArrow)
        self.button.setAutoRaise(True)
        self.button.toggled.connect(self.expand)
        self.body = QWidget()
        self.form = QFormLayout(self.body)
        self.form.setContentsMargins(12, 0, 0, 0)
        self.body.setVisible(False)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.setSpacing(0)
        layout.addWidget(self.button)
        layout.addWidget(self.body)

    def expand(self, on: bool) -> None:
        self.button.setChecked(on)
        self.button.setArrowType(Qt.DownArrow if on else Qt.RightArrow)
        self.body.setVisible(on)


class EnginePanel(QGroupBox):
    """Every registered engine and every spec in use, checkable; the highlighted one is
    shown as "cleaned" and its parameters can be edited. Engines are imported only when
    used (listing them must not import them all): one that fails to load fails its run,
    with the reason in its tooltip and the messages."""

    def __init__(self, session, parent=None) -> None:
        super().__init__("Engines", parent)
        self.session = session
        self.names = registry.available()
        self.list = QListWidget()
        self.list.setMinimumHeight(130)
        self.list.itemChanged.connect(self._checked)
        self.list.currentItemChanged.connect(self._highlighted)
        self.add = QLineEdit()
        self.add.setPlaceholderText("add a spec, e.g. lerp>gaussian:sigma_ms=80")
        self.add.returnPressed.connect(self._add)
        self.params = QVBoxLayout()
        self.params.setContentsMargins(4, 2, 4, 2)
        self.params_box = QGroupBox("Parameters")
        self.params_box.setLayout(self.params)
        self.save = QPushButton("Save cleaned BVH…")
        self.save.setToolTip("write the take as cleaned by the highlighted engine")
        self.save.clicked.connect(self._save)
        self.video = QPushButton("Export video…")
        self.video.setToolTip("the playback of the shown engines with the error plot's cursor, as MP4, in real time")
        self.video.clicked.connect(self._export_video)
        self.compare = QCheckBox("Compare checked engines side by side")
        self.compare.toggled.connect(session.set_compare)
        self.follow = QCheckBox("Camera follows the root")
        self.follow.setChecked(session.follow)
        self.follow.toggled.connect(session.set_follow)
        layout = QVBoxLayout(self)
        files = QHBoxLayout()
        files.addWidget(self.save)
        files.addWidget(self.video)
        for w in (self.list, self.add, self.params_box):
            layout.addWidget(w)
        layout.addLayout(files)
        for w in (self.compare, self.follow):
            layout.addWidget(w)
        # per stage of the shown spec: its name, an edit per inference parameter, the
        # values of the others (kept as the spec has them)
        self.edits: list[tuple[str, dict[str, QLineEdit], dict[str, str]]] = []
        self._params_for: str | None = None
        for signal in (session.takeChanged, session.runsChanged, session.viewChanged):
            signal.connect(self.refresh)
        self.refresh()

    def _specs(self) -> list[str]:
        return self.names + [spec for spec in self.session.specs if spec not in self.names]

    def _status(self, spec: str) -> str:
        run = self.session.runs.get(spec)
        if spec not in self.session.specs:
            return ""
        if run is None:
            return "running…" if spec in self.session.running else "queued"
        if not isinstance(run, EngineRun):
            return "failed"
        universal = run.weights_kind == "universal weights"  # the surprise: no weights of its own
        return f"{run.seconds:.2f} s" + (", universal weights" if universal else "")

    def refresh(self) -> None:
        s = self.session
        self.list.blockSignals(True)
        self.list.clear()
        for spec in self._specs():
            status = self._status(spec)
            item = QListWidgetItem(f"{spec}   ({status})" if status else spec)
            item.setData(SPEC_ROLE, spec)
            item.setFlags(Qt.ItemIsSelectable | Qt.ItemIsUserCheckable | Qt.ItemIsEnabled)
            item.setCheckState(Qt.Checked if spec in s.specs else Qt.Unchecked)
            run = s.runs.get(spec)
            item.setToolTip(run if isinstance(run, str) else getattr(run, "weights", None) or "")
            self.list.addItem(item)
            if spec == s.current:
                self.list.setCurrentItem(item)
        self.list.blockSignals(False)
        self.save.setEnabled(s.current_run() is not None)
        self.compare.setChecked(s.compare)
        self._show_params(s.current)

    def _checked(self, item: QListWidgetItem) -> None:
        spec = item.data(SPEC_ROLE)
        specs = [x for x in self.session.specs if x != spec]
        if item.checkState() == Qt.Checked:
            specs.append(spec)
        self.session.set_specs(specs, spec if item.checkState() == Qt.Checked else None)

    def _highlighted(self, item: QListWidgetItem | None, _previous=None) -> None:
        if item is not None:
            spec = item.data(SPEC_ROLE)
            self.session.set_current(spec)
            self._show_params(spec)

    def _save(self) -> None:
        s = self.session
        stem = Path(s.take.source).stem if s.take else "take"
        name = re.sub(r"[^A-Za-z0-9.-]+", "_", f"{stem}_{s.current}").strip("_") + ".bvh"
        path, _ = QFileDialog.getSaveFileName(self, "Save the cleaned take", name, "BVH files (*.bvh)")
        if path:
            s.save_current(path)

    def _export_video(self) -> None:
        s = self.session
        if s.take is None:
            return
        stem = re.sub(r"[^A-Za-z0-9.-]+", "_", Path(s.take.source).stem).strip("_") or "take"
        path, _ = QFileDialog.getSaveFileName(self, "Export the playback as video", f"{stem}.mp4", "MP4 video (*.mp4)")
        if not path:
            return
        dialog = QProgressDialog("Rendering the video…", "Cancel", 0, 0, self)
        dialog.setWindowModality(Qt.WindowModal)
        dialog.setMinimumDuration(300)

        def progress(done: int, total: int) -> bool:
            dialog.setMaximum(total)
            dialog.setValue(done)
            QApplication.processEvents()
            return not dialog.wasCanceled()

        try:
            s.export_video(path, progress)
        finally:
            dialog.close()

    def _add(self) -> None:
        spec = self.add.text().strip()
        if spec:
            self.add.clear()
            self.session.set_specs(self.session.specs + [spec], spec)

    # -- parameters -----------------------------------------------------------------
    def _show_params(self, spec: str) -> None:
        """A collapsed group per stage of ``spec`` with a field per inference parameter
        (training and trained ones are ``workbench train``'s) and a trainable stage's
        weights folder, then an Apply button; kept as typed while ``spec`` stays the one
        shown."""
        if spec == self._params_for:
            return
        self._params_for = spec
        while self.params.count():
            old = self.params.takeAt(0).widget()
            old.setParent(None)  # gone from the panel now, deleted when Qt next can
            old.deleteLater()
        self.edits = []
        try:
            engine = registry.create(spec, pretrained=False) if spec else None
        except Exception as err:  # a bad spec: say so where its parameters would be
            self.params.addWidget(QLabel(f"cannot build {spec}: {err}", wordWrap=True))
            return
        if engine is None:
            return
        for stage in getattr(engine, "stages", [engine]):
            roles = param_roles(stage.params)
            values = {name: str(getattr(stage.params, name)) for name in roles}
            fields = {name: QLineEdit(values[name]) for name, role in roles.items() if role == INFERENCE}
            if stage.info.trainable:
                fields[WEIGHTS_OPTION] = QLineEdit(
                    str(stage.weights_folder or ""),
                    placeholderText="default",
                    toolTip="a folder that `workbench train --out` wrote; empty: the committed weights",
                )
            kept = {name: value for name, value in values.items() if name not in fields}
            self.edits.append((stage.info.name, fields, kept))
            group = Collapsible(f"{stage.info.name} ({len(fields)} parameters)" if fields else stage.info.name)
            if not fields:
                group.form.addRow(QLabel("no inference parameters"))
            for name, edit in fields.items():
                edit.returnPressed.connect(self._apply_params)
                group.form.addRow(name, edit)
            self.params.addWidget(group)
        if any(fields for _, fields, _ in self.edits):
            button = QPushButton("Apply parameters")
            button.clicked.connect(self._apply_params)
            self.params.addWidget(button)

    def _apply_params(self) -> None:
        """Replace the current spec by one with the edited parameters and run it."""
        s = self.session
        try:
            spec = ">".join(
                registry.create(
                    name
                    + ":"
                    + ",".join(
                        f"{k}={v}" for k, v in (kept | {k: e.text().strip() for k, e in fields.items()}).items()
                    ),
                    pretrained=False,
                ).spec
                for name, fields, kept in self.edits
            )
        except Exception as err:  # a bad value: tell the user, keep the old spec
            s.message.emit(f"bad parameters: {err}")
            return
        if spec != s.current:
            s.set_specs(
                [spec if x == s.current else x for x in s.specs] if s.current in s.specs else s.specs + [spec], spec
            )


class MessageLog(QListWidget):
    """The newest messages first (engine failures, files that cannot be read...)."""

    def add(self, text: str) -> None:
        self.insertItem(0, text)
        self.item(0).setToolTip(text)
        while self.count() > MAX_MESSAGES:
            self.takeItem(self.count() - 1)


class ControlPanel(QScrollArea):
    """The take, the engines and the messages in a column that scrolls vertically when
    the window is shorter than it."""

    def __init__(self, session, parent=None) -> None:
        super().__init__(parent)
        self.take = TakePanel(session)
        self.engines = EnginePanel(session)
        self.log = MessageLog()
        self.log.setWordWrap(True)
        session.message.connect(self.log.add)
        column = QWidget()
        layout = QVBoxLayout(column)
        layout.setContentsMargins(6, 6, 6, 6)
        layout.addWidget(self.take)
        layout.addWidget(self.engines, 1)
        layout.addWidget(QLabel("Messages"))
        layout.addWidget(self.log)
        self.log.setMaximumHeight(110)
        self.setWidget(column)
        self.setWidgetResizable(True)
        self.setHorizontalScrollBarPolicy(Qt.ScrollBarAlwaysOff)
        self.setFrameShape(QScrollArea.NoFrame)
        self.setMinimumWidth(column.minimumSizeHint().width() + self.verticalScrollBar().sizeHint().width())
