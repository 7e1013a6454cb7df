"""Radii files: an outline given as numbers sampled at equal angles."""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from rockscan.core.errors import ParameterError

if TYPE_CHECKING:
    pass

from rockscan.core.errors import first_line as _first_line


def read_radii(path: str | os.PathLike[str]) -> NDArray[np.float64]:
    """Read an outline given as radii: a text file of numbers (any whitespace or
    commas), or a ``.npy`` array, sampled at equal angles from theta = 0.

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
            text = path.read_text(encoding="utf-8").replace(",", " ")
            values = np.array([float(tok) for tok in text.split()])
    except FileNotFoundError:
        raise ParameterError(f"{path}: radii file not found") from None
    except (OSError, ValueError, UnicodeDecodeError) as exc:
        raise ParameterError(f"{path}: cannot read radii ({_first_line(exc)})") from None
    values = np.asarray(values, dtype=np.float64).ravel()
    if values.size < 8 or not np.all(np.isfinite(values)) or np.any(values < 0) or values.max() <= 0:
        raise ParameterError(f"{path}: radii must be at least 8 finite, non-negative numbers, not all zero")
    return values
