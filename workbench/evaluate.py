"""Benchmarks: engines x clips x seeds -> a tidy table of errors and speed (no GUI).

Every engine sees the same corrupted observations (same corruption spec and seeds).
``frames_per_s`` is cleaning throughput: frames cleaned divided by the wall time spent
inside ``engine.clean`` (single process, this machine). ``peak_mb`` is the most resident
memory the engine's clean of the longest case added to the process, in MB, measured in a
clean of its own after the timed ones: its working memory, beyond its loaded weights
(Linux; absent elsewhere). Other summary values are means over all (clip, seed) rows of
an engine; :meth:`BenchResult.summarise` gives them over some of the clips (one dataset).
``glitches`` names the capture glitches of the clean clips scored against
(:mod:`workbench.data.quality`), which stay in the scores. A clip too short for the
corruption is skipped, and one an engine refuses left out of its rows, each with a note.
"""

from __future__ import annotations

import ctypes
import dataclasses
import math
import time
from dataclasses import dataclass, field
from typing import Callable, Mapping, Sequence

import numpy as np

from . import metrics, registry
from .core.motion import Case, Motion, Observation
from .corruption import CorruptionApplyError, make_case, parse_corruption
from .data.quality import Glitch, reference_glitches
from .engine import Engine, EngineError
from .metrics import METRICS

#: summary columns after the metrics: speed and memory
COST_COLUMNS = ("frames_per_s", "peak_mb")


