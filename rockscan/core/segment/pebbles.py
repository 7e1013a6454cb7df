"""Pebbles that touch a rock and join its region: how much of it they are, and taking them off.

A pebble that touches a rock is as dark (or light) as the rock and joins its
region at any threshold; the outline then runs round both, and the photo
supports it all round. What gives a pebble away is its shape against the
body: opened by a disk (``split.opened``), the region loses whatever hangs
off it at a contact narrower than the disk, and of those pieces a pebble is
*round* (the disk inscribed in it nearly as large as a disk of its area) and
meets the body at a *neck* (its inscribed diameter at least about half its
contact with the body). The tips of a star are neither: they taper, and are
widest where they join. Lobes of the rock's own shape (a lobed star, a
Superformula of high symmetry) are round and necked too, but they come as
several pieces of much the same size all round the body, at even angles;
pebbles touch a rock where they happen to lie, even when they lie all round
it. A pebble pressed hard against a rock meets it along a contact nearly as
wide as itself, with no neck; the outline still
turns in at a wedge on either side of it, where the tip of a teardrop runs
on along a gently hollow flank.

Two uses:

* :func:`pebble_share`, a feature of the choice among candidate outlines
  (``rockscan.core.segment.choose``): the share of a candidate's area in
  round pieces;
* :func:`pebbles_off`, the last step on the main rock's outline: the
  pebbles cut off along their contacts, the rock's own edge left where it is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rockscan.core.segment.split import Pieces, cut_back, opened_pieces, piece_angles
from rockscan.core.segment.stats import label_maxima

__all__ = ["lobed", "pebble_share", "pebbles_off"]

#: A piece counts as a pebble when the disk inscribed in it has at least this
#: share of the radius of a disk of its area (a blunt lobe, not a star's arm).
ROUNDNESS = 0.6
#: ... and when that disk's diameter is at least this share of the piece's
#: contact with the body: a pebble meets the rock at a neck, a star's tip
#: is widest where it joins the body (measured: 0.24-0.38 for the tips of
#: rendered stars, mostly 0.45-1.3 for generated touching pebbles).
NECK = 0.45
#: :func:`pebbles_off` also cuts a round piece necked down to this share when
#: the region's outline turns in sharply beside it: a notch at least ``NOTCH``
#: of the piece's inscribed radius deep, whose sides, followed along the
#: outline for two such radii, meet at ``WEDGE`` degrees or less. A pebble
#: pressed against a rock meets it along a contact nearly as wide as itself,
#: at a wedge (73-135 degrees for the pebbles of development photos 680-799
#: in this band); the tip of a teardrop is as broad at its base, and the
#: outline runs into it along a gently hollow flank (157-173 degrees for the
#: default library's, drawn at radii of 30-60 pixels).
CUT_NECK = 0.35
NOTCH = 1.0
WEDGE = 145.0
#: At least this many round pieces, the largest at most ``LOBES_ALIKE``
#: times the smallest, are lobes of the rock's own shape.
LOBES = 3
LOBES_ALIKE = 2.0
#: Regions are measured scaled to at most this equivalent radius, in pixels
#: (what is a pebble does not depend on resolution).
RADIUS = 40.0
#: Radius of the opening that :func:`pebbles_off` cuts with, in equivalent
#: radii of the region: wider than the opened candidates' (``split.OPEN_SHARE``),
#: since a pebble pressed against a rock meets it along a contact nearly as
#: wide as itself. Set on the development part of the segmentation benchmark.
CUT_SHARE = 0.3
#: Alike pieces whose directions from the body's centre average to a
#: resultant under this length lie all round it. On development photos 0-39:
#: 320 of 440 one-rock photos at IoU >= 0.9 for any value from 0 to 0.3, 318
#: at 0.5, 316 at 0.7; at 0 (never lobes) shapes of the default library lose
#: lobes, so the largest of the best is taken.
LOBES_SPREAD = 0.3
#: ... and they are lobes only when the pieces also come at even angles: the
#: angular gaps between neighbours spread (standard deviation) by at most
#: this share of their mean. A symmetric shape's lobes come at even angles:
#: 0.10-0.26 for Superformula rocks that rockscan's renderer draws and
#: segments, under 0.03 for 95% of Superformulas of symmetry 3-12 drawn as
#: masks. Pebbles touch a rock where they happen to lie: on development
#: photos 3000-3039 and 4000-4159, of the 31 sets of pebbles that lay all
#: round a rock, 23 spread by 0.35-0.65 (8 by 0.08-0.27).
EVEN_SPREAD = 0.3


@dataclass(frozen=True)
class _Pieces:
    """What an opening takes off a region (``split.Pieces``), and what each piece is like."""

    opened: Pieces
    size: NDArray[np.float64]
    round_necked: NDArray[np.bool_]
    #: Of the round pieces, those necked down to ``CUT_NECK`` only.
    round_broad: NDArray[np.bool_]
    inscribed: NDArray[np.float64]


def _pieces(mask: NDArray[np.bool_], share: float, *, by_distance: bool = False) -> _Pieces | None:
    """The region in its bounding box (scaled to at most ``RADIUS``, padded by 2)
    and the pieces an opening of ``share`` takes off it; None if there are none."""
    import cv2

    found = opened_pieces(mask, share, RADIUS, by_distance=by_distance)
    if found is None:
        return None
    region, body, labels, stats = found.region, found.body, found.labels, found.stats
    count = stats.shape[0]
    # The pieces are apart, so one distance map gives each its inscribed radius.
    inside = labels > 0
    distance = cv2.distanceTransform(inside.astype(np.uint8), cv2.DIST_L2, 5)
    inscribed = label_maxima(distance, labels, count)
    rim = cv2.dilate(body.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    contact = np.maximum(np.bincount(labels[rim], minlength=count), 1)
    size = stats[:, cv2.CC_STAT_AREA].astype(np.float64)
    rounded = (size >= max(4.0, 0.005 * float(np.count_nonzero(region)))) & (
        inscribed >= ROUNDNESS * np.sqrt(size / math.pi)
    )
    rounded[0] = False
    round_necked = rounded & (2.0 * inscribed >= NECK * contact)
    round_broad = rounded & ~round_necked & (2.0 * inscribed >= CUT_NECK * contact)
    return _Pieces(found, size, round_necked, round_broad, inscribed.astype(np.float64))


def _notched(found: _Pieces) -> NDArray[np.bool_]:
    """Which of the broad round pieces have a notch of the region's outline beside
    them: a convexity defect within half their inscribed radius, at least
    ``NOTCH`` of that radius deep, a wedge of at most ``WEDGE`` degrees."""
    import cv2

    notched = np.zeros_like(found.round_broad)
    if not found.round_broad.any():
        return notched
    region = found.opened.region.astype(np.uint8)
    contours, _ = cv2.findContours(region, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    contour = max(contours, key=cv2.contourArea)
    try:
        defects = cv2.convexityDefects(contour, cv2.convexHull(contour, returnPoints=False))
    except cv2.error:  # a self-touching outline has no well-defined hull order
        return notched
    if defects is None:
        return notched
    defects = defects.reshape(-1, 4)
    outline = contour.reshape(-1, 2)
    deepest = outline[defects[:, 2]]
    depths = defects[:, 3] / 256.0
    labels = found.opened.labels
    for k in np.flatnonzero(found.round_broad):
        radius = max(float(found.inscribed[k]), 1.0)
        away = cv2.distanceTransform((labels != k).astype(np.uint8), cv2.DIST_L2, 5)
        near = (away[deepest[:, 1], deepest[:, 0]] <= 1.0 + 0.5 * radius) & (depths >= NOTCH * radius)
        notched[k] = any(_wedge(outline, int(at), radius) <= WEDGE for at in defects[near, 2])
    return notched


def _wedge(outline: NDArray[np.int32], at: int, radius: float) -> float:
    """The angle, in degrees, at point ``at`` of a closed outline between the
    points two ``radius`` along it on either side."""
    step = max(round(2.0 * radius), 2)
    here = outline[at].astype(np.float64)
    before = outline[(at - step) % len(outline)] - here
    after = outline[(at + step) % len(outline)] - here
    cosine = float(before @ after) / max(float(np.linalg.norm(before) * np.linalg.norm(after)), 1e-9)
    return math.degrees(math.acos(min(max(cosine, -1.0), 1.0)))


def pebble_share(mask: NDArray[np.bool_]) -> float:
    """Share of a region's area in round pieces that an opening takes off its body.

    The region is opened as the "opened" candidates are (``split.opened``);
    of what the opening takes off, a piece is a pebble when it is round and
    meets the body at a neck (module docstring). Thin pieces (rough edges)
    and the tips of a star do not count, nor do round pieces when there are
    ``LOBES`` or more of much the same size: lobes all round are the rock's
    own shape.

    Parameters
    ----------
    mask : (h, w) ndarray of bool

    Returns
    -------
    share : float
        In [0, 1]; 0 for an empty region or one without round pieces.
    """
    found = _pieces(mask, share=0.2)
    if found is None:
        return 0.0
    pebbles = found.size[found.round_necked]
    # Alike lobes all round are the rock's own shape (a lobed star, a
    # Superformula of high symmetry), not pebbles that happen to touch it.
    if pebbles.size >= LOBES and pebbles.max() <= LOBES_ALIKE * pebbles.min():
        return 0.0
    return float(pebbles.sum() / np.count_nonzero(found.opened.region))


def pebbles_off(mask: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """The region with the pebbles that touch it cut off along their contacts.

    Pieces an opening by a disk of ``CUT_SHARE`` of the region's equivalent
    radius takes off are pebbles when they are round and meet the body at a
    neck, or at a broader contact with a notch of the outline beside them
    (module docstring; ``CUT_NECK``, ``NOTCH``, ``WEDGE``). When ``LOBES``
    or more pieces of much the same
    size as the pebbles lie all round the body (their directions from its
    centre average to a resultant under ``LOBES_SPREAD``) and at even angles
    (``EVEN_SPREAD``), they are the
    rock's own lobes and nothing is cut. Only the pebbles' pixels go: the
    rock keeps its own edge, and its corners, where they are.

    Parameters
    ----------
    mask : (h, w) ndarray of bool
        One region.

    Returns
    -------
    (h, w) ndarray of bool
        The largest part of the region left once the pebbles are off;
        ``mask`` itself when there are none.
    """

    found = _pieces(mask, CUT_SHARE, by_distance=True)
    if found is None:
        return mask
    pebbles = found.round_necked | _notched(found)
    if not pebbles.any():
        return mask
    # Any piece of much the pebbles' size counts towards lobes, round or not:
    # the arms of a star are cut off as several pieces, only some of them round.
    alike = _alike(found, float(np.median(found.size[pebbles])))
    if _lobes(found, alike):
        return mask
    return cut_back(mask, found.opened.box, pebbles[found.opened.labels])


def lobed(mask: NDArray[np.bool_]) -> bool:
    """Whether a region is lobed all round, as a star is: what an opening takes off it
    (as :func:`pebbles_off` opens) is ``LOBES`` or more pieces, all of much
    the same size, lying all round the body and at even angles
    (``LOBES_SPREAD``, ``EVEN_SPREAD``).

    A lobed region is not solid, yet nothing joined it: a rock with a pebble
    or its shadow joined has what hangs off it on one side only.

    Parameters
    ----------
    mask : (h, w) ndarray of bool
        One region.

    Returns
    -------
    bool
    """
    found = _pieces(mask, CUT_SHARE, by_distance=True)
    if found is None:
        return False
    pieces = _alike(found, None)
    if pieces.size < LOBES:
        return False
    sizes = found.size[pieces]
    typical = float(np.median(sizes))
    alike = sizes.max() <= LOBES_ALIKE * typical and LOBES_ALIKE * sizes.min() >= typical
    return bool(alike) and _lobes(found, pieces)


def _alike(found: _Pieces, typical: float | None) -> NDArray[np.int64]:
    """The pieces that are more than specks (of any size when ``typical`` is
    None, else within a factor ``LOBES_ALIKE`` of it)."""
    size = found.size
    keep = size >= max(4.0, 0.005 * float(np.count_nonzero(found.opened.region)))
    if typical is not None:
        keep &= (size <= LOBES_ALIKE * typical) & (LOBES_ALIKE * size >= typical)
    keep[0] = False
    return np.flatnonzero(keep)


def _lobes(found: _Pieces, alike: NDArray[np.int64]) -> bool:
    """Whether alike pieces are the rock's own lobes: ``LOBES`` or more of them,
    lying all round the body (``LOBES_SPREAD``), and every piece at even angles
    (the gaps between neighbours spread by at most ``EVEN_SPREAD`` of their mean).

    Every piece counts towards the spacing, of the alike size or not: a
    star's arms on its narrow side come off smaller than the rest.
    """
    if alike.size < LOBES:
        return False
    every = _alike(found, None)  # the alike pieces are among them
    angles = piece_angles(found.opened.labels, found.opened.body, every)
    if abs(np.exp(1j * angles[np.isin(every, alike)]).mean()) >= LOBES_SPREAD:
        return False
    angles = np.sort(angles)
    gaps = np.diff(angles, append=angles[0] + 2.0 * math.pi)
    return bool(gaps.std() <= EVEN_SPREAD * gaps.mean())
