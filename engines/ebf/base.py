"""What EBF, BF, NN and EBD share: windowed networks over per-frame features, trained
with one loop, saved as plain arrays, run offline on all windows of a clip at once.

Every output frame sees exactly its own window of 2 x 15 + 1 frames (at ``STRIDE``
frames apart), edge frames repeated where the window runs off the clip; this is what
lets the streaming API reproduce offline results exactly.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar, Mapping, Sequence

import numpy as np

from workbench.core.channels import retime, unwrap_deg
from workbench.core.motion import Motion, Observation
from workbench.engine import CleanResult, Engine, EngineError, training

from .features import RADIUS, FrameData, Layout, Normaliser, anchor_turns, frame_data, window_index


def _inner_windows(frames, radius: int, stride: int):
    """(F - 2 radius stride, 2 radius + 1, ...) views of the windows of ``frames`` (F, ...),
    a torch tensor with F > 2 radius stride, around frames radius stride to F - 1 - radius
    stride (those that need no edge padding): the windows ``frames[idx]`` gathers for
    :func:`window_index`'s ``idx``, without copying them (a 10-minute take's ebf gathered
    2.3 GB: 0.3 s)."""
    return frames.unfold(0, 2 * radius * stride + 1, 1)[..., ::stride].movedim(-1, 1)


@dataclass(frozen=True)
class TrainingParams:
    """Parameters common to the four engines: how they train (which does not change the
    network's shape), and ``bf16``."""

    #: passes over the training data; each pass draws fresh noise on every clip
    epochs: int = training(20)
    #: seeds network initialisation, noise and sampling
    seed: int = training(0)
    #: Adam's initial learning rate (cosine-decayed to 2 % of it)
    learning_rate: float = training(2e-3)
    #: windows per optimisation step
    batch_windows: int = training(256)
    #: dropout probability on the B-LSTM's inputs during training (paper: 0.5)
    dropout: float = training(0.5)
    #: augmentation: each training copy is played at a speed drawn log-uniformly
    #: between 1 / (1 + p/100) and 1 + p/100 (our train subjects move more slowly,
    #: relative to the noise, than the test subjects; see the issue note)
    time_scale_pct: float = training(50.0)
    #: run the B-LSTM in bfloat16 where the CPU does so natively (AMX or AVX512-BF16:
    #: :func:`~workbench.engine.torch_support.bf16_is_native`), about 3x faster; float32
    #: elsewhere, and in training
    bf16: bool = True

    def __post_init__(self) -> None:
        if self.epochs < 1 or self.batch_windows < 1 or not self.learning_rate > 0 or self.seed < 0:
            raise ValueError("epochs and batch_windows must be >= 1, learning_rate > 0 and seed >= 0")
        if self.time_scale_pct < 0:
            raise ValueError(f"time_scale_pct must be >= 0, got {self.time_scale_pct}")
        if not 0 <= self.dropout < 1:
            raise ValueError(f"dropout must be in [0, 1), got {self.dropout}")


class WindowEngine(Engine):
    """Base of the windowed network engines. Subclasses set ``info``, ``Params`` and the
    class constants, and implement :meth:`_build_net`, :meth:`_predict` and
    :meth:`_training_pairs`."""

    QUICK_FIT = {"epochs": "1"}
    #: frames between window samples (EBD: 4)
    STRIDE: ClassVar[int] = 1
    #: consecutive window centres per training run (see training.py)
    RUN: ClassVar[int] = 8
    #: network input includes the observed mask of the angle channels
    WITH_MASK: ClassVar[bool] = False
    #: the training loss covers missing entries only
    MISSING_ONLY: ClassVar[bool] = False
    #: the training loss measures errors in training stds of each channel (else degrees)
    ERRORS_IN_STDS: ClassVar[bool] = False
    #: the training loss is the mean per-frame RMS error (else the mean squared error)
    FRAME_RMS_LOSS: ClassVar[bool] = True
    #: the prediction reads the angle values of the whole window (a filter); else of its
    #: centre frame only, and inference gathers just that one (B, 1, C)
    WINDOW_VALUES: ClassVar[bool] = True
    #: windows evaluated per forward pass at inference. Small passes keep the LSTM's
    #: activations and the filter's (B, 31, C) float64 arrays near the cache: on a 39-s
    #: take (4,723 frames) ebf cleans at 7.0-8.9k frames/s with 512 against 4.4-5.2k with
    #: 4096, bit-identical (2-core AVX2 EPYC; 256 changed the output in the last bits
    #: there); on the 10-minute take 9.2-9.6 s with 128 against 9.7-11.7 s with 512,
    #: bit-identical for ebf and ebd>ebf (2-core Xeon with AMX). EBD, with no filter
    #: arrays, takes 512.
    INFERENCE_CHUNK: ClassVar[int] = 128

    net_ = None
    norm_: Normaliser | None = None
    loss_history_: np.ndarray | None = None

    # -- weights --------------------------------------------------------------------
    def state_arrays(self) -> dict[str, np.ndarray]:
        from workbench.engine.torch_support import module_arrays

        steps = {} if self.norm_.step_std is None else {"norm_step_std": self.norm_.step_std}
        return {
            **module_arrays(self.net_, "net."),
            "norm_mean": self.norm_.mean,
            "norm_std": self.norm_.std,
            **steps,
            "loss_history": np.asarray(self.loss_history_, np.float32),
        }

    def load_state_arrays(self, arrays: Mapping[str, np.ndarray], manifest: Mapping) -> None:
        from workbench.engine.torch_support import load_module_arrays

        mean, std = np.asarray(arrays["norm_mean"], float), np.asarray(arrays["norm_std"], float)
        step_std = np.asarray(arrays["norm_step_std"], float) if "norm_step_std" in arrays else None
        if (None if step_std is None else step_std.shape) != (mean[:-3].shape if self.step_inputs else None):
            raise EngineError(
                f"weights do not fit step_inputs={self.step_inputs}: they hold "
                + ("no steps' stds" if step_std is None else f"steps' stds of shape {step_std.shape}")
                + "; they were saved by another version or by hand: train again"
            )
        self.norm_ = Normaliser(mean, std, step_std)
        net = self._build_net(mean.size - 3)
        load_module_arrays(net, arrays, "net.")
        self._use_net(net)
        self.loss_history_ = np.asarray(arrays.get("loss_history", []), float)

    def _use_net(self, net) -> None:
        """Make the trained or loaded ``net`` the engine's network, in eval mode; its
        B-LSTM in bf16 where ``bf16`` asks for it and the CPU runs bf16 natively."""
        from workbench.engine.torch_support import bf16_is_native

        self.net_ = net.eval()
        if self.params.bf16 and bf16_is_native():
            net.run_core_in_bf16()

    # -- subclass hooks -------------------------------------------------------------
    def _build_net(self, n_channels: int):
        """The untrained network for ``n_channels`` joint-angle channels."""
        raise NotImplementedError

    def _predict(self, net, windows, values, valid, trig=None) -> tuple[Any, dict[str, Any]]:
        """Cleaned angles (B, C) in degrees of windows of codes (B, L, E), given the
        window's angle values (B, L, C) (or, without :attr:`WINDOW_VALUES`, possibly its
        centre frame's alone, (B, 1, C)) and ``valid`` (B, L); plus named (B, C)
        diagnostics. ``trig``: the values' :class:`.nets.Trig` where the caller has it
        (inference, with :attr:`WINDOW_VALUES`), for :func:`.nets.circular_mean`."""
        raise NotImplementedError

    def _training_pairs(self, motions: Sequence[Motion], epoch: int) -> list[tuple[Observation, Motion]]:
        """Corrupted observations of the training motions for one epoch, with their truth."""
        raise NotImplementedError

    # -- shared work ----------------------------------------------------------------
    @property
    def noise_context(self) -> bool:
        """The network sees the take's own noise level (:func:`.features.noise_context`)."""
        return getattr(self.params, "noise_context", False)

    @property
    def smoothing_context(self) -> bool:
        """The network sees the width kalman would smooth the take with
        (:func:`.features.smoothing_context`)."""
        return getattr(self.params, "smoothing_context", False)

    @property
    def step_inputs(self) -> bool:
        """The network reads each frame's angle steps from the frame before, not its angles
        (:class:`.features.Normaliser`)."""
        return getattr(self.params, "step_inputs", False)

    def _frame_data(self, observation: Observation) -> FrameData:
        return frame_data(
            observation,
            Layout.of(observation.skeleton),
            self.norm_,
            self.WITH_MASK,
            self.noise_context,
            self.smoothing_context,
        )

    def clean(self, observation: Observation, /) -> CleanResult:
        """Clean the take in the engine's view of it (:meth:`model_view`: body-rooted, at the
        rate of the weights) and put the result back on the take."""
        view = self.model_view(observation)
        return view.restore(self._clean(view.observation), self.info.keeps_observed)

    def _clean(self, observation: Observation) -> CleanResult:
        """:meth:`clean` on an observation in the engine's view (subclasses implement it)."""
        raise NotImplementedError

    def _run(self, data: FrameData, centres: np.ndarray) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """Run the network on the windows around ``centres`` (N,) of a clip: cleaned
        angles (N, C) in degrees and diagnostics (N, C), all windows batched."""
        import torch

        from .nets import Trig

        preds = np.zeros((centres.size, data.values.shape[1]))
        diags: dict[str, np.ndarray] = {}  # filled chunk by chunk: no list of chunks to join
        reach = RADIUS * self.STRIDE  # frames from a window's centre to its ends
        with torch.inference_mode():
            codes = self.net_.encode(torch.from_numpy(data.inputs))
            values = torch.from_numpy(data.values)  # float64: filters in double precision
            inner = data.n_frames > 2 * reach  # windows that need no edge padding exist
            code_windows = _inner_windows(codes, RADIUS, self.STRIDE) if inner else None
            value_windows = _inner_windows(values, RADIUS, self.STRIDE) if inner and self.WINDOW_VALUES else None
            every_frame = torch.ones((self.INFERENCE_CHUNK, 2 * RADIUS + 1), dtype=torch.bool)
            for i in range(0, centres.size, self.INFERENCE_CHUNK):
                chunk = centres[i : i + self.INFERENCE_CHUNK]
                if self.WINDOW_VALUES:  # the sines and cosines of the frames the windows span, each once
                    first = max(chunk[0] - reach, 0)
                    trig = Trig.of_degrees(values[first : min(chunk[-1] + reach, data.n_frames - 1) + 1])
                if chunk[0] >= reach and chunk[-1] < data.n_frames - reach and chunk[-1] - chunk[0] == len(chunk) - 1:
                    run = slice(chunk[0] - reach, chunk[-1] - reach + 1)  # consecutive: views
                    valid = every_frame[: len(chunk)]
                    window_codes = code_windows[run]
                    if self.WINDOW_VALUES:
                        window_values = value_windows[run]
                        window_trig = Trig(*(_inner_windows(t, RADIUS, self.STRIDE) for t in trig))
                    else:
                        window_values, window_trig = values[chunk[0] : chunk[-1] + 1, None], None
                else:
                    idx, valid = window_index(chunk, data.n_frames, RADIUS, self.STRIDE)
                    idx_t, valid = torch.from_numpy(idx), torch.from_numpy(valid)
                    window_codes = codes[idx_t]
                    if self.WINDOW_VALUES:
                        window_values, window_trig = values[idx_t], Trig(*(t[idx_t - first] for t in trig))
                    else:
                        window_values, window_trig = values[idx_t[:, RADIUS, None]], None
                pred, diag = self._predict(self.net_, window_codes, window_values, valid, window_trig)
                done = slice(i, i + len(chunk))
                preds[done] = pred.double().numpy()
                for key, value in diag.items():
                    if key not in diags:  # (setdefault's default was a whole-take array made every chunk)
                        diags[key] = np.zeros_like(preds)
                    diags[key][done] = value.double().numpy()
        return preds, diags

    def fit(self, motions: Sequence[Motion], /) -> "WindowEngine":
        """Train on clean motions of one skeleton (fresh corruption every epoch);
        progress bar and per-epoch losses on stderr."""
        from workbench.engine.torch_support import reproducible_training

        motions = self.training_motions(motions)
        with reproducible_training(self.params.seed):
            self._train(motions)
        self.fitted_on(motions[0])
        return self

    def _train(self, motions: list[Motion]) -> None:
        """Build the network and train it on ``motions``; sets the fitted state."""
        from .training import Corpus, train

        layout = Layout.of(motions[0].skeleton)
        self.norm_ = Normaliser.fit(motions, layout, steps=self.step_inputs)
        net = self._build_net(layout.n_channels)

        def truth(m: Motion) -> np.ndarray:
            return anchor_turns(unwrap_deg(m.channels[:, layout.columns]), self.norm_.angle_mean)

        def make_corpus(epoch: int) -> Corpus:
            return Corpus.build([(self._frame_data(obs), truth(m)) for obs, m in self._training_pairs(motions, epoch)])

        p = self.params
        self.loss_history_ = np.array(
            train(
                net,
                make_corpus,
                self._predict,
                epochs=p.epochs,
                learning_rate=p.learning_rate,
                batch_windows=p.batch_windows,
                run=self.RUN,
                radius=RADIUS,
                stride=self.STRIDE,
                seed=p.seed,
                missing_only=self.MISSING_ONLY,
                error_unit=self.norm_.angle_std if self.ERRORS_IN_STDS else None,
                frame_rms=self.FRAME_RMS_LOSS,
                desc=self.variant,
            )
        )
        self._use_net(net)

    def retimed(self, motion: Motion, rng: np.random.Generator) -> Motion:
        """``motion`` played at a random speed (the ``time_scale_pct`` augmentation)."""
        p = self.params.time_scale_pct
        if p <= 0:
            return motion
        X = motion.channels
        X[:, 3:] = unwrap_deg(X[:, 3:])
        return motion.with_channels(retime(X, float(np.exp(rng.uniform(-1.0, 1.0) * np.log1p(p / 100)))))

    def epoch_seeds(self, epoch: int, n: int) -> np.ndarray:
        """``n`` corruption seeds for one epoch, from the engine's seed."""
        return np.random.default_rng([self.params.seed, 2, epoch]).integers(0, 2**31 - 1, size=n)
