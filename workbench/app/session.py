"""The app's one evented state, which every view subscribes to.

A :class:`Session` holds the take (clip, corruption, seed), the engine specs and their
runs, the engine shown as "cleaned", compare mode, follow-root, the frame, playing and
speed, and the selected joints. Views call its setters and redraw on its signals; no
view talks to another. Loading a take and running engines happen on a worker thread
(a one-thread QThreadPool, so engines never compete for the two cores with each other):
the window never waits for them, and a failure (EngineError or any other exception)
becomes the run's error text and a ``message``, never a traceback.

Units: frames (the take's fps), playback speed as a multiple of real time.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from PySide6.QtCore import QObject, QRunnable, QThreadPool, QTimer, Signal

from ..data.inspection import Inspection, Interval
from ..errors import describe
from .take import (
    DEFAULT_CORRUPTION,
    EngineRun,
    Take,
    inspect_runs,
    inspect_take,
    open_take,
    run_engine,
    stage_engines,
)

TICK_MS = 15


class _Signals(QObject):
    started = Signal()
    done = Signal(object)
    failed = Signal(str)
    skipped = Signal()


class _Job(QRunnable):
    """Runs ``fn()`` on a pool thread and posts its value or its error text back;
    skips ``fn`` when ``stale()`` says its result would be dropped anyway, and says so
    (``skipped``)."""

    def __init__(self, fn: Callable[[], object], stale: Callable[[], bool]) -> None:
        super().__init__()
        self.fn, self.stale, self.signals = fn, stale, _Signals()

    def run(self) -> None:
        if self.stale():
            self.signals.skipped.emit()
            return
        self.signals.started.emit()
        try:
            value = self.fn()
        except Exception as err:  # shown in the window, never raised on the console
            self.signals.failed.emit(describe(err))
        else:
            self.signals.done.emit(value)


class Session(QObject):
    takeChanged = Signal()
    runsChanged = Signal()  # a run arrived, failed, or the engine list changed
    viewChanged = Signal()  # the shown engine, compare mode or follow-root changed
    frameChanged = Signal(int)
    playingChanged = Signal(bool)
    selectionChanged = Signal()
    busyChanged = Signal(str)  # what the worker is doing, "" when idle
    message = Signal(str)
    openFailed = Signal()  # a take asked for did not open: the shown one stays

    def __init__(self, parent: QObject | None = None) -> None:
        super().__init__(parent)
        self.take: Take | None = None
        self.specs: list[str] = []
        self.runs: dict[str, EngineRun | str] = {}
        self.current = ""
        self.compare = False
        self.follow = True
        self.frame = 0
        self.playing = False
        self.speed = 1.0
        self.selected: tuple[int, ...] = ()
        self._pool = QThreadPool(self)
        self._pool.setMaxThreadCount(1)
        self._jobs: dict[_Job, str] = {}
        self._generation = 0  # counts takes shown: runs for an older one are dropped
        self._opening = 0  # counts open requests: only the latest is shown
        self._timer = QTimer(self)
        self._timer.setInterval(TICK_MS)
        self._timer.timeout.connect(self._tick)
        self._clock = (0.0, 0)  # (time, frame) playback started from
        self._rules: tuple[Take, Inspection | None] | None = None  # the rules' inspection of a take (None: failed)
        self._inspection: tuple[tuple, Inspection] | None = None  # (what it was made of, it)
        self.running: set[str] = set()  # the specs the worker has begun cleaning with
        self._queued: set[str] = set()  # the specs with a run of this take on the worker, begun or not
        self._seconds_per_frame: dict[str, float] = {}  # each spec's last run

    # -- the worker -----------------------------------------------------------------
    def _submit(
        self,
        what: str,
        fn: Callable[[], object],
        done: Callable[[object], None],
        failed: Callable[[str], None],
        wanted: Callable[[], bool],
        started: Callable[[], None] | None = None,
        settled: Callable[[], None] | None = None,
    ) -> None:
        """Run ``fn`` on the worker, then ``done(value)`` or ``failed(text)`` here, unless
        ``wanted()`` has turned False meanwhile (a newer take or request); ``started()``
        here when the worker begins it, ``settled()`` here when it is over, wanted or not."""
        job = _Job(fn, lambda: not wanted())
        if started is not None:
            job.signals.started.connect(lambda: wanted() and started())

        def finish(handler, value) -> None:
            del self._jobs[job]
            # Qt holds the slots, and the slots hold the job and what its function
            # captured (a take): let go of them, or every take ever opened stays alive
            signals = [job.signals.done, job.signals.failed, job.signals.skipped]
            for signal in signals + ([job.signals.started] if started else []):
                signal.disconnect()
            self.busyChanged.emit(self._busy_text())
            if handler is None and wanted():  # skipped on the worker, wanted again since: it runs after all
                self._submit(what, fn, done, failed, wanted, started, settled)
                return
            if settled is not None:
                settled()
            if handler is not None and wanted():
                handler(value)

        job.signals.done.connect(lambda value: finish(done, value))
        job.signals.failed.connect(lambda text: finish(failed, text))
        job.signals.skipped.connect(lambda: finish(None, None))
        self._jobs[job] = what
        self.busyChanged.emit(self._busy_text())
        self._pool.start(job)

    def _busy_text(self) -> str:
        whats = list(self._jobs.values())
        return "" if not whats else whats[0] + (f" (+{len(whats) - 1} queued)" if len(whats) > 1 else "")

    @property
    def busy(self) -> bool:
        return bool(self._jobs)

    def wait(self, msecs: int = 30000) -> bool:
        """Block until the worker is idle (for scripts and tests)."""
        return self._pool.waitForDone(msecs)

    def shutdown(self) -> None:
        """Stop playing and wait for the worker (before closing); queued jobs become
        stale, so they end at once, and only the running one is waited for."""
        self.set_playing(False)
        self._generation += 1
        self._opening += 1
        self._pool.waitForDone()

    # -- the take -------------------------------------------------------------------
    def open(
        self, source: str, corruption: str = DEFAULT_CORRUPTION, seed: int = 0, fill_suspects: bool = False
    ) -> None:
        """Load a clip id or file and corrupt it (with ``fill_suspects``, what the
        inspection rules flag as bad data made gaps), on the worker (the latest request
        wins)."""
        self._opening += 1
        request = self._opening
        self._submit(
            f"loading {source}",
            lambda: open_take(source, corruption, seed, fill_suspects),
            self.set_take,
            lambda text: self._open_failed(f"cannot open {source}: {text}"),
            lambda: request == self._opening,
        )

    def _open_failed(self, text: str) -> None:
        self.message.emit(text)
        self.openFailed.emit()

    def set_take(self, take: Take) -> None:
        """Show ``take`` and run every engine on it."""
        self._generation += 1
        self.set_playing(False)
        names = [self.take.motion.skeleton.names[j] for j in self.selected] if self.take is not None else []
        self.take, self.runs, self.frame, self.running, self._queued = take, {}, 0, set(), set()
        kept = take.motion.skeleton.names  # the selected joints, by name: another skeleton's index is another joint
        self.selected = tuple(kept.index(name) for name in names if name in kept)
        self.takeChanged.emit()
        self.frameChanged.emit(0)
        self._run(self.specs)
        generation = self._generation
        self._submit(
            "inspecting the take",
            lambda: inspect_take(take),
            self._inspected,
            lambda text: self._inspection_failed(take, text),
            lambda: generation == self._generation,
        )

    def _inspection_failed(self, take: Take, text: str) -> None:
        self._rules = take, None
        self.message.emit(f"cannot inspect the take: {text}")

    def _inspected(self, rules: Inspection) -> None:
        self._rules = self.take, rules
        self.runsChanged.emit()  # the suspicious track redraws

    # -- engines --------------------------------------------------------------------
    def set_specs(self, specs: list[str], current: str | None = None) -> None:
        """The engine list; runs the new ones. ``current`` is shown as "cleaned" (the
        first spec when not given or not in the list)."""
        specs = list(dict.fromkeys(s.strip() for s in specs if s.strip()))
        new = [s for s in specs if s not in self.runs and s not in self._queued]  # ticked again: its run goes on
        self.specs = specs
        self.runs = {s: r for s, r in self.runs.items() if s in specs}
        self.current = (
            current if current in specs else (self.current if self.current in specs else (specs[0] if specs else ""))
        )
        self.runsChanged.emit()
        self.viewChanged.emit()
        self._run(new)

    def _run(self, specs: list[str]) -> None:
        """Queue the runs of ``specs`` on the take: the shown engine first, then the
        fastest (:meth:`expected_seconds_per_frame`), so one slow engine does not keep
        the others waiting."""
        take = self.take
        if take is None:
            return
        generation = self._generation

        def settled(spec: str) -> None:  # done, failed or dropped: a later tick runs it again
            if generation == self._generation:
                self._queued.discard(spec)
                self.running.discard(spec)

        for spec in sorted(specs, key=lambda s: (s != self.current, self.expected_seconds_per_frame(s))):
            self._queued.add(spec)
            self._submit(
                f"cleaning with {spec}",
                lambda spec=spec: run_engine(spec, take),
                lambda run: self._arrived(run.spec, run),
                lambda text, spec=spec: self._arrived(spec, text),
                lambda spec=spec: generation == self._generation and spec in self.specs,
                lambda spec=spec: self._started(spec),
                lambda spec=spec: settled(spec),
            )

    def expected_seconds_per_frame(self, spec: str) -> float:
        """What a run of ``spec`` is expected to cost: the seconds per frame its last run
        took; before it has run, 0 for an engine with no trained stage (the classical
        ones run at tens of thousands of frames a second) and infinity for a trained one."""
        if spec in self._seconds_per_frame:
            return self._seconds_per_frame[spec]
        from ..engine import EngineError

        try:
            trained = any(engine.info.trainable for engine in stage_engines(spec))
        except EngineError:
            trained = True
        return float("inf") if trained else 0.0

    def _started(self, spec: str) -> None:
        self.running.add(spec)
        self.runsChanged.emit()

    def _arrived(self, spec: str, run: EngineRun | str) -> None:
        if spec not in self.specs:
            return
        self.runs[spec] = run
        if isinstance(run, EngineRun) and self.take is not None:
            self._seconds_per_frame[spec] = run.seconds / max(self.take.n_frames, 1)
        if isinstance(run, str):
            self.message.emit(f"engine {spec} failed: {run}")
        self.runsChanged.emit()

    @property
    def shown(self) -> list[str]:
        """The engines in the 3D views and plots: all of them when comparing, else the
        current one."""
        return list(self.specs) if self.compare else [self.current] if self.current else []

    def shown_runs(self) -> list[EngineRun]:
        """The shown engines' finished runs."""
        return [r for s in self.shown if isinstance(r := self.runs.get(s), EngineRun)]

    def current_run(self) -> EngineRun | None:
        """The finished run of the engine shown as "cleaned", if there is one."""
        run = self.runs.get(self.current)
        return run if isinstance(run, EngineRun) else None

    def save_current(self, path: str) -> bool:
        """Write the current engine's cleaned take to ``path`` as BVH (atomically: a
        failed write leaves no file); says what happened in a ``message``. Returns
        whether it was written."""
        from ..io import write_bvh

        run = self.current_run()
        if run is None:
            self.message.emit(f"nothing to save: {self.current or 'no engine'} has no result yet")
            return False
        try:
            write_bvh(path, run.track.motion)
        except (OSError, ValueError) as err:
            self.message.emit(f"cannot save {path}: {describe(err)}")
            return False
        self.message.emit(f"saved {run.spec}'s cleaned take to {path}")
        return True

    def export_video(self, path: str, progress=None) -> bool:
        """Write the playback of the shown engines' runs with the error plot's cursor to
        ``path`` (MP4, real time; :func:`workbench.app.video.write_video`, whose
        ``progress`` can cancel it); says what happened in a ``message``. Returns whether
        it was written."""
        from .video import write_video

        if self.take is None:
            return False
        self.set_playing(False)
        runs = self.shown_runs()
        try:
            written = write_video(path, self.take, runs, progress)
        except (OSError, ValueError, RuntimeError) as err:
            self.message.emit(f"cannot write {path}: {describe(err)}")
            return False
        if written is None:
            self.message.emit(f"video cancelled: {path} not written")
            return False
        missing = [spec for spec in self.shown if spec not in {r.spec for r in runs}]
        failed = [spec for spec in missing if isinstance(self.runs.get(spec), str)]
        waiting = [spec for spec in missing if spec not in failed]
        left_out = "".join(
            f" ({', '.join(specs)} left out: {why})"
            for specs, why in ((failed, "failed"), (waiting, "still running"))
            if specs
        )
        self.message.emit(f"wrote the video of {', '.join(r.spec for r in runs) or 'the take'} to {path}{left_out}")
        return True

    def set_current(self, spec: str) -> None:
        if spec in self.specs and spec != self.current:
            self.current = spec
            self.viewChanged.emit()

    def set_compare(self, on: bool) -> None:
        if bool(on) != self.compare:
            self.compare = bool(on)
            self.viewChanged.emit()

    def set_follow(self, on: bool) -> None:
        if bool(on) != self.follow:
            self.follow = bool(on)
            self.viewChanged.emit()

    # -- suspicious frames ------------------------------------------------------------
    def inspection(self) -> Inspection | None:
        """The take's suspicious samples: the rules' (made on the worker after the take is
        shown; None until then) and the evidence of every checked engine's finished run
        (rejected samples, disagreement)."""
        if self.take is None or self._rules is None or self._rules[0] is not self.take or self._rules[1] is None:
            return None
        runs = [r for s in self.specs if isinstance(r := self.runs.get(s), EngineRun)]
        key = (self.take, tuple(map(id, runs)))
        if self._inspection is None or self._inspection[0] != key:
            self._inspection = key, inspect_runs(self.take, self._rules[1], runs)
        return self._inspection[1]

    def suspects(self) -> list[Interval]:
        """The suspicious intervals, by first frame."""
        found = self.inspection()
        return found.intervals() if found is not None else []

    def jump_to_suspect(self, direction: int = 1) -> Interval | None:
        """Pause and show the first frame of the next suspicious interval after the
        current frame (``direction`` -1: the one before), wrapping round; says which in a
        ``message``. Returns it (None when there is none)."""
        intervals = self.suspects()
        if not intervals:
            if self.inspection() is not None:
                self.message.emit("no suspicious frames in this take")
            elif self._rules is not None and self._rules[0] is self.take:  # its inspection failed
                self.message.emit("the take could not be inspected: no suspicious frames to show")
            else:
                self.message.emit("the take is still being inspected")
            return None
        starts = sorted({i.first for i in intervals})
        later = [f for f in starts if (f - self.frame) * direction > 0]
        frame = (min(later) if direction > 0 else max(later)) if later else starts[0 if direction > 0 else -1]
        self.step(frame - self.frame)
        here = [i for i in intervals if i.first == frame]
        self.message.emit(" · ".join(str(i) for i in here))
        return here[0]

    # -- time -----------------------------------------------------------------------
    @property
    def n_frames(self) -> int:
        return self.take.n_frames if self.take else 0

    def set_frame(self, frame: int) -> None:
        """Show ``frame`` (clamped); playback goes on from there."""
        frame = min(max(int(frame), 0), max(self.n_frames - 1, 0))
        self._clock = (time.perf_counter(), frame)
        self._show(frame)

    def _show(self, frame: int) -> None:
        if frame != self.frame:
            self.frame = frame
            self.frameChanged.emit(frame)

    def step(self, n: int) -> None:
        """Pause and move ``n`` frames."""
        self.set_playing(False)
        self.set_frame(self.frame + n)

    def set_playing(self, on: bool) -> None:
        on = bool(on) and self.n_frames > 1
        if on == self.playing:
            return
        self.playing = on
        if on:
            self._clock = (time.perf_counter(), self.frame)
            self._timer.start()
        else:
            self._timer.stop()
        self.playingChanged.emit(on)

    def toggle_playing(self) -> None:
        self.set_playing(not self.playing)

    def set_speed(self, speed: float) -> None:
        self._clock = (time.perf_counter(), self.frame)
        self.speed = float(speed)

    def _tick(self) -> None:
        t0, f0 = self._clock
        elapsed = int((time.perf_counter() - t0) * self.take.fps * self.speed)
        self._show((f0 + elapsed) % self.n_frames)

    # -- joints ---------------------------------------------------------------------
    def select_joint(self, joint: int | None, add: bool = False) -> None:
        """Select ``joint`` (None clears); ``add`` toggles it in the selection instead."""
        if joint is None:
            selected: tuple[int, ...] = ()
        elif add:
            selected = tuple(j for j in self.selected if j != joint) + (() if joint in self.selected else (joint,))
        else:
            selected = (joint,)
        if selected != self.selected:
            self.selected = selected
            self.selectionChanged.emit()
