"""A light rock's shaded side, left out of its outline, and taking it back in.

Under a low light a domed rock's far side turns from the light and is lit by
the sky alone, as is the ground in the rock's cast shadow beyond it. Both
are darker than the lit ground by far, and every cue that reads brightness
outlines the rock's lit part alone (or its lit part with its shadow). In sky
light, though, the two keep the ratio of their albedos: a rock lighter than
its ground is lighter than its shadow, on the far side as on the lit one,
by a step of about the same size in log brightness.

Around the outline (within ``REACH`` equivalent radii), the pixels darker
than the ground (by ``DARK`` in log brightness, or ``NOISE`` of its spreads)
that touch the rock are its shaded side and its shadow. Otsu's threshold
parts them in two levels; when the two lie apart by about the rock's step
above the ground (``SPLIT``), the lighter level's largest piece that touches
the rock is its shaded side, and joins it. Darker patches of the ground's texture and a
shadow's penumbra make lighter pieces too, which wrap round the rock or
reach out along its shadow: the rock takes its shaded side only when it
comes out about as compact as it was (its solidity down by at most
``SOLIDITY_LOSS``, its outline no longer against its area by more than
``LONGER``) and grows by ``MIN_GROWTH`` to ``MAX_GROWTH`` of its area (a
dome's shaded side is a crescent, not a second rock). A side that reaches
the edge of the window the frame cut is not taken: the photo shows neither
it whole nor the ground round it.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from rockscan.core.segment.split import largest_part
from rockscan.core.segment.trace import _disk

__all__ = ["shade_on", "side_joined", "stays_compact"]

#: How far past the outline the shaded side and its shadow are looked for,
#: in equivalent radii of the rock.
REACH = 1.2
#: Darker than the ground by this much log brightness ...
DARK = 0.25
#: ... and by this many robust spreads of the ground.
NOISE = 1.0
#: The rock is light enough to be told from its shadow in sky light when its
#: level is this far above the ground's (log brightness).
MIN_STEP = 0.15
#: The two levels of the dark pixels lie apart by this share of the rock's
#: step above the ground, at least and at most: in sky light a rock and its
#: ground keep the ratio of their albedos, which the lit rock's step shows
#: too (a little more, for the faces turned to the light).
SPLIT = (0.5, 1.5)
#: The rock grows by this share of its area at least, and at most ...
MIN_GROWTH = 0.03
MAX_GROWTH = 0.35
#: ... its solidity falls by at most this much (the opening takes the
#: crescent's thin tips off, and leaves a small notch at each) ...
SOLIDITY_LOSS = 0.01
#: ... and its outline's length over the square root of its area grows by at most this factor.
LONGER = 1.05
#: The shaded side is opened by a disc of this share of the rock's equivalent
#: radius (at least ``MIN_OPEN`` pixels): the blurred edges of a shadow, a few
#: pixels wide, reach the rock where the shadow begins.
OPEN = 0.08
MIN_OPEN = 2
#: Where the levels are read: the ground in a ring from ``RING[0]`` (plus 2
#: pixels) to ``RING[1]`` equivalent radii past the outline, at this percentile
#: (above the ring's median: the shadow darkens part of it).
RING = (0.1, 0.4)
GROUND_PERCENTILE = 60.0


def shade_on(gray: NDArray[np.floating], mask: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """A light rock's mask with its shaded side taken in (module docstring).

    Parameters
    ----------
    gray : (rows, cols) ndarray of float
        Log brightness of the photo around the rock, on the mask's grid,
        with a margin of at least ``REACH`` of the rock's equivalent radius
        (less where the frame cuts it: a side reaching its edge is not taken).
    mask : (rows, cols) ndarray of bool
        The rock's region (one piece, holes filled).

    Returns
    -------
    (rows, cols) ndarray of bool
        The rock with its shaded side, or ``mask`` itself, unchanged, when
        the rock is not light, has no dark side beside it, or the side found
        would not leave it compact.
    """
    from scipy import ndimage
    from skimage.filters import threshold_otsu

    area = int(np.count_nonzero(mask))
    if area < 50:
        return mask
    radius = math.sqrt(area / math.pi)
    distance = ndimage.distance_transform_edt(~mask)
    ring = (distance > RING[0] * radius + 2.0) & (distance <= RING[1] * radius)
    if np.count_nonzero(ring) < 50:
        return mask
    log = gray.astype(np.float64)
    fine = ndimage.gaussian_filter(log, 1.0)
    ring_values = fine[ring]
    ground = float(np.percentile(ring_values, GROUND_PERCENTILE))
    step = float(np.median(fine[mask])) - ground
    if step < MIN_STEP:
        return mask
    upper = ring_values[ring_values > np.percentile(ring_values, 40.0)]
    # A ground of one level over most of the ring (a drawn or clipped photo)
    # leaves nothing above its 40th percentile: its spread is the ring's.
    spread = float(np.subtract(*np.percentile(upper if upper.size else ring_values, [75.0, 25.0])))
    touching = distance <= 2.0
    dark = (fine < ground - max(DARK, NOISE * spread)) & (distance > 0) & (distance <= REACH * radius)
    dark = ndimage.binary_opening(dark, _disk(1))
    dark = _touching(dark, touching)
    if np.count_nonzero(dark) < 50:
        return mask
    coarse = ndimage.gaussian_filter(log, 2.0)
    values = coarse[dark]
    threshold = float(threshold_otsu(values))
    lighter, darker = values[values >= threshold], values[values < threshold]
    if lighter.size == 0 or darker.size == 0:
        return mask
    if not SPLIT[0] * step <= np.median(lighter) - np.median(darker) <= SPLIT[1] * step:
        return mask
    disk = _disk(max(MIN_OPEN, round(OPEN * radius)))
    # A dome's shaded side is one crescent; where it meets the rock, the
    # shadow's blurred edges leave small pieces beside it.
    side = largest_part(_touching(ndimage.binary_opening(dark & (coarse >= threshold), disk), touching))
    # A side that reaches the edge of the window runs on past the frame: the
    # photo does not show it whole, nor the ground round it.
    if side is None or side[[0, -1], :].any() or side[:, [0, -1]].any():
        return mask
    return side_joined(mask, side, disk, MAX_GROWTH)


def side_joined(
    mask: NDArray[np.bool_], side: NDArray[np.bool_], disk: NDArray[np.bool_], max_growth: float
) -> NDArray[np.bool_]:
    """A rock's mask with a side beside it joined, or ``mask`` itself when
    the rock would not grow by ``MIN_GROWTH`` to ``max_growth`` of its area or
    would not stay about as compact (``SOLIDITY_LOSS``, ``LONGER``).

    The two are closed across the seam of blurred pixels between them by
    ``disk`` (the closing's erosion treats the window's edge as ground: the
    rock keeps every pixel it had), and holes are filled.
    """
    from scipy import ndimage

    area = int(np.count_nonzero(mask))
    grown = ndimage.binary_fill_holes(mask | ndimage.binary_closing(mask | side, disk))
    added = int(np.count_nonzero(grown)) - area
    if not MIN_GROWTH * area <= added <= max_growth * area or not stays_compact(mask, grown):
        return mask
    return grown


def stays_compact(before: NDArray[np.bool_], after: NDArray[np.bool_]) -> bool:
    """Whether a rock's mask ``after`` a change is about as compact as
    ``before``: its solidity down by at most ``SOLIDITY_LOSS``, its outline's
    length over the square root of its area up by at most ``LONGER``."""
    solid = _solidity(after) >= _solidity(before) - SOLIDITY_LOSS
    return solid and _roundness(after) <= LONGER * _roundness(before)


def _touching(parts: NDArray[np.bool_], near: NDArray[np.bool_], connectivity: int = 1) -> NDArray[np.bool_]:
    """The pieces of ``parts`` that reach into ``near``; pixels meeting at
    their sides (``connectivity`` 1) or their corners too (2) are one piece."""
    from scipy import ndimage

    labels, _ = ndimage.label(parts, structure=ndimage.generate_binary_structure(2, connectivity))
    keep = np.unique(labels[near & parts])
    return np.isin(labels, keep[keep > 0])


def _solidity(mask: NDArray[np.bool_]) -> float:
    """The area inside the region's outline over its convex hull's.

    Both run through the outer pixels' centres, so that a convex region
    measures 1 at any size (``stats.solidity`` counts the pixels, a little
    over 1 for a small one): a rock and its grown copy are compared alike.
    """
    import cv2

    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    hull = cv2.contourArea(cv2.convexHull(np.vstack(contours)))
    return sum(cv2.contourArea(c) for c in contours) / max(hull, 1.0)


def _roundness(mask: NDArray[np.bool_]) -> float:
    """The outline's length over the square root of the area (its least, a disc's, is 2 sqrt(pi))."""
    import cv2

    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    length = sum(cv2.arcLength(c, True) for c in contours)
    return length / math.sqrt(max(np.count_nonzero(mask), 1))
