"""Cleaning takes: one file (:func:`clean_file`), or a whole library on Dask distributed
(:func:`clean_library`, ``workbench clean DIR -o OUT``).

Takes are the unit of work. Each is read, cleaned and written atomically (an interrupted
batch leaves no partial file; a worker killed mid-write leaves a temporary file that the
next write of that take removes) by one task, on a worker of a local cluster (``workers``
processes of one thread) or of an existing one (``scheduler``, its address): the same
code path either way. A worker creates each engine once and keeps it, so an engine's
weights are loaded once per worker, not once per take.

Every task cleans with one thread (BLAS and torch), so that a take's result is the same
bit for bit whatever the number of workers; a serial run is ``workers=1``. (With two
threads mssa's and kalman's BLAS sums differ in the last bits.)

No take is split into chunks: every engine's result at a frame may depend on frames
any distance away (the Kalman smoother's backward pass, mssa's robust fit of the whole
take, gap bridging, each engine's per-take noise estimate), so a cut would change it.

The output folder's :data:`MANIFEST` (:class:`FolderRecord`) holds the engine and options
it is cleaned with, then a line per take written: its output and what it was cleaned
from. ``resume`` skips a take whose output is the file that line records and whose take
and mask sidecar have the bytes they had then (SHA-256): an edit, a take copied over
with its old time, a mask moved away or an output replaced cleans it again.

Paths go to the workers absolute: a worker of an existing cluster runs in a folder of its
own.
"""

from __future__ import annotations

import errno
import json
import os
import signal
import time
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from .errors import ClusterError

#: the file in an output folder that records how its takes were cleaned (:class:`FolderRecord`)
MANIFEST = ".workbench-clean.json"


@dataclass(frozen=True)
class TakeReport:
    """What became of one take: ``frames`` cleaned in ``seconds`` (the engine's clean
    alone), ``filled`` missing joint samples; ``notes`` for the user; ``error`` (one
    line) if it failed, ``skipped`` if ``resume`` found it done."""

    source: Path
    output: Path
    frames: int = 0
    seconds: float = 0.0
    filled: int = 0
    engine: str = ""
    weights: str | None = None
    notes: tuple[str, ...] = ()
    error: str | None = None
    skipped: bool = False
    #: what the take was cleaned from (:func:`take_stamp`), where it was written
    stamp: dict | None = None

    def __str__(self) -> str:
        if self.error is not None:  # (a file error names the take already)
            return self.error if self.error.startswith(f"{self.source}:") else f"{self.source}: {self.error}"
        if self.skipped:
            return f"kept {self.output}: up to date"
        weights = f" ({self.weights})" if self.weights else ""
        return (
            f"wrote {self.output}: {self.frames} frames cleaned by {self.engine}{weights} in {self.seconds:.2f} s "
            f"({self.frames / max(self.seconds, 1e-9):,.0f} frames/s); {self.filled} missing joint samples filled"
        )


#: frames per second below which ``clean`` says a take's frame time looks wrong: motion
#: capture runs at 24-240 fps, and a take whose exporter left its frame time at 1 s (a
#: Blender export did) is resampled 120-fold by the engines that work at 120 fps
LEAST_CAPTURE_FPS = 10.0
#: ... and above which: body capture rarely runs above 500 fps, and a frame time with a
#: digit too many (0.00083333 for 0.0083333) has the engines that work at 120 fps keep
#: one frame in ten and see motion ten times too fast
MOST_CAPTURE_FPS = 1000.0


def _frame_time_note(source: Path, motion) -> str | None:
    """A note for a take whose frame rate lies outside any capture's (its Frame Time line
    is likely wrong), else None."""
    from .engine.base import UNIVERSAL_FPS
    from .engine.view import resampled_frames

    if LEAST_CAPTURE_FPS <= motion.fps <= MOST_CAPTURE_FPS:
        return None
    where = "far below" if motion.fps < LEAST_CAPTURE_FPS else "far above"
    return (
        f"{source} runs at {motion.fps:g} fps (Frame Time {1 / motion.fps:g} s), {where} any capture's rate; if its "
        f"exporter wrote the wrong frame time, mend that line: an engine that works at {UNIVERSAL_FPS:g} fps "
        f"resamples the take to {resampled_frames(motion.n_frames, motion.fps, UNIVERSAL_FPS):,} frames"
    )


