"""A region that holds several rocks, cut into one region per rock.

Growth at a low threshold joins rocks that touch, or nearly touch through
the blur between them, into one region. Two cues part them again, each a
watershed from markers (see :func:`split_rocks`):

1. **Contrast.** Every rock is a hump of contrast with its own top; between
   two rocks the contrast dips towards the ground's. The region is flooded
   from its local maxima, and two neighbouring basins are joined again when
   the pass between them is high for the lower of their tops (texture on one
   rock), and kept apart when it is low (the ground, or a dark crack, between
   two rocks). This is the dynamics of the maxima, relative to their height,
   so rocks of different contrast part alike.
2. **Shape.** Rocks that touch without any dip between them are still
   several compact blobs joined by necks. The distance to the ground has one
   peak per blob: the part is flooded from those peaks and cut where the
   neck between two peaks is narrow for the smaller blob.

A single rock, however textured or shaded, has one top that its texture
barely dents and one peak of its distance map, and stays whole.

With ``--all``, an outline traced at working size is looked at once more
(:func:`split_blobs`, the shape cue on the outline); in a colour photo by a
third cue, **colour** (:func:`split_colours`): touching rocks of clearly
different hues are two rocks even where they meet along a long contact
without a neck; and by a fourth, **seams** (:func:`split_seams`): where two
rocks touch, each curves away from the camera and the light, and the line
they meet along is darker than either rock, whichever of rock and ground is
the lighter. At detection size that line is a pixel wide or less and blurs
away; at working size it parts rocks of one colour that touch along a
contact too long for a neck. Before those, an outline much larger than the
median is looked at for a fifth, **pockets** (:func:`split_pockets`): rocks
that touch round a patch of ground are outlined together and the patch is
filled in, but it keeps the ground's colour; taken out, it leaves a neck
between each rock and the next.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rockscan.core.segment.stats import bounding_box, label_maxima, solidity, touching_pairs

__all__ = [
    "label_image",
    "largest_part",
    "nearest_regions",
    "opened",
    "pockets",
    "rejoined",
    "split_blobs",
    "split_colours",
    "split_necks",
    "split_pockets",
    "split_rocks",
    "split_seams",
    "territories",
]

#: A pass between two humps of contrast at least this share of the lower top
#: joins them (texture on one rock); below it they are two rocks.
PASS_SHARE = 0.5
#: Solidity from which a region is taken for one rock without looking further.
CONVEX = 0.96
#: Solidity from which a cell the contrast left whole is one rock (shape cue skipped).
CONVEX_CELL = 0.95
#: A neck narrower than this share of the smaller blob's inscribed radius
#: (both as distances to the ground) parts two blobs.
NECK_SHARE = 0.72
#: A border between two parts at least this share of the smaller part's
#: equivalent diameter joins them: rocks touch along a short contact, while a
#: cut through one rock runs across it.
CUT_SHARE = 0.8
#: Smallest inscribed radius of a blob, in pixels, for it to stand alone.
MIN_PEAK = 2.0


def split_rocks(
    signed: NDArray[np.float32], region: NDArray[np.bool_], min_area: float, floor: float
) -> list[NDArray[np.bool_]]:
    """The rocks one region holds.

    Parameters
    ----------
    signed : (rows, cols) ndarray of float32
        Contrast against the ground, positive towards the rocks (smoothed).
    region : (rows, cols) ndarray of bool
        One connected region of contrast above ``floor``.
    min_area : float
        Smallest rock, in pixels.
    floor : float
        The contrast the region was grown to (its edge).

    Returns
    -------
    list of (rows, cols) ndarray of bool
        One mask per rock, together covering the region; the region itself
        when it is one rock.
    """
    if np.count_nonzero(region) < 2 * min_area:
        return [region]
    r0, r1, c0, c1 = bounding_box(region)
    # A pixel of ground all round keeps the window's edge out of the flooding.
    r0, c0 = max(0, r0 - 1), max(0, c0 - 1)
    r1, c1 = min(region.shape[0], r1 + 1), min(region.shape[1], c1 + 1)
    sub = region[r0:r1, c0:c1]
    if solidity(sub) >= CONVEX:
        # Touching rocks leave notches where they meet: a convex region is one rock.
        return [region]
    values = np.where(sub, signed[r0:r1, c0:c1], 0.0).astype(np.float32)
    cells = _contrast_cells(values, sub, floor)
    parts = []
    for label in range(1, int(cells.max()) + 1):
        cell = cells == label
        if np.count_nonzero(cell) < min_area:
            continue
        if solidity(cell) >= CONVEX_CELL:
            # No notch where a neighbour would touch: one rock, however its light falls.
            parts.append(cell)
            continue
        # Necks are judged half-way up the cell's contrast: at the region's own
        # floor the blur between touching rocks fills them in.
        # Half-way up to the brighter rocks' level, and to the fainter ones'
        # (a faint rock against a clear one shows its necks only there).
        blobs = max(
            (
                split_necks(
                    _filled(cell & (values > floor + 0.5 * (level - floor)), min_area), 0.5 * min_area
                )
                for level in np.percentile(values[cell], [90, 30])
            ),
            key=len,
        )
        if len(blobs) == 1:
            parts.append(cell)
        else:
            owners = territories(blobs)
            parts.extend(cell & (owners == i) for i in range(1, len(blobs) + 1))
    if len(parts) <= 1:
        return [region]
    out = []
    for part in parts:
        full = np.zeros(region.shape, bool)
        full[r0:r1, c0:c1] = part
        out.append(full)
    return out


#: Solidity under which an outlined rock is looked at again for touching blobs.
BLOB_SOLIDITY = 0.93
#: Smallest blob, as a share of the outlined rock's area.
BLOB_MIN_SHARE = 0.1
#: A blob down to ``BLOB_SMALL_SHARE`` of the outlined rock's area is still a
#: rock of its own when it is round: its area at most ``BLOB_ROUND`` times the
#: square of its inscribed radius (a disc's is pi, a 1.4:1 ellipse's 4.4; a
#: sliver's or a crescent's far more). A cluster holds rocks of sizes 10 to 1
#: in area, and a small one beside large ones was given to its neighbour.
#: Chosen on the development crowded scenes 0-199 (rocks one to one, of 4,366,
#: and scenes counted exactly, of 200: 88.5% and 48 without; 88.8% and 48 at
#: 4.0, 89.1% and 47 at 4.5, 89.3% and 43 at 5.0; every blob down to 5% of
#: the outline, round or not, 89.4% and 40).
BLOB_SMALL_SHARE = 0.03
BLOB_ROUND = 4.5
#: ``NECK_SHARE`` and ``CUT_SHARE`` for the last look at an outlined rock
#: with ``--all``, where the cues of the detection have already had their say.
BLOB_NECK_SHARE = 0.9
BLOB_CUT_SHARE = 1.0


def split_blobs(mask: NDArray[np.bool_]) -> list[NDArray[np.bool_]]:
    """An outlined rock that is several compact blobs cut at the necks between them.

    The last look at a region that the cues of :func:`split_rocks`, judged on
    the detection image, left whole: on the outline traced at working size,
    a region that is not solid (solidity under ``BLOB_SOLIDITY``) is cut by
    the shape cue (:func:`split_necks`) into blobs of at least
    ``BLOB_MIN_SHARE`` of its area, or of at least ``BLOB_SMALL_SHARE`` when
    round (``BLOB_ROUND``); a smaller or thinner piece goes to the blob it
    lies nearest. A star's arms widen towards its body and keep it whole;
    two touching rocks meet at a neck.

    Parameters
    ----------
    mask : (rows, cols) ndarray of bool

    Returns
    -------
    list of (rows, cols) ndarray of bool
        The blobs, or ``[mask]``.
    """
    if np.count_nonzero(mask) < 50 or solidity(mask) >= BLOB_SOLIDITY:
        return [mask]
    owners = _blob_territories(mask)
    if owners is None:
        return [mask]
    return [mask & (owners == i) for i in range(1, int(owners.max()) + 1)]


def _blob_territories(mask: NDArray[np.bool_]) -> NDArray[np.int32] | None:
    """The territories (:func:`territories`) of the blobs :func:`split_blobs`
    cuts ``mask`` into, or None when it is one blob."""
    area = int(np.count_nonzero(mask))
    parts = split_necks(mask, BLOB_SMALL_SHARE * area, neck_share=BLOB_NECK_SHARE, cut_share=BLOB_CUT_SHARE)
    parts = [p for p in parts if np.count_nonzero(p) >= BLOB_MIN_SHARE * area or _round(p)]
    return territories(parts) if len(parts) >= 2 else None


def _round(part: NDArray[np.bool_]) -> bool:
    """Whether a blob's area is at most ``BLOB_ROUND`` squared inscribed radii."""
    import cv2

    inscribed = float(cv2.distanceTransform(np.pad(part, 1).astype(np.uint8), cv2.DIST_L2, 5).max())
    return inscribed > 0 and np.count_nonzero(part) <= BLOB_ROUND * inscribed**2


