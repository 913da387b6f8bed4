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
import functools
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar, Mapping, Sequence

import numpy as np

from ..core.motion import Motion, Observation
from ..core.skeleton import Skeleton

if typing.TYPE_CHECKING:
    from .view import ModelView

TASKS = frozenset({"denoise", "fill"})
#: the spec option of trainable engines that names a folder of trained weights
WEIGHTS_OPTION = "weights"
SPACES = frozenset({"angles", "positions"})
#: the field-metadata key of a parameter's role, and the three roles (module docstring)
ROLE = "role"
TRAINED, TRAINING, INFERENCE = "trained", "training", "inference"
#: the trained parameter of an engine's skeleton-agnostic variant (``cae:universal=true``)
UNIVERSAL = "universal"
#: the skeleton signature such a variant's weights record: they model the canonical humanoid
HUMANOID_SIGNATURE = "canonical humanoid"
#: the rate (fps) a universal variant trains and runs at where its class sets no
#: :attr:`Engine.MODEL_FPS`: pooled data sets come at several rates
UNIVERSAL_FPS = 120.0


def trained(default: typing.Any) -> typing.Any:
    """A parameter field fixed by the weights (``lstm_units: int = trained(64)``).

    Loading weights takes their value of it, and a spec that asks for another is refused
    (:meth:`Engine.weights_params`); the trained parameters name the weights' variant
    (:attr:`Engine.variant`).

    Parameters
    ----------
    default : object
        The field's default value.

    Returns
    -------
    dataclasses.Field
        A field whose metadata give it the role :data:`TRAINED` (under :data:`ROLE`).
    """
    return field(default=default, metadata={ROLE: TRAINED})


def training(default: typing.Any) -> typing.Any:
    """As :func:`trained`, for a parameter used by ``fit`` only (``epochs: int =
    training(20)``), of role :data:`TRAINING`: loading weights takes their value, so that
    the spec says how they were trained, and a spec asking for another is not refused."""
    return field(default=default, metadata={ROLE: TRAINING})


def param_roles(params: typing.Any) -> dict[str, str]:
    """Each field of a Params dataclass (or instance) and its role, in field order.

    Parameters
    ----------
    params : type or object
        A Params dataclass or an instance of one.

    Returns
    -------
    dict of str to str
        Field name to role: :data:`TRAINED`, :data:`TRAINING` or, for a plain field,
        :data:`INFERENCE`.

    Raises
    ------
    TypeError
        ``params`` is not a dataclass or an instance of one.
    """
    return {f.name: f.metadata.get(ROLE, INFERENCE) for f in dataclasses.fields(params)}


def _of_role(params: typing.Any, role: str) -> dict[str, typing.Any]:
    """The values of the parameters of ``params`` with ``role``, by name."""
    return {name: getattr(params, name) for name, r in param_roles(params).items() if r == role}


class EngineError(ValueError):
    """A user-facing problem with an engine: bad spec, wrong skeleton, unusable input.

    Its message says what is wrong and, where it can, what to do instead. A subclass of
    ``ValueError``.
    """


class NotFittedError(EngineError):
    """``clean`` was called on a trainable engine that has neither been fitted nor loaded.

    Raised by :meth:`Engine.require_fitted` (which :meth:`Engine.save` calls too); a
    subclass of :class:`EngineError`.
    """


@dataclass(frozen=True)
class EngineInfo:
    """What an engine is: its name, what it is for and what it promises.

    Attributes
    ----------
    name : str
        The engine's name, the first part of its specs (``gaussian`` of
        ``gaussian:sigma_ms=58``).
    summary : str
        What it does, in one line.
    tasks : frozenset of str
        A subset of :data:`TASKS`, {"denoise", "fill"}: the tasks it does. The
        conformance suite (:mod:`workbench.testing`) requires at least one.
    space : {"angles", "positions"}
        What it cleans (:data:`SPACES`): the joint angles of the channel matrix, or the
        joint positions, brought back to angles by IK.
    trainable : bool
        It has fitted state: ``fit`` learns it and weights hold it.
    keeps_observed : bool
        Observed samples come back unchanged (angles up to whole turns of 360 degrees).
    citation : str
        Where the method comes from; empty if nowhere in particular.

    Raises
    ------
    ValueError
        ``tasks`` is not a subset of :data:`TASKS` or ``space`` is not in :data:`SPACES`.
    """

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
    """The cleaned motion and named diagnostics: what :meth:`Engine.clean` returns.

    Attributes
    ----------
    motion : Motion
        The cleaned take: same skeleton, fps and frame count as the input, finite
        everywhere.
    diagnostics : Mapping[str, ndarray]
        Named arrays the engine can explain itself with, each of shape (F, ...) with the
        frame axis first, e.g. ``filter_sigma_frames`` (F, C) for filter-predicting
        engines (default: none).
    """

    motion: Motion
    diagnostics: Mapping[str, np.ndarray] = field(default_factory=dict)


@dataclass(frozen=True)
class NoParams:
    """The parameters of engines without parameters: a frozen dataclass with no fields."""


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


