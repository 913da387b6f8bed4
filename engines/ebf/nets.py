"""The networks and the adaptive filter (PyTorch), shared by EBF, BF, NN and EBD.

Shapes: B windows, L = 2 radius + 1 frames per window, E code width, C joint-angle
channels. Angles in degrees, filter widths in frames.
"""

from __future__ import annotations

import copy
from typing import NamedTuple

import numpy as np
import torch
from torch import nn

#: encoder widths after the input: 4 fully connected tanh layers down to a 64-d code
ENCODER_WIDTHS = (256, 128, 96, 64)
#: hidden widths of the 4-layer filter head / decoder after the B-LSTM
HEAD_WIDTHS = (128, 128, 128)
#: hidden widths of the feed-forward NN ablation (6 fully connected layers in all)
NN_WIDTHS = (256, 256, 128, 128, 128)
#: predicted log standard deviations are clamped to this range (0.0025 to 403 frames)
LOG_SIGMA_RANGE = (-6.0, 6.0)
#: a local quadratic fit whose moment matrix (offsets in Gaussian stds, weights summing to
#: 1) has a smaller determinant is ill-posed: its weights fall back to the Gaussian's
ILL_POSED_DET = 1e-6


def mlp(widths: tuple[int, ...], tanh_last: bool) -> nn.Sequential:
    """Fully connected layers ``widths[0] -> ... -> widths[-1]`` with tanh between them
    (and after the last one when ``tanh_last``), Glorot-initialised for tanh: with
    PyTorch's default initialisation the signal fades through the 4-layer tanh stacks
    and training sat on a plateau for tens of epochs."""
    layers: list[nn.Module] = []
    for i, (a, b) in enumerate(zip(widths[:-1], widths[1:])):
        linear = nn.Linear(a, b)
        nn.init.xavier_uniform_(linear.weight, gain=nn.init.calculate_gain("tanh"))
        nn.init.zeros_(linear.bias)
        layers.append(linear)
        if tanh_last or i < len(widths) - 2:
            layers.append(nn.Tanh())
    return nn.Sequential(*layers)


class WindowLSTM(nn.Module):
    """Two bidirectional LSTM layers over a window (B, L, E) with input dropout; returns
    the (B, 2H) state at the centre frame. The second layer runs forward over frames
    0..centre and backward over centre..L-1 only: exactly what a full bidirectional layer
    gives at the centre, at about half the cost."""

    def __init__(self, n_in: int, hidden: int, dropout: float) -> None:
        super().__init__()
        self.dropout = nn.Dropout(dropout)
        self.layer1 = nn.LSTM(n_in, hidden, batch_first=True, bidirectional=True)
        self.forward2 = nn.LSTM(2 * hidden, hidden, batch_first=True)
        self.backward2 = nn.LSTM(2 * hidden, hidden, batch_first=True)

    def forward(self, windows: torch.Tensor) -> torch.Tensor:
        r = windows.shape[1] // 2
        h, _ = self.layer1(self.dropout(windows))
        f, _ = self.forward2(h[:, : r + 1])
        b, _ = self.backward2(h[:, r:].flip(1))
        return torch.cat([f[:, -1], b[:, -1]], dim=1)


#: an LSTM layer's weights as ``torch.lstm`` takes them: W_ih (4H, n_in), W_hh (4H, H),
#: b_ih (4H,), b_hh (4H,), gates in PyTorch's order (input, forget, cell, output)
LSTMWeights = tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]


def _lstm_weights(lstm: nn.LSTM, suffix: str = "") -> LSTMWeights:
    """The weights of ``lstm``'s first layer (``suffix`` "_reverse": of its backward direction)."""
    names = ("weight_ih_l0", "weight_hh_l0", "bias_ih_l0", "bias_hh_l0")
    return tuple(getattr(lstm, name + suffix).detach() for name in names)  # type: ignore[return-value]