#: Separation of two colours inside one outline, in their pooled standard
#: deviations along the main axis of the chromaticity, from which they are
#: two rocks. Chosen on the development crowded scenes 0-199 (rocks one to
#: one, of 4,366: 83.8% without the colour cue; 84.9% at 3, with 24 more
#: pieces of rocks counted as rocks; 84.9% at 5; 84.1% at 7).
COLOUR_SEPARATION = 5.0
#: Least difference of the two colours' mean chromaticity (a share of r + g + b):
#: a gray photo's three equal channels differ only by rounding.
COLOUR_STEP = 0.01
#: Least share of the outline each colour covers, and of each colour's pixels
#: in its largest connected part (one rock is one piece).
COLOUR_MIN_SHARE = 0.15
COLOUR_COHERENCE = 0.9
#: How many times the parts are looked at again (a region of three rocks is cut twice).
COLOUR_DEPTH = 3


def split_colours(mask: NDArray[np.bool_], rgb: NDArray[np.float32]) -> list[NDArray[np.bool_]]:
    """An outline that holds touching rocks of clearly different colours cut between them.

    The cue of colour: rocks of one scene differ in hue more than one rock
    does across its own skin, whose texture varies mostly in brightness.
    Inside the outline (less a band along its edge, where rock and ground
    blend), the chromaticity ``(r, g) / (r + g + b)`` is projected on its
    main axis and cut in two at Otsu's threshold. The outline is two rocks
    when the two classes lie ``COLOUR_SEPARATION`` pooled standard
    deviations apart (and at least ``COLOUR_STEP``), each covers at least
    ``COLOUR_MIN_SHARE`` of it, and each is one piece (``COLOUR_COHERENCE``);
    they are cut along the border between the two colours' territories. A
    convex outline (solidity at least ``CONVEX_CELL``) is one rock whatever
    its colours: touching rocks leave notches where they meet, a
    two-coloured rock does not. Each part is looked at again, up to ``COLOUR_DEPTH`` times.

    Parameters
    ----------
    mask : (rows, cols) ndarray of bool
        The outline.
    rgb : (rows, cols, 3) ndarray of float32
        The photo on the same grid, in [0, 1].

    Returns
    -------
    list of (rows, cols) ndarray of bool
        The parts, or ``[mask]``.
    """
    import cv2

    chroma = None
    # Each round looks only at the parts the last one cut (a part left whole stays so).
    whole: list[NDArray[np.bool_]] = []
    parts = [mask]
    for _ in range(COLOUR_DEPTH):
        cut = []
        for part in parts:
            if int(np.count_nonzero(part)) < _COLOUR_LEAST_AREA or solidity(part) >= CONVEX_CELL:
                whole.append(part)
                continue
            if chroma is None:
                blurred = cv2.GaussianBlur(np.ascontiguousarray(rgb, np.float32), (0, 0), _COLOUR_SIGMA)
                total = blurred.sum(axis=2) + 1e-3
                chroma = np.stack([blurred[..., 0] / total, blurred[..., 1] / total], axis=-1)
            pieces = _two_colours(part, chroma)
            (cut if len(pieces) > 1 else whole).extend(pieces)
        parts = cut
        if not parts:
            break
    return whole + parts