def clean_file(
    engine,
    source: Path,
    output: Path,
    mask: str | None = None,
    keep_reference: bool = False,
    fill_suspects: bool = False,
    unit_cm: float | None = None,
) -> TakeReport:
    """Clean the take ``source`` with ``engine`` and write it to ``output`` as BVH
    (atomically). Its mask is ``mask``, else the ``SOURCE.mask.json`` sidecar if there is
    one; a T-pose reference frame 0 is written back as it is unless ``keep_reference``;
    with ``fill_suspects`` the samples ``workbench inspect`` flags as bad data
    (:func:`workbench.data.inspection.suspects_missing`) are cleaned as gaps; ``unit_cm``
    overrides the take's guessed unit (:func:`workbench.io.read_motion`).
    Raises what reading and cleaning raise (MotionFileError, EngineError, ...)."""
    from .data import has_reference_frame
    from .io import read_motion, write_bvh
    from .io.errors import MotionFileError
    from .io.mask import observed_take, take_mask

    source, output = Path(source), Path(output)
    motion = read_motion(source, unit_cm)
    notes = [note] if (note := _frame_time_note(source, motion)) else []
    observed, mask_path = take_mask(source, motion.skeleton, motion.n_frames, mask)
    if mask_path and not mask:
        notes.append(f"using the mask sidecar {mask_path}")
    reference = None
    if has_reference_frame(motion) and not keep_reference:
        reference, motion = motion.channels[:1], motion.slice(1)
        if not np.isfinite(reference).all():  # it would stop the write, after the whole clean
            raise MotionFileError(
                source,
                "frame 0, a T-pose reference frame that clean writes back as it is, has a missing value (NaN): "
                "mend it, or clean it with the motion (--keep-reference)",
            )
        observed = None if observed is None else observed[1:]
        notes.append(
            f"frame 0 of {source} is a T-pose reference frame: written back as it is, not cleaned "
            "(--keep-reference cleans it with the motion)"
        )
    observation = observed_take(source, motion, observed)
    never = [motion.skeleton.names[j] for j in np.flatnonzero(~observation.observed.any(axis=0))]
    if never:
        notes.append(
            f"{', '.join(never[:4])}{f' and {len(never) - 4} more' if len(never) > 4 else ''}: never observed in "
            f"the take, so the engine could only make {'them' if len(never) > 1 else 'it'} up"
        )
    if fill_suspects:
        from .data.inspection import FILL_REASONS, suspects_missing

        before, observation = observation, suspects_missing(observation)
        whole = before.observed.any(axis=0) & ~observation.observed.any(axis=0)
        if whole.any():  # a joint bad in every frame is not bad data but a wrong unit or frame time
            from .core.motion import Observation

            kept = observation.observed | (before.observed & whole)
            observation = Observation(before.motion, kept, observation.capture_step)
            names = [observation.skeleton.names[j] for j in np.flatnonzero(whole)]
            notes.append(
                f"{', '.join(names)}: flagged as bad data in every frame it was observed, so kept as observed; if "
                f"the take's unit ({observation.skeleton.unit_cm:g} cm, from its rest pose's height) or frame time "
                "is wrong, the whole take looks broken: mend the file"
            )
        suspects = before.observed & ~observation.observed
        notes.append(
            f"{int(suspects.sum())} samples in {int(suspects.any(axis=1).sum())} frames flagged as bad data "
            f"({', '.join(FILL_REASONS)}) cleaned as gaps"
        )
        del before
    elif (broken := _broken_frames(observation)) is not None:
        notes.append(broken)
    del motion  # the observation holds the take: a long take's 50 MB are not kept twice
    t0 = time.perf_counter()
    result = engine.clean(observation)
    seconds = time.perf_counter() - t0
    cleaned = result.motion
    if (rejected := _rejected_note(result, observation, engine.spec_used_ or engine.spec)) is not None:
        notes.append(rejected)
    if (trial := _trial_note(result, engine.info.name)) is not None:
        notes.append(trial)
    del result
    if reference is not None:
        cleaned = cleaned.with_channels(np.concatenate([reference, cleaned.channels]))
    _remove_stale_temporaries(output)
    write_bvh(output, cleaned)
    return TakeReport(
        source,
        output,
        observation.n_frames,
        seconds,
        int((~observation.observed).sum()),
        engine.spec_used_ or engine.spec,
        engine.weights_used_,
        tuple(notes),
    )


