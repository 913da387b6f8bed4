"""Training shared by ``cae``, ``cae-vanilla`` and ``holden`` (Kaufmann et al. 2020, §3.3).

Each step draws a batch of windows (``window_frames`` frames) of normalised training
images, each window from a clip with probability proportional to its length, at a
random start (clips shorter than a window are reflected at their end, as at
inference); half of them mirrored left/right. Every window gets one of two holes, at
random with equal chance:

* a block of whole frames (every joint and the root missing), length drawn from
  N(mu_e, gap_sigma_frames^2), clipped to 1..T-2, at a uniform start with at least one
  known frame on each side; the curriculum raises mu_e from 10 frames by 10 every
  ``curriculum_epochs`` epochs up to 120. In 30 % of the blocks of 10 frames or more,
  1 to 3 random joints stay known over 5 to 30 frames inside the block (partial poses,
  e.g. tracked end effectors): this teaches the network to follow such entries, which
  is what the constraints of tertiary motion blending are;
* 1 to 3 joints whose angles are missing for the whole window (among the joints whose
  angles vary in the training data): in this position image, every joint below them
  is unknown (:func:`representation.known_positions`), exactly what the ``joints:N``
  corruption does.

Augmentation (our data is a small fraction of the paper's): left/right mirroring (joints
swapped by name) and every clip also played 10 % slower and faster. Trained for 32
epochs without the six held-out training clips and scored on them, the two together
lowered the reconstruction error from 4.8 to 4.2 cm and the gap error from 5.6 to
5.4 cm (60 frames) and 8.1 to 7.7 cm (120 frames), though the training loss ended
higher (less overfitting). Rotation about the up axis would change nothing: the image
is heading-invariant.

Unknown entries enter as 0 (the training mean) and the known-mask is the second input
channel. The loss is the L1 distance over the whole window (all rows, all frames),
Adam at ``learning_rate``, held for the first three quarters of the epochs and then
annealed (cosine) to a tenth.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np
import torch

from engines.torch_support import progress

from .representation import Layout, image_mask, known_positions

GAP_START_FRAMES = 10
GAP_STEP_FRAMES = 10
GAP_MAX_FRAMES = 120
#: share of the blocks (10 frames or longer) given partial poses inside
PARTIAL_PROBABILITY = 0.3


def gap_mean_frames(epoch: int, curriculum_epochs: int) -> int:
    """mu_e, the mean block length at ``epoch`` (0-based) of the curriculum."""
    return min(GAP_START_FRAMES + GAP_STEP_FRAMES * (epoch // max(curriculum_epochs, 1)), GAP_MAX_FRAMES)


class WindowSampler:
    """Batches of normalised windows (B, T, H) and their known-masks (B, T, H) from raw
    training images (each (F_i, H), padded to at least T frames), with mirroring and
    holes. A window comes from image i with probability proportional to ``frames[i]``,
    its length before padding, so every captured frame is drawn equally often."""

    def __init__(self, images: Sequence[np.ndarray], frames: Sequence[int], mean: np.ndarray, std: np.ndarray,
                 layout: Layout, mirror: tuple[np.ndarray, np.ndarray] | None, maskable: np.ndarray,
                 window_frames: int, gap_sigma_frames: float, rng: np.random.Generator) -> None:
        self.images = [((im - mean) / std).astype(np.float32) for im in images]
        self.mirrored = None
        if mirror is not None:
            perm, sign = mirror
            self.mirrored = [((im[:, perm] * sign - mean) / std).astype(np.float32) for im in images]
        self.lengths = np.array([im.shape[0] for im in images])
        self.weights = np.asarray(frames, float) / np.sum(frames)
        self.layout, self.maskable, self.T = layout, maskable, window_frames
        self.sigma, self.rng = gap_sigma_frames, rng

    def batch(self, size: int, gap_mean: float) -> tuple[np.ndarray, np.ndarray]:
        """(size, T, H) normalised windows and (size, T, H) known-masks."""
        rng, T = self.rng, self.T
        clips = rng.choice(len(self.images), size=size, p=self.weights)
        starts = rng.integers(0, self.lengths[clips] - T + 1)
        flip = rng.random(size) < 0.5 if self.mirrored is not None else np.zeros(size, bool)
        X = np.stack([(self.mirrored if f else self.images)[c][s:s + T] for c, s, f in zip(clips, starts, flip)])
        observed = np.ones((size, T, self.layout.n_joints), bool)
        block = rng.random(size) < 0.5
        blocks = []
        for b in range(size):
            if block[b]:
                n = int(np.clip(round(rng.normal(gap_mean, self.sigma)), 1, T - 2))
                s = int(rng.integers(1, T - n))
                observed[b, s:s + n] = False
                blocks.append((b, s, n))
            else:
                k = min(int(rng.integers(1, 4)), self.maskable.size)
                observed[b, :, rng.choice(self.maskable, size=k, replace=False)] = False
        mask = image_mask(self.layout, known_positions(observed, self.layout.parents))
        for b, s, n in blocks:  # partial poses inside some blocks: a few joints over a few frames
            if n >= 10 and rng.random() < PARTIAL_PROBABILITY:
                length = int(rng.integers(5, min(n, 30) + 1))
                start = s + int(rng.integers(0, n - length + 1))
                for j in rng.choice(self.layout.joints, size=int(rng.integers(1, 4)), replace=False):
                    mask[b, start:start + length, self.layout.rows(int(j))] = True
        return X, mask


def network_input(X: np.ndarray, mask: np.ndarray) -> torch.Tensor:
    """(B, 2, H, T) float32 network input from normalised images (B, T, H) and masks."""
    x = np.stack([np.where(mask, X, 0.0), mask], axis=1).astype(np.float32)
    return torch.from_numpy(np.ascontiguousarray(x.transpose(0, 1, 3, 2)))


def train(net: torch.nn.Module, sampler: WindowSampler, epochs: int, batches_per_epoch: int, batch_size: int,
          learning_rate: float, curriculum_epochs: int, desc: str) -> list[float]:
    """Train ``net`` in place; returns the mean L1 loss of every epoch."""
    opt = torch.optim.Adam(net.parameters(), lr=learning_rate, fused=True)
    anneal_from = int(0.75 * epochs)
    net.train()
    log: list[float] = []
    bar = progress(range(epochs), desc=desc)
    for epoch in bar:
        if epoch >= anneal_from:
            frac = (epoch - anneal_from) / max(epochs - anneal_from, 1)
            for g in opt.param_groups:
                g["lr"] = learning_rate * (0.1 + 0.9 * 0.5 * (1 + math.cos(math.pi * frac)))
        gap = gap_mean_frames(epoch, curriculum_epochs)
        total = 0.0
        for _ in range(batches_per_epoch):
            X, mask = sampler.batch(batch_size, gap)
            target = torch.from_numpy(np.ascontiguousarray(X.transpose(0, 2, 1)))
            loss = (net(network_input(X, mask)) - target).abs().mean()
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            total += loss.item()
        log.append(total / batches_per_epoch)
        bar.set_postfix(loss=f"{log[-1]:.4f}", gap=gap)
    net.eval()
    return log
