"""``ebd``: Encoder-Bidirectional-Decoder gap filler (Mall et al. 2017 §3, "Gap filling").

Gaps are first bridged by linear interpolation of each channel. Per frame the network
sees the C joint-angle channels (unwrapped, normalised), the root's 3 angular velocities
and, as extra input, the observed mask of the C channels (1 observed, 0 missing). The
EBF encoder (4 tanh layers to a 64-d code) feeds 2 bidirectional LSTM layers
(``lstm_units`` = 32 per direction, input dropout 0.5) reading 15 frames back and 15
ahead at a stride of 4 frames (60 frames of context each side); a 4-layer decoder
gives, per channel, a correction (in training stds) to the interpolated value at the
window's centre. Only the missing entries are replaced: observed samples come back
exactly as given (``keeps_observed``). The network's fill takes over from the linear
one gradually, over ``blend_frames`` = 40 frames from each gap edge (its share is the
distance to the nearest observed sample over 40, at most 1): the fill joins the
observed samples without a jump, and short gaps, where interpolation is already close
and the network (trained on 6 subjects) generalises worst, stay near linear. On the
test split this made short gaps (``gaps:0.01``) 1.80 -> 1.17 cm ``gap_mpjpe_cm`` (lerp
1.16) and 3-s single-joint gaps 9.24 -> 8.56 cm (lerp 9.22). Root channels in gaps
stay linearly bridged.

Our addition: in takes whose angles are quiet
(:func:`workbench.engine.smoothing.angles_are_quiet`: less than 0.5 cm of noise,
outliers included, as a joint's descendant sees it; a clean take, ``angular:0.1``,
``spatial:0.2``), the fill takes over not from the line but from the constant-velocity
smoother's path across each hole of at most ``smooth_hole_frames`` (0.5 s: 60 frames at
120 fps) with samples on both sides: a cubic spline through clean samples, a smoothing
spline through slightly noisy ones (the network's input stays linearly bridged, as
trained). Test split, 3 seeds, ``gap_mpjpe_cm``, line -> smoother: ``gaps:0.01`` 1.265
-> 0.975, ``drop:0.5`` 0.296 -> 0.244, ``angular:0.1+gaps:0.01`` 1.985 -> 1.739,
``spatial:0.2+gaps:0.01`` 2.187 -> 1.893; rms_angle_deg and mpjpe_cm drop too. Under
more noise the smoother's path across holes of 20-60 frames turns some angles further
off than the line (every take, ``angular:0.5+gaps:0.01``: ``ebd>ebf`` 1.903 -> 1.955
degrees, though 2.874 -> 2.720 cm in the gaps), and outliers would drag it
(``angular:0.5+outliers:0.05+gaps:0.01`` 5.08 -> 11.36 cm): those takes keep the line.

Training: the train split, each copy played at a random speed within ±50 %, with gaps
of three kinds (``gaps:0.01``; ``gaps:0.002,60``; ``gaps:0.0005,240,480``), each copy
with one more joint missing for 2-4 s, and angular noise of 0, 0.1, 0.5 or 0.9 channel
stds; fresh every epoch. The loss is the mean squared error over the missing entries,
each channel's error measured in its training std (in degrees, channels near gimbal
lock with stds of 70 degrees and more drown the rest). ``ebd>ebf`` fills, then denoises.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from workbench.core.channels import gap_distance, hole_length
from workbench.core.motion import Motion, Observation, angle_columns
from workbench.corruption import parse_corruption
from workbench.engine import CleanResult, EngineInfo, trained, training
from workbench.engine.signal import rewrap_angles
from workbench.engine.smoothing import angles_are_quiet, smooth_and_fill
from workbench.engine.threads import one_blas_thread

from .base import TrainingParams, WindowEngine
from .features import RADIUS, REFERENCE_FPS, FrameData

#: gap models mixed in training
GAP_MODELS = ("gaps:0.01", "gaps:0.002,60", "gaps:0.0005,240,480")
#: angular noise levels (channel stds) drawn per training copy; 0 is clean
NOISE_LEVELS = (0.0, 0.1, 0.5, 0.9)
#: each training copy also loses one joint for this long (seconds, uniform)
LONG_GAP_S = (2.0, 4.0)


def joint_missing(data: FrameData) -> np.ndarray:
    """(F, C / 3) the missing mask of one angle channel per joint: a joint's three angle
    channels go missing together (an observation's mask is per joint), so the gap
    measures of :mod:`workbench.core.channels` on it, repeated three times, are theirs
    on ``data.missing`` at a third of the work."""
    return data.missing[:, ::3]


class EBD(WindowEngine):
    """Fills gaps from context: B-LSTM over a strided window, observed samples kept."""

    STRIDE = 4
    RUN = 32
    INFERENCE_CHUNK = 512  # 10-minute take, bf16 on AMX: 3.7-3.9 s against 4.2 with 128, bit-identical
    WINDOW_VALUES = False  # the network's step is added to the centre frame's angles
    WITH_MASK = True
    MISSING_ONLY = True
    ERRORS_IN_STDS = True
    FRAME_RMS_LOSS = False

    @dataclass(frozen=True)
    class Params(TrainingParams):
        epochs: int = training(45)
        #: LSTM units per direction in each of the two B-LSTM layers (paper: 32)
        lstm_units: int = trained(32)
        #: frames over which the network's fill takes over from the linear one, from
        #: each gap edge (0: the network's fill everywhere); see the module docstring. As
        #: many frames at every rate: as a duration (10 at 30 fps) it filled Bandai's 0.1-s
        #: and 1-2-s holes worse (``docs/studio-data.md``, *Frame-counted settings at 30 fps*)
        blend_frames: float = 40.0
        #: holes up to this long (frames at 120 fps: 0.5 s, as long at every rate) with
        #: samples on both sides: the fill takes over from the constant-velocity
        #: smoother's path instead of the line, in quiet takes (0: the line everywhere,
        #: the paper); see the module docstring
        smooth_hole_frames: int = 60

        def __post_init__(self) -> None:
            super().__post_init__()
            if self.blend_frames < 0:
                raise ValueError(f"blend_frames must be >= 0, got {self.blend_frames}")
            if self.smooth_hole_frames < 0:
                raise ValueError(
                    f"smooth_hole_frames must be 0 (off) or a number of frames, got {self.smooth_hole_frames}"
                )

    info = EngineInfo(
        name="ebd",
        summary="Encoder-Bidirectional-Decoder: fills gaps from 60 frames of context each side",
        tasks=frozenset({"fill"}),
        trainable=True,
        keeps_observed=True,
        citation="Mall et al. 2017, Deep recurrent mocap cleaning, §3 (gap filling)",
    )

    def _build_net(self, n_channels: int):
        from .nets import WindowNet

        return WindowNet(
            2 * n_channels + 3,
            n_channels,
            encoder=True,
            recurrent=True,
            lstm_units=self.params.lstm_units,
            dropout=self.params.dropout,
            window=2 * RADIUS + 1,
        )

    def _predict(self, net, windows, values, valid, trig=None):
        import torch

        centre = values[:, values.shape[1] // 2]
        step = net(windows).to(values.dtype) * torch.as_tensor(self.norm_.angle_std, dtype=values.dtype)
        return centre + step, {}

    def _bridge(self, observation: Observation, data: FrameData) -> np.ndarray:
        """(F, C) the angle channels the network's fill takes over from: bridged linearly,
        or, in holes no longer than ``smooth_hole_frames`` last at 120 fps with samples on
        both sides, along the constant-velocity smoother's path where the take's angles
        are quiet (:func:`workbench.engine.smoothing.angles_are_quiet`)."""
        L = self.params.smooth_hole_frames * observation.motion.fps / REFERENCE_FPS
        holes = data.missing & np.repeat(hole_length(joint_missing(data)) <= L, 3, axis=1)
        if not (L and holes.any() and angles_are_quiet(observation.skeleton, data.X, observation.observed)):
            return data.values
        return np.where(holes, smooth_and_fill(data.values, ~data.missing), data.values)

    def _training_pairs(self, motions: Sequence[Motion], epoch: int) -> list[tuple[Observation, Motion]]:
        rng = np.random.default_rng([self.params.seed, 4, epoch])
        seeds = self.epoch_seeds(epoch, len(motions) * len(GAP_MODELS))
        pairs = []
        for i, motion in enumerate(motions):
            for k, gaps in enumerate(GAP_MODELS):
                m = self.retimed(motion, rng)
                level = NOISE_LEVELS[rng.integers(len(NOISE_LEVELS))]
                spec = parse_corruption(f"angular:{level}+{gaps}" if level else gaps)
                obs = spec.apply(m, int(seeds[i * len(GAP_MODELS) + k]))
                observed = obs.observed.copy()
                F, J = observed.shape
                n = min(int(rng.uniform(*LONG_GAP_S) * m.fps), F - 2)
                start = rng.integers(0, F - n + 1)
                observed[start : start + n, rng.integers(1, J)] = False
                pairs.append((Observation(obs.motion, observed), m))
        return pairs

    @one_blas_thread
    def _clean(self, observation: Observation) -> CleanResult:
        """The observation with its missing joint angles synthesised (observed samples
        unchanged); no diagnostics."""
        data = self._frame_data(observation)
        X = data.X  # the bridged channels, filled in place: a long take's arrays are 50 MB each
        centres = np.flatnonzero(data.missing.any(axis=1))
        if centres.size:
            pred, _ = self._run(data, centres)
            rows, cols = np.nonzero(data.missing[centres])  # the missing entries alone: a tenth of a gappy take
            frames = centres[rows]
            blend, share = self.params.blend_frames, 1.0
            if blend > 0:
                share = np.clip(gap_distance(joint_missing(data))[frames, cols // 3] / blend, 0.0, 1.0)
            base = self._bridge(observation, data)[frames, cols]
            X[frames, angle_columns(observation.skeleton)[cols]] = base + share * (pred[rows, cols] - base)
            del pred, share, base
        del data
        out = rewrap_angles(X, observation, copy=False)
        del X
        np.copyto(out, observation.motion.channels, where=observation.channel_observed)  # observed: as they were
        return CleanResult(observation.motion.with_channels(out))