#: the share of a take's observed samples a robust engine may set aside before ``clean`` says so
REJECTED_SHARE_NOTED = 0.01


def _broken_frames(observation) -> str | None:
    """A note where the body jumps faster than a body can (``workbench inspect``'s ``jump``
    rule, the one cheap enough for every clean): an engine that trusts such frames spreads
    them over the take; else None."""
    from .data.inspection import RULES

    flags = RULES["jump"](observation.motion)[0]  # (a missing root, NaN, is not fast: no bridging needed)
    frames = np.flatnonzero((flags & observation.observed).any(axis=1))
    if not frames.size:
        return None
    return (
        f"{frames.size} frames (from {frames[0]}) jump faster than a body can: broken frames an engine trusts as "
        "observed, which a network spreads over the take; `workbench inspect` shows them and --fill-suspects "
        "cleans them as gaps"
    )


def _rejected_note(result, observation, spec: str) -> str | None:
    """A note where a robust engine set aside more than :data:`REJECTED_SHARE_NOTED` of the
    observed samples as outliers (``robust_weight`` below 0.5): on a clean take that is
    motion faster than its bases hold, which it then smooths away; else None."""
    weight = result.diagnostics.get("robust_weight")
    if weight is None:
        return None
    weight = np.asarray(weight)
    if weight.shape == observation.motion.channels.shape:
        seen = observation.channel_observed
    elif observation.observed.all():  # over joint positions (F, 3J; mssa's position mode): all observed too
        seen = np.ones(weight.shape, bool)
    else:
        return None
    seen = seen & (weight > 0).any(axis=0)  # the channels it weighs (not those it leaves out, weighed 0 throughout)
    rejected = int(((weight < 0.5) & seen).sum())
    if rejected <= REJECTED_SHARE_NOTED * max(int(seen.sum()), 1):
        return None
    return (
        f"{spec} set aside {rejected} of the observed samples ({100 * rejected / seen.sum():.1f} %) as outliers and "
        "replaced them; on a take with no outliers that is motion its bases do not hold (a kick, a dance), smoothed "
        "away: `robust=false` keeps it"
    )


def _trial_note(result, name: str) -> str | None:
    """A note where an autoencoder filled long holes partly by linear interpolation, as trials
    beside them asked (its ``network_share`` diagnostic below 1); else None."""
    share = result.diagnostics.get("network_share")
    if share is None:
        return None
    share = np.asarray(share)
    moved = share < 1.0
    if not moved.any():
        return None
    return (
        f"{name} filled {int(moved.sum())} frames of long holes partly by linear interpolation (its network's "
        f"fill kept at {share[moved].mean():.0%}, the mean over the joints): on stretches hidden "
        "beside them lerp came nearer, as on motion unlike its training takes; `trial_holes=false` keeps the "
        "network's fill"
    )


def _remove_stale_temporaries(output: Path) -> None:
    """Remove what an atomic write of ``output`` killed mid-way left beside it."""
    for stale in output.parent.glob(f".{output.name}.*.tmp") if output.parent.is_dir() else ():
        stale.unlink(missing_ok=True)


