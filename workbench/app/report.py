"""``workbench report``: the app's 3D panes and plots rendered headless into one figure
(no Qt): the panes off-screen at one frame (noisy | each engine with the truth faded in
| truth), the scores, the error over time, the filter widths and the bone lengths. (Its
``--video`` is :mod:`workbench.app.video`.)

Units: as in the app (cm, seconds, frames). The file is written atomically.
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np

from ..plots import TimeCursor
from ..plots.style import error_mappable
from .figures import draw_bone_lengths, draw_data_weights, draw_errors, draw_filter_widths
from .take import EngineRun, Take, open_take, run_engine, scene_panes

PANE_PX = (420, 460)
DPI = 110
#: inches of figure height per heatmap (filter widths, data weights) in the bottom row
MAP_HEIGHT_IN = 2.0
FORMATS = (".png", ".pdf")


def render_panes(take: Take, runs: list[EngineRun], frame: int) -> np.ndarray:
    """(H, W, 3) uint8 off-screen image of the panes at ``frame``."""
    from ..render import SkeletonScene, new_plotter
    from .main import configure_headless

    configure_headless()
    panes = scene_panes(take, [r.spec for r in runs], {r.spec: r for r in runs}, compare=False)
    plotter = new_plotter(len(panes), (PANE_PX[0] * len(panes), PANE_PX[1]))
    try:
        scene = SkeletonScene(plotter, panes, take.motion.skeleton, take.root, take.error_scale_cm())
        scene.set_frame(frame)
        return np.asarray(plotter.screenshot(return_img=True))[..., :3].copy()
    finally:
        plotter.close()


def scores_text(take: Take, runs: list[EngineRun]) -> str:
    """One line per engine: its headline scores (needs a truth)."""
    from ..metrics import score

    lines = []
    for r in runs:
        sc = score(take.truth, r.track.motion, take.observation.observed)
        gap = f", in gaps {sc['gap_mpjpe_cm']:.2f} cm" if "gap_mpjpe_cm" in sc else ""
        lines.append(
            f"{r.spec}: joint error {sc['mpjpe_cm']:.2f} cm{gap}, angles {sc['rms_angle_deg']:.2f}° RMS, "
            f"{r.seconds:.2f} s" + (f" ({r.weights_kind})" if r.weights_kind else "")
        )
    return "\n".join(lines)


def report_figure(take: Take, runs: list[EngineRun], frame: int, selected: tuple[int, ...] = ()):
    """The report as a matplotlib Figure (Agg, no window)."""
    from matplotlib.figure import Figure

    image = render_panes(take, runs, frame)
    width = max(12.0, image.shape[1] / DPI)
    views_h = width * image.shape[0] / image.shape[1] + 0.2 * (len(runs) + 1)  # the image, the scores
    n_widths = sum(r.filter_sigma_frames is not None for r in runs)
    n_weights = sum(r.robust_weight is not None for r in runs)
    # (draw, heatmaps): the filter widths (or the note that no engine has any), the data weights
    panels = [(draw_filter_widths, max(n_widths, 1))] * (n_widths > 0 or n_weights == 0)
    panels += [(draw_data_weights, n_weights)] * (n_weights > 0)
    maps_h = max(4.0, MAP_HEIGHT_IN * sum(n for _, n in panels))
    fig = Figure(figsize=(width, views_h + 4.5 + maps_h), dpi=DPI, layout="constrained")
    fig.suptitle(
        f"{take.source} · corruption {take.corruption} · seed {take.seed} · frame {frame} ({frame / take.fps:.2f} s)",
        fontsize="large",
    )
    views, errors, bottom = fig.subfigures(3, 1, height_ratios=[views_h, 4.5, maps_h])
    ax = views.subplots()
    ax.imshow(image, interpolation="nearest")
    ax.set_axis_off()
    views.colorbar(
        error_mappable(take.error_scale_cm()),
        ax=ax,
        location="right",
        shrink=0.6,
        pad=0.005,
        aspect=15,
        label=take.error_label,
    )
    if take.truth is not None and runs:
        ax.set_title(scores_text(take, runs), fontsize="medium", loc="left")
    axes = draw_errors(errors, take, runs, selected)
    maps, bones = bottom.subfigures(1, 2, width_ratios=[1.1, 1.0])
    subs = maps.subfigures(len(panels), 1, squeeze=False, height_ratios=[n for _, n in panels])[:, 0]
    for sub, (draw, _) in zip(subs, panels, strict=True):
        axes += draw(sub, take, runs, selected)
    draw_bone_lengths(bones, take, runs, selected)
    TimeCursor(axes, take.fps, animated=False).move(frame, blit=False)
    return fig


def clean_take(
    source: str,
    corruption: str,
    seed: int,
    specs: list[str],
    on_refused: Callable[[str, str], None] | None = None,
    fill_suspects: bool = False,
) -> tuple[Take, list[EngineRun]]:
    """Load and corrupt ``source`` (:func:`open_take`, ``fill_suspects`` as there) and run
    the engines on it. Raises what the engines raise; with ``on_refused``, an engine that
    refuses the take (EngineError: a trained engine on another skeleton) is left out and
    ``on_refused(spec, message)`` told instead."""
    from ..engine import EngineError

    take = open_take(source, corruption, seed, fill_suspects)
    runs = []
    for spec in specs:
        try:
            runs.append(run_engine(spec, take))
        except EngineError as err:
            if on_refused is None:
                raise
            on_refused(spec, str(err))
    return take, runs


def write_report(path: str | Path, take: Take, runs: list[EngineRun], frame: int | None = None) -> Path:
    """Write the report of ``take`` and ``runs`` (PNG or PDF by suffix) atomically;
    ``frame`` defaults to the middle of the take."""
    from ..io.atomic import atomic_path

    path = Path(path)
    if path.suffix.lower() not in FORMATS:
        raise ValueError(f"the report must be a .png or .pdf file, not {path.name!r}")
    frame = take.n_frames // 2 if frame is None else min(max(frame, 0), take.n_frames - 1)
    fig = report_figure(take, runs, frame)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format=path.suffix[1:].lower())
    return path