def resident_mb(field: str = "VmRSS") -> float:
    """This process's resident memory (``VmRSS``) or its peak (``VmHWM``) in MB; NaN
    where /proc does not tell (not Linux)."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith(field + ":"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return math.nan


def reset_peak_resident() -> float:
    """Hand freed heap memory back to the system (glibc's malloc_trim: what an earlier
    engine freed would otherwise be reused unseen), then start a new peak of resident
    memory at the current one (Linux: clear_refs 5); returns the current resident MB,
    NaN where the peak cannot be reset."""
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        pass
    try:
        with open("/proc/self/clear_refs", "w", encoding="ascii") as fh:
            fh.write("5")
    except OSError:
        return math.nan
    return resident_mb()


def format_value(metric: str, value: float) -> str:
    """A table cell: speeds and memory whole, jitter in 3 significant digits, the rest to
    3 decimals; "–" for NaN (undefined)."""
    if math.isnan(value):
        return "–"
    if metric in COST_COLUMNS:
        return f"{value:,.0f}"
    return f"{value:.3g}" if metric == "jitter_cm_s3" else f"{value:.3f}"


@dataclass
class BenchResult:
    """Per-row results and per-engine summaries, keyed by each spec exactly as given.

    ``skipped``: the clips the corruption could not be applied to (too short for a
    block), with the reason, left out for every engine. ``refused``: per engine, the
    clips it refused to clean (an engine trained for another skeleton, a filter longer
    than the take), with its message; its summary is over the clips it cleaned.
    ``dataset_of``: each clip's dataset, where the caller said; ``peaks``: per engine, the
    ``peak_mb`` of each dataset, measured on its longest case (the summary's is the
    largest). ``fill_suspects``: the engines saw the samples ``workbench inspect`` flags
    as bad data missing (:func:`workbench.data.inspection.suspects_missing`), and
    ``gap_mpjpe_cm`` covers them too."""

    corruption: str
    seeds: list[int]
    clips: list[str]
    rows: list[dict] = field(default_factory=list)
    summary: dict[str, dict[str, float]] = field(default_factory=dict)
    #: the capture glitches of each clip's clean motion, for the clips that have any
    glitches: dict[str, list[Glitch]] = field(default_factory=dict)
    skipped: dict[str, str] = field(default_factory=dict)
    refused: dict[str, dict[str, str]] = field(default_factory=dict)
    dataset_of: dict[str, str] = field(default_factory=dict)
    peaks: dict[str, dict[str, float]] = field(default_factory=dict)
    fill_suspects: bool = False
    #: on Dask, each worker's peak resident memory (MB) by its address: a fact of the run,
    #: not a result, so not in the JSON
    worker_peaks_mb: dict[str, float] = field(default_factory=dict)

    def to_json(self) -> dict:
        return {
            "corruption": self.corruption,
            "fill_suspects": self.fill_suspects,
            "seeds": self.seeds,
            "clips": self.clips,
            "rows": self.rows,
            "summary": self.summary,
            "summary_by_dataset": {name: self.summarise(name) for name in self.datasets()},
            "skipped": self.skipped,
            "refused": self.refused,
            "reference_glitches": {
                clip: [dataclasses.asdict(g) for g in found] for clip, found in self.glitches.items()
            },
        }

    def datasets(self) -> dict[str, list[str]]:
        """The benchmarked clips by dataset (``dataset_of``; "" where it is not known), in
        benchmark order."""
        out: dict[str, list[str]] = {}
        for clip in self.clips:
            out.setdefault(self.dataset_of.get(clip, ""), []).append(clip)
        return out

    def summarise(self, dataset: str) -> dict[str, dict[str, float]]:
        """Per engine, the summary over the rows of one dataset's clips: each metric's
        mean, the throughput and the dataset's ``peak_mb``."""
        chosen = set(self.datasets().get(dataset, ()))
        out = {}
        for spec in self.summary:
            out[spec] = summarise_rows([r for r in self.rows if r["engine"] == spec and r["clip"] in chosen])
            if dataset in self.peaks.get(spec, {}):
                out[spec]["peak_mb"] = self.peaks[spec][dataset]
        return out

    def markdown(self, dataset: str | None = None) -> str:
        """The summary table, over all clips or over one dataset's; "–" for an engine that
        cleaned none of them."""
        summary = self.summary if dataset is None else self.summarise(dataset)
        cols = [m for m in (*METRICS, *COST_COLUMNS) if any(m in s for s in summary.values())]
        head = "| engine | " + " | ".join(cols) + " |"
        lines = [head, "|" + "---|" * (len(cols) + 1)]
        for spec, s in summary.items():
            cells = [format_value(c, s.get(c, math.nan)) for c in cols]
            lines.append(f"| {spec} | " + " | ".join(cells) + " |")
        return "\n".join(lines)

    def per_clip(self, metric: str) -> dict[str, dict[str, float]]:
        """``metric``'s mean over the seeds, by clip (in benchmark order), then by engine;
        NaN where no seed defines it (e.g. ``gap_mpjpe_cm`` without missing data)."""
        if metric not in METRICS:
            raise ValueError(f"unknown metric {metric!r}; one of {', '.join(METRICS)}")
        values: dict[tuple[str, str], list[float]] = {}
        for r in self.rows:
            if not math.isnan(r.get(metric, math.nan)):
                values.setdefault((r["clip"], r["engine"]), []).append(r[metric])
        return {
            clip: {
                spec: float(np.mean(values[clip, spec])) if (clip, spec) in values else math.nan
                for spec in self.summary
            }
            for clip in self.clips
        }

    def per_joint(self, metric: str, dataset: str | None = None) -> dict[str, dict[str, float]]:
        """``metric`` (one of :data:`~workbench.metrics.JOINT_METRICS`) by joint, in the
        skeleton's order, then by engine: the mean over the rows (clips and seeds) of
        one dataset, or of all, that define it for the joint (rows made with
        ``per_joint``; NaN for an engine with none)."""
        if metric not in metrics.JOINT_METRICS:
            raise ValueError(f"unknown per-joint metric {metric!r}; one of {', '.join(metrics.JOINT_METRICS)}")
        chosen = set(self.clips if dataset is None else self.datasets().get(dataset, ()))
        values: dict[str, dict[str, list[float]]] = {}
        for r in self.rows:
            if r["clip"] in chosen and "per_joint" in r:
                for joint, value in r["per_joint"].get(metric, {}).items():
                    by_engine = values.setdefault(joint, {})
                    if not math.isnan(value):
                        by_engine.setdefault(r["engine"], []).append(value)
        return {
            joint: {spec: float(np.mean(by_engine[spec])) if spec in by_engine else math.nan for spec in self.summary}
            for joint, by_engine in values.items()
        }

    def per_joint_markdown(self, metric: str, dataset: str | None = None) -> str:
        """A table of ``metric`` with a row per joint (:meth:`per_joint`) and a column per engine."""
        specs = list(self.summary)
        lines = [f"| joint ({metric}) | " + " | ".join(specs) + " |", "|" + "---|" * (len(specs) + 1)]
        for joint, by_engine in self.per_joint(metric, dataset).items():
            lines.append(f"| {joint} | " + " | ".join(format_value(metric, by_engine[s]) for s in specs) + " |")
        return "\n".join(lines)

    def per_clip_markdown(self, metric: str) -> str:
        """A table of ``metric`` with a row per clip (its frame count, then every engine's
        mean over the seeds) and a last row with the summary's mean over all rows."""
        frames = {r["clip"]: r["frames"] for r in self.rows}
        specs = list(self.summary)
        lines = [f"| clip ({metric}) | frames | " + " | ".join(specs) + " |", "|" + "---|" * (len(specs) + 2)]

        def cells(values) -> str:
            return " | ".join(format_value(metric, v) for v in values)

        for clip, by_engine in self.per_clip(metric).items():
            lines.append(f"| {clip} | {frames.get(clip, 0)} | {cells(by_engine[s] for s in specs)} |")
        lines.append(f"| **mean** | | {cells(self.summary[s].get(metric, math.nan) for s in specs)} |")
        return "\n".join(lines)