#: Smoothing of the colours before they are compared, in pixels (noise, JPEG's half-resolution colour).
_COLOUR_SIGMA = 2.0
#: Smallest outline, in pixels, whose colours are compared (two parts of 15% and their insides).
_COLOUR_LEAST_AREA = 200


def _two_colours(mask: NDArray[np.bool_], chroma: NDArray[np.float32]) -> list[NDArray[np.bool_]]:
    """One cut of :func:`split_colours` of a part it found neither small nor convex:
    the two parts, or ``[mask]``."""
    import cv2
    from skimage.filters import threshold_otsu

    area = int(np.count_nonzero(mask))
    inner = cv2.erode(mask.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    if np.count_nonzero(inner) < 100:
        return [mask]
    samples = chroma[inner].astype(np.float64)
    centre = samples.mean(axis=0)
    _, vectors = np.linalg.eigh(np.cov((samples - centre).T))
    projected = (chroma - centre.astype(np.float32)) @ vectors[:, -1].astype(np.float32)
    values = projected[inner]
    threshold = float(threshold_otsu(values))
    low, high = values[values < threshold], values[values >= threshold]
    if min(low.size, high.size) < COLOUR_MIN_SHARE * values.size:
        return [mask]
    step = float(high.mean() - low.mean())
    pooled = math.sqrt(0.5 * (float(low.var()) + float(high.var())))
    if step < COLOUR_STEP or step < COLOUR_SEPARATION * pooled:
        return [mask]
    # A median filter keeps a colour's stray pixels (glints, veins) with the rock round them.
    side = cv2.medianBlur((mask & (projected >= threshold)).astype(np.uint8), 5) > 0
    pieces = []
    for colour in (side & mask, ~side & mask):
        piece = largest_part(colour)
        if (
            piece is None
            or np.count_nonzero(piece) < COLOUR_COHERENCE * np.count_nonzero(colour)
            or np.count_nonzero(piece) < COLOUR_MIN_SHARE * area
        ):
            return [mask]
        pieces.append(piece)
    owners = territories(pieces)
    return [mask & (owners == 1), mask & (owners == 2)]


#: A seam no brighter than this share of the way from the outline's darkest
#: level (its 5th percentile) up to the lower of the two sides' tops parts
#: them. Chosen on the development crowded scenes 0-199 (rocks one to one, of
#: 4,366: 85.8% without seams; 87.6% at 0.2, 88.1% at 0.3, 87.9% at 0.4, more
#: single rocks cut along their shading the higher it is).
SEAM_SHARE = 0.3
#: ... and at least this share of the lower top's brightness below it: on a
#: rock of even brightness the spread between its darkest and brightest
#: pixels is noise, and the share above would cut along it; the seams
#: measured in development scenes 30 and 31 fall by 32-49%. Chosen on the
#: scenes 0-199 (one to one 89.2% at 0, 89.3% at 0.1, 0.15 and 0.2; splits
#: 263, 255, 251 and 235, merges 101, 102, 103 and 110), and on a speckled
#: outline, which 0.1 and over leave whole.
SEAM_DEPTH = 0.15
#: Smoothing of the brightness before seams are read, in working pixels: noise
#: and JPEG blocks, not the seam, which is a few pixels wide at working size.
SEAM_SIGMA = 1.5
#: Band along the outline, in working pixels, where no seam is read: there the
#: outline blends rock with ground, and a ground lighter than the rocks (or
#: blur) would bridge every seam at its ends. Chosen on the same scenes: one
#: to one on scenes 0-39 and 40-199, 89.7% and 87.4% at 3 px, 89.8% and
#: 87.6% at 5, 89.4% and 87.2% at 7.
SEAM_BAND = 5


def split_seams(mask: NDArray[np.bool_], gray: NDArray[np.float32]) -> list[NDArray[np.bool_]]:
    """An outline of touching rocks cut along the dark seams between them.

    The cue of seams (module docstring): inside the outline less a band of
    ``SEAM_BAND`` pixels along it, the smoothed brightness is flooded from its
    local maxima, and two basins are joined again unless the brightest point
    of their whole border (the pass) lies below ``SEAM_SHARE`` of the way
    from the outline's darkest level up to the lower of their tops, and at
    least ``SEAM_DEPTH`` of that top's brightness below it. Texture
    and shading dent a rock's brightness here and there, but a line across
    one rock is not dark from end to end; the line between two touching
    rocks is. Parts under ``BLOB_MIN_SHARE`` of the outline, or enclosed by
    another part (a boss on one rock, not a rock of its own), join their
    neighbours. A convex outline (solidity at least ``CONVEX_CELL``) is one
    rock: touching rocks leave notches where they meet.

    Parameters
    ----------
    mask : (rows, cols) ndarray of bool
        The outline, at working size.
    gray : (rows, cols) ndarray of float32
        The photo's brightness on the same grid.

    Returns
    -------
    list of (rows, cols) ndarray of bool
        The parts, together covering ``mask``, or ``[mask]``.
    """
    import cv2

    area = int(np.count_nonzero(mask))
    if area < _SEAM_LEAST_AREA or solidity(mask) >= CONVEX_CELL:
        return [mask]
    disk = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * SEAM_BAND + 1, 2 * SEAM_BAND + 1))
    inner = cv2.erode(mask.astype(np.uint8), disk) > 0
    if np.count_nonzero(inner) < _SEAM_LEAST_AREA // 2:
        return [mask]
    values = cv2.GaussianBlur(np.ascontiguousarray(gray, np.float32), (0, 0), SEAM_SIGMA)
    base = float(np.percentile(values[inner], 5))
    # No long-cut rule here (as in the other cues): rocks in a pile touch along
    # contacts as long as they are wide, and darkness all along is the evidence.
    labels = _flood_and_join(
        values,
        inner,
        inner,
        lambda height, lower, cut, smaller: (
            height - base >= SEAM_SHARE * (lower - base) or lower - height < SEAM_DEPTH * lower
        ),
    )
    parts = [labels == i for i in range(1, int(labels.max()) + 1)]
    edge = mask & ~inner
    parts = [p for p in parts if np.count_nonzero(p) >= BLOB_MIN_SHARE * area and _reaches(p, edge)]
    if len(parts) < 2:
        return [mask]
    owners = territories(parts)
    return [mask & (owners == i) for i in range(1, len(parts) + 1)]


