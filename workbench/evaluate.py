"""Benchmarks: engines x clips x seeds -> a tidy table of errors and speed (no GUI).

Every engine sees the same corrupted observations (same corruption spec and seeds).
``frames_per_s`` is cleaning throughput: frames cleaned divided by the wall time spent
inside ``engine.clean`` (single process, this machine). ``peak_mb`` is the most resident
memory the engine's clean of the longest case added to the process, in MB, measured in a
clean of its own after the timed ones: its working memory, beyond its loaded weights
(Linux; absent elsewhere). Other summary values are means over all (clip, seed) rows of
an engine. ``glitches`` names the capture glitches of the clean clips scored against
(:mod:`workbench.data.quality`), which stay in the scores.
"""

from __future__ import annotations

import ctypes
import dataclasses
import math
import time
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from . import metrics, registry
from .core.motion import Case, Motion, Observation
from .engine import Engine
from .corruption import make_case
from .data.quality import Glitch, reference_glitches
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
    """Per-row results and per-engine summaries, keyed by each spec exactly as given."""

    corruption: str
    seeds: list[int]
    clips: list[str]
    rows: list[dict] = field(default_factory=list)
    summary: dict[str, dict[str, float]] = field(default_factory=dict)
    #: the capture glitches of each clip's clean motion, for the clips that have any
    glitches: dict[str, list[Glitch]] = field(default_factory=dict)

    def to_json(self) -> dict:
        return {"corruption": self.corruption, "seeds": self.seeds, "clips": self.clips,
                "rows": self.rows, "summary": self.summary,
                "reference_glitches": {clip: [dataclasses.asdict(g) for g in found]
                                       for clip, found in self.glitches.items()}}

    def markdown(self) -> str:
        cols = [m for m in (*METRICS, *COST_COLUMNS) if any(m in s for s in self.summary.values())]
        head = "| engine | " + " | ".join(cols) + " |"
        lines = [head, "|" + "---|" * (len(cols) + 1)]
        for spec, s in self.summary.items():
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
        return {clip: {spec: float(np.mean(values[clip, spec])) if (clip, spec) in values else math.nan
                       for spec in self.summary} for clip in self.clips}

    def per_clip_markdown(self, metric: str) -> str:
        """A table of ``metric`` with a row per clip (its frame count, then every engine's
        mean over the seeds) and a last row with the summary's mean over all rows."""
        frames = {r["clip"]: r["frames"] for r in self.rows}
        specs = list(self.summary)
        lines = [f"| clip ({metric}) | frames | " + " | ".join(specs) + " |", "|" + "---|" * (len(specs) + 2)]
        cells = lambda values: " | ".join(format_value(metric, v) for v in values)
        for clip, by_engine in self.per_clip(metric).items():
            lines.append(f"| {clip} | {frames.get(clip, 0)} | {cells(by_engine[s] for s in specs)} |")
        lines.append(f"| **mean** | | {cells(self.summary[s].get(metric, math.nan) for s in specs)} |")
        return "\n".join(lines)


def run_benchmark(
    engine_specs: Sequence[str | Engine],
    corruption: str,
    clips: Sequence[tuple[str, Motion]],
    seeds: Sequence[int] = (0,),
    progress: Callable[[str], None] | None = None,
) -> BenchResult:
    """Corrupt each clip with each seed, clean it with each engine, score it. Engines are
    spec strings or ready engine objects (keyed by their ``spec``)."""
    engines = {(e if isinstance(e, str) else e.spec): (registry.create(e) if isinstance(e, str) else e)
               for e in engine_specs}
    cases: list[tuple[str, Case]] = [
        (clip_id, make_case(motion, corruption, seed)) for clip_id, motion in clips for seed in seeds
    ]
    result = BenchResult(corruption=str(cases[0][1].corruption) if cases else corruption,
                         seeds=list(seeds), clips=[c for c, _ in clips],
                         glitches={clip_id: found for clip_id, motion in clips if (found := reference_glitches(motion))})
    for spec, engine in engines.items():
        if cases:  # warm-up (lazy imports, caches) outside the timed calls
            obs = cases[0][1].observation
            n = min(obs.n_frames, 256)
            engine.clean(Observation(obs.motion.slice(0, n), obs.observed[:n]))
        frames = 0
        seconds = 0.0
        for clip_id, case in cases:
            if progress:
                progress(f"{spec} on {clip_id} seed {case.seed}")
            t0 = time.perf_counter()
            cleaned = engine.clean(case.observation)
            dt = time.perf_counter() - t0
            frames += case.truth.n_frames
            seconds += dt
            row = {"engine": spec, "clip": clip_id, "seed": case.seed, "frames": case.truth.n_frames,
                   "seconds": dt}
            row.update(metrics.score(case.truth, cleaned.motion, case.observation.observed))
            result.rows.append(row)
        rows = [r for r in result.rows if r["engine"] == spec]
        summary = {}
        for m in METRICS:
            vals = [r[m] for r in rows if m in r and not math.isnan(r[m])]
            if vals:
                summary[m] = float(np.mean(vals))
        summary["frames_per_s"] = frames / seconds if seconds > 0 else float("inf")
        if cases:  # memory in a clean of its own, so that its page faults stay out of the timings
            longest = max(cases, key=lambda c: c[1].truth.n_frames)[1].observation
            before = reset_peak_resident()
            engine.clean(longest)
            peak = resident_mb("VmHWM") - before
            if not math.isnan(peak):
                summary["peak_mb"] = max(peak, 0.0)
        result.summary[spec] = summary
    return result
