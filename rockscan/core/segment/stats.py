"""Robust statistics of pixel samples, shared by the segmentation's steps."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["robust_spread"]

#: The median absolute deviation of a normal distribution times this is its standard deviation.
MAD_TO_SIGMA = 1.4826


def robust_spread(values: NDArray[np.floating], median: float | None = None) -> float:
    """Robust standard deviation of ``values``: the median absolute deviation
    from ``median`` (the values' own median by default), scaled to a normal
    distribution's standard deviation. Texture, specks and a neighbour's
    edge in the sample barely move it."""
    centre = np.median(values) if median is None else median
    return MAD_TO_SIGMA * float(np.median(np.abs(values - centre)))
