"""Streaming EBF (and BF, NN): frames go in one at a time; each cleaned frame comes out
``RADIUS`` = 15 frames later, equal (to float precision) to offline cleaning of the whole
take, because both evaluate exactly the same 31-frame window per output frame with the
same edge padding (the first frame repeated before the take, the last after it), and
unwrap the angles by the same causal rule. The root's filter (:mod:`.root`) also sees
only the window. The network runs as :class:`.nets.OneWindowNet`, its form for one
window at a time (the same function in fewer, cheaper calls). Where the B-LSTM runs in
bf16 (the engines' ``bf16``, on by default on CPUs that run it natively), its kernels
for one window and for a batch of them round differently: the two then agree to within
hundredths of a degree (0.044 at most on 8 CMU takes under ``angular:0.5``,
``angular:1`` and ``spatial:1``, 0.030 on 6 Bandai takes); with ``bf16=false``, to float
precision.

>>> stream = engine.stream(motion.skeleton, motion.fps)
>>> out = [row for f in motion.channels if (row := stream.push(f)) is not None]
>>> out += list(stream.flush())            # the last 15 frames

Rows are channel-matrix frames (D,) = (3 + 3J + 3T,): root position, every joint's Euler
angles in degrees, the translated joints' translations. Frames must be complete (no NaN):
a stream cannot bridge gaps. A take whose body hangs under a reference node (a
MotionBuilder export: ``joint_Root`` carries the translated ``Hips``) or whose bones
stretch streams as offline cleaning sees it, each frame in its body view
(:mod:`workbench.engine.view`) and back, the joints above the body root and the bones'
translations as they came.
"""

from __future__ import annotations

import copy
from collections import deque

import numpy as np

from workbench.core.channels import robust_unwrap_step
from workbench.core.motion import Motion, channel_count
from workbench.core.skeleton import Skeleton
from workbench.engine import EngineError
from workbench.engine.view import body_skeleton, from_body, to_body

from .features import RADIUS, VELOCITY_BASELINE, Layout, rotation_rate_dps
from .root import root_frames, roughness, smooth_root


class Window:
    """The last ``size`` frames of a stream, oldest first: one array (size, ...) per
    named field, shifted in place (cheaper than stacking per-frame arrays every frame)."""

    def __init__(self, size: int, **fields: tuple[tuple[int, ...], type]) -> None:
        self.arrays = {name: np.empty((size, *shape), dtype) for name, (shape, dtype) in fields.items()}
        self.size, self.count = size, 0

    @property
    def full(self) -> bool:
        return self.count == self.size

    def append(self, **values) -> None:
        for name, value in values.items():
            self.arrays[name][self.count] = value
        self.count += 1

    def last(self) -> dict[str, np.ndarray]:
        """The newest frame's fields (views: writing to them changes the window)."""
        return {name: a[self.count - 1] for name, a in self.arrays.items()}

    def pop(self) -> None:
        """Drop the oldest frame."""
        for a in self.arrays.values():
            a[:-1] = a[1:]
        self.count -= 1


