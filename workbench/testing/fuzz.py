"""Coverage-guided fuzzing of the motion readers (atheris, which drives libFuzzer over the
Python code of :mod:`workbench.io`).

    python -m workbench.testing.fuzz bvh --runs 100000
    python -m workbench.testing.fuzz asfamc --runs 100000

The contract fuzzed: for any bytes, :func:`workbench.io.read_bvh` and
:func:`workbench.io.asfamc.read_amc` return a Motion or raise
:class:`~workbench.io.MotionFileError`; nothing else escapes, no input takes more than
:data:`TIMEOUT_S`, and none makes the process resident beyond :data:`RSS_LIMIT_MB`.
libFuzzer stops at the first input that breaks it and writes that input, as
``crash-*``, ``timeout-*`` or ``oom-*``, into the run folder: each one found becomes a
regression file under ``tests/io/fuzz_regressions/`` (``tests/io/test_fuzz.py`` reads
them all).

Seeds: every take of the data root (:func:`workbench.data.find_data_root`) in the
reader's format, each cut to its hierarchy and first :data:`SEED_FRAMES` frames (with
its ``Frames:`` line, or its AMC frame numbers, saying so) so that mutations explore the
parsing rather than re-read long frame sections. An ASF/AMC input is the ASF text,
:data:`SEPARATOR`, then the AMC text; one without the separator is read as an ASF file.
The corpus grows in ``runs/fuzz/READER/`` (``--corpus``) and is kept between runs.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import sys
import tempfile
from pathlib import Path

#: libFuzzer's limits for one input
TIMEOUT_S = 1
RSS_LIMIT_MB = 500
#: frames of each take kept in its seed
SEED_FRAMES = 4
#: the longest input the fuzzer makes (bytes); the longest seed is longer where one is
MAX_LEN = 16_384
#: between the ASF and the AMC text of an ASF/AMC input
SEPARATOR = b"\n\x00AMC\x00\n"
READERS = ("bvh", "asfamc")
#: each reader's keywords, handed to libFuzzer as its dictionary so that mutations
#: splice them in (libFuzzer's escapes: \x0D\x0A is a CRLF line end)
KEYWORDS = {
    "bvh": (
        "HIERARCHY ROOT JOINT End Site { } OFFSET CHANNELS MOTION Frames: Frame Time: "
        "Xposition Yposition Zposition Xrotation Yrotation Zrotation nan inf -1e308 0.0083333 \\x0D\\x0A \\x09"
    ),
    "asfamc": (
        ":version :name :units :documentation :root :bonedata :hierarchy :DEGREES :RADIANS "
        "mass length angle deg rad order axis orientation position begin end id name direction "
        "dof limits rx ry rz tx ty tz l XYZ ZYX root ( ) inf nan \\x0D\\x0A"
    ),
}


def bvh_seed(text: str, frames: int = SEED_FRAMES) -> str:
    """A BVH take's text cut to its hierarchy and first ``frames`` frames."""
    head, motion, body = text.partition("MOTION")
    lines = body.splitlines()
    kept = [re.sub(r"\d+", str(min(frames, len(lines) - 3)), lines[1], count=1), *lines[2 : 3 + frames]]
    return head + motion + lines[0] + "\n" + "\n".join(kept) + "\n"


def amc_seed(text: str, frames: int = SEED_FRAMES) -> str:
    """An AMC take's text cut to its header and first ``frames`` frames (a frame starts at
    a line holding only its number)."""
    out, seen = [], 0
    for line in text.splitlines():
        if line.strip().isdigit():
            seen += 1
            if seen > frames:
                break
        out.append(line)
    return "\n".join(out) + "\n"


def write_seeds(reader: str, folder: Path, data_root: Path) -> int:
    """Write the seeds of ``reader`` from the takes under ``data_root`` into ``folder``;
    their count."""
    from ..data.roots import files_under

    folder.mkdir(parents=True, exist_ok=True)
    count = 0
    for path in files_under(data_root):
        if reader == "bvh" and path.suffix.lower() == ".bvh":
            seed = bvh_seed(path.read_text(encoding="utf-8", errors="replace")).encode()
        elif reader == "asfamc" and path.suffix.lower() == ".amc":
            from ..io.asfamc import find_asf

            try:
                asf = find_asf(path).read_bytes()
            except Exception:  # a take without its skeleton beside it seeds nothing
                continue
            seed = asf + SEPARATOR + amc_seed(path.read_text(encoding="utf-8", errors="replace")).encode()
        else:
            continue
        (folder / f"{count:04d}-{path.stem}").write_bytes(seed)
        count += 1
    return count


