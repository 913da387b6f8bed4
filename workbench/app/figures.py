"""The plot panels of the app and the report, drawn into a given matplotlib Figure or
SubFigure (no Qt): joint error over time with the gaps, the filter-width and data-weight
heatmaps, the bone-length boxes.

Units: errors and lengths in cm, time in seconds, filter widths in frames.
"""

from __future__ import annotations

import numpy as np

from ..core.motion import channel_count, channel_mask, position_unknown
from ..metrics import body_joints
from ..plots import plot_bone_lengths, plot_data_weights, plot_errors, plot_filter_widths, plot_note
from ..plots.style import ENGINE_STYLES, JOINTS, MOVED_AXIS_LABEL, NOISY, TEXT, engine_colour
from ..plots.timeline import Series
from .take import EngineRun, Take, bone_choice

WAITING = "waiting for the engine..."


def error_series(take: Take, runs: list[EngineRun], selected: tuple[int, ...]) -> list[Series]:
    """Lines of the error plot: the RMS over joints of the noisy take's error and of each
    run's, then each selected joint's error per run (joint colours, one line style per
    run) with the noisy error of that joint faint behind it. On a take without a truth a
    run's errors are how far it moved the recording (:class:`.take.Track`), and there are
    no noisy lines."""
    names, body = take.motion.skeleton.names, body_joints(take.motion.skeleton)
    noisy, per_run = take.noisy.errors_cm, [r.track.errors_cm for r in runs]
    series = [] if noisy is None else [Series("noisy (RMS)", rms_over_joints(noisy[:, body]), NOISY, 1.2)]
    series += [
        Series(f"{r.spec} (RMS)", rms_over_joints(e[:, body]), engine_colour(i), 2.0)
        for i, (r, e) in enumerate(zip(runs, per_run))
    ]
    for k, j in enumerate(selected):
        colour = JOINTS[k % len(JOINTS)]
        if noisy is not None:
            series.append(Series(f"{names[j]} noisy", noisy[:, j], colour, 0.8, alpha=0.3))
        for i, (r, e) in enumerate(zip(runs, per_run)):
            style = ENGINE_STYLES[i % len(ENGINE_STYLES)]
            series.append(Series(f"{names[j]} · {r.spec}", e[:, j], colour, 1.5, style))
    return series


def rms_over_joints(errors_cm: np.ndarray) -> np.ndarray:
    """(F,) root-mean-square over the joints of (F, J) errors."""
    return np.sqrt(np.mean(errors_cm**2, axis=1))


def draw_errors(fig, take: Take, runs: list[EngineRun], selected: tuple[int, ...]) -> list:
    """Error over time above a strip of the missing joints (grey, joints x time); the
    selected joints' gaps are shaded in the error plot. Without a truth the plot shows
    how far each engine moved the recording instead. Returns the time axes."""
    ax, strip = fig.subplots(2, 1, sharex=True, height_ratios=[5, 1])
    missing = take.missing
    if take.truth is None and not runs:
        plot_note(
            ax,
            "no ground truth: errors need a clean take corrupted here;\n"
            "once an engine has run, how far it moved the recording",
        )
        ax.set_axis_on()
        ax.set_yticks([])
    else:
        gaps = missing[:, list(selected)].any(axis=1) if selected else None
        labels = (
            ()
            if take.truth is not None
            else ("no ground truth: how far each engine moved the recording", MOVED_AXIS_LABEL)
        )
        plot_errors(ax, error_series(take, runs, selected), take.fps, gaps, *labels)
        ax.set_xlabel("")
    F, J = missing.shape
    strip.imshow(
        missing.T,
        aspect="auto",
        interpolation="nearest",
        cmap="Greys",
        vmin=0,
        vmax=1.6,
        extent=(0, F / take.fps, J, 0),
    )
    for k, j in enumerate(selected):
        strip.axhspan(j, j + 1, color=JOINTS[k % len(JOINTS)], alpha=0.35, lw=0)
    strip.set_yticks([])
    strip.set_ylabel("gaps", rotation=0, ha="right", va="center", fontsize="small", color=TEXT)
    strip.set_xlabel("time (s)")
    ax.tick_params(labelbottom=False)
    return [ax, strip]


