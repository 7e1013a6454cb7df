"""Radii files: an outline given as numbers sampled at equal angles."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from rockscan.core.errors import ParameterError
from rockscan.core.errors import first_line as _first_line


def read_radii(path: str | os.PathLike[str]) -> NDArray[np.float64]:
    """Read an outline given as radii: a text file of numbers (any whitespace or
    commas; ``#`` starts a comment), or a ``.npy`` array, sampled at equal
    angles from theta = 0.

    Parameters
    ----------
    path : path-like

    Returns
    -------
    radii : (n,) ndarray of float

    Raises
    ------
    ParameterError
        If the file cannot be read or holds no usable radii.
    """
    path = Path(path)
    try:
        if path.suffix.lower() == ".npy":
            values = np.load(path, allow_pickle=False)
        else:
            # utf-8-sig: a byte-order mark (Excel's "CSV UTF-8") is no part of the first number.
            text = path.read_text(encoding="utf-8-sig")
            # A '#' starts a comment, as numpy.loadtxt reads it (savetxt's header, notes).
            rows = [line.split("#", 1)[0].replace(",", " ").split() for line in text.splitlines()]
            rows = [row for row in rows if row]
            if len(rows) > 1 and len({len(row) for row in rows}) == 1 and len(rows[0]) > 1:
                # A table (rows of one length, more than one column) would be read
                # row after row, its columns interleaved; wrapped text is one run.
                raise ParameterError(f"{path}: radii must be one row or one column of numbers, not a table")
            values = np.array([float(tok) for row in rows for tok in row])
    except ParameterError:
        raise
    except FileNotFoundError:
        raise ParameterError(f"{path}: radii file not found") from None
    except (OSError, ValueError, UnicodeDecodeError) as exc:
        raise ParameterError(f"{path}: cannot read radii ({_first_line(exc)})") from None
    if not isinstance(values, np.ndarray) or values.dtype.kind not in "uif":
        kind = values.dtype if isinstance(values, np.ndarray) else type(values).__name__
        raise ParameterError(f"{path}: radii must be real numbers, got {kind}")
    if values.ndim != 1:
        raise ParameterError(f"{path}: radii must be a 1-D array, got shape {values.shape}")
    values = values.astype(np.float64)
    if values.size < 8 or not np.all(np.isfinite(values)) or np.any(values < 0) or values.max() <= 0:
        raise ParameterError(f"{path}: radii must be at least 8 finite, non-negative numbers, not all zero")
    if values.max() > MAX_RADIUS:
        # Sums of squares of such radii overflow; a shape has no size to the matcher.
        raise ParameterError(f"{path}: radii must be at most {MAX_RADIUS:g} (scale them down)")
    return values


#: Largest radius read: squares and sums of far larger ones overflow a float.
MAX_RADIUS = 1e100
