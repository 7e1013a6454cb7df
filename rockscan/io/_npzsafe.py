"""Reading ``.npz`` archives that may be hostile, within a memory budget.

``numpy.load`` trusts an archive: it inflates a member before it knows its size
(a 6 MB zip bomb took 4 GB and 20 s), allocates whatever shape a header claims
(745 GiB), parses headers with Python's tokenizer (TokenError, SyntaxError) and
advises loading "unsafely using allow_pickle" when it cannot tell a file's kind.
This reader checks everything it can before it inflates or allocates anything:

* the central directory is small (a library has a few members) and not zip64;
* a member is stored or deflated, not encrypted, inflates at most 50 times
  (above 1 MiB), and its declared size fits the budget, counted over the whole
  archive;
* the ``.npy`` header is short, of format version 1 to 3, names a plain numeric
  dtype (bool, integers, floats; no objects, no records) and a shape whose bytes
  are exactly what the member holds after the header.

Then it inflates into an array of that size, a chunk at a time, and checks the
CRC. Every fault is a :class:`rockscan.core.errors.LibraryError` with one line.
"""

from __future__ import annotations

import ast
import math
import struct
import zipfile
import zlib
from typing import IO, Any

import numpy as np
from numpy.typing import NDArray

from rockscan.core.errors import LibraryError
from rockscan.core.errors import first_line as _first_line

__all__ = ["MAX_ARCHIVE_BYTES", "SafeNpz"]

#: Most bytes the arrays of one archive may take once read (a library of 1,000
#: information-face shapes, the most a family makes, takes about 155 MB).
MAX_ARCHIVE_BYTES = 256 * 2**20
#: Most a member above ``_RATIO_FLOOR`` bytes may inflate, as a multiple of its
#: deflated size: rockscan stores members uncompressed, and floats of real shapes
#: deflate by a few times, while a run of zeros deflates a thousandfold.
_MAX_RATIO = 50
_RATIO_FLOOR = 2**20
#: Most members an archive may list (a library has eight or so).
_MAX_MEMBERS = 256
#: Longest central directory read (bytes).
_MAX_DIRECTORY = 64 * 1024
#: Longest ``.npy`` header accepted (numpy writes under 128 bytes).
_MAX_HEADER = 4096
_CHUNK = 1 << 20
_DTYPE_KINDS = "biuf"
# What zipfile and zlib raise on archives they cannot read.
_ZIP_ERRORS = (
    zipfile.BadZipFile,
    zlib.error,
    EOFError,
    OSError,
    ValueError,
    NotImplementedError,
    RuntimeError,
    struct.error,
    OverflowError,
    KeyError,
    IndexError,
    TypeError,
)


class SafeNpz:
    """An ``.npz`` archive whose arrays are read on demand, each checked first.

    Use as a context manager; ``files`` lists the array names, ``archive[name]``
    reads one (the budget counts every array read).

    Parameters
    ----------
    fh : binary file object
        Open for reading and seekable.
    source : str
        Named in error messages (the file's path).
    max_bytes : int, optional
        Budget for all the arrays read, in bytes (default ``MAX_ARCHIVE_BYTES``).
    """

    def __init__(self, fh: IO[bytes], source: str, *, max_bytes: int | None = None) -> None:
        self.source = source
        self.max_bytes = MAX_ARCHIVE_BYTES if max_bytes is None else int(max_bytes)
        self._used = 0
        _check_directory(fh, source)
        try:
            self._zip = zipfile.ZipFile(fh)
            infos = self._zip.infolist()
        except _ZIP_ERRORS as exc:
            raise self._error(f"not a readable .npz archive ({_first_line(exc)})") from None
        self._members: dict[str, zipfile.ZipInfo] = {}
        for info in infos:
            name = info.filename[:-4] if info.filename.endswith(".npy") else info.filename
            if name in self._members:
                raise self._error(f"the archive lists {name!r} twice")
            self._members[name] = info

    @property
    def files(self) -> list[str]:
        """Names of the arrays in the archive."""
        return list(self._members)

    def __contains__(self, name: object) -> bool:
        return name in self._members

    def __enter__(self) -> SafeNpz:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        self._zip.close()

    def _error(self, reason: str) -> LibraryError:
        return LibraryError(f"{self.source}: {reason}")

    def __getitem__(self, name: str) -> NDArray[Any]:
        info = self._members.get(name)
        if info is None or not info.filename.endswith(".npy"):
            raise KeyError(name)
        where = f"array {name!r}"
        if info.flag_bits & 0x1:
            raise self._error(f"{where} is encrypted")
        if info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
            raise self._error(f"{where} is compressed by an unsupported method ({info.compress_type})")
        if info.file_size > max(_RATIO_FLOOR, _MAX_RATIO * info.compress_size):
            raise self._error(
                f"{where} would inflate {info.file_size / max(info.compress_size, 1):,.0f} times "
                "(a zip bomb, not a library)"
            )
        if self._used + info.file_size > self.max_bytes:
            raise self._error(
                f"{where} would take {info.file_size:,} bytes, past the {self.max_bytes:,} a library may hold"
            )
        self._used += info.file_size
        try:
            with self._zip.open(info) as member:
                dtype, shape, fortran, header_len = _read_header(member)
                count = math.prod(shape)
                if header_len + count * dtype.itemsize != info.file_size:
                    raise self._error(
                        f"{where}: its header describes {count * dtype.itemsize:,} bytes of data, "
                        f"the archive holds {info.file_size - header_len:,}"
                    )
                array = np.empty(count, dtype=dtype)
                view = memoryview(array).cast("B")
                done = 0
                while done < view.nbytes:
                    got = member.readinto(view[done : done + _CHUNK])
                    if not got:
                        raise self._error(f"{where} is truncated")
                    done += got
                if member.read(1):
                    raise self._error(f"{where} holds more than its header says")
        except LibraryError:
            raise
        except _HeaderError as exc:
            raise self._error(f"{where}: {exc}") from None
        except MemoryError:
            raise self._error(f"not enough memory to read {where}") from None
        except _ZIP_ERRORS as exc:
            raise self._error(f"library file is truncated or corrupt ({_first_line(exc)})") from None
        return array.reshape(shape, order="F" if fortran else "C")