#: Smallest outline, in working pixels, looked at for seams.
_SEAM_LEAST_AREA = 200


#: A pixel belongs to a pocket when its colour lies within this share of the
#: rock-to-ground distance from the ground's colour (both colours medians: of
#: a ring just outside the outline, and of its core). Chosen on the
#: development crowded scenes 0-199 (rocks one to one, of 4,366, and scenes
#: counted exactly, of 200: 89.2% and 56 without pockets; 90.8% and 55 at
#: 0.25, 91.0% and 56 at 0.3, 91.3% and 58 at 0.35, 91.2% and 58 at 0.4,
#: 91.1% and 53 at 0.5, where more textured rocks are cut).
POCKET_LEVEL = 0.35
#: Smallest pocket, as a share of the outline's area and in working pixels
#: (below, a spot of a rock's own texture). One to one on the same scenes
#: (at a level of 0.25): 90.8% at 0.002, 90.7% at 0.003, 90.3% at 0.005 and
#: 89.9% at 0.01.
POCKET_LEAST_SHARE = 0.002
POCKET_LEAST_PIXELS = 20
#: Depth inside the outline, in working pixels, from which pockets are read:
#: along the outline, rock and ground blend.
POCKET_DEPTH = 3
#: Width of the ring of ground read round the outline, in working pixels.
POCKET_RING = 4


