"""``workbench``: the command line.

Subcommands: data, engines, skeleton, corrupt, clean, bench, train, and the app's gui (also
``workbench`` with no arguments), report, screenshots. Every user error (bad file, bad
spec, missing data or weights) prints one clear line on stderr and exits with status 2;
nothing is half-written.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

from . import __version__


class UserError(Exception):
    """A problem the user can fix; printed without a traceback."""


def _user_errors() -> tuple[type, ...]:
    from .errors import user_errors

    return (UserError, *user_errors())


def _message(err: BaseException) -> str:
    """A user error's one line (a name not found without the quotes a KeyError's str() adds)."""
    from .errors import NameNotFoundError

    return err.args[0] if isinstance(err, NameNotFoundError) and err.args else str(err)


def split_engine_specs(values: list[str]) -> list[str]:
    """``["ebf:bias=true,free=1,gaussian"]`` -> ``["ebf:bias=true,free=1", "gaussian"]``:
    a comma-separated piece that is a bare ``key=value`` continues the previous spec.
    UserError where ``values`` name no engine at all (``","``)."""
    specs: list[str] = []
    for value in values:
        for piece in filter(None, (p.strip() for p in value.split(","))):
            if specs and "=" in piece and ":" not in piece.split("=")[0] and ">" not in piece:
                specs[-1] += "," + piece
            else:
                specs.append(piece)
    if values and not specs:
        raise UserError(f"no engine named in {' '.join(values)!r}: name one or more, e.g. 'kalman,ebf'")
    return specs


# -- data -------------------------------------------------------------------------------
def _data_root(args, training: bool = False) -> Path:
    """The data root of ``--data`` (found as :func:`find_data_root` does). The embedded
    takes are said to be in use, and refused for training: they are test clips."""
    from .data import CMU_CLIPS, find_data_root, is_embedded

    root = find_data_root(args.data)
    if is_embedded(root):
        if training:
            raise UserError(
                "no data folder found (--data, $WORKBENCH_DATA, datasets/, ../shared/data), and the two CMU "
                f"takes embedded in the package are test clips, never trained on.\n{CMU_CLIPS}"
            )
        print(
            "note: no data folder found (--data, $WORKBENCH_DATA, datasets/, ../shared/data); "
            "using the two CMU takes embedded in the package (cmu/walk/35_31, cmu/jump/16_06)",
            file=sys.stderr,
        )
    return root


def cmd_data(args) -> int:
    from .data import SPLITS, catalogue, select

    root = _data_root(args)
    every = catalogue(root)
    clips = select(every, args.split, dataset=args.dataset)
    if not clips:
        datasets = ", ".join(dict.fromkeys(c.dataset for c in every)) or "none"
        raise UserError(
            f"no clips of split={args.split!r} dataset={args.dataset!r} under {root} (its datasets: {datasets})"
        )
    print(f"data root: {root}")
    wide = {"id": 4, "category": 8, "who": 13}
    for c in clips:
        wide = {
            "id": max(wide["id"], len(c.id)),
            "category": max(wide["category"], len(c.category)),
            "who": max(wide["who"], len(c.subject or c.style)),
        }
    print(
        f"{'clip':{wide['id']}s}  {'category':{wide['category']}s}  {'subject/style':{wide['who']}s}  "
        f"{'split':10s} {'frames':>6s} {'fps':>4s}"
    )
    for c in clips:
        print(
            f"{c.id:{wide['id']}s}  {c.category:{wide['category']}s}  {c.subject or c.style:{wide['who']}s}  "
            f"{c.split or '-':10s} {c.frames or '?':>6} {f'{c.fps:g}' if c.fps else '?':>4}"
        )
    for name in dict.fromkeys(c.dataset for c in clips):
        mine = [c for c in clips if c.dataset == name]
        counts = ", ".join(f"{n} {s}" for s in SPLITS if (n := sum(c.split == s for c in mine)))
        rates = "/".join(f"{r:g}" for r in sorted({c.fps for c in mine if c.fps}))
        frames = sum(c.frames for c in mine)
        print(
            f"{name or 'clips'}: {len(mine)} clips ({counts or 'in no split'})"
            + (f", {frames:,} frames" if frames else "")
            + (f" at {rates} fps" if rates else "")
        )
    if any(c.dataset == "cmu" for c in clips):
        print("Frame 0 of the cgspeed conversions (cmu) is a T-pose reference frame; loading drops it.")
    return 0


def cmd_engines(args) -> int:
    import dataclasses

    from . import registry
    from .engine import WEIGHTS_OPTION, EngineInfo

    for name in registry.available():
        try:
            cls = registry.get(name)
        except Exception as err:  # show broken plugins instead of hiding them (its message names the engine)
            print(f"{name:16s} ({err})")
            continue
        info = getattr(cls, "info", None)
        if not isinstance(info, EngineInfo):
            print(f"{name:16s} (broken: {cls.__module__}.{cls.__name__} sets no `info = EngineInfo(...)`)")
            continue
        params = ", ".join(
            [
                f"{f.name}={f.default if f.default is not dataclasses.MISSING else '(no default: a fault)'}"
                for f in dataclasses.fields(cls.Params)
            ]
            + ([f"{WEIGHTS_OPTION}=DIR (trained weights; default: the committed ones)"] if info.trainable else [])
        )
        flags = "/".join(sorted(info.tasks)) + f", {info.space}" + (", trainable" if info.trainable else "")
        print(f"{name:16s} {info.summary} [{flags}]" + (f"\n{'':16s} parameters: {params}" if params else ""))
        if info.citation:
            print(f"{'':16s} source: {info.citation}")
    return 0


# -- corrupt / clean --------------------------------------------------------------------
def _read(path: str, unit_cm: float | None = None):
    from .io import read_motion

    return read_motion(path, unit_cm)


def cmd_skeleton(args) -> int:
    from .core.humanoid import HumanoidError, map_humanoid
    from .core.upright import up_turn
    from .engine.view import body_skeleton

    motion = _read(args.take, args.unit)
    s = motion.skeleton
    overrides = _pins(args)
    print(
        f"{args.take}: {s.n_joints} joints, root {s.names[0]!r}, body root {s.names[s.body_root]!r}, {motion.fps:g} fps"
    )
    unit = f"unit: {s.unit_cm:g} cm{_unit_source(s, args.unit)}"
    try:  # refused as the engines refuse it, on the body view (no reference node above the body root)
        map_humanoid(body_skeleton(s), overrides)
        mapping = map_humanoid(s, overrides)
    except HumanoidError:  # what was found, then why it is refused
        print(map_humanoid(s, overrides, checked=False).describe())
        print(unit)
        raise
    print(mapping.describe())
    turn = up_turn(motion, overrides)
    up = "+Y" if turn is None else "".join(f"{'+' if v > 0 else '-'}{a}" for a, v in zip("XYZ", turn[1]) if v)
    print(f"{unit}; up: {up}" + ("" if turn is None else " (turned onto +Y for the trained engines and the app)"))
    return 0


def _unit_source(skeleton, given: float | None) -> str:
    """How a take's unit was found, where it was not from its rest pose's height."""
    from .core.skeleton import fitting_unit_cm

    if given is not None:
        return " (--unit)"
    if fitting_unit_cm(skeleton) is None:
        return " (no unit makes the rest pose 120-220 cm tall: cm is a guess; --unit says it)"
    return ""


def _pins(args) -> dict[str, str | None] | None:
    """The canonical joints the ``--mapping`` file pins (read once a command), or None."""
    from .io.mapping import read_mapping

    return read_mapping(args.mapping) if args.mapping else None


def _with_epochs(engine, epochs: int):
    """``engine`` (one engine, not a pipeline) with ``epochs``: ``--epochs`` wins over an
    ``epochs=`` in the spec (one copied from a manifest). UserError where it is fitted in
    closed form."""
    if not hasattr(engine.params, "epochs"):
        raise UserError(f"{engine.info.name} is fitted in closed form, not in epochs: leave out --epochs")
    return type(engine)(dataclasses.replace(engine.params, epochs=epochs))


def cmd_inspect(args) -> int:
    if args.measure:
        given = [args.take] if args.take is not None else []
        given += [f"--{name}" for name in ("mask", "mapping", "unit", "json") if getattr(args, name)]
        if given:
            raise UserError(
                f"inspect --measure scores the flags on catalogue clips, not on a take: leave out {', '.join(given)}"
            )
        return _measure_inspection(args)
    if args.take is None:
        raise UserError("inspect needs a TAKE, or --measure")
    from . import registry
    from .core.motion import Observation
    from .data import without_reference_frame
    from .data.inspection import FILL_REASONS, inspect_motion
    from .engine import with_humanoid_overrides
    from .io.mask import observed_take, take_mask

    recorded = _read(args.take, args.unit)
    motion = without_reference_frame(recorded)
    dropped = recorded.n_frames - motion.n_frames
    observed, mask = take_mask(args.take, recorded.skeleton, recorded.n_frames, args.mask)  # the file's frames
    observed = observed_take(args.take, motion, None if observed is None else observed[dropped:]).observed
    weights, points, overrides = [], [], _pins(args)
    if overrides:  # checked against the take as every engine checks it, whether or not one runs
        from .core.humanoid import map_humanoid
        from .engine.view import body_skeleton

        map_humanoid(body_skeleton(motion.skeleton), overrides)
    for spec in args.engine or []:
        result = with_humanoid_overrides(registry.create(spec), overrides).clean(Observation(motion, observed))
        points.append(result.motion.positions * motion.skeleton.unit_cm)
        if "robust_weight" in result.diagnostics:
            weights.append(result.diagnostics["robust_weight"])
    found = inspect_motion(motion, observed, weights, points)
    report = found.to_json() | {"take": args.take, "reference_frames_dropped": dropped}
    if args.json:
        print(_strict_json(report))
        return 0
    if dropped:
        print("note: dropped frame 0, a T-pose reference frame; frames below count from the next", file=sys.stderr)
    if mask is not None:
        print(f"note: the missing samples are those {mask} lists", file=sys.stderr)
    intervals = found.intervals()
    print(
        f"{args.take}: {motion.n_frames} frames at {motion.fps:g} fps; {report['flagged_frames']} suspicious "
        f"frames in {len(intervals)} intervals"
    )
    for interval in intervals:
        print(f"  {interval}")
    if any(i.reason in FILL_REASONS for i in intervals):
        print(
            f"note: `workbench clean {args.take} -o OUT.bvh --engine SPEC --fill-suspects` cleans what "
            f"{', '.join(FILL_REASONS)} flag as gaps",
            file=sys.stderr,
        )
    return 0


def _measure_inspection(args) -> int:
    from .evaluate import inspection_markdown, measure_inspection

    chosen = _bench_clips(args)
    seeds = list(range(args.seed0, args.seed0 + args.seeds))
    print(f"measuring inspect on {len(chosen)} clips x {len(seeds)} seeds", file=sys.stderr)
    for name in sorted({c.dataset for c in chosen}):
        clips = [(c.id, c.load()) for c in chosen if c.dataset == name]
        print(f"{name} ({len(clips)} clips, split {args.split}, {len(seeds)} seeds):")
        print(inspection_markdown(measure_inspection(clips, seeds, args.engine or [])))
        print()
    return 0


def _check_bvh_output(output: Path) -> None:
    """Raise UserError unless ``output`` names a BVH file (what the commands write)."""
    if output.is_dir():
        raise UserError(f"-o {output} is a folder: name the .bvh file to write, e.g. -o {output / 'take.bvh'}")
    if output.suffix.lower() != ".bvh":
        raise UserError(f"-o {output}: the take is written as BVH; name the file with the .bvh suffix")


def _refuse_overwriting(output: Path, take: Path, mask: Path, hint: str) -> None:
    """Raise UserError where the file ``output`` is the input ``take`` or its ``mask``
    (the one it is read with, or its sidecar): writing it would lose the user's data."""
    for path, what in ((take, "the input take"), (mask, f"the mask of {take}")):
        if output.resolve() == path.resolve() or output.exists() and path.exists() and output.samefile(path):
            raise UserError(f"-o {output} is {what}: writing it would overwrite the raw data; {hint}")