def summarise_rows(rows: Sequence[dict]) -> dict[str, float]:
    """Each metric's mean over the ``rows`` that define it, and ``frames_per_s``: the
    frames of all rows over their cleaning seconds (absent without rows)."""
    summary = {}
    for m in METRICS:
        vals = [r[m] for r in rows if m in r and not math.isnan(r[m])]
        if vals:
            summary[m] = float(np.mean(vals))
    if rows:
        seconds = sum(r["seconds"] for r in rows)
        summary["frames_per_s"] = sum(r["frames"] for r in rows) / seconds if seconds > 0 else float("inf")
    return summary


def run_benchmark(
    engine_specs: Sequence[str | Engine],
    corruption: str,
    clips: Sequence[tuple[str, Motion]],
    seeds: Sequence[int] = (0,),
    progress: Callable[[str], None] | None = None,
    datasets: Mapping[str, str] | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    per_joint: bool = False,
    fill_suspects: bool = False,
) -> BenchResult:
    """Corrupt each clip with each seed, clean it with each engine, score it. Engines are
    spec strings or ready engine objects (keyed by their ``spec``); ``datasets``: each
    clip's dataset, for summaries per dataset. A clip the corruption cannot be applied to
    (too short for a block) is skipped, and a clip an engine refuses (EngineError) is
    left out of that engine's rows; both are recorded with the reason. Raises
    CorruptionApplyError when the corruption fits no clip.

    With ``workers`` or ``scheduler`` (spec strings only) each (engine, clip) is a task
    on Dask distributed (:func:`workbench.batch.dask_client`), run with one thread, and
    ``peak_mb`` is a worker's; the rows' scores are then the same bit for bit whatever
    the number of workers (the seconds are measured where each task ran). With
    ``per_joint`` each row also holds :func:`workbench.metrics.per_joint` under
    ``"per_joint"`` (for :meth:`BenchResult.per_joint`). With ``fill_suspects`` the
    engines see the samples ``workbench inspect`` flags as bad data missing
    (:attr:`BenchResult.fill_suspects`)."""
    result = BenchResult(
        corruption=str(parse_corruption(corruption)),
        seeds=list(seeds),
        clips=[],
        glitches={clip_id: found for clip_id, motion in clips if (found := reference_glitches(motion))},
        dataset_of=dict(datasets or {}),
        fill_suspects=fill_suspects,
    )
    cases: list[tuple[str, Case]] = []
    for clip_id, motion in clips:
        try:
            cases += [(clip_id, make_case(motion, corruption, seed)) for seed in seeds]
        except CorruptionApplyError as err:
            result.skipped[clip_id] = str(err)
            result.glitches.pop(clip_id, None)
            continue
        result.clips.append(clip_id)
    if clips and not cases:
        first = next(iter(result.skipped.items()))
        raise CorruptionApplyError(f"{result.corruption} fits none of the {len(clips)} clips; {first[0]}: {first[1]}")
    if fill_suspects:
        from .data.inspection import suspects_missing

        cases = [(i, dataclasses.replace(c, observation=suspects_missing(c.observation))) for i, c in cases]
    specs = [e if isinstance(e, str) else e.spec for e in engine_specs]
    if workers is not None or scheduler is not None:
        runner = _DaskRunner(specs, workers, scheduler, per_joint)
    else:
        runner = _SerialRunner(engine_specs, per_joint)
    with runner:
        for spec in specs:
            rows, refused = runner.rows(spec, cases, progress)
            result.rows += rows
            if refused:
                result.refused[spec] = refused
            summary = summarise_rows(rows)
            for name, ids in result.datasets().items():  # memory in a clean of its own per dataset
                mine = set(ids) - set(refused)
                accepted = [case for clip_id, case in cases if clip_id in mine]
                if accepted:
                    mb = runner.peak_mb(spec, max(accepted, key=lambda c: c.truth.n_frames).observation)
                    if not math.isnan(mb):
                        result.peaks.setdefault(spec, {})[name] = mb
            if result.peaks.get(spec):
                summary["peak_mb"] = max(result.peaks[spec].values())
            result.summary[spec] = summary
    result.worker_peaks_mb = getattr(runner, "worker_peaks_mb", {})
    return result


