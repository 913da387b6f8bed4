"""The one training loop of EBF, EBD, BF and NN (PyTorch): windows sampled as runs of
consecutive centre frames, Adam with a cosine learning-rate schedule; the loss the mean
per-frame RMS error in degrees (EBF's, BF's and NN's) or the mean squared error in training stds (EBD's),
as :func:`train` says.

Each epoch the engine makes fresh corrupted copies of the training clips (``Corpus``); the
epoch visits every frame of every copy once as a window centre. A batch holds
``segments`` runs of ``run`` consecutive centres; the encoder runs once per frame of a
run (plus its window margins), and the windows of codes are cut from there.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np
import torch

from workbench.engine.torch_support import progress

from .features import FrameData, window_offsets


@dataclass
class Corpus:
    """Frames of several clips, concatenated. inputs (N, n_in) float32 normalised
    features; values, truth (N, C) float32 degrees (corrupted, clean); missing (N, C)
    bool; start, length, local (N,) int: the clip's first row, its frame count and the
    frame's index in it."""

    inputs: torch.Tensor
    values: torch.Tensor
    truth: torch.Tensor
    missing: torch.Tensor
    start: np.ndarray
    length: np.ndarray
    local: np.ndarray
    clips: np.ndarray  # (K, 2) first row and frame count of each clip

    @classmethod
    def build(cls, pairs: list[tuple[FrameData, np.ndarray]]) -> "Corpus":
        """From (corrupted frame data, clean angle values (F, C)) pairs."""
        lengths = np.array([d.n_frames for d, _ in pairs])
        starts = np.concatenate([[0], np.cumsum(lengths)[:-1]])
        return cls(
            inputs=torch.from_numpy(np.concatenate([d.inputs for d, _ in pairs]).astype(np.float32)),
            values=torch.from_numpy(np.concatenate([d.values for d, _ in pairs]).astype(np.float32)),
            truth=torch.from_numpy(np.concatenate([t for _, t in pairs]).astype(np.float32)),
            missing=torch.from_numpy(np.concatenate([d.missing for d, _ in pairs])),
            start=np.repeat(starts, lengths),
            length=np.repeat(lengths, lengths),
            local=np.concatenate([np.arange(n) for n in lengths]),
            clips=np.stack([starts, lengths], axis=1),
        )

    def n_runs(self, run: int) -> int:
        """About how many runs :meth:`run_starts` gives."""
        return int(sum(n // run for n in self.clips[:, 1]))

    def run_starts(self, run: int, rng: np.random.Generator) -> np.ndarray:
        """Rows starting runs of ``run`` consecutive frames that tile every clip (from a
        random offset), shuffled."""
        out = []
        for s, n in self.clips:
            if n < run:
                continue
            first = rng.integers(0, min(run, n - run + 1))
            out.append(s + np.arange(first, n - run + 1, run))
        if not out:
            from workbench.engine import EngineError

            raise EngineError(f"every training take is shorter than {run} frames, the run a training step reads")
        rows = np.concatenate(out)
        return rows[rng.permutation(rows.size)]


@dataclass
class Batch:
    """frames (S, run + 2 margin, n_in) inputs to encode; positions (run, L) where each
    centre's window frames sit in a run; values (B, L, C), valid (B, L), truth and
    missing (B, C) of the B = S x run windows."""

    frames: torch.Tensor
    positions: torch.Tensor
    values: torch.Tensor
    valid: torch.Tensor
    truth: torch.Tensor
    missing: torch.Tensor


def gather(corpus: Corpus, starts: np.ndarray, run: int, radius: int, stride: int) -> Batch:
    """The batch of runs beginning at corpus rows ``starts``; window frames beyond a
    clip's ends repeat its edge frames (as at inference) and are not ``valid``."""
    margin = radius * stride
    offsets = window_offsets(radius, stride)
    start, length, local = corpus.start[starts, None], corpus.length[starts, None], corpus.local[starts, None]
    span = local + np.arange(-margin, run + margin)[None, :]
    frame_rows = start + np.clip(span, 0, length - 1)  # (S, run + 2 margin)
    centre = local + np.arange(run)[None, :]  # (S, run)
    win = centre[:, :, None] + offsets[None, None, :]  # (S, run, L)
    valid = (win >= 0) & (win < length[:, :, None])
    win_rows = start[:, :, None] + np.clip(win, 0, length[:, :, None] - 1)
    centre_rows = (start + centre).reshape(-1)
    L = offsets.size
    return Batch(
        frames=corpus.inputs[torch.from_numpy(frame_rows)],
        positions=torch.from_numpy(np.arange(run)[:, None] + margin + offsets[None, :]),
        values=corpus.values[torch.from_numpy(win_rows.reshape(-1, L))],
        valid=torch.from_numpy(valid.reshape(-1, L)),
        truth=corpus.truth[torch.from_numpy(centre_rows)],
        missing=corpus.missing[torch.from_numpy(centre_rows)],
    )


def window_codes(net, batch: Batch) -> torch.Tensor:
    """(B, L, E) windows of codes: each run's frames encoded once, then cut into windows."""
    codes = net.encode(batch.frames)  # (S, run + 2m, E)
    windows = codes[:, batch.positions]  # (S, run, L, E)
    return windows.reshape(-1, windows.shape[2], windows.shape[3])


def wrapped_error_deg(pred: torch.Tensor, truth: torch.Tensor) -> torch.Tensor:
    """Angle differences in degrees, wrapped into [-180, 180)."""
    return torch.remainder(pred - truth + 180.0, 360.0) - 180.0


def train(
    net: torch.nn.Module,
    make_corpus: Callable[[int], Corpus],
    predict: Callable,
    *,
    epochs: int,
    learning_rate: float,
    batch_windows: int,
    run: int,
    radius: int,
    stride: int,
    seed: int,
    missing_only: bool,
    error_unit: np.ndarray | None,
    frame_rms: bool,
    desc: str,
) -> list[float]:
    """Train ``net`` in place; returns each epoch's training error: the mean per-frame
    RMS error (``frame_rms``) or the RMS error over all entries the loss covers.

    make_corpus(epoch) gives that epoch's data; predict(net, windows, values, valid)
    returns ((B, C) predicted angles in degrees, diagnostics). The loss covers every
    channel, or the missing entries only (``missing_only``, EBD); errors are in degrees,
    or divided by ``error_unit`` (C,) when given (EBD: each channel's training std).
    With ``frame_rms`` (EBF, BF, NN) the loss is the L2 norm of each frame's error (its
    RMS over the channels; the benchmark's per-frame figure) averaged over frames,
    which unlike the mean squared error does not let the few frames with huge errors
    (channels near gimbal lock under heavy noise) drown the rest; otherwise it is the
    mean squared error. Adam; learning rate warmed up over the first 2 % of steps, then
    cosine-decayed to 2 % of ``learning_rate``.
    """
    rng = np.random.default_rng([seed, 1])
    unit = torch.ones(1) if error_unit is None else torch.as_tensor(error_unit, dtype=torch.float32)
    segments = max(1, batch_windows // run)
    try:
        opt = torch.optim.Adam(net.parameters(), lr=learning_rate, fused=True)
    except (RuntimeError, TypeError):
        opt = torch.optim.Adam(net.parameters(), lr=learning_rate)
    corpus = make_corpus(0)
    starts = corpus.run_starts(run, rng)  # takes too short for a run are refused before the bar is drawn
    total = epochs * math.ceil(corpus.n_runs(run) / segments)
    warmup = max(1, total // 50)
    history: list[float] = []
    step = 0
    bar = progress(range(total), desc=desc, total=total)
    t0 = time.perf_counter()
    for epoch in range(epochs):
        if epoch:
            corpus = make_corpus(epoch)
            starts = corpus.run_starts(run, rng)
        net.train()
        err_sum, count = 0.0, 0.0
        for i in range(0, starts.size, segments):
            batch = gather(corpus, starts[i : i + segments], run, radius, stride)
            pred, _ = predict(net, window_codes(net, batch), batch.values, batch.valid)
            sq = (wrapped_error_deg(pred, batch.truth) / unit) ** 2
            weight = batch.missing.float() if missing_only else torch.ones_like(sq)
            counts = weight.sum(dim=1)
            used = counts > 0
            if not used.any():
                continue
            if frame_rms:
                per_frame = torch.sqrt((sq * weight).sum(dim=1)[used] / counts[used] + 1e-6)
                loss, total_err, n = per_frame.mean(), per_frame.sum(), used.sum()
            else:
                total_err, n = (sq * weight).sum(), counts.sum()
                loss = total_err / n
            frac = min(step / warmup, 0.5 * (1 + math.cos(math.pi * min(step / total, 1.0))))
            for group in opt.param_groups:
                group["lr"] = learning_rate * max(frac, 0.02)
            opt.zero_grad(set_to_none=True)
            loss.backward()
            torch.nn.utils.clip_grad_norm_(net.parameters(), 10.0)
            opt.step()
            step += 1
            err_sum += float(total_err.detach())
            count += float(n)
            bar.update(1)
            if step % 20 == 0:
                bar.set_postfix(epoch=epoch + 1, error=f"{_error(err_sum, count, frame_rms):.3f}")
        history.append(_error(err_sum, count, frame_rms))
        bar.write(
            f"{desc} epoch {epoch + 1}/{epochs}: training error {history[-1]:.3f} ({time.perf_counter() - t0:.0f} s)",
            file=sys.stderr,
        )
    bar.close()
    net.eval()
    return history


def _error(total: float, count: float, frame_rms: bool) -> float:
    return total / max(count, 1.0) if frame_rms else math.sqrt(total / max(count, 1.0))
