import dataclasses

import numpy as np
import pytest

from workbench import registry
from workbench.core import Motion, Observation
from workbench.core.rotations import wrap_deg
from workbench.engine import CleanResult, Engine, EngineError, EngineInfo, Pipeline


def test_identity_bridges_gaps_and_keeps_observed(walk):
    observed = np.ones((walk.n_frames, walk.skeleton.n_joints), bool)
    observed[50:60, 4] = False
    res = registry.create("identity").clean(Observation(walk, observed))
    X, T = res.motion.channels, walk.channels
    assert np.isfinite(X).all()
    c = 3 + 3 * 4
    assert np.allclose(X[50:60, c], np.interp(np.arange(50, 60), [49, 60], [T[49, c], T[60, c]]))
    keep = np.ones(X.shape[1], bool)
    assert np.allclose(wrap_deg((X - T)[:50]), 0)
    del keep


def test_observation_bridged_is_what_the_engines_bridge(walk):
    """Observation.bridged (the corrupt command's BVH, the app's noisy skeleton) holds
    the channels every angle engine starts from (workbench.engine.signal.bridge_gaps)."""
    from workbench.corruption import parse_corruption
    from workbench.engine.signal import bridge_gaps

    obs = parse_corruption("angular:0.5+outliers:0.05+gaps:0.02").apply(walk, seed=4)
    assert obs.has_gaps
    X = obs.bridged().channels
    assert np.isfinite(X).all()
    assert np.allclose(X, bridge_gaps(obs), atol=1e-9)


def test_unknown_engine_and_bad_params_are_clear():
    with pytest.raises(EngineError, match="unknown engine 'nope'; available: .*identity"):
        registry.create("nope")
    with pytest.raises(EngineError, match="unknown engine 'GAUSSIAN'; did you mean 'gaussian'"):
        registry.create("GAUSSIAN")
    with pytest.raises(EngineError, match="unknown engine 'kalmann'; did you mean 'kalman'"):
        registry.create("kalmann")
    with pytest.raises(EngineError, match="has no parameter 'x'"):
        registry.create("identity:x=1")
    with pytest.raises(EngineError, match="name=value"):
        registry.create("identity:oops")
    with pytest.raises(EngineError, match=r"'sigma_ms' given twice \(5 and 6\)"):
        registry.create("gaussian:sigma_ms=5,sigma_ms=6")


def test_train_epochs_win_over_the_specs_own():
    from workbench.cli import _with_epochs

    assert _with_epochs(registry.create("ebf:epochs=3,bias=true", pretrained=False), 2).spec == "ebf:epochs=2,bias=True"


class Doubler(Engine):
    """A test engine with typed parameters."""

    from dataclasses import dataclass as _dc

    @_dc(frozen=True)
    class Params:
        gain: float = 1.0
        flag: bool = False
        label: str = "a"

    info = EngineInfo(name="doubler", summary="test", tasks=frozenset({"denoise"}))

    def clean(self, observation, /):
        return CleanResult(observation.motion)


def test_params_from_spec_and_spec_round_trip():
    registry.register("doubler", Doubler)
    e = registry.create("doubler:gain=2.5,flag=yes,label=b")
    assert e.params == Doubler.Params(gain=2.5, flag=True, label="b")
    assert e.spec == "doubler:gain=2.5,flag=True,label=b"
    assert registry.create(e.spec).params == e.params
    assert registry.create("doubler").spec == "doubler"
    with pytest.raises(EngineError, match="true or false"):
        registry.create("doubler:flag=maybe")
    with pytest.raises(EngineError, match="doubler': gain must be a number, got 'abc'"):
        registry.create("doubler:gain=abc")
    with pytest.raises(EngineError, match="'gaussian': sigma_ms must be a number, got 'x'"):
        registry.create("gaussian:sigma_ms=x")
    with pytest.raises(EngineError, match="'cae': views must be a whole number, got '2.5'"):
        registry.create("cae:views=2.5", pretrained=False)