class _SerialRunner:
    """Cleans in this process, each engine made once."""

    def __init__(self, engine_specs: Sequence[str | Engine], per_joint: bool) -> None:
        self.engines = {(e if isinstance(e, str) else e.spec): e for e in engine_specs}
        self.per_joint = per_joint

    def __enter__(self):
        return self

    def __exit__(self, *_exc) -> None:
        pass

    def _engine(self, spec: str) -> Engine:
        if isinstance(self.engines[spec], str):
            self.engines[spec] = registry.create(spec)
        return self.engines[spec]

    def rows(self, spec, cases, progress):
        return _clean_cases(self._engine(spec), cases, progress, spec, self.per_joint)

    def peak_mb(self, spec: str, observation: Observation) -> float:
        return _peak_mb(self._engine(spec), observation)


class _DaskRunner:
    """Cleans on Dask distributed, a task per (engine, clip), every engine's tasks
    submitted at once; rows come back in the serial order."""

    def __init__(self, specs: list[str], workers: int | None, scheduler: str | None, per_joint: bool) -> None:
        self.specs, self.workers, self.scheduler, self.per_joint = specs, workers, scheduler, per_joint
        self.futures: dict = {}

    def __enter__(self):
        from .batch import dask_client

        self._session = dask_client(self.workers, self.scheduler)
        self.client = self._session.__enter__()
        return self

    def __exit__(self, *exc) -> None:
        try:
            self.worker_peaks_mb = self.client.run(resident_mb, "VmHWM")
        finally:
            self._session.__exit__(*exc)

    def rows(self, spec, cases, progress):
        by_clip: dict[str, list[tuple[str, Case]]] = {}
        for clip_id, case in cases:
            by_clip.setdefault(clip_id, []).append((clip_id, case))
        if not self.futures:  # every engine's tasks at once: the workers never wait for the next engine
            self.futures = {
                (s, clip_id): self.client.submit(bench_task, s, clip_cases, self.per_joint, pure=False)
                for s in self.specs
                for clip_id, clip_cases in by_clip.items()
            }
        rows, refused = [], {}
        for clip_id in by_clip:
            clip_rows, clip_refused = self.futures[spec, clip_id].result()
            rows += clip_rows
            refused.update(clip_refused)
            if progress:
                progress(f"{spec} on {clip_id}: done")
        return rows, refused

    def peak_mb(self, spec: str, observation: Observation) -> float:
        return self.client.submit(peak_task, spec, observation, pure=False).result()


