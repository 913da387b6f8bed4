"""Streaming EBF (and BF, NN): frames go in one at a time; each cleaned frame comes out
``RADIUS`` = 15 frames later, equal (to float precision) to offline cleaning of the whole
take, because both evaluate exactly the same 31-frame window per output frame with the
same edge padding (the first frame repeated before the take, the last after it).

>>> stream = engine.stream(motion.skeleton, motion.fps)
>>> out = [row for f in motion.channels if (row := stream.push(f)) is not None]
>>> out += list(stream.flush())            # the last 15 frames

Rows are channel-matrix frames (D,) = (3 + 3J,): root position, then every joint's Euler
angles in degrees. Frames must be complete (no NaN): a stream cannot bridge gaps.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from workbench.core.skeleton import Skeleton
from workbench.engine import EngineError

from .features import RADIUS, VELOCITY_BASELINE, Layout, root_angular_velocity_dps


class FilterStream:
    """Streaming cleaner of a fitted :class:`~engines.ebf.filters.FilterEngine` for takes
    of one skeleton at ``fps`` frames per second."""

    def __init__(self, engine, skeleton: Skeleton, fps: float) -> None:
        engine.require_fitted()
        engine.check_skeleton(skeleton)
        self.engine = engine
        self.layout = Layout.of(skeleton)
        self.fps = float(fps)
        self.width = 3 + 3 * skeleton.n_joints
        self._reset()

    def _reset(self) -> None:
        self._codes: deque = deque()      # (E,) codes of the window frames
        self._values: deque = deque()     # (C,) unwrapped, anchored angles (degrees)
        self._valid: deque = deque()      # the window frame exists
        self._pending: deque = deque()    # raw rows (D,) not yet output
        self._root: deque = deque(maxlen=VELOCITY_BASELINE + 1)  # recent root angles (3,)
        self._last_raw: np.ndarray | None = None
        self._correction = None           # whole turns added by unwrapping, per channel
        self._anchor = None               # whole turns that anchor each channel

    def _unwrap(self, angles: np.ndarray) -> np.ndarray:
        """One step of ``numpy.unwrap(period=360)`` (same arithmetic), then the anchor
        turns fixed by the first frame (as :func:`features.anchor_turns`)."""
        if self._last_raw is None:
            self._correction = np.zeros_like(angles)
            self._anchor = 360.0 * np.round((self.engine.norm_.angle_mean - angles) / 360.0)
        else:
            dd = angles - self._last_raw[self.layout.columns]
            ddmod = np.mod(dd + 180.0, 360.0) - 180.0
            ddmod[(ddmod == -180.0) & (dd > 0)] = 180.0
            step = ddmod - dd
            step[np.abs(dd) < 180.0] = 0.0
            self._correction = self._correction + step
        return angles + self._correction + self._anchor

    def push(self, frame: np.ndarray) -> np.ndarray | None:
        """Add the next frame (D,); returns the cleaned frame 15 frames back, or None
        while the first 15 frames are still waiting for their look-ahead."""
        from engines.torch_support import torch_threads

        with torch_threads(1):
            return self._push(frame)

    def _push(self, frame: np.ndarray) -> np.ndarray | None:
        import torch

        row = np.array(frame, dtype=float).reshape(-1)
        if row.size != self.width or not np.isfinite(row).all():
            raise EngineError(f"stream frames must be {self.width} finite channel values (no gaps)")
        values = self._unwrap(row[self.layout.columns])
        self._root.append(row[3:6])
        velocity = root_angular_velocity_dps(np.stack(self._root), self.layout.root_order, self.fps)[-1]
        features = self.engine.norm_(np.concatenate([values, velocity]))
        with torch.inference_mode():
            code = self.engine.net_.encode(torch.from_numpy(features.astype(np.float32))[None])[0]
        if self._last_raw is None:
            for _ in range(RADIUS):  # the first frame repeated before the take
                self._append(code, values, False)
        self._last_raw = row
        self._append(code, values, True)
        self._pending.append(row)
        return self._emit() if len(self._codes) == 2 * RADIUS + 1 else None

    def flush(self) -> np.ndarray:
        """Clean the frames still waiting (the last frame repeated after the take);
        returns them (n, D) and resets the stream for a new take."""
        from engines.torch_support import torch_threads

        out = []
        with torch_threads(1):
            while self._pending:
                while len(self._codes) < 2 * RADIUS + 1:  # (a take shorter than the window: more)
                    self._append(self._codes[-1], self._values[-1], False)
                out.append(self._emit())
        self._reset()
        return np.array(out).reshape(-1, self.width)

    def _append(self, code, values: np.ndarray, valid: bool) -> None:
        self._codes.append(code)
        self._values.append(values)
        self._valid.append(valid)

    def _emit(self) -> np.ndarray:
        import torch

        with torch.inference_mode():
            pred, _ = self.engine._predict(
                self.engine.net_, torch.stack(list(self._codes))[None],
                torch.from_numpy(np.stack(self._values))[None], torch.tensor([list(self._valid)]))
        pred = pred[0].double().numpy()
        row = self._pending.popleft().copy()
        cols = self.layout.columns
        row[cols] = pred + 360.0 * np.round((row[cols] - pred) / 360.0)  # back on the input's branch
        for buf in (self._codes, self._values, self._valid):
            buf.popleft()
        return row