def test_a_trained_engine_loads_the_weights_folder_its_spec_names(walk, tmp_path):
    from engines.mssa import MSSA

    committed = MSSA().default_weights_dir() / "cmu"
    e = registry.create(f"mssa:prior_weight=2,weights={committed}")
    assert e.weights_folder == committed and e.skeleton_signature_ == walk.skeleton.signature()
    assert e.spec == f"mssa:prior_weight=2.0,weights={committed}"
    assert registry.create(e.spec, pretrained=False).spec == e.spec
    assert registry.create("mssa:weights=").weights_folder is None  # empty: the committed ones
    with pytest.raises(EngineError, match="no weights manifest here"):
        registry.create(f"mssa:weights={tmp_path}")
    with pytest.raises(EngineError, match="these weights are for engine 'mssa', not 'cae'"):
        registry.create(f"cae:weights={committed}")
    with pytest.raises(EngineError, match="'gaussian' has no parameter 'weights'"):
        registry.create(f"gaussian:weights={committed}")


def test_weights_bring_their_architecture_unless_the_spec_asks_for_another():
    from engines.ebf import EBF

    bias = EBF().default_weights_dir().parent / "ebf-bias" / "cmu"
    assert registry.create(f"ebf:weights={bias}").params.bias is True  # taken from the weights
    with pytest.raises(EngineError, match=r"trained with \{'lstm_units': 64\}, not \{'lstm_units': 32\}"):
        registry.create(f"ebf:lstm_units=32,weights={bias}")
    cae = registry.create("cae").default_weights_dir() / "cmu"
    with pytest.raises(EngineError, match=r"trained with \{'base_width': 16\}, not \{'base_width': 8\}"):
        registry.create(f"cae:base_width=8,weights={cae}")
    narrow = registry.create("cae:base_width=8")  # another variant: its own weights, none committed
    assert narrow.variant == "cae-base_width8" and narrow.skeleton_signature_ is None  # was: the 16-wide, silently
    trained = registry.create("cae:epochs=3").spec  # training settings come with the weights
    assert trained == registry.create("cae").spec and "epochs=3" not in trained


def test_fit_takes_a_list_of_motions_and_says_so_otherwise(walk):
    engine = registry.create("kalman-learned", pretrained=False)
    for bad, kind in (
        ((m for m in [walk]), "a list of Motion, not a generator"),
        ("takes/", "a list of Motion, not a str"),
    ):
        with pytest.raises(TypeError, match=kind):
            engine.fit(bad)
    with pytest.raises(TypeError, match="trains on Motion objects .workbench.io.read_motion., not on 'Observation'"):
        engine.fit([walk, Observation(walk)])


def test_import_path_specs():
    e = registry.create("engines.identity:Identity")
    assert e.info.name == "identity"
    with pytest.raises(EngineError, match="cannot import"):
        registry.create("no.such.module:Thing")
    for path in ("workbench.io:read_motion", "workbench.engine:Engine", "workbench.engine:Pipeline"):
        with pytest.raises(EngineError, match=f"'{path}' is no engine class"):
            registry.create(path)
    with pytest.raises(TypeError, match="an engine spec is a string such as 'ebf' or 'lerp>ebf', not a list"):
        registry.create(["lerp"])


def test_pipeline_passes_filled_motion_as_fully_observed(walk):
    seen = []

    class Spy(Doubler):
        info = EngineInfo(name="spy", summary="records what it sees", tasks=frozenset({"denoise"}))

        def clean(self, observation, /):
            seen.append(observation.observed.all())
            return CleanResult(observation.motion, {"x": np.zeros(observation.n_frames)})

    registry.register("spy", Spy)
    p = registry.create("identity>spy")
    assert isinstance(p, Pipeline) and p.spec == "identity>spy"
    observed = np.ones((walk.n_frames, walk.skeleton.n_joints), bool)
    observed[5:9, 3] = False
    res = p.clean(Observation(walk, observed))
    assert seen == [True] and "x" in res.diagnostics
    with pytest.raises(EngineError, match="two engines"):
        Pipeline([registry.create("identity")])


def test_observation_nan_counts_as_missing(walk):
    X = walk.channels
    X[3, 3 + 3 * 7 + 1] = np.nan
    obs = Observation(walk.with_channels(X))
    assert not obs.observed[3, 7] and obs.observed.sum() == obs.observed.size - 1
    assert np.isnan(obs.motion.angles_deg[3, 7]).all()


