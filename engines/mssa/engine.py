"""The ``mssa`` engine: example-based robust denoising and gap filling with M-SSA filter
bases (Lou and Chai 2010). See the package docstring for the design."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from functools import cached_property
from typing import Mapping, Sequence

import numpy as np

from workbench.core.channels import unwrap_deg
from workbench.core.kinematics import inverse_kinematics
from workbench.core.motion import Motion, Observation, angle_columns, channel_matrix
from workbench.core.skeleton import Skeleton
from workbench.engine import CleanResult, Engine, EngineError, EngineInfo, trained
from workbench.engine.canonical import CanonicalBody
from workbench.engine.signal import bridge_gaps, rewrap_angles
from workbench.engine.smoothing import ik_reference, measurement_variance, smooth_observed, smoothing_ratio

from .bases import filter_bases, lag_covariance
from .solver import WindowProjector, robust_filter

SPACES = ("angles", "positions")
OUTPUTS = ("motion", "reconstruction")
#: a channel whose spread within training takes is smaller (degrees or file units) is held
CONSTANT_STD = 1e-6
#: normalisation floors: angles in degrees, positions in centimetres
SCALE_FLOOR_DEG = 1.0
SCALE_FLOOR_CM = 1.0


@dataclass(frozen=True)
class SpaceModel:
    """Fitted bases of one space. columns (L,): the modelled channels of that space's
    layout; held: its channels that never vary within a training take (held at the
    take's median); scale (L,): u = (x - take median) / scale; mean (L,): training mean,
    the centre of a channel never observed in a take; bases (L M, K) float32,
    orthonormal columns; spectrum (L M,): every eigenvalue of C_D, largest first."""

    columns: np.ndarray
    held: np.ndarray
    mean: np.ndarray
    scale: np.ndarray
    bases: np.ndarray
    spectrum: np.ndarray

    @cached_property
    def projector(self) -> WindowProjector:
        return WindowProjector(self.bases, self.bases.shape[0] // self.columns.size)

    @property
    def energy_share(self) -> float:
        """Share of the training energy the K kept bases hold."""
        K = self.bases.shape[1]
        return float(self.spectrum[:K].sum() / self.spectrum.sum())


def _ancestors_observed(skeleton: Skeleton, observed: np.ndarray) -> np.ndarray:
    """(F, J) True where a joint's root-relative position is known: every strict
    ancestor's rotation is observed (a joint's own rotation moves only its children)."""
    known = np.ones_like(observed, dtype=bool)
    for j, p in enumerate(skeleton.parents):
        if p >= 0:
            known[:, j] = known[:, p] & observed[:, p]
    return known


def _relative_positions(skeleton: Skeleton, channels: np.ndarray) -> np.ndarray:
    """(F, 3J) joint positions minus the root joint's, in file units, from a finite
    channel matrix (F, 3 + 3J)."""
    F = channels.shape[0]
    P = Motion(skeleton, 1.0, channels[:, :3], channels[:, 3:].reshape(F, -1, 3)).positions
    return (P - P[:, :1]).reshape(F, -1)


def _modelled_positions(relative: np.ndarray, body: CanonicalBody | None) -> np.ndarray:
    """(F, 3K) the positions the bases model, from the take's root-relative positions (F,
    3J, file units; :func:`_relative_positions`): those themselves, or with ``body`` its
    canonical joints' (canonical cm; a joint the take lacks at the root)."""
    if body is None:
        return relative
    F = relative.shape[0]
    return np.nan_to_num(body.positions(relative.reshape(F, -1, 3)), nan=0.0).reshape(F, -1)


def _take_weights(body: CanonicalBody, canonical: np.ndarray, observed: np.ndarray) -> np.ndarray:
    """(F, 3J) robust weights of the take's joint positions from the canonical ones (F,
    63): a mapped joint's are its canonical joint's, the others' 1 where observed."""
    F = observed.shape[0]
    out = np.repeat(observed.astype(float), 3, axis=1).reshape(F, -1, 3)
    joints = np.array(body.mapping.joints)
    c = np.flatnonzero(joints >= 0)
    out[:, joints[c]] = canonical.reshape(F, -1, 3)[:, c]
    return out.reshape(F, -1)