def _strict_json(doc) -> str:
    """``doc`` as JSON that any parser reads: numpy numbers as numbers, NaN and infinities
    (a metric with nothing to measure) as null, which Python's json writes as NaN."""

    def plain(value):
        if isinstance(value, dict):
            return {k: plain(v) for k, v in value.items()}
        if isinstance(value, (list, tuple)):
            return [plain(v) for v in value]
        if isinstance(value, (float, np.floating)):
            return float(value) if math.isfinite(value) else None
        return value.item() if isinstance(value, np.generic) else value

    return json.dumps(plain(doc), indent=1, allow_nan=False)


def cmd_corrupt(args) -> int:
    from .corruption import parse_corruption
    from .data import without_reference_frame
    from .io import write_bvh
    from .io.atomic import atomic_path, written_path
    from .io.mask import sidecar_path, write_mask

    recorded = _read(args.input, args.unit)
    motion = recorded if args.keep_reference else without_reference_frame(recorded)
    if motion.n_frames < recorded.n_frames:
        print("note: dropped frame 0, a T-pose reference frame (--keep-reference keeps it)", file=sys.stderr)
    source, out = Path(args.input), Path(args.output)
    missing = ~np.isfinite(motion.channels).all(axis=1)
    if missing.any():
        first = int(np.argmax(missing)) + recorded.n_frames - motion.n_frames  # the file's frame number
        raise UserError(
            f"{source} has missing values (NaN) in {int(missing.sum())} frame(s), first in frame {first} of the "
            "file: corrupt makes a test take from a complete, clean one; clean this one first (workbench clean)"
        )
    mask_path = sidecar_path(written_path(out))  # beside the file written (a link's target), where its reader looks
    for path in (out, mask_path):
        _refuse_overwriting(path, source, sidecar_path(source), "name another file")
    _check_bvh_output(out)
    obs = parse_corruption(args.corrupt).apply(motion, seed=args.seed)
    with atomic_path(out) as take_tmp, atomic_path(mask_path) as mask_tmp:  # both, or neither
        write_bvh(take_tmp, obs.bridged())
        write_mask(mask_tmp, obs.observed, motion.skeleton)
    missing = 1.0 - obs.observed.mean()
    print(f"wrote {out} ({motion.n_frames} frames, corruption {parse_corruption(args.corrupt)}, seed {args.seed})")
    print(f"wrote {mask_path} ({missing:.1%} of joint samples missing; gaps are bridged linearly in the BVH)")
    return 0


#: the suffix of the raw take ``clean --in-place`` keeps beside it
BACKUP_SUFFIX = ".orig"


def _backup_of(take: Path) -> Path:
    """Where ``clean --in-place`` keeps the raw ``take``: TAKE.orig beside it."""
    return take.with_name(take.name + BACKUP_SUFFIX)


