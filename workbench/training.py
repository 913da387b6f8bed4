"""Training an engine: the one entry point, and the one writer of weights manifests.

:func:`train_engine` fits an engine on clean clips (seeded, as its ``fit`` is), times
it, measures the resident memory it adds, scores the result on test clips when given
(``angular:0.5`` for a denoiser, ``gaps:0.01`` for a filler; one seed: a record of what
the weights do, not a choice made with them) and saves the weights with their manifest:
the clips actually used, their data sets and terms (weights trained on a data set
inherit its licence), the minutes, the peak memory and the test scores.

Units: minutes of wall time; memory in MB (Linux; absent elsewhere).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping, Sequence

from .core.motion import Motion
from .data import dataset_terms
from .engine import Engine
from .evaluate import reset_peak_resident, resident_mb, run_benchmark


@dataclass(frozen=True)
class TrainingRun:
    """What :func:`train_engine` did: the manifest written, the minutes fitting took, the
    most memory it added (MB, NaN where not measured) and the test scores (empty
    without test clips)."""

    manifest: Path
    minutes: float
    peak_mb: float
    test_scores: dict = field(default_factory=dict)


def scoring_corruption(engine: Engine) -> str:
    """The corruption a trained engine's test scores are measured on: ``angular:0.5``
    for a denoiser, ``gaps:0.01`` for a gap filler."""
    return "angular:0.5" if "denoise" in engine.info.tasks else "gaps:0.01"


def train_engine(
    engine: Engine,
    clips: Sequence[tuple[str, Motion]],
    out: str | Path,
    *,
    test: Sequence[tuple[str, Motion]] = (),
    datasets: Mapping[str, str] | None = None,
) -> TrainingRun:
    """Fit ``engine`` on ``clips`` ((id, clean motion), of one skeleton layout unless the
    engine is :attr:`~workbench.engine.Engine.skeleton_agnostic`), score it on
    ``test`` and save its weights and manifest in ``out``. ``datasets``: each clip's data
    set (default: the first part of its id, ``cmu`` of ``cmu/walk/02_01``). Raises
    EngineError for motions the engine cannot train on (checked before fitting)."""
    motions = engine.training_motions([m for _, m in clips])
    resident = reset_peak_resident()
    t0 = time.perf_counter()
    engine.fit(motions)
    minutes = (time.perf_counter() - t0) / 60
    peak_mb = resident_mb("VmHWM") - resident
    scores = {}
    if test:
        corruption = scoring_corruption(engine)
        summary = run_benchmark([engine], corruption, test, seeds=[0]).summary[engine.spec]
        scores = {"corruption": corruption, "split": "test", "seeds": [0], **summary}
    names = sorted({(datasets or {}).get(clip, clip.split("/")[0]) for clip, _ in clips})
    record = {
        "clips": [clip for clip, _ in clips],
        "split": "train",
        "minutes": round(minutes, 2),
        "datasets": [{"name": name, "terms": dataset_terms(name)} for name in names],
    }
    if not math.isnan(peak_mb):
        record["peak_mb"] = round(peak_mb)
    manifest = engine.save(out, {"training": record, "test_scores": scores})
    return TrainingRun(manifest, minutes, peak_mb, scores)