def _paired_weights(first: LSTMWeights, second: LSTMWeights, columns: tuple[list[int], list[int]], n_in: int):
    """The weights of one LSTM of twice the width that runs two single-layer LSTMs of
    width H side by side: its units are ``first``'s then ``second``'s, each gate's
    weights block-diagonal (no unit reads the other's state). It reads inputs of ``n_in``
    columns, of which ``columns[0]`` (in order) are ``first``'s input, ``columns[1]``
    ``second``'s."""
    H = first[1].shape[1]
    W_ih, W_hh = first[0].new_zeros(8 * H, n_in), first[0].new_zeros(8 * H, 2 * H)
    b_ih, b_hh = first[0].new_zeros(8 * H), first[0].new_zeros(8 * H)
    for (w_ih, w_hh, bias_ih, bias_hh), cols, units in zip((first, second), columns, (slice(0, H), slice(H, 2 * H))):
        for gate in range(4):
            rows, source = slice(2 * gate * H + units.start, 2 * gate * H + units.stop), slice(gate * H, (gate + 1) * H)
            W_ih[rows, cols], W_hh[rows, units] = w_ih[source], w_hh[source]
            b_ih[rows], b_hh[rows] = bias_ih[source], bias_hh[source]
    return W_ih, W_hh, b_ih, b_hh


def _run_lstm(inputs: torch.Tensor, weights: LSTMWeights) -> torch.Tensor:
    """(B, T, H) outputs of a single-layer LSTM of ``weights`` over ``inputs`` (B, T,
    n_in), from a zero state."""
    zero = inputs.new_zeros(1, inputs.shape[0], weights[1].shape[1])
    return torch.lstm(inputs, (zero, zero), weights, True, 1, 0.0, False, False, True)[0]


class OneWindowLSTM:
    """:class:`WindowLSTM`'s function for one window at a time, as a stream calls it, in
    two LSTM calls instead of four (equal to it to rounding): on a CPU a call costs some
    50 us before its first step (oneDNN sets the layer up) and about 1 us a step at a
    batch of one, so the calls, not the 94 steps, were most of the B-LSTM's time. Each
    layer's two directions run as one LSTM of twice the width (:func:`_paired_weights`):
    the first over the window and its mirror image side by side, the second over the
    first's output beside its own mirror image, whose row k holds every input both
    directions of the second layer read at their step k. Built from a core in eval
    mode; runs in its dtype."""

    def __init__(self, core: WindowLSTM) -> None:
        E, H = core.layer1.input_size, core.layer1.hidden_size
        self.dtype = core.layer1.weight_ih_l0.dtype
        self.layer1 = _paired_weights(
            _lstm_weights(core.layer1), _lstm_weights(core.layer1, "_reverse"), (_span(0, E), _span(E, 2 * E)), 2 * E
        )
        # the first layer's output row t is (forward state at frame t, backward state at
        # frame L-1-t); beside its mirror image, row k is (fw k, bw L-1-k, fw L-1-k, bw k):
        # the second layer's forward direction reads frame k, its backward one frame L-1-k
        columns = (_span(0, H) + _span(3 * H, 4 * H), _span(2 * H, 3 * H) + _span(H, 2 * H))
        self.layer2 = _paired_weights(_lstm_weights(core.forward2), _lstm_weights(core.backward2), columns, 4 * H)

    def __call__(self, window: np.ndarray) -> np.ndarray:
        """(L, E) float32 window of codes -> (2H,) float32 state at its centre frame."""
        r = window.shape[0] // 2
        with torch.inference_mode():
            x = torch.from_numpy(window)[None].to(self.dtype)
            y = _run_lstm(torch.cat([x, x.flip(1)], dim=2), self.layer1)
            state = _run_lstm(torch.cat([y, y.flip(1)], dim=2)[:, : r + 1], self.layer2)[0, -1]
        return state.float().numpy()


def _span(start: int, stop: int) -> list[int]:
    return list(range(start, stop))