def _clean_record(take: Path) -> Path:
    """Where ``clean --in-place`` records the SHA-256 of the take it wrote: a hidden file
    beside it, so that the next in-place clean can tell its own output from a new take."""
    return take.with_name(f".{take.name}{BACKUP_SUFFIX}.json")


def _back_up(take: Path) -> Path | None:
    """Keep ``take`` as TAKE.orig before it is cleaned over itself (atomically) and return
    that file. An existing backup is kept (None), since it holds the take as it was before
    the first clean, if ``take`` is what the last in-place clean wrote (its record, else
    the backup's skeleton and frame count); otherwise UserError: ``take`` is another take
    (a new raw take copied over a cleaned one), which cleaning would lose."""
    import shutil

    from .engine.weights import sha256_file
    from .io import read_motion
    from .io.atomic import atomic_path
    from .io.errors import MotionFileError

    backup = _backup_of(take)
    if not backup.exists():
        with atomic_path(backup) as tmp:
            shutil.copy2(take, tmp)
        return backup
    try:
        written = json.loads(_clean_record(take).read_text(encoding="utf-8"))["cleaned_sha256"]
    except (OSError, ValueError, KeyError, TypeError):  # a backup made before the record was kept
        written = None
    if written is not None:
        other = sha256_file(take) != written
    else:
        try:
            kept = read_motion(backup)
        except MotionFileError as err:
            raise UserError(f"{backup} cannot be read ({err}); move it away before cleaning {take} in place") from None
        now = read_motion(take)
        other = (kept.skeleton.signature(), kept.n_frames) != (now.skeleton.signature(), now.n_frames)
    if other:
        raise UserError(
            f"{take} is not the take its last in-place clean wrote (another take copied over it, or an edit), and "
            f"{backup} holds another: cleaning in place would leave no copy of this one; move the old backup away"
        )
    print(f"note: {backup} is kept as it is (the take before its first in-place clean)", file=sys.stderr)
    return None


def _settle_mask(take: Path, backed_up: bool) -> None:
    """After ``clean --in-place`` filled the gaps ``take``'s mask sidecar names: left
    beside the cleaned take, the sidecar would mark filled samples missing (``inspect``, a
    later clean). Where this clean ``backed_up`` the raw take, the sidecar describes that
    backup and moves beside it; otherwise (the backup is an earlier take's, or has a mask)
    it stays, with a note to remove it."""
    from .io.mask import sidecar_path

    mask, kept = sidecar_path(take), sidecar_path(_backup_of(take))
    if backed_up and not kept.exists():
        os.replace(mask, kept)
        print(f"note: the mask moved with the raw take, to {kept}", file=sys.stderr)
    else:
        print(f"note: {mask} names the gaps this clean filled: remove it before cleaning again", file=sys.stderr)


def cmd_clean(args) -> int:
    from . import registry
    from .engine import with_humanoid_overrides
    from .io.mask import sidecar_path

    source = Path(args.input)
    if not source.exists():
        raise UserError(f"{source}: no such file or folder")
    if args.in_place:
        if args.output:
            raise UserError("--in-place writes the cleaned take over its input: leave out -o")
        if source.is_dir() or source.suffix.lower() != ".bvh":
            raise UserError(f"--in-place cleans one BVH take over itself; for {source} name an output with -o")
        output = source
    elif not args.output:
        raise UserError("name the cleaned take's file with -o (or clean a BVH take over itself with --in-place)")
    else:
        output = Path(args.output)
        if not source.is_dir():
            _refuse_overwriting(
                output,
                source,
                Path(args.mask) if args.mask else sidecar_path(source),
                f"name another file, or pass --in-place, which keeps the raw take as {source.name}{BACKUP_SUFFIX}",
            )
            _check_bvh_output(output)
    overrides = _pins(args)
    # a bad spec or weights stop here, before any take
    engine = with_humanoid_overrides(registry.create(args.engine), overrides)
    if not source.is_dir():
        from .batch import clean_file

        ignored = [name for name, value in (("--workers", args.workers), ("--scheduler", args.scheduler)) if value]
        if args.resume:
            ignored.append("--resume")
        if ignored:
            print(
                f"note: {', '.join(ignored)}: for a folder of takes; {source} is one take, cleaned here",
                file=sys.stderr,
            )
        from .io.atomic import check_writable

        check_writable(output)  # a read-only or unwritable output is found before the clean, not after it
        backup = _back_up(source) if args.in_place else None
        try:
            report = clean_file(engine, source, output, args.mask, args.keep_reference, args.fill_suspects, args.unit)
        except BaseException:  # the take is as it was: no backup of it is left to mislead a later run
            if backup is not None:
                backup.unlink()
            raise
        if backup is not None:
            print(f"note: the raw take is kept as {backup}", file=sys.stderr)
        if args.in_place:
            from .engine.weights import sha256_file
            from .io.atomic import atomic_write_text

            atomic_write_text(_clean_record(source), json.dumps({"cleaned_sha256": sha256_file(source)}) + "\n")
        for note in report.notes:
            print(f"note: {note}", file=sys.stderr)
        if args.in_place and not args.mask and sidecar_path(source).exists():
            _settle_mask(source, backup is not None)
        print(report)
        return 0
    if args.mask:
        raise UserError("--mask is one take's mask; in a folder each take's own INPUT.mask.json is used")
    if output.resolve() == source.resolve() or output.exists() and not output.is_dir():
        raise UserError(f"-o {output}: for a folder of takes, name another folder for the cleaned ones")
    from .batch import library_jobs

    try:
        jobs = library_jobs(source, output)
    except ValueError as err:
        raise UserError(str(err)) from None
    return _clean_library(args, engine.spec, jobs, overrides)


def _clean_library(args, spec: str, jobs: list[tuple[Path, Path]], overrides: dict | None) -> int:
    """``clean DIR -o OUT`` on Dask (:func:`workbench.batch.clean_library`): a line per
    take (a progress bar above them on a terminal), the failed takes and their reasons
    at the end; exit status 2 when some failed, 130 when interrupted. ``overrides``: what
    the ``--mapping`` file pins (:func:`_pins`), recorded for ``--resume``. A folder this
    command made is removed again where no take was written into it."""
    from .batch import FolderRecord

    # the mapping by what it pins (``overrides``), not by its path: an edited file cleans again
    mapping = None if overrides is None else dict(sorted(overrides.items()))
    settings = {"engine": spec, "keep_reference": args.keep_reference, "mapping": mapping}
    if args.fill_suspects:  # only when set: a folder cleaned before the option existed still resumes
        settings["fill_suspects"] = True
    if args.unit is not None:
        settings["unit_cm"] = args.unit
    try:
        record = FolderRecord(Path(args.output), settings, args.resume)
    except ValueError as err:
        raise UserError(str(err)) from None
    try:
        return _clean_into(args, spec, jobs, record)
    finally:
        record.discard_if_unused()