class MSSA(Engine):
    """Robust M-SSA filtering (Lou and Chai 2010): learned spatio-temporal filter bases,
    Welsch data term: IRLS, each majoriser minimised exactly by conjugate gradients
    (``solver=alternating``: the paper's alternating coefficient / motion updates)."""

    @dataclass(frozen=True)
    class Params:
        #: "angles": filter the joint-angle channels; "positions": filter root-relative
        #: joint positions and recover angles by inverse kinematics (their marker mode)
        space: str = "angles"
        #: M, frames per window (the paper's 20)
        window_frames: int = trained(20)
        #: share of the training energy the kept bases hold; sets K (the paper's 0.99)
        energy_kept: float = trained(0.999)
        #: Welsch scale p in normalised units (the channel's within-take training spread)
        welsch_p_std: float = 3.0
        #: lambda, weight of the bases term against the data term (the paper's 0.1)
        prior_weight: float = 3.0
        #: Welsch data term; False: plain least squares (no outlier rejection)
        robust: bool = True
        #: stop when the objective changes by less than this share of its value
        tol_rel_cost: float = 1e-3
        #: most coefficient/motion update rounds
        max_iterations: int = 100
        #: "motion": the filtered motion z of Eq. 11 (the paper's output); "reconstruction":
        #: at each frame the mean of the covering windows' basis reconstructions E c_s
        output: str = "motion"
        #: noise-adaptive data term: estimate every channel's noise std sigma from the
        #: observation (MAD of second differences), weight its samples by 1 / (sigma^2 +
        #: noise_floor^2) and set its Welsch scale to welsch_p_sigma sqrt(sigma^2 +
        #: noise_floor^2); False: the paper's uniform data term with scale welsch_p_std
        adaptive: bool = True
        #: model-error floor of the adaptive noise estimate, normalised units
        noise_floor: float = 0.05
        #: adaptive Welsch scale, in multiples of sqrt(sigma^2 + noise_floor^2)
        welsch_p_sigma: float = 3.0
        #: beta, weight of the per-channel smoothness term (needs solver "cg"; 0: the
        #: paper's objective): mu_l = beta alpha_l lambda_l / 2 with alpha_l the channel's
        #: data weight and lambda_l the smoothing ratio r / q that the ``kalman`` engine
        #: would choose for it (Stein's unbiased risk; r the channel's noise variance), so
        #: beta = 1 adds exactly the prior of that engine's smoother
        smoothness: float = 1.0
        #: lambda of a final refit (needs solver "cg"; 0: none, the paper): once the
        #: robust iterations stop, the motion is solved for once more with their final
        #: Welsch weights fixed and this weight on the bases term. The strong prior_weight
        #: makes outliers stand out; the weaker refit biases the samples kept less
        refit_prior_weight: float = 1.0
        #: the robust iterations start from a running median over this many frames of
        #: the observation (1: from the observation itself, the paper)
        start_median_frames: int = 5
        #: "alternating": the paper's coefficient / motion updates; "cg": exact
        #: minimisation of each IRLS majoriser by conjugate gradients (same objective)
        solver: str = "cg"
        #: space "positions": joints whose aimed children all lie within this many cm
        #: (CMU: the hands and finger bases) keep their observed angles, smoothed by the
        #: kalman smoother, instead of being aimed from the filtered positions (as in
        #: ``cae``); 0: aim every joint
        short_lever_cm: float = 5.0
        #: space "positions": joints whose aimed descendants lie within this many cm keep
        #: their smoothed observed angles where the noise is in the angles (as in
        #: ``cae``; :func:`workbench.engine.smoothing.ik_reference`); 0: none
        angle_lever_cm: float = 30.0
        #: space "positions" only: filter the canonical humanoid's positions (root-relative,
        #: canonical cm; :mod:`workbench.engine.canonical`) instead of the take's joints, so
        #: the bases train on several skeletons together (at
        #: :data:`workbench.engine.base.UNIVERSAL_FPS`) and clean any that maps onto it
        universal: bool = trained(False)

        def __post_init__(self) -> None:
            if self.space not in SPACES:
                raise ValueError(f"space must be 'angles' or 'positions', got {self.space!r}")
            if self.window_frames < 2:
                raise ValueError(f"window_frames must be at least 2, got {self.window_frames}")
            if not 0.0 < self.energy_kept <= 1.0:
                raise ValueError(f"energy_kept must be in (0, 1], got {self.energy_kept}")
            for name in ("welsch_p_std", "prior_weight", "noise_floor", "welsch_p_sigma"):
                value = getattr(self, name)
                if not (math.isfinite(value) and value > 0):
                    raise ValueError(f"{name} must be a positive number, got {value}")
            if self.output not in OUTPUTS:
                raise ValueError(f"output must be 'motion' or 'reconstruction', got {self.output!r}")
            if self.solver not in ("alternating", "cg"):
                raise ValueError(f"solver must be 'alternating' or 'cg', got {self.solver!r}")
            if not (math.isfinite(self.smoothness) and self.smoothness >= 0):
                raise ValueError(f"smoothness must be a number >= 0, got {self.smoothness}")
            if not (math.isfinite(self.refit_prior_weight) and self.refit_prior_weight >= 0):
                raise ValueError(f"refit_prior_weight must be a number >= 0, got {self.refit_prior_weight}")
            if (self.smoothness > 0 or self.refit_prior_weight > 0) and self.solver != "cg":
                raise ValueError(
                    'smoothness > 0 and refit_prior_weight > 0 need solver="cg"; set both to 0 '
                    "for the alternating solver"
                )
            if self.start_median_frames < 1:
                raise ValueError(f"start_median_frames must be at least 1, got {self.start_median_frames}")
            for name in ("short_lever_cm", "angle_lever_cm"):
                if not (math.isfinite(getattr(self, name)) and getattr(self, name) >= 0):
                    raise ValueError(f"{name} must be 0 (off) or a length in cm, got {getattr(self, name)}")
            if self.universal and self.space != "positions":
                raise ValueError("universal bases model positions: write mssa:space=positions,universal=true")
            if not self.tol_rel_cost >= 0 or self.max_iterations < 1:
                raise ValueError("tol_rel_cost must be >= 0 and max_iterations >= 1")

    info = EngineInfo(
        name="mssa",
        summary="example-based robust filtering with M-SSA bases learned from clean motion",
        tasks=frozenset({"denoise", "fill"}),
        trainable=True,
        citation="Lou and Chai 2010, Example-based human motion denoising (IEEE TVCG)",
    )

    def __init__(self, params: "MSSA.Params | None" = None) -> None:
        super().__init__(params)
        self.info = dataclasses.replace(type(self).info, space=self.params.space)
        self.models_: dict[str, SpaceModel] = {}

    # -- training ---------------------------------------------------------------------
    def _training_channels(self, motion: Motion, space: str) -> tuple[np.ndarray, np.ndarray]:
        """(candidate columns, (F, len(columns)) channels) of a clean motion in ``space``."""
        skeleton = motion.skeleton
        if space == "positions":
            rel = _modelled_positions(_relative_positions(skeleton, motion.channels), self._body(skeleton))
            return np.arange(rel.shape[1]), rel
        cols = angle_columns(skeleton)
        return cols, unwrap_deg(motion.channels[:, cols])

    def _fit_space(self, motions: Sequence[Motion], space: str) -> SpaceModel:
        parts = [self._training_channels(m, space) for m in motions]
        candidates = parts[0][0]
        centred = [X - np.median(X, axis=0) for _, X in parts]
        spread = np.sqrt(np.mean(np.square(np.concatenate(centred)), axis=0))
        keep = spread > CONSTANT_STD
        unit_cm = 1.0 if self.params.universal else motions[0].skeleton.unit_cm  # canonical cm
        floor = SCALE_FLOOR_DEG if space == "angles" else SCALE_FLOOR_CM / unit_cm
        scale = np.maximum(spread[keep], floor)
        mean = np.concatenate([X for _, X in parts]).mean(axis=0)[keep]
        normalised = [X[:, keep] / scale for X in centred]
        bases, spectrum = filter_bases(lag_covariance(normalised, self.params.window_frames), self.params.energy_kept)
        return SpaceModel(candidates[keep], candidates[~keep], mean, scale, bases.astype(np.float32), spectrum)

    def fit(self, motions: Sequence[Motion], /) -> "MSSA":
        """Learn the filter bases of both spaces from clean motions of one skeleton layout
        (universal: of the canonical humanoid's positions, from any skeletons that map)."""
        motions = self.training_motions(motions)
        M = self.params.window_frames
        if max(m.n_frames for m in motions) < M:
            raise EngineError(f"mssa: no training motion has the {M} frames a window needs")
        self.models_ = {space: self._fit_space(motions, space) for space in self._spaces}
        self.fitted_on(motions[0])
        return self

    @property
    def _spaces(self) -> tuple[str, ...]:
        """The spaces the weights hold: both, or the positions of universal bases."""
        return ("positions",) if self.params.universal else SPACES

    def _body(self, skeleton: Skeleton) -> CanonicalBody | None:
        """The canonical body universal bases see a take of ``skeleton`` as; None for others."""
        return CanonicalBody(self.humanoid(skeleton)) if self.params.universal else None

    # -- cleaning ---------------------------------------------------------------------
    def clean(self, observation: Observation, /) -> CleanResult:
        """Clean the take in the engine's view of it (:meth:`model_view`: body-rooted, at the
        rate of the weights) and put the result back on the take; in position space, a take
        whose skeleton has no committed bases of its own by the committed universal ones
        (:meth:`Engine.universal_clean`)."""
        if (result := self.universal_clean(observation)) is not None:
            return result
        view = self.model_view(observation)
        return view.restore(self._clean(view.observation))

    def _clean(self, observation: Observation) -> CleanResult:
        skeleton, step = observation.skeleton, observation.capture_step
        model = self.models_[self.params.space]
        mask = observation.channel_observed
        X = bridge_gaps(observation)
        F = X.shape[0]
        body = self._body(skeleton)
        if self.params.space == "angles":
            Y, observed = X, mask
        else:
            relative = _relative_positions(skeleton, X)
            Y = _modelled_positions(relative, body)
            known = _ancestors_observed(skeleton, observation.observed)
            observed = np.repeat(known if body is None else body.known(known), 3, axis=1)

        cols = model.columns
        sub = Y[:, cols]
        seen = observed[:, cols].any(axis=0)
        centre = np.where(seen, np.median(sub, axis=0), model.mean)
        u = np.where(seen, (sub - centre) / model.scale, 0.0)
        del sub
        p = self.params
        seen_at = observed[:, cols]
        sigma2 = measurement_variance(u, seen_at, step=step)
        var = sigma2 + p.noise_floor**2
        weight, welsch = (1.0 / var, p.welsch_p_sigma * np.sqrt(var)) if p.adaptive else (1.0, p.welsch_p_std)
        mu = None
        if p.smoothness > 0:
            mu = 0.5 * p.smoothness * weight * smoothing_ratio(u, sigma2, seen_at.mean(axis=0))
        result = robust_filter(
            u,
            seen_at * weight,
            model.projector,
            p.prior_weight,
            welsch,
            p.robust,
            p.tol_rel_cost,
            p.max_iterations,
            p.solver,
            mu,
            p.refit_prior_weight,
            p.start_median_frames,
        )
        out = np.array(Y)
        filtered = result.z if p.output == "motion" else result.reconstruction
        out[:, cols] = filtered * model.scale + centre
        out[:, model.held] = np.median(Y[:, model.held], axis=0)
        root_track = smooth_observed(X[:, :6], mask[:, :6], step=step)  # the root's position and rotation
        if self.params.space == "angles":
            out[:, :6] = root_track
        weight = observed.astype(float)
        weight[:, cols] = result.weight

        diagnostics = {}
        if self.params.space == "positions":
            root_joint = root_track[:, :3] + skeleton.offsets[0]
            reference, ik = ik_reference(
                skeleton,
                X,
                observation.observed,
                relative.reshape(F, -1, 3),
                self.params.short_lever_cm,
                self.params.angle_lever_cm,
                step=step,
            )
            if body is None:
                world = out.reshape(F, -1, 3) + root_joint[:, None]
                diagnostics["raw_positions"] = world
                root, angles, translations = inverse_kinematics(skeleton, world, reference, **ik)
            else:  # canonical targets; the joints the take has keep their observed weights
                canonical = out.reshape(F, -1, 3) + (root_joint * body.scale)[:, None]
                root, angles, translations = body.solve(canonical, root_track[:, :3], reference, **ik)
                weight = _take_weights(body, weight, observation.observed)
            out = channel_matrix(root, angles, translations)
        rewrap_angles(out, observation, copy=False)  # the input's angle branch (and Euler triples)
        motion = observation.motion.with_channels(out)
        return CleanResult(motion, diagnostics | {"robust_weight": weight})

    # -- fitted state -----------------------------------------------------------------
    def state_arrays(self) -> dict[str, np.ndarray]:
        return {
            f"{space}_{f.name}": getattr(model, f.name)
            for space, model in self.models_.items()
            for f in dataclasses.fields(SpaceModel)
        }

    def load_state_arrays(self, arrays: Mapping[str, np.ndarray], manifest: Mapping) -> None:
        fields = [f.name for f in dataclasses.fields(SpaceModel)]
        keys = {space: {name: f"{space}_{name}" for name in fields} for space in self._spaces}
        missing = sorted(k for names in keys.values() for k in names.values() if k not in arrays)
        if missing:
            raise EngineError(f"mssa: these weights lack {', '.join(missing)} (an older format); retrain them")
        self.models_ = {
            space: SpaceModel(**{name: np.asarray(arrays[key]) for name, key in names.items()})
            for space, names in keys.items()
        }