def pockets(mask: NDArray[np.bool_], image: NDArray[np.float32]) -> NDArray[np.bool_]:
    """The pockets of ground an outline encloses.

    Rocks that touch round a patch of ground enclose it, and the outline
    traced round them fills it in; the patch still has the ground's colour.
    A pocket is a connected patch, at least ``POCKET_DEPTH`` pixels inside
    the outline, within ``POCKET_LEVEL`` of the way from the ground's colour
    to the rock's, of at least ``POCKET_LEAST_SHARE`` of the outline's area
    (and ``POCKET_LEAST_PIXELS``).

    Parameters
    ----------
    mask : (rows, cols) ndarray of bool
        The outline, holes filled, with ground round it in the window.
    image : (rows, cols) or (rows, cols, 3) ndarray of float32
        The photo on the same grid: brightness, or colour.

    Returns
    -------
    (rows, cols) ndarray of bool
        The pockets; all False when there is none.
    """
    import cv2

    none = np.zeros(mask.shape, bool)
    mask8 = mask.astype(np.uint8)
    ring_disk = cv2.getStructuringElement(cv2.MORPH_RECT, (2 * POCKET_RING + 1, 2 * POCKET_RING + 1))
    depth_disk = cv2.getStructuringElement(cv2.MORPH_RECT, (2 * POCKET_DEPTH + 1, 2 * POCKET_DEPTH + 1))
    ring = (cv2.dilate(mask8, ring_disk) > 0) & ~mask
    core = cv2.erode(mask8, depth_disk) > 0
    if np.count_nonzero(ring) < 10 or np.count_nonzero(core) < 10:
        return none
    ground = np.median(image[ring], axis=0)
    rock = np.median(image[core], axis=0)
    step = float(np.linalg.norm(np.atleast_1d(rock - ground)))
    if step == 0.0:
        return none
    # Smoothed as split_seams reads brightness: noise, not the pocket.
    smooth = cv2.GaussianBlur(np.ascontiguousarray(image, np.float32), (0, 0), SEAM_SIGMA)
    off = smooth - ground
    distance = np.abs(off) if off.ndim == 2 else np.linalg.norm(off, axis=-1)
    candidate = core & (distance < POCKET_LEVEL * step)
    count, labels, stats, _ = cv2.connectedComponentsWithStats(candidate.astype(np.uint8), connectivity=4)
    least = max(POCKET_LEAST_PIXELS, POCKET_LEAST_SHARE * float(np.count_nonzero(mask)))
    keep = stats[:, cv2.CC_STAT_AREA] >= least
    keep[0] = False
    return keep[labels] if count > 1 else none


def split_pockets(mask: NDArray[np.bool_], image: NDArray[np.float32]) -> list[NDArray[np.bool_]]:
    """An outline of rocks that touch round pockets of ground, cut into them.

    The outline less its :func:`pockets` is cut at its necks as
    :func:`split_blobs` cuts a region: round a pocket, each rock meets the
    next at a neck between the pocket and the ground outside. Each part takes
    its share of the pockets (:func:`territories`) and keeps no hole.

    Parameters
    ----------
    mask, image
        As for :func:`pockets`.

    Returns
    -------
    list of (rows, cols) ndarray of bool
        The parts, together covering ``mask``, or ``[mask]``.
    """
    pocket = pockets(mask, image)
    if not pocket.any():
        return [mask]
    owners = _blob_territories(mask & ~pocket)
    if owners is None:
        return [mask]
    parts = (mask & (owners == i) for i in range(1, int(owners.max()) + 1))
    return [_filled(np.pad(part, 1), math.inf)[1:-1, 1:-1] for part in parts]