# -- on a worker ------------------------------------------------------------------------
#: the engines this process has made, by (spec, mapping file): each worker loads weights once
_ENGINES: dict[tuple[str, str | None], object] = {}


def worker_engine(spec: str, mapping: str | None = None):
    """The engine ``spec`` (with the humanoid ``mapping`` file's overrides), made once per
    process and kept; the first one also tunes the worker's allocator for long takes, as
    the command line does (:func:`workbench.allocator.keep_freed_arrays`)."""
    key = (spec, mapping)
    if key not in _ENGINES:
        from . import registry
        from .allocator import keep_freed_arrays

        if not _ENGINES:
            keep_freed_arrays()

        engine = registry.create(spec)
        if mapping:
            from .engine import with_humanoid_overrides
            from .io.mapping import read_mapping

            with_humanoid_overrides(engine, read_mapping(mapping))
        _ENGINES[key] = engine
    return _ENGINES[key]


@contextmanager
def one_thread():
    """BLAS and torch (where the torch engines have loaded it) on one thread: a task's
    result is then the same whatever runs beside it."""
    import sys

    from threadpoolctl import threadpool_limits

    torch = sys.modules.get("torch")
    threads = torch.get_num_threads() if torch is not None else None
    with threadpool_limits(1):
        if torch is not None:
            torch.set_num_threads(1)
        try:
            yield
        finally:
            if torch is not None:
                torch.set_num_threads(threads)


def clean_task(
    spec: str,
    mapping: str | None,
    source: str,
    output: str,
    keep_reference: bool,
    fill_suspects: bool = False,
    unit_cm: float | None = None,
) -> TakeReport:
    """One take, on a worker, with one thread: its report, with the reason as ``error``
    when it failed (a bad file, a skeleton the engine refuses, or a bug)."""
    from .errors import describe

    try:
        with one_thread():
            engine = worker_engine(spec, mapping)
            try:  # before the take is read: an edit while it is cleaned then shows on the next resume
                stamp = take_stamp(Path(source))
            except OSError:  # (clean_file says what is wrong with it)
                stamp = None
            report = clean_file(engine, Path(source), Path(output), None, keep_reference, fill_suspects, unit_cm)
            return replace(report, stamp=stamp)
    except Exception as err:  # reported with the others at the end, never raised on the worker
        return TakeReport(Path(source), Path(output), error=describe(err))


# -- the batch --------------------------------------------------------------------------
def take_stamp(source: Path) -> dict:
    """What a take is cleaned from: the SHA-256 of its bytes, of its mask sidecar's (None
    where it has none) and, for an AMC take, of its ASF skeleton's. Raises OSError where
    the take cannot be read."""
    from .engine.weights import sha256_file
    from .io.mask import sidecar_path

    if not source.is_file():  # (a pipe would block the read)
        raise OSError(f"{source} is not a file")
    sidecar = sidecar_path(source)
    stamp = {"take": sha256_file(source), "mask": sha256_file(sidecar) if sidecar.is_file() else None}
    if source.suffix.lower() == ".amc":
        from .io.asfamc import find_asf
        from .io.errors import MotionFileError

        try:
            stamp["skeleton"] = sha256_file(find_asf(source))
        except MotionFileError as err:
            raise OSError(str(err)) from None
    return stamp


