"""The three networks over the motion image (torch).

Every network maps an input (B, 2, H, T), the image with its unknown entries zeroed and
the known-entries mask as a second channel (our addition: a zero then never reads as
"exactly the training mean"), to the completed image (B, H, T), in normalised units.
T must be a multiple of ``time_multiple`` (callers pad the clip); H is padded to a
multiple of ``row_multiple`` inside (the last row repeated) and cropped again. The body
runs in channels_last layout, under bf16 autocast where the CPU runs bf16 natively (4-5x
faster with AMX, PERFORMANCE.md; elsewhere bf16 is emulated and far slower, so the body
runs in float32: :func:`workbench.engine.torch_support.bf16_is_native`); the output layer runs in
float32 so the result carries no bf16 rounding. Weights start from He (kaiming)
initialisation: with PyTorch's default the 2-D autoencoder does not learn here. Leaky
ReLU slope 0.2.

* :class:`KaufmannNet` (``cae``, §3.2): 5 encoding units of two 3x3 convolutions with
  leaky ReLU and 2x2 max pooling; 5 decoding units mirroring them, each a strided 3x3
  transposed convolution (x2 in both axes) and, but in the last, a 3x3 convolution
  (the output layer follows it), no weights shared, no activation on the output.
  Widths 16, 32, 64, 128, 192 (the paper's are about twice that; these train at about
  30k frames/s here and keep the float32 weights under 10 MB): 2.0M weights, a 2 x T/32 x 192
  latent for the 64-row CMU image.
* :class:`VanillaNet` (``cae-vanilla``, the "Vanilla AE" of Table 1): one strided 3x3
  convolution per encoding unit and one strided 3x3 transposed convolution per decoding
  unit.
* :class:`HoldenNet` (``holden``, Holden et al. 2016's motion manifold): a temporal
  convolution over frames with the pose rows (and mask) as channels, ReLU, max pooling
  over 2 frames; the decoder unpools (Psi-dagger: each value back to the frame the
  maximum came from, zero in the other) and convolves back to the pose rows.
"""

from __future__ import annotations

import copy

import numpy as np
import torch
from torch import nn

from workbench.engine.torch_support import bf16_is_native

LEAK = 0.2


def widths(base: int, top: int, units: int = 5) -> list[int]:
    """Channel widths of the encoding units: ``base`` doubling per unit, at most ``top``."""
    return [min(base * 2**i, top) for i in range(units)]


def he_init(module: nn.Module) -> None:
    """He (kaiming) normal initialisation of every convolution, zero biases."""
    for m in module.modules():
        if isinstance(m, (nn.Conv1d, nn.Conv2d, nn.ConvTranspose2d)):
            nn.init.kaiming_normal_(m.weight, a=LEAK, nonlinearity="leaky_relu")
            nn.init.zeros_(m.bias)


