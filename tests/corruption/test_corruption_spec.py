"""Spec text, determinism, stream independence, errors and the import boundary."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from workbench.core.motion import Case, Observation
from workbench.corruption import (
    MODELS,
    Corruption,
    CorruptionApplyError,
    CorruptionSpecError,
    make_case,
    models_help,
    parse_corruption,
    random_stream,
)
from workbench.corruption.base import FRAME_KINDS, Seconds, Work

EXAMPLES = {
    "angular:0.5": "angular:0.5",
    "uniform:1": "uniform:1",
    "bias:0.25": "bias:0.25",
    "sine:0.3": "sine:0.3",
    "spatial:0.5": "spatial:0.5",
    "spatial-ends:0.5,0.1": "spatial-ends:0.5,0.1",
    "outliers:0.05": "outliers:0.05",
    "jumps:0.005": "jumps:0.005",
    "gaps:0.1": "gaps:0.1",
    "gaps:0.1,12,600": "gaps:0.1",
    "gaps:0.1,12.0": "gaps:0.1",
    "gaps:0.1,20": "gaps:0.1,20",
    "gaps:0.1,12,30": "gaps:0.1,12,30",
    "block:60": "block:60",
    "block:60,100": "block:60,100",
    "joints:3": "joints:3",
    "drop:0.1": "drop:0.1",
    "": "none",
    "none": "none",
    " NONE ": "none",
    "Angular:5e-1": "angular:0.5",
    " angular : 0.50 + gaps : 0.010 ": "angular:0.5+gaps:0.01",
    "angular:0.5+gaps:0.01": "angular:0.5+gaps:0.01",
    "spatial:1e-05+drop:0.2+block:30,5": "spatial:1e-05+drop:0.2+block:30,5",
    "angular:0.5+angular:0.5": "angular:0.5+angular:0.5",
}

ALL_SPECS = [
    "angular:0.5",
    "uniform:0.5",
    "bias:0.5",
    "sine:0.5",
    "spatial:0.5",
    "spatial-ends:0.5,0.1",
    "outliers:0.05",
    "jumps:0.01",
    "gaps:0.05",
    "block:30",
    "joints:3",
    "drop:0.1",
]


@pytest.mark.parametrize("text, canonical", EXAMPLES.items())
def test_parse_str_round_trip(text, canonical):
    spec = parse_corruption(text)
    assert isinstance(spec, Corruption)
    assert str(spec) == canonical
    again = parse_corruption(str(spec))
    assert again == spec and str(again) == canonical


def test_every_model_has_an_example_and_help():
    names = {part.split(":")[0] for text in EXAMPLES for part in text.replace(" ", "").lower().split("+") if part}
    assert set(MODELS) <= names
    help_text = models_help()
    for name, cls in MODELS.items():
        assert cls.name == name
        assert cls.description and "\n" not in cls.description
        assert cls.params and all(p.name for p in cls.params)
        assert cls.signature() in help_text


def test_empty_spec_is_identity(walk):
    for text in ("", "none"):
        obs = parse_corruption(text).apply(walk, seed=3)
        assert obs.observed.all()
        assert np.array_equal(obs.motion.channels, walk.channels)
    assert not parse_corruption("none") and parse_corruption("drop:0.1")


def test_composition_operator():
    a, b = parse_corruption("angular:0.5"), parse_corruption("gaps:0.01")
    assert str(a + b) == "angular:0.5+gaps:0.01"
    assert str(a + "drop:0.1") == "angular:0.5+drop:0.1"


# -- property test over generated specs --------------------------------------------------

_VALUES = {
    "scale": st.floats(0, 100, allow_nan=False) | st.integers(0, 100),
    "cm": st.floats(0, 100, allow_nan=False) | st.integers(0, 100),
    "prob": st.floats(0, 1) | st.sampled_from([0, 1]),
    "mean-frames": st.floats(1, 1e4) | st.integers(1, 10_000),
    "count": st.integers(0, 10**6),
    "frames": st.integers(1, 10**6),
    "frame-count": st.integers(0, 10**6),
    "frame": st.integers(0, 10**6),
}
_SECONDS = st.floats(1e-3, 1e3) | st.integers(1, 1000)


def _draw_value(draw, kind):
    """A parameter value, or for one counted in frames sometimes a Seconds."""
    if kind in FRAME_KINDS and draw(st.booleans()):
        return Seconds(float(draw(_SECONDS)))
    return draw(_VALUES[kind])


def _text(draw, value) -> str:
    if isinstance(value, Seconds):
        return draw(st.sampled_from([repr, str]))(value.value) + draw(st.sampled_from(["s", "S"]))
    return draw(st.sampled_from([repr, str]))(float(value) if draw(st.booleans()) else value)


@st.composite
def model_texts(draw):
    cls = MODELS[draw(st.sampled_from(sorted(MODELS)))]
    n_req = sum(p.required for p in cls.params)
    n = draw(st.integers(n_req, len(cls.params)))
    values = [_draw_value(draw, p.kind) for p in cls.params[:n]]
    texts = [_text(draw, v) for v in values]
    name = draw(st.sampled_from([cls.name, cls.name.upper()]))
    return f"{name}:{','.join(texts)}", cls, values


@settings(max_examples=300, deadline=None)
@given(st.lists(model_texts(), min_size=1, max_size=4))
def test_generated_specs_round_trip(parts):
    text = "+".join(t for t, _, _ in parts)
    spec = parse_corruption(text)
    assert [type(m) for m in spec.models] == [cls for _, cls, _ in parts]
    for model, (_, cls, values) in zip(spec.models, parts):
        full = values + [p.default for p in cls.params[len(values) :]]
        assert list(model.values()) == [v if v is None or isinstance(v, Seconds) else float(v) for v in full]
    canonical = str(spec)
    assert parse_corruption(canonical) == spec
    assert str(parse_corruption(canonical)) == canonical
    assert "+".join(str(m) for m in spec.models) == canonical


# -- errors ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "text, words",
    [
        ("angualr:0.5", ["unknown", "angualr", "angular:K", "gaps:P[,MEAN[,MAX]]", "drop:P"]),
        ("angular", ["angular", "1 parameter", "got 0"]),
        ("angular:0.5,1", ["angular", "got 2"]),
        ("spatial-ends:0.5", ["spatial-ends", "2 parameters", "got 1"]),
        ("gaps:0.1,1,2,3", ["gaps", "1 to 3", "got 4"]),
        ("angular:abc", ["angular", "K", "'abc'"]),
        ("angular:-1", ["angular", "K", "from 0 to 1,000", "-1"]),
        ("spatial:-0.5", ["spatial", "S", "-0.5"]),
        ("angular:nan", ["angular", "nan"]),
        ("spatial:1e308", ["spatial", "S", "from 0 to 100,000", "1e+308"]),
        ("uniform:1e308", ["uniform", "K", "from 0 to 1,000"]),
        ("bias:inf", ["bias", "inf"]),
        ("gaps:1.5", ["gaps", "probability", "1.5"]),
        ("drop:-0.1", ["drop", "probability"]),
        ("outliers:2", ["outliers", "probability"]),
        ("gaps:0.1,0.5", ["gaps", "MEAN", ">= 1"]),
        ("gaps:0.1,12,0", ["gaps", "MAX"]),
        ("gaps:0.1,12,2.5", ["gaps", "MAX", "whole"]),
        ("block:1.5", ["block", "N", "whole"]),
        ("block:2x", ["block", "N", "seconds (as in 2s)", "'2x'"]),
        ("block:-1s", ["block", "N", ">= 0 seconds", "-1s"]),
        ("gaps:0.1,0s", ["gaps", "MEAN", "> 0 seconds"]),
        ("angular:2s", ["angular", "K", "'2s'"]),
        ("joints:-1", ["joints", "N"]),
        ("angular:0.5++drop:0.1", ["empty"]),
        ("+angular:0.5", ["empty"]),
        ("none+drop:0.1", ["none"]),
    ],
)
def test_bad_specs(text, words):
    with pytest.raises(CorruptionSpecError) as info:
        parse_corruption(text)
    assert isinstance(info.value, ValueError)
    for w in words:
        assert w in str(info.value)


def test_direct_construction_is_validated():
    with pytest.raises(CorruptionSpecError):
        MODELS["angular"](-1.0)
    with pytest.raises(CorruptionSpecError):
        MODELS["block"](3.5)


def test_errors_that_depend_on_the_clip(walk):
    F = walk.n_frames
    with pytest.raises(CorruptionApplyError, match=f"at least {F + 1} frames"):
        parse_corruption(f"block:{F - 1}").apply(walk)
    parse_corruption(f"block:{F - 2}").apply(walk)  # exactly fits
    with pytest.raises(CorruptionApplyError, match="START"):
        parse_corruption("block:10,0").apply(walk)
    with pytest.raises(CorruptionApplyError, match="START"):
        parse_corruption(f"block:10,{F - 10}").apply(walk)
    with pytest.raises(CorruptionApplyError, match="joints:30.*at most 24"):
        parse_corruption("joints:30").apply(walk)
    with pytest.raises(CorruptionApplyError, match="take of one frame.*use 2 or more"):
        parse_corruption("joints:3").apply(walk.slice(0, 1))
    parse_corruption("joints:0").apply(walk.slice(0, 1))  # nothing to take away
    still = walk.slice(0, 10).with_channels(np.repeat(walk.channels[:1], 10, axis=0))
    with pytest.raises(CorruptionApplyError, match="no non-root joint of this take moves"):
        parse_corruption("joints:1").apply(still)
    for seed in (-1, 1.5, "0", True):
        with pytest.raises(CorruptionApplyError, match="seed"):
            parse_corruption("angular:0.5").apply(walk, seed=seed)


def test_non_finite_input_is_refused(walk):
    ang = walk.angles_deg.copy()
    ang[5, 3, 1] = np.nan
    bad = walk.replace(angles_deg=ang)
    with pytest.raises(CorruptionApplyError, match="non-finite.*frame 5"):
        parse_corruption("angular:0.5").apply(bad)
    root = walk.root_positions.copy()
    root[7, 0] = np.inf
    with pytest.raises(CorruptionApplyError, match="frame 7"):
        make_case(walk.replace(root_positions=root), "drop:0.1")


# -- determinism, purity, independence ---------------------------------------------------


def _same(a: Observation, b: Observation) -> bool:
    return np.array_equal(a.observed, b.observed) and np.array_equal(
        a.motion.channels, b.motion.channels, equal_nan=True
    )


@pytest.mark.parametrize("text", ALL_SPECS + ["angular:0.5+gaps:0.02+spatial:0.3"])
def test_same_seed_same_output_other_seed_other_output(walk, text):
    before = walk.channels.copy()
    spec = parse_corruption(text)
    a, b, c = spec.apply(walk, seed=7), spec.apply(walk, seed=7), spec.apply(walk, seed=8)
    assert _same(a, b)
    assert not _same(a, c)
    assert np.array_equal(walk.channels, before)  # input untouched
    assert a.motion.skeleton is walk.skeleton and a.motion.fps == walk.fps and a.motion.name == walk.name
    assert a.motion.channels.shape == walk.channels.shape
    # missing values are NaN and only they are
    assert np.array_equal(np.isnan(a.motion.channels), ~a.channel_observed)


def test_streams_are_independent(walk):
    base = parse_corruption("angular:0.5").apply(walk, seed=1)
    for extra in ("drop:0.2", "gaps:0.02", "block:50", "joints:4", "outliers:0.0"):
        more = parse_corruption(f"angular:0.5+{extra}").apply(walk, seed=1)
        obs = more.channel_observed
        assert np.array_equal(more.motion.channels[obs], base.motion.channels[obs]), extra
    # a gap model's mask does not depend on models after it
    g = parse_corruption("gaps:0.02").apply(walk, seed=4)
    g2 = parse_corruption("gaps:0.02+sine:0.5+uniform:0.3").apply(walk, seed=4)
    assert np.array_equal(g.observed, g2.observed)


def test_stream_is_seed_position_and_name(walk):
    obs = parse_corruption("drop:0.1+angular:0.5").apply(walk, seed=5)
    work = Work(walk)
    from workbench.corruption import Angular

    Angular(0.5).corrupt(work, random_stream(5, 1, "angular"))
    ok = obs.channel_observed
    assert np.array_equal(obs.motion.channels[ok], work.channels[ok])
    # the same model twice draws different noise
    twice = parse_corruption("angular:0.5+angular:0.5").apply(walk, seed=5).motion.channels
    once = parse_corruption("angular:0.5").apply(walk, seed=5).motion.channels
    d1, d2 = once - walk.channels, twice - once
    cols = np.flatnonzero(np.abs(d1).sum(axis=0) > 0)
    assert not np.allclose(d1[:, cols], d2[:, cols])


def test_make_case(walk):
    case = make_case(walk, "Angular:0.50+gaps:0.01,12,600", seed=11)
    assert isinstance(case, Case)
    assert case.truth is walk
    assert case.corruption == "angular:0.5+gaps:0.01"
    assert case.seed == 11
    assert _same(case.observation, parse_corruption(case.corruption).apply(walk, seed=11))
    case2 = make_case(walk, parse_corruption("drop:0.1"), seed=2)
    assert case2.corruption == "drop:0.1"


def test_import_is_light():
    code = (
        "import sys, workbench.corruption\n"
        "heavy = [m for m in ('torch', 'matplotlib', 'pyvista', 'PySide6') if m in sys.modules]\n"
        "print(','.join(heavy))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "", f"importing workbench.corruption imported {out.stdout.strip()}"


def test_error_hierarchy():
    assert issubclass(CorruptionApplyError, CorruptionSpecError)
    assert issubclass(CorruptionSpecError, ValueError)