def _checked_clean(clean):
    """``clean`` (an engine's method), refusing what no engine can clean and what no
    engine may return, each with an error that says so: TypeError for an input that is
    not an :class:`Observation` and for a result that is not a :class:`CleanResult`;
    EngineError for an observation with no channel observed (an engine would make every
    value up), for a result of another frame count, rate or skeleton layout than the
    take's, and for one that is not finite everywhere, naming the engine and, for a
    trained one, its weights (broken weights, a diverged training); and EngineError where
    the user's :attr:`Engine.humanoid_overrides` do not fit the take's skeleton, for every
    engine alike (a mapping file given for the take is checked, used or not)."""

    @functools.wraps(clean)
    def checked(self, observation, /, **kwargs):
        if not isinstance(observation, Observation):
            raise TypeError(
                f"{self.info.name}.clean takes an Observation, not a {type(observation).__name__}: "
                "Observation(motion), with its observed mask where it has gaps"
            )
        if not observation.channel_observed.any():
            raise EngineError("no sample of the take is observed (every value is NaN or masked as missing)")
        if self.humanoid_overrides:  # the user's --mapping fits the take, whether or not this engine maps it
            from .view import body_skeleton

            self.humanoid(body_skeleton(observation.skeleton))
        result = clean(self, observation, **kwargs)
        if not isinstance(result, CleanResult):
            raise TypeError(f"{self.info.name}.clean returned a {type(result).__name__}, not a CleanResult")
        motion, take = result.motion, observation.motion
        if (
            motion.n_frames != take.n_frames
            or abs(motion.fps - take.fps) > 1e-9 * take.fps
            or not motion.skeleton.same_layout(take.skeleton)
        ):
            raise EngineError(
                f"{self.spec} returned {motion.n_frames} frames at {motion.fps:g} fps of another skeleton or rate than "
                f"the take's {take.n_frames} at {take.fps:g}: a fault of the engine"
            )
        parts = (motion.root_positions, motion.angles_deg, motion.translations)
        if not all(np.isfinite(a).all() for a in parts if a is not None):
            cause = (
                f"its weights{f' ({self.weights_used_})' if self.weights_used_ else ''} may be broken (a training "
                "that diverged?: retrain them, or clean with the committed ones), or its code"
                if self.info.trainable
                else "a fault of the engine"
            )
            raise EngineError(f"{self.spec} returned missing or infinite values: {cause}")
        return result

    return checked


