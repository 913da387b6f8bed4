"""The engine conformance suite, for the built-in engines and any third-party one.

Each check in :data:`CHECKS` is ``check(engine, name=..., motion=..., foreign=...,
make_untrained=..., training=...)``: ``engine`` is ready (a trained one fitted or
loaded); ``motion`` a short clean take of its skeleton; ``foreign`` takes of other
skeleton layouts (a skeleton-agnostic engine must clean each, a trained one refuse
each it has no committed weights for, and clean the others); ``make_untrained()`` a
fresh engine with the quick training options of
:attr:`workbench.engine.Engine.QUICK_FIT`, and ``training`` the short clean takes it is
fitted on. A check raises AssertionError naming the engine and the broken rule, or
:class:`CheckSkipped` with the reason it does not apply (never a silent pass).

- :func:`check_engine` runs the checks and returns the skipped ones with their reasons.
- :func:`parametrize_with_engine_checks` and :func:`run_check` make them pytest cases,
  one per engine and check, a skip reported as one.
"""

from __future__ import annotations

import dataclasses
import tempfile
from typing import Callable, Sequence

import numpy as np

from .. import registry
from ..core.motion import Motion, Observation, angle_columns, angle_slice, length_columns
from ..engine import Engine, EngineError, EngineInfo, NotFittedError