class WindowNet(nn.Module):
    """Per-frame encoder (or none), then a window core, then a head giving ``n_out``
    numbers per window.

    encoder: 4 tanh layers to a 64-d code (EBF, EBD) or the raw features (BF, NN).
    recurrent: the 2-layer B-LSTM and a 4-layer head (EBF, BF, EBD), or (NN) 6 fully
    connected layers over the flattened (L x features) window. Either core drops its
    inputs out with probability ``dropout`` in training.
    """

    def __init__(
        self, n_in: int, n_out: int, *, encoder: bool, recurrent: bool, lstm_units: int, dropout: float, window: int
    ) -> None:
        super().__init__()
        self.encoder = mlp((n_in,) + ENCODER_WIDTHS, tanh_last=True) if encoder else nn.Identity()
        self.code_width = width = ENCODER_WIDTHS[-1] if encoder else n_in
        if recurrent:
            self.core: nn.Module = WindowLSTM(width, lstm_units, dropout)
            self.head = mlp((2 * lstm_units,) + HEAD_WIDTHS + (n_out,), tanh_last=False)
        else:
            self.core = nn.Sequential(nn.Dropout(dropout), nn.Flatten())
            self.head = mlp((window * width,) + NN_WIDTHS + (n_out,), tanh_last=False)
        last = self.head[-1]
        with torch.no_grad():  # start near "no correction": small outputs
            last.weight.mul_(0.1)
            last.bias.zero_()

        self.__dict__["bf16_core"] = None  # not a registered submodule: never saved

    def run_core_in_bf16(self) -> None:
        """Evaluate the B-LSTM core on a bfloat16 copy of it from now on, in eval mode
        (training still runs the float32 weights; the NN's core has no weights and stays
        as it is). The head reads the core's output back in float32, so the filters it
        predicts carry the bf16 rounding of the LSTM's state only. Call it when the
        weights are final: the copy is made here, once."""
        if isinstance(self.core, WindowLSTM):
            self.__dict__["bf16_core"] = copy.deepcopy(self.core).to(torch.bfloat16)

    def one_window(self) -> "OneWindowNet":
        """This network for one frame and window at a time (:class:`OneWindowNet`); make
        it when the weights are final."""
        return OneWindowNet(self)

    def encode(self, frames: torch.Tensor) -> torch.Tensor:
        """(..., n_in) normalised frame features -> (..., E) codes."""
        return self.encoder(frames)

    def forward(self, windows: torch.Tensor) -> torch.Tensor:
        """(B, L, E) windows of codes -> (B, n_out)."""
        if self.bf16_core is not None and not self.training:
            return self.head(self.bf16_core(windows.to(torch.bfloat16)).float())
        return self.head(self.core(windows))


class NumpyMLP:
    """An :func:`mlp`'s function (its ``nn.Sequential`` of linear and tanh layers) in
    numpy float32, on one input (n_in,) at a time: at that size torch's dispatch of its
    seven or eight modules took four times as long (some 33 us against 7)."""

    def __init__(self, layers: nn.Module) -> None:
        self.layers: list[tuple[np.ndarray, np.ndarray, bool]] = []
        for layer in layers.children():  # (none for an nn.Identity: the input as it is)
            if isinstance(layer, nn.Linear):
                weight, bias = (t.detach().float().numpy() for t in (layer.weight, layer.bias))
                self.layers.append((np.ascontiguousarray(weight.T), bias.copy(), False))
            elif isinstance(layer, nn.Tanh):
                self.layers[-1] = self.layers[-1][:2] + (True,)
            else:
                raise TypeError(f"not an mlp layer: {layer}")

    def __call__(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, np.float32)
        for weight, bias, tanh in self.layers:
            x = x @ weight
            x += bias
            if tanh:
                np.tanh(x, out=x)
        return x


