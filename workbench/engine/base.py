"""The engine protocol: what every cleaning method implements, and shared machinery.

An engine sees an :class:`~workbench.core.Observation` (never the truth) and returns a
:class:`CleanResult`: a complete Motion (same skeleton, fps and frame count, finite
everywhere) plus named diagnostic arrays it can explain itself with, e.g.
``filter_sigma_frames`` (F, C) for filter-predicting engines.

Parameters are a frozen dataclass ``Params`` with units in the field names; fitted state
ends with ``_``; ``clean`` on an unfitted trainable engine raises :class:`NotFittedError`.
Engines that depend on a skeleton record it at fit time and refuse another one with
:class:`EngineError`.

Each parameter of a trainable engine has one of three roles, set by its field
(:func:`trained`, :func:`training`; a plain field is *inference*):

- *trained*: fixed by the weights, as the network's width is. Loading weights takes
  their value; a spec that asks for another is refused. They name the weights'
  variant (:attr:`Engine.variant`: ``ebf-bias``).
- *training*: used by ``fit`` only (epochs, seed, augmentation). Loading weights takes
  their value, so that the spec says how the loaded weights were trained.
- *inference*: free at clean time; the spec's value is kept.

:meth:`Engine.load` applies the rule for every engine. Committed weights live in
``engines/<package>/weights/<variant>/`` (:meth:`Engine.default_weights_dir`).
"""

from __future__ import annotations

import dataclasses
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar, Mapping, Sequence

import numpy as np

from ..core.motion import Motion, Observation
from ..core.skeleton import Skeleton

TASKS = frozenset({"denoise", "fill"})
#: the spec option of trainable engines that names a folder of trained weights
WEIGHTS_OPTION = "weights"
SPACES = frozenset({"angles", "positions"})
#: the field-metadata key of a parameter's role, and the three roles (module docstring)
ROLE = "role"
TRAINED, TRAINING, INFERENCE = "trained", "training", "inference"


def trained(default: typing.Any) -> typing.Any:
    """A parameter field fixed by the weights (``lstm_units: int = trained(64)``)."""
    return field(default=default, metadata={ROLE: TRAINED})


def training(default: typing.Any) -> typing.Any:
    """A parameter field used by ``fit`` only (``epochs: int = training(20)``)."""
    return field(default=default, metadata={ROLE: TRAINING})


def param_roles(params: typing.Any) -> dict[str, str]:
    """Each field of a Params dataclass (or instance) and its role, in field order."""
    return {f.name: f.metadata.get(ROLE, INFERENCE) for f in dataclasses.fields(params)}


def _of_role(params: typing.Any, role: str) -> dict[str, typing.Any]:
    """The values of the parameters of ``params`` with ``role``, by name."""
    return {name: getattr(params, name) for name, r in param_roles(params).items() if r == role}


#: the engines to point a user to for takes no trained engine models (translated joints)
CLASSICAL = "kalman, gaussian, butterworth, lerp, spline"


def _moving(skeleton: Skeleton) -> str:
    """What moves by position channels, in words: ``Hips moves by position channels``."""
    names = [skeleton.names[j] for j in skeleton.translated]
    return f"{', '.join(names)} move{'s' if len(names) == 1 else ''} by position channels"


class EngineError(ValueError):
    """A user-facing problem with an engine: bad spec, wrong skeleton, unusable input."""


class NotFittedError(EngineError):
    """``clean`` was called on a trainable engine that has neither been fitted nor loaded."""


@dataclass(frozen=True)
class EngineInfo:
    """What an engine is. tasks: subset of {"denoise", "fill"}; space: "angles" or
    "positions"; keeps_observed: observed samples come back unchanged."""

    name: str
    summary: str
    tasks: frozenset[str]
    space: str = "angles"
    trainable: bool = False
    keeps_observed: bool = False
    citation: str = ""

    def __post_init__(self) -> None:
        if not self.tasks <= TASKS or self.space not in SPACES:
            raise ValueError(f"engine {self.name!r}: bad tasks {set(self.tasks)} or space {self.space!r}")


