"""The engine machinery shared by ``cae``, ``cae-vanilla`` and ``holden``: the motion image
(:mod:`.representation`), training (:mod:`.training`), inference and IK back to angles.

Cleaning a take (Observation -> Motion):

1. The observation with its gaps bridged (angles unwrapped) gives world joint positions
   by FK; the image (F, H) is built from them and masked where the positions are not
   known (root or an ancestor's angles missing). Joints whose angles never vary in the
   training data (CMU: LHipJoint, RHipJoint, LeftShoulder, RightShoulder) count as
   observed, their bridged value being exact, and so do holes of at most
   ``short_hole_frames`` (6, 50 ms at 120 fps; our addition) in a joint's angles: a
   bridge is nearer the truth there than the network's fill (whole frames missing, test
   split: 4 frames, lerp 0.18 cm, cae 0.31; 8 frames 0.45 and 0.42), and scattered
   drop-outs would otherwise hide most of the body, a position being unknown wherever
   any ancestor's angles are (``drop:0.5``: cae 1.65 -> 0.29 cm, lerp 0.25). These short
   holes are bridged by the constant-velocity smoother's path
   (:func:`workbench.engine.smoothing.smooth_and_fill`: a cubic spline through a clean take,
   a smoothing spline through a noisy one), the longer ones linearly. Test split, 5
   seeds, gap_mpjpe_cm, linear -> smoother: ``drop:0.3`` 0.133 -> 0.113, ``drop:0.5``
   0.265 -> 0.226 (spline 0.108 and 0.190: through clean samples a spline is best, but
   it follows their noise: with cubic bridges ``angular:0.5+gaps:0.01`` went 2.520 ->
   2.693), ``angular:0.5+gaps:0.01`` 2.520 -> 2.492, ``spatial:0.5+gaps:0.01`` 1.892 ->
   1.845. So are holes of at most ``partial_hole_frames`` (60; our addition) in frames
   where the root is observed (part of the body missing), in takes whose noise lets the
   angles bridge them (:func:`workbench.engine.smoothing.angles_bridge_holes`: no outliers in
   the angles, and position noise below 0.5 cm or below the angles'). The network was
   trained on whole frames and whole joints missing; a joint's own holes of a few dozen
   frames the smoother of its angles bridges better. Validation (subjects 05/06 held
   out, 3 seeds, gap_mpjpe_cm, partial holes left to the network -> bridged up to 60
   frames): ``gaps:0.01`` 2.042 -> 1.111 (kalman 0.907), ``angular:0.5+gaps:0.01``
   5.099 -> 4.179 (kalman 4.293), ``drop:0.5`` 0.271 -> 0.257. Under position noise
   the network wins from about 0.5 cm (``spatial:0.4+gaps:0.01`` 1.996 -> 1.894,
   ``spatial:0.5+...`` 2.112 -> 2.142, ``spatial:0.7+...`` 2.349 -> 2.586), and with
   outliers in the angles by far (``angular:0.5+outliers:0.05+gaps:0.01`` 10.03 ->
   18.34): there the holes are left to it. Up to 30 frames: ``gaps:0.01`` 1.609; up to
   120: 0.887 on validation but 1.026 on the test split (60: 0.931; one clip). Whole-body
   holes keep the 6 frames: longer bridges lose to the network and the blend below
   (``block:30`` 0.806 -> 0.867 at 60). Test split, 5 seeds: ``gaps:0.01`` 1.352 ->
   0.931, ``angular:0.5+gaps:0.01`` 2.492 -> 2.319, ``drop:0.5`` 0.226 -> 0.185.
2. The clip is reflected at its end to a multiple of 32 frames, normalised with the
   training statistics, unknown entries bridged or zeroed (``input_fill``), the mask
   added as a second channel, and the network predicts the whole image in one pass;
   the padding is cropped. With ``views`` > 1 (our addition) the take's views under
   the symmetries of motion, in this order mirrored left/right, played backwards
   (:func:`.representation.reverse_time`) and both, are completed in the same batch,
   mapped back and averaged with it. The network learnt these symmetries only
   approximately (training mirrors half the windows and never plays them backwards),
   so the completions differ and their mean is the better one. With all four views the
   result is itself symmetric (exactly, but for a second-order turn of the reversed
   floor steps). Three views (the default) were chosen on validation (subjects 05/06
   held out, two training seeds): as good as four on gaps (60 frames 2.89 and 2.92 cm
   against 2.95 and 2.87; 120 frames 6.74 and 6.51 against 6.75 and 6.58), 1 % worse
   under noise and dropped joints, and a quarter of the network's work cheaper. Test
   split, 60-frame gap, one to four views: 3.67, 3.61, 3.52, 3.52 cm; 120-frame gap
   5.50, 5.35, 5.22, 5.29.
   The completion is then smoothed over time by a Gaussian of std
   ``output_sigma_frames`` (1.5 frames; our addition). The strided transposed
   convolutions (``holden``: the unpooling) leave a periodic ripple at 2, 4 and 8
   frames: on the test split, with no corruption, the power of the network's miss
   peaks there, at 12, 48 and 170 times the truth's own power at 8, 4 and 2 frames.
   The ripple is a fraction of a millimetre, but it makes the filled motion jerky.
   This Gaussian keeps 93 % of a 5-Hz motion (at 120 fps; the truth's power above
   7 Hz is 1 % of its power at 4 Hz) and damps the ripple by half at 8 frames, 16
   times at 4 and wipes it out at 2. Test split, ``block:120``, seed 0, mean jerk over
   the gaps' frames, without -> with the smoothing: cae 1.29e6 -> 7.6e4 cm/s^3,
   holden 2.37e6 -> 1.2e5, cae-vanilla 1.06e6 -> 8.8e4; the truth's 2.6e5. With 5
   seeds the errors stay or drop: ``block:120`` 5.224 -> 5.217 cm, ``block:60`` 3.515
   -> 3.510, ``spatial:1`` 0.614 -> 0.569, ``drop:0.5`` 0.293 -> 0.265 (``spatial``:
   mpjpe_cm, else gap_mpjpe_cm). 1.5 frames is the narrowest Gaussian that removes
   the ripple at 2 and 4 frames. Wider ones lower the errors a little more on
   validation (subjects 05/06 held out; ``block:120`` 5.174, 5.158 and 5.143 cm at
   0, 1.5 and 4 frames; ``spatial:1`` 0.574, 0.516 and 0.499) but damp the real
   motion too (a 5-Hz motion keeps 74 % at 3 frames).
3. The root's floor trajectory is the observed one where the root is observed and the
   predicted velocities integrated across the gaps (attached to the known frames at
   both ends); the image on that trajectory gives the raw network positions
   (diagnostic ``raw_positions``, (F, J, 3), file units). With ``anchor`` the observed
   floor points and headings are first smoothed (:func:`anchored_trajectory`; across a
   gap inside the take the floor path is then mostly the smoother's fill) and the image
   is built on that track: the image is root-relative, so the root's noise would
   otherwise enter every joint's rows and the result would be put back on the noisy
   track (test split, ``spatial:1``: 1.30 -> 0.69 cm, the root 1.31 -> 0.51 cm off; no
   corruption: 0.017 -> 0.019 cm).
4. IK with the skeleton's bone lengths turns them into angles (twist about single-child
   bones and the leaves' rotations from the bridged observation, with ``anchor``
   smoothed; below), so the result is a normal Motion. Before IK
   the image is *anchored* to the observation (``anchor``, our addition; on by
   default): the network's miss at the known entries (known minus predicted) is
   smoothed row by row by the ``kalman`` engine's constant-velocity smoother
   (:mod:`workbench.engine.smoothing`), bridged linearly across each hole and added to the
   prediction. The smoother's measurement noise is estimated from the observation
   (the miss's own fast wobble is the network's, to be kept), its smoothing ratio by
   the risk estimate on the miss. The noise variance is the mean square of the
   observation's second differences (:func:`workbench.engine.smoothing.measurement_variance`
   with ``robust=False``), not the median-based estimate the ``kalman`` engine uses on
   angles. Angle noise moves the joint positions with heavy tails (a hip's turn lifts
   the foot by 1 - cos), the median misses up to half their variance, and the smoother,
   told the noise is small, keeps it. Test split, 5 seeds, median -> mean square:
   ``angular:0.5`` mpjpe 1.250 -> 1.114 cm (kalman 1.196), jerk 1.34e6 -> 3.2e5
   cm/s^3 (the truth's 2.9e5); ``angular:0.5+gaps:0.01`` 1.778 -> 1.636;
   ``+outliers:0.05`` 6.77 -> 3.41; ``spatial:1`` 0.576 -> 0.569; gaps alike
   (``block:60`` 3.509 -> 3.510). The mean square counts the motion's own
   accelerations too: a clean take moves by 0.036 cm instead of 0.018. The result
   keeps the observation's course and sheds its noise: the autoencoder's bottleneck
   loses a few cm of every pose (test split, no corruption: 3.9 cm, anchored 0.04
   cm), a noisy root makes its velocity rows 10-20 training deviations wrong
   (``spatial:1.5``: 9.2 cm, anchored 0.80 cm), and a filled gap joins its ends.
   ``anchor=false`` returns the network's output as it is, as in the paper
   (unsmoothed with ``output_sigma_frames=0``). Observed frames change slightly
   either way. Joints whose children all sit within ``short_lever_cm`` of them (5
   cm; CMU: the hands and finger bases) are not aimed from positions, where a few
   mm of error turn a 3-cm lever by tens of degrees: they keep their observed
   angles, bridged linearly across the holes, as ``lerp`` does, and with ``anchor``
   smoothed first (:func:`workbench.engine.smoothing.smooth_joint_angles`: position noise
   makes the observed hand angles noisy too); IK aims them only when
   they are never observed. Test split, RMS angle error, aimed -> kept: no corruption
   0.088 -> 0.051 degrees (0.042 kept unsmoothed), 60-frame gap 2.28 -> 1.71,
   ``drop:0.5`` 10.3 -> 3.3, ``spatial:1.5`` 4.69 -> 3.32 (7.9 kept unsmoothed).
   With ``anchor`` every joint's observed angles are smoothed so (our addition): the
   twist and the leaves come from them, and angle noise left them as noisy as the
   input. The joints aimed at one descendant within ``angle_lever_cm`` (13.5 cm; CMU:
   the feet, LowerBack, Spine, Neck, Neck1) keep their smoothed angles in the frames
   they are observed, when the take's noise is in the angles
   (:func:`workbench.engine.smoothing.angles_are_quieter`): a toe's position then carries the
   noise of the whole leg, and aimed at it from 13 cm the foot was off by 7-10 degrees
   under ``angular:0.5`` (kalman's feet: 1.6-2.0). Across their holes IK aims them and
   bridges the kept angles' departure from the aim, so they join without a jump.
   Under position noise, or with outliers in the angles (the smoother passes them),
   they are aimed as before. Test split, 5 seeds, before -> after (rms_angle_deg;
   mpjpe_cm): ``angular:0.5`` 3.12 -> 1.36 (kalman 1.27); 1.114 -> 1.070 cm;
   ``angular:0.9`` 7.00 -> 2.32 (kalman 2.03); 2.035 -> 1.847; ``angular:0.1`` 0.60
   -> 0.38; ``angular:0.5+gaps:0.01`` 3.80 -> 2.22; 1.636 -> 1.579;
   ``+outliers:0.05`` 12.2 -> 11.5; 3.408 both. The cost is the smoothing of angles
   that were clean: no corruption 0.068 -> 0.079 degrees; ``spatial:1`` 2.08 -> 2.13
   (the spatial corruption keeps the true twist); positions and gaps level (``block:60``
   3.510 both).
   Inside a hole of L unknown frames of an image row with L < ``hole_blend_frames``
   (60; our addition), where the whole body is missing (the root unknown), the
   anchored output moves towards the constant-velocity smoother's fill of the row's
   known entries, by the weight 1 - L / 60: the network was trained for long gaps, and
   on short ones the smoother (and a spline) fill better.
   Test split, whole frames missing, gap error without -> with, spline: 8 frames 0.45
   -> 0.20 cm (0.17), 15 frames 0.74 -> 0.41 (0.37), 30 frames 1.61 -> 1.29 (1.38),
   45 frames 2.74 -> 2.59 (3.01); 60 and more unchanged.
   With ``keep_observed=true`` the observed angles and root positions come back
   exactly: the miss is added in full at the known entries (not smoothed), so the
   filled stretch joins the kept frames without a jump; IK then aims the missing
   joints from the exactly known positions. (So it fills gaps but does not denoise.)

Constraints (the paper's tertiary motion blending): ``clean(observation,
constraints={joint: (frames, positions)})`` with ``frames`` (n,) frame indices and
``positions`` (n, 3) world positions in file units enters those positions as known
entries of the image. Where the root is missing they are placed in the body frame of
a first, unconstrained pass's trajectory, which the result then keeps. The network
takes them as known entries (it was trained with such partial poses inside gaps), and
they are then met, as far as the bone lengths allow: the network's miss at the
constrained entries is added to its output, blended in linearly from the anchor's
correction at the neighbouring known entries of the same row (from zero with
``anchor=false``, from their own miss with ``keep_observed=true``). ``raw_positions``
stays the network's output.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from workbench.core.channels import hole_length, interpolate_gaps
from workbench.core.kinematics import forward_kinematics, inverse_kinematics, local_rotations, short_lever_joints
from workbench.core.motion import Motion, Observation, channel_mask, position_unknown
from workbench.engine import CleanResult, Engine, EngineError, trained, training
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

from .representation import (
    Layout,
    decode,
    encode,
    heading,
    image_mask,
    mirror_rows,
    pad_time,
    reverse_time,
    trajectory,
    turn_y,
    wrap,
)

#: most image columns (views x padded frames) per network call: per column, bigger calls
#: are slower on these CPUs (2-core AVX2 EPYC, cae: 27 us up to 14k columns, 34-43 us
#: from 21k; the 3 views of a 7,200-frame take take 931 ms in one call, 600 in three)
MAX_CALL_COLUMNS = 10_000
#: the views' symmetries, (mirrored, reversed), in the order ``views`` takes them
VIEWS = ((False, False), (True, False), (False, True), (True, True))

Constraints = Mapping[int, tuple[Sequence[int], np.ndarray]]
#: with ``anchor``, the share of the constant-velocity smoother's fill in the root's floor
#: path across a gap inside the take, the rest the network's integrated path. The root
#: off in the gap's frames, cm, network's path only / 0.5 / 0.75 / the fill only, test
#: split, 5 seeds: 15-frame gap 0.50 / 0.36 / 0.31 / 0.29, 30 frames 1.41 / 1.16 / 1.10 /
#: 1.08, 60 frames 3.30 / 2.97 / 2.97 / 3.09, 120 frames 7.78 / 6.07 / 5.52 / 5.35;
#: validation (subjects 05/06 held out, 3 seeds): 0.29 / 0.25 / 0.25 / 0.27, 1.02 / 0.80 /
#: 0.74 / 0.72, 2.79 / 2.16 / 1.95 / 1.84, 5.14 / 3.97 / 3.67 / 3.65. 0.75 is at or below
#: 0.5 at every length; the fill alone is not, and leaves the network's steps unused
SMOOTHER_PATH_SHARE = 0.75


@dataclass(frozen=True)
class TrainingParams:
    """Training and use, shared by the three engines. An epoch is ``frames_per_epoch``
    frames in windows of ``window_frames`` frames (a multiple of 32); the curriculum
    raises the mean gap by 10 frames every ``curriculum_epochs`` epochs (10 to 120, then
    held). Augmentation (:class:`.training.WindowSampler`): ``time_scale_pct``, each
    window played at a speed drawn log-uniformly in [1 / (1 + p/100), 1 + p/100];
    ``body_scale_pct``, each window's body and motion scaled uniformly by a factor in
    1 +- p/100; ``pose_copies``, each clip also trained on this many times with every
    upper-body joint angle (joints above the root at rest) that varies in the training
    data offset by a constant drawn from N(0, ``pose_jitter_deg``^2) degrees per copy;
    ``mirror``, half the windows mirrored left/right; ``input_noise``, Gaussian noise
    of this standard deviation (normalised units) on the known input entries.
    ``sampling`` ("clips" or "frames") and ``input_fill`` ("linear" or "zero"): see
    :mod:`.training`. ``ema_decay``: the weights kept are the exponential moving average
    over the steps with this decay per step (0: the last step's). ``bf16``: bf16 autocast
    (training and inference).
    ``keep_observed``: return observed samples exactly; ``anchor``: anchor the output
    to the observation; ``short_lever_cm``: joints whose children lie closer keep their
    observed angles, 0 for none; ``angle_lever_cm``: with ``anchor``, joints aimed at one
    descendant this close keep their smoothed observed angles where the noise is in the
    angles, 0 for none (both: the module docstring); ``views``: how many of
    :data:`VIEWS` (the take, its left/right mirror, the take played backwards, the mirror
    played backwards) are completed and averaged (all: the module docstring);
    ``short_hole_frames``: holes in a joint's angles up to this long are bridged by the
    constant-velocity smoother and count as observed (0: none); ``partial_hole_frames``:
    so are holes up to this long in frames where the root is observed, where the take's
    noise allows (0: none); ``hole_blend_frames``:
    inside a hole shorter than this the network's fill is blended with the
    constant-velocity smoother's (0: none; all three: the module docstring);
    ``output_sigma_frames``: the network's completion is smoothed over time by a
    Gaussian of this std in frames before it is used (0: none; the module docstring)."""

    epochs: int = training(120)
    frames_per_epoch: int = training(100_000)
    window_frames: int = training(256)
    batch_size: int = training(16)
    learning_rate: float = training(1e-3)
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
    sampling: str = training("clips")
    seed: int = training(0)
    bf16: bool = True
    keep_observed: bool = False
    anchor: bool = True
    short_lever_cm: float = 5.0
    angle_lever_cm: float = 13.5
    views: int = 3
    short_hole_frames: int = 6
    partial_hole_frames: int = 60
    hole_blend_frames: int = 60
    output_sigma_frames: float = 1.5

    def __post_init__(self) -> None:
        if self.input_fill not in ("zero", "linear"):
            raise ValueError(f"input_fill must be 'zero' or 'linear', got {self.input_fill!r}")
        if self.sampling not in ("frames", "clips"):
            raise ValueError(f"sampling must be 'frames' or 'clips', got {self.sampling!r}")
        if self.views not in range(1, len(VIEWS) + 1):
            raise ValueError(f"views must be 1 to {len(VIEWS)}, got {self.views}")
        for name in ("short_hole_frames", "partial_hole_frames", "hole_blend_frames"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be 0 (off) or a number of frames, got {getattr(self, name)}")
        for name in ("short_lever_cm", "angle_lever_cm"):
            if not (np.isfinite(getattr(self, name)) and getattr(self, name) >= 0):
                raise ValueError(f"{name} must be 0 (off) or a positive length in cm, got {getattr(self, name)}")
        if not (np.isfinite(self.output_sigma_frames) and self.output_sigma_frames >= 0):
            raise ValueError(
                f"output_sigma_frames must be 0 (off) or a positive number of frames, got {self.output_sigma_frames}"
            )


class ConvAutoencoderEngine(Engine):
    """Base of the motion-image autoencoders; subclasses set ``info``, ``Params`` and
    :meth:`build_network`."""

    Params = TrainingParams
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
        """Train on clean motions of one skeleton layout (the training split)."""
        from workbench.engine.torch_support import reproducible_training

        motions = self.training_motions(motions)
        with reproducible_training(self.params.seed):
            self._train(motions)
        return self

    def _train(self, motions: Sequence[Motion]) -> None:
        """Build the network and train it on ``motions``; sets the fitted state."""
        from .training import WindowSampler, train

        p = self.params
        skeleton = motions[0].skeleton
        layout = Layout.from_skeleton(skeleton)
        net = self.build_network(layout.n_rows)
        if p.window_frames % net.time_multiple:
            raise EngineError(f"window_frames must be a multiple of {net.time_multiple}, got {p.window_frames}")
        varies = np.concatenate([m.angles_deg for m in motions]).std(axis=0) > 1e-9  # (J, 3) per angle
        varies[0] = False
        constant = np.flatnonzero(~varies.any(axis=1))
        constant = constant[constant > 0]
        maskable = np.array([j for j in range(1, skeleton.n_joints) if j not in constant and skeleton.has_rotation[j]])
        rest = np.zeros(skeleton.n_joints)  # height above the root in the rest pose
        for j, parent in enumerate(skeleton.parents):
            rest[j] = rest[parent] + skeleton.offsets[j, 1] if parent >= 0 else 0.0
        jitter = varies & (rest > 0)[:, None]  # upper-body angles: the feet keep their contacts
        images = []
        rng = np.random.default_rng(p.seed)
        for m in motions:
            for copy in range(1 + p.pose_copies):
                angles = m.angles_deg.copy()
                if copy:  # the same offsets in every frame: other, still smooth poses
                    angles += rng.normal(0.0, p.pose_jitter_deg, jitter.shape) * jitter
                P, R = forward_kinematics(skeleton, m.root_positions, angles)
                images.append(encode(layout, P, heading(R[:, 0])))
        mirror = mirror_rows(layout, skeleton.names) if p.mirror else None
        pool = np.concatenate(images + ([im[:, mirror[0]] * mirror[1] for im in images] if mirror else []))
        # float32 as saved, so a loaded engine computes exactly what the fitted one does
        mean = pool.mean(axis=0).astype(np.float32).astype(float)
        std = np.maximum(pool.std(axis=0), 1e-6).astype(np.float32).astype(float)
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
        )
        batches = max(1, p.frames_per_epoch // (p.batch_size * p.window_frames))
        log = train(
            net,
            sampler,
            p.epochs,
            batches,
            p.batch_size,
            p.learning_rate,
            p.curriculum_epochs,
            p.ema_decay,
            desc=f"train {self.info.name}",
        )
        self.net_, self.layout_, self.constant_ = net, layout, constant
        self.mean_, self.std_, self.loss_log_ = mean, std, np.array(log)
        self.skeleton_signature_ = skeleton.signature()

    # -- fitted state ---------------------------------------------------------------
    def training_record(self) -> dict[str, list[float]]:
        """The loss of every epoch."""
        return {"loss_per_epoch": [round(float(x), 5) for x in self.loss_log_]}

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

    # -- cleaning -------------------------------------------------------------------
    def complete(
        self, image: np.ndarray, mask: np.ndarray, mirror: tuple[np.ndarray, np.ndarray] | None = None, views: int = 1
    ) -> np.ndarray:
        """The network's completion (F, H) of a raw image (F, H) known where ``mask``: the
        mean of the completions of the first ``views`` of :data:`VIEWS`, each mapped back;
        batched, at most :data:`MAX_CALL_COLUMNS` columns a call. ``mirror``: the row permutation and signs of
        :func:`.representation.mirror_rows`, needed for the mirrored views."""
        import torch

        from workbench.engine.torch_support import default_threads, torch_threads

        from .training import network_input

        F = image.shape[0]
        if views > 1 and mirror is None:
            raise ValueError("the mirrored views need the mirror's rows and signs (mirror_rows)")
        perm, sign = mirror if mirror is not None else (None, None)
        batch = []  # (image, mask, mirrored, reversed) of each view
        for mirrored, reversed_ in VIEWS[:views]:
            x, m = (image[:, perm] * sign, mask[:, perm]) if mirrored else (image, mask)
            batch.append((*(reverse_time(x, m) if reversed_ else (x, m)), mirrored, reversed_))
        frames = -(-F // self.net_.time_multiple) * self.net_.time_multiple
        padded = [pad_time(x, m, frames) for x, m, _, _ in batch]
        X, M = np.stack([x for x, _ in padded]), np.stack([m for _, m in padded])
        x = network_input((X - self.mean_) / self.std_, M, self.params.input_fill)
        per_call = max(1, MAX_CALL_COLUMNS // frames)
        with torch_threads(default_threads()), torch.inference_mode():
            Y = np.concatenate([self.net_(x[i : i + per_call]).numpy() for i in range(0, len(x), per_call)])
        Y = Y[..., :F].transpose(0, 2, 1) * self.std_ + self.mean_
        total = np.zeros_like(image)
        for y, (_, m, mirrored, reversed_) in zip(Y, batch):
            if reversed_:
                y = reverse_time(y, m)[0]
            total += y[:, perm] * sign if mirrored else y
        return total / len(batch)

    @one_blas_thread
    def clean(self, observation: Observation, /, *, constraints: Constraints | None = None) -> CleanResult:
        """Fill the gaps of (and denoise) ``observation``; ``constraints`` maps a joint index
        to (frames (n,), world positions (n, 3) in file units) that guide the network."""
        self.require_fitted()
        skeleton = observation.skeleton
        self.check_skeleton(skeleton)
        layout = self.layout_
        linear = bridge_gaps(observation)
        holes = self.bridged_holes(observation, linear)
        seen, bridge = observation.channel_observed, channel_mask(holes, skeleton)
        # smoothed once: the holes' bridges and (with anchor) the IK reference
        smoothed = smooth_and_fill(linear, seen) if self.params.anchor or holes.any() else None
        bridged = np.where(bridge, smoothed, linear) if holes.any() else linear
        ref = bridged[:, 3:].reshape(observation.n_frames, -1, 3)
        ref_local = local_rotations(skeleton, ref)
        P, R = forward_kinematics(skeleton, bridged[:, :3], ref, local=ref_local)
        theta = heading(R[:, 0])
        ground = P[:, 0] * np.array([1.0, 0.0, 1.0])
        observed = observation.observed | holes
        observed[:, self.constant_] = True
        known = ~position_unknown(observed, layout.parents)
        if self.params.anchor:
            ground, theta = anchored_trajectory(ground, theta, known[:, 0])
        image, mask = encode(layout, P, theta, ground), image_mask(layout, known)
        mirror = mirror_rows(layout, skeleton.names) if self.params.views > 1 else None
        net_out = self.complete(image, mask, mirror, self.params.views)
        out = self.low_pass(net_out)
        path, theta = trajectory(out, known[:, 0], ground, theta)
        if self.params.anchor:  # across a gap inside the take: mostly the smoother's path
            share = SMOOTHER_PATH_SHARE
            ground = np.where(np.isinf(hole_length(~known[:, :1])), path, (1.0 - share) * path + share * ground)
        else:
            ground = path
        exact = mask.copy() if self.params.keep_observed else np.zeros_like(mask)
        if constraints:  # a second pass, on the first one's trajectory
            image, mask, constrained = self._constrain(image, mask, constraints, ground, theta)
            exact |= constrained
            net_out = self.complete(image, mask, mirror, self.params.views)
            out = self.low_pass(net_out)
        raw = decode(layout, net_out, ground, theta)
        if exact.any() or self.params.anchor:
            out = out + self.correction(image, mask, out, exact)
            if self.params.anchor and self.params.hole_blend_frames:
                out = self.blend_short_holes(out, mask)
        target = raw if out is net_out else decode(layout, out, ground, theta)  # as the paper: once
        short, frames, ref, ref_local = self._ik_reference(observation, bridged, smoothed, P, ref, ref_local)
        root, angles, translations = inverse_kinematics(
            skeleton, target, ref, reference_local=ref_local, reference_joints=short, reference_frames=frames
        )
        solved = observation.motion.replace(root_positions=root, angles_deg=angles, translations=translations)
        channels = rewrap_angles(solved.channels, observation)
        if self.params.keep_observed:
            given = observation.channel_observed
            channels[given] = observation.motion.channels[given]
        return CleanResult(observation.motion.with_channels(channels), {"raw_positions": raw})

    def bridged_holes(self, observation: Observation, channels: np.ndarray) -> np.ndarray:
        """The holes (F, J) that count as observed, bridged by the constant-velocity
        smoother of their angles: those of at most ``short_hole_frames``, and those of at
        most ``partial_hole_frames`` in frames where the root is observed, in takes whose
        noise lets the angles bridge them (:func:`workbench.engine.smoothing.angles_bridge_holes`).
        ``channels`` (F, 3 + 3J): the observation's, gaps bridged (:func:`bridge_gaps`)."""
        p = self.params
        missing = ~observation.observed
        length = hole_length(missing)
        holes = missing & (length <= p.short_hole_frames)
        partial = missing & (length <= p.partial_hole_frames) & observation.observed[:, :1] & ~holes
        if partial.any():
            positions, _ = forward_kinematics(
                observation.skeleton, channels[:, :3], channels[:, 3:].reshape(observation.n_frames, -1, 3)
            )
            if angles_bridge_holes(observation.skeleton, channels, observation.observed, positions, p.short_lever_cm):
                holes |= partial
        return holes

    def _ik_reference(
        self,
        observation: Observation,
        bridged: np.ndarray,
        smoothed: np.ndarray | None,
        positions: np.ndarray,
        ref: np.ndarray,
        ref_local: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """What IK keeps of the observation: with ``anchor``
        :func:`workbench.engine.smoothing.ik_reference` (its joints, frames and smoothed reference
        angles, with their local rotations; ``smoothed``: the channels'
        :func:`workbench.engine.smoothing.smooth_and_fill`); without it the bridged observation's
        reference angles and local rotations, and the short levers in every frame."""
        skeleton, observed = observation.skeleton, observation.observed
        p = self.params
        if not p.anchor:
            return (
                short_lever_joints(skeleton, p.short_lever_cm, observed),
                np.zeros(observed.shape, bool),
                ref,
                ref_local,
            )
        ref, short, frames = ik_reference(
            skeleton, bridged, observed, positions, p.short_lever_cm, p.angle_lever_cm, smoothed
        )
        return short, frames, ref, local_rotations(skeleton, ref)

    def low_pass(self, out: np.ndarray) -> np.ndarray:
        """The network's completion ``out`` (F, H) smoothed over time by a Gaussian of std
        ``output_sigma_frames`` (normalised convolution: renormalised at the clip's ends)."""
        sigma = self.params.output_sigma_frames
        return normalized_gaussian(out, np.ones(out.shape[0]), sigma) if sigma > 0 else out

    def correction(self, image: np.ndarray, mask: np.ndarray, out: np.ndarray, exact: np.ndarray) -> np.ndarray:
        """(F, H) added to the network's output ``out``: its miss (image - out) in full at the
        ``exact`` entries; at the other known entries the miss smoothed row by row by the
        constant-velocity smoother (0 without ``anchor``); bridged linearly across the holes.

        The smoother's measurement variance is the observation's (its noise is what the miss
        must shed; a clean take's miss passes through), from the mean square of its second
        differences (the module docstring), its smoothing ratio the one that minimises the
        risk on the miss, as the ``kalman`` engine picks it."""
        miss = np.where(mask, image - out, 0.0)
        kept = exact
        if self.params.anchor:
            r = measurement_variance(image, mask, robust=False)
            lam = smoothing_ratio(interpolate_gaps(miss, mask), r, mask.mean(axis=0))
            miss = np.where(exact, miss, cv_smooth(miss, mask, r / lam, r))
            kept = mask
        return interpolate_gaps(np.where(kept, miss, 0.0), mask)

    def blend_short_holes(self, out: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """``out`` (F, H) with its entries in each hole of L unknown frames of a row (L <
        ``hole_blend_frames``), in frames where the root is unknown too, moved towards the
        constant-velocity smoother's fill of the row's known entries, by the weight
        1 - L / ``hole_blend_frames``: the network fills long gaps better, the smoother
        short ones. Holes where only part of the body is missing are left to the network
        for speed: there the smoother helps less and costs more (``drop:0.5``, test
        split: 0.291 -> 0.255 cm, for 1.8 ms of a 20-ms clean, the fill spanning the take)."""
        H = self.params.hole_blend_frames
        length = hole_length(~mask)
        short = (length < H) & ~mask & ~mask[:, :1]  # in frames whose root is unknown too
        cols = np.flatnonzero(short.any(axis=0))
        if not cols.size:
            return out
        hit = np.flatnonzero(short[:, cols].any(axis=1))
        span = slice(max(hit[0] - H, 0), hit[-1] + H + 1)  # the holes and H frames around them
        rows = out[span, cols]
        fill = smooth_and_fill(rows, mask[span, cols])
        weight = np.where(short[span, cols], 1.0 - length[span, cols] / H, 0.0)
        out = out.copy()
        out[span, cols] += weight * (fill - rows)
        return out

    def _constrain(
        self, image: np.ndarray, mask: np.ndarray, constraints: Constraints, ground: np.ndarray, theta: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Image, mask and the constrained entries (F, H), with the constrained positions
        entered as known entries in the body frame of the trajectory (ground (F, 3),
        theta (F,))."""
        image, mask, constrained = image.copy(), mask.copy(), np.zeros_like(mask)
        for joint, (frames, positions) in constraints.items():
            j = self.layout_.source[joint] if 0 <= joint < self.layout_.n_joints else -1
            if j <= 0:
                raise EngineError(
                    f"engine {self.info.name!r}: cannot constrain joint {joint}; give a non-root "
                    f"joint index below {self.layout_.n_joints}"
                )
            frames = np.asarray(frames, int)
            positions = np.asarray(positions, float).reshape(len(frames), 3)
            rows = self.layout_.rows(j)
            image[frames, rows] = turn_y(positions - ground[frames], -theta[frames])
            constrained[frames, rows] = True
        return image, mask | constrained, constrained


def anchored_trajectory(ground: np.ndarray, theta: np.ndarray, root_known: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The root's floor points (F, 3) and headings (F,) radians where ``root_known`` (F,),
    smoothed by the ``kalman`` engine's constant-velocity smoother with the noise levels
    it estimates from them, and its fill where the root is unknown. The image is
    root-relative, so a noisy root would otherwise shake the whole body: every joint's
    rows would carry the root's noise, and the decoded pose would be put back on the
    noisy track. Across a gap inside the take the floor path is
    :data:`SMOOTHER_PATH_SHARE` of this fill and the rest the network's."""
    Y = np.column_stack([ground[:, 0], ground[:, 2], np.unwrap(theta)])
    S = smooth_and_fill(Y, np.repeat(root_known[:, None], 3, axis=1))
    smoothed = ground.copy()
    smoothed[:, [0, 2]] = S[:, :2]
    return smoothed, wrap(S[:, 2])
