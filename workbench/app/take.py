"""A take ready to compare, and engine runs on it: the arrays every view draws (no Qt;
the Session, the report and the tests share it).

Units: positions in the take's file unit (``skeleton.unit_cm`` cm each); errors in cm,
root-aligned (:func:`workbench.metrics.joint_position_error_cm`); time in frames at the
motion's fps.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core.motion import Motion, Observation
from ..data.inspection import Inspection, inspect_motion
from ..io import MOTION_SUFFIXES, read_motion
from ..io.mask import observed_take
from ..metrics import body_joints, joint_position_error_cm
from ..render.scene import skeleton_points
from .defaults import DEFAULT_CORRUPTION, DEFAULT_ENGINES


def stage_engines(spec: str) -> list:
    """The engine class of each stage of an engine spec, without making them (raises
    EngineError for a name that is not registered or does not import)."""
    from .. import registry

    return [registry.get(stage.split(":")[0].strip()) for stage in spec.split(">")]


def loadable(spec: str) -> bool:
    """True when every stage of an engine spec names an engine that imports."""
    from ..engine import EngineError

    try:
        stage_engines(spec)
    except EngineError:
        return False
    return True


def default_engines() -> list[str]:
    """The default engines that are registered and load, small ones first."""
    return [spec for spec in DEFAULT_ENGINES if loadable(spec)]


def load_motion(source: str) -> Motion:
    """A catalogue clip id (``cmu/walk/35_31``) or a BVH/AMC path; a T-pose frame 0 is
    dropped from either, as the catalogue does."""
    from ..data import find_clip, without_reference_frame

    path = Path(source).expanduser()
    if not path.exists():
        try:  # a clip id; one with a file's suffix where the take is kept in two formats (kick/11_01.amc)
            clip = find_clip(source)
        except (KeyError, OSError):
            if path.suffix.lower() not in MOTION_SUFFIXES:
                raise
        else:
            return clip.load()
    return without_reference_frame(read_motion(path)).replace(name=path.stem)  # (a missing file: its error)


def sidecar_mask(source: str, motion: Motion) -> np.ndarray | None:
    """The observed mask (F, J) written beside a corrupted BVH by ``workbench corrupt``."""
    from ..io.mask import take_mask

    return take_mask(source, motion.skeleton, motion.n_frames)[0]


@dataclass(frozen=True)
class Track:
    """One skeleton to draw and score: its motion, points (F, J + E, 3) in file units and
    joint errors (F, J) in cm, root-aligned, against a reference: the truth, or on a take
    without one the recording, so that they say how far cleaning moved each joint (None
    without a reference)."""

    motion: Motion
    points: np.ndarray
    errors_cm: np.ndarray | None

    @classmethod
    def of(cls, motion: Motion, reference: Motion | None) -> Track:
        errors = None if reference is None else joint_position_error_cm(reference, motion)
        return cls(motion, skeleton_points(motion), errors)


@dataclass(frozen=True)
class Take:
    """What the user compares engines on. ``truth`` is None for a take shown as recorded
    (corruption ``none``); ``noisy`` is the observation drawn with its gaps bridged;
    ``fill_suspects``: the samples the inspection rules flag as bad data are gaps of the
    observation (:func:`workbench.data.inspection.suspects_missing`)."""

    source: str
    corruption: str
    seed: int
    observation: Observation
    truth: Motion | None
    noisy: Track
    truth_track: Track | None
    fill_suspects: bool = False

    @property
    def motion(self) -> Motion:
        return self.truth if self.truth is not None else self.observation.motion

    @property
    def n_frames(self) -> int:
        return self.observation.n_frames

    @property
    def fps(self) -> float:
        return self.observation.motion.fps

    @property
    def missing(self) -> np.ndarray:
        """(F, J) True where a joint is missing from the observation."""
        return ~self.observation.observed

    @property
    def root(self) -> np.ndarray:
        """(F, 3) the trajectory the camera follows, the body root's (the truth's when
        known)."""
        return (self.truth_track or self.noisy).points[:, self.motion.skeleton.body_root]

    @property
    def error_label(self) -> str:
        """What the joint colours and the error plot measure: error against the truth,
        or how far an engine moved the recording when there is no truth."""
        from ..plots.style import ERROR_LABEL, MOVED_LABEL

        return ERROR_LABEL if self.truth is not None else MOVED_LABEL

    def error_scale_cm(self) -> tuple[float, float]:
        """(0, hi): the joint-error colour scale, hi the noisy errors' 95th percentile
        rounded up to a whole number of cm (5 cm without a truth)."""
        if self.noisy.errors_cm is None:
            return 0.0, 5.0
        body = body_joints(self.motion.skeleton)
        return 0.0, float(max(1.0, np.ceil(np.percentile(self.noisy.errors_cm[:, body], 95))))


def make_take(
    motion: Motion,
    corruption: str = DEFAULT_CORRUPTION,
    seed: int = 0,
    source: str = "",
    observed: np.ndarray | None = None,
    fill_suspects: bool = False,
) -> Take:
    """Corrupt a clean ``motion`` with ``corruption`` and ``seed``; with corruption
    ``none`` it is the observation itself (``observed`` mask (F, J) if known), no truth.
    With ``fill_suspects`` the samples the inspection rules flag as bad data are gaps."""
    from ..corruption import make_case, parse_corruption

    spec = parse_corruption(corruption)
    if spec:
        case = make_case(motion, spec, seed)
        truth, observation = motion, case.observation
    else:
        truth, observation = None, observed_take(source or motion.name, motion, observed)
    if fill_suspects:
        from ..data.inspection import suspects_missing

        observation = suspects_missing(observation)
    truth_track = None if truth is None else Track.of(truth, None)
    noisy = Track.of(observation.bridged(), truth)
    return Take(
        source or motion.name,
        str(spec),
        int(seed),
        observation,
        truth,
        noisy,
        truth_track,
        fill_suspects,
    )


def open_take(source: str, corruption: str = DEFAULT_CORRUPTION, seed: int = 0, fill_suspects: bool = False) -> Take:
    """Load ``source`` (clip id or file) and make its take (:func:`make_take`); a file
    shown as recorded keeps the gaps its mask sidecar lists."""
    from ..corruption import parse_corruption

    motion = load_motion(source)
    observed = None if parse_corruption(corruption) else sidecar_mask(source, motion)
    return make_take(motion, corruption, seed, source, observed, fill_suspects)


@dataclass(frozen=True)
class EngineRun:
    """One engine's result on a take: the cleaned track, its diagnostics (arrays with the
    frame axis first), the time its clean took (s; loading the engine and its weights
    not counted, as in ``workbench clean``) and which weights it used
    (:attr:`workbench.engine.Engine.weights_used_`: "universal weights FOLDER",
    "skeleton-specific weights FOLDER", the latter "blended SHARE towards universal weights
    FOLDER"; None for an engine with none)."""

    spec: str
    track: Track
    diagnostics: Mapping[str, np.ndarray] = field(default_factory=dict)
    seconds: float = 0.0
    weights: str | None = None

    @property
    def weights_kind(self) -> str | None:
        """Which weights, short enough for a pane title: universal ones, the skeleton's
        own, or its own blended with universal ones (``cae:universal_share``): "universal
        weights", "own weights", "own and universal weights"; None for an engine with no
        weights."""
        if not self.weights:
            return None
        if self.weights.startswith("universal"):
            return "universal weights"
        return "own and universal weights" if " towards universal weights " in self.weights else "own weights"

    @property
    def filter_sigma_frames(self) -> np.ndarray | None:
        """(F, C) the filter widths the engine chose, in frames, if it reports them."""
        return self.diagnostics.get("filter_sigma_frames")

    @property
    def robust_weight(self) -> np.ndarray | None:
        """(F, C) the data weight a robust estimator gave every sample (near 0: treated as
        an outlier, 0 where missing), if the engine reports them."""
        return self.diagnostics.get("robust_weight")

    @property
    def raw_positions(self) -> np.ndarray | None:
        """(F, J, 3) a position-space engine's output positions before IK, in file units,
        if the engine reports them."""
        return self.diagnostics.get("raw_positions")


def inspect_take(take: Take) -> Inspection:
    """The rules' suspicious samples of the take as the engines see it (the noisy track,
    its gaps as "missing"): seconds on a 10-minute take, so the app makes it on its worker
    once the take is shown."""
    return inspect_motion(take.noisy.motion, take.observation.observed)


def inspect_runs(take: Take, rules: Inspection, runs: list[EngineRun]) -> Inspection:
    """The take's inspection by the rules (:func:`inspect_take`) with the engines'
    evidence: the samples the robust ones among ``runs`` rejected, and where two or more
    of them disagree."""
    J, unit = take.motion.skeleton.n_joints, take.motion.skeleton.unit_cm
    return rules.with_evidence(
        take.observation.observed,
        [r.robust_weight for r in runs if r.robust_weight is not None],
        [r.track.points[:, :J] * unit for r in runs],
    )


def run_engine(spec: str, take: Take) -> EngineRun:
    """Create the engine ``spec`` and clean the take's observation (raises what the
    engine raises)."""
    from .. import registry

    engine = registry.create(spec)
    t0 = time.perf_counter()
    result = engine.clean(take.observation)
    seconds = time.perf_counter() - t0
    reference = take.truth if take.truth is not None else take.noisy.motion  # else: how far it moved
    return EngineRun(spec, Track.of(result.motion, reference), dict(result.diagnostics), seconds, engine.weights_used_)


def bone_choice(skeleton, selected: tuple[int, ...] = (), n: int = 6) -> list[int]:
    """Child joints of the bones to box-plot: those ending at the selected joints, else
    the ``n`` longest bones of the rest pose (the root chain has none: a moving Hips
    under a reference root is carried, not a bone)."""
    bones = [j for j in range(skeleton.n_joints) if j not in skeleton.root_chain]
    chosen = [j for j in selected if j in bones][:n]
    if chosen:
        return chosen
    lengths = np.linalg.norm(skeleton.offsets[bones], axis=1)
    return sorted(np.asarray(bones, int)[np.argsort(-lengths)[:n]].tolist())  # fewer where the skeleton has fewer


#: lines of a failed engine's message a pane shows (the whole of it is in the Messages list)
NOTE_LINES = 12
NO_TRUTH = "no ground truth:\nthe take is shown as recorded\n(corruption none)"


def scene_panes(take: Take, specs: list[str], runs: Mapping[str, EngineRun | str], compare: bool) -> list:
    """The 3D panes: noisy, one per engine in ``specs`` (its run, "running..." while it
    has none, or its error text) with the truth faded in, and the truth unless
    comparing."""
    import textwrap

    from ..plots.style import TRUTH
    from ..render import Pane

    ghost = take.truth_track.points if take.truth_track else None
    corruption = take.corruption.replace("+", "\n+")  # a line per model: fits a narrow pane
    noisy_title = f"noisy\n{corruption}" if take.truth is not None else "noisy\nas recorded"
    panes = [Pane(noisy_title, take.noisy.points, take.noisy.errors_cm, take.missing)]
    # a failure's lines as wide as a pane: 34 characters where three share the view
    chars = max(12, 102 // (1 + len(specs) + (not compare)))
    for spec in specs:
        run = runs.get(spec)
        title = f"cleaned\n{spec}"
        if isinstance(run, EngineRun):
            title += f"\n{run.weights_kind}" if run.weights_kind else ""
            panes.append(Pane(title, run.track.points, run.track.errors_cm, ghost=ghost))
        else:
            lines = textwrap.wrap(run or "", chars)
            lines = lines if len(lines) <= NOTE_LINES else [*lines[: NOTE_LINES - 1], "... (see Messages)"]
            note = "running..." if run is None else "\n".join(["failed:", *lines])
            panes.append(Pane(title, ghost=ghost, note=note))
    if not compare:
        panes.append(
            Pane("ground truth", note=NO_TRUTH) if ghost is None else Pane("ground truth", ghost, colour=TRUTH)
        )
    return panes