class FolderRecord:
    """An output folder's :data:`MANIFEST`: a JSON line of the settings it is cleaned with
    (``{"settings": ...}``), then one per take written (``{"output": its path below the
    folder, "stamp": take_stamp, "size": bytes, "mtime_ns": ...}``; a later line of an
    output replaces an earlier one). A line cut short by a killed process is left out.

    Opened with ``resume``, a folder cleaned with other settings is refused (ValueError
    naming both) and its lines are kept; otherwise the record starts afresh with the
    settings alone (atomically), so no earlier take counts as done. A record written
    before the takes had lines (one JSON object of the settings) resumes nothing. An
    output folder that cannot be made, or a record that cannot be written, raises
    :class:`workbench.io.OutputFileError` (the folders made for it removed again)."""

    def __init__(self, out_dir: Path, settings: dict, resume: bool) -> None:
        from .io.atomic import atomic_write_text
        from .io.errors import OutputFileError

        self.out_dir, self.settings, self.resume = Path(out_dir), settings, resume
        self.path = self.out_dir / MANIFEST
        self.done: dict[str, dict] = {}
        #: the folders this record made, innermost first (:meth:`discard_if_unused`)
        self.created: list[Path] = []
        if resume and self.path.exists():
            before, self.done = self._read()
            if before != settings:
                raise ValueError(
                    f"{out_dir} was cleaned with {_settings_text(before)}, not {_settings_text(settings)}: --resume "
                    "would mix the two; leave out --resume to clean every take again, or name another folder"
                )
        else:
            if self.out_dir.is_symlink() and not self.out_dir.exists():
                raise OutputFileError(self.out_dir, FileNotFoundError(errno.ENOENT, "a link to nothing"))
            self.created = [d for d in (self.out_dir, *self.out_dir.parents) if not d.exists()]
            try:
                self.out_dir.mkdir(parents=True, exist_ok=True)
            except OSError as err:  # a file in the way, no permission
                raise OutputFileError(self.out_dir, err) from None
        # written whole (atomically): a record of the old layout or a last line cut short
        # would otherwise take the lines appended after it
        lines = [{"settings": settings}, *self.done.values()]
        try:
            atomic_write_text(self.path, "".join(json.dumps(line) + "\n" for line in lines))
        except OutputFileError:
            self.discard_if_unused()
            raise

    def _read(self) -> tuple[dict, dict[str, dict]]:
        unreadable = ValueError(
            f"{self.path} cannot be read, so what {self.out_dir} was cleaned with is not known: --resume could mix "
            "two cleanings; leave out --resume to clean every take again, or name another folder"
        )
        try:
            text = self.path.read_text(encoding="utf-8")
        except (OSError, ValueError):
            raise unreadable from None
        try:
            whole = json.loads(text)
        except ValueError:
            whole = None
        if isinstance(whole, dict) and "settings" not in whole:  # the record of a clean before takes had lines
            return whole, {}
        lines = text.splitlines()
        done: dict[str, dict] = {}
        try:
            settings = json.loads(lines[0])["settings"]
            for i, line in enumerate(lines[1:], 2):
                try:
                    entry = json.loads(line)
                except ValueError:
                    if i == len(lines):  # the last line, cut short by a killed process
                        break
                    raise
                done[entry["output"]] = entry
        except (ValueError, KeyError, TypeError, IndexError):
            raise unreadable from None
        return settings, done

    def _key(self, output: Path) -> str:
        return Path(output).relative_to(self.out_dir).as_posix()

    def up_to_date(self, source: Path, output: Path) -> bool:
        """Whether ``output`` is the file this record says was cleaned from ``source`` as it is now."""
        entry = self.done.get(self._key(output))
        if entry is None or not Path(output).is_file():
            return False
        stat = Path(output).stat()
        if (stat.st_size, stat.st_mtime_ns) != (entry.get("size"), entry.get("mtime_ns")):
            return False
        try:
            return take_stamp(Path(source)) == entry.get("stamp")
        except OSError:
            return False

    def add(self, report: TakeReport) -> None:
        """Record a take ``report`` says was written (appended, flushed to disk); one gone
        since (moved away meanwhile) is left out, so a resume cleans it again."""
        try:
            stat = report.output.stat()
        except OSError:
            return
        entry = {"output": self._key(report.output), "stamp": report.stamp}
        entry |= {"size": stat.st_size, "mtime_ns": stat.st_mtime_ns}
        with self.path.open("a", encoding="utf-8", newline="\n") as f:
            f.write(json.dumps(entry) + "\n")
            f.flush()
            os.fsync(f.fileno())
        self.done[entry["output"]] = entry

    def discard_if_unused(self) -> None:
        """Remove the record and the folders it made where they hold no other file (every
        take failed, or the cluster could not be reached): a failed command leaves no output
        folder behind. Where a file is there (a take whose report was cut off by an
        interrupt), everything stays, the record too, so ``--resume`` goes on."""
        if not self.created or self.done:
            return
        try:
            inside = [p for p in self.out_dir.rglob("*") if p != self.path]
            if not all(p.is_dir() for p in inside):
                return
            self.path.unlink(missing_ok=True)
            inside.sort(key=lambda p: len(p.parts), reverse=True)
            for folder in [*inside, *self.created]:  # the deepest first: each is empty when its turn comes
                folder.rmdir()
        except OSError:  # a file that came meanwhile: what is left stays
            pass