class CheckSkipped(Exception):
    """A check that does not apply to this engine; the message says why."""


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
            observed[F // 3 : F // 3 + 20, j] = False
        observed[rng.random(observed.shape) < 0.02] = False
        observed[:, 0] = True
    return Observation(motion.with_channels(X), observed)


def _same_frame(a: Motion, b: Motion) -> bool:
    return a.skeleton.allclose(b.skeleton) and a.fps == b.fps and a.n_frames == b.n_frames


def check_info(engine, name: str, **_) -> None:
    assert isinstance(engine, Engine), f"{name}: an engine must be a workbench.engine.Engine"
    assert isinstance(engine.info, EngineInfo), f"{name}: info must be an EngineInfo"
    assert engine.info.tasks, f"{name}: info.tasks is empty"


def check_shapes_and_finite(engine, name: str, motion: Motion, **_) -> None:
    for obs in (_noisy(motion), _noisy(motion, gaps=True)):
        res = engine.clean(obs)  # a finite CleanResult of its frames, rate and layout, or its clean raised
        assert _same_frame(res.motion, motion), f"{name}: skeleton, fps or frame count changed"  # bones too
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
        raise CheckSkipped(f"{name} does not say it keeps observed samples (info.keeps_observed)")
    obs = _noisy(motion, gaps=True)
    out = engine.clean(obs).motion.channels
    mask, lengths, angles = obs.channel_observed, length_columns(motion.skeleton), angle_slice(motion.skeleton)
    assert np.allclose((out - obs.motion.channels)[:, lengths][mask[:, lengths]], 0, atol=1e-6), (
        f"{name}: says keeps_observed but moved observed root positions or translations"
    )
    ang = ((out - obs.motion.channels)[:, angles] + 180.0) % 360.0 - 180.0
    assert np.allclose(ang[mask[:, angles]], 0, atol=1e-6), f"{name}: says keeps_observed but changed observed angles"


def check_result_is_not_a_view(engine, name: str, motion: Motion, **_) -> None:
    obs = _noisy(motion, gaps=True)
    out = engine.clean(obs).motion
    for field in ("root_positions", "angles_deg", "translations"):
        assert not np.shares_memory(getattr(out, field), getattr(obs.motion, field)), (
            f"{name}: the cleaned {field} share memory with the input's"
        )


def _has_committed_weights_for(engine, skeleton) -> bool:
    """The engine runs on committed weights and has some for ``skeleton``'s body view: its
    own, or those of its universal variant (:meth:`~workbench.engine.Engine.universal_twin`)."""
    from workbench.engine.view import body_skeleton

    try:
        body = body_skeleton(skeleton)
        return engine.committed_for(body) is not None or engine.universal_twin(body) is not None
    except EngineError:  # a skeleton no trained engine models
        return False


def check_foreign_skeleton(
    engine, name: str, motion: Motion, foreign: Motion | Sequence[Motion] | None = None, **_
) -> None:
    others = [foreign] if isinstance(foreign, Motion) else list(foreign or ())
    if not others:
        raise CheckSkipped("no take of another skeleton layout was given")
    for other in others:
        if engine.info.trainable and _has_committed_weights_for(engine, other.skeleton):
            check_shapes_and_finite(engine, name, other)  # the weights for its skeleton, picked
            continue
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
            if engine.info.keeps_observed:
                check_keeps_observed(engine, name, other)
        except AssertionError as err:
            raise AssertionError(f"{err} (on another skeleton: {layout})") from None


def check_parameters_are_frozen(engine, name: str, **_) -> None:
    params = engine.params
    assert dataclasses.is_dataclass(params) and type(params).__dataclass_params__.frozen, (
        f"{name}: Params must be a frozen dataclass"
    )
    for f in dataclasses.fields(params):
        try:
            setattr(params, f.name, getattr(params, f.name))
        except dataclasses.FrozenInstanceError:
            continue
        raise AssertionError(f"{name}: parameter {f.name!r} can be changed in place")


def check_spec_round_trip(engine, name: str, **_) -> None:
    again = registry.create(engine.spec, pretrained=False)
    assert again.spec == engine.spec, f"{name}: spec {engine.spec!r} does not round-trip ({again.spec!r})"


def check_unfitted(engine, name: str, motion: Motion, make_untrained: Callable[[], Engine] | None = None, **_) -> None:
    if not engine.info.trainable:
        raise CheckSkipped(f"{name} is not trainable: it has nothing to fit")
    fresh = make_untrained() if make_untrained else registry.create(engine.spec, pretrained=False)
    try:
        fresh.clean(_noisy(motion))
    except NotFittedError:
        return
    raise AssertionError(f"{name}: an unfitted trainable engine must raise NotFittedError")


def check_fit_returns_self_and_repeats(
    engine, name: str, make_untrained: Callable[[], Engine] | None = None, training: Sequence[Motion] | None = None, **_
) -> None:
    """``fit`` returns the engine itself, two seeded fits give the same state, and that
    state saved and loaded again is the same (so a ``state_arrays`` that gives no plain
    arrays of numbers fails here, not at the end of a training)."""
    if not training:
        raise CheckSkipped("no training takes were given")
    if make_untrained is None:
        raise CheckSkipped("no way to make an untrained engine was given (make_untrained)")
    first = make_untrained()
    assert first.fit(list(training)) is first, f"{name}: fit must return the engine itself"
    if not engine.info.trainable:
        return
    a, b = first.state_arrays(), make_untrained().fit(list(training)).state_arrays()
    assert a.keys() == b.keys(), f"{name}: two fits saved different state"
    changed = [k for k in a if not np.array_equal(a[k], b[k])]
    assert not changed, f"{name}: two seeded fits on the same takes differ in {', '.join(changed[:5])}"
    with tempfile.TemporaryDirectory() as folder:  # what it saves, it loads (state_arrays: arrays of numbers)
        first.save(folder)
        loaded = make_untrained().load(folder).state_arrays()
    lost = [k for k in a if k not in loaded or not np.array_equal(np.asarray(a[k]), np.asarray(loaded[k]))]
    assert not lost, f"{name}: saved and loaded again, its state differs in {', '.join(lost[:5])}"


CHECKS: dict[str, Callable] = {
    "info": check_info,
    "shapes_and_finite": check_shapes_and_finite,
    "input_untouched": check_input_untouched,
    "deterministic": check_deterministic,
    "keeps_observed": check_keeps_observed,
    "not_a_view": check_result_is_not_a_view,
    "foreign_skeleton": check_foreign_skeleton,
    "frozen_params": check_parameters_are_frozen,
    "spec_round_trip": check_spec_round_trip,
    "unfitted": check_unfitted,
    "fit": check_fit_returns_self_and_repeats,
}


def check_engine(
    make_engine: Callable[[], Engine],
    motion: Motion,
    foreign: Motion | Sequence[Motion] | None = None,
    checks: list[str] | None = None,
    make_untrained: Callable[[], Engine] | None = None,
    training: Sequence[Motion] | None = None,
) -> dict[str, str]:
    """Run the conformance checks (all, or the named ones) on one engine; returns the
    checks that did not apply, with the reason. Raises AssertionError on the first
    broken rule."""
    engine = make_engine()
    name = engine.info.name
    skipped = {}
    for key in checks or list(CHECKS):
        try:
            CHECKS[key](
                engine, name=name, motion=motion, foreign=foreign, make_untrained=make_untrained, training=training
            )
        except CheckSkipped as why:
            skipped[key] = str(why)
    return skipped


def quick_untrained(name: str) -> Callable[[], Engine]:
    """A factory of fresh, untrained engines ``name`` with its quick training options
    (:attr:`workbench.engine.Engine.QUICK_FIT`), for :func:`check_fit_returns_self_and_repeats`."""
    options = ",".join(f"{k}={v}" for k, v in registry.get(name).QUICK_FIT.items())
    return lambda: registry.create(f"{name}:{options}" if options else name, pretrained=False)


def parametrize_with_engine_checks(names: Sequence[str]):
    """A ``pytest.mark.parametrize`` over every (engine name, check name) pair, as the
    arguments ``engine`` and ``check``; run each with :func:`run_check`."""
    import pytest

    return pytest.mark.parametrize("engine, check", [pytest.param(n, c, id=f"{n}-{c}") for n in names for c in CHECKS])


def run_check(check: str, make_engine: Callable[[], Engine], motion: Motion, **context) -> None:
    """Run one check inside a pytest test: a broken rule fails it, a check that does not
    apply skips it with the reason (``context``: foreign, make_untrained, training)."""
    import pytest

    skipped = check_engine(make_engine, motion, checks=[check], **context)
    if skipped:
        pytest.skip(skipped[check])


def conformance_clips(root=None, frames: int = 150, dataset: str | None = None) -> tuple[Motion, list[Motion]]:
    """Short clean takes of the data root: the primary, the first training clip of
    ``dataset`` (default: of the first dataset whose skeleton trained engines can model,
    without translated joints; ``"cmu"`` with the team's data), and a take of each other
    dataset whose skeleton has another layout (with the team's data, a cmu-daz take and
    a Bandai take, whose Hips is translated)."""
    from functools import cache

    from ..data import catalogue

    load = cache(lambda clip: clip.load())  # each take read once
    clips = sorted(catalogue(root), key=lambda c: c.split != "train")
    names = list(dict.fromkeys(c.dataset for c in clips))
    if dataset is None:  # the first dataset whose first clip has no translated joints
        dataset = next(
            (n for n in names if not load(next(c for c in clips if c.dataset == n)).skeleton.translated),
            clips[0].dataset,
        )
    clips.sort(key=lambda c: c.dataset != dataset)  # stable: the training clips first within each
    primary = load(clips[0]).slice(0, frames)
    layouts, foreign = {primary.skeleton.signature()}, []
    for name in names:  # a take long enough of each dataset
        m = next((m for c in clips if c.dataset == name and (m := load(c)).n_frames >= frames), None)
        if m is not None and m.skeleton.signature() not in layouts:
            layouts.add(m.skeleton.signature())
            foreign.append(m.slice(0, frames))
    return primary, foreign
