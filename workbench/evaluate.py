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
    largest)."""

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

    def to_json(self) -> dict:
        return {
            "corruption": self.corruption,
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
) -> BenchResult:
    """Corrupt each clip with each seed, clean it with each engine, score it. Engines are
    spec strings or ready engine objects (keyed by their ``spec``); ``datasets``: each
    clip's dataset, for summaries per dataset. A clip the corruption cannot be applied to
    (too short for a block) is skipped, and a clip an engine refuses (EngineError) is
    left out of that engine's rows; both are recorded with the reason. Raises
    CorruptionApplyError when the corruption fits no clip."""
    engines = {
        (e if isinstance(e, str) else e.spec): (registry.create(e) if isinstance(e, str) else e) for e in engine_specs
    }
    result = BenchResult(
        corruption=str(parse_corruption(corruption)),
        seeds=list(seeds),
        clips=[],
        glitches={clip_id: found for clip_id, motion in clips if (found := reference_glitches(motion))},
        dataset_of=dict(datasets or {}),
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
    for spec, engine in engines.items():
        warm = False
        refused: dict[str, str] = {}
        for clip_id, case in cases:
            if clip_id in refused:
                continue
            if progress:
                progress(f"{spec} on {clip_id} seed {case.seed}")
            try:
                if not warm:  # warm-up (lazy imports, caches) outside the timed calls
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
            result.rows.append(row)
        if refused:
            result.refused[spec] = refused
        summary = summarise_rows([r for r in result.rows if r["engine"] == spec])
        # memory in a clean of its own per dataset, so that its page faults stay out of the timings
        for name, ids in result.datasets().items():
            mine = set(ids) - set(refused)
            accepted = [case for clip_id, case in cases if clip_id in mine]
            if accepted:
                longest = max(accepted, key=lambda c: c.truth.n_frames).observation
                before = reset_peak_resident()
                engine.clean(longest)
                peak = resident_mb("VmHWM") - before
                if not math.isnan(peak):
                    result.peaks.setdefault(spec, {})[name] = max(peak, 0.0)
        if result.peaks.get(spec):
            summary["peak_mb"] = max(result.peaks[spec].values())
        result.summary[spec] = summary
    return result