def _clean_into(args, spec: str, jobs: list[tuple[Path, Path]], record) -> int:
    """The takes of ``jobs`` cleaned into the folder of ``record`` (a
    :class:`workbench.batch.FolderRecord`), reported as :func:`_clean_library` says."""
    from .batch import clean_library

    _cluster_notes(args)
    bar = _progress_bar(len(jobs), sum(_size(p) for p, _ in jobs))
    done: list = []
    started = time.time()

    def on_report(report) -> None:
        done.append(report)
        for note in report.notes:
            _say(bar, f"note: {note}", sys.stderr)
        _say(
            bar,
            f"workbench clean: error: {report}" if report.error else str(report),
            sys.stderr if report.error else sys.stdout,
        )
        if bar is not None:
            bar.update(_size(report.source))
            frames = sum(r.frames for r in done)
            bar.set_postfix_str(
                f"{len(done)}/{len(jobs)} takes, {frames / max(bar.format_dict['elapsed'], 1e-9):,.0f} frames/s"
            )

    try:
        reports = clean_library(
            spec,
            jobs,
            args.keep_reference,
            args.fill_suspects,
            args.mapping,
            args.workers,
            args.scheduler,
            record,
            on_report,
            unit_cm=args.unit,
        )
    except KeyboardInterrupt:
        if bar is not None:
            bar.close()
        reported = {r.source for r in done}  # and the takes that were finishing as the cluster closed:
        finishing = sum(1 for source, output in jobs if source not in reported and _size(output, since=started))
        written = sum(1 for r in done if r.error is None and not r.skipped) + finishing
        left = len(jobs) - len(done) - finishing
        print(
            f"workbench clean: interrupted: {written} takes written, {left} not done (no partial file is left); the "
            "same command with --resume goes on from there",
            file=sys.stderr,
        )
        return 130
    if bar is not None:
        bar.close()
    failed = [r for r in reports if r.error is not None]
    skipped = sum(r.skipped for r in reports)
    if skipped:
        print(f"note: {skipped} takes were up to date (--resume) and kept", file=sys.stderr)
    if failed:
        others = (
            "none was written"
            if len(failed) == len(jobs)
            else "the others were written" + (" or kept" if skipped else "")
        )
        print(f"workbench clean: {len(failed)} of {len(jobs)} takes failed ({others}):", file=sys.stderr)
        for report in failed:
            print(f"  {report}", file=sys.stderr)
        return 2
    return 0


def _cluster_notes(args) -> None:
    """On stderr, before a cluster is reached: that --workers does not apply to an
    existing one, and that reaching one may take Dask's 30-s timeout."""
    if args.scheduler is None:
        return
    if args.workers:
        print(f"note: --workers is for a local cluster; the one at {args.scheduler} has its own", file=sys.stderr)
    print(f"note: reaching the Dask scheduler at {args.scheduler} (up to 30 s)", file=sys.stderr)


def _size(path: Path, since: float | None = None) -> int:
    """A file's size in bytes; 0 where it is not there (a dangling link, a take deleted)
    or, with ``since``, was last written before that time (s since the epoch)."""
    try:
        stat = path.stat()
    except OSError:
        return 0
    return 0 if since is not None and stat.st_mtime < since else stat.st_size


def _progress_bar(n_takes: int, total_bytes: int):
    """A tqdm bar over the takes' bytes (time left follows the size still to clean) on a
    terminal; None in a log."""
    if not sys.stderr.isatty():
        return None
    from tqdm import tqdm

    return tqdm(total=total_bytes, unit="B", unit_scale=True, desc=f"{n_takes} takes", file=sys.stderr)


def _say(bar, line: str, stream) -> None:
    """A line above the progress bar (or plainly, without one)."""
    if bar is not None:
        bar.write(line, file=stream)
    else:
        print(line, file=stream, flush=True)


# -- bench ------------------------------------------------------------------------------
def _bench_clips(args):
    """The catalogue clips to benchmark: of every dataset (or ``--dataset``), those in
    ``--split``, or all of them where none of the matching clips is in a split."""
    from .data import CMU_CLIPS, catalogue, is_embedded, select

    root = _data_root(args)
    matched = select(catalogue(root), None, dataset=args.dataset, pattern=args.clips)
    if any(c.split for c in matched):
        chosen = select(matched, args.split)
    else:
        chosen = matched
        if matched and args.split != "all":
            print(
                f"note: these clips have no train/validation/test split; benchmarking all {len(matched)}",
                file=sys.stderr,
            )
    if not chosen:
        splits = sorted({c.split for c in matched if c.split})  # the clips match, in other splits
        elsewhere = (
            f"; the {len(matched)} that match are in {' and '.join(splits)}: --split NAME or all" if splits else ""
        )
        raise UserError(
            f"no clips match split={args.split!r} dataset={args.dataset!r} clips={args.clips!r} under {root}"
            + elsewhere
            + (f"\n{CMU_CLIPS}" if is_embedded(root) else "")
        )
    return _in_unit(chosen, args)


def _in_unit(clips: list, args) -> list:
    """``clips`` read in the length unit ``--unit`` gives, where it is given."""
    unit = getattr(args, "unit", None)
    return clips if unit is None else [dataclasses.replace(c, unit_cm=unit) for c in clips]


def _bench_notes(result) -> None:
    """On stderr: the clips left out (too short for the corruption, refused by an engine,
    one line per engine and reason) and the reference's capture glitches."""
    from .data.quality import MAX_TURN_DPS

    if result.skipped:
        print(
            f"note: {len(result.skipped)} clips could not be corrupted with {result.corruption} and were left out:",
            file=sys.stderr,
        )
        for clip, reason in result.skipped.items():
            print(f"  {clip}: {reason}", file=sys.stderr)
    for spec, refused in result.refused.items():
        by_reason: dict[str, list[str]] = {}
        for clip, reason in refused.items():
            by_reason.setdefault(reason, []).append(clip)
        for reason, clips in by_reason.items():
            more = f" and {len(clips) - 1} more" if len(clips) > 1 else ""
            print(f"note: {spec} did not clean {len(clips)} clips ({clips[0]}{more}): {reason}", file=sys.stderr)
    if result.glitches:
        print(
            f"note: {len(result.glitches)} of the clean clips have capture glitches, where a joint turns faster "
            f"than a body can (over {MAX_TURN_DPS:,.0f} degrees/s); an engine that removes one is scored as wrong "
            "there:",
            file=sys.stderr,
        )
        for clip, found in result.glitches.items():
            print(f"  {clip}: " + "; ".join(map(str, found)), file=sys.stderr)


def _each_once(specs: list[str]) -> list[str]:
    """``specs``, or UserError naming those given twice (a row or a pane is one engine's)."""
    if twice := sorted({s for s in specs if specs.count(s) > 1}):
        raise UserError(f"{', '.join(twice)} named twice: name each engine once")
    return specs


