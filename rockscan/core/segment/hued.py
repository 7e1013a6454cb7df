"""A rock's outline told by hue: a side of the rock's own hue that brightness
left out taken in, and a part of the ground's hue it took taken off.

A rock that differs from its ground in hue keeps its hue where its brightness
changes: on its side turned from the light, on a band of its skin darker or
lighter than the rest, on a face the vignetting dims. Every cue that reads
brightness may then outline the rock's lit part alone, and the step that
takes a shaded side back by brightness (``shade``) asks for a shadow beside
it to tell the side's level from. Hue tells it without: a cast shadow is the
ground's own surface darkened and keeps the ground's hue
(``shadow.hue_from_ground``), while the rock's shaded side keeps the rock's.

Each pixel's chromaticity ``(r, g) / (r + g + b)`` (smoothed over ``SIGMA``
pixels) is placed along the line from the ground's hue (0: the median of a
ring ``RING`` equivalent radii past the outline, beyond the part left out)
to the rock's (1: the median of the outline's core). Only where hue tells
the two apart (at most a share ``SEPARATE`` of the ring past half-way to the
rock's hue, and of the core short of it), the pixels at least ``ROCK_HUE``
of the way to the rock's, within ``REACH`` radii of the outline, are opened
by a disc of ``OPEN`` of the rock's radius, and their largest piece that
touches the rock joins it. A neighbour of the rock's hue, or a patch of the
ground's texture near it, would join as well: the rock takes the piece only
when it grows by 3% (``shade.MIN_GROWTH``) to ``MAX_GROWTH`` of its area and
comes out about as compact as it was, as a shaded side must
(``shade.side_joined``). Pixels too dark to have a hue are never taken.

The other way (``hue_off``), a cast shadow, a patch of ground or a pebble of
the ground's hue taken in with the rock lies near the ground's hue: the ground
is read in a ring just past the outline (``OFF_RING``), the rock on the half
of the outline's pixels farthest in hue from it (an outline that took its
shadow may have the shadow in its core). Where hue tells the two apart, the pixels of the
outline at most ``1 - ROCK_HUE`` of the way to the rock's hue, opened, that
reach the outline's edge are cut off; the rock keeps the largest piece of the
rest, opened too, when it loses ``MIN_SHRINK`` to ``MAX_SHRINK`` of its area
and stays about as compact as it was (``shade.stays_compact``): a band of
the rock's skin near the ground's hue cuts it in two or notches it.

An outline that took more of its cast shadow, or of a patch of ground, than
of the rock reads the shadow's hue on either half, and ``hue_off`` finds no
rock's hue to place its pixels by. There the outline's own two colours tell
them (``hue_parted``): the cue that parts touching rocks of different hues
with ``--all`` (``split.split_colours``) cuts it between its colours, and
each part's hue (its median chromaticity) is measured from the ground's (the
ring of ``hue_off``) in units of the ring's own spread round it. When every
part but the one farthest from the ground lies within ``PART_GROUND`` of the
ground's hue, ``PART_APART`` times nearer than that one, and is no lighter
than the ground (``PART_LIGHTER``: a shadow or the ground itself, where a
lit rock of the ground's hue would stand out lighter), and the farthest
lies at least ``PART_ROCK`` from it, the rock is the farthest part's
largest piece. A two-coloured rock keeps both colours: neither lies near
the ground's hue and darker than it.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from rockscan.core.segment.channels import _LEAST_LIGHT
from rockscan.core.segment.shade import _touching, side_joined, stays_compact
from rockscan.core.segment.split import largest_part, split_colours
from rockscan.core.segment.trace import _disk

__all__ = ["ROCK_HUE", "hue_off", "hue_on", "hue_parted"]

#: How far from the ground's hue towards the rock's a pixel (or a part a
#: shadow cut would take off, ``finish.rock_hued``) must lie to be the
#: rock's. Half-way is where it is as near either; where the two hues lie
#: close, noise puts a cast shadow on either side of it, and the rock's own
#: shaded side lies nearer the rock's by far.
ROCK_HUE = 0.75
#: The ground's hue is read in a ring this far past the outline, in
#: equivalent radii of the rock: beyond the part of the rock left out, which
#: may be as wide as the part outlined.
RING = (0.8, 1.4)
#: The rock's hue is read on its core, this far inside the outline (radii).
CORE = 0.3
#: Hue tells rock from ground when at most this share of the ground's ring
#: lies past half-way to the rock's hue, and of the rock's core short of it.
SEPARATE = 0.1
#: How far past the outline the rock's part is looked for (radii).
REACH = 1.0
#: The rock grows by at most this share of its area: the part an outline
#: left out may be larger than the part it took.
MAX_GROWTH = 1.5
#: The part is opened, and closed with the rock, by a disc of this share of
#: the rock's equivalent radius (at least one pixel).
OPEN = 0.05
#: Chromaticity is smoothed by a Gaussian of this many pixels: sensor noise
#: in a dim part moves its hue most.
SIGMA = 1.0
#: Fewest pixels with a hue for the ring and the core to be read.
MIN_RING = 50
MIN_CORE = 20
#: ``hue_off`` reads the ground's hue in a ring this far past the outline
#: (equivalent radii, plus a pixel for the blurred edge) ...
OFF_RING = (0.1, 0.5)
#: ... and cuts off at least this share of the rock's area, and at most this:
#: a shadow may be as large as the rock it joins.
MIN_SHRINK = 0.03
MAX_SHRINK = 0.6
#: ``hue_parted``: a part of the outline is the ground's when its hue lies
#: within this many of the ring's spreads of the ground's ...
PART_GROUND = 10.0
#: ... this many times nearer than the rock's part ...
PART_APART = 2.0
#: ... and no lighter than the ring by more than this (brightness in [0, 1]);
#: the rock's part lies at least this many spreads from the ground's hue.
PART_LIGHTER = 0.05
PART_ROCK = 5.0


def hue_on(colour: NDArray[np.floating], mask: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """A rock's mask with the part of its own hue beside it taken in (module docstring).

    Parameters
    ----------
    colour : (rows, cols, 3) ndarray of float
        Red, green and blue in [0, 1] around the rock, on the mask's grid,
        with a margin of at least ``RING[1]`` of the rock's equivalent radius
        (less where the frame cuts it).
    mask : (rows, cols) ndarray of bool
        The rock's region (one piece, holes filled).

    Returns
    -------
    (rows, cols) ndarray of bool
        The rock with the part of its hue, or ``mask`` itself, unchanged,
        when hue does not tell the rock from its ground, no part of the
        rock's hue lies beside it, or the part would not leave it compact.
    """
    from scipy import ndimage

    area = int(np.count_nonzero(mask))
    if area < 50:
        return mask
    radius = math.sqrt(area / math.pi)
    outside = ndimage.distance_transform_edt(~mask)
    inside = ndimage.distance_transform_edt(mask)
    ring = (outside > RING[0] * radius) & (outside <= RING[1] * radius)
    core = inside > CORE * radius
    if np.count_nonzero(core) < MIN_CORE:
        core = inside > 0.5 * inside.max()
    chroma, has_hue = _smoothed_chromaticity(colour)
    ring &= has_hue
    core &= has_hue
    if np.count_nonzero(ring) < MIN_RING or np.count_nonzero(core) < MIN_CORE:
        return mask
    place = _place(chroma, ring, core)
    if place is None:
        return mask
    disk = _disk(max(1, round(OPEN * radius)))
    own = has_hue & (place >= ROCK_HUE) & (outside > 0) & (outside <= REACH * radius)
    own = ndimage.binary_opening(own, disk)
    part = largest_part(_touching(own, outside <= 2.0)) if own.any() else None
    return mask if part is None else side_joined(mask, part, disk, MAX_GROWTH)


def hue_off(colour: NDArray[np.floating], mask: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """A rock's mask with a part of the ground's hue that reaches its edge cut
    off (module docstring).

    Parameters
    ----------
    colour : (rows, cols, 3) ndarray of float
        Red, green and blue in [0, 1] around the rock, on the mask's grid,
        with a margin of at least ``OFF_RING[1]`` of the rock's equivalent
        radius (less where the frame cuts it).
    mask : (rows, cols) ndarray of bool
        The rock's region (one piece, holes filled).

    Returns
    -------
    (rows, cols) ndarray of bool
        The rock without the part, inside ``mask``, or ``mask`` itself,
        unchanged, when hue does not tell the rock from its ground, no part
        of the ground's hue reaches the outline, or the rest would not be
        compact.
    """
    from scipy import ndimage

    area = int(np.count_nonzero(mask))
    if area < 50:
        return mask
    radius = math.sqrt(area / math.pi)
    chroma, has_hue, ring = _off_ring(colour, mask, radius)
    inside = mask & has_hue
    if np.count_nonzero(ring) < MIN_RING or np.count_nonzero(inside) < MIN_RING:
        return mask
    # The rock is the half of the outline farthest in hue from the ground:
    # its core may be the shadow's.
    apart = np.hypot(*np.moveaxis(chroma - np.median(chroma[ring], axis=0), -1, 0))
    rock = inside & (apart >= np.median(apart[inside]))
    place = _place(chroma, ring, rock)
    if place is None:
        return mask
    disk = _disk(max(1, round(OPEN * radius)))
    ground = ndimage.binary_opening(mask & has_hue & (place <= 1.0 - ROCK_HUE), disk)
    ground = _touching(ground, mask & (ndimage.distance_transform_edt(mask) <= 2.0))
    if not ground.any():
        return mask
    kept = largest_part(ndimage.binary_opening(mask & ~ground, disk))
    if kept is None:
        return mask
    kept = ndimage.binary_fill_holes(kept)
    cut = area - int(np.count_nonzero(kept))
    if not MIN_SHRINK * area <= cut <= MAX_SHRINK * area or not stays_compact(mask, kept):
        return mask
    return kept


def hue_parted(colour: NDArray[np.floating], mask: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """A rock's mask with the parts of the ground's hue its two colours tell
    from it cut off (module docstring).

    Parameters
    ----------
    colour, mask : ndarray
        As for :func:`hue_off`.

    Returns
    -------
    (rows, cols) ndarray of bool
        The largest piece of the rock's part, holes filled, or ``mask``
        itself, unchanged, when the outline is of one colour or its parts
        are not the rock and the ground's hue.
    """
    from scipy import ndimage

    area = int(np.count_nonzero(mask))
    if area < 50:
        return mask
    parts = split_colours(mask, np.asarray(colour, np.float32))
    if len(parts) < 2:
        return mask
    chroma, has_hue, ring = _off_ring(colour, mask, math.sqrt(area / math.pi))
    if np.count_nonzero(ring) < MIN_RING:
        return mask
    ground = np.median(chroma[ring], axis=0)
    spread = max(float(np.median(np.hypot(*np.moveaxis(chroma[ring] - ground, -1, 0)))), 1e-6)
    brightness = np.mean(colour, axis=-1)
    ground_level = float(np.mean(brightness[ring]))
    apart = []
    for part in parts:
        hued = part & has_hue
        # A part too dark for a hue is placed on the ground's: it may be a shadow.
        hue = np.median(chroma[hued], axis=0) if np.count_nonzero(hued) >= MIN_CORE else ground
        apart.append(float(np.hypot(*(hue - ground))) / spread)
    rock = int(np.argmax(apart))
    if apart[rock] < PART_ROCK:
        return mask
    for index, part in enumerate(parts):
        if index != rock and not (
            apart[index] <= PART_GROUND
            and PART_APART * apart[index] <= apart[rock]
            and float(np.mean(brightness[part])) <= ground_level + PART_LIGHTER
        ):
            return mask
    kept = largest_part(parts[rock])
    return mask if kept is None else ndimage.binary_fill_holes(kept)


def _off_ring(
    colour: NDArray[np.floating], mask: NDArray[np.bool_], radius: float
) -> tuple[NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_]]:
    """The smoothed chromaticity, where a pixel has a hue, and the ring of
    ground ``OFF_RING`` radii (plus a pixel) past the mask where it has one."""
    from scipy import ndimage

    outside = ndimage.distance_transform_edt(~mask)
    chroma, has_hue = _smoothed_chromaticity(colour)
    ring = (outside > OFF_RING[0] * radius + 1.0) & (outside <= OFF_RING[1] * radius) & has_hue
    return chroma, has_hue, ring


def _smoothed_chromaticity(colour: NDArray[np.floating]) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Red and green shares ``(r, g) / (r + g + b)`` of the colour smoothed by
    ``SIGMA`` pixels, and where a pixel is light enough to have a hue."""
    from scipy import ndimage

    smooth = np.stack([ndimage.gaussian_filter(colour[..., k], SIGMA) for k in range(3)], axis=-1)
    total = smooth.sum(axis=-1)
    return smooth[..., :2] / np.maximum(total, 1e-6)[..., None], total > _LEAST_LIGHT


def _place(
    chroma: NDArray[np.floating], ground: NDArray[np.bool_], rock: NDArray[np.bool_]
) -> NDArray[np.float64] | None:
    """Each pixel's place along the line in chromaticity from the median of
    ``ground`` (0) to that of ``rock`` (1); None when the two are one hue or
    hue does not tell them apart (``SEPARATE``)."""
    origin = np.median(chroma[ground], axis=0)
    axis = np.median(chroma[rock], axis=0) - origin
    length2 = float(axis @ axis)
    if length2 == 0.0:
        return None
    place = ((chroma - origin) @ axis) / length2
    if np.quantile(place[ground], 1.0 - SEPARATE) > 0.5 or np.quantile(place[rock], SEPARATE) < 0.5:
        return None
    return place