class Engine:
    """Base class of every engine, with the machinery they share.

    Parameters from spec strings (:meth:`from_options`, :attr:`spec`), skeleton checks
    (:meth:`training_motions`, :meth:`check_skeleton`), and saving and loading fitted
    state with a checksummed manifest (:meth:`save`, :meth:`load`). A subclass sets
    :attr:`info` and :attr:`Params` and implements :meth:`clean` (which the class wraps
    in :func:`_checked_clean`: the input is an observation with something observed, the
    output a finite CleanResult of its frame count, rate and skeleton layout); a
    trainable one also :meth:`fit`,
    :meth:`state_arrays` and :meth:`load_state_arrays`.

    Parameters
    ----------
    params : Params, optional
        The engine's parameters (default: ``Params()``, every field at its default).

    Attributes
    ----------
    info : EngineInfo
        What the engine is (a class attribute every engine sets).
    Params : type
        The frozen dataclass of its parameters, units in the field names, each field's
        role set by :func:`trained`, :func:`training` or neither (inference); a class
        attribute, :class:`NoParams` by default.
    QUICK_FIT : Mapping[str, str]
        Spec options under which ``fit`` takes seconds on a few short takes: what the
        conformance suite trains with to check that a seeded fit repeats (a class
        attribute, empty by default).
    MODEL_FPS : float or None
        The rate (fps) ``fit`` resamples the training takes to (a class attribute); None,
        the default: the takes' own, which they must share.
    TRAINS_WITHOUT_OPTIONAL_JOINTS : bool
        A universal variant's ``fit`` leaves out the canonical joints a training skeleton
        lacks (a class attribute; False, the default: it refuses such skeletons).
    skeleton_signature_ : str or None
        The fitted skeleton layout (of the takes' body view,
        :func:`workbench.engine.view.body_skeleton`),
        :meth:`workbench.core.skeleton.Skeleton.signature`; trainable engines set it in
        ``fit`` (:meth:`fitted_on`) and :meth:`load` sets it. None: not fitted.
    fps_ : float or None
        The frame rate the fitted model runs at; takes of other rates are resampled to it
        (:meth:`model_view`). Set with :attr:`skeleton_signature_`.
    weights_folder : Path or None
        The folder that the spec option ``weights=DIR`` names, to load trained state from
        instead of the committed weights (None: the committed ones).
    params : Params
        The engine's parameters, an instance of :attr:`Params`.
    """

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
    #: the frame rate the fitted model runs at (fps; None: not fitted): takes of another
    #: rate are resampled to it (:meth:`model_view`)
    fps_: float | None = None
    #: the rate ``fit`` resamples its training takes to (fps); None: train at the takes'
    #: own rate, which they must share
    MODEL_FPS: ClassVar[float | None] = None
    #: a universal variant's ``fit`` leaves out the canonical joints a training skeleton
    #: lacks (never trains on a placeholder for them), so it takes such skeletons
    TRAINS_WITHOUT_OPTIONAL_JOINTS: ClassVar[bool] = False
    #: the folder the weights in use were loaded from (None: fitted here, or not fitted)
    loaded_from_: Path | None = None
    #: which weights the last clean used, for its output line and the app: "skeleton-specific
    #: weights FOLDER" or "universal weights FOLDER" (a universal variant's, also where a plain
    #: engine's skeleton has none of its own: :meth:`universal_twin`), the first followed by
    #: " blended SHARE towards universal weights FOLDER" where an engine mixes the two
    #: (``cae:universal_share``; no comma, which separates a pipeline's stages); None:
    #: fitted here
    weights_used_: str | None = None
    #: the spec of the engine that ran the last clean, for its output line: this one's, or
    #: its universal twin's, whose training parameters are the universal weights'; None
    #: where no clean picked weights (then :attr:`spec` says it)
    spec_used_: str | None = None
    #: canonical joints pinned by the user (``--mapping``): a skeleton-agnostic engine maps
    #: the take with them, a trained one finds the take's up axis with them, and every
    #: engine refuses a take they do not fit (:func:`_checked_clean`)
    humanoid_overrides: Mapping[str, str | None] | None = None
    #: the committed universal variant, loaded once (:meth:`committed_universal`)
    _universal_twin: "Engine | None" = None

    def __init_subclass__(cls, **kwargs) -> None:
        """Every engine's own ``clean`` is wrapped by :func:`_checked_clean`, which holds
        its input and output to :meth:`clean`'s contract in one place; a ``Params`` field
        without a default is a TypeError when the class is made (a registered plugin's
        shows in ``workbench engines``)."""
        super().__init_subclass__(**kwargs)
        if "clean" in cls.__dict__:
            cls.clean = _checked_clean(cls.__dict__["clean"])
        params = cls.__dict__.get("Params")
        if params is not None and dataclasses.is_dataclass(params):  # a spec sets only what it names
            bare = [f.name for f in dataclasses.fields(params) if f.default is f.default_factory is dataclasses.MISSING]
            if bare:
                raise TypeError(
                    f"{cls.__name__}.Params: {', '.join(bare)} without a default; every parameter needs one"
                )

    def __init__(self, params: typing.Any = None) -> None:
        self.params = self.Params() if params is None else params

    @property
    def skeleton_agnostic(self) -> bool:
        """This is a universal variant (its :data:`UNIVERSAL` parameter true): it models the
        canonical humanoid (:mod:`workbench.core.humanoid`), so it trains on takes of
        several skeletons together and cleans any skeleton that maps onto it."""
        return bool(getattr(self.params, UNIVERSAL, False))

    def humanoid(self, skeleton: Skeleton):
        """The :class:`~workbench.core.humanoid.HumanoidMapping` of a body view, with the
        user's :attr:`humanoid_overrides`.

        Raises
        ------
        EngineError
            The skeleton does not map (the message names the joints it lacks).
        """
        from ..core.humanoid import HumanoidError, map_humanoid

        try:
            return map_humanoid(skeleton, self.humanoid_overrides)
        except HumanoidError as err:
            raise EngineError(f"engine {self.spec!r}: {err}") from None

    def up_turn(self, motion: Motion) -> np.ndarray | None:
        """The turn that stands ``motion`` on +Y (:func:`workbench.core.upright.up_turn`),
        its head and feet found with the user's :attr:`humanoid_overrides`; EngineError
        where those do not fit the take."""
        from ..core.humanoid import HumanoidError
        from ..core.upright import up_turn

        try:
            return up_turn(motion, self.humanoid_overrides)
        except HumanoidError as err:
            raise EngineError(f"engine {self.spec!r}: {err}") from None

    # -- parameters -----------------------------------------------------------------
    @classmethod
    def from_options(cls, options: Mapping[str, str]) -> "Engine":
        """Build an engine from ``{"sigma_ms": "58"}``-style text options, with clear errors.

        Parameters
        ----------
        options : Mapping[str, str]
            Parameter names and their values as text, parsed as the field's type (``int``,
            ``float``, ``str``; ``bool`` from ``true``/``false``, ``yes``/``no``,
            ``on``/``off`` or ``1``/``0``). A trainable engine also takes ``weights=DIR``
            (see :attr:`weights_folder`; ``~`` expanded).

        Returns
        -------
        Engine
            An instance of this class; the parameters not named are at their defaults.

        Raises
        ------
        EngineError
            An option names no parameter (the message lists the valid ones), a value does
            not parse as its field's type, or ``Params`` refuses the values.
        """
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
        """The spec string that recreates this engine, e.g. ``gaussian:sigma_ms=58``.

        Returns
        -------
        str
            The engine's name, then after a colon, comma separated, each parameter that
            differs from its default and ``weights=DIR`` when :attr:`weights_folder` is
            set; the name alone when there are none.
        """
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
        """Fit the engine to clean training motions.

        The base class has nothing to fit. A trainable engine overrides it: it checks the
        motions (:meth:`training_motions`), learns its state and records the skeleton
        layout in :attr:`skeleton_signature_`; two seeded fits on the same motions give
        the same state.

        Parameters
        ----------
        motions : Sequence[Motion]
            Clean takes (positional only).

        Returns
        -------
        Engine
            The engine itself.

        Raises
        ------
        EngineError
            In a trainable engine: motions it cannot train on.
        """
        return self

    def clean(self, observation: Observation, /) -> CleanResult:
        """Clean an observation: the one method every engine implements.

        Parameters
        ----------
        observation : Observation
            The corrupted take and its observed mask (F, J), NaN where missing
            (positional only); left unchanged.

        Returns
        -------
        CleanResult
            A complete Motion of the same skeleton, fps and frame count, finite everywhere
            and sharing no memory with the input (its observed samples unchanged where
            ``info.keeps_observed``), and named diagnostics with the frame axis first.

        Raises
        ------
        TypeError
            ``observation`` is not an :class:`Observation`, or the result is not a
            :class:`CleanResult` (every engine's ``clean`` checks, :func:`_checked_clean`).
        NotFittedError
            A trainable engine that is neither fitted nor loaded (:meth:`require_fitted`).
        EngineError
            A skeleton layout other than the fitted one (:meth:`check_skeleton`), input
            the engine cannot use, no sample observed, or a result of another frame
            count, rate or skeleton layout, or not finite (:func:`_checked_clean`).
        NotImplementedError
            In the base class: every engine overrides it.
        """
        raise NotImplementedError

    @property
    def streams(self) -> bool:
        """Whether the engine cleans a live stream, frame by frame (:meth:`stream`)."""
        return type(self).stream is not Engine.stream

    def stream(self, skeleton: Skeleton, fps: float):
        """A live cleaner of takes of ``skeleton`` at ``fps``: ``push`` a frame (D,), get a
        cleaned one back some frames later, ``flush`` the rest. Engines that can override
        it (``ebf``, ``bf``, ``nn``); here an EngineError saying so."""
        raise EngineError(
            f"engine {self.info.name!r} does not stream: it cleans whole takes (`workbench clean`); "
            "ebf, bf and nn stream"
        )

    # -- skeleton checks ------------------------------------------------------------
    def training_motions(self, motions: Sequence[Motion]) -> list[Motion]:
        """``motions`` as a trained engine's ``fit`` takes them: in their body view,
        upright, at the model's rate.

        At least one, all of one skeleton layout; each is shown as the engine sees a
        take (:mod:`workbench.engine.view`): in its body view (a reference node above the
        pelvis collapsed into it), turned upright where it stands on another axis than Y,
        and resampled to :attr:`MODEL_FPS` where the class sets
        one; without it they must share one frame rate. A :attr:`skeleton_agnostic`
        variant takes several skeletons, each of which must map onto the canonical
        humanoid, with every canonical joint unless the class
        :attr:`TRAINS_WITHOUT_OPTIONAL_JOINTS`, resampled to :attr:`MODEL_FPS` or else
        :data:`UNIVERSAL_FPS`.

        Parameters
        ----------
        motions : Sequence[Motion]
            The training takes.

        Returns
        -------
        list of Motion
            ``motions``, in their order, in their body view at the model's rate.

        Raises
        ------
        EngineError
            Saying which rule they break (a take of fewer than 2 frames, with NaN or
            infinite values, or that never moves teaches nothing; skeletons of several
            layouts, or frame rates, where the engine trains on one; a skeleton a
            universal variant cannot map whole; a take a ``--mapping`` file does not
            fit), or what resampling to the model's rate refuses (a take that would grow
            past its frame limit).
        """
        from .view import model_motion, resample

        name = self.info.name
        if not isinstance(motions, Sequence) or isinstance(motions, (str, bytes)):
            raise TypeError(f"engine {name!r} trains on a list of Motion, not a {type(motions).__name__}")
        if not motions:
            raise EngineError(f"engine {name!r}: no training motions")
        if other := next((m for m in motions if not isinstance(m, Motion)), None):
            raise TypeError(
                f"engine {name!r} trains on Motion objects (workbench.io.read_motion), not on {type(other).__name__!r}"
            )
        for i, m in enumerate(motions):
            if (trouble := _teaches_nothing(m)) is not None:
                raise EngineError(
                    f"engine {name!r}: training take {m.name or i} {trouble}; train on complete takes of motion"
                )
        views = [model_motion(m, self.up_turn(m)) for m in motions]
        if self.skeleton_agnostic:  # each in its own body view; every skeleton must map
            for view in {v.skeleton.signature(): v for v in views}.values():
                lacking = self.humanoid(view.skeleton).lacking()
                if lacking and not self.TRAINS_WITHOUT_OPTIONAL_JOINTS:  # a placeholder would train as truth
                    raise EngineError(
                        f"engine {name!r}: a universal variant trains on skeletons with every canonical joint; "
                        f"{view.name or 'a training take'} has none for {', '.join(lacking)} "
                        "(pin them with a mapping file, or leave these takes out)"
                    )
            return [resample(v, self.MODEL_FPS or UNIVERSAL_FPS) for v in views]
        first = views[0]
        for m in views[1:]:
            if m.skeleton.signature() != first.skeleton.signature():
                raise EngineError(
                    f"engine {name!r} trains on one skeleton layout; {first.name or 'motion 0'} "
                    f"and {m.name or 'another'} have different ones"
                    + (f" (`{name}:{UNIVERSAL}=true` trains on several)" if hasattr(self.params, UNIVERSAL) else "")
                )
            if self.MODEL_FPS is None and abs(m.fps - first.fps) > 1e-6:
                raise EngineError(
                    f"engine {name!r}: the training motions mix frame rates ({first.fps:g} and {m.fps:g} fps); "
                    "train on takes of one rate"
                )
        fps = first.fps if self.MODEL_FPS is None else self.MODEL_FPS
        return [resample(v, fps) for v in views]

    def fitted_on(self, motion: Motion) -> None:
        """Record what ``fit`` fitted for: the skeleton layout (:attr:`skeleton_signature_`)
        and frame rate (:attr:`fps_`) of ``motion``, one of :meth:`training_motions`."""
        self.skeleton_signature_ = HUMANOID_SIGNATURE if self.skeleton_agnostic else motion.skeleton.signature()
        self.fps_ = float(motion.fps)
        self.loaded_from_ = None

    def model_view(self, observation: Observation) -> "ModelView":
        """The observation as this fitted engine models it, with the way back.

        Picks the committed weights trained for the take's skeleton when this engine
        runs on committed weights (:meth:`use_weights_for`), checks the skeleton
        (:meth:`check_skeleton`) and shows the take in its body view, upright, at
        :attr:`fps_` (:class:`workbench.engine.view.ModelView`; ``restore`` puts a result
        back).

        Parameters
        ----------
        observation : Observation
            The take to clean.

        Returns
        -------
        ModelView

        Raises
        ------
        NotFittedError
            Neither fitted nor loaded.
        EngineError
            A skeleton it has no weights for, or one no trained engine models.
        """
        from .view import ModelView, model_skeleton

        turn = self.up_turn(observation.motion)
        body = model_skeleton(observation.skeleton, turn)
        self.use_weights_for(body)
        self.require_fitted()
        self.check_skeleton(body)
        self.weights_used_ = self.weights_description()
        self.spec_used_ = self.spec
        return ModelView.of(observation, self.fps_, turn)

    def weights_description(self) -> str | None:
        """ "universal weights FOLDER" or "skeleton-specific weights FOLDER" for the weights
        (FOLDER relative to the working directory where it lies below it); None where the
        engine was fitted here."""
        if self.loaded_from_ is None:
            return None
        folder = self.loaded_from_.resolve()
        shown = folder.relative_to(Path.cwd()) if folder.is_relative_to(Path.cwd()) else folder
        kind = "universal" if self.skeleton_signature_ == HUMANOID_SIGNATURE else "skeleton-specific"
        return f"{kind} weights {shown}"

    def check_skeleton(self, skeleton: Skeleton) -> None:
        """Refuse a skeleton of another layout than the one this engine was fitted for.

        An engine that is not fitted (:attr:`skeleton_signature_` None) accepts any; one
        fitted for the canonical humanoid (:data:`HUMANOID_SIGNATURE`) any that maps onto it.

        Parameters
        ----------
        skeleton : Skeleton
            The skeleton the engine models a take in: its body view
            (:func:`workbench.engine.view.body_skeleton`).

        Raises
        ------
        EngineError
            ``skeleton.signature()`` differs from :attr:`skeleton_signature_`. The message
            says how to train the engine for it.
        """
        if self.skeleton_signature_ == HUMANOID_SIGNATURE:
            self.humanoid(skeleton)
            return
        if self.skeleton_signature_ is not None and skeleton.signature() != self.skeleton_signature_:
            known = self.weights_skeletons_()
            differs = _naming_difference(list(skeleton.names), known)
            raise EngineError(
                f"engine {self.info.name!r} has no weights for this skeleton ({skeleton.n_joints} body joints "
                f"rooted at {skeleton.names[0]!r}{differs}; it has weights for "
                + " and ".join(f"{_describe_signature(sig)} ({name})" for sig, name in known.items())
                + f"). Train it on takes of this skeleton (`workbench train {self.info.name} --data DIR --out "
                f"FOLDER`) and clean with `{self.info.name}:{WEIGHTS_OPTION}=FOLDER`."
            )

    def weights_skeletons_(self) -> dict[str, str]:
        """The skeletons this engine has weights for, each by the name of its weights'
        folder: every committed set where it runs on committed weights, else the weights
        it was fitted or loaded with (empty when it has none)."""
        if self.runs_on_committed_weights:
            return {sig: folder.name for sig, folder in self.committed_weights().items()}
        if self.skeleton_signature_ is None:
            return {}
        return {self.skeleton_signature_: self.loaded_from_.name if self.loaded_from_ else "fitted here"}

    def require_fitted(self) -> None:
        """Refuse a trainable engine that has neither been fitted nor loaded.

        Raises
        ------
        NotFittedError
            ``info.trainable`` and :attr:`skeleton_signature_` is None; the message says
            how to train it or give it weights.
        """
        if self.info.trainable and self.skeleton_signature_ is None:
            raise NotFittedError(
                f"engine {self.spec!r} is not trained: run `workbench train '{self.spec}'` or give it weights"
            )

    # -- fitted state ---------------------------------------------------------------
    def state_arrays(self) -> dict[str, np.ndarray]:
        """Fitted state as named arrays (trainable engines override).

        Returns
        -------
        dict of str to ndarray
            Plain numeric arrays, which :meth:`save` stores in ``weights.npz`` (never
            pickled) and :meth:`load_state_arrays` takes back.

        Raises
        ------
        NotImplementedError
            The engine has no fitted state (the base class).
        """
        raise NotImplementedError(f"engine {self.info.name!r} has no fitted state")

    def load_state_arrays(self, arrays: Mapping[str, np.ndarray], manifest: Mapping) -> None:
        """Take back fitted state saved from :meth:`state_arrays` (trainable engines override).

        :meth:`load` calls it after setting :attr:`params` from the manifest
        (:meth:`weights_params`) and before setting :attr:`skeleton_signature_`.

        Parameters
        ----------
        arrays : Mapping[str, ndarray]
            The arrays of ``weights.npz``, checksum verified.
        manifest : Mapping
            The weights' manifest (``manifest.json``).

        Raises
        ------
        NotImplementedError
            The engine has no fitted state (the base class).
        EngineError
            In an override: arrays missing or of shapes that do not fit the parameters.
        """
        raise NotImplementedError(f"engine {self.info.name!r} has no fitted state")

    def training_record(self) -> dict[str, typing.Any]:
        """What the manifest keeps of the last ``fit`` beyond the parameters.

        Returns
        -------
        dict of str to object
            JSON values, e.g. a torch engine's loss per epoch; empty in the base class.
        """
        return {}

    def save(self, folder: str | Path, extra_manifest: Mapping | None = None) -> Path:
        """Save fitted state and its manifest into ``folder``.

        The manifest holds the engine's name, :attr:`variant`, :attr:`spec`, parameters
        and :attr:`skeleton_signature_`, then :meth:`training_record` and
        ``extra_manifest``; :func:`workbench.engine.weights.save_weights` adds the
        checksum and the code's version. :func:`workbench.training.train_engine` writes
        the training's record (``extra_manifest``: clips, data sets and their licences,
        minutes, test scores).

        Parameters
        ----------
        folder : str or Path
            As in :func:`~workbench.engine.weights.save_weights`, which returns the path.
        extra_manifest : Mapping, optional
            More manifest entries, JSON values; they override entries of the same name.

        Raises
        ------
        NotFittedError
            A trainable engine that is not fitted (and what ``save_weights`` raises).
        """
        from .weights import save_weights

        self.require_fitted()
        manifest = {
            "engine": self.info.name,
            "variant": self.variant,
            "spec": self.spec,
            "params": dataclasses.asdict(self.params),
            "skeleton_signature": self.skeleton_signature_,
            "fps": self.fps_,
            **self.training_record(),
            **(extra_manifest or {}),
        }
        return save_weights(folder, self.state_arrays(), manifest)

    def load(self, folder: str | Path) -> "Engine":
        """Load fitted state saved by :meth:`save`, its trained and training parameters with it.

        The checksum is verified and nothing is unpickled
        (:func:`workbench.engine.weights.load_weights`); then :attr:`params` are set by
        :meth:`weights_params`, the state by :meth:`load_state_arrays`, and
        :attr:`skeleton_signature_` from the manifest.

        Parameters
        ----------
        folder : str or Path
            The folder holding ``manifest.json`` and ``weights.npz``.

        Returns
        -------
        Engine
            The engine itself.

        Raises
        ------
        EngineError
            Missing, corrupt or changed files, weights of another engine, parameters the
            weights refuse (:meth:`weights_params`), or arrays that
            :meth:`load_state_arrays` refuses.
        NotImplementedError
            An engine with no fitted state.
        """
        from .weights import load_weights

        arrays, manifest = load_weights(folder)
        if manifest.get("engine") != self.info.name:
            raise EngineError(
                f"{folder}: these weights are for engine {manifest.get('engine')!r}, not {self.info.name!r}"
            )
        fps = manifest.get("fps")
        if not isinstance(fps, (int, float)) or not fps > 0:
            raise EngineError(
                f"{folder}: the weights' manifest does not say the frame rate they were trained at; "
                "retrain them (`workbench train SPEC --out FOLDER`)"
            )
        asked, self.params = self.params, self.weights_params(manifest, folder)
        try:
            self.load_state_arrays(arrays, manifest)
        except EngineError as err:
            self.params = asked  # all or nothing: as it was before
            raise EngineError(f"{folder}: {err}") from None  # (the message names the folder)
        except BaseException:
            self.params = asked
            raise
        self.skeleton_signature_ = manifest["skeleton_signature"]
        self.fps_ = float(fps)
        self.loaded_from_ = Path(folder)
        return self

    def weights_params(self, manifest: Mapping, folder: str | Path = "") -> typing.Any:
        """This engine's parameters with the trained and training ones of some weights.

        The trained and training parameters take the values ``manifest`` records (one
        missing there, newer than the weights, at its default); the inference ones stay
        as they are. A trained parameter that the spec leaves at its default counts as
        not asked for, so it takes the weights' value.

        Parameters
        ----------
        manifest : Mapping
            A weights manifest; its ``params`` maps parameter names to values.
        folder : str or Path
            Where the weights are, to name in messages.

        Returns
        -------
        Params
            A new instance; :attr:`params` itself is not changed.

        Raises
        ------
        EngineError
            The spec asked for another value of a trained parameter than the weights
            have, or the weights record a parameter this engine lacks (they are from
            another version of it).
        """
        default, saved = self.Params(), dict(manifest.get("params") or {})
        roles = param_roles(default)
        if unknown := self.unknown_params(manifest):
            raise EngineError(
                f"{folder}: these weights record parameters engine {self.info.name!r} does not have "
                f"({', '.join(unknown)}): they are from another version of it; retrain them"
            )
        fixed = {k: saved.get(k, getattr(default, k)) for k, role in roles.items() if role != INFERENCE}
        hints = typing.get_type_hints(type(default))  # the field types, as from_options reads them
        if wrong := [f"{k}={v!r}" for k, v in fixed.items() if not _of_type(v, hints[k])]:
            raise EngineError(
                f"{folder}: these weights record parameters of the wrong kind ({', '.join(wrong)}): they are damaged "
                "or not this engine's; retrain them"
            )
        asked = {k: v for k, v in _of_role(self.params, TRAINED).items() if v != getattr(default, k) and v != fixed[k]}
        if asked:
            raise EngineError(
                f"engine {self.info.name!r}: these weights were trained with "
                f"{ {k: fixed[k] for k in asked} }, not {asked}; train this variant first "
                f"(`workbench train SPEC --out FOLDER`, then add {WEIGHTS_OPTION}=FOLDER to the spec)"
            )
        return dataclasses.replace(self.params, **fixed)

    def unknown_params(self, manifest: Mapping) -> list[str]:
        """The parameters a weights ``manifest`` records that this engine lacks, sorted:
        weights from another version of it where any."""
        return sorted(set(manifest.get("params") or {}) - set(param_roles(self.Params)))

    @property
    def variant(self) -> str:
        """The name of this engine's weights, e.g. ``ebf-bias``, ``ebf-lstm_units96``.

        Returns
        -------
        str
            Its name, then, joined by ``-``, each trained parameter that differs from its
            default: the parameter's name where its value is True, else the name followed
            by the value.
        """
        default = self.Params()
        parts = [self.info.name]
        for name, value in _of_role(self.params, TRAINED).items():
            if value != getattr(default, name):
                parts.append(name if value is True else f"{name}{value}")
        return "-".join(parts)

    def default_weights_dir(self) -> Path:
        """Where the committed weights of this variant live: ``engines/<package>/weights/<variant>/``,
        one folder in it per skeleton, named for the data set they were trained on
        (``cmu/``, ``bandai/``).

        Returns
        -------
        Path
            ``weights/<variant>`` in the folder of the package (the module's folder) that
            defines the engine class, absolute; it need not exist.
        """
        import sys

        module = sys.modules[type(self).__module__]
        return Path(module.__file__).resolve().parent / "weights" / self.variant

    def committed_weights(self) -> dict[str, Path]:
        """The committed weights of this variant, by the skeleton they were trained for.

        Returns
        -------
        dict of str to Path
            Skeleton signature (of the body view) to the folder in
            :meth:`default_weights_dir` whose manifest records it, folders in name order;
            empty for an engine that is not trainable or has none. A manifest that cannot
            be read is left out here and refused with its reason by :meth:`load`.
        """
        import json

        found: dict[str, Path] = {}
        if not self.info.trainable or not self.default_weights_dir().is_dir():
            return found
        for manifest in sorted(self.default_weights_dir().glob("*/manifest.json")):
            try:
                signature = json.loads(manifest.read_text(encoding="utf-8"))["skeleton_signature"]
            except (OSError, ValueError, KeyError, TypeError):
                continue
            found.setdefault(signature, manifest.parent)
        return found

    def load_pretrained(self) -> "Engine":
        """Load the weights of ``weights_folder`` when set, else committed weights, if any.

        Of the committed weights (:meth:`committed_weights`), those in the first folder
        by name are loaded; :meth:`model_view` switches to the ones trained for a take's
        skeleton when it cleans one (:meth:`use_weights_for`).

        Returns
        -------
        Engine
            The engine itself.

        Raises
        ------
        EngineError
            As :meth:`load`.
        """
        if self.weights_folder is not None:
            return self.load(self.weights_folder)
        folders = sorted(self.committed_weights().values())
        if folders:
            self.load(folders[0])
        return self

    def committed_for(self, skeleton: Skeleton) -> Path | None:
        """The committed weights this engine switches to for ``skeleton`` (a body view,
        :func:`workbench.engine.view.body_skeleton`), if it runs on committed weights.

        Returns
        -------
        Path or None
            The folder of :meth:`committed_weights` trained for ``skeleton``; None when
            there is none, or when the weights in use are not committed ones (fitted
            here, or a folder a user named: theirs to choose).
        """
        return self.committed_weights().get(skeleton.signature()) if self.runs_on_committed_weights else None

    @property
    def runs_on_committed_weights(self) -> bool:
        """Whether the weights in use are committed ones the engine chose (not fitted
        here, nor a folder a user named: theirs to choose)."""
        return (
            self.weights_folder is None
            and self.loaded_from_ is not None
            and self.loaded_from_.parent == self.default_weights_dir()
        )

    def use_weights_for(self, skeleton: Skeleton) -> None:
        """Switch to the committed weights trained for ``skeleton`` (a body view) where
        :meth:`committed_for` names some; otherwise change nothing (and
        :meth:`check_skeleton` says what is missing).

        Raises
        ------
        EngineError
            As :meth:`load`.
        """
        if skeleton.signature() != self.skeleton_signature_:
            folder = self.committed_for(skeleton)
            if folder is not None:
                self.load(folder)

    def universal_clean(self, observation: Observation, /, **options) -> CleanResult | None:
        """The :meth:`universal_twin`'s clean of ``observation`` (``options``: the keyword
        arguments of ``clean``), with :attr:`weights_used_` and :attr:`spec_used_` set to its own; None where
        this engine has weights of its own for the take's skeleton (or no twin), so that
        a trained engine's ``clean`` starts with it."""
        from .view import model_skeleton

        twin = self.universal_twin(model_skeleton(observation.skeleton, self.up_turn(observation.motion)))
        if twin is None:
            return None
        result = twin.clean(observation, **options)
        self.weights_used_, self.spec_used_ = twin.weights_used_, twin.spec_used_
        return result

    def universal_twin(self, skeleton: Skeleton) -> "Engine | None":
        """The committed universal variant that cleans ``skeleton`` (a body view) for this
        engine: where this one runs on committed weights, has none for that skeleton, and
        its class has a universal variant with committed weights (loaded once).

        Returns
        -------
        Engine or None
            This engine's parameters with :data:`UNIVERSAL` true, on the universal
            variant's committed weights; None where any condition fails.

        Raises
        ------
        EngineError
            As :meth:`load` (a trained parameter the universal weights do not have).
        """
        if self.skeleton_agnostic or self.weights_folder is not None:
            return None
        if self.loaded_from_ is None or self.loaded_from_.parent != self.default_weights_dir():
            return None
        if skeleton.signature() == self.skeleton_signature_ or skeleton.signature() in self.committed_weights():
            return None  # weights of its own (loaded already: no manifests read on every clean)
        return self.committed_universal()

    def universal_params(self):
        """This engine's parameters for its universal variant: :data:`UNIVERSAL` true.

        Raises
        ------
        ValueError
            The variant has no universal form.
        """
        return dataclasses.replace(self.params, **{UNIVERSAL: True})

    def committed_universal(self) -> "Engine | None":
        """This engine's parameters with :data:`UNIVERSAL` true, on the universal variant's
        committed weights (loaded once); None for a variant that is universal already, or
        whose class has no universal form or none committed.

        Raises
        ------
        EngineError
            As :meth:`load` (a trained parameter the universal weights do not have).
        """
        if self.skeleton_agnostic or not hasattr(self.params, UNIVERSAL):
            return None
        if self._universal_twin is None:
            try:
                params = self.universal_params()
            except ValueError:  # no universal form of this variant (mssa's angle space)
                return None
            twin = type(self)(params)
            twin.humanoid_overrides = self.humanoid_overrides
            folders = sorted(twin.committed_weights().values())
            if not folders:
                return None
            self._universal_twin = twin.load(folders[0])
        return self._universal_twin


