"""Rocks of the ground's own colour, found by the edge round them (``--all``).

A rock whose colour and brightness are the ground's stands out in no channel
the detection reads, yet a person sees it at once: its rim is a closed ring
of steep change, as strong as the other rocks' edges, round a patch as
smooth as the rock's skin. Among rocks already found, such a ring is looked
for in the ground they leave:

1. The colour gradient (CIELAB, lightly blurred) is taken for an edge where it reaches ``EDGE_SHARE`` of its
   median along the found rocks' outlines: the scene's own measure of what a
   rock's edge is.
2. The pixels off every edge and every found rock make regions; those that
   touch the frame, or are larger than ``MOST_CORE`` times the median rock,
   are ground (a rock of a crowded scene lies in the frame, and a patch of
   plain ground between rocks is most often larger than a rock); those
   under ``LEAST_CORE`` of it are specks.
3. Each region left is grown through its ring to the ridge of the gradient,
   all at once: a watershed from the regions, the found rocks and the rest
   of the ground, where ground lies farther than ``REACH`` of a region's
   equivalent radius from every region whatever edges cross it.
4. A grown region counts as a rock when it is large enough (the caller's
   least share of the median rock), compact (solidity at least ``SOLID``),
   no thin strip (thickness at least ``THICK``), and lies mostly against
   ground rather than against found rocks (at most ``ON_ROCKS`` of a band
   round it): a pocket of ground walled in by rocks is a region closed by
   their edges, not by its own.

Chosen on the development crowded scenes 4000-4159 and checked on 4160-4479
(``docs/segment-algorithm.md``, step 2).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from rockscan.core.segment.split import nearest_regions
from rockscan.core.segment.stats import solidity

__all__ = ["lab_gradient", "ringed_regions"]

#: Share of the median gradient along the found rocks' outlines from which a
#: pixel is an edge (development crowded scenes 4000-4159).
EDGE_SHARE = 0.4
#: Least area of a region closed by edges, in median rocks, to be looked at.
LEAST_CORE = 0.1
#: Largest area of a region closed by edges, in median rocks: larger is ground.
MOST_CORE = 4.0
#: Least solidity of a grown region for it to be a rock.
SOLID = 0.9
#: Least thickness of a grown region (its inscribed radius over its
#: equivalent radius; an ellipse of axes 1 and 0.36): a strip of ground
#: between bricks or along a shadow is closed by edges, but thin.
THICK = 0.6
#: Largest share of the band round a grown region that may lie on found rocks.
ON_ROCKS = 0.2
#: Blur of the colour before its gradient is taken, in pixels.
GRADIENT_SIGMA = 1.0
#: How far a core may grow through the edges round it, in its equivalent radii.
REACH = 0.5
#: Width of the band round a grown region read for ``ON_ROCKS``, in pixels.
BAND = 2


def lab_gradient(colour: NDArray[np.float32], sigma: float = GRADIENT_SIGMA) -> NDArray[np.float32]:
    """The magnitude of the colour gradient, in CIELAB units per pixel.

    The length of the gradient in CIELAB, so that a rim counts alike in
    every hue, as the ground patches' rule reads colour
    (``rockscan.core.segment.cues.colour_gradient``, the largest gradient
    over the RGB channels, is what the one-rock candidates' basins flood).

    Parameters
    ----------
    colour : (rows, cols, channels) ndarray of float32
        The photo in CIELAB (``rockscan.core.segment.channels.cielab``; one
        channel, 100 times the brightness, for gray).
    sigma : float
        Gaussian blur before the derivatives, in pixels.

    Returns
    -------
    (rows, cols) ndarray of float32
        The Euclidean norm of the channels' Sobel derivatives.
    """
    import cv2

    colour = cv2.GaussianBlur(np.ascontiguousarray(colour, dtype=np.float32), (0, 0), sigma)
    # Sobel's 3x3 kernel sums to 8 across a unit step: divided by 8, the
    # gradient summed across a step is the step's height.
    dx = cv2.Sobel(colour, cv2.CV_32F, 1, 0, ksize=3) / 8.0
    dy = cv2.Sobel(colour, cv2.CV_32F, 0, 1, ksize=3) / 8.0
    squared = dx * dx + dy * dy
    if squared.ndim == 3:
        squared = squared.sum(axis=2)
    return np.sqrt(squared).astype(np.float32)


def ringed_regions(
    gradient: NDArray[np.float32], labels: NDArray[np.integer], least_area: float
) -> list[NDArray[np.bool_]]:
    """Regions of the ground that a ring of edge closes round (module docstring).

    Parameters
    ----------
    gradient : (rows, cols) ndarray of float32
        The colour gradient (:func:`lab_gradient`).
    labels : (rows, cols) ndarray of int
        The rocks found: 0 for ground, one positive label each.
    least_area : float
        Least area of a rock, as a share of the median rock's
        (``SegmentConfig.min_median_area``).

    Returns
    -------
    list of (rows, cols) ndarray of bool
        The new rocks, none on a found rock, by decreasing area; empty with
        fewer than three rocks found (no median to judge by).
    """
    import cv2
    from scipy import ndimage as ndi
    from skimage.segmentation import watershed

    taken = labels > 0
    areas = np.bincount(labels.ravel())[1:]
    areas = areas[areas > 0]
    if areas.size < 3:
        return []
    median = float(np.median(areas))
    taken8 = taken.astype(np.uint8)
    outline = taken & (cv2.erode(taken8, np.ones((3, 3), np.uint8)) == 0)
    # Rocks that fill the frame leave no outline against ground to read.
    if not outline.any():
        return []
    rim = float(np.median(gradient[outline]))
    if not rim > 0.0:
        return []
    walls = (gradient > EDGE_SHARE * rim) | (cv2.dilate(taken8, np.ones((3, 3), np.uint8)) > 0)
    open_, count = ndi.label(~walls)
    if count == 0:
        return []
    sizes = np.bincount(open_.ravel(), minlength=count + 1)
    frame = np.zeros(count + 1, bool)
    frame[np.concatenate([open_[0], open_[-1], open_[:, 0], open_[:, -1]])] = True
    inside = ~frame & (sizes >= LEAST_CORE * median) & (sizes <= MOST_CORE * median)
    inside[0] = False
    cores = np.flatnonzero(inside)
    if cores.size == 0:
        return []
    # One watershed for every core: the ring between a core and the ground or
    # a found rock is parted along its ridge, where the rock's edge lies.
    index = np.zeros(count + 1, np.int32)
    index[cores] = np.arange(1, cores.size + 1)
    markers = index[open_]
    # A ring is about as wide as the blur of an edge: what lies farther from
    # every core than half its radius is ground, whatever edges cross it.
    distance, nearest = nearest_regions(markers)
    reach = np.concatenate([[0.0], REACH * np.sqrt(sizes[cores] / np.pi) + BAND + 1])
    ground = ((open_ > 0) & ~inside[open_]) | taken | (distance > reach[nearest])
    markers[ground] = cores.size + 1
    # Only what is not ground is flooded, from the ground's edge a pixel wide:
    # the watershed's cost grows with the pixels it is given.
    active = cv2.dilate((~ground).astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    flooded = watershed(gradient, markers, mask=active)
    band_kernel = np.ones((2 * BAND + 1,) * 2, np.uint8)
    found = []
    for number, box in enumerate(ndi.find_objects(flooded, max_label=cores.size), start=1):
        if box is None:
            continue
        r0, c0 = max(box[0].start - BAND, 0), max(box[1].start - BAND, 0)
        r1, c1 = min(box[0].stop + BAND, labels.shape[0]), min(box[1].stop + BAND, labels.shape[1])
        # Holes are filled, but not over another core's region: a ring-shaped
        # core round a band of its rim would take the rock's own core.
        window = flooded[r0:r1, c0:c1]
        others = (window != number) & (window <= cores.size)
        part = ndi.binary_fill_holes(window == number) & ~taken[r0:r1, c0:c1] & ~others
        area = int(np.count_nonzero(part))
        if area < least_area * median or solidity(part) < SOLID or _thickness(part, area) < THICK:
            continue
        band = (cv2.dilate(part.astype(np.uint8), band_kernel) > 0) & ~part
        if np.count_nonzero(band & taken[r0:r1, c0:c1]) > ON_ROCKS * np.count_nonzero(band):
            continue
        whole = np.zeros(labels.shape, bool)
        whole[r0:r1, c0:c1] = part
        found.append(whole)
    found.sort(key=lambda mask: -int(np.count_nonzero(mask)))
    return found


def _thickness(mask: NDArray[np.bool_], area: int) -> float:
    """A mask's inscribed radius (its largest distance to the outside) over its equivalent radius."""
    import cv2

    inscribed = cv2.distanceTransform(np.pad(mask, 1).astype(np.uint8), cv2.DIST_L2, 5).max()
    return float(inscribed) / math.sqrt(area / math.pi)
