"""Write files atomically: a reader (or a crash) never sees a half-written output."""

from __future__ import annotations

import errno
import os
import stat
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from .errors import OutputFileError


def file_in_the_way(folder: str | Path) -> Path | None:
    """The file that stands where ``folder`` or one of the folders above it should be
    (so that it cannot be made), if any: the nearest of them that exists, when it is not
    a folder."""
    folder = Path(folder)
    nearest = next((f for f in (folder, *folder.parents) if f.exists()), None)
    return nearest if nearest is not None and not nearest.is_dir() else None


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on success it replaces ``path``, on any
    error it is removed and ``path`` is left as it was.

    A ``path`` that is a symbolic link is written through to the file it names, as a
    shell's ``>`` would (the link stays); a read-only file is refused, not replaced.

    Raises
    ------
    OutputFileError
        For any OSError while making the folder, writing the temporary file (in the
        ``with`` block: a full disk) or renaming it: the file named and nothing lost.
    """
    given, path = path, written_path(path)  # errors name the path as the user gave it
    tmp = None
    try:
        tmp = _temporary_beside(path)
        umask = os.umask(0)
        os.umask(umask)
        yield Path(tmp)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes it owner-only; outputs are ordinary files
        os.replace(tmp, path)
    except OutputFileError:
        raise
    except OSError as err:
        raise OutputFileError(given, err) from None
    finally:
        if tmp is not None and os.path.exists(tmp):
            os.unlink(tmp)


def written_path(path: str | Path) -> Path:
    """The file that writing ``path`` writes: the target of a symbolic link, else itself."""
    return Path(os.path.realpath(path)) if os.path.islink(path) else Path(path)


def _temporary_beside(path: Path, make_folders: bool = True) -> str:
    """An empty temporary file made beside ``path`` (its folders made first), or, without
    ``make_folders``, in the nearest folder above it that exists; OSError where that
    cannot be."""
    if (blocking := file_in_the_way(path.parent)) is not None:  # say so, not "File exists"
        raise NotADirectoryError(errno.ENOTDIR, f"{blocking} is a file, not a folder")
    if path.is_dir():
        raise IsADirectoryError(errno.EISDIR, f"{path} is a folder")
    # by its mode, not os.access, which lets root write anything: replacing a file made
    # read-only would lose its protection
    if path.is_file() and not path.stat().st_mode & stat.S_IWUSR:
        raise PermissionError(errno.EACCES, "the file is read-only: make it writable or name another file")
    if make_folders:
        path.parent.mkdir(parents=True, exist_ok=True)
        folder = path.parent
    else:
        folder = next(f for f in (path.parent, *path.parent.absolute().parents) if f.exists())
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=folder)
    os.close(fd)
    return tmp


def check_writable(path: str | Path) -> None:
    """Raise :class:`OutputFileError` unless :func:`atomic_path` could write ``path`` now
    (a temporary file made beside it, or in the nearest folder above it that exists, and
    removed; no folder is made): for a command that writes its output after minutes of
    work, and may fail before."""
    try:
        os.unlink(_temporary_beside(written_path(path), make_folders=False))
    except OSError as err:
        raise OutputFileError(path, err) from None


def atomic_write_text(path: str | Path, text: str) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8", newline="\n")