def cmd_bench(args) -> int:
    from .evaluate import run_benchmark

    specs = _each_once(split_engine_specs(args.engines))  # a table has a row per engine
    if args.long and args.json:
        raise UserError("--json is for the clips' benchmark; --long prints its table: leave out --json")
    if args.json:  # before the benchmark's minutes, not after
        from .io.atomic import check_writable

        check_writable(args.json)  # first: a folder or a file in the way is named as such, not by its suffix
        if Path(args.json).suffix.lower() != ".json":  # a take or a data set's MANIFEST.csv is never overwritten
            raise UserError(f"--json {args.json}: the scores are written as JSON; name the file with the .json suffix")
    if args.long:
        return _bench_long(args, specs)
    chosen = _bench_clips(args)
    clips = [(c.id, c.load()) for c in chosen]
    seeds = list(range(args.seed0, args.seed0 + args.seeds))
    print(
        f"benchmark: {len(specs)} engines x {len(clips)} clips x {len(seeds)} seeds, corruption {args.corrupt}"
        + (", suspects filled" if args.fill_suspects else ""),
        file=sys.stderr,
    )
    progress = None
    if args.verbose:

        def progress(msg):
            print("  " + msg, file=sys.stderr)

    _cluster_notes(args)
    result = run_benchmark(
        specs,
        args.corrupt,
        clips,
        seeds,
        progress=progress,
        datasets={c.id: c.dataset for c in chosen},
        workers=args.workers,
        scheduler=args.scheduler,
        per_joint=bool(args.per_joint),
        fill_suspects=args.fill_suspects,
    )
    if not result.rows:  # no table to print, nor scores to write
        _bench_notes(result)
        raise UserError("no engine cleaned any clip (the notes above say why): nothing to score")
    datasets = result.datasets()
    if len(datasets) > 1:  # a table per dataset: their frame rates and skeletons differ
        for name, ids in datasets.items():
            print(f"{name or 'clips'} ({len(ids)} clips):")
            print(result.markdown(name))
            print()
    else:
        print(result.markdown())
    if args.per_clip:
        print()
        print(result.per_clip_markdown(args.per_clip))
    if args.per_joint:  # a table per dataset: their skeletons differ
        for name, ids in datasets.items():
            print()
            if len(datasets) > 1:
                print(f"{name or 'clips'} ({len(ids)} clips):")
            print(result.per_joint_markdown(args.per_joint, name))
    _bench_notes(result)
    if result.worker_peaks_mb:
        peaks = ", ".join(f"{mb:,.0f}" for mb in result.worker_peaks_mb.values())
        print(f"note: the {len(result.worker_peaks_mb)} workers' peak memory: {peaks} MB", file=sys.stderr)
    if args.json:
        from .io.atomic import atomic_write_text

        atomic_write_text(args.json, _strict_json(result.to_json()) + "\n")
        print(f"wrote {args.json}", file=sys.stderr)
    return 0


def _bench_long(args, specs: list[str]) -> int:
    """``bench --long``: the long take made from a shared take, its BVH's speeds, and a
    ``workbench clean`` command per engine on it."""
    from .data import find_clip
    from .evaluate import LONG_CLIP, long_take, run_long_benchmark

    motion = long_take(find_clip(LONG_CLIP, _data_root(args)).load(), args.minutes)
    print(
        f"long benchmark: {LONG_CLIP} forwards and backwards to {args.minutes:g} minutes, corruption {args.corrupt}, "
        f"{len(specs)} engines, each by a workbench clean command of its own",
        file=sys.stderr,
    )
    result = run_long_benchmark(motion, specs, args.corrupt, args.seed0)
    print(result.markdown())
    if failed := [row["engine"] for row in result.rows if "error" in row]:
        print(f"workbench bench: {', '.join(failed)} did not clean the long take (the table says why)", file=sys.stderr)
        return 2
    return 0


# -- train ------------------------------------------------------------------------------
#: the dataset the committed weights were trained on: ``train``'s default where a data
#: root holds the training splits of several
COMMITTED_WEIGHTS_DATASET = "cmu"
#: the data sets a universal variant's committed weights pool (cmu-daz stays out: the unseen skeleton)
COMMITTED_UNIVERSAL_DATASETS = "cmu,bandai"


def _weights_out(named: str | None, engine, overwrite: bool = False) -> Path:
    """The folder ``train`` saves ``engine``'s weights into: ``--out`` (``named``), checked
    before the training, or ``runs/VARIANT``, numbered ``runs/VARIANT-2`` and on where that
    holds weights already. UserError for a folder that cannot take them: one below a file,
    an unwritable one, one among the engine's committed weights or any engine package's
    (they change only by ``--promote``), or a named one that holds weights, unless
    ``overwrite`` (``--overwrite``: a training's minutes are not lost by a typo)."""
    from .engine.weights import MANIFEST_FILE, WEIGHTS_FILE
    from .io.atomic import check_writable, file_in_the_way

    def has_weights(folder: Path) -> bool:
        return (folder / MANIFEST_FILE).exists() or (folder / WEIGHTS_FILE).exists()

    if named is None:
        out, n = Path("runs") / engine.variant, 1
        while has_weights(out):
            n += 1
            out = Path("runs") / f"{engine.variant}-{n}"
    else:
        out = Path(named)
    what = f"--out {out}" if named else f"the weights' folder {out} (--out names another)"
    if (blocking := file_in_the_way(out)) is not None:
        raise UserError(f"{what}: {blocking} is a file; the weights go into a folder")
    # the committed weights of this engine, or of any engine package: a weights/ folder beside an __init__.py
    committed, target = engine.default_weights_dir().parent, out.resolve()
    committed = next(
        (f for f in (target, *target.parents) if f.name == "weights" and (f.parent / "__init__.py").exists()), committed
    )
    if target.is_relative_to(committed):
        raise UserError(
            f"{what} is among the committed weights ({committed}): train into another folder (--promote then "
            "replaces the committed weights of its data set)"
        )
    if has_weights(out) and not overwrite:
        raise UserError(f"{what} holds weights already: name another folder, or pass --overwrite to replace them")
    check_writable(out / WEIGHTS_FILE)  # (no folder made before the training)
    return out


