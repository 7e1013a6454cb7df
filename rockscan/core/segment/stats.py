"""Robust statistics of pixel samples and measures of masks, shared by the segmentation's steps."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "bounding_box",
    "label_maxima",
    "logistic",
    "logit",
    "notch",
    "robust_spread",
    "solidity",
    "touching_pairs",
]

#: The median absolute deviation of a normal distribution times this is its standard deviation.
MAD_TO_SIGMA = 1.4826


def logit(p: float) -> float:
    """Log-odds of a probability, held within 1e-4 of 0 and 1 (a certainty is no finite feature)."""
    p = min(max(float(p), 1e-4), 1.0 - 1e-4)
    return math.log(p / (1.0 - p))


def logistic(t: float) -> float:
    """The probability of log-odds ``t`` (beyond +-50 it is 0 or 1 to float precision)."""
    return 1.0 / (1.0 + math.exp(-max(min(float(t), 50.0), -50.0)))


def robust_spread(values: NDArray[np.floating], median: float | None = None) -> float:
    """Robust standard deviation of ``values``: the median absolute deviation
    from ``median`` (the values' own median by default), scaled to a normal
    distribution's standard deviation. Texture, specks and a neighbour's
    edge in the sample barely move it."""
    centre = np.median(values) if median is None else median
    return MAD_TO_SIGMA * float(np.median(np.abs(values - centre)))


def label_maxima(
    values: NDArray[np.floating], labels: NDArray[np.integer], count: int
) -> NDArray[np.float64]:
    """The largest of ``values`` under each label ``0 .. count - 1``, at least 0
    (0 for a label with no pixels).

    ``np.maximum.at`` into zeros: since numpy 1.25 it costs a fifth of
    ``scipy.ndimage.maximum``, which sorts by label.
    """
    out = np.zeros(count)
    # Values at or below 0 cannot raise a maximum that is at least 0 (a distance map is mostly zeros).
    positive = values > 0
    np.maximum.at(out, labels[positive], values[positive].astype(np.float64))
    return out


def bounding_box(mask: NDArray[np.bool_]) -> tuple[int, int, int, int] | None:
    """Rows ``r0:r1`` and columns ``c0:c1`` that hold every pixel of a mask, or None if it is empty.

    The same as the extremes of ``np.nonzero``, from the rows' and columns'
    projections: a fraction of the cost on a frame-sized mask.
    """
    rows = np.flatnonzero(mask.any(axis=1))
    if rows.size == 0:
        return None
    cols = np.flatnonzero(mask.any(axis=0))
    return int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1


def solidity(mask: NDArray[np.bool_] | NDArray[np.uint8]) -> float:
    """A mask's area over the area of its convex hull.

    The hull runs through the outer pixels' centres, so a small mask's
    solidity is a little over 1; nonzero pixels are the mask.
    """
    import cv2

    mask8, hull = _hull(mask)
    if hull is None:
        return 0.0
    return float(np.count_nonzero(mask8)) / max(cv2.contourArea(hull), 1.0)


def notch(mask: NDArray[np.bool_] | NDArray[np.uint8]) -> float:
    """How far one gap dominates a region's convex hull: the share of the hull
    that its largest gap (a 4-connected part of the hull outside the region)
    covers, less the share of the second largest.

    A rock that took something in (a pebble, a neighbour half joined, ground
    between them) or left a bite out has one deep notch; a star's arms leave
    gaps all round, of much the same size, and a solid outline none: both
    measure near 0.

    Parameters
    ----------
    mask : (h, w) ndarray of bool or uint8
        One region; nonzero pixels are the region.

    Returns
    -------
    float
        In [0, 1); 0 for an empty or convex mask.
    """
    import cv2

    mask8, points = _hull(mask)
    if points is None:
        return 0.0
    hull = np.zeros_like(mask8)
    cv2.fillConvexPoly(hull, points, 1)
    _, _, parts, _ = cv2.connectedComponentsWithStats(hull & (1 - mask8), connectivity=4)
    gaps = np.sort(parts[1:, cv2.CC_STAT_AREA])[::-1]
    if gaps.size == 0:
        return 0.0
    second = gaps[1] if gaps.size > 1 else 0
    return float(gaps[0] - second) / float(max(np.count_nonzero(hull), 1))


def touching_pairs(labels: NDArray[np.integer]) -> NDArray[np.int64]:
    """Pairs of labels that touch, 8-connected, each once.

    Parameters
    ----------
    labels : (rows, cols) ndarray of int
        0 for ground, positive labels for regions.

    Returns
    -------
    (n_pairs, 2) ndarray of int64
        Labels ``a < b`` of the pairs, in increasing order.
    """
    labels = np.asarray(labels).astype(np.int64)
    base = int(labels.max()) + 1 if labels.size else 1
    keys = []
    # Every pair of 8-neighbours once: right, down, down-right and down-left. A
    # maximum filter would miss a pixel's lower neighbour beside a higher one.
    for here, there in (
        (labels[:, :-1], labels[:, 1:]),
        (labels[:-1, :], labels[1:, :]),
        (labels[:-1, :-1], labels[1:, 1:]),
        (labels[:-1, 1:], labels[1:, :-1]),
    ):
        meet = (here > 0) & (there > 0) & (here != there)
        lo, hi = np.minimum(here[meet], there[meet]), np.maximum(here[meet], there[meet])
        keys.append(lo * base + hi)
    keys = np.unique(np.concatenate(keys))
    return np.stack(np.divmod(keys, base), axis=1).astype(np.int64).reshape(-1, 2)


def _hull(mask: NDArray[np.bool_] | NDArray[np.uint8]) -> tuple[NDArray[np.uint8], NDArray[np.int32] | None]:
    """A mask as 0/1 bytes and the convex hull of its outer outlines (through
    the outer pixels' centres); None for an empty mask."""
    import cv2

    mask8 = (np.asarray(mask) != 0).astype(np.uint8)
    contours, _ = cv2.findContours(mask8, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    if not contours:
        return mask8, None
    return mask8, cv2.convexHull(np.concatenate(contours))
