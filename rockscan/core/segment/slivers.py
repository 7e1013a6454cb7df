"""Thin slivers of ground that join a rock's outline, and taking them off.

Where a rock touches a neighbour, or a neighbour reaches into a crop, the
crevice between them is shaded, often as dark as a dark rock; a light
neighbour's rim can be as light as a light one. The outline then runs out
along it: a thin band, many times longer than it is wide, reaching well
away from the rock's body. Opened by a disk of ``OPEN_SHARE`` of the rock's
equivalent radius (``split.opened``), the region loses such a band, and
with it the tips, corners and lips of its own shape. Of those pieces, a
sliver is

* *long*: the ratio of the larger to the smaller second moment of its
  pixels is at least ``ELONGATION`` (a star's tips are short: at most 3 on
  the renderer's library shapes; pebbles and blunt lobes less);
* *reaching away*: its farthest pixel lies at least ``REACH`` disk radii
  from the body. A lip of the rock's own edge, left between the edge and a
  dent or a shading line just inside it, is long too, but it stays within
  a disk radius of the body.

Slivers run off one side of the rock (on both sides of its contact with the
neighbour). Two or more long pieces, with the pieces of about their size,
lying all round the body are the rock's own arms (a star of thin needles,
the two tips of a spindle), and nothing is cut: a random rock of eight
needles that the renderer draws lost two thirds of its area without this
test; with it, none of 400 random rendered rocks loses a pixel.

Measured on the development part of the segmentation benchmark (one-rock
photos 0-39 of each condition, 480): the slivers of 5 photos go (IoU 0.80-0.92
-> 0.88-0.96, 2 of them crossing 0.9), no photo loses. Without the reach
test, lips went too, and 1 photo crossed 0.9 the other way.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from rockscan.core.segment.split import all_round, cut_back, opened_pieces

__all__ = ["slivers_off"]

#: Radius of the opening, in equivalent radii of the region. On the
#: development photos, 0.12, 0.16, 0.2 and 0.25 all moved 4-5 photos up and
#: none down (2 across IoU 0.9); 0.2 gained most (summed IoU +0.27, against
#: +0.22-0.24).
OPEN_SHARE = 0.2
#: Regions are measured scaled to at most this equivalent radius, in pixels
#: (what is a sliver does not depend on resolution, and a large rock costs no more).
RADIUS = 40.0
#: Smallest piece that counts, as a share of the region's area.
MIN_SHARE = 0.01
#: Smallest ratio of a sliver's second moments (its length over its width,
#: squared): 12-47 for the development slivers; 1.1-2.9 for the pieces the
#: opening takes off the library's shapes rendered at 400 x 300 and
#: 1024 x 768 (the tips of stars and of the teardrop, corners).
ELONGATION = 8.0
#: Smallest distance from the body to a sliver's farthest pixel, in radii of
#: the opening's disk: 1.7-7.5 for the development slivers, 0.6-0.7 for lips
#: of a rock's own edge (elongation 9.5-34).
REACH = 1.5
#: Two or more long pieces whose directions from the body's centre average to
#: a resultant under this length lie all round it: a star's thin arms (a
#: Superformula of 8 needles), a spindle's two tips. The slivers of a crevice
#: run off one side of the rock, on both sides of the contact.
SPREAD = 0.5
#: Pieces within this factor of the slivers' median size count as alike.
ALIKE = 2.0


def slivers_off(mask: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """The region with the thin slivers that run off it taken off.

    Parameters
    ----------
    mask : (h, w) ndarray of bool
        The rock's region, on its window.

    Returns
    -------
    (h, w) ndarray of bool
        What is left of it without the slivers (its largest part), or
        ``mask`` itself when it has none.
    """
    import cv2

    found = opened_pieces(mask, OPEN_SHARE, RADIUS)
    if found is None:
        return mask
    region, body, labels, stats = found.region, found.body, found.labels, found.stats
    count = stats.shape[0]
    scaled_area = int(np.count_nonzero(region))
    large = np.flatnonzero(stats[1:, cv2.CC_STAT_AREA] >= MIN_SHARE * scaled_area) + 1
    if large.size == 0:
        return mask
    disk = max(OPEN_SHARE * math.sqrt(scaled_area / math.pi), 1.0)
    away = cv2.distanceTransform((~body).astype(np.uint8), cv2.DIST_L2, 5)
    cut = np.zeros(count, bool)
    for i in large:
        piece = labels == i
        if _elongation(piece) >= ELONGATION and float(away[piece].max()) >= REACH * disk:
            cut[i] = True
    if not cut.any():
        return mask
    # Every large piece of about the slivers' size counts towards arms, long or
    # not: a star's arms are cut off as several pieces, only some of them long.
    typical = float(np.median(stats[cut, cv2.CC_STAT_AREA]))
    sizes = stats[large, cv2.CC_STAT_AREA]
    alike = large[(sizes <= ALIKE * typical) & (ALIKE * sizes >= typical)]
    # Two or more alike pieces all round are a star's arms or a spindle's tips.
    if alike.size >= 2 and all_round(labels, body, alike, SPREAD):
        return mask
    return cut_back(mask, found.box, cut[labels])


def _elongation(piece: NDArray[np.bool_]) -> float:
    """The larger over the smaller eigenvalue of the second central moments of a piece's pixels."""
    import cv2

    m = cv2.moments(piece.view(np.uint8), binaryImage=True)
    a, b, c = m["mu20"], m["mu11"], m["mu02"]
    root = math.hypot(a - c, 2.0 * b)
    small = 0.5 * (a + c - root)
    return float(0.5 * (a + c + root) / max(small, 1e-9))