def _clean_cases(
    engine: Engine,
    cases: Sequence[tuple[str, Case]],
    progress: Callable[[str], None] | None,
    spec: str,
    per_joint: bool = False,
) -> tuple[list[dict], dict[str, str]]:
    """(rows, refused): ``engine`` timed and scored on each (clip, case), after a warm-up
    (lazy imports, caches) outside the timed calls, its rows keyed by ``spec`` (with
    ``per_joint``, the scores by joint too); the clips it refused, with its message."""
    rows: list[dict] = []
    refused: dict[str, str] = {}
    warm = False
    for clip_id, case in cases:
        if clip_id in refused:
            continue
        if progress:
            progress(f"{spec} on {clip_id} seed {case.seed}")
        try:
            if not warm:
                n = min(case.observation.n_frames, 256)
                engine.clean(Observation(case.observation.motion.slice(0, n), case.observation.observed[:n]))
                warm = True
            t0 = time.perf_counter()
            cleaned = engine.clean(case.observation)
            dt = time.perf_counter() - t0
        except EngineError as err:
            refused[clip_id] = str(err)
            continue
        row = {"engine": spec, "clip": clip_id, "seed": case.seed, "frames": case.truth.n_frames, "seconds": dt}
        row.update(metrics.score(case.truth, cleaned.motion, case.observation.observed))
        if per_joint:
            row["per_joint"] = metrics.per_joint(case.truth, cleaned.motion, case.observation.observed)
        rows.append(row)
    return rows, refused


def _peak_mb(engine: Engine, observation: Observation) -> float:
    """The resident memory (MB) a clean of ``observation`` adds at its peak, in a clean
    of its own (NaN where /proc does not tell)."""
    before = reset_peak_resident()
    engine.clean(observation)
    return max(resident_mb("VmHWM") - before, 0.0)


def bench_task(spec: str, cases: list[tuple[str, Case]], per_joint: bool = False) -> tuple[list[dict], dict[str, str]]:
    """:func:`_clean_cases` on a worker, with one thread and the worker's engine."""
    from .batch import one_thread, worker_engine

    with one_thread():
        return _clean_cases(worker_engine(spec), cases, None, spec, per_joint)


def peak_task(spec: str, observation: Observation) -> float:
    """:func:`_peak_mb` on a worker, with one thread."""
    from .batch import one_thread, worker_engine

    with one_thread():
        return _peak_mb(worker_engine(spec), observation)


# -- inspection -------------------------------------------------------------------------
#: the corrupted cases ``workbench inspect --measure`` scores the flags on: (name,
#: corruption, reasons scored). ``spikes``: the truth is every sample whose rotation the
#: outliers moved by more than :data:`SPIKE_TRUTH_DEG`. ``linear fills``: the gaps filled
#: by ``lerp`` and printed at 6 significant digits, as an exporter fills and prints them, and
#: read back without a mask; the truth is every filled sample (a one-frame fill is a
#: point on any curve, and a hold at a take's ends does not move: those are the misses).
#: ``jumps``: the truth is every frame the body root was moved, on the body root.
#: ``glitches``: the clean take itself, whose truth is its capture glitches
#: (:func:`workbench.data.quality.reference_glitches`), scored on every rule's flags.
INSPECTION_CASES = (
    ("spikes", "outliers:0.01", ("spike", "turn", "rejected", "disagree")),
    ("linear fills", "gaps:0.01", ("linear",)),
    ("jumps", "jumps:0.005", ("jump",)),
    ("glitches", "none", ("spike", "turn", "jump", "linear", "bone")),
)
SPIKE_TRUTH_DEG = 10.0  # every outlier turns its joint by at least 30 degrees
#: significant digits the linear fills are printed with
FILL_DIGITS = 6


