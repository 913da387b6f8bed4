"""Training shared by ``cae``, ``cae-vanilla`` and ``holden`` (Kaufmann et al. 2020, §3.3).

Lengths are in frames at the network's rate (:attr:`.engine.ConvAutoencoderEngine.NETWORK_FPS`).
Each step draws a batch of windows (``window_frames`` frames) of training images, each window
from a clip drawn uniformly (``sampling="clips"``, the default; ours: a few long takes hold much
of our training frames) or with probability proportional to its length (``"frames"``), at a
random start (clips too short are reflected at their end, as at inference), augmented and
normalised (:meth:`WindowSampler.windows`).

Every window gets one of two holes, at random with equal chance (the paper's two):

* a block of whole frames (every joint and the root missing), length drawn from
  N(mu_e, gap_sigma_frames^2), clipped to 1..T-2, at a uniform start with at least one known
  frame on each side; the curriculum raises mu_e from 10 frames by 10 every ``curriculum_epochs``
  epochs up to 120. In :data:`PARTIAL_PROBABILITY` of the blocks of 10 frames or more, 1 to 3
  random joints stay known over 5 to 30 frames inside the block (ours: partial poses, e.g.
  tracked end effectors, teach the network to follow the constraints of tertiary motion blending);
* 1 to 3 joints whose angles are missing for the whole window (among the joints whose angles vary
  in the training data): in this position image every joint below them is unknown
  (:func:`workbench.core.motion.position_unknown`), exactly what the ``joints:N`` corruption does.

Augmentation (ours: our six training subjects are a small fraction of the paper's data): each
window played at a random speed (linear interpolation; velocities scaled with it), its body and
motion scaled uniformly by a few per cent, mirrored left/right (joints swapped by name) half of the
time, and Gaussian noise on the known input entries (the target stays clean); the images may
include copies of the clips with other upper-body poses (``pose_copies``, made in
:meth:`.engine.ConvAutoencoderEngine.fit`). Rotation about the up axis would change nothing: the
image is heading-invariant.

Unknown entries enter bridged linearly over time from the known entries of their row
(``input_fill="linear"``, the default; ours: the network sees the gap's ends where it works on the
gap; rows never known enter as 0, the training mean) or all as 0 (``"zero"``, the paper); the
known-mask is the second input channel.

The loss is the L1 distance over the whole window, as in the paper, but for the rows of canonical
joints the window's skeleton lacks (toes), never known in its input either, as at inference. Adam
at the rate :func:`learning_rate_at` gives each epoch: held, then annealed (cosine) to a tenth. The
weights kept are the exponential moving average of the steps' weights (``ema_decay`` per step;
ours: it damps the last steps' noise). History and results: docs/engines/cae.md.
"""

from __future__ import annotations

import math
import warnings
from typing import Sequence

import numpy as np
import torch

from workbench.core.channels import interpolate_frames, interpolate_gaps
from workbench.core.motion import position_unknown
from workbench.engine.torch_support import progress

from .representation import TAIL_ROWS, Layout, image_mask, pad_time

GAP_START_FRAMES = 10
GAP_STEP_FRAMES = 10
GAP_MAX_FRAMES = 120
#: share of the blocks (10 frames or longer) given partial poses inside
PARTIAL_PROBABILITY = 0.3


