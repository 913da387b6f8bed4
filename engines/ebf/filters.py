"""``ebf``: Encoder-Bidirectional-Filter (Mall et al. 2017 §3), and its ablations ``bf``
(no encoder) and ``nn`` (feed-forward over the window).

Per frame the network sees the C joint-angle channels (the rotation channels of every joint
but the root; unwrapped, normalised with the training mean and std, or their steps with
``step_inputs``) and the root's 3 angular velocities (its own frame, deg/s over the last
1/15 s: heading-invariant context, not output).
EBF: 4 tanh layers encode each frame to 64 numbers; 2 bidirectional LSTM layers
(``lstm_units`` per direction, input dropout 0.5) read the 31-frame window around each
output frame (15 back, 15 ahead); 4 fully connected layers (tanh, then exp) give one
Gaussian std in frames per channel. The cleaned channel is the Gaussian-weighted
average of the noisy channel over the window (weights renormalised over the frames
that exist at the clip's ends). The root's position and rotation, which the paper passes
through, get a Gaussian over the same window whose width grows with the noise found in
it (:mod:`.root`; ``root_sigma_frames=0`` passes them through); gaps are bridged
linearly first (use ``ebd>ebf`` for data with gaps).

Variants: ``bias=true`` also predicts a per-channel bias (degrees) that is subtracted
(trained on angular, constant-bias and sinusoidal-bias noise); ``free=true`` predicts 31 free
filter weights per channel (softmax) instead of a Gaussian. Ours: ``positions=true`` is also
trained on joint-position noise solved back to angles (a fourth copy of every clip with
``spatial:0.5``, ``spatial:1`` or ``spatial-ends:0.5,0.1``): marker noise is not independent
per channel. ``noise_context=true`` also shows the network the take's own noise std per
channel (:func:`.features.noise_context`, as kalman estimates it: a window cannot tell fast
motion from noise, a whole take can; so it does not stream), and ``smoothing_context=true``
the width kalman's smoother would take for each whole channel
(:func:`.features.smoothing_context`). ``quadratic=true`` fits a parabola under the predicted
Gaussian weights instead of taking their mean (:func:`.nets.local_quadratic_weights`: no
flattened peaks). ``step_inputs=true`` gives the network each frame's angle steps from the
frame before instead of its angles (:class:`.features.Normaliser`). Each variant has its own
weights folder, ``weights/ebf/<dataset>``, ``weights/ebf-bias/<dataset>``, ...

Diagnostics, (F, D) over the channel matrix (D = 3 + 3J): ``filter_sigma_frames``, the filter's
std in frames (free filters: the weights' std; quadratic: the Gaussian's under the fit; root
channels: the root filter's); with ``bias=true``, ``bias`` (degrees, subtracted; 0 on the root).

Training: every clip of the train split every epoch (at a random speed within ±50 %) with
fresh angular noise of 0.1, 0.5 and 0.9 channel stds; loss: the mean over frames of the
frame's RMS error (degrees) of filtered against clean angles; Adam.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from workbench.core.motion import Motion, Observation, angle_columns
from workbench.corruption import parse_corruption
from workbench.engine import CleanResult, EngineInfo, trained, training
from workbench.engine.signal import rewrap_angles
from workbench.engine.threads import one_blas_thread

from .base import TrainingParams, WindowEngine
from .features import RADIUS
from .root import clean_root

#: training corruptions: every epoch each clip gets one copy per slot, its spec drawn
#: from the slot. Angular noise of 0.1, 0.5 and 0.9 channel stds (Mall et al. §4.1)
TRAINING_SLOTS = (("angular:0.1",), ("angular:0.5",), ("angular:0.9",))
#: the bias variant's slots: angular, constant-bias and sinusoidal-bias noise mixed
BIAS_TRAINING_SLOTS = tuple(tuple(f"{model}:{k}" for model in ("angular", "bias", "sine")) for k in (0.1, 0.5, 0.9))
#: the positions variant's extra slot: joint-position noise solved back to angles, as
#: marker noise reaches the angles of a real take
POSITION_TRAINING_SLOT = ("spatial:0.5", "spatial:1", "spatial-ends:0.5,0.1")
#: filter width the network starts from, frames
INITIAL_SIGMA_FRAMES = 4.0

CITATION = "Mall, Lal, Agrawal, Hajnik, Nguyen, Carr, Kavan, Vouga 2017, Deep recurrent mocap cleaning, §3"


@dataclass(frozen=True)
class FilterParams(TrainingParams):
    """Parameters of every filter engine (EBF, BF, NN)."""

    #: widest Gaussian on the root's channels, frames at 120 fps, reached when the window
    #: is noisy (:mod:`.root`: at other rates the position's lasts as long, the
    #: rotation's is as many frames; 0: the root passes through, as in the paper)
    root_sigma_frames: float = 5.0

    def __post_init__(self) -> None:
        super().__post_init__()
        if not (math.isfinite(self.root_sigma_frames) and self.root_sigma_frames >= 0):
            raise ValueError(f"root_sigma_frames must be a number >= 0, got {self.root_sigma_frames}")


class FilterEngine(WindowEngine):
    """Engines predicting an adaptive filter per channel and frame (EBF, BF, NN)."""

    #: per-frame encoder before the window core
    ENCODER = True
    #: B-LSTM core (else 6 fully connected layers over the flattened window)
    RECURRENT = True

    @property
    def bias(self) -> bool:
        return getattr(self.params, "bias", False)

    @property
    def free(self) -> bool:
        return getattr(self.params, "free", False)

    @property
    def positions(self) -> bool:
        return getattr(self.params, "positions", False)

    @property
    def quadratic(self) -> bool:
        return getattr(self.params, "quadratic", False)

    def _build_net(self, n_channels: int):
        import torch

        from .nets import WindowNet

        L, C = 2 * RADIUS + 1, n_channels
        n_out = (L if self.free else 1) * C + (C if self.bias else 0)
        net = WindowNet(
            C + 3 + (C if self.noise_context else 0) + (C if self.smoothing_context else 0),
            n_out,
            encoder=self.ENCODER,
            recurrent=self.RECURRENT,
            lstm_units=getattr(self.params, "lstm_units", 0),
            dropout=self.params.dropout,
            window=L,
        )
        with torch.no_grad():  # start from a Gaussian of INITIAL_SIGMA_FRAMES everywhere
            d = torch.arange(-RADIUS, RADIUS + 1, dtype=torch.float32)
            start = (
                (-0.5 * d**2 / INITIAL_SIGMA_FRAMES**2).repeat_interleave(C)
                if self.free
                else torch.full((C,), math.log(INITIAL_SIGMA_FRAMES))
            )
            net.head[-1].bias[: start.numel()] = start
        return net

    def _predict(self, net, windows, values, valid, trig=None):
        return self._filter(net(windows), values, valid, trig)

    def _filter(self, z, values, valid, trig=None):
        """:meth:`_predict` from the network's outputs ``z`` (B, n_out) for the windows."""
        import torch

        from .nets import (
            circular_mean,
            filter_windows,
            gaussian_filter,
            local_quadratic_weights,
            offsets_like,
            sigma_frames,
            weights_sigma,
        )

        B, L, C = values.shape
        z = z.to(values.dtype)
        offsets = offsets_like(values)
        if self.free:
            out, weights = filter_windows(z[:, : L * C].reshape(B, L, C), values, valid, trig)
            sigma = weights_sigma(weights, offsets)
        else:
            sigma = sigma_frames(z[:, :C])
            if self.quadratic:
                out = circular_mean(local_quadratic_weights(sigma, offsets, valid), values, trig)
            else:
                out = gaussian_filter(sigma, values, valid, trig)
        diag = {"filter_sigma_frames": sigma}
        if self.bias:
            bias = z[:, -C:] * torch.as_tensor(self.norm_.angle_std, dtype=values.dtype)
            out = out - bias
            diag["bias"] = bias
        return out, diag

    def _training_pairs(self, motions: Sequence[Motion], epoch: int) -> list[tuple[Observation, Motion]]:
        slots = BIAS_TRAINING_SLOTS if self.bias else TRAINING_SLOTS
        if self.positions:
            slots += (POSITION_TRAINING_SLOT,)
        rng = np.random.default_rng([self.params.seed, 3, epoch])
        seeds = iter(self.epoch_seeds(epoch, len(motions) * len(slots)))
        pairs = []
        for m in motions:
            for slot in slots:
                clean = self.retimed(m, rng)
                pairs.append((parse_corruption(slot[rng.integers(len(slot))]).apply(clean, int(next(seeds))), clean))
        return pairs

    @one_blas_thread
    def _clean(self, observation: Observation) -> CleanResult:
        """Cleaned motion (gaps bridged linearly, then filtered) and diagnostics (F, D)."""
        data = self._frame_data(observation)
        pred, diag = self._run(data, np.arange(data.n_frames))
        cols = angle_columns(observation.skeleton)
        Y = data.X  # the bridged channels, filtered in place: a long take's arrays are 50 MB each
        del data
        Y[:, cols] = pred
        del pred
        diagnostics = {}
        for key in list(diag):
            full = np.zeros_like(Y)
            full[:, cols] = diag.pop(key)
            diagnostics[key] = full
        if self.params.root_sigma_frames > 0 and Y.shape[0]:
            skeleton = observation.skeleton
            Y[:, :6], sigma = clean_root(
                Y[:, :6],
                self.params.root_sigma_frames,
                skeleton.unit_cm,
                skeleton.rotation_order(0),
                observation.motion.fps,
            )
            diagnostics["filter_sigma_frames"][:, :6] = np.repeat(sigma, 3, axis=1)
        return CleanResult(observation.motion.with_channels(rewrap_angles(Y, observation, copy=False)), diagnostics)

    def stream(self, skeleton, fps: float):
        """A :class:`~engines.ebf.stream.FilterStream` for takes of ``skeleton`` at
        ``fps``: push frames (D,) one at a time, get each cleaned frame 15 frames later,
        identical to offline :meth:`clean`."""
        from .stream import FilterStream

        return FilterStream(self, skeleton, fps)