def cmd_train(args) -> int:
    from . import registry
    from .data import catalogue, select, share
    from .engine import WEIGHTS_OPTION, with_humanoid_overrides
    from .engine.base import UNIVERSAL
    from .training import train_engine

    engine = registry.create(args.engine, pretrained=False)
    if hasattr(engine, "stages"):  # weights are saved per engine, not per pipeline
        raise UserError(
            f"{args.engine} is a pipeline: train its stages one at a time (`workbench train STAGE`), then clean "
            "with the pipeline"
        )
    if not engine.info.trainable:
        raise UserError(f"engine {engine.info.name!r} has nothing to train")
    if engine.weights_folder is not None:
        raise UserError(
            f"{WEIGHTS_OPTION}= names weights to clean with; to train, leave it out "
            "(--out says where the new weights go)"
        )
    if args.epochs is not None:
        engine = _with_epochs(engine, args.epochs)
    engine = with_humanoid_overrides(engine, _pins(args))
    root = _data_root(args, training=True)
    clips = _in_unit(catalogue(root), args)
    dataset = args.dataset
    if dataset is None and len({c.dataset for c in select(clips, "train")}) > 1:
        dataset = COMMITTED_UNIVERSAL_DATASETS if engine.skeleton_agnostic else COMMITTED_WEIGHTS_DATASET
        print(
            f"note: training on the {dataset} training split, as the committed weights were "
            "(--dataset NAME trains on another; NAME,NAME pools several)",
            file=sys.stderr,
        )
    clips = select(clips, dataset=dataset)
    train = select(clips, "train") or select(clips, None)
    if not train:
        raise UserError(f"no training clips under {root}" + (f" in dataset {dataset!r}" if dataset else ""))
    if args.share is not None:
        if not 0 < args.share <= 100:
            raise UserError(f"--share is a percentage in (0, 100], not {args.share:g}")
        train = share(train, args.share)
        if not train:
            raise UserError(f"--share {args.share:g} keeps no clip of the training split: name a larger share")
    loaded = [(c, c.load()) for c in train]
    # the skeleton most clips have (on a tie, the first clip's): a stray take of another rig, a still calibration
    # take among them, does not decide, nor stop the training before the check below
    layout = Counter(m.skeleton.signature() for _, m in loaded).most_common(1)[0][0]
    used = [(c, m) for c, m in loaded if engine.skeleton_agnostic or m.skeleton.signature() == layout]
    if len(used) < len(loaded):
        universal = f"{engine.info.name}:{UNIVERSAL}=true"
        pooled = f" (`{universal}` trains on several)" if hasattr(engine.params, UNIVERSAL) else ""
        print(
            f"note: training on the {len(used)} clips of the skeleton most have, leaving out "
            f"{len(loaded) - len(used)} of other skeletons{pooled}",
            file=sys.stderr,
        )
    engine.training_motions([m for _, m in used])  # the checks fit makes, before loading the test clips
    if args.promote:  # where the promoted weights go, before the training
        named = [name.strip() for name in dataset.split(",")] if dataset else []  # in the order given
        pooled = [d for d in named if any(c.dataset == d for c, _ in used)] or [used[0][0].dataset]
        if not all(pooled):
            raise UserError(
                "--promote replaces the committed weights of a data set of the catalogue (--dataset NAME); "
                "weights trained on a folder of takes stay in --out: clean with them by weights=DIR"
            )
    out = _weights_out(args.out, engine, args.overwrite)
    print(f"training {engine.spec} on {len(used)} clips ({sum(m.n_frames for _, m in used):,} frames)", file=sys.stderr)
    test = [(c.id, c.load()) for c in select(clips, "test")]
    try:
        run = train_engine(
            engine, [(c.id, m) for c, m in used], out, test=test, datasets={c.id: c.dataset for c, _ in used}
        )
    except KeyboardInterrupt:  # status 130, as every command interrupted
        print("workbench train: interrupted; nothing was saved", file=sys.stderr)
        return 130
    if run.test_scores:
        scores = {k: v for k, v in run.test_scores.items() if isinstance(v, float)}
        print(
            f"test split, {run.test_scores['corruption']}: " + ", ".join(f"{k} {v:.3f}" for k, v in scores.items()),
            file=sys.stderr,
        )
    memory = "" if np.isnan(run.peak_mb) else f" using {run.peak_mb:,.0f} MB more memory at most"
    print(
        f"trained in {run.minutes:.1f} min{memory}; saved {run.manifest}; clean with it as "
        f"--engine '{engine.spec}{',' if ':' in engine.spec else ':'}{WEIGHTS_OPTION}={out}'"
    )
    if args.promote:
        import shutil

        dest = engine.default_weights_dir() / "+".join(pooled)  # cmu/, or cmu+bandai/ for pooled data
        dest.mkdir(parents=True, exist_ok=True)
        for f in out.iterdir():
            shutil.copy2(f, dest / f.name)
        print(f"promoted to {dest}")
    return 0


# -- the app (gui, report, screenshots) ---------------------------------------------------
def cmd_gui(args) -> int:
    from .app.main import run_gui

    specs = split_engine_specs(args.engine) if args.engine else None
    if args.measure_fps is not None:
        return _measure_fps(args, specs)
    return run_gui(args.clip, args.corrupt, args.seed, specs, args.fill_suspects)


def _measure_fps(args, specs) -> int:
    """Play the take in a 1200 x 800 window (under Xvfb where there is no display) and
    print how many frames per second the 3D views showed."""
    import shutil
    import subprocess

    from .app.defaults import DEFAULT_CLIP, DEFAULT_CORRUPTION
    from .app.main import WINDOW_SIZE, has_display, measure_playback, open_window

    if not has_display() and shutil.which("xvfb-run"):  # a real (virtual) display, as a user has
        return subprocess.call(
            ["xvfb-run", "-a", "-s", "-screen 0 1600x1000x24", sys.executable, "-m", "workbench", *sys.argv[1:]]
        )
    window = open_window(
        args.clip or DEFAULT_CLIP,
        args.corrupt or DEFAULT_CORRUPTION,
        args.seed or 0,
        specs,
        size=WINDOW_SIZE,
        fill_suspects=bool(args.fill_suspects),
    )
    rates = measure_playback(window, args.measure_fps)
    size = window.size()
    print(
        f"playback of {window.session.take.source} ({window.session.take.fps:g} fps) in a {size.width()} x "
        f"{size.height()} window, {len(window.scene.plotter.renderers)} views: {rates['rendered_fps']:.1f} frames "
        f"shown per second over {rates['seconds']:.1f} s"
    )
    window.close()
    return 0


def cmd_report(args) -> int:
    from .app.report import FORMATS, clean_take, write_report
    from .app.take import default_engines
    from .app.video import SUFFIXES, write_video

    if args.output is None and args.video is None:
        raise UserError("report needs -o FILE.png|FILE.pdf, --video FILE.mp4, or both")
    if args.output is not None and Path(args.output).suffix.lower() not in FORMATS:
        raise UserError(f"the report must be a .png or .pdf file, not {args.output!r}")
    if args.video is not None and Path(args.video).suffix.lower() not in SUFFIXES:
        raise UserError(f"the video must be an .mp4 file, not {args.video!r}")

    def refused(spec: str, message: str) -> None:
        print(f"note: {spec} left out: {message}", file=sys.stderr)

    specs = _each_once(split_engine_specs(args.engine)) if args.engine else default_engines()  # a pane each
    take, runs = clean_take(
        args.clip,
        args.corrupt,
        args.seed,
        specs,
        on_refused=None if args.engine else refused,
        fill_suspects=args.fill_suspects,
    )  # the defaults: those that take it
    if args.frame is not None and not 0 <= args.frame < take.n_frames:
        raise UserError(f"--frame {args.frame}: the take's frames are 0 to {take.n_frames - 1}")
    if args.output is not None:
        print(f"wrote {write_report(args.output, take, runs, args.frame)}")
    if args.video is not None:
        print(f"wrote {write_video(args.video, take, runs, _video_progress())}")
    return 0


def _video_progress():
    """A progress bar of the video's frames on a terminal (stderr), else nothing."""
    if not sys.stderr.isatty():
        return None
    from tqdm import tqdm

    bar = tqdm(desc="video", unit="frame", file=sys.stderr, leave=False)

    def progress(done: int, total: int) -> bool:
        bar.total = total
        bar.update(done - bar.n)
        if done == total:
            bar.close()
        return True

    return progress


def cmd_screenshots(args) -> int:
    import shutil
    import subprocess

    from .app.main import has_display, make_screenshots

    specs = split_engine_specs(args.engine) if args.engine else None
    if not has_display() and shutil.which("xvfb-run"):  # prefer a real (virtual) display
        cmd = [sys.executable, "-m", "workbench", "screenshots", "--out", args.out]
        cmd += [a for spec in specs or [] for a in ("--engine", spec)]
        return subprocess.call(["xvfb-run", "-a", "-s", "-screen 0 1600x1000x24", *cmd])
    for path in make_screenshots(args.out, specs=specs):
        print(f"wrote {path}")
    return 0