def _reaches(part: NDArray[np.bool_], band: NDArray[np.bool_]) -> bool:
    """Whether ``part`` touches ``band`` (8-neighbours)."""
    import cv2

    grown = cv2.dilate(part.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    return bool(np.any(grown & band))


#: Radius of the opening that takes touching pebbles off a region, in its equivalent radii.
OPEN_SHARE = 0.2


def opened(
    mask: NDArray[np.bool_], share: float = OPEN_SHARE, *, by_distance: bool = False
) -> NDArray[np.bool_] | None:
    """The mask opened by a disk of ``share`` of its equivalent radius, its largest part kept.

    Pebbles that touch a rock join it at contacts narrower than they are:
    the opening takes them off and leaves the rock's own edge where it is.

    Parameters
    ----------
    mask : (rows, cols) ndarray of bool
    share : float
        Radius of the disk, in equivalent radii of the mask.
    by_distance : bool
        Erode and dilate by thresholds of distance maps rather than with a
        disk kernel: a fraction of the cost for a disk of 10 pixels and
        more. The result differs from the kernel's by a pixel along the
        edge, and on pieces about as wide as the disk, which one keeps and
        the other takes off.

    Returns
    -------
    (rows, cols) ndarray of bool or None
        None when the disk would be under 2 pixels or nothing is left.
    """
    import cv2

    radius = math.sqrt(max(int(np.count_nonzero(mask)), 1) / math.pi)
    size = round(share * radius)
    if size < 2:
        return None
    if by_distance:
        # The quarter pixel matches OpenCV's elliptic kernel of side 2 size + 1 best.
        reach = size + 0.25
        core = cv2.distanceTransform(mask.astype(np.uint8), cv2.DIST_L2, 5) > reach
        grown = cv2.distanceTransform((~core).astype(np.uint8), cv2.DIST_L2, 5) <= reach
        body = (grown & mask).astype(np.uint8)
    else:
        disk = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * size + 1, 2 * size + 1))
        body = cv2.morphologyEx(mask.astype(np.uint8), cv2.MORPH_OPEN, disk)
    return largest_part(body)


def scaled_region(
    mask: NDArray[np.bool_], radius: float
) -> tuple[tuple[int, int, int, int], NDArray[np.bool_]]:
    """A region's bounding box (r0, r1, c0, c1) and the region in it, scaled
    down to an equivalent radius of at most ``radius`` pixels and padded by 2.

    What hangs off a region is judged at one resolution, whatever the photo's,
    and a large rock costs no more than a small one.
    """
    import cv2

    box = bounding_box(mask)
    region = mask[box[0] : box[1], box[2] : box[3]]
    own = math.sqrt(int(np.count_nonzero(mask)) / math.pi)
    if own > radius:
        scale = radius / own
        shape = (max(1, round(region.shape[1] * scale)), max(1, round(region.shape[0] * scale)))
        region = cv2.resize(region.astype(np.float32), shape, interpolation=cv2.INTER_AREA) >= 0.5
    return box, np.pad(region, 2)


@dataclass(frozen=True)
class Pieces:
    """What an opening takes off a region, on :func:`scaled_region`'s scaled, padded region."""

    box: tuple[int, int, int, int]
    region: NDArray[np.bool_]
    body: NDArray[np.bool_]
    #: The pieces off the body, labelled 1..n (8-connected), and their OpenCV stats.
    labels: NDArray[np.int32]
    stats: NDArray[np.int32]


def opened_pieces(
    mask: NDArray[np.bool_], share: float, radius: float, *, by_distance: bool = True
) -> Pieces | None:
    """The pieces an opening by a disk of ``share`` of its equivalent radius
    (:func:`opened`) takes off a region, measured scaled to at most ``radius``;
    None for a region under 30 pixels or one the disk empties."""
    import cv2

    if np.count_nonzero(mask) < 30:
        return None
    box, region = scaled_region(mask, radius)
    body = opened(region, share, by_distance=by_distance)
    if body is None:
        return None
    _, labels, stats, _ = cv2.connectedComponentsWithStats((region & ~body).astype(np.uint8), connectivity=8)
    return Pieces(box, region, body, labels, stats)


def all_round(
    labels: NDArray[np.integer], body: NDArray[np.bool_], pieces: NDArray[np.intp], spread: float
) -> bool:
    """Whether the labelled pieces lie all round the body: the unit vectors from
    the body's centre to theirs average to a resultant shorter than ``spread``
    (lobes or arms of the rock's own shape, not something joined on one side)."""
    angles = piece_angles(labels, body, pieces)
    return bool(abs(np.exp(1j * angles).mean()) < spread)


def piece_angles(
    labels: NDArray[np.integer], body: NDArray[np.bool_], pieces: NDArray[np.intp]
) -> NDArray[np.float64]:
    """The direction, in radians, from the body's centre to each labelled piece's centre."""
    rows, cols = np.indices(labels.shape)
    flat = labels.ravel()
    size = np.maximum(np.bincount(flat), 1)
    row_sums = np.bincount(flat, weights=rows.ravel())
    col_sums = np.bincount(flat, weights=cols.ravel())
    body_rows, body_cols = np.nonzero(body)
    return np.arctan2(
        row_sums[pieces] / size[pieces] - body_rows.mean(),
        col_sums[pieces] / size[pieces] - body_cols.mean(),
    )


def cut_back(
    mask: NDArray[np.bool_], box: tuple[int, int, int, int], cut: NDArray[np.bool_]
) -> NDArray[np.bool_]:
    """The largest part of ``mask`` left once ``cut`` is off; ``cut`` is drawn on
    :func:`scaled_region`'s scaled, padded region of ``box`` (``mask`` itself
    when nothing is left)."""
    import cv2

    r0, r1, c0, c1 = box
    cut = cut[2:-2, 2:-2]
    if cut.shape != (r1 - r0, c1 - c0):
        cut = cv2.resize(cut.astype(np.float32), (c1 - c0, r1 - r0), interpolation=cv2.INTER_LINEAR) >= 0.5
    kept = mask.copy()
    kept[r0:r1, c0:c1] &= ~cut
    part = largest_part(kept)
    return mask if part is None else part


