"""A part of a rock of the rock's own hue, left out of its outline, and taking it back in.

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
(``shade.side_joined``). Pixels too dark to
have a hue are never taken.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from rockscan.core.segment.channels import _LEAST_LIGHT
from rockscan.core.segment.shade import _touching, side_joined
from rockscan.core.segment.split import largest_part
from rockscan.core.segment.trace import _disk

__all__ = ["ROCK_HUE", "hue_on"]

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
    smooth = np.stack([ndimage.gaussian_filter(colour[..., k], SIGMA) for k in range(3)], axis=-1)
    total = smooth.sum(axis=-1)
    hued = total > _LEAST_LIGHT
    ring &= hued
    core &= hued
    if np.count_nonzero(ring) < MIN_RING or np.count_nonzero(core) < MIN_CORE:
        return mask
    chroma = smooth[..., :2] / np.maximum(total, 1e-6)[..., None]
    ground = np.median(chroma[ring], axis=0)
    axis = np.median(chroma[core], axis=0) - ground
    length2 = float(axis @ axis)
    if length2 == 0.0:
        return mask
    place = ((chroma - ground) @ axis) / length2
    if np.quantile(place[ring], 1.0 - SEPARATE) > 0.5 or np.quantile(place[core], SEPARATE) < 0.5:
        return mask
    disk = _disk(max(1, round(OPEN * radius)))
    own = hued & (place >= ROCK_HUE) & (outside > 0) & (outside <= REACH * radius)
    own = ndimage.binary_opening(own, disk)
    part = largest_part(_touching(own, outside <= 2.0)) if own.any() else None
    return mask if part is None else side_joined(mask, part, disk, MAX_GROWTH)