def _settings_text(settings: dict) -> str:
    """A record's settings as the options that give them."""
    parts = [f"--engine {settings.get('engine')!r}"]
    parts += [f"--{name.replace('_', '-')}" for name in ("keep_reference", "fill_suspects") if settings.get(name)]
    if settings.get("unit_cm"):
        parts.append(f"--unit {settings['unit_cm']:g}")
    if settings.get("mapping"):
        parts.append(f"--mapping pinning {', '.join(f'{k}={v}' for k, v in settings['mapping'].items())}")
    return " ".join(parts)


def library_jobs(source: Path, out_dir: Path) -> list[tuple[Path, Path]]:
    """The (take, cleaned take) pairs of ``clean SOURCE -o OUT_DIR``: every .bvh and .amc
    file below ``source``, outside ``out_dir`` (which may lie inside it), to the same place
    below ``out_dir`` as .bvh. ValueError, naming the files, when ``source`` holds no take,
    when it lies inside ``out_dir``, when ``out_dir`` lies inside it and holds takes no
    clean wrote, when two takes would be cleaned to one file (``a.bvh`` and ``a.BVH``, ``a.bvh`` and
    ``a.amc``, or ``A.bvh`` and ``a.bvh``, one file on a disk that ignores case), or when
    ``out_dir`` holds files where cleaned takes go but no clean has written there (no
    :data:`MANIFEST`): they are someone's takes, which it would overwrite."""
    from .data.roots import files_under
    from .io import MOTION_SUFFIXES

    inside = out_dir.resolve()
    if source.resolve().is_relative_to(inside):
        raise ValueError(f"{source} lies inside the output folder {out_dir}: name an output folder outside it")
    found = [p for p in files_under(source) if p.suffix.lower() in MOTION_SUFFIXES]
    takes = [p for p in found if not p.resolve().is_relative_to(inside)]
    if len(takes) < len(found) and not (out_dir / MANIFEST).exists():  # takes, not what a clean wrote there
        held = [p for p in found if p not in takes]
        raise ValueError(
            f"the output folder {out_dir} lies inside {source} and holds {held[0]}"
            f"{f' and {len(held) - 1} more takes' if len(held) > 1 else ''}, which would not be cleaned: name an "
            "output folder outside it"
        )
    if not takes:
        raise ValueError(f"{source} holds no .bvh or .amc file")
    jobs = [(p, out_dir / p.relative_to(source).with_suffix(".bvh")) for p in takes]
    first: dict[str, Path] = {}
    for take, output in jobs:
        key = output.relative_to(out_dir).as_posix().casefold()  # one file where names ignore case
        if key in first:
            raise ValueError(f"{first[key]} and {take} would both be cleaned to {output}: move or rename one of them")
        first[key] = take
    there = [output for _, output in jobs if output.exists()]
    if there and not (out_dir / MANIFEST).exists():
        raise ValueError(
            f"{out_dir} already holds {there[0]}{f' and {len(there) - 1} more' if len(there) > 1 else ''} where "
            "cleaned takes go, and no clean wrote them: cleaning would overwrite them; name a new or empty folder"
        )
    return jobs