def largest_part(mask: NDArray[np.bool_] | NDArray[np.uint8]) -> NDArray[np.bool_] | None:
    """The largest 4-connected part of a mask, or None when the mask is empty."""
    import cv2

    count, labels, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=4)
    if count < 2:
        return None
    return labels == 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))


def rejoined(parts: list[NDArray[np.bool_]], convex: float = CONVEX_CELL) -> list[NDArray[np.bool_]]:
    """Parts that touch and together are convex joined again, the most convex pair first.

    The contrast cue cuts a rock along a shading line or a vein as readily as
    two rocks along the ground between them, when the cut is judged within
    one region. Across the regions of a whole scene the shape tells them
    apart: touching rocks leave notches where they meet, and two pieces of
    one rock make a convex whole (solidity at least ``convex``).

    Parameters
    ----------
    parts : list of (rows, cols) ndarray of bool
        Disjoint masks on one grid.
    convex : float
        Solidity from which two touching parts are one (``CONVEX_CELL``).

    Returns
    -------
    list of (rows, cols) ndarray of bool
        The parts, those joined in place of the first of each pair.
    """
    parts = list(parts)
    # Each part's token names it while it lasts, so that a pair's solidity is
    # measured once, not again after every join elsewhere.
    tokens = list(range(len(parts)))
    solidities: dict[tuple[int, int], float] = {}
    while len(parts) > 1:
        best = None
        for a, b in touching_pairs(label_image(parts)).tolist():
            pair = (tokens[a - 1], tokens[b - 1])
            if pair not in solidities:
                union = parts[a - 1] | parts[b - 1]
                r0, r1, c0, c1 = bounding_box(union)
                solidities[pair] = solidity(union[r0:r1, c0:c1])
            if solidities[pair] >= convex and (best is None or solidities[pair] > best[0]):
                best = (solidities[pair], a, b)
        if best is None:
            break
        _, a, b = best
        parts[a - 1] = parts[a - 1] | parts[b - 1]
        tokens[a - 1] = max(tokens) + 1
        del parts[b - 1], tokens[b - 1]
    return parts


def label_image(parts: list[NDArray[np.bool_]]) -> NDArray[np.int32]:
    """Parts on one grid as labels 1..n in list order (0 elsewhere); where parts
    overlap, the first keeps the pixel."""
    labels = np.zeros(parts[0].shape, np.int32)
    for i, part in enumerate(parts, start=1):
        labels[part & (labels == 0)] = i
    return labels


def territories(regions: list[NDArray[np.bool_]]) -> NDArray[np.int32]:
    """Every pixel given to the nearest region (1-based labels, in list order).

    A rock's outline, traced later on a finer image, must not run into a
    neighbour it touches: it is kept to its territory.
    """
    if not regions:
        raise ValueError("territories of no region")
    labels = label_image(regions)
    if len(regions) == 1:
        return np.ones_like(labels)
    return nearest_regions(labels)[1]


def nearest_regions(labels: NDArray[np.integer]) -> tuple[NDArray[np.float32], NDArray[np.int32]]:
    """Each pixel's distance to the nearest region and that region's label.

    Parameters
    ----------
    labels : (rows, cols) ndarray of int
        0 for ground, positive labels for regions (at least one).

    Returns
    -------
    distance : (rows, cols) ndarray of float32
        Euclidean distance to the nearest region's pixel (0 on the regions).
    nearest : (rows, cols) ndarray of int32
        That region's label: the regions' Voronoi cells.
    """
    import cv2

    # OpenCV labels each ground pixel by its nearest zero pixel; those are
    # mapped back to the regions.
    distance, nearest = cv2.distanceTransformWithLabels(
        (labels == 0).astype(np.uint8), cv2.DIST_L2, 5, labelType=cv2.DIST_LABEL_PIXEL
    )
    owner = np.zeros(int(nearest.max()) + 1, np.int32)
    owner[nearest[labels > 0]] = labels[labels > 0]
    return distance, owner[nearest]


def _contrast_cells(
    values: NDArray[np.float32], region: NDArray[np.bool_], floor: float
) -> NDArray[np.int32]:
    """Basins of the contrast's maxima, joined across high passes (module docstring, cue 1)."""
    return _flood_and_join(
        values,
        region & (values > floor),
        region,
        lambda height, lower, cut, smaller: (
            height - floor >= PASS_SHARE * (lower - floor) or _long_cut(cut, smaller)
        ),
    )