class OneWindowNet:
    """A :class:`WindowNet`'s function for one frame and one window at a time (a
    stream's), in eval mode, equal to it to rounding: the B-LSTM as
    :class:`OneWindowLSTM` (in the dtype the network runs it in), the encoder and the
    head as :class:`NumpyMLP`."""

    def __init__(self, net: WindowNet) -> None:
        core = net.bf16_core if net.bf16_core is not None else net.core
        self.lstm = OneWindowLSTM(core) if isinstance(core, WindowLSTM) else None
        self.encode = NumpyMLP(net.encoder)
        self.head = NumpyMLP(net.head)

    def __call__(self, window: np.ndarray) -> np.ndarray:
        """(L, E) float32 window of codes -> (n_out,) outputs."""
        return self.head(window.reshape(-1) if self.lstm is None else self.lstm(window))  # NN: the window flattened


def offsets_like(values: torch.Tensor) -> torch.Tensor:
    """(L,) frame offsets -r..r of a window tensor (B, L, C), in its dtype."""
    r = values.shape[1] // 2
    return torch.arange(-r, r + 1, dtype=values.dtype, device=values.device)


def sigma_frames(log_sigma: torch.Tensor) -> torch.Tensor:
    """Filter standard deviations in frames from the head's outputs: ``exp``, clamped."""
    return torch.exp(log_sigma.clamp(*LOG_SIGMA_RANGE))


def gaussian_logits(sigma: torch.Tensor, offsets: torch.Tensor) -> torch.Tensor:
    """Log weights (B, L, C) of Gaussians with std ``sigma`` (B, C) frames at ``offsets``
    (L,) frames (up to the normalisation)."""
    return -0.5 * offsets[None, :, None] ** 2 / sigma[:, None, :] ** 2


def filter_windows(
    logits: torch.Tensor, values: torch.Tensor, valid: torch.Tensor, trig: Trig | None = None
) -> tuple[torch.Tensor, torch.Tensor]:
    """Weighted circular mean over each window: ``softmax(logits)`` over the window
    frames that exist (``valid`` (B, L); weights renormalised over them), applied to the
    angles ``values`` (B, L, C) in degrees. Returns the filtered centre frames (B, C),
    on the centre frame's branch (within 180 degrees of it), and the weights (B, L, C).
    For small spreads this is the weighted average; unlike it, a whole turn that noise
    slipped into the unwrapped channel, or noise of tens of degrees on a channel near
    gimbal lock, does not wreck it. The centre frame must be valid. ``trig``: as
    :func:`circular_mean` takes it."""
    logits = logits.to(values.dtype).masked_fill(~valid[:, :, None], float("-inf"))
    weights = torch.softmax(logits, dim=1)
    return circular_mean(weights, values, trig), weights


def gaussian_filter(
    sigma: torch.Tensor, values: torch.Tensor, valid: torch.Tensor, trig: Trig | None = None
) -> torch.Tensor:
    """(B, C) what ``filter_windows(gaussian_logits(sigma, offsets), values, valid)``
    filters (to rounding), for Gaussians of std ``sigma`` (B, C) frames over windows of
    angles ``values`` (B, L, C) degrees whose frames exist where ``valid`` (B, L), the
    centre frame among them: the weights are left unnormalised (the centre frame's is
    1), which the circular mean does not need, and invalid frames are zeroed only in a
    batch that has any: the softmax and the mask took 8 % of ebf's cleaning time.
    ``trig``: as :func:`circular_mean` takes it."""
    weights = torch.exp(gaussian_logits(sigma, offsets_like(values)).to(values.dtype))
    if not bool(valid.all()):
        weights = weights * valid[:, :, None]
    return circular_mean(weights, values, trig)


class Trig(NamedTuple):
    """Sines and cosines of angles, each shaped as the angles."""

    sin: torch.Tensor
    cos: torch.Tensor

    @classmethod
    def of_degrees(cls, angles: torch.Tensor) -> "Trig":
        radians = torch.deg2rad(angles)
        return cls(torch.sin(radians), torch.cos(radians))