def _of_type(value: object, kind: typing.Any) -> bool:
    """Whether a parameter's recorded ``value`` is of its field's type ``kind``, the types
    :func:`_coerce` reads from text: a bool for bool, a whole number for int, a number for
    float, text for str; any value for other types."""
    if kind is bool:
        return isinstance(value, bool)
    if kind in (int, float):
        return isinstance(value, int if kind is int else (int, float)) and not isinstance(value, bool)
    return isinstance(value, str) if kind is str else True


def with_humanoid_overrides(engine: Engine, overrides: Mapping[str, str | None] | None) -> Engine:
    """``engine`` with the user's canonical joints ``overrides`` (a ``--mapping`` file,
    :func:`workbench.io.mapping.read_mapping`), if any, on each of its stages (itself, or
    a pipeline's): :attr:`Engine.humanoid_overrides`. Returns the same engine."""
    if overrides:
        for stage in getattr(engine, "stages", [engine]):
            stage.humanoid_overrides = overrides
    return engine


class Pipeline(Engine):
    """``a>b``: stage a fills gaps, then b cleans the filled motion as fully observed.

    Each stage after the first cleans the motion of the one before as fully observed.
    Diagnostics of the last stage keep their names; earlier ones are prefixed with their
    stage's name and a dot.

    Parameters
    ----------
    stages : Sequence[Engine]
        Two or more engines, in the order they run.

    Attributes
    ----------
    stages : list of Engine
        The stages.
    info : EngineInfo
        Named by the stages' specs joined by ``>``; their tasks together, the last
        stage's space, trainable if any stage is.

    Raises
    ------
    EngineError
        Fewer than two stages.
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
        """The stages' specs joined by ``>``, e.g. ``lerp>gaussian:sigma_ms=58``.

        Returns
        -------
        str
        """
        return ">".join(s.spec for s in self.stages)

    def fit(self, motions: Sequence[Motion], /) -> "Pipeline":
        """Fit every stage on the same clean motions.

        Parameters
        ----------
        motions : Sequence[Motion]
            Clean takes (positional only).

        Returns
        -------
        Pipeline
            The pipeline itself.

        Raises
        ------
        EngineError
            As the stages' ``fit``.
        """
        for s in self.stages:
            s.fit(motions)
        return self

    def clean(self, observation: Observation, /) -> CleanResult:
        """Run the stages in turn, each on the motion of the one before as fully observed.

        Parameters
        ----------
        observation : Observation
            The take the first stage cleans (positional only).

        Returns
        -------
        CleanResult
            The last stage's motion; the diagnostics of every stage, those of the earlier
            ones named ``<stage name>.<name>``. :attr:`weights_used_` lists the stages',
            :attr:`spec_used_` joins theirs.

        Raises
        ------
        EngineError
            As the stages' ``clean`` (:class:`NotFittedError` included).
        """
        diagnostics: dict[str, np.ndarray] = {}
        result = None
        for i, stage in enumerate(self.stages):
            result = stage.clean(observation)
            last = i == len(self.stages) - 1
            for key, value in result.diagnostics.items():
                diagnostics[key if last else f"{stage.info.name}.{key}"] = value
            observation = Observation(result.motion)
        assert result is not None
        # "KIND weights ebd FOLDER, ebf FOLDER"; KIND universal where any stage ran on such (a
        # blended stage's FOLDER reads "FOLDER blended SHARE towards universal weights FOLDER")
        used = [(s.info.name, *s.weights_used_.split(" weights ", 1)) for s in self.stages if s.weights_used_]
        kind = "universal" if any(k == "universal" for _, k, _ in used) else "skeleton-specific"
        self.weights_used_ = f"{kind} weights " + ", ".join(f"{n} {folder}" for n, _, folder in used) if used else None
        self.spec_used_ = ">".join(s.spec_used_ or s.spec for s in self.stages)
        return CleanResult(result.motion, diagnostics)


def _teaches_nothing(motion: Motion) -> str | None:
    """Why a training take teaches nothing (fewer than 2 frames, NaN or infinite values,
    no motion at all), in words; None for one that can be trained on."""
    if motion.n_frames < 2:
        return f"has {motion.n_frames} frames"
    X = motion.channels
    broken = ~np.isfinite(X).all(axis=1)
    if broken.any():
        return f"has missing (NaN) or infinite values in {broken.sum()} frames, first frame {broken.argmax()}"
    return None if np.ptp(X, axis=0).any() else "never moves"


def _signature_joints(signature: str) -> list[str]:
    """The joint names of a skeleton signature (:meth:`Skeleton.signature`), in order."""
    return [part.split("<")[0] for part in signature.split(";") if part and not part.startswith("translated:")]


def _naming_difference(names: list[str], known: Mapping[str, str]) -> str:
    """For a message refusing a skeleton with joints ``names``: how it differs from the
    nearest of the ``known`` weights' skeletons (signature -> folder name), where that is
    one of the same joints (", the joints of its cmu weights with other channels ...")
    or of the same count with up to 3 joints named otherwise; else ""."""
    for signature, folder in known.items():
        if _signature_joints(signature) == names:
            return f", the joints of its {folder} weights with other channels or rotation orders"
    for signature, folder in known.items():
        theirs = _signature_joints(signature)
        renamed = [(ours, other) for ours, other in zip(names, theirs) if ours != other]
        if len(theirs) == len(names) and len(renamed) <= 3:
            return f", the joints of its {folder} weights but " + ", ".join(
                f"{ours!r} where they have {other!r}" for ours, other in renamed
            )
    return ""


def _describe_signature(signature: str) -> str:
    """A skeleton signature in words, for messages: ``31 joints rooted at 'Hips'``."""
    if signature == HUMANOID_SIGNATURE:
        return "the canonical humanoid"
    joints = _signature_joints(signature)
    return f"{len(joints)} joints rooted at {joints[0]!r}" if joints else "an unknown skeleton"