@dataclass(frozen=True)
class CleanResult:
    """The cleaned motion and named diagnostics (arrays with the frame axis first)."""

    motion: Motion
    diagnostics: Mapping[str, np.ndarray] = field(default_factory=dict)


@dataclass(frozen=True)
class NoParams:
    """Engines without parameters."""


def _coerce(value: str, kind: typing.Any, name: str) -> typing.Any:
    if kind is bool:
        low = value.lower()
        if low in ("1", "true", "yes", "on"):
            return True
        if low in ("0", "false", "no", "off"):
            return False
        raise ValueError(f"{name} must be true or false, got {value!r}")
    if kind is str:
        return value
    if kind in (int, float):
        try:
            return kind(value)
        except ValueError:
            what = "a whole number" if kind is int else "a number"
            raise ValueError(f"{name} must be {what}, got {value!r}") from None
    raise ValueError(f"{name}: cannot set a parameter of type {kind} from text")


class Engine:
    """Base class with the shared machinery: parameters from spec strings, skeleton
    checks, saving and loading fitted state with a checksummed manifest."""

    info: ClassVar[EngineInfo]
    Params: ClassVar[type] = NoParams
    #: spec options under which ``fit`` takes seconds on a few short takes (what the
    #: conformance suite trains with to check that a seeded fit repeats)
    QUICK_FIT: ClassVar[Mapping[str, str]] = {}
    #: fitted skeleton layout signature (trainable engines set it in fit/load)
    skeleton_signature_: str | None = None
    #: the folder that the spec option ``weights=DIR`` names, to load trained state from
    #: instead of the committed weights (None: the committed ones)
    weights_folder: Path | None = None

    def __init__(self, params: typing.Any = None) -> None:
        self.params = self.Params() if params is None else params

    # -- parameters -----------------------------------------------------------------
    @classmethod
    def from_options(cls, options: Mapping[str, str]) -> "Engine":
        """Build from ``{"sigma_ms": "58"}``-style text options, with clear errors. A
        trainable engine also takes ``weights=DIR`` (see :attr:`weights_folder`)."""
        fields = {f.name: f for f in dataclasses.fields(cls.Params)}
        hints = typing.get_type_hints(cls.Params)
        values = {}
        for key, text in options.items():
            if key == WEIGHTS_OPTION and cls.info.trainable:
                continue
            if key not in fields:
                valid = ", ".join([*fields, WEIGHTS_OPTION] if cls.info.trainable else fields) or "none"
                raise EngineError(f"engine {cls.info.name!r} has no parameter {key!r} (parameters: {valid})")
            try:
                values[key] = _coerce(text, hints[key], key)
            except ValueError as err:
                raise EngineError(f"engine {cls.info.name!r}: {err}") from None
        try:
            engine = cls(cls.Params(**values))
        except (TypeError, ValueError) as err:
            raise EngineError(f"engine {cls.info.name!r}: {err}") from None
        if options.get(WEIGHTS_OPTION) and cls.info.trainable:
            engine.weights_folder = Path(options[WEIGHTS_OPTION]).expanduser()
        return engine

    @property
    def spec(self) -> str:
        """The spec string that recreates this engine, e.g. ``gaussian:sigma_ms=58``."""
        default = self.Params()
        changed = [
            f"{f.name}={getattr(self.params, f.name)}"
            for f in dataclasses.fields(self.params)
            if getattr(self.params, f.name) != getattr(default, f.name)
        ]
        if self.weights_folder is not None:
            changed.append(f"{WEIGHTS_OPTION}={self.weights_folder}")
        return self.info.name + (":" + ",".join(changed) if changed else "")

    # -- the protocol ---------------------------------------------------------------
    def fit(self, motions: Sequence[Motion], /) -> "Engine":
        return self

    def clean(self, observation: Observation, /) -> CleanResult:
        raise NotImplementedError

    # -- skeleton checks ------------------------------------------------------------
    def training_motions(self, motions: Sequence[Motion], same_fps: bool = False) -> list[Motion]:
        """``motions`` as a list, checked as every trained engine's ``fit`` needs them: at
        least one, all of one skeleton layout (and, with ``same_fps``, one frame rate),
        none with translated joints, which no trained engine models yet. Raises
        EngineError saying which rule they break."""
        motions = list(motions)
        name = self.info.name
        if not motions:
            raise EngineError(f"engine {name!r}: no training motions")
        first = motions[0]
        for m in motions[1:]:
            if m.skeleton.signature() != first.skeleton.signature():
                raise EngineError(
                    f"engine {name!r} trains on one skeleton layout; {first.name or 'motion 0'} "
                    f"and {m.name or 'another'} have different ones"
                )
            if same_fps and abs(m.fps - first.fps) > 1e-6:
                raise EngineError(
                    f"engine {name!r}: the training motions mix frame rates ({first.fps:g} and {m.fps:g} fps)"
                )
        if first.skeleton.translated:
            raise EngineError(
                f"engine {name!r} cannot be trained on skeletons with translated joints yet "
                f"({_moving(first.skeleton)}); clean such takes with a classical engine: "
                f"{CLASSICAL}"
            )
        return motions

    def check_skeleton(self, skeleton: Skeleton) -> None:
        """Raise EngineError if this engine was fitted for another skeleton layout."""
        if self.skeleton_signature_ is not None and skeleton.signature() != self.skeleton_signature_:
            mine = (
                f"engine {self.info.name!r} was trained for another skeleton ({self.skeleton_description_}); "
                f"this take has {skeleton.n_joints} joints rooted at {skeleton.names[0]!r}"
            )
            if skeleton.translated:  # no trained engine models them yet
                raise EngineError(
                    f"{mine}, and joints it cannot model yet: {_moving(skeleton)}. "
                    f"Clean it with a classical engine: {CLASSICAL}."
                )
            raise EngineError(
                f"{mine}. Train it on takes of this skeleton "
                f"(`workbench train {self.info.name} --data DIR --out FOLDER`) and clean with "
                f"`{self.info.name}:{WEIGHTS_OPTION}=FOLDER`."
            )

    @property
    def skeleton_description_(self) -> str:
        sig = self.skeleton_signature_ or ""
        joints = sig.split(";")
        return f"{len(joints)} joints rooted at {joints[0].split('<')[0]!r}" if sig else "unknown"

    def require_fitted(self) -> None:
        if self.info.trainable and self.skeleton_signature_ is None:
            raise NotFittedError(
                f"engine {self.spec!r} is not trained: run `workbench train '{self.spec}'` or give it weights"
            )

    # -- fitted state ---------------------------------------------------------------
    def state_arrays(self) -> dict[str, np.ndarray]:
        """Fitted state as named arrays (trainable engines override)."""
        raise NotImplementedError(f"engine {self.info.name!r} has no fitted state")

    def load_state_arrays(self, arrays: Mapping[str, np.ndarray], manifest: Mapping) -> None:
        raise NotImplementedError(f"engine {self.info.name!r} has no fitted state")

    def training_record(self) -> dict[str, typing.Any]:
        """What the manifest keeps of the last ``fit`` beyond the parameters (a torch
        engine's loss per epoch); JSON values."""
        return {}

    def save(self, folder: str | Path, extra_manifest: Mapping | None = None) -> Path:
        """Save fitted state and its manifest into ``folder``; returns the manifest path.
        :func:`workbench.engine.training.train_engine` writes the training's record
        (``extra_manifest``: clips, data sets and their licences, minutes, test scores)."""
        from .weights import save_weights

        self.require_fitted()
        manifest = {
            "engine": self.info.name,
            "variant": self.variant,
            "spec": self.spec,
            "params": dataclasses.asdict(self.params),
            "skeleton_signature": self.skeleton_signature_,
            **self.training_record(),
            **(extra_manifest or {}),
        }
        return save_weights(folder, self.state_arrays(), manifest)

    def load(self, folder: str | Path) -> "Engine":
        """Load fitted state saved by :meth:`save` (checksum verified, no pickle), its
        trained and training parameters with it (:meth:`weights_params`)."""
        from .weights import load_weights

        arrays, manifest = load_weights(folder)
        if manifest.get("engine") != self.info.name:
            raise EngineError(
                f"{folder}: these weights are for engine {manifest.get('engine')!r}, not {self.info.name!r}"
            )
        self.params = self.weights_params(manifest, folder)
        self.load_state_arrays(arrays, manifest)
        self.skeleton_signature_ = manifest["skeleton_signature"]
        return self

    def weights_params(self, manifest: Mapping, folder: str | Path = "") -> typing.Any:
        """This engine's parameters with the trained and training ones of the weights of
        ``manifest`` (one missing there, newer than the weights, at its default), the
        inference ones as they are. Raises EngineError where the spec asked for another
        value of a trained one, or the weights record a parameter this engine lacks."""
        default, saved = self.Params(), dict(manifest.get("params") or {})
        roles = param_roles(default)
        unknown = sorted(set(saved) - set(roles))
        if unknown:
            raise EngineError(
                f"{folder}: these weights record parameters engine {self.info.name!r} does not have "
                f"({', '.join(unknown)}): they are from another version of it; retrain them"
            )
        fixed = {k: saved.get(k, getattr(default, k)) for k, role in roles.items() if role != INFERENCE}
        asked = {k: v for k, v in _of_role(self.params, TRAINED).items() if v != getattr(default, k) and v != fixed[k]}
        if asked:
            raise EngineError(
                f"engine {self.info.name!r}: these weights were trained with "
                f"{ {k: fixed[k] for k in asked} }, not {asked}; train this variant first "
                f"(`workbench train SPEC --out FOLDER`, then add {WEIGHTS_OPTION}=FOLDER to the spec)"
            )
        return dataclasses.replace(self.params, **fixed)

    @property
    def variant(self) -> str:
        """The name of this engine's weights: its name, then each trained parameter that
        differs from its default (``ebf-bias``, ``ebf-lstm_units96``)."""
        default = self.Params()
        parts = [self.info.name]
        for name, value in _of_role(self.params, TRAINED).items():
            if value != getattr(default, name):
                parts.append(name if value is True else f"{name}{value}")
        return "-".join(parts)

    def default_weights_dir(self) -> Path:
        """``engines/<package>/weights/<variant>/``: where the committed weights of this
        variant live, in the folder of the package that defines the engine class."""
        import sys

        module = sys.modules[type(self).__module__]
        return Path(module.__file__).resolve().parent / "weights" / self.variant

    def load_pretrained(self) -> "Engine":
        """Load the weights of ``weights_folder`` when set, else the committed weights
        when this engine is trainable and has some."""
        if self.weights_folder is not None:
            return self.load(self.weights_folder)
        if self.info.trainable and (self.default_weights_dir() / "manifest.json").exists():
            self.load(self.default_weights_dir())
        return self