def clean_library(
    spec: str,
    jobs: list[tuple[Path, Path]],
    keep_reference: bool = False,
    fill_suspects: bool = False,
    mapping: str | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    record: FolderRecord | None = None,
    on_report: Callable[[TakeReport], None] | None = None,
    unit_cm: float | None = None,
) -> list[TakeReport]:
    """Clean every (source, output) of ``jobs`` with the engine ``spec`` on Dask
    distributed: a local cluster of ``workers`` processes (default: the machine's
    cores), or the cluster at ``scheduler``. ``record``: the output folder's, where each
    take written is recorded; opened with ``resume``, the takes it holds as done are
    skipped. ``on_report`` sees each take's report as it arrives (skipped ones first);
    ``keep_reference``, ``fill_suspects`` and ``unit_cm``: as :func:`clean_file`'s. Returns the
    reports, in ``jobs``' order. Interrupting it (KeyboardInterrupt) cancels the takes
    not done and re-raises."""
    reports: dict[Path, TakeReport] = {}
    given = {os.path.abspath(source): (source, output) for source, output in jobs}  # as the user named them

    def arrived(report: TakeReport) -> None:
        source, output = given[os.path.abspath(report.source)]

        def as_given(text: str) -> str:  # the files as the user named them
            return text.replace(str(report.source), str(source)).replace(str(report.output), str(output))

        error = None if report.error is None else as_given(report.error)
        notes = tuple(as_given(note) for note in report.notes)
        report = replace(report, source=source, output=output, error=error, notes=notes)
        if record is not None and report.error is None and not report.skipped:
            record.add(report)
        reports[source] = report
        if on_report is not None:
            on_report(report)

    todo = []
    for source, output in jobs:
        if record is not None and record.resume and record.up_to_date(source, output):
            arrived(TakeReport(source, output, skipped=True))
        else:
            _remove_stale_temporaries(output)  # a batch killed mid-write left it
            todo.append((source, output))
    if todo:
        from distributed import as_completed

        mapping = None if mapping is None else os.path.abspath(mapping)
        with dask_client(workers, scheduler, len(todo)) as client:
            futures = [
                client.submit(
                    clean_task,
                    spec,
                    mapping,
                    os.path.abspath(s),
                    os.path.abspath(o),
                    keep_reference,
                    fill_suspects,
                    unit_cm,
                    pure=False,
                )
                for s, o in todo
            ]
            try:
                for future in as_completed(futures):
                    arrived(future.result())
            except BaseException:
                client.cancel(futures)
                raise
    return [reports[source] for source, _ in jobs]


@contextmanager
def _ctrl_c_left_to_this_process():
    """Processes started inside ignore SIGINT. Ctrl-C reaches every process of the
    terminal's group: the local cluster's workers then leave it to the client, which
    closes them (each printed its tracebacks). The price: a Ctrl-C while they start (a
    second or two) is lost. From the main thread only; elsewhere nothing changes."""
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    handler = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, handler)


@contextmanager
def dask_client(workers: int | None, scheduler: str | None, n_tasks: int | None = None):
    """A Dask client of the cluster at ``scheduler`` (left running), or of a new local
    cluster of ``workers`` single-threaded processes (default: the machine's cores), no
    more than ``n_tasks`` where given, closed with the client."""
    import logging

    from distributed import Client, LocalCluster

    if scheduler is not None:
        try:
            client = Client(scheduler)
        except (OSError, ValueError) as err:  # (a bad address, or nothing listening there: after Dask's timeout)
            raise ClusterError(
                f"cannot reach a Dask scheduler at {scheduler!r} ({err}); start one there (`dask scheduler`), "
                "or leave out --scheduler to run on a local cluster"
            ) from None
        with client:
            yield client
        return
    n = max(1, min(workers or os.cpu_count() or 1, n_tasks or 1 << 30))
    with _ctrl_c_left_to_this_process():
        cluster = LocalCluster(
            n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=logging.ERROR
        )
    with cluster, Client(cluster) as client:
        yield client