def none_reported(runs: list[EngineRun], what: str) -> str:
    """The note of a map panel whose engines report no ``what``."""
    if not runs:
        return WAITING
    return f"{'this engine reports' if len(runs) == 1 else 'these engines report'} no {what}"


def draw_maps(fig, maps: list[tuple[str, np.ndarray]], plot_one, what: str, runs: list[EngineRun]) -> list:
    """One heatmap per (spec, (F, C) array) in ``maps``, stacked, drawn by ``plot_one(ax,
    spec, array)``, or a note saying no engine reports ``what``. Returns the time axes."""
    if not maps:
        plot_note(fig.subplots(), none_reported(runs, what))
        return []
    axes = np.atleast_1d(fig.subplots(len(maps), 1, sharex=True, squeeze=False)[:, 0]).tolist()
    for ax, (spec, values) in zip(axes, maps, strict=True):
        plot_one(ax, spec, np.asarray(values))
    for ax in axes[:-1]:
        ax.set_xlabel("")
    return axes


def draw_filter_widths(fig, take: Take, runs: list[EngineRun], selected: tuple[int, ...]) -> list:
    """One heatmap per run that reports ``filter_sigma_frames``, on one colour scale, or
    a note saying none does. Returns the time axes."""
    maps = [(r.spec, r.filter_sigma_frames) for r in runs if r.filter_sigma_frames is not None]
    vmax = max((float(np.nanmax(s, initial=0.0)) for _, s in maps), default=0.0)
    skeleton = take.motion.skeleton
    return draw_maps(
        fig,
        maps,
        lambda ax, spec, sigma: plot_filter_widths(
            ax, sigma, take.fps, skeleton.names, f"filter widths · {spec}", vmax, selected, skeleton.translated
        ),
        "filter widths",
        runs,
    )


def unknown_samples(take: Take, n_rows: int) -> np.ndarray | None:
    """(F, n_rows) True where a data-weight map's sample was not observed: the channel
    layout (3 + 3J + 3T) from the missing joints, root-relative positions (3J) from the
    joints whose position depends on a missing one; None for another layout."""
    skeleton = take.motion.skeleton
    if n_rows == channel_count(skeleton):
        return ~channel_mask(~take.missing, skeleton)
    if n_rows == 3 * skeleton.n_joints:
        return np.repeat(position_unknown(~take.missing, skeleton.parents, skeleton.translated), 3, axis=1)
    return None


def draw_data_weights(fig, take: Take, runs: list[EngineRun], selected: tuple[int, ...]) -> list:
    """One heatmap per run that reports ``robust_weight`` (which samples a robust
    estimator treated as outliers), missing samples grey, or a note saying none does.
    Returns the time axes."""
    maps = []
    for r in runs:
        if r.robust_weight is not None:
            weights = np.array(r.robust_weight, float)
            unknown = unknown_samples(take, weights.shape[1])
            if unknown is not None:
                weights[unknown] = np.nan
            maps.append((r.spec, weights))
    skeleton = take.motion.skeleton
    return draw_maps(
        fig,
        maps,
        lambda ax, spec, weights: plot_data_weights(
            ax,
            weights,
            take.fps,
            skeleton.names,
            f"data weights · {spec} (dark: treated as an outlier)",
            selected,
            skeleton.translated,
        ),
        "outlier weights",
        runs,
    )


def draw_bone_lengths(fig, take: Take, runs: list[EngineRun], selected: tuple[int, ...]) -> None:
    """Bone-length boxes (noisy, each run; the truth as dots) for the selected joints'
    bones, else the six longest. A run that reports its raw output positions before IK
    (``raw_positions``: the position-space engines) is boxed by those, its IK'd result,
    whose bones are the skeleton's, marked beside them as exact; the other runs' boxes
    are their results'."""
    skeleton = take.motion.skeleton
    sources = [("noisy", take.noisy.motion.positions, NOISY)]
    exact = {}
    for i, r in enumerate(runs):
        if r.raw_positions is not None:
            exact[len(sources)] = r.track.motion.positions
            sources.append((f"{r.spec} before IK", r.raw_positions, engine_colour(i)))
        else:
            sources.append((r.spec, r.track.motion.positions, engine_colour(i)))
    truth = take.truth.positions if take.truth is not None else None
    plot_bone_lengths(fig.subplots(), sources, skeleton, bone_choice(skeleton, selected), truth, exact)