def test_every_engine_s_clean_refuses_what_it_cannot_clean_and_what_it_must_not_return(walk):
    class Broken(Engine):
        info = EngineInfo(name="test-broken", summary="test: weights that give NaN", tasks=frozenset({"denoise"}))

        def clean(self, observation, /):
            return CleanResult(observation.motion.with_channels(np.full_like(observation.motion.channels, np.nan)))

    with pytest.raises(TypeError, match="test-broken.clean takes an Observation, not a Motion: Observation"):
        Broken().clean(walk)
    nothing = Observation(walk, np.zeros((walk.n_frames, walk.skeleton.n_joints), bool))
    sk = walk.skeleton  # and a joint without channels, which is never missing, does not count as observed
    still = dataclasses.replace(sk, channels=(*sk.channels[:-1], ()))
    unseen = Motion(still, walk.fps, walk.root_positions * np.nan, walk.angles_deg * np.nan)
    for engine in (Broken(), registry.create("kalman"), registry.create("ebd>ebf"), registry.create("lerp")):
        for observation in (nothing, Observation(unseen)):
            with pytest.raises(EngineError, match="no sample of the take is observed"):
                engine.clean(observation)
    with pytest.raises(EngineError, match="test-broken returned missing or infinite values: a fault of the engine"):
        Broken().clean(Observation(walk))

    class Short(Engine):
        info = EngineInfo(name="test-short", summary="test: drops a frame", tasks=frozenset({"denoise"}))

        def clean(self, observation, /):
            return CleanResult(observation.bridged().slice(0, -1))

    with pytest.raises(EngineError, match=rf"test-short returned {walk.n_frames - 1} frames .*: a fault of the engine"):
        Short().clean(Observation(walk))


def test_engines_lists_a_plugin_without_info_as_broken(monkeypatch, capsys):
    from workbench.cli import main

    class NoInfo(Engine):
        def clean(self, observation, /):
            return CleanResult(observation.bridged())

    monkeypatch.setitem(registry._registered, "test-noinfo", NoInfo)
    assert main(["engines"]) == 0
    out = capsys.readouterr().out
    assert "test-noinfo      (broken: " in out and "NoInfo sets no `info = EngineInfo(...)`" in out
    assert "kalman " in out, "the other engines are listed"


def test_every_trained_engine_has_its_own_weights_folder_and_its_committed_weights_load():
    folders = {}
    for name in registry.available():
        engine = registry.create(name)
        if not engine.info.trainable:
            continue
        assert engine.skeleton_signature_ is not None, f"{name}: the committed weights did not load"
        folder = engine.default_weights_dir()
        assert folder.parent.name == "weights" and folder.name == engine.variant == name
        folders[name] = folder
    assert len(set(folders.values())) == len(folders) == 9


@pytest.mark.slow
@pytest.mark.usefixtures("data_root")
def test_train_writes_its_variant_s_folder_with_a_manifest_of_what_it_used(tmp_path, monkeypatch, capsys):
    import json

    from workbench.cli import main
    from workbench.data import dataset_terms

    monkeypatch.chdir(tmp_path)
    assert main(["train", "kalman-learned"]) == 0
    manifest = json.loads((tmp_path / "runs" / "kalman-learned" / "manifest.json").read_text())
    assert manifest["format_version"] == 3 and manifest["variant"] == "kalman-learned"
    training = manifest["training"]
    assert training["datasets"] == [{"name": "cmu", "terms": dataset_terms("cmu")}]
    assert len(training["clips"]) == 36 and all(c.startswith("cmu/") for c in training["clips"])
    assert manifest["test_scores"]["split"] == "test" and manifest["test_scores"]["rms_angle_deg"] > 0
    assert "note: training on the cmu training split" in capsys.readouterr().err


def test_an_engine_that_does_not_stream_says_so():
    assert registry.create("ebf", pretrained=False).streams and not registry.create("kalman").streams
    with pytest.raises(EngineError, match="engine 'kalman' does not stream: .*ebf, bf and nn stream"):
        registry.create("kalman").stream(None, 120.0)


def test_an_engine_whose_parameter_has_no_default_is_refused_when_made():
    with pytest.raises(TypeError, match="Bare.Params: k without a default; every parameter needs one"):

        class Bare(Engine):
            info = EngineInfo(name="test-bare", summary="test", tasks=frozenset({"denoise"}))

            @dataclasses.dataclass(frozen=True)
            class Params:
                k: int


def test_a_key_error_in_an_engine_is_its_fault_and_a_name_not_found_the_user_s():
    from workbench.errors import NameNotFoundError, describe, user_errors

    assert describe(KeyError("sigma_frames")) == "KeyError: 'sigma_frames'" and KeyError not in user_errors()
    assert describe(NameNotFoundError("no clip named 'x'")) == "no clip named 'x'"
