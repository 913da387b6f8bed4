"""``workbench report --video`` and the app's Export video: the side-by-side playback
(noisy | each engine with the truth faded in | truth) above the error plot with its
time cursor, rendered headless (no Qt) and encoded as H.264 MP4 by the ffmpeg that
``imageio-ffmpeg`` ships.

The video plays in real time at :data:`VIDEO_FPS` frames per second: frame k shows the
take's frame nearest to time k / VIDEO_FPS. The file is written atomically: an error or
a cancel leaves no file.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from .figures import draw_errors
from .take import EngineRun, Take, scene_panes

VIDEO_FPS = 30
#: (width, height) px of each 3D pane, narrower where the panes would be wider than
#: :data:`MAX_WIDTH_PX` together; the error plot below is as wide as the panes
PANE_PX = (400, 440)
MAX_WIDTH_PX = 1920
PLOT_HEIGHT_PX = 300
DPI = 100
SUFFIXES = (".mp4",)


def video_frames(take: Take, fps: float = VIDEO_FPS) -> np.ndarray:
    """The take's frames a real-time video at ``fps`` shows, one per video frame."""
    n = max(1, int(np.floor((take.n_frames - 1) / take.fps * fps)) + 1)
    return np.minimum(np.round(np.arange(n) * take.fps / fps).astype(int), take.n_frames - 1)


def _even(n: int) -> int:
    return n - n % 2  # H.264 in yuv420p needs even sides


def write_video(
    path: str | Path,
    take: Take,
    runs: list[EngineRun],
    progress: Callable[[int, int], bool] | None = None,
) -> Path | None:
    """Render ``take`` and ``runs`` frame by frame and write ``path`` (.mp4) atomically;
    returns ``path``. ``progress(done, total)`` is called after each frame and cancels the
    video when it returns False: no file is written and None is returned. Raises
    ValueError for another suffix, RuntimeError when ffmpeg fails."""
    import imageio_ffmpeg
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from ..io.atomic import atomic_path
    from ..plots import TimeCursor
    from ..render import SkeletonScene, new_plotter
    from .main import configure_headless

    path = Path(path)
    if path.suffix.lower() not in SUFFIXES:
        raise ValueError(f"the video must be an .mp4 file, not {path.name!r}")
    configure_headless()
    panes = scene_panes(take, [r.spec for r in runs], {r.spec: r for r in runs}, compare=False)
    width = _even(min(PANE_PX[0], MAX_WIDTH_PX // len(panes)) * len(panes))
    plotter = new_plotter(len(panes), (width, _even(PANE_PX[1])))
    fig = Figure(figsize=(width / DPI, PLOT_HEIGHT_PX / DPI), dpi=DPI, layout="constrained")
    canvas = FigureCanvasAgg(fig)
    cursor = TimeCursor(draw_errors(fig, take, runs, ()), take.fps)
    canvas.draw()  # the plot once; the cursor is blitted onto it per frame
    frames = video_frames(take)
    try:
        scene = SkeletonScene(plotter, panes, take.motion.skeleton, take.root, take.error_scale_cm())
        with atomic_path(path) as tmp:
            writer = None
            for k, f in enumerate(frames):
                scene.set_frame(int(f))
                views = np.asarray(plotter.screenshot(return_img=True))[..., :3]
                cursor.move(int(f))
                plot = np.full((_even(PLOT_HEIGHT_PX), width, 3), 255, np.uint8)  # the figure may round a pixel off
                drawn = np.asarray(canvas.buffer_rgba())[: plot.shape[0], :width, :3]
                plot[: drawn.shape[0], : drawn.shape[1]] = drawn
                image = np.ascontiguousarray(np.vstack([views[:, :width], plot]))
                if writer is None:
                    writer = imageio_ffmpeg.write_frames(
                        str(tmp),
                        (image.shape[1], image.shape[0]),
                        fps=VIDEO_FPS,
                        codec="libx264",
                        pix_fmt_out="yuv420p",
                        output_params=["-f", "mp4"],
                        macro_block_size=2,
                        ffmpeg_log_level="error",
                    )
                    writer.send(None)  # start ffmpeg
                writer.send(image)
                if progress is not None and progress(k + 1, len(frames)) is False:
                    writer.close()
                    raise _Cancelled
            writer.close()
    except _Cancelled:
        return None
    finally:
        plotter.close()
    return path


class _Cancelled(Exception):
    """The progress callback asked to stop: the temporary file is dropped."""