@dataclass
class FlagCounts:
    """True and false positives and misses of flags against a truth, per sample (frame,
    joint) and per frame (any joint)."""

    samples: np.ndarray = field(default_factory=lambda: np.zeros(3, int))
    frames: np.ndarray = field(default_factory=lambda: np.zeros(3, int))

    def add(self, flags: np.ndarray, truth: np.ndarray) -> None:
        for counts, f, t in ((self.samples, flags, truth), (self.frames, flags.any(1), truth.any(1))):
            counts += [(f & t).sum(), (f & ~t).sum(), (~f & t).sum()]

    @staticmethod
    def recall_precision(counts: np.ndarray) -> tuple[float, float]:
        tp, fp, fn = (int(c) for c in counts)
        return (tp / (tp + fn) if tp + fn else math.nan), (tp / (tp + fp) if tp + fp else math.nan)


def _rotation_moved_deg(a: Motion, b: Motion) -> np.ndarray:
    """(F, J) degrees between each joint's local rotations in ``a`` and ``b``."""
    from .core.kinematics import local_rotations
    from .core.rotations import rotation_angle_deg

    joints = np.arange(a.skeleton.n_joints)
    return rotation_angle_deg(
        local_rotations(a.skeleton, a.angles_deg, joints), local_rotations(b.skeleton, b.angles_deg, joints)
    )


def _printed(motion: Motion, digits: int) -> Motion:
    """``motion`` written as BVH with ``digits`` significant digits and read back."""
    import tempfile
    from pathlib import Path

    from .io import read_bvh, write_bvh

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "take.bvh"
        write_bvh(path, motion, digits=digits)
        return read_bvh(path, unit_cm=motion.skeleton.unit_cm).replace(name=motion.name)


def measure_inspection(
    clips: Sequence[tuple[str, Motion]],
    seeds: Sequence[int] = (0,),
    engine_specs: Sequence[str] = (),
) -> dict[tuple[str, str], FlagCounts]:
    """How well :func:`workbench.data.inspection.inspect_motion` finds what is known to be
    broken: for each case of :data:`INSPECTION_CASES`, clip and seed, the counts of each
    reason's flags (and of all of them, reason ``any``) against the case's truth, keyed by
    (case, reason). The engines (``rejected`` from those reporting ``robust_weight``,
    ``disagree`` from two or more) clean the spikes case; an engine that refuses a clip
    is left out on it."""
    from .data.inspection import inspect_motion, turn_flags

    engines = {spec: registry.create(spec) for spec in engine_specs}
    counts: dict[tuple[str, str], FlagCounts] = {}
    for clip_id, motion in clips:
        for case, corruption, reasons in INSPECTION_CASES:
            for seed in seeds if corruption != "none" else seeds[:1]:
                weights, points = [], []
                if case == "spikes":
                    observation = parse_corruption(corruption).apply(motion, seed=seed)
                    taken, truth = observation.motion, _rotation_moved_deg(motion, observation.motion) > SPIKE_TRUTH_DEG
                    for engine in engines.values():
                        try:
                            result = engine.clean(observation)
                        except EngineError:
                            continue
                        points.append(result.motion.positions * motion.skeleton.unit_cm)
                        if "robust_weight" in result.diagnostics:
                            weights.append(result.diagnostics["robust_weight"])
                elif case == "linear fills":
                    observation = parse_corruption(corruption).apply(motion, seed=seed)
                    taken = _printed(registry.create("lerp").clean(observation).motion, FILL_DIGITS)
                    truth = ~observation.observed
                elif case == "jumps":
                    taken = parse_corruption(corruption).apply(motion, seed=seed).motion
                    b = motion.skeleton.body_root
                    truth = np.zeros((motion.n_frames, motion.skeleton.n_joints), bool)
                    truth[:, b] = (taken.positions[:, b] != motion.positions[:, b]).any(axis=1)
                else:  # the glitches, as the turn rule flags them
                    taken, truth = motion, turn_flags(motion)[0]
                found = inspect_motion(taken, robust_weights=weights, cleaned_points_cm=points)
                scored = [r for r in reasons if r in found.flags]
                for reason in scored:
                    counts.setdefault((case, reason), FlagCounts()).add(found.flags[reason], truth)
                every = np.logical_or.reduce([found.flags[r] for r in scored])
                counts.setdefault((case, "any"), FlagCounts()).add(every, truth)
    return counts