def gap_mean_frames(epoch: int, curriculum_epochs: int) -> int:
    """mu_e, the mean block length at ``epoch`` (0-based) of the curriculum."""
    return min(GAP_START_FRAMES + GAP_STEP_FRAMES * (epoch // max(curriculum_epochs, 1)), GAP_MAX_FRAMES)


def learning_rate_at(epoch: int, epochs: int, learning_rate: float, anneal_from_pct: float) -> float:
    """The learning rate of ``epoch`` (0-based) of ``epochs``: ``learning_rate`` for the
    first ``anneal_from_pct`` per cent of them, then annealed (cosine) to a tenth of it."""
    anneal_from = int(anneal_from_pct / 100 * epochs)
    if epoch < anneal_from:
        return learning_rate
    frac = (epoch - anneal_from) / max(epochs - anneal_from, 1)
    return learning_rate * (0.1 + 0.9 * 0.5 * (1 + math.cos(math.pi * frac)))


class WindowSampler:
    """Batches of windows (B, T, H) from raw training images (each (F_i, H)): played at a
    random speed, scaled, mirrored, normalised, with holes and input noise. A window
    comes from image i with probability proportional to its length F_i (``sampling``
    "frames": every captured frame is drawn equally often) or alike for every image
    ("clips"); with ``groups`` (one label per image: its skeleton layout) each group is
    drawn equally often, its images as ``sampling`` says, so a data set of many takes does
    not drown a smaller one. Images too short for a window are reflected at their end
    (:func:`representation.pad_time`), as at inference."""

    def __init__(
        self,
        images: Sequence[np.ndarray],
        mean: np.ndarray,
        std: np.ndarray,
        layout: Layout,
        mirror: tuple[np.ndarray, np.ndarray] | None,
        maskable: np.ndarray,
        window_frames: int,
        gap_sigma_frames: float,
        time_scale_pct: float,
        body_scale_pct: float,
        input_noise: float,
        input_fill: str,
        sampling: str,
        rng: np.random.Generator,
        groups: Sequence[int] | None = None,
        present: Sequence[np.ndarray] | None = None,
    ) -> None:
        self.max_speed = 1 + time_scale_pct / 100
        span = int(math.ceil((window_frames - 1) * self.max_speed)) + 2
        self.weights = np.array([im.shape[0] if sampling == "frames" else 1 for im in images], float)
        if groups is not None:
            labels = np.asarray(groups)
            for g in np.unique(labels):
                self.weights[labels == g] /= self.weights[labels == g].sum()
        self.weights /= self.weights.sum()
        self.images = [pad_time(im, im, span)[0] for im in images]
        self.lengths = np.array([im.shape[0] for im in self.images])
        self.mean, self.std, self.mirror = mean, std, mirror
        self.layout, self.maskable, self.T = layout, maskable, window_frames
        self.sigma, self.body_scale, self.noise = gap_sigma_frames, body_scale_pct / 100, input_noise
        self.fill, self.rng = input_fill, rng
        H = images[0].shape[1]
        self.present = np.ones((len(images), H), bool) if present is None else np.stack(present)

    def windows(self, size: int) -> tuple[np.ndarray, np.ndarray]:
        """(size, T, H) normalised windows: each played ``speed`` times as fast (drawn
        log-uniformly in [1 / max_speed, max_speed]; linear interpolation, the velocity
        and turning-rate rows times ``speed``), scaled uniformly by 1 +- body_scale (every
        row but the turning rate: lengths and velocities), half of them mirrored; and
        (size, H) the rows each window's skeleton has (its image's ``present``)."""
        rng, T = self.rng, self.T
        clips = rng.choice(len(self.images), size=size, p=self.weights)
        speed = np.exp(rng.uniform(-1.0, 1.0, size) * np.log(self.max_speed))
        starts = rng.uniform(0.0, self.lengths[clips] - 1 - (T - 1) * speed)
        t = starts[:, None] + np.arange(T) * speed[:, None]
        X = np.stack([interpolate_frames(self.images[c], t[b]) for b, c in enumerate(clips)])
        X[..., -TAIL_ROWS:] *= speed[:, None, None]
        X[..., :-1] *= rng.uniform(1 - self.body_scale, 1 + self.body_scale, (size, 1, 1))
        present = self.present[clips]
        if self.mirror is not None:
            flip = rng.random(size) < 0.5
            X[flip] = X[flip][..., self.mirror[0]] * self.mirror[1]
            present[flip] = present[flip][:, self.mirror[0]]
        return ((X - self.mean) / self.std).astype(np.float32), present

    def batch(self, size: int, gap_mean: float) -> tuple[np.ndarray, torch.Tensor, np.ndarray]:
        """(size, T, H) normalised windows (the target), the network input (size, 2, H,
        T): the windows with holes, noise N(0, input_noise^2) on the known entries, and
        (size, H) the rows each window's skeleton has (the others never known)."""
        rng, T = self.rng, self.T
        X, present = self.windows(size)
        observed = np.ones((size, T, self.layout.n_joints), bool)
        block = rng.random(size) < 0.5
        blocks = []
        for b in range(size):
            if block[b]:
                n = int(np.clip(round(rng.normal(gap_mean, self.sigma)), 1, T - 2))
                s = int(rng.integers(1, T - n))
                observed[b, s : s + n] = False
                blocks.append((b, s, n))
            else:
                k = min(int(rng.integers(1, 4)), self.maskable.size)
                observed[b, :, rng.choice(self.maskable, size=k, replace=False)] = False
        mask = image_mask(self.layout, ~position_unknown(observed, self.layout.parents))
        for b, s, n in blocks:  # partial poses inside some blocks: a few joints over a few frames
            if n >= 10 and rng.random() < PARTIAL_PROBABILITY:
                length = int(rng.integers(5, min(n, 30) + 1))
                start = s + int(rng.integers(0, n - length + 1))
                for j in rng.choice(self.layout.joints, size=int(rng.integers(1, 4)), replace=False):
                    mask[b, start : start + length, self.layout.rows(int(j))] = True
        mask &= present[:, None, :]
        noisy = X + (self.noise * rng.standard_normal(X.shape)).astype(np.float32) if self.noise > 0 else X
        return X, network_input(noisy, mask, self.fill), present


def image_units(
    images: Sequence[np.ndarray], present: Sequence[np.ndarray], mirror: tuple[np.ndarray, np.ndarray] | None
) -> tuple[np.ndarray, np.ndarray]:
    """The normalisation of training images (each (F_i, H)): the mean and std (H,) of
    each row over the images that have it (``present``, one (H,) bool per image; a row
    no image has gets 0 and 1), their mirrored copies too, the std floored at 1e-6;
    rounded to float32 as they are saved, so a loaded engine computes what the fitted
    one does."""
    parts = [im if has.all() else np.where(has, im, np.nan) for im, has in zip(images, present)]
    if mirror is not None:
        parts += [im[:, mirror[0]] * mirror[1] for im in parts]
    pool = np.concatenate(parts)
    del parts
    if all(has.all() for has in present):  # the same numbers, without nanmean's copies of the pool
        mean, std = pool.mean(axis=0), pool.std(axis=0)
    else:
        with warnings.catch_warnings():  # the rows no image has: NaN, then 0 and 1
            warnings.simplefilter("ignore", RuntimeWarning)
            mean, std = np.nanmean(pool, axis=0), np.nanstd(pool, axis=0)
    none = np.isnan(mean)
    mean[none], std[none] = 0.0, 1.0
    return mean.astype(np.float32).astype(float), np.maximum(std, 1e-6).astype(np.float32).astype(float)


def network_input(X: np.ndarray, mask: np.ndarray, fill: str) -> torch.Tensor:
    """(B, 2, H, T) float32 network input from normalised images (B, T, H) and masks; the
    unknown entries are 0 (``fill="zero"``, the training mean) or bridged linearly over
    time from the known entries of their row (``"linear"``; 0 in rows never known)."""
    out = np.empty((len(X), 2, X.shape[2], X.shape[1]), np.float32)
    for x, m, o in zip(X, mask, out):  # an image at a time: no float64 copy of the batch
        o[0] = (interpolate_gaps(x, m) if fill == "linear" else np.where(m, x, 0.0)).T
        o[1] = m.T
    return torch.from_numpy(out)


def train(
    net: torch.nn.Module,
    sampler: WindowSampler,
    epochs: int,
    batches_per_epoch: int,
    batch_size: int,
    learning_rate: float,
    anneal_from_pct: float,
    curriculum_epochs: int,
    ema_decay: float,
    desc: str,
) -> list[float]:
    """Train ``net`` in place; returns the mean L1 loss of every epoch. With ``ema_decay``
    > 0, ``net`` ends with the exponential moving average of its weights over the steps
    (this decay per step) instead of the last step's weights; the learning rate of each
    epoch is :func:`learning_rate_at`'s."""
    opt = torch.optim.Adam(net.parameters(), lr=learning_rate, fused=True)
    ema = None
    if ema_decay > 0:
        from torch.optim.swa_utils import AveragedModel, get_ema_multi_avg_fn

        ema = AveragedModel(net, multi_avg_fn=get_ema_multi_avg_fn(ema_decay))
    net.train()
    log: list[float] = []
    bar = progress(range(epochs), desc=desc)
    for epoch in bar:
        for g in opt.param_groups:
            g["lr"] = learning_rate_at(epoch, epochs, learning_rate, anneal_from_pct)
        gap = gap_mean_frames(epoch, curriculum_epochs)
        total = 0.0
        for _ in range(batches_per_epoch):
            X, x, present = sampler.batch(batch_size, gap)
            target = torch.from_numpy(np.ascontiguousarray(X.transpose(0, 2, 1)))
            rows = torch.from_numpy(present[:, :, None].astype(np.float32))  # the L1 mean over the rows there are
            loss = ((net(x) - target).abs() * rows).mean() * (present.size / present.sum())
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            if ema is not None:
                ema.update_parameters(net)
            total += loss.item()
        log.append(total / batches_per_epoch)
        bar.set_postfix(loss=f"{log[-1]:.4f}", gap=gap)
    if ema is not None:
        net.load_state_dict(ema.module.state_dict())
    net.eval()
    return log