class FilterStream:
    """Streaming cleaner of a fitted :class:`~engines.ebf.filters.FilterEngine` for takes
    of one skeleton at ``fps`` frames per second."""

    def __init__(self, engine, skeleton: Skeleton, fps: float) -> None:
        body = body_skeleton(skeleton)  # frame by frame: the body view, no resampling
        engine.use_weights_for(body)  # the committed weights trained for it, if any
        engine.require_fitted()
        engine.check_skeleton(body)
        if engine.noise_context or engine.smoothing_context:  # each measured over the whole take
            raise EngineError(
                f"engine {engine.spec!r} measures each take's noise over the whole take, so it cannot "
                "stream; stream with plain 'ebf', or clean the take offline (`workbench clean`)"
            )
        if not abs(fps - engine.fps_) <= 1e-6:  # (NaN too)
            raise EngineError(
                f"engine {engine.info.name!r} streams takes at the {engine.fps_:g} fps its weights run at, "
                f"not {fps:g}; clean the take offline (`workbench clean`), which resamples it"
            )
        self.engine = copy.copy(engine)  # its weights kept: the engine may switch to another skeleton's
        self.net = engine.net_.one_window()
        self.layout = Layout.of(body)
        self.fps = float(fps)
        self.width = channel_count(skeleton)
        self.unit_cm = body.unit_cm
        # a take carried by a reference node, or with stretchy bones: each frame to its body view and back
        self._views = (_one_frame(skeleton, fps), _one_frame(body, fps)) if body is not skeleton else None
        self._reset()

    def _reset(self) -> None:
        C = self.layout.n_channels
        self._window = Window(
            2 * RADIUS + 1,
            code=((self.engine.net_.code_width,), np.float32),  # the frame's code
            values=((C,), float),  # unwrapped, anchored angles (degrees)
            root=((12,), float),  # the root (:func:`.root.root_frames`)
            rough=((2, 3), float),  # root roughness (NaN: not known)
            valid=((), bool),
        )  # the window frame exists
        self._pending: deque = deque()  # (raw row (D,), its body view) not yet output
        self._recent: deque = deque(maxlen=VELOCITY_BASELINE + 1)  # the last frames' roots (12,)
        self._unwrapped: deque = deque(maxlen=3)  # the last frames' unwrapped angles (C,)
        self._anchor = None  # whole turns that anchor each channel

    def _unwrap(self, angles: np.ndarray) -> np.ndarray:
        """One step of the robust unwrapping offline cleaning applies
        (:func:`workbench.core.channels.robust_unwrap_step`): each sample within 180
        degrees of the median of the three unwrapped samples before it, so one outlier
        near 180 degrees away does not leave a whole turn behind it; then the anchor turns
        fixed by the first frame (as :func:`features.anchor_turns`). Offline, a channel
        that never steps by 180 degrees is left as it is, which the median rule gives too
        unless a channel climbs by nearly 180 degrees a frame for two frames running."""
        recent = self._unwrapped
        if not recent:
            self._anchor = 360.0 * np.round((self.engine.norm_.angle_mean - angles) / 360.0)
            unwrapped = angles
        else:
            unwrapped = robust_unwrap_step(angles, recent)
        recent.append(unwrapped)
        return unwrapped + self._anchor

    def push(self, frame: np.ndarray) -> np.ndarray | None:
        """Add the next frame (D,); returns the cleaned frame 15 frames back, or None
        while the first 15 frames are still waiting for their look-ahead."""
        from workbench.engine.torch_support import torch_threads

        with torch_threads(1):
            return self._push(frame)

    def _push(self, frame: np.ndarray) -> np.ndarray | None:
        try:
            raw = np.array(frame, dtype=float)
        except (TypeError, ValueError):
            raw = np.zeros(0)
        if raw.shape != (self.width,) or not np.isfinite(raw).all():
            raise EngineError(f"stream frames must be {self.width} finite channel values, (D,) (no gaps)")
        row = raw
        if self._views is not None:
            take, body = self._views
            row = to_body(take.with_channels(raw[None]), body.skeleton).channels[0]
        values = self._unwrap(row[self.layout.columns])
        root = root_frames(row[None, :6], self.layout.root_order)[0]
        self._recent.append(root)
        velocity = rotation_rate_dps(
            self._recent[0][3:].reshape(3, 3), root[3:].reshape(3, 3), len(self._recent) - 1, self.fps
        )
        if self.engine.params.root_sigma_frames > 0 and len(self._recent) >= 4:  # the roughness of the frame 2 back
            self._window.arrays["rough"][self._window.count - 2] = roughness(
                np.stack(list(self._recent)[-4:]), self.unit_cm
            )[0]
        previous = self._window.count - 1  # the frame before, for step inputs (none before the take's first)
        before = self._window.arrays["values"][previous] if previous >= 0 else values
        code = self.net.encode(self.engine.norm_(values[None], velocity[None], before)[0])
        frame_fields = dict(code=code, values=values, root=root, rough=np.nan)
        if len(self._recent) == 1:
            for _ in range(RADIUS):  # the first frame repeated before the take
                self._window.append(**frame_fields, valid=False)
        self._window.append(**frame_fields, valid=True)
        self._pending.append((raw, row))
        return self._emit() if self._window.full else None

    def flush(self) -> np.ndarray:
        """Clean the frames still waiting (the last frame repeated after the take);
        returns them (n, D) and resets the stream for a new take."""
        from workbench.engine.torch_support import torch_threads

        out = []
        with torch_threads(1):
            while self._pending:
                while not self._window.full:  # (a take shorter than the window: more)
                    self._window.append(**{**self._window.last(), "rough": np.nan, "valid": False})
                out.append(self._emit())
        self._reset()
        return np.array(out).reshape(-1, self.width)

    def _emit(self) -> np.ndarray:
        import torch

        w = self._window.arrays
        with torch.inference_mode():
            pred, _ = self.engine._filter(
                torch.from_numpy(self.net(w["code"]))[None],
                torch.from_numpy(w["values"])[None],
                torch.from_numpy(w["valid"])[None],
            )
        pred = pred[0].double().numpy()
        raw, row = self._pending.popleft()
        row = row.copy()
        cols = self.layout.columns
        row[cols] = pred + 360.0 * np.round((row[cols] - pred) / 360.0)  # back on the input's branch
        if self.engine.params.root_sigma_frames > 0:
            root, _ = smooth_root(
                w["root"][None],
                w["rough"][None],
                w["valid"][None],
                row[None, 3:6],
                self.engine.params.root_sigma_frames,
                self.layout.root_order,
                self.fps,
            )
            row[:6] = root[0]
        self._window.pop()
        if self._views is not None:  # the joints above the body root as they came
            take, body = self._views
            row = from_body(body.with_channels(row[None]), take.with_channels(raw[None])).channels[0]
        return row


def _one_frame(skeleton: Skeleton, fps: float) -> Motion:
    """A one-frame motion of ``skeleton`` whose ``with_channels`` makes a stream's frames
    motions (to go to the body view and back)."""
    J, T = skeleton.n_joints, len(skeleton.translated)
    return Motion(skeleton, fps, np.zeros((1, 3)), np.zeros((1, J, 3)), translations=np.zeros((1, T, 3)))