def read_input(reader: str, data: bytes, workdir: Path) -> None:
    """Read ``data`` as a file of ``reader``'s format (written into ``workdir``); raises what
    the reader raises."""
    from ..io import read_bvh
    from ..io.asfamc import read_amc, read_asf

    if reader == "bvh":
        path = workdir / "input.bvh"
        path.write_bytes(data)
        read_bvh(path)
        return
    asf, separated, amc = data.partition(SEPARATOR)
    (workdir / "input.asf").write_bytes(asf)
    if not separated:
        read_asf(workdir / "input.asf")
        return
    (workdir / "input.amc").write_bytes(amc)
    read_amc(workdir / "input.amc", workdir / "input.asf")


def _instrument(atheris, packages: tuple[str, ...]) -> None:
    """Give libFuzzer the coverage of every loaded function of ``packages`` (the readers
    and the skeleton and motion code they build): ``atheris.instrument_all`` would patch
    all 5,800 loaded functions, 13 of a short pass's 25 s of start-up."""
    import gc
    import inspect

    for function in [f for f in gc.get_objects() if inspect.isfunction(f)]:
        if (function.__module__ or "").startswith(packages):
            atheris.instrument_func(function)


def fuzz(reader: str, runs: int, corpus: Path, data_root: Path) -> None:
    """Fuzz ``reader`` for ``runs`` inputs (never returns: the process exits with
    libFuzzer's status, 0 when every input kept the contract)."""
    import atheris

    from ..io import (
        MotionFileError,
        asfamc,  # noqa: F401 (loaded before _instrument, so it is instrumented)
    )

    seeds = corpus / "seeds"
    if not seeds.is_dir():
        print(f"{write_seeds(reader, seeds, data_root)} seeds from {data_root}", file=sys.stderr)
    grown = corpus / "grown"
    grown.mkdir(parents=True, exist_ok=True)
    workdir = Path(tempfile.mkdtemp(prefix=f"fuzz-{reader}-", dir="/dev/shm" if Path("/dev/shm").is_dir() else None))
    longest = max((p.stat().st_size for p in seeds.iterdir()), default=0)
    dictionary = corpus / "keywords.dict"
    dictionary.write_text("".join(f'"{word}"\n' for word in KEYWORDS[reader].split()), encoding="utf-8")

    def one_input(data: bytes) -> None:
        try:
            read_input(reader, data, workdir)
        except MotionFileError:
            pass

    _instrument(atheris, ("workbench.io", "workbench.core"))
    argv = [
        sys.argv[0],
        f"-runs={runs}",
        f"-timeout={TIMEOUT_S}",
        f"-rss_limit_mb={RSS_LIMIT_MB}",
        f"-max_len={max(MAX_LEN, longest)}",
        f"-artifact_prefix={corpus}/",
        f"-dict={dictionary}",
        "-print_final_stats=1",
        str(grown),
        str(seeds),
    ]
    atheris.Setup(argv, one_input)
    # libFuzzer's memory limit reads the process's peak resident size, which Linux carries
    # over an exec from the process that started it (a test run's pytest: a gigabyte); a
    # child forked here starts from this process's own, so the limit measures the readers
    child = os.fork()
    if child == 0:
        atheris.Fuzz()
    status = os.waitstatus_to_exitcode(os.waitpid(child, 0)[1])
    shutil.rmtree(workdir, ignore_errors=True)
    sys.exit(status)


def main(argv: list[str] | None = None) -> None:
    from ..data import find_data_root

    p = argparse.ArgumentParser(prog="python -m workbench.testing.fuzz", description=__doc__.split("\n\n")[0])
    p.add_argument("reader", choices=READERS)
    p.add_argument("--runs", type=int, default=100_000, help="inputs to try (default 100000)")
    p.add_argument("--corpus", type=Path, help="the run folder (default runs/fuzz/READER)")
    p.add_argument("--data", help="the data root whose takes seed it (default: as the workbench finds it)")
    args = p.parse_args(argv)
    fuzz(args.reader, args.runs, args.corpus or Path("runs") / "fuzz" / args.reader, find_data_root(args.data))


if __name__ == "__main__":
    main()