class EBF(FilterEngine):
    """Encoder-Bidirectional-Filter: adaptive Gaussian filter per channel and frame."""

    @dataclass(frozen=True)
    class Params(FilterParams):
        #: LSTM units per direction in each of the two B-LSTM layers (paper: 126)
        lstm_units: int = trained(64)
        #: also predict and subtract a per-channel bias (for biased noise)
        bias: bool = trained(False)
        #: free filter shapes (31 softmax weights per channel) instead of Gaussians
        free: bool = trained(False)
        #: also trained on joint-position noise (for marker-based takes; our addition)
        positions: bool = trained(False)
        #: the network also sees the take's own noise level per channel (our addition;
        #: offline only: it is estimated over the whole take)
        noise_context: bool = trained(False)
        #: the network also sees the width kalman would give each channel of the take
        #: (our addition; offline only: it is chosen over the whole take)
        smoothing_context: bool = trained(False)
        #: the predicted Gaussian weights a local quadratic fit instead of a mean (our
        #: addition: it follows peaks and fast motion that a mean flattens and lags)
        quadratic: bool = trained(False)
        #: the network reads each frame's angle steps from the frame before instead of its
        #: angles (our addition: inputs that do not depend on the pose, so the widths it
        #: learns carry over to styles it has not seen)
        step_inputs: bool = trained(False)

        def __post_init__(self) -> None:
            super().__post_init__()
            if self.lstm_units < 1:
                raise ValueError("lstm_units must be >= 1")
            if self.free and self.quadratic:
                raise ValueError("free and quadratic are two filter shapes; choose one")

    info = EngineInfo(
        name="ebf",
        summary="Encoder-Bidirectional-Filter: a B-LSTM predicts a Gaussian filter per channel and frame",
        tasks=frozenset({"denoise"}),
        trainable=True,
        citation=CITATION,
    )


class BF(FilterEngine):
    """Ablation: EBF without the encoder (the B-LSTM reads the frame features directly)."""

    ENCODER = False

    @dataclass(frozen=True)
    class Params(FilterParams):
        #: LSTM units per direction in each of the two B-LSTM layers
        lstm_units: int = trained(64)

    info = EngineInfo(
        name="bf",
        summary="ablation of EBF without the encoder (B-LSTM on raw frame features, Gaussian filter)",
        tasks=frozenset({"denoise"}),
        trainable=True,
        citation=CITATION.replace("§3", "§4.1 (ablation BF)"),
    )


class NN(FilterEngine):
    """Ablation: 6 fully connected layers over the whole 31-frame window, no recurrence."""

    RECURRENT = False

    @dataclass(frozen=True)
    class Params(FilterParams):
        epochs: int = training(45)

    info = EngineInfo(
        name="nn",
        summary="ablation of EBF: feed-forward network over the 31-frame window predicts the Gaussian filters",
        tasks=frozenset({"denoise"}),
        trainable=True,
        citation=CITATION.replace("§3", "§4.1 (ablation NN)"),
    )