class ImageNet(nn.Module):
    """Shared forward pass: ``body`` under bf16 autocast (when ``bf16`` is asked for and
    the CPU runs it natively), ``head`` in float32. Subclasses set body, head and the
    multiples."""

    time_multiple = 32
    row_multiple = 32
    channels_last = True
    #: the frames either side of an output frame that it depends on, a multiple of
    #: ``time_multiple`` (the receptive field's reach; the tests measure it by NaN propagation)
    time_reach = 160

    def __init__(self, body: nn.Module, head: nn.Module, bf16: bool) -> None:
        super().__init__()
        self.body, self.head, self.bf16 = body, head, bf16 and bf16_is_native()
        he_init(self)
        if self.channels_last:
            self.to(memory_format=torch.channels_last)
        self._drop_bf16_body()

    def _drop_bf16_body(self) -> None:
        self.__dict__["_bf16_body"] = None  # not a registered submodule: never saved

    def train(self, mode: bool = True) -> "ImageNet":
        self._drop_bf16_body()  # the weights may change from here
        return super().train(mode)

    def load_state_dict(self, *args, **kwargs):
        self._drop_bf16_body()
        return super().load_state_dict(*args, **kwargs)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """(B, 2, H, T) -> (B, H, T); H is padded (last row repeated) to a multiple of
        ``row_multiple`` inside and cropped again, T must be a multiple of ``time_multiple``.
        In eval mode the bf16 body is a copy cast once (autocast casts the weights on
        every call; same result, about 3 % of a clean faster)."""
        H = x.shape[2]
        if H % self.row_multiple:
            x = nn.functional.pad(x, (0, 0, 0, -H % self.row_multiple), mode="replicate")
        if self.channels_last:
            x = x.contiguous(memory_format=torch.channels_last)
        if self.bf16 and not self.training:
            if self._bf16_body is None:
                self.__dict__["_bf16_body"] = copy.deepcopy(self.body).to(torch.bfloat16)
            y = self.head(self._bf16_body(x.to(torch.bfloat16)).float())
            if not torch.isfinite(y).all():  # checked on the output: a 16th of the body's last layer
                # oneDNN's bfloat16 convolutions (torch 2.13, these AVX2 EPYCs) now and then
                # return NaN from a process's first call on a small image: about one first
                # call in three of VanillaNet on a 32-frame image; float32 then
                y = self.head(self.body(x))
        else:
            with torch.autocast("cpu", dtype=torch.bfloat16, enabled=self.bf16):
                h = self.body(x)
            y = self.head(h.float())
        return y[:, 0, :H]

    def predict(self, x: torch.Tensor, max_columns: int) -> np.ndarray:
        """:meth:`forward` of ``x`` (B, 2, H, T) as float32 (B, H, T), at most about
        ``max_columns`` image columns (batch x frames) a call: several images a call when
        they are short; a long image a window of frames at a time, each computed from its
        frames and :attr:`time_reach` frames either side (windows start at multiples of
        ``time_multiple``, so the pooling grid is the whole image's): the values of one
        call on the whole image, to float32 rounding (bit for bit for ``cae``'s network on
        these CPUs; ``holden``'s convolutions round by batch and width), in memory
        proportional to the window rather than T (a 10-minute take's first layer is 300 MB)."""
        B, T = x.shape[0], x.shape[-1]
        step = self.time_multiple
        window = max(step, (max_columns - 2 * self.time_reach) // step * step)
        out = np.empty((B, x.shape[2], T), np.float32)
        if T <= window + 2 * self.time_reach:
            per_call = max(1, max_columns // T)
            for b in range(0, B, per_call):
                out[b : b + per_call] = self(x[b : b + per_call]).numpy()
            return out
        for b in range(B):
            for start in range(0, T, window):
                end = min(start + window, T)
                lo, hi = max(0, start - self.time_reach), min(T, end + self.time_reach)
                out[b, :, start:end] = self(x[b : b + 1, ..., lo:hi])[0, :, start - lo : end - lo].numpy()
        return out


def _leaky() -> nn.LeakyReLU:
    """Leaky ReLU in place: on these CPUs 8 % of a forward pass saved (no new tensor per
    layer), the same values; every one follows a convolution whose output nothing else reads."""
    return nn.LeakyReLU(LEAK, inplace=True)


def _conv(c_in: int, c_out: int, stride: int = 1) -> nn.Conv2d:
    return nn.Conv2d(c_in, c_out, 3, stride=stride, padding=1)


def _up(c_in: int, c_out: int) -> nn.ConvTranspose2d:
    return nn.ConvTranspose2d(c_in, c_out, 3, stride=2, padding=1, output_padding=1)


class KaufmannNet(ImageNet):
    """Kaufmann et al.'s convolutional autoencoder; encoder widths ``widths(base, top)``."""

    def __init__(self, base: int = 16, top: int = 192, bf16: bool = True) -> None:
        enc = widths(base, top)
        dec = enc[::-1]
        layers: list[nn.Module] = []
        c = 2
        for w in enc:
            layers += [_conv(c, w), _leaky(), _conv(w, w), _leaky(), nn.MaxPool2d(2)]
            c = w
        for i, w in enumerate(dec):
            layers += [_up(c, w), _leaky()]
            if i < len(dec) - 1:
                layers += [_conv(w, w), _leaky()]
            c = w
        super().__init__(nn.Sequential(*layers), _conv(c, 1), bf16)


class VanillaNet(ImageNet):
    """The "Vanilla AE": one strided 3x3 convolution per unit."""

    time_reach = 64

    def __init__(self, base: int = 16, top: int = 192, bf16: bool = True) -> None:
        enc = widths(base, top)
        layers: list[nn.Module] = []
        c = 2
        for w in enc:
            layers += [_conv(c, w, stride=2), _leaky()]
            c = w
        for w in enc[::-1][1:]:
            layers += [_up(c, w), _leaky()]
            c = w
        super().__init__(nn.Sequential(*layers), _up(c, 1), bf16)


class _Unpooled(nn.Module):
    """Temporal convolution, ReLU, max pooling over 2 frames, and Holden's inverse
    pooling (each value back where its maximum came from)."""

    def __init__(self, rows: int, hidden: int, kernel: int) -> None:
        super().__init__()
        self.conv = nn.Conv1d(2 * rows, hidden, kernel, padding=kernel // 2)
        self.pool = nn.MaxPool1d(2, return_indices=True)
        self.unpool = nn.MaxUnpool1d(2)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        B, _, H, T = x.shape
        h = torch.relu(self.conv(x.reshape(B, 2 * H, T)))
        pooled, where = self.pool(h)
        return self.unpool(pooled, where, output_size=h.shape[-1:])


class _TemporalHead(nn.Module):
    def __init__(self, hidden: int, rows: int, kernel: int) -> None:
        super().__init__()
        self.conv = nn.Conv1d(hidden, rows, kernel, padding=kernel // 2)

    def forward(self, h: torch.Tensor) -> torch.Tensor:
        return self.conv(h)[:, None]


class HoldenNet(ImageNet):
    """Holden et al.'s single-layer temporal convolutional autoencoder over the pose rows."""

    time_multiple = 2
    row_multiple = 1
    channels_last = False
    time_reach = 24

    def __init__(self, rows: int, hidden: int = 256, kernel: int = 25, bf16: bool = True) -> None:
        super().__init__(_Unpooled(rows, hidden, kernel), _TemporalHead(hidden, rows, kernel), bf16)