def _whole_number(least: int):
    """An argparse type: a whole number of at least ``least``."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"want a whole number, got {text!r}") from None
        if value < least:
            raise argparse.ArgumentTypeError(f"want a whole number of at least {least}, got {value}")
        return value

    return parse


def _corruption_text(text: str) -> str:
    """An argparse type: a corruption spec, not blank (an empty shell variable would
    otherwise score the clean take, every error 0). :func:`main` parses it before the
    command runs."""
    if not text.strip():
        raise argparse.ArgumentTypeError(
            "empty: give a spec such as angular:0.5+gaps:0.01, or 'none' for the clean take"
        )
    return text


def _unit(text: str) -> float:
    """An argparse type: a length unit's size in cm, by name
    (:data:`workbench.core.skeleton.UNITS_CM`) or as a number from 1e-4 (a micrometre) to
    1e4 (100 m): beyond those a body's size would be nothing or overflow."""
    from .core.skeleton import UNITS_CM

    if text.lower() in UNITS_CM:
        return UNITS_CM[text.lower()]
    want = f"want {', '.join(UNITS_CM)} or the unit's size in cm (1e-4 to 1e4)"
    try:
        value = _positive_number(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(f"{want}, got {text!r}") from None
    if not 1e-4 <= value <= 1e4:
        raise argparse.ArgumentTypeError(f"{want}, got {text!r}")
    return value


def _given(text: str) -> str:
    """An argparse type: a value that is not empty (an unset shell variable would otherwise
    stand for the option's default, or the current folder)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("empty: give a value, or leave the option out for its default")
    return text


def _long_minutes(text: str) -> float:
    """An argparse type: the long take's length in minutes, 0.1 (6 s) to 600 (10 hours):
    shorter holds too few frames to time, longer more memory than a machine has."""
    value = _positive_number(text)
    if not 0.1 <= value <= 600:
        raise argparse.ArgumentTypeError(f"want 0.1 to 600 minutes, got {text!r}")
    return value


def _positive_number(text: str) -> float:
    """An argparse type: a finite number above 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"want a number, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"want a number above 0, got {text}")
    return value


class _CorruptionModelsHelp(argparse.HelpFormatter):
    """Help that ends with the corruption models a ``--corrupt SPEC`` chains
    (:func:`workbench.corruption.models_help`, as printed), imported only when the help
    is shown: every other command starts without them."""

    def format_help(self) -> str:
        from .corruption import models_help

        return f"{super().format_help()}\ncorruption models (SPEC):\n{models_help()}\n"


def build_parser() -> argparse.ArgumentParser:
    from .data import SPLITS
    from .metrics import JOINT_METRICS, METRICS

    corruptions = {"formatter_class": _CorruptionModelsHelp}  # a --corrupt SPEC's models below the options
    p = argparse.ArgumentParser(prog="workbench", description=__doc__.split("\n\n")[0])
    p.add_argument("--version", action="version", version=f"mocap-workbench {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")

    def data_opt(sp, dataset_help: str = "only the clips of this dataset (e.g. cmu, bandai)"):
        sp.add_argument(
            "--data", type=_given, metavar="DIR", help="data root (default: $WORKBENCH_DATA, datasets/, ../shared/data)"
        )
        sp.add_argument("--dataset", type=_given, metavar="NAME", help=dataset_help)

    def mapping_opt(sp):
        sp.add_argument(
            "--mapping",
            type=_given,
            metavar="FILE",
            help='JSON pinning canonical joints where the rules guess wrong, e.g. {"neck": "Neck1"} '
            "(`workbench skeleton TAKE --mapping FILE` shows what it maps)",
        )

    def unit_opt(sp, whose: str = "the take's length unit"):
        sp.add_argument(
            "--unit",
            type=_unit,
            metavar="UNIT",
            help=f"{whose}, where the one the rest pose's height suggests is wrong: mm, cm, m, in, "
            "cmu (CMU's 5.64 cm) or a unit's size in cm",
        )

    def clip_options(sp, default_split: str):
        """The catalogue clips and seeds a benchmark runs on."""
        sp.add_argument(
            "--split",
            choices=[*SPLITS, "all"],
            default=default_split,
            help=f"the clips of this split of every dataset that has one (default: {default_split})",
        )
        data_opt(sp)
        sp.add_argument(
            "--clips",
            type=_given,
            metavar="GLOB",
            help="only clips whose id or a part of it matches, e.g. 'cmu/walk/*' or 'walk'",
        )
        sp.add_argument("--seeds", type=_whole_number(1), default=1, help="number of seeds (default 1)")
        sp.add_argument("--seed0", type=_whole_number(0), default=0, help="first seed (default 0)")

    sp = sub.add_parser("data", help="list the clips and their train/validation/test split")
    data_opt(sp)
    sp.add_argument("--split", choices=[*SPLITS, "all"], default="all")
    sp.set_defaults(func=cmd_data)

    sp = sub.add_parser("engines", help="list the registered engines and their parameters")
    sp.set_defaults(func=cmd_engines)

    sp = sub.add_parser("skeleton", help="a take's skeleton and the canonical humanoid joints found on it")
    sp.add_argument("take", type=_given, help="a BVH/AMC take")
    mapping_opt(sp)
    unit_opt(sp)
    sp.set_defaults(func=cmd_skeleton)

    sp = sub.add_parser("inspect", help="which frames of a take (no ground truth needed) look broken, and why")
    sp.add_argument("take", type=_given, nargs="?", help="a BVH/AMC take")
    sp.add_argument("--json", action="store_true", help="the intervals as JSON on stdout")
    mapping_opt(sp)
    unit_opt(sp)
    sp.add_argument(
        "--mask", type=_given, metavar="FILE", help="observed-mask sidecar (default: TAKE.mask.json if present)"
    )
    sp.add_argument(
        "--engine",
        action="append",
        metavar="SPEC",
        help="clean with this engine too (repeatable): a robust one's rejected samples, two or more's disagreement",
    )
    sp.add_argument(
        "--measure",
        action="store_true",
        help="instead of a take: recall and precision of the flags on corrupted catalogue clips (spikes, linear "
        "fills, capture glitches)",
    )
    clip_options(sp, default_split="test")
    sp.set_defaults(func=cmd_inspect)

    sp = sub.add_parser(
        "corrupt", help="corrupt a clean take reproducibly (BVH + observed-mask sidecar)", **corruptions
    )
    sp.add_argument("input", type=_given)
    sp.add_argument("-o", "--output", type=_given, required=True)
    sp.add_argument(
        "--corrupt", required=True, type=_corruption_text, metavar="SPEC", help="e.g. angular:0.5+gaps:0.01"
    )
    sp.add_argument("--seed", type=_whole_number(0), default=0)
    sp.add_argument("--keep-reference", action="store_true", help="keep a T-pose frame 0")
    unit_opt(sp)
    sp.set_defaults(func=cmd_corrupt)

    sp = sub.add_parser("clean", help="clean a take (or a folder of takes) with an engine and write BVH")
    sp.add_argument(
        "input", help="a BVH/AMC take, or a folder of them (cleaned into the folder -o names, with the same layout)"
    )
    sp.add_argument("-o", "--output", type=_given, help="the cleaned take (or folder); never the input itself")
    sp.add_argument(
        "--in-place",
        action="store_true",
        help=f"write the cleaned take over its input (one BVH take), keeping the raw one as INPUT{BACKUP_SUFFIX}",
    )
    sp.add_argument("--engine", required=True, metavar="SPEC", help="e.g. gaussian:sigma_ms=58 or lerp>gaussian")
    sp.add_argument(
        "--mask", type=_given, metavar="FILE", help="observed-mask sidecar (default: INPUT.mask.json if present)"
    )
    sp.add_argument(
        "--workers",
        type=_whole_number(1),
        metavar="N",
        help="a folder: clean on a local Dask cluster of N single-threaded workers (default: the machine's cores)",
    )
    sp.add_argument(
        "--scheduler", metavar="ADDRESS", help="a folder: clean on the Dask cluster whose scheduler is at ADDRESS"
    )
    sp.add_argument(
        "--resume",
        action="store_true",
        help="a folder: skip the takes whose cleaned file is the one the folder's record says was cleaned from the "
        "take and its mask as they are now (same engine and options)",
    )
    sp.add_argument(
        "--keep-reference",
        action="store_true",
        help="clean a T-pose frame 0 with the motion (default: write it back untouched)",
    )
    sp.add_argument(
        "--fill-suspects",
        action="store_true",
        help="clean the samples `workbench inspect` flags as bad data (spike, turn, jump, linear) as gaps: "
        "the engine fills them instead of trusting them",
    )
    mapping_opt(sp)
    unit_opt(sp)
    sp.set_defaults(func=cmd_clean)

    sp = sub.add_parser("bench", help="benchmark engines on corrupted clips (markdown table, JSON)", **corruptions)
    sp.add_argument("--engines", required=True, action="append", metavar="SPEC,SPEC")
    sp.add_argument("--corrupt", required=True, type=_corruption_text, metavar="SPEC")
    clip_options(sp, default_split="test")
    unit_opt(sp, "the length unit of every clip benchmarked (a folder of takes by --data)")
    sp.add_argument(
        "--per-clip",
        choices=METRICS,
        metavar="METRIC",
        help=f"also a table of METRIC per clip, mean over the seeds ({', '.join(METRICS)})",
    )
    sp.add_argument(
        "--per-joint",
        choices=JOINT_METRICS,
        metavar="METRIC",
        help=f"also a table of METRIC per joint, mean over the clips and seeds ({', '.join(JOINT_METRICS)})",
    )
    sp.add_argument(
        "--fill-suspects",
        action="store_true",
        help="as clean --fill-suspects: the engines see what `workbench inspect` flags as bad data missing "
        "(gap_mpjpe_cm then covers it too)",
    )
    sp.add_argument(
        "--json", type=_given, metavar="FILE.json", help="also the scores, per clip and seed, as JSON (not with --long)"
    )
    sp.add_argument("-v", "--verbose", action="store_true")
    sp.add_argument(
        "--workers",
        type=_whole_number(1),
        metavar="N",
        help="run on a local Dask cluster of N single-threaded workers, a task per engine and clip (default: here, "
        "in this process)",
    )
    sp.add_argument("--scheduler", metavar="ADDRESS", help="run on the Dask cluster whose scheduler is at ADDRESS")
    sp.add_argument(
        "--long",
        action="store_true",
        help="instead of the clips: a studio-length take (cmu/walk/03_04 forwards and backwards), BVH read and "
        "write speeds, and a workbench clean command per engine on it (time, frames/s, peak memory)",
    )
    sp.add_argument(
        "--minutes", type=_long_minutes, default=10.0, help="the long take's length, 0.1 to 600 (default 10)"
    )
    sp.set_defaults(func=cmd_bench)

    sp = sub.add_parser("train", help="train an engine on the training split")
    sp.add_argument("engine", metavar="SPEC")
    sp.add_argument("--epochs", type=_whole_number(1))
    data_opt(
        sp,
        f"train on this dataset's training split (default: {COMMITTED_WEIGHTS_DATASET} where the data "
        "root has the splits of several)",
    )
    sp.add_argument(
        "--share",
        type=float,
        metavar="PCT",
        help="train on this percentage of the training clips (for learning curves; a fixed, nested choice)",
    )
    sp.add_argument(
        "--out",
        type=_given,
        metavar="DIR",
        help="where to save (default runs/<weights folder>, e.g. runs/ebf-bias, or -2, -3, ...)",
    )
    sp.add_argument("--overwrite", action="store_true", help="replace the weights --out holds already")
    mapping_opt(sp)
    unit_opt(sp, "the length unit of every clip trained on (a folder of takes by --data)")
    sp.add_argument(
        "--promote",
        action="store_true",
        help="also copy the result into the committed weights, engines/<package>/weights/<variant>/<dataset>/",
    )
    sp.set_defaults(func=cmd_train)

    from .app.defaults import DEFAULT_CLIP, DEFAULT_CORRUPTION, DEFAULT_ENGINES

    def take_opts(sp, remembered: bool = False):
        """The take's arguments; ``remembered``: the app's, whose defaults are the last session's."""
        last = "with no argument at all the last session's, else " if remembered else ""
        sp.add_argument(
            "clip",
            type=_given,
            nargs="?",
            default=DEFAULT_CLIP,
            help=f"clip id or BVH/AMC file (default {last}{DEFAULT_CLIP})",
        )
        sp.add_argument(
            "--corrupt",
            default=DEFAULT_CORRUPTION,
            type=_corruption_text,
            metavar="SPEC",
            help=f"corruption of a clean take, 'none' for a noisy one (default {last}{DEFAULT_CORRUPTION})",
        )
        sp.add_argument("--seed", type=_whole_number(0), default=0)
        sp.add_argument(
            "--engine",
            action="append",
            metavar="SPEC",
            help=f"engine spec, repeatable (default: those of {', '.join(DEFAULT_ENGINES)} that load)",
        )

    sp = sub.add_parser(
        "gui", help="open the desktop app (also: workbench with no arguments); with no take, the last one shown"
    )
    take_opts(sp, remembered=True)
    sp.add_argument(
        "--measure-fps",
        type=float,
        metavar="SECONDS",
        help="instead of opening the app for use: play the take for SECONDS in a 1200 x 800 window and print the "
        "frames per second the 3D views showed",
    )
    sp.add_argument(
        "--fill-suspects",
        action="store_true",
        default=None,
        help="as clean --fill-suspects: the fill suspects box ticked (default: as the app was left, with no take)",
    )
    sp.set_defaults(func=cmd_gui, clip=None, corrupt=None, seed=None)

    sp = sub.add_parser("report", help="the app's views and plots as one figure (PNG or PDF), headless")
    take_opts(sp)
    sp.add_argument("-o", "--output", type=_given, metavar="FILE.png|FILE.pdf")
    sp.add_argument("--frame", type=int, help="frame shown in 3D (default: the middle)")
    sp.add_argument(
        "--video",
        type=_given,
        metavar="FILE.mp4",
        help="also (or instead) the side-by-side playback with the error plot's cursor, in real time",
    )
    sp.add_argument(
        "--fill-suspects", action="store_true", help="as clean --fill-suspects (the app's fill suspects box)"
    )
    sp.set_defaults(func=cmd_report)

    sp = sub.add_parser("screenshots", help="regenerate the app's screenshots")
    sp.add_argument(
        "--out",
        type=_given,
        default="screenshots",
        metavar="DIR",
        help="where to write them (default screenshots/, the README's)",
    )
    sp.add_argument("--engine", action="append", metavar="SPEC", help="engine spec, repeatable (default as for gui)")
    sp.set_defaults(func=cmd_screenshots)
    return p


def main(argv: list[str] | None = None) -> int:
    from .allocator import keep_freed_arrays

    keep_freed_arrays()  # a long take's freed arrays reused, not faulted in afresh
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        args = parser.parse_args(["gui"])
    try:
        if getattr(args, "corrupt", None):  # a spec's fault, before any take is read (a 68 MB one, or a library)
            from .corruption import parse_corruption

            parse_corruption(args.corrupt)
        return args.func(args)
    except _user_errors() as err:
        print(f"workbench {args.command}: error: {_message(err)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # (a folder's clean says more itself: what was written, how to go on)
        print(f"workbench {args.command}: interrupted; no partial file is left", file=sys.stderr)
        return 130
    except BrokenPipeError:  # the reader stopped early (`workbench engines | head`): not an error of ours
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # so the exit's flush stays quiet
        return 0


if __name__ == "__main__":
    sys.exit(main())