def inspection_markdown(counts: Mapping[tuple[str, str], FlagCounts]) -> str:
    """The counts of :func:`measure_inspection` as a table of recall and precision."""
    lines = [
        "| case | reason | recall (samples) | precision (samples) | recall (frames) | precision (frames) |",
        "|---|---|---|---|---|---|",
    ]
    for (case, reason), c in counts.items():
        cells = [*FlagCounts.recall_precision(c.samples), *FlagCounts.recall_precision(c.frames)]
        lines.append(f"| {case} | {reason} | " + " | ".join("–" if math.isnan(v) else f"{v:.3f}" for v in cells) + " |")
    return "\n".join(lines)


# -- the long take ----------------------------------------------------------------------
#: the take the long benchmark plays forwards and backwards to a studio take's length
LONG_CLIP = "cmu/walk/03_04"
LONG_MINUTES = 10.0


def long_take(motion: Motion, minutes: float = LONG_MINUTES) -> Motion:
    """``motion`` played forwards, then backwards, and so on, to ``minutes`` of motion
    (every turn continuous: the last frame of one pass is the first of the next)."""
    frames = int(round(minutes * 60 * motion.fps))
    there = motion.channels
    loop = np.concatenate([there, there[-2:0:-1]])  # forwards, then back without repeating the ends
    index = np.arange(frames) % len(loop)
    return motion.with_channels(loop[index]).replace(name=f"{motion.name}-{minutes:g}min")


@dataclass
class LongResult:
    """The long benchmark: ``io`` the BVH's size and reading and writing speeds; ``rows``
    one per engine (its clean alone, the whole ``workbench clean`` command, the command's
    peak memory)."""

    frames: int
    fps: float
    io: dict[str, float]
    rows: list[dict] = field(default_factory=list)
    #: one per engine that streams (:func:`stream_ms_per_frame`): ``engine`` and
    #: ``ms_per_frame``, or ``error``
    streams: list[dict] = field(default_factory=list)

    def markdown(self) -> str:
        io = self.io
        lines = [
            f"{self.frames:,} frames ({self.frames / self.fps / 60:.1f} min at {self.fps:g} fps), "
            f"{io['megabytes']:.0f} MB of BVH: read at {io['read_frames_per_s']:,.0f} frames/s, "
            f"written at {io['write_frames_per_s']:,.0f} frames/s",
            "",
            "| engine | clean alone (s) | frames/s | whole command (s) | peak memory (GB) |",
            "|---|---|---|---|---|",
        ]
        for r in self.rows:
            if "error" in r:
                lines.append(f"| {r['engine']} | failed: {r['error']} | | | |")
                continue
            lines.append(
                f"| {r['engine']} | {r['clean_s']:.1f} | {r['frames_per_s']:,.0f} | {r['command_s']:.1f} | "
                f"{r['peak_gb']:.2f} |"
            )
        if self.streams:
            lines += ["", f"| stream ({STREAM_FRAMES:,} frames) | ms per pushed frame |", "|---|---|"]
            for r in self.streams:
                lines.append(f"| {r['engine']} | {r['error'] if 'error' in r else format(r['ms_per_frame'], '.3f')} |")
        return "\n".join(lines)


#: how often ``bench --long`` writes and reads the long take, its speeds the best of them
IO_REPEATS = 3


