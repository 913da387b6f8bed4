"""The engine conformance suite.

``check_engine(make_engine, clean_motion, foreign_motion)`` runs every check in
:data:`CHECKS` and raises AssertionError naming the engine and the broken rule.
``make_engine()`` must return a ready engine (trained engines already fitted or
loaded); ``clean_motion`` is a short clean take of the engine's skeleton and
``foreign_motion`` a take of another skeleton layout, or a list of such takes (one per
layout: a skeleton-agnostic engine must clean each, a trained one refuse each).
"""

from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

from .. import registry
from ..core.motion import Motion, Observation, angle_columns, angle_slice, length_columns
from ..engine import CleanResult, EngineError, EngineInfo, NotFittedError


def _noisy(motion: Motion, seed: int = 7, gaps: bool = False) -> Observation:
    """A noisy observation (0.5 x channel std Gaussian noise on every joint-angle channel),
    optionally with a 20-frame gap in three joints and a few scattered missing samples."""
    rng = np.random.default_rng(seed)
    X = motion.channels
    cols = angle_columns(motion.skeleton)
    std = X[:, cols].std(axis=0)
    X[:, cols] += rng.normal(size=(X.shape[0], cols.size)) * 0.5 * std
    observed = np.ones((motion.n_frames, motion.skeleton.n_joints), bool)
    if gaps:
        F = motion.n_frames
        for j in (2, motion.skeleton.n_joints // 2, motion.skeleton.n_joints - 1):
            observed[F // 3:F // 3 + 20, j] = False
        observed[rng.random(observed.shape) < 0.02] = False
        observed[:, 0] = True
    return Observation(motion.with_channels(X), observed)


def _same_frame(a: Motion, b: Motion) -> bool:
    return (a.skeleton.allclose(b.skeleton) and a.fps == b.fps and a.n_frames == b.n_frames)


def check_info(engine, name: str, **_) -> None:
    assert isinstance(engine.info, EngineInfo), f"{name}: info must be an EngineInfo"
    assert engine.info.tasks, f"{name}: info.tasks is empty"


def check_shapes_and_finite(engine, name: str, motion: Motion, **_) -> None:
    for obs in (_noisy(motion), _noisy(motion, gaps=True)):
        res = engine.clean(obs)
        assert isinstance(res, CleanResult), f"{name}: clean must return a CleanResult"
        assert _same_frame(res.motion, motion), f"{name}: skeleton, fps or frame count changed"
        assert np.isfinite(res.motion.channels).all(), f"{name}: output has NaN or inf (gaps={obs.has_gaps})"
        for key, arr in res.diagnostics.items():
            assert np.shape(arr)[0] == motion.n_frames, f"{name}: diagnostic {key!r} must have frames first"


def check_input_untouched(engine, name: str, motion: Motion, **_) -> None:
    obs = _noisy(motion, gaps=True)
    before = obs.motion.channels.copy(), obs.observed.copy()
    engine.clean(obs)
    assert np.array_equal(obs.motion.channels, before[0], equal_nan=True), f"{name}: clean changed its input"
    assert np.array_equal(obs.observed, before[1]), f"{name}: clean changed the observed mask"


def check_deterministic(engine, name: str, motion: Motion, **_) -> None:
    obs = _noisy(motion, gaps=True)
    a, b = engine.clean(obs).motion.channels, engine.clean(obs).motion.channels
    assert np.array_equal(a, b), f"{name}: two cleans of the same input differ"


def check_keeps_observed(engine, name: str, motion: Motion, **_) -> None:
    if not engine.info.keeps_observed:
        return
    obs = _noisy(motion, gaps=True)
    out = engine.clean(obs).motion.channels
    mask, lengths, angles = obs.channel_observed, length_columns(motion.skeleton), angle_slice(motion.skeleton)
    assert np.allclose((out - obs.motion.channels)[:, lengths][mask[:, lengths]], 0, atol=1e-6), \
        f"{name}: says keeps_observed but moved observed root positions or translations"
    ang = ((out - obs.motion.channels)[:, angles] + 180.0) % 360.0 - 180.0
    assert np.allclose(ang[mask[:, angles]], 0, atol=1e-6), f"{name}: says keeps_observed but changed observed angles"


def check_foreign_skeleton(engine, name: str, motion: Motion,
                           foreign: Motion | Sequence[Motion] | None = None, **_) -> None:
    for other in [foreign] if isinstance(foreign, Motion) else foreign or ():
        if engine.info.trainable:
            try:
                engine.clean(_noisy(other))
            except EngineError as err:
                assert "skeleton" in str(err), f"{name}: the foreign-skeleton error should say so: {err}"
                continue
            raise AssertionError(f"{name}: a trained engine must refuse a skeleton it was not trained for")
        layout = f"{other.skeleton.n_joints} joints rooted at {other.skeleton.names[0]!r}"
        try:
            check_shapes_and_finite(engine, name, other)
            check_keeps_observed(engine, name, other)
        except AssertionError as err:
            raise AssertionError(f"{err} (on another skeleton: {layout})") from None


def check_spec_round_trip(engine, name: str, **_) -> None:
    again = registry.create(engine.spec, pretrained=False)
    assert again.spec == engine.spec, f"{name}: spec {engine.spec!r} does not round-trip ({again.spec!r})"


def check_unfitted(engine, name: str, motion: Motion, **_) -> None:
    if not engine.info.trainable:
        return
    fresh = registry.create(engine.spec, pretrained=False)
    try:
        fresh.clean(_noisy(motion))
    except NotFittedError:
        return
    raise AssertionError(f"{name}: an unfitted trainable engine must raise NotFittedError")


CHECKS: dict[str, Callable] = {
    "info": check_info,
    "shapes_and_finite": check_shapes_and_finite,
    "input_untouched": check_input_untouched,
    "deterministic": check_deterministic,
    "keeps_observed": check_keeps_observed,
    "foreign_skeleton": check_foreign_skeleton,
    "spec_round_trip": check_spec_round_trip,
    "unfitted": check_unfitted,
}


def check_engine(make_engine: Callable, motion: Motion, foreign: Motion | Sequence[Motion] | None = None,
                 checks: list[str] | None = None) -> None:
    """Run the conformance checks (all, or the named ones) on one engine."""
    engine = make_engine()
    name = engine.info.name
    for key in checks or list(CHECKS):
        CHECKS[key](engine, name=name, motion=motion, foreign=foreign)


def conformance_clips(root=None, frames: int = 150, dataset: str | None = None) -> tuple[Motion, list[Motion]]:
    """Short clean takes of the data root: the primary, the first training clip of
    ``dataset`` (default: of the first dataset whose skeleton trained engines can model,
    without translated joints; ``"cmu"`` with the team's data), and a take of each other
    dataset whose skeleton has another layout (with the team's data, a cmu-daz take and
    a Bandai take, whose Hips is translated)."""
    from ..data import catalogue

    clips = sorted(catalogue(root), key=lambda c: c.split != "train")
    if dataset is None:  # the first dataset whose first clip has no translated joints
        dataset = next((name for name in dict.fromkeys(c.dataset for c in clips)
                        if not next(c for c in clips if c.dataset == name).load().skeleton.translated),
                       clips[0].dataset)
    clips.sort(key=lambda c: c.dataset != dataset)  # stable: the training clips first within each
    primary = clips[0].load().slice(0, frames)
    layouts, foreign = {primary.skeleton.signature()}, []
    for name in dict.fromkeys(c.dataset for c in clips):  # a take long enough of each dataset
        m = next((m for c in clips if c.dataset == name and (m := c.load()).n_frames >= frames), None)
        if m is not None and m.skeleton.signature() not in layouts:
            layouts.add(m.skeleton.signature())
            foreign.append(m.slice(0, frames))
    return primary, foreign