def circular_mean(weights: torch.Tensor, values: torch.Tensor, trig: Trig | None = None) -> torch.Tensor:
    """(B, C) weighted circular mean of the angles ``values`` (B, L, C) in degrees with
    ``weights`` (B, L, C) whose sum over the window is positive (some may be negative;
    their scale does not matter), on the centre frame's branch. ``values`` carry no
    gradient (the window's (B, L, C) temporaries are reused in place).

    ``trig``: the values' sines and cosines (:meth:`Trig.of_degrees`), where the caller
    has them, e.g. as windows of each frame's: the weighted sums then need no sine and
    cosine per window entry, and the mean is the same to about 1e-12 degrees (the
    angle-difference identities). A 10-minute take's ebf computed each frame's 31 times,
    0.7 of its 5 s."""
    c = values.shape[1] // 2
    centre = values[:, c]
    if trig is None:
        deviation = torch.deg2rad_(values - centre[:, None])
        sin = torch.sin(deviation)
        cos = deviation.cos_()
        return centre + torch.rad2deg(torch.atan2((weights * sin).sum(dim=1), (weights * cos).sum(dim=1)))
    sin, cos = (weights * trig.sin).sum(dim=1), (weights * trig.cos).sum(dim=1)
    at_sin, at_cos = trig.sin[:, c], trig.cos[:, c]  # the sums turned by minus the centre angle
    mean = torch.atan2(sin * at_cos - cos * at_sin, cos * at_cos + sin * at_sin)
    return centre + torch.rad2deg(mean)


def local_quadratic_weights(sigma: torch.Tensor, offsets: torch.Tensor, valid: torch.Tensor) -> torch.Tensor:
    """(B, L, C) equivalent kernel of a Gaussian-weighted local quadratic fit: the weights
    whose sum over a window's values is the value at the centre of the parabola fitted to
    the window's valid frames by least squares, each frame weighted by a Gaussian of std
    ``sigma`` (B, C) frames at ``offsets`` (L,) frames. They sum to 1 and reproduce any
    parabola exactly (a Gaussian's weights flatten peaks and lag fast motion by
    ``sigma^2`` times the curvature); some are negative. Where the fit is ill-posed (fewer
    than 3 valid frames with weight, as when ``sigma`` is far below a frame) the weights
    fall back to the Gaussian's (they are then within a hair of the centre frame alone)."""
    g = torch.softmax(gaussian_logits(sigma, offsets).masked_fill(~valid[:, :, None], float("-inf")), dim=1)
    k = offsets[None, :, None] / sigma.clamp(min=0.5)[:, None, :]  # in stds: the same system at every width
    m = [(g * k**j).sum(dim=1) for j in range(5)]  # (B, C) moments
    A = torch.stack([torch.stack([m[i + j] for j in range(3)], dim=-1) for i in range(3)], dim=-2)  # (B, C, 3, 3)
    ok = torch.linalg.det(A) > ILL_POSED_DET
    eye = torch.eye(3, dtype=A.dtype, device=A.device)
    a = torch.linalg.solve(torch.where(ok[..., None, None], A, eye), eye[0].expand(*A.shape[:-1]))  # (B, C, 3)
    quadratic = g * (a[:, None, :, 0] + a[:, None, :, 1] * k + a[:, None, :, 2] * k**2)
    return torch.where(ok[:, None, :], quadratic, g)


def weights_sigma(weights: torch.Tensor, offsets: torch.Tensor) -> torch.Tensor:
    """(B, C) standard deviation in frames of filter weights (B, L, C) over ``offsets``."""
    mean = (weights * offsets[None, :, None]).sum(dim=1)
    second = (weights * offsets[None, :, None] ** 2).sum(dim=1)
    return torch.sqrt(torch.clamp(second - mean**2, min=0.0))