def run_long_benchmark(motion: Motion, engine_specs: Sequence[str], corruption: str, seed: int = 0) -> LongResult:
    """Time reading and writing ``motion`` as BVH (the best of :data:`IO_REPEATS`),
    corrupt it (``workbench corrupt``'s files: the BVH and its mask), then clean it with
    each engine by a ``workbench clean`` process of its own: its clean alone (as it
    reports), the whole command, its peak resident memory; and push the corrupted take
    through each of those engines that streams, in this process
    (:func:`stream_ms_per_frame`). The files go into a temporary folder."""
    import os
    import re
    import subprocess
    import sys
    import tempfile
    from pathlib import Path

    from .io import read_bvh, write_bvh
    from .io.mask import sidecar_path, write_mask

    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        clean_path, noisy_path = root / "long.bvh", root / "long-noisy.bvh"
        write_s = read_s = np.inf
        for _ in range(IO_REPEATS):  # the best of a few: the first pays polars' import and first touches
            t0 = time.perf_counter()
            write_bvh(clean_path, motion)
            write_s = min(write_s, time.perf_counter() - t0)
            t0 = time.perf_counter()
            read_bvh(clean_path)
            read_s = min(read_s, time.perf_counter() - t0)
        io = {
            "megabytes": clean_path.stat().st_size / 2**20,
            "read_frames_per_s": motion.n_frames / read_s,
            "write_frames_per_s": motion.n_frames / write_s,
        }
        observation = parse_corruption(corruption).apply(motion, seed=seed)
        noisy = observation.bridged()
        write_bvh(noisy_path, noisy)
        write_mask(sidecar_path(noisy_path), observation.observed, motion.skeleton)
        result = LongResult(motion.n_frames, motion.fps, io)
        for spec in engine_specs:
            out = root / "long-cleaned.bvh"
            command = [sys.executable, "-m", "workbench", "clean", str(noisy_path), "-o", str(out), "--engine", spec]
            log, errors = root / "clean.out", root / "clean.err"  # files: a full pipe would block the command
            with log.open("w") as out_file, errors.open("w") as err_file:
                t0 = time.perf_counter()
                process = subprocess.Popen(command, stdout=out_file, stderr=err_file)
                _, status, usage = os.wait4(process.pid, 0)  # its own rusage: the peak memory of this command
                command_s = time.perf_counter() - t0
            stdout, stderr = log.read_text(), errors.read_text()
            found = re.search(r"in ([0-9.]+) s \(([0-9,]+) frames/s\)", stdout)
            if os.waitstatus_to_exitcode(status) != 0 or found is None:
                result.rows.append({"engine": spec, "error": (stderr.strip().splitlines() or ["?"])[-1]})
                continue
            result.rows.append(
                {
                    "engine": spec,
                    "clean_s": float(found.group(1)),
                    # clean's own, of the unrounded time (a short take prints 0.00 s)
                    "frames_per_s": float(found.group(2).replace(",", "")),
                    "command_s": command_s,
                    "peak_gb": usage.ru_maxrss / 2**20,  # kB on Linux
                }
            )
    for row in result.rows:  # the engines that cleaned it and stream: timed here, in this process
        spec = row["engine"]
        if "error" in row or not registry.create(spec, pretrained=False).streams:
            continue
        try:
            result.streams.append({"engine": spec, "ms_per_frame": stream_ms_per_frame(registry.create(spec), noisy)})
        except EngineError as err:  # a variant that cannot stream (it measures the whole take)
            result.streams.append({"engine": spec, "error": str(err)})
    return result


#: frames ``bench --long`` pushes through each streaming engine (10 s at 120 fps), after a
#: take of :data:`STREAM_WARMUP` frames that pays the first calls' costs
STREAM_FRAMES, STREAM_WARMUP = 1200, 50


def stream_ms_per_frame(engine: Engine, motion: Motion) -> float:
    """Milliseconds per pushed frame of ``engine``'s stream (``engine.stream``) over the
    first :data:`STREAM_FRAMES` frames of ``motion`` (complete frames), its flush
    included, after a warm-up take of the first :data:`STREAM_WARMUP`."""
    frames = motion.channels[:STREAM_FRAMES]
    stream = engine.stream(motion.skeleton, motion.fps)
    for frame in frames[:STREAM_WARMUP]:
        stream.push(frame)
    stream.flush()
    t0 = time.perf_counter()
    for frame in frames:
        stream.push(frame)
    stream.flush()
    return (time.perf_counter() - t0) / len(frames) * 1e3