class _HeaderError(Exception):
    """A member's ``.npy`` header is not one this reader accepts."""


def _check_directory(fh: IO[bytes], source: str) -> None:
    """Refuse archives whose central directory is large or zip64, before zipfile parses it."""
    fh.seek(0, 2)
    size = fh.tell()
    tail_len = min(size, 22 + 65535)
    fh.seek(size - tail_len)
    tail = fh.read(tail_len)
    at = tail.rfind(b"PK\x05\x06")
    if at < 0 or len(tail) - at < 22:
        raise LibraryError(f"{source}: library file is truncated or corrupt (no zip directory)")
    _, _, _, _, entries, directory_size, _, _ = struct.unpack("<4s4H2LH", tail[at : at + 22])
    if entries == 0xFFFF or directory_size == 0xFFFFFFFF:
        raise LibraryError(f"{source}: not a rockscan library (a zip64 archive)")
    if entries > _MAX_MEMBERS or directory_size > _MAX_DIRECTORY:
        raise LibraryError(f"{source}: not a rockscan library (an archive of {entries:,} members)")
    fh.seek(0)


def _read_header(member: IO[bytes]) -> tuple[np.dtype[Any], tuple[int, ...], bool, int]:
    """dtype, shape, Fortran order and total header length of a ``.npy`` stream."""
    magic = member.read(8)
    if len(magic) < 8 or magic[:6] != b"\x93NUMPY":
        raise _HeaderError("not a .npy array")
    major = magic[6]
    if major == 1:
        size_field, length_format = member.read(2), "<H"
    elif major in (2, 3):
        size_field, length_format = member.read(4), "<I"
    else:
        raise _HeaderError(f".npy format version {major} is not supported")
    if len(size_field) != struct.calcsize(length_format):
        raise _HeaderError("header is truncated")
    (length,) = struct.unpack(length_format, size_field)
    if length > _MAX_HEADER:
        raise _HeaderError(f"header of {length:,} bytes is too long")
    raw = member.read(length)
    if len(raw) != length:
        raise _HeaderError("header is truncated")
    try:
        text = raw.decode("utf-8" if major == 3 else "latin1")
        header = ast.literal_eval(text)
    except Exception:  # any fault of a short, untrusted header text
        raise _HeaderError("header is not readable") from None
    if not isinstance(header, dict) or set(header) != {"descr", "fortran_order", "shape"}:
        raise _HeaderError("header is not numpy's")
    descr, fortran, shape = header["descr"], header["fortran_order"], header["shape"]
    if not isinstance(descr, str) or not isinstance(fortran, bool):
        raise _HeaderError("header is not numpy's")
    try:
        dtype = np.dtype(descr)
    except Exception:  # numpy's dtype parser on an untrusted string
        raise _HeaderError(f"dtype {descr!r} is not readable") from None
    if dtype.kind not in _DTYPE_KINDS or dtype.fields is not None or dtype.subdtype is not None:
        raise _HeaderError(f"dtype {descr!r} is not a plain number")
    if (
        not isinstance(shape, tuple)
        or len(shape) > 8
        or not all(isinstance(n, int) and not isinstance(n, bool) and n >= 0 for n in shape)
    ):
        raise _HeaderError(f"shape {shape!r} is not a shape")
    return dtype, shape, fortran, len(magic) + len(size_field) + length