class Pipeline(Engine):
    """``a>b``: stage a fills gaps, then b cleans the filled motion as fully observed.

    Diagnostics of the last stage keep their names; earlier ones are prefixed with their
    stage's name and a dot.
    """

    def __init__(self, stages: Sequence[Engine]) -> None:
        if len(stages) < 2:
            raise EngineError("a pipeline needs at least two engines, as in 'lerp>gaussian'")
        self.stages = list(stages)
        super().__init__(NoParams())
        tasks = frozenset().union(*(s.info.tasks for s in stages))
        self.info = EngineInfo(
            name=">".join(s.spec for s in stages),
            summary=" then ".join(s.info.name for s in stages),
            tasks=tasks,
            space=stages[-1].info.space,
            trainable=any(s.info.trainable for s in stages),
        )

    @property
    def spec(self) -> str:
        return ">".join(s.spec for s in self.stages)

    def fit(self, motions: Sequence[Motion], /) -> "Pipeline":
        for s in self.stages:
            s.fit(motions)
        return self

    def clean(self, observation: Observation, /) -> CleanResult:
        diagnostics: dict[str, np.ndarray] = {}
        result = None
        for i, stage in enumerate(self.stages):
            result = stage.clean(observation)
            last = i == len(self.stages) - 1
            for key, value in result.diagnostics.items():
                diagnostics[key if last else f"{stage.info.name}.{key}"] = value
            observation = Observation(result.motion)
        assert result is not None
        return CleanResult(result.motion, diagnostics)
