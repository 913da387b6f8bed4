"""Cleaning shared by ``cae``, ``cae-vanilla`` and ``holden`` (Kaufmann et al. 2020: §3.1 the motion
image, :mod:`.representation`; §3.3 training, :mod:`.training`; §4.2 tertiary motion blending): the
network completes the image of a take and IK turns it back into angles (the paper stops at positions).

1. FK of the observation (angles in degrees, gaps bridged, unwrapped) gives the image (F, H) of its
   positions (file units), masked where a position is unknown (the root or an ancestor's angles
   missing). Counted as observed: joints that never vary in the training data (their bridge is
   exact); holes of at most ``short_hole_frames`` in a joint's angles (ours: a bridge beats the
   network there, and drop-outs would hide every joint below them); holes of at most
   ``partial_hole_frames`` where the root is observed, if :func:`workbench.engine.smoothing.angles_bridge_holes`
   finds the noise allows (ours: the network was trained on whole frames and whole joints missing).
   Both are bridged along the path of :func:`workbench.engine.smoothing.smooth_and_fill`.
2. The image at the network's rate (the paper's 60 fps; all else at 120), reflected to a multiple of the
   network's ``time_multiple`` (32 frames; ``holden``'s 2), normalised, holes bridged or zeroed (``input_fill``),
   the mask as a second channel, is completed in one pass and resampled back. Its mirror, and for a 120-fps
   network its reversal (:func:`.representation.reverse_time`), are completed in the same batch and averaged
   (ours, ``views``: the network learnt them only roughly); a Gaussian (``output_sigma_frames``) removes ripple.
3. The root's floor track is the observed one, the predicted velocities integrated across its gaps;
   ``raw_positions`` (F, J, 3) is the network's output on it. With ``anchor`` the observed track is
   smoothed first (:func:`anchored_trajectory`: the image is root-relative, so the root's noise would
   enter every row), leaning :data:`SMOOTHER_PATH_SHARE` on the smoother's fill inside a gap.
4. ``anchor`` (ours, default): the network's miss at the known entries (its bottleneck loses a few cm of every
   pose) is smoothed row by row by the constant-velocity smoother, bridged over holes (there fading towards its
   mean over the row's known frames, over ``miss_fade_s``) and added; its noise is the observation's mean-square
   second difference (:func:`workbench.engine.smoothing.measurement_variance`, ``robust=False``: angle noise
   moves positions with heavy tails, which a median misses). Holes of L < ``hole_blend_frames`` frames with the
   root unknown move towards the smoother's fill by 1 - L / ``hole_blend_frames`` (ours: the network was trained
   for long gaps); longer ones towards the linear fill as far as a trial beside them asks (``trial_holes``, ours).
   IK's reference (:func:`workbench.engine.smoothing.ik_reference` with ``anchor``, else the bridged observation)
   gives the twist, the leaves and the angles of joints within ``short_lever_cm`` of all their children (mm of
   error turn a 3-cm lever by tens of degrees); with ``anchor``, under angle noise, also those of joints aimed
   within ``angle_lever_cm`` (feet, chest, arms); the other aimed joints weigh it against their aim by the noise
   in each. ``anchor=false,output_sigma_frames=0``: the paper's output; ``keep_observed``: observed samples come
   back exactly (fills, does not denoise).

Constraints (§4.2): ``clean(..., constraints={joint: (frames (n,), world positions (n, 3))})`` enters them as
known entries (in a first pass's body frame where the root is missing); the network's miss there is added in
full, so they are met as far as the bone lengths allow. Every noise estimate above is measured on the take's
captured frames (a 30-fps take is seen at 120 fps: :attr:`workbench.core.motion.Observation.capture_step`).
History and results: docs/engines/cae.md.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Mapping, Sequence

import numpy as np

from workbench.core.channels import gap_distance, hole_length, interpolate_gaps, known_at
from workbench.core.kinematics import forward_kinematics, joint_positions, local_rotations, short_lever_joints
from workbench.core.motion import Motion, Observation, blended, channel_mask, channel_matrix, position_unknown
from workbench.core.skeleton import Skeleton
from workbench.engine import TRAINED, CleanResult, Engine, EngineError, param_roles, trained, training
from workbench.engine.signal import bridge_gaps, normalized_gaussian, rewrap_angles
from workbench.engine.smoothing import (
    angles_bridge_holes,
    cv_smooth,
    ik_reference,
    measurement_variance,
    smooth_and_fill,
    smoothing_ratio,
)
from workbench.engine.threads import one_blas_thread
from workbench.engine.view import frame_times, resample

from .bodies import CANONICAL_LAYOUT, CanonicalJoints, OwnJoints
from .representation import (
    HEAD_ROWS,
    TAIL_ROWS,
    Layout,
    decode,
    encode,
    image_mask,
    mirror_rows,
    pad_time,
    retime,
    reverse_time,
    trajectory,
    turn_y,
    wrap,
)

#: most image columns (views x padded frames) per network call: bigger calls run slower per
#: column (the 10-minute take's three views: 2.5 s in windows of 3,072 columns, 3.2 s of
#: 10,000, 4.3 s of 16,384; bf16 on AMX), and their activations take memory in proportion
MAX_CALL_COLUMNS = 3072
#: the views' symmetries, (mirrored, reversed), in the order ``views`` takes them
VIEWS = ((False, False), (True, False), (False, True), (True, True))

Constraints = Mapping[int, tuple[Sequence[int], np.ndarray]]
#: with ``anchor``, the smoother's share of the root's path across a gap inside the take: the network drifts
SMOOTHER_PATH_SHARE = 0.75
#: seconds of the take around a long hole and its trial block that a trial completes (``trial_holes``)
TRIAL_CONTEXT_S = 2.0
#: how much nearer a trial's mix must put a joint (or the body) in the hidden stretches than the network's fill alone
TRIAL_MARGIN = 0.15


@dataclass(frozen=True)
class TrainingParams:
    """Training and use, shared by the three engines. Frames of the network's are at
    :attr:`ConvAutoencoderEngine.network_fps_` (60 fps for weights trained now). An epoch
    is ``frames_per_epoch`` frames in windows of ``window_frames`` network frames (a
    multiple of 32); the curriculum raises the mean gap by 10 network frames every
    ``curriculum_epochs`` epochs (10 to 120, then held). Augmentation
    (:class:`.training.WindowSampler`): ``time_scale_pct``, each window played at a
    speed drawn log-uniformly in [1 / (1 + p/100), 1 + p/100]; ``body_scale_pct``, each
    window's body and motion scaled uniformly by a factor in 1 +- p/100; ``pose_copies``,
    each clip also trained on this many times with every upper-body joint angle (joints
    above the root at rest) that varies in the training data offset by a constant drawn
    from N(0, ``pose_jitter_deg``^2) degrees per copy;
    ``mirror``, half the windows mirrored left/right; ``input_noise``, Gaussian noise
    of this standard deviation (normalised units) on the known input entries.
    ``sampling`` ("clips" or "frames") and ``input_fill`` ("linear" or "zero"): see
    :class:`.training.WindowSampler` (pooled skeletons, as a universal variant trains on,
    are drawn equally often each). ``learning_rate`` is held for the first
    ``anneal_from_pct`` per cent of the epochs, then annealed (cosine) to a tenth.
    ``ema_decay``: the weights kept are the exponential moving average
    over the steps with this decay per step (0: the last step's). ``bf16``: bf16 autocast
    (training and inference).
    ``keep_observed``: return observed samples exactly; ``anchor``: anchor the output
    to the observation; ``short_lever_cm``: joints whose children lie closer keep their
    observed angles, 0 for none; ``angle_lever_cm``: with ``anchor``, joints whose aimed
    descendants lie this close keep their smoothed observed angles where the noise is in the
    angles, 0 for none (both: the module docstring); ``views``: how many of
    :data:`VIEWS` (the take, its left/right mirror, the take played backwards, the mirror
    played backwards) are completed and averaged (all: the module docstring; 0: the
    weights' own, :meth:`ConvAutoencoderEngine.views_used`);
    ``short_hole_frames``: holes in a joint's angles up to this long are bridged by the
    constant-velocity smoother and count as observed (0: none); ``partial_hole_frames``:
    so are holes up to this long in frames where the root is observed, where the take's
    noise allows (0: none); ``hole_blend_frames``:
    inside a hole shorter than this the network's fill is blended with the
    constant-velocity smoother's (0: none; all three: the module docstring);
    ``output_sigma_frames``: the network's completion is smoothed over time by a
    Gaussian of this std in network frames before it is used (0: none; the module docstring).
    ``miss_fade_s``: the network's miss bridged across a hole fades towards its
    mean over the row's known frames by exp(-d / this) at d seconds from the nearest
    known frame (0: no fading;
    :meth:`ConvAutoencoderEngine.correction`). ``trial_holes``: with ``anchor``, the
    network's fill of each hole of at least ``hole_blend_frames`` frames where the root is
    unknown is tried against linear interpolation on stretches of the take hidden beside
    it, and each joint moves towards the linear fill where that fills the trial better
    (:meth:`ConvAutoencoderEngine.trial_mix`; not with constraints, which the trial would
    not see); the diagnostic ``network_share`` (F,) is the mean share of the network's fill
    kept over the joints tried, in each frame (1 outside the holes tried).
    ``init_weights``: a weights folder of this engine to train on from (its network and its
    image normalisation, the layout and network rate the same; fine-tuning, or a run
    continued), instead of a fresh network (empty: fresh).
    ``universal``: the image holds the canonical humanoid instead of the take's joints
    (:mod:`.bodies`), so the weights train on several skeletons together and clean any
    that maps onto it; a plain engine with no weights for a take's skeleton cleans it
    with the committed universal weights (:meth:`Engine.universal_twin`).
    ``universal_share``: a take whose skeleton has weights of its own (committed, or
    ``weights=DIR``) is cleaned with them and with the committed universal weights, and the
    two cleans blended, this share the universal's (:func:`workbench.core.motion.blended`);
    twice the cost of a clean. 0: the own weights alone. Not with constraints, which the
    blend would not keep."""

    epochs: int = training(120)
    frames_per_epoch: int = training(100_000)
    window_frames: int = training(256)
    batch_size: int = training(16)
    learning_rate: float = training(1e-3)
    anneal_from_pct: float = training(75.0)
    ema_decay: float = training(0.998)
    curriculum_epochs: int = training(8)
    gap_sigma_frames: float = training(20.0)
    mirror: bool = training(True)
    time_scale_pct: float = training(10.0)
    body_scale_pct: float = training(0.0)
    input_noise: float = training(0.0)
    pose_copies: int = training(0)
    pose_jitter_deg: float = training(0.0)
    input_fill: str = trained("linear")
    universal: bool = trained(False)
    sampling: str = training("clips")
    seed: int = training(0)
    init_weights: str = training("")
    bf16: bool = True
    keep_observed: bool = False
    anchor: bool = True
    short_lever_cm: float = 5.0
    angle_lever_cm: float = 30.0
    views: int = 0
    short_hole_frames: int = 6
    partial_hole_frames: int = 60
    hole_blend_frames: int = 60
    output_sigma_frames: float = 1.5
    miss_fade_s: float = 1.0
    trial_holes: bool = True
    universal_share: float = 0.0

    def __post_init__(self) -> None:
        for name in ("epochs", "frames_per_epoch", "window_frames", "batch_size"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be a whole number of at least 1, got {getattr(self, name)}")
        for name in ("curriculum_epochs", "pose_copies", "seed"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be a whole number of at least 0, got {getattr(self, name)}")
        for name in ("gap_sigma_frames", "time_scale_pct", "body_scale_pct", "input_noise", "pose_jitter_deg"):
            if not (np.isfinite(getattr(self, name)) and getattr(self, name) >= 0):
                raise ValueError(f"{name} must be a number of at least 0, got {getattr(self, name)}")
        if not (np.isfinite(self.learning_rate) and self.learning_rate > 0) or not 0 <= self.ema_decay < 1:
            raise ValueError(
                f"learning_rate must be above 0 and ema_decay from 0 to below 1, got {self.learning_rate} and "
                f"{self.ema_decay}"
            )
        if self.input_fill not in ("zero", "linear"):
            raise ValueError(f"input_fill must be 'zero' or 'linear', got {self.input_fill!r}")
        if self.sampling not in ("frames", "clips"):
            raise ValueError(f"sampling must be 'frames' or 'clips', got {self.sampling!r}")
        if self.views not in range(len(VIEWS) + 1):
            raise ValueError(f"views must be 1 to {len(VIEWS)}, or 0 for the weights' own, got {self.views}")
        for name in ("short_hole_frames", "partial_hole_frames", "hole_blend_frames"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be 0 (off) or a number of frames, got {getattr(self, name)}")
        if not 0 <= self.anneal_from_pct <= 100:
            raise ValueError(f"anneal_from_pct must be 0 to 100 (per cent of the epochs), got {self.anneal_from_pct}")
        for name in ("short_lever_cm", "angle_lever_cm"):
            if not (np.isfinite(getattr(self, name)) and getattr(self, name) >= 0):
                raise ValueError(f"{name} must be 0 (off) or a positive length in cm, got {getattr(self, name)}")
        if not (np.isfinite(self.output_sigma_frames) and self.output_sigma_frames >= 0):
            raise ValueError(
                f"output_sigma_frames must be 0 (off) or a positive number of frames, got {self.output_sigma_frames}"
            )
        if not (np.isfinite(self.miss_fade_s) and self.miss_fade_s >= 0):
            raise ValueError(f"miss_fade_s must be 0 (off) or a positive time in seconds, got {self.miss_fade_s}")
        if not 0 <= self.universal_share <= 1:
            raise ValueError(f"universal_share must be 0 (off) to 1, got {self.universal_share}")
        if self.universal and self.universal_share:
            raise ValueError("universal_share blends a skeleton's own weights with the universal ones, not universal's")


class ConvAutoencoderEngine(Engine):
    """Base of the motion-image autoencoders; subclasses set ``info``, ``Params`` and
    :meth:`build_network`."""

    Params = TrainingParams
    #: windows, pooling levels and gap lengths are counted in frames, and the network's
    #: time resolution is its pooling's: at 30 fps a 1 s gap fills no better than lerp
    #: (0.96 x lerp, the studio-data issue), at 120 fps, resampled, as on CMU (0.57). So
    #: it trains and runs at 120 fps, whatever the takes' rate.
    MODEL_FPS = 120.0
    #: the rate (fps) the network of weights trained now sees the motion at, the paper's:
    #: a window of 256 frames spans 4.3 s and the curriculum's gaps reach 2 s (at 120 fps:
    #: 2.1 and 1 s, shorter than the 2-s gaps it is asked to fill). Every other stage
    #: stays at :attr:`MODEL_FPS`, so no captured frame is dropped (a model view at 60 fps
    #: denoised CMU takes 17 % worse). Bandai validation, the pooled model, 120 epochs,
    #: gap_mpjpe_cm: ``block:1s`` 2.496 -> 2.305, ``block:2s`` 4.213 -> 3.496
    #: (docs/universal.md, *The network at 60 fps*).
    NETWORK_FPS = 60.0
    #: the rate (fps) the loaded or fitted network sees the motion at (weights saved
    #: before it was recorded: :attr:`fps_`)
    network_fps_: float | None = None
    #: a skeleton without toes (or another optional canonical joint) trains the universal
    #: network on the rows it has: those rows are never known in its windows and out of
    #: the loss, as at inference, where the network fills them and they are dropped
    TRAINS_WITHOUT_OPTIONAL_JOINTS = True
    QUICK_FIT = {
        "epochs": "1",
        "frames_per_epoch": "512",
        "window_frames": "64",
        "batch_size": "4",
        "time_scale_pct": "0",
    }

    # -- the network ----------------------------------------------------------------
    def build_network(self, n_rows: int):
        """A fresh network for images of ``n_rows`` rows (torch module)."""
        raise NotImplementedError

    # -- training -------------------------------------------------------------------
    def fit(self, motions: Sequence[Motion], /) -> "ConvAutoencoderEngine":
        """Train on clean motions of one skeleton layout (the training split); a universal
        variant on those of any skeletons that map onto the canonical humanoid."""
        from workbench.engine.torch_support import reproducible_training

        motions = self.training_motions(motions)
        with reproducible_training(self.params.seed):
            self._train(motions)
        return self

    def _train(self, motions: Sequence[Motion]) -> None:
        """Build the network and train it on ``motions``; sets the fitted state."""
        from .training import WindowSampler, image_units, train

        p = self.params
        layout = CANONICAL_LAYOUT if p.universal else Layout.from_skeleton(motions[0].skeleton)
        net = self.build_network(layout.n_rows)
        self.started_from_ = None
        units = self._start_from(p.init_weights, net, layout) if p.init_weights else None
        first = motions[0]  # at the model's rate, which the fitted engine runs at
        motions = [resample(m, self.NETWORK_FPS) for m in motions]  # windows and gaps in network frames
        if p.window_frames % net.time_multiple:
            raise EngineError(f"window_frames must be a multiple of {net.time_multiple}, got {p.window_frames}")
        images, groups, present = [], [], []
        constant, maskable = np.zeros(0, int), np.arange(1, layout.n_joints)
        rng = np.random.default_rng(p.seed)
        for group, motions_of_one in enumerate(_by_skeleton(motions)):
            skeleton = motions_of_one[0].skeleton
            imaging = self.imaging(skeleton, layout)
            rows = image_mask(layout, imaging.known(np.ones((1, skeleton.n_joints), bool)))[0]  # (H,) it has
            varies = np.concatenate([m.angles_deg for m in motions_of_one]).std(axis=0) > 1e-9  # (J, 3) per angle
            varies[0] = False
            if not p.universal:  # joints that never move are always known; the others can go missing
                constant = np.flatnonzero(~varies.any(axis=1))
                constant = constant[constant > 0]
                maskable = np.array(
                    [j for j in range(1, skeleton.n_joints) if j not in constant and skeleton.has_rotation[j]]
                )
            rest = np.zeros(skeleton.n_joints)  # height above the root in the rest pose
            for j, parent in enumerate(skeleton.parents):
                rest[j] = rest[parent] + skeleton.offsets[j, 1] if parent >= 0 else 0.0
            jitter = varies & (rest > 0)[:, None]  # upper-body angles: the feet keep their contacts
            for m in motions_of_one:
                for copy in range(1 + p.pose_copies):
                    angles = m.angles_deg.copy()
                    if copy:  # the same offsets in every frame: other, still smooth poses
                        angles += rng.normal(0.0, p.pose_jitter_deg, jitter.shape) * jitter
                    P, R = forward_kinematics(skeleton, m.root_positions, angles)
                    P = imaging.positions(P)
                    images.append(encode(layout, P, imaging.heading(P, R[:, 0])))
                    groups.append(group)
                    present.append(rows)
        mirror = mirror_rows(layout, imaging.names) if p.mirror else None
        if units is None:
            units = image_units(images, present, mirror)
        mean, std = units
        sampler = WindowSampler(
            images,
            mean,
            std,
            layout,
            mirror,
            maskable,
            p.window_frames,
            p.gap_sigma_frames,
            p.time_scale_pct,
            p.body_scale_pct,
            p.input_noise,
            p.input_fill,
            p.sampling,
            rng,
            groups,
            present,
        )
        batches = max(1, p.frames_per_epoch // (p.batch_size * p.window_frames))
        log = train(
            net,
            sampler,
            p.epochs,
            batches,
            p.batch_size,
            p.learning_rate,
            p.anneal_from_pct,
            p.curriculum_epochs,
            p.ema_decay,
            desc=f"train {self.info.name}",
        )
        self.net_, self.layout_, self.constant_ = net, layout, constant
        self.mean_, self.std_, self.loss_log_ = mean, std, np.array(log)
        self.fitted_on(first)
        self.network_fps_ = self.NETWORK_FPS

    def _start_from(self, folder: str, net, layout: Layout) -> tuple[np.ndarray, np.ndarray]:
        """Load the network of the weights in ``folder`` into ``net`` (the fresh network of
        ``layout``) and return their image mean and std (H,): a network trained on goes on
        in the units it knows. Sets :attr:`started_from_`, the record of those weights
        that the new manifest keeps (their checksum, spec and training: clips, data sets
        and licences, which the new weights inherit).

        Raises
        ------
        EngineError
            Files :func:`~workbench.engine.weights.load_weights` refuses, weights of another
            engine or another version of it (parameters it lacks), or with another value of
            a trained parameter (``input_fill``, ``universal``, the network's widths), image
            layout, network rate or shape.
        """
        from workbench.engine.torch_support import load_module_arrays
        from workbench.engine.weights import load_weights

        arrays, manifest = load_weights(folder)
        rate = np.asarray(arrays.get("network.fps", manifest.get("fps", np.nan)), float)
        rate, problem = rate.item() if rate.size == 1 else np.nan, None
        same_rows = all(
            np.array_equal(arrays.get(f"layout.{k}"), getattr(layout, k)) for k in ("joints", "source", "parents")
        )
        saved, default = dict(manifest.get("params") or {}), self.Params()
        trained_with = {k: saved.get(k, getattr(default, k)) for k, r in param_roles(default).items() if r == TRAINED}
        differ = {k: v for k, v in trained_with.items() if v != getattr(self.params, k)}
        unknown = self.unknown_params(manifest)
        if manifest.get("engine") != self.info.name:
            problem = f"they are weights of engine {manifest.get('engine')!r}"
        elif unknown:
            problem = f"they record parameters this engine lacks ({', '.join(unknown)}): from another version of it"
        elif differ:
            problem = "they were trained with " + ", ".join(
                f"{k}={v} (asked: {getattr(self.params, k)})" for k, v in differ.items()
            )
        elif not same_rows:
            problem = "their image holds other joints (another skeleton, or universal against not)"
        elif rate != self.NETWORK_FPS:
            problem = f"their network runs at {rate:g} fps, not {self.NETWORK_FPS:g}"
        if problem is None:
            try:
                load_module_arrays(net, arrays, "net.")
            except EngineError as err:
                problem = str(err)
        if problem is not None:
            raise EngineError(
                f"engine {self.info.name!r}: cannot train on from {folder}: {problem}; "
                "name weights trained with the same engine, skeleton and trained parameters"
            )
        self.started_from_ = {k: manifest.get(k) for k in ("sha256", "spec", "training")}
        return arrays["image.mean"].astype(float), arrays["image.std"].astype(float)

    # -- fitted state ---------------------------------------------------------------
    def training_record(self) -> dict[str, object]:
        """The loss of every epoch; for a network trained on from other weights, their
        record (``started_from``, :meth:`_start_from`)."""
        record = {"loss_per_epoch": [round(float(x), 5) for x in self.loss_log_]}
        return record if self.started_from_ is None else {**record, "started_from": self.started_from_}

    def state_arrays(self) -> dict[str, np.ndarray]:
        from workbench.engine.torch_support import module_arrays

        return {
            **module_arrays(self.net_, "net."),
            "image.mean": self.mean_.astype(np.float32),
            "image.std": self.std_.astype(np.float32),
            "layout.joints": np.array(self.layout_.joints),
            "layout.source": np.array(self.layout_.source),
            "layout.parents": np.array(self.layout_.parents),
            "constant_joints": np.array(self.constant_),
            "training.loss_per_epoch": self.loss_log_.astype(np.float32),
            "network.fps": np.array(self.network_fps_),
        }

    def load_state_arrays(self, arrays: Mapping[str, np.ndarray], manifest: Mapping) -> None:
        from workbench.engine.torch_support import load_module_arrays

        self.layout_ = Layout(
            tuple(int(j) for j in arrays["layout.joints"]),
            tuple(int(j) for j in arrays["layout.source"]),
            tuple(int(j) for j in arrays["layout.parents"]),
        )
        self.net_ = self.build_network(self.layout_.n_rows)
        load_module_arrays(self.net_, arrays, "net.")
        self.net_.eval()
        self.mean_ = arrays["image.mean"].astype(float)
        self.std_ = arrays["image.std"].astype(float)
        self.constant_ = arrays["constant_joints"].astype(int)
        self.loss_log_ = arrays["training.loss_per_epoch"].astype(float)
        self.started_from_ = manifest.get("started_from")
        rate = np.asarray(arrays.get("network.fps", manifest["fps"]), float)
        if rate.shape != () or not (np.isfinite(rate) and rate > 0):
            raise EngineError(
                f"engine {self.info.name!r}: the weights' network.fps ({rate}) is not a frame rate; "
                "retrain them (`workbench train SPEC --out FOLDER`)"
            )
        self.network_fps_ = float(rate)

    # -- cleaning -------------------------------------------------------------------
    def complete(
        self, image: np.ndarray, mask: np.ndarray, mirror: tuple[np.ndarray, np.ndarray] | None = None, views: int = 1
    ) -> np.ndarray:
        """The network's completion (F, H) of a raw image (F, H) at :attr:`fps_` known where
        ``mask``: the mean of the completions of the first ``views`` of :data:`VIEWS`, each
        mapped back; the image resampled to :attr:`network_fps_` for them and the mean back
        (:func:`.representation.retime`; an entry known there where both frames around it
        are); at most about :data:`MAX_CALL_COLUMNS` columns a network call
        (``ImageNet.predict``). ``mirror``: the row permutation and signs of
        :func:`.representation.mirror_rows`, needed for the mirrored views."""
        import torch

        from workbench.engine.torch_support import default_threads, torch_threads

        from .training import network_input

        if views > 1 and mirror is None:
            raise ValueError("the mirrored views need the mirror's rows and signs (mirror_rows)")
        n_frames, times = image.shape[0], None  # times: the network's frames in the image's
        if n_frames >= 2 and self.network_fps_ != self.fps_:
            times = frame_times(n_frames, self.fps_, self.network_fps_)
            image, mask = retime(image, times), known_at(mask, times)
        F, H = image.shape
        perm, sign = mirror if mirror is not None else (None, None)
        chosen = VIEWS[:views]
        frames = -(-F // self.net_.time_multiple) * self.net_.time_multiple
        x = torch.empty((len(chosen), 2, H, frames))
        masks = []  # each view's mask, to map its completion back
        for b, (mirrored, reversed_) in enumerate(chosen):  # a view at a time: a 10-minute take's is 35 MB
            v, m = (image[:, perm] * sign, mask[:, perm]) if mirrored else (image, mask)
            v, m = reverse_time(v, m) if reversed_ else (v, m)
            masks.append(m)
            v, m = pad_time(v, m, frames)
            x[b] = network_input(((v - self.mean_) / self.std_)[None], m[None], self.params.input_fill)[0]
        with torch_threads(default_threads()), torch.inference_mode():
            Y = self.net_.predict(x, MAX_CALL_COLUMNS)
        del x
        total = np.zeros_like(image)
        for y, m, (mirrored, reversed_) in zip(Y, masks, chosen):
            y = y[:, :F].T * self.std_ + self.mean_
            if reversed_:
                y = reverse_time(y, m)[0]
            total += y[:, perm] * sign if mirrored else y
        total /= len(chosen)
        if times is not None:
            total = retime(total, np.interp(np.arange(n_frames), times, np.arange(F)))
        return total

    @one_blas_thread
    def clean(self, observation: Observation, /, *, constraints: Constraints | None = None) -> CleanResult:
        """Fill the gaps of (and denoise) ``observation``; ``constraints`` maps a joint index
        to (frames (n,), world positions (n, 3) in file units) that guide the network.
        The take is cleaned in the engine's view of it (:meth:`model_view`: body-rooted,
        at the rate of the weights) and the result put back on it; a take whose skeleton
        has no committed weights of its own by the universal variant's committed weights
        (:meth:`Engine.universal_twin`; :attr:`weights_used_` says which were used). With
        ``universal_share`` and no constraints the clean on weights of the skeleton's own is
        blended that far towards the universal variant's clean of the take
        (:func:`workbench.core.motion.blended`; :meth:`Engine.committed_universal`); an
        EngineError where no universal weights are committed for its trained parameters."""
        if (result := self.universal_clean(observation, constraints=constraints)) is not None:  # no own weights
            return result
        view = self.model_view(observation)
        guides = constraints and {view.joint(j): (view.frames(f), P) for j, (f, P) in constraints.items()}
        result = view.restore(self._clean(view.observation, guides), self.params.keep_observed)
        share = self.params.universal_share
        if share and not constraints:
            if (partner := self.committed_universal()) is None:
                raise EngineError(
                    f"universal_share blends with the committed weights of {self.info.name}:universal=true and these "
                    "trained parameters, and there are none: leave out universal_share"
                )
            own = self.weights_used_ or "skeleton-specific weights fitted in this process"
            other = partner.clean(observation)
            result = CleanResult(blended(result.motion, other.motion, share), result.diagnostics)
            self.weights_used_ = f"{own} blended {share:g} towards {partner.weights_used_}"
        return result

    def universal_params(self) -> TrainingParams:
        """This engine's parameters with ``universal`` true and no ``universal_share`` (a
        universal variant has no weights of a skeleton's own to blend)."""
        return replace(self.params, universal=True, universal_share=0.0)

    def imaging(self, skeleton: Skeleton, layout: Layout) -> OwnJoints | CanonicalJoints:
        """The body the image of a take of ``skeleton`` (a body view) holds (:mod:`.bodies`):
        the canonical humanoid for a universal variant, else the take's own joints in
        ``layout``.

        Raises
        ------
        EngineError
            A universal variant and a skeleton that does not map onto the humanoid.
        """
        return CanonicalJoints(self.humanoid(skeleton)) if self.params.universal else OwnJoints(skeleton, layout)

    def _clean(self, observation: Observation, constraints: Constraints | None) -> CleanResult:
        skeleton, step = observation.skeleton, observation.capture_step
        layout = self.layout_
        imaging = self.imaging(skeleton, layout)
        linear = bridge_gaps(observation)
        P = joint_positions(skeleton, linear[:, :3], linear[:, 3:].reshape(observation.n_frames, -1, 3))
        holes = self.bridged_holes(observation, linear, P)
        seen, bridge = observation.channel_observed, channel_mask(holes, skeleton)
        # smoothed once: the holes' bridges and (with anchor) the IK reference
        smoothed = smooth_and_fill(linear, seen, step=step) if self.params.anchor or holes.any() else None
        bridged = np.where(bridge, smoothed, linear) if holes.any() else linear
        del linear
        ref = bridged[:, 3:].reshape(observation.n_frames, -1, 3)
        if holes.any():  # FK is frame by frame: only the bridged frames move
            moved = np.flatnonzero(bridge.any(axis=1))
            P[moved] = joint_positions(skeleton, bridged[moved, :3], ref[moved])
        image_positions = imaging.positions(P)
        theta = imaging.heading(image_positions, local_rotations(skeleton, ref, [0])[:, 0])
        ik_angles, ik_options = self._ik_reference(observation, bridged, smoothed, P, ref)
        ik_root = bridged[:, :3].copy()
        del bridged, smoothed, ref  # done with: a long take's are 50 MB each
        ground = image_positions[:, 0] * np.array([1.0, 0.0, 1.0])
        observed = observation.observed | holes
        observed[:, self.constant_] = True
        known = imaging.known(~position_unknown(observed, skeleton.parents))
        own_frame = theta, ground  # the bridged take's heading and floor point: lerp's across a gap
        if self.params.anchor:
            ground, theta = anchored_trajectory(ground, theta, known[:, 0], step)
        image, mask = encode(layout, image_positions, theta, ground), image_mask(layout, known)
        views = self.views_used()
        mirror = mirror_rows(layout, imaging.names) if views > 1 else None
        trialled = self.params.trial_holes and self.params.anchor and not constraints
        trial = None
        if trialled:
            trial = self.trial_mix(observation, imaging, image, mask, image_positions, own_frame, mirror, views)
        del own_frame
        net_out = self.complete(image, mask, mirror, views)
        out = self.low_pass(net_out)
        path, theta = trajectory(out, known[:, 0], ground, theta)
        if self.params.anchor:  # across a gap inside the take: mostly the smoother's path
            share = SMOOTHER_PATH_SHARE
            ground = np.where(np.isinf(hole_length(~known[:, :1])), path, (1.0 - share) * path + share * ground)
        else:
            ground = path
        exact = mask.copy() if self.params.keep_observed else np.zeros_like(mask)
        if constraints:  # a second pass, on the first one's trajectory
            image, mask, constrained = self._constrain(imaging, image, mask, constraints, ground, theta)
            exact |= constrained
            net_out = self.complete(image, mask, mirror, views)
            out = self.low_pass(net_out)
        raw = decode(layout, net_out, ground, theta)
        raw_positions = imaging.targets(raw, P)  # the take's joints where the network put them
        del P, image_positions
        out = self.anchored(image, mask, out, exact, step)
        diagnostics = {"raw_positions": raw_positions}
        if trialled:
            diagnostics["network_share"] = np.ones(image.shape[0])
        if trial is not None:
            out, theta = trial.applied(out, theta)
            diagnostics["network_share"][trial.holes] = trial.network_share
        target = raw if out is net_out else decode(layout, out, ground, theta)  # as the paper: once
        del image, net_out, out
        root, angles, translations = imaging.solve(target, ik_root, ik_angles, **ik_options)
        del target, ik_angles
        channels = rewrap_angles(channel_matrix(root, angles, translations), observation, copy=False)
        del angles
        if self.params.keep_observed:
            given = observation.channel_observed
            channels[given] = observation.motion.channels[given]
        return CleanResult(observation.motion.with_channels(channels), diagnostics)

    def anchored(
        self, image: np.ndarray, mask: np.ndarray, out: np.ndarray, exact: np.ndarray, step: float
    ) -> np.ndarray:
        """The smoothed completion ``out`` (F, H) of ``image`` known where ``mask``, with the
        :meth:`correction` added and short holes blended (:meth:`blend_short_holes`) where
        ``anchor`` asks for them; ``out`` itself where nothing is added."""
        if exact.any() or self.params.anchor:
            out = out + self.correction(image, mask, out, exact, step)
            if self.params.anchor and self.params.hole_blend_frames:
                out = self.blend_short_holes(out, mask, step)
        return out

    def trial_mix(
        self,
        observation: Observation,
        imaging: OwnJoints | CanonicalJoints,
        image: np.ndarray,
        mask: np.ndarray,
        image_positions: np.ndarray,
        own_frame: tuple[np.ndarray, np.ndarray],
        mirror: tuple[np.ndarray, np.ndarray] | None,
        views: int,
    ) -> "TrialMix | None":
        """The mix of the network's and the linear fill that trials ask for in a take's long
        holes, those where the root is unknown for at least ``hole_blend_frames`` frames
        inside the take; None where no long hole has room for a trial. Beside each long hole
        observed stretches as long are hidden (:func:`trial_blocks`), the take around them
        (:data:`TRIAL_CONTEXT_S` each side) completed again as a clean completes it, and the
        hidden stretches filled linearly (:meth:`linear_image`). A joint's share of the
        network's fill is the one of 0, 0.1, ..., 1 whose mix puts it nearest its known
        positions there (mean distance in the image, each pose on its own floor point and
        heading), where that beats the network's alone by :data:`TRIAL_MARGIN`, else 1; the
        hips' height and the heading take the share chosen so for all the joints tried
        together. The mix applies to the holes that had a trial of their own.
        ``image_positions`` (F, J, 3), J the layout's joints, and ``own_frame`` (headings
        (F,), floor points (F, 3)): the bridged take's, so linearly interpolated across the
        long holes. The root's floor path across a hole stays the network's and the
        smoother's (:data:`SMOOTHER_PATH_SHARE`): the mix is of the pose and the heading. Ours:
        ``docs/engines/cae.md``, *Trial holes*."""
        F, K = image.shape[0], (image.shape[1] - HEAD_ROWS - TAIL_ROWS) // 3
        root_known = mask[:, 0]
        length = hole_length(~root_known[:, None])[:, 0]
        long_holes = ~root_known & (length >= max(self.params.hole_blend_frames, 1)) & np.isfinite(length)
        blocks = trial_blocks(long_holes, root_known)
        if not blocks:
            return None
        context = round(TRIAL_CONTEXT_S * self.fps_)
        rows = slice(HEAD_ROWS, HEAD_ROWS + 3 * K)
        shares = np.linspace(0.0, 1.0, 11)
        distance = np.zeros((len(shares), K))  # summed over the hidden stretches' known positions
        tried, holes = np.zeros(K, bool), np.zeros(F, bool)
        for (a, b), (s, e) in blocks:
            holes[a:b] = True
            lo, hi = max(min(a, s) - context, 0), min(max(b, e) + context, F)
            hidden = np.zeros((hi - lo, 1), bool)
            hidden[s - lo : e - lo] = True
            crop = slice(lo, hi)
            tmask = mask[crop] & image_mask(self.layout_, np.broadcast_to(~hidden, (hi - lo, self.layout_.n_joints)))
            exact = tmask if self.params.keep_observed else np.zeros_like(tmask)
            completed = self.low_pass(self.complete(image[crop], tmask, mirror, views))
            fill = self.anchored(image[crop], tmask, completed, exact, observation.capture_step)[s - lo : e - lo]
            part = Observation(observation.motion.slice(lo, hi), observation.observed[crop], observation.capture_step)
            linear = self.linear_image(part, hidden[:, 0], imaging)[s - lo : e - lo, rows].reshape(e - s, K, 3)
            truth = image[s:e, rows].reshape(e - s, K, 3)
            known = mask[s:e, rows].reshape(e - s, K, 3).all(axis=2)
            net = fill[:, rows].reshape(e - s, K, 3)
            tried |= known.any(axis=0)
            for i, share in enumerate(shares):
                distance[i] += np.where(known, np.linalg.norm(linear + share * (net - linear) - truth, axis=2), 0).sum(
                    0
                )
        if not tried.any():
            return None

        def chosen(d: np.ndarray) -> np.ndarray:  # d (shares, n) -> (n,)
            best = np.argmin(d, axis=0)
            return np.where(d[best, np.arange(d.shape[1])] < (1.0 - TRIAL_MARGIN) * d[-1], shares[best], 1.0)

        whole = float(chosen(distance.sum(axis=1, keepdims=True))[0])
        joint_shares = chosen(distance)
        theta, ground = own_frame[0][holes], own_frame[1][holes]
        linear = encode(self.layout_, image_positions[holes], theta, ground)[:, : rows.stop]
        return TrialMix(
            holes,
            np.r_[np.full(HEAD_ROWS, whole), np.repeat(joint_shares, 3)],
            whole,
            linear,
            theta,
            float(joint_shares[tried].mean()),
        )

    def linear_image(
        self, observation: Observation, hidden: np.ndarray, imaging: OwnJoints | CanonicalJoints
    ) -> np.ndarray:
        """The image rows (F, H) of ``observation`` with its ``hidden`` frames (F,) missing
        too and the angles interpolated linearly across every gap (:func:`bridge_gaps`),
        each frame on the bridged take's own floor point and heading (the velocity rows only
        as :func:`.representation.encode` gives them)."""
        observed = observation.observed & ~hidden[:, None]
        channels = observation.motion.channels.copy()
        channels[hidden] = np.nan
        seen = Observation(observation.motion.with_channels(channels), observed, observation.capture_step)
        linear = bridge_gaps(seen)
        F, skeleton = observation.n_frames, observation.skeleton
        angles = linear[:, 3:].reshape(F, -1, 3)
        positions = imaging.positions(joint_positions(skeleton, linear[:, :3], angles))
        theta = imaging.heading(positions, local_rotations(skeleton, angles, [0])[:, 0])
        return encode(self.layout_, positions, theta, positions[:, 0] * np.array([1.0, 0.0, 1.0]))

    def bridged_holes(self, observation: Observation, channels: np.ndarray, positions: np.ndarray) -> np.ndarray:
        """The holes (F, J) that count as observed, bridged by the constant-velocity
        smoother of their angles: those of at most ``short_hole_frames``, and those of at
        most ``partial_hole_frames`` in frames where the root is observed, in takes whose
        noise lets the angles bridge them (:func:`workbench.engine.smoothing.angles_bridge_holes`).
        ``channels`` (F, 3 + 3J): the observation's, gaps bridged (:func:`bridge_gaps`);
        ``positions`` (F, J, 3): their joint positions (file units)."""
        p = self.params
        missing = ~observation.observed
        length = hole_length(missing)
        holes = missing & (length <= p.short_hole_frames)
        partial = missing & (length <= p.partial_hole_frames) & observation.observed[:, :1] & ~holes
        if partial.any():
            skeleton, step = observation.skeleton, observation.capture_step
            if angles_bridge_holes(skeleton, channels, observation.observed, positions, p.short_lever_cm, step):
                holes |= partial
        return holes

    def _ik_reference(
        self,
        observation: Observation,
        bridged: np.ndarray,
        smoothed: np.ndarray | None,
        positions: np.ndarray,
        ref: np.ndarray,
    ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """What IK keeps of the observation: the reference angles (F, J, 3) and the
        reference's other arguments of :func:`~workbench.core.kinematics.inverse_kinematics`.
        With ``anchor`` :func:`workbench.engine.smoothing.ik_reference`'s (``smoothed``:
        the channels' :func:`workbench.engine.smoothing.smooth_and_fill`); without it the
        bridged observation's angles ``ref``, and the short levers in every frame."""
        skeleton, observed = observation.skeleton, observation.observed
        p = self.params
        if not p.anchor:
            return ref, {"reference_joints": short_lever_joints(skeleton, p.short_lever_cm, observed)}
        step = observation.capture_step
        return ik_reference(skeleton, bridged, observed, positions, p.short_lever_cm, p.angle_lever_cm, smoothed, step)

    def views_used(self) -> int:
        """How many of :data:`VIEWS` a clean completes: ``views``, or where it is 0 what
        validation chose for the weights' network. Three for a network at the model's rate
        (CMU's held-out subjects 05/06); two, the take and its mirror, for one at
        :attr:`NETWORK_FPS`, whose completions of the take played backwards make the mean
        worse (Bandai validation, 5 seeds, gap error with two views against three:
        ``block:1s`` 1.856 against 1.965 cm for the universal weights, 2.251 against 2.430
        for the Bandai ones; level under noise; ``docs/engines/cae.md``, *Views*)."""
        if self.params.views:
            return self.params.views
        return 3 if self.network_fps_ == self.fps_ else 2

    def low_pass(self, out: np.ndarray) -> np.ndarray:
        """The network's completion ``out`` (F, H) smoothed over time by a Gaussian of std
        ``output_sigma_frames`` network frames (normalised convolution: renormalised at the
        clip's ends)."""
        sigma = self.params.output_sigma_frames * self.fps_ / self.network_fps_
        return normalized_gaussian(out, np.ones(out.shape[0]), sigma) if sigma > 0 else out

    def correction(
        self, image: np.ndarray, mask: np.ndarray, out: np.ndarray, exact: np.ndarray, step: float = 1.0
    ) -> np.ndarray:
        """(F, H) added to the network's output ``out``: its miss (image - out) in full at the
        ``exact`` entries; at the other known entries the miss smoothed row by row by the
        constant-velocity smoother (0 without ``anchor``); bridged linearly across the holes,
        there its departure from the row's mean miss over the known entries (with
        ``anchor``; else from 0) faded by
        exp(-d / ``miss_fade_s``), d the time (s) to the row's nearest known frame: the
        network's miss at a gap's edges tells less of its miss deeper inside, but what it
        misses at every known frame (a body it has not seen, whose shoulders it pulls 14
        cm down) it misses there too (ours; ``docs/engines/cae.md``, *Fading the miss*,
        and *Keeping the mean miss*).

        The smoother's measurement variance is the observation's (its noise is what the miss
        must shed; a clean take's miss passes through), from the mean square of its second
        differences over the captured frames, ``step`` apart (the module docstring), its
        smoothing ratio the one that minimises the risk on the miss, as the ``kalman``
        engine picks it."""
        miss = image - out  # in place from here: a long take's (F, H) are 35 MB each
        miss[~mask] = 0.0
        kept = exact
        if self.params.anchor:
            r = measurement_variance(image, mask, robust=False, step=step)
            lam = smoothing_ratio(interpolate_gaps(miss, mask), r, mask.mean(axis=0))
            np.copyto(miss, cv_smooth(miss, mask, r / lam, r), where=~exact)
            kept = mask
        miss[~kept] = 0.0
        bridged = interpolate_gaps(miss, mask)
        holes = ~mask
        cols = np.flatnonzero(holes.any(axis=0))  # rows with a hole: a denoised take has none
        if self.params.miss_fade_s and cols.size:
            mean = 0.0  # without the anchor the miss is a constraint's alone, which says nothing far from it
            if self.params.anchor:
                mean = miss[:, cols].sum(axis=0) / np.maximum(kept[:, cols].sum(axis=0), 1)
            fade = np.exp(-gap_distance(holes[:, cols]) / (self.params.miss_fade_s * self.fps_))
            bridged[:, cols] = mean + (bridged[:, cols] - mean) * fade
        return bridged

    def blend_short_holes(self, out: np.ndarray, mask: np.ndarray, step: float = 1.0) -> np.ndarray:
        """``out`` (F, H) with its entries in each hole of L unknown frames of a row (L <
        ``hole_blend_frames``), in frames where the root is unknown too, moved towards the
        constant-velocity smoother's fill of the row's known entries, by the weight
        1 - L / ``hole_blend_frames``: the network fills long gaps better, the smoother
        short ones. Holes where only part of the body is missing are left to the network
        for speed: there the smoother helps less and costs more (``drop:0.5``, test
        split: 0.291 -> 0.255 cm, for 1.8 ms of a 20-ms clean, the fill spanning the take).
        ``step``: frames per captured frame, for the smoother's noise."""
        H = self.params.hole_blend_frames
        length = hole_length(~mask)
        short = (length < H) & ~mask & ~mask[:, :1]  # in frames whose root is unknown too
        cols = np.flatnonzero(short.any(axis=0))
        if not cols.size:
            return out
        hit = np.flatnonzero(short[:, cols].any(axis=1))
        span = slice(max(hit[0] - H, 0), hit[-1] + H + 1)  # the holes and H frames around them
        rows = out[span, cols]
        fill = smooth_and_fill(rows, mask[span, cols], step=step)
        weight = np.where(short[span, cols], 1.0 - length[span, cols] / H, 0.0)
        out = out.copy()
        out[span, cols] += weight * (fill - rows)
        return out

    def _constrain(
        self,
        imaging: OwnJoints | CanonicalJoints,
        image: np.ndarray,
        mask: np.ndarray,
        constraints: Constraints,
        ground: np.ndarray,
        theta: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Image, mask and the constrained entries (F, H), with the constrained positions
        (file units) entered as known entries of their image joints (``imaging``) in the
        body frame of the trajectory (ground (F, 3), theta (F,), image units)."""
        image, mask, constrained = image.copy(), mask.copy(), np.zeros_like(mask)
        for joint, (frames, positions) in constraints.items():
            j = imaging.image_joint(joint)
            if j <= 0:
                raise EngineError(
                    f"engine {self.info.name!r}: cannot constrain joint {joint}; give a non-root "
                    f"joint index below {imaging.skeleton.n_joints}"
                    + (" that maps onto the canonical humanoid" if self.params.universal else "")
                )
            frames = np.asarray(frames, int)
            positions = np.asarray(positions, float).reshape(len(frames), 3) * imaging.scale
            rows = self.layout_.rows(j)
            image[frames, rows] = turn_y(positions - ground[frames], -theta[frames])
            constrained[frames, rows] = True
        return image, mask | constrained, constrained


@dataclass(frozen=True)
class TrialMix:
    """What the trials beside a take's long holes ask (:meth:`ConvAutoencoderEngine.trial_mix`):
    in the frames ``holes`` (F,) bool the image's body rows (the hips' height, each joint's
    three; (H - 3,)) keep ``shares`` of the network's fill and take the rest from
    ``linear`` (n, H - 3), the linear fill's rows on its own floor point and heading; the
    heading keeps ``turn_share`` of the network's and takes the rest from ``linear_theta``
    (n,). ``network_share``: the mean of the tried joints' shares (the ``network_share``
    diagnostic in those frames)."""

    holes: np.ndarray
    shares: np.ndarray
    turn_share: float
    linear: np.ndarray
    linear_theta: np.ndarray
    network_share: float

    def applied(self, out: np.ndarray, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The completion (F, H) and the headings (F,) decoded from it, mixed in the holes."""
        if (self.shares == 1.0).all() and self.turn_share == 1.0:
            return out, theta
        out, theta = out.copy(), theta.copy()
        body = np.ix_(self.holes, np.arange(self.shares.size))  # the root's path is the network's and smoother's
        out[body] = self.linear + self.shares * (out[body] - self.linear)
        theta[self.holes] = self.linear_theta + self.turn_share * wrap(theta[self.holes] - self.linear_theta)
        return out, theta


def trial_blocks(long_holes: np.ndarray, root_known: np.ndarray) -> list[tuple[tuple[int, int], tuple[int, int]]]:
    """For each run of ``long_holes`` (F,) bool and each side of it, ((hole first, hole end),
    (trial first, trial end)): a stretch as long as the hole a quarter of its length (at
    least 2 frames) away, where the root is known (``root_known`` (F,)) in it and in the
    frame on either side and no other trial block touches it; a side without room gets
    none."""
    F = len(long_holes)
    taken = np.zeros(F, bool)
    blocks = []
    edges = np.flatnonzero(np.diff(np.concatenate([[0], long_holes.astype(np.int8), [0]])))
    for a, b in zip(edges[::2], edges[1::2]):
        n, gap = b - a, max((b - a) // 4, 2)
        for s, e in ((a - gap - n, a - gap), (b + gap, b + gap + n)):
            if s >= 1 and e <= F - 1 and root_known[s - 1 : e + 1].all() and not taken[s - 1 : e + 1].any():
                taken[s:e] = True
                blocks.append(((int(a), int(b)), (int(s), int(e))))
    return blocks


def _by_skeleton(motions: Sequence[Motion]) -> list[list[Motion]]:
    """The motions grouped by skeleton layout, the groups and the motions in each in the
    order they come."""
    groups: dict[str, list[Motion]] = {}
    for m in motions:
        groups.setdefault(m.skeleton.signature(), []).append(m)
    return list(groups.values())


def anchored_trajectory(
    ground: np.ndarray, theta: np.ndarray, root_known: np.ndarray, step: float = 1.0
) -> tuple[np.ndarray, np.ndarray]:
    """The root's floor points (F, 3) and headings (F,) radians where ``root_known`` (F,),
    smoothed by the constant-velocity smoother (:func:`workbench.engine.smoothing.smooth_and_fill`)
    with the noise levels it estimates from them (on the captured frames, ``step`` apart), and its fill where
    the root is unknown. The image is root-relative, so a noisy root would otherwise
    shake the whole body: every joint's rows would carry the root's noise, and the
    decoded pose would be put back on the noisy track. Across a gap inside the take the
    floor path is :data:`SMOOTHER_PATH_SHARE` of this fill and the rest the network's."""
    Y = np.column_stack([ground[:, 0], ground[:, 2], np.unwrap(theta)])
    S = smooth_and_fill(Y, np.repeat(root_known[:, None], 3, axis=1), step=step)
    smoothed = ground.copy()
    smoothed[:, [0, 2]] = S[:, :2]
    return smoothed, wrap(S[:, 2])
