"""One atomic write for every file rockscan makes.

A file is written under a temporary name beside its target and renamed over it
(``os.replace``, atomic on POSIX and Windows), so a reader sees the old file or
the new one, never half of one, and an interrupted write leaves no debris.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from pathlib import Path
from typing import BinaryIO

from rockscan.core.errors import WriteError

__all__ = ["atomic_file", "remove_leftovers", "temporary_name", "write_bytes_atomic"]


def temporary_name(path: str | os.PathLike[str]) -> Path:
    """The hidden name a file is written under before it is renamed over ``path``."""
    path = Path(path)
    return path.with_name(f".{path.name}.tmp{os.getpid()}")


def remove_leftovers(path: str | os.PathLike[str]) -> int:
    """Remove the temporary files a killed process left beside ``path`` (``kill -9``
    while it wrote: nothing ran to remove them); those of live processes stay.

    Returns
    -------
    int
        How many were removed.
    """
    path = Path(path)
    prefix = f".{path.name}.tmp"
    removed = 0
    try:
        entries = list(os.scandir(path.parent))
    except OSError:
        return 0
    for entry in entries:
        pid = entry.name[len(prefix) :]
        if not entry.name.startswith(prefix) or not pid.isdigit() or _alive(int(pid)):
            continue
        with contextlib.suppress(OSError):
            os.unlink(entry.path)
            removed += 1
    return removed


def _alive(pid: int) -> bool:
    """Whether a process of that id runs (one of another user counts as running)."""
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError, OSError):
        return True
    return True


@contextlib.contextmanager
def atomic_file(path: str | os.PathLike[str], *, what: str = "file") -> Iterator[BinaryIO]:
    """Open a binary file whose content replaces ``path`` only if the block completes.

    Parameters
    ----------
    path : path-like
        The target.
    what : str
        What is written, for the error message (``"library"``, ``"report"``, ...).

    Yields
    ------
    BinaryIO
        The temporary file. On an exception inside the block it is removed and
        ``path`` is left as it was.

    Raises
    ------
    WriteError
        If the file cannot be written or renamed; one line naming the path.
    """
    path = Path(path)
    tmp = temporary_name(path)
    try:
        with open(tmp, "wb") as fh:
            yield fh
        os.replace(tmp, path)
    except OSError as exc:
        raise WriteError(f"{path}: cannot write {what} ({exc.strerror or exc})") from None
    finally:
        # On a read-only file system the temporary file was never made, and asking
        # to remove it fails too (EROFS, not "no such file").
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)


def write_bytes_atomic(path: str | os.PathLike[str], data: bytes, *, what: str = "file") -> None:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_file`)."""
    with atomic_file(path, what=what) as fh:
        fh.write(data)