def split_necks(
    cell: NDArray[np.bool_],
    min_area: float,
    *,
    neck_share: float = NECK_SHARE,
    cut_share: float = CUT_SHARE,
) -> list[NDArray[np.bool_]]:
    """A mask cut at narrow necks between compact blobs (module docstring, cue 2).

    Parameters
    ----------
    cell : (rows, cols) ndarray of bool
    min_area : float
        Smallest part, in pixels.
    neck_share, cut_share : float
        A neck at least ``neck_share`` of the smaller blob's inscribed radius
        joins two blobs, and so does a border at least ``cut_share`` of the
        smaller part's equivalent diameter (``NECK_SHARE``, ``CUT_SHARE``).

    Returns
    -------
    list of (rows, cols) ndarray of bool
        The parts; ``[cell]`` when it is one blob.
    """
    import cv2

    dist = cv2.distanceTransform(np.pad(cell, 1).astype(np.uint8), cv2.DIST_L2, 5)[1:-1, 1:-1]
    labels = _flood_and_join(
        dist,
        cell & (dist >= MIN_PEAK),
        cell,
        lambda height, lower, cut, smaller: (
            height >= neck_share * lower or _long_cut(cut, smaller, cut_share)
        ),
    )
    parts = [labels == i for i in range(1, int(labels.max()) + 1)]
    parts = [p for p in parts if np.count_nonzero(p) >= min_area]
    return parts if len(parts) > 1 else [cell]


def _filled(mask: NDArray[np.bool_], largest: float) -> NDArray[np.bool_]:
    """The mask with its holes smaller than ``largest`` pixels filled: dark relief
    on a light rock is no neck, the ground enclosed by a ring of rocks stays."""
    import cv2

    _, labels, stats, _ = cv2.connectedComponentsWithStats((~mask).astype(np.uint8), connectivity=4)
    small = stats[:, cv2.CC_STAT_AREA] < largest
    # Holes touch no edge of the window (its first row and column are outside the region).
    small[labels[0, 0]] = False
    return mask | small[labels]


def _long_cut(cut: float, smaller: float, share: float = CUT_SHARE) -> bool:
    """Whether a border of ``cut`` pixels runs across a part of ``smaller`` pixels (``share``: CUT_SHARE)."""
    return cut >= share * math.sqrt(4.0 * smaller / math.pi)


def _flood_and_join(
    values: NDArray[np.float32],
    allowed: NDArray[np.bool_],
    region: NDArray[np.bool_],
    join: Callable[[float, float, float, float], bool],
) -> NDArray[np.int32]:
    """Watershed of ``values`` from its local maxima within ``allowed``, basins joined across passes.

    Two neighbouring basins are joined, from the highest pass down as a flood
    would join them (a component tree), when ``join(pass, lower top, cut,
    smaller area)`` holds: the lower top and the smaller area are those of the
    two sides as joined so far, the cut the length of their border. Returns labels
    1..n over ``region``, 0 elsewhere.
    """
    import cv2
    from skimage.segmentation import watershed

    peaks = (values >= cv2.dilate(values, np.ones((3, 3), np.uint8))) & allowed
    count, markers = cv2.connectedComponents(peaks.astype(np.uint8), connectivity=8)
    if count <= 2:
        return region.astype(np.int32)
    basins = watershed(-values, markers, mask=region).astype(np.int32)
    top = label_maxima(values, basins, count)
    # Passes between 4-neighbours of different basins: the lower of the two
    # pixels; a pair's pass is the highest such value along their border.
    pairs, heights = [], []
    for a, b, va, vb in (
        (basins[:, :-1], basins[:, 1:], values[:, :-1], values[:, 1:]),
        (basins[:-1], basins[1:], values[:-1], values[1:]),
    ):
        border = (a != b) & (a > 0) & (b > 0)
        lo, hi = np.minimum(a[border], b[border]), np.maximum(a[border], b[border])
        pairs.append(lo.astype(np.int64) * count + hi)
        heights.append(np.minimum(va[border], vb[border]))
    keys, height = np.concatenate(pairs), np.concatenate(heights)
    if keys.size == 0:
        return basins
    order = np.argsort(keys, kind="stable")
    keys, height = keys[order], height[order]
    starts = np.flatnonzero(np.r_[True, keys[1:] != keys[:-1]])
    passes = np.maximum.reduceat(height, starts)
    cuts = np.diff(np.r_[starts, keys.size])
    keys = keys[starts]
    parent = np.arange(count)
    area = np.bincount(basins.ravel(), minlength=count).astype(np.float64)

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for k in np.argsort(-passes, kind="stable"):
        i, j = root(int(keys[k] // count)), root(int(keys[k] % count))
        if i != j and join(float(passes[k]), min(top[i], top[j]), float(cuts[k]), min(area[i], area[j])):
            parent[j] = i
            top[i] = max(top[i], top[j])
            area[i] += area[j]
    roots = np.array([root(i) for i in range(count)])
    # Basin 0 (outside the region) is its own root and keeps label 0.
    _, relabel = np.unique(roots, return_inverse=True)
    return relabel.astype(np.int32)[basins]
