"""Exceptions raised by rockscan.

Every error a user can cause derives from :class:`RockscanError`, and each
subclass also derives from the builtin it resembles, so callers may catch either.
The command line turns a ``RockscanError`` into the one-line error of the public
interface; any other exception is a bug.
"""

from __future__ import annotations

__all__ = [
    "ImageReadError",
    "LibraryError",
    "NoRockFoundError",
    "ParameterError",
    "RockscanError",
    "SpecError",
    "WriteError",
    "first_line",
]


class RockscanError(Exception):
    """Root of all errors rockscan reports to its users."""


class ParameterError(RockscanError, ValueError):
    """An argument is out of its valid range or of the wrong shape."""


class ImageReadError(RockscanError, OSError):
    """A photo cannot be read: missing, unreadable, truncated or of no use."""


class NoRockFoundError(RockscanError, ValueError):
    """A photo was read but no rock could be segmented in it."""


class LibraryError(RockscanError, ValueError):
    """A library file is corrupt, truncated, foreign or inconsistent."""


class SpecError(LibraryError):
    """A library spec (TOML) is malformed or names impossible shapes."""


class WriteError(RockscanError, OSError):
    """A result cannot be written: a library, report, plot, spec or photo (disk full,
    no such folder, no permission). Nothing half-written is left behind."""


def internal_error(exc: BaseException) -> str:
    """The one-line error of a photo whose classification failed on a bug, not on the
    photo: said as one, so that the batch goes on and the bug gets reported."""
    first = str(exc).splitlines()[0] if str(exc) else ""
    return f"internal error, please report it: {type(exc).__name__}: {first}".rstrip(": ")


def first_line(exc: BaseException) -> str:
    """The first line of an exception's message (its type name when it has none),
    for the one-line errors of the public interface."""
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__
