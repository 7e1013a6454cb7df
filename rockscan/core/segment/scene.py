"""Every rock of a photo (``segment(..., all_rocks=True)``, ``rockscan classify --all``).

Each channel's detection is outlined on one working image (:class:`rockscan.core.segment.outliner.Outliner`);
a later channel's rocks count where no earlier rock lies. Rocks are parted by
the cues of blobs, colours, seams and pockets (``rockscan.core.segment.split``),
dimmer rocks left over under a brighter one's level are outlined at their own,
pieces of one rock are joined and touching rocks parted by the learnt join
(``rockscan.core.segment.join``), specks and patches of the ground's colour are
dropped, and rocks of the ground's own colour are found by their rims
(``rockscan.core.segment.ringed``). The steps and their
measured effect are in ``rockscan.core.segment``'s module docstring (step 5)
and ``docs/segment-algorithm.md``.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numpy.typing import NDArray

from rockscan.core.segment import join
from rockscan.core.segment.channels import _LUMA, _channels, _unit, cielab
from rockscan.core.segment.detect import _detect, _Detection
from rockscan.core.segment.outliner import Outliner, assemble, cropped
from rockscan.core.segment.ringed import lab_gradient, ringed_regions
from rockscan.core.segment.split import (
    CONVEX_CELL,
    largest_part,
    nearest_regions,
    split_blobs,
    split_colours,
    split_pockets,
    split_seams,
    territories,
)
from rockscan.core.segment.stats import solidity
from rockscan.core.segment.trace import _disk, _fill_holes, _scored
from rockscan.core.segment.types import RockMask, Segmentation, SegmentConfig

__all__ = ["rocks_of_every_channel"]


def rocks_of_every_channel(
    small: NDArray[np.float32], outline: Outliner, config: SegmentConfig
) -> Segmentation | None:
    """Every rock of a photo (``all_rocks``; ``rockscan.core.segment``'s module docstring,
    step 5), or None.

    The rocks of the first channel that shows any, and those of a later
    channel (chromaticity after luminance, then the distance from the
    ground's hue) that lie where no earlier rock is: a rock that differs from
    its ground in hue only is no rock to luminance, and a scene can hold both
    kinds, in hues on every side of the ground's. Every channel's rocks are outlined on
    one working image, at the scale the smallest of them asks for.
    """
    detections = []
    for channel in _channels(small, every_hue=True):
        # A rock lies farther from the ground's hue than the ground, whatever
        # its brightness: a polarity set for brightness is no polarity of hue.
        own = dataclasses.replace(config, polarity="light") if channel.name == "hue" else config
        detection = _detect(channel.values(small), channel, own, True)
        if detection is not None:
            detections.append(detection)
    if not detections:
        return None
    scale = min(outline.work_scale(d) for d in detections)
    found: list[Segmentation] = []
    rocks: list[RockMask] = []
    first, taken = None, None
    for detection in detections:
        if taken is not None and detection.channel.name == "hue":
            detection = _unseen(detection, taken, outline, found[0])
            if detection is None:
                continue
        edge = LIGHT_EDGE if detection.polarity == "light" else 0.5
        made = outline(detection, work_scale=scale, edge=edge)
        if made is None:
            continue
        parted = _parted(made, outline.works[id(made)][0], outline.dtype)
        if first is None or taken is None:
            first = parted
            rocks = list(first.rocks)
            taken = first.labels > 0
        else:
            _add_where_free(parted.rocks, rocks, taken)
        found.append(made)
        # A rock may lie in a region under the level its outline was drawn at
        # (a dimmer rock touching brighter ones): what no outline took, where
        # it makes a rock of its own, is outlined at its own level.
        left = _left_over(detection, taken, outline, found[0], rocks)
        more = None if left is None else outline(left, work_scale=scale, edge=edge)
        if more is not None:
            _add_where_free(_parted(more, outline.works[id(more)][0], outline.dtype).rocks, rocks, taken)
    if first is None:
        return None
    # Pieces of one rock are joined before specks are judged: a small piece then
    # joins its rock rather than being dropped.
    rocks = _two_rocks_parted(_pieces_joined(rocks, outline, found[0]), outline, found[0])
    # Specks are judged against the largest rock once every outline is cut into
    # its rocks: before, the largest region may be a cluster of touching rocks.
    largest = max(r.area for r in rocks)
    kept = [r for r in rocks if r.area >= config.min_relative_area * largest]
    # Among several rocks, a region much smaller than the typical one is a
    # piece of a textured rock or ground between rocks far more often than a
    # rock of its own (development crowded scenes 0-199: of the regions under
    # a fifth of the median, 62 pieces and 21 patches of ground, 3 rocks).
    if len(kept) >= MEDIAN_LEAST:
        median = float(np.median([r.area for r in kept]))
        kept = [r for r in kept if r.area >= config.min_median_area * median]
    if len(kept) >= MEDIAN_LEAST:
        work = outline.works[id(found[0])][0]
        colour = cielab(_unit(work[..., :3] if work.ndim == 3 else work, outline.dtype))
        kept = _unlike_ground(kept, colour)
        # A rock of the ground's own colour stands out in no channel, only by its rim.
        kept.extend(_ringed(kept, colour, outline, found[0]))
    if len(kept) == len(rocks) == len(first.rocks):
        return first
    return assemble(kept, first.labels.shape, first.scale_rowcol, first.polarity, first.channel)


def _ringed(
    rocks: list[RockMask], colour: NDArray[np.float32], outline: Outliner, found: Segmentation
) -> list[RockMask]:
    """The rocks a closed ring of edge outlines in the ground the others leave
    (``rockscan.core.segment.ringed``; ``colour`` the working image in
    CIELAB), each scored on its outline."""
    work, up, detection = outline.works[id(found)]
    labels = assemble(rocks, work.shape[:2], found.scale_rowcol, found.polarity, found.channel).labels
    regions = ringed_regions(lab_gradient(colour), labels, outline.config.min_median_area)
    if not regions:
        return []
    to_detect = outline.to_detect(work.shape[:2], up)
    out = []
    for region in regions:
        whole = RockMask(mask=region, coverage=region.astype(np.float32), origin_rowcol=(0, 0))
        out.append(_scored(work, outline.dtype, cropped(whole), to_detect, up, detection, outline.config))
    return out


def _unlike_ground(rocks: list[RockMask], colour: NDArray[np.float32]) -> list[RockMask]:
    """The rocks less those whose colour lies as near their ground's as the ground's own patches do.

    Among several rocks, a region whose median colour (``colour``, the
    working image in CIELAB: ``channels.cielab``) lies closer to the ground's round it than
    ``GROUND_LIKE`` of the median rock's distance is a patch of ground
    between rocks, lit or shaded differently from the rest, far more often
    than a rock. Each region's ground is the free ground within
    ``GROUND_REACH`` of its equivalent radius (light and shade vary across a
    frame), or, where rocks hem it in, all the free ground; free ground lies
    off every rock by a margin.
    """
    import cv2

    owner = np.zeros(colour.shape[:2], np.int32)
    for index, rock in enumerate(rocks, start=1):
        owner[rock.window][rock.mask] = index
    taken = (owner > 0).astype(np.uint8)
    free = cv2.dilate(taken, np.ones((2 * GROUND_MARGIN + 1,) * 2, np.uint8)) == 0
    if np.count_nonzero(free) < GROUND_LEAST * free.size:
        return rocks
    # Each free pixel is ground to its nearest rock: one transform for them all.
    gap, nearest = nearest_regions(owner)
    areas = np.array([rock.area for rock in rocks], np.float64)
    reach = GROUND_REACH * np.sqrt(areas / math.pi) + GROUND_MARGIN
    ground = free.copy()
    ground[free] = gap[free] <= reach[nearest[free] - 1]
    whose = nearest[ground] - 1
    values = colour[ground]
    order = np.argsort(whose, kind="stable")
    bounds = np.searchsorted(whose[order], np.arange(len(rocks) + 1))
    distance = np.empty(len(rocks))
    everywhere = None
    for index, rock in enumerate(rocks):
        own = values[order[bounds[index] : bounds[index + 1]]]
        # Hemmed in by rocks, a region's ground is all the free ground.
        if 2 * len(own) < areas[index]:
            if everywhere is None:
                everywhere = np.median(colour[free], axis=0)
            own = everywhere[None, :]
        level = np.median(own, axis=0)
        distance[index] = np.linalg.norm(np.median(colour[rock.window][rock.mask], axis=0) - level)
    typical = float(np.median(distance))
    if typical <= 0.0:
        return rocks
    return [rock for rock, far in zip(rocks, distance, strict=True) if far >= GROUND_LIKE * typical]


#: Least share of the median rock's distance from the ground's colour
#: (:func:`_unlike_ground`) at which a region among several counts as a rock.
#: Chosen on the development crowded scenes 4000-4159 (exact counts 63 of 160
#: before; 67, 73 and 73 at 0.3, 0.35 and 0.4; rocks one to one 3,016 of
#: 3,248 before, 3,014, 3,012 and 3,012) and checked on scenes 4160-4319
#: (62 -> 68, 2,946 -> 2,945 of 3,185) and 4320-4479 (70 -> 70, five right
#: and five wrong; 3,061 -> 3,058 of 3,352). What goes wrong is a rock of
#: nearly the ground's colour among rocks of strong colours.
GROUND_LIKE = 0.35
#: How far round a region its ground's colour is read, in its equivalent
#: radii (twice as far: the same counts within one scene a block).
GROUND_REACH = 1.0
#: Pixels round every rock left out of the ground's colour: its blurred edge.
GROUND_MARGIN = 3
#: Least share of the working image left for the ground's colour to be read.
GROUND_LEAST = 0.05


def _add_where_free(new: list[RockMask], rocks: list[RockMask], taken: NDArray[np.bool_]) -> None:
    """Append to ``rocks`` what of each new rock is free (``_where_free``), and mark it ``taken``."""
    for rock in new:
        part = _where_free(rock, taken)
        if part is not None:
            rocks.append(part)
            taken |= part.whole(taken.shape)


def _taken_on_detection(
    shape: tuple[int, int], taken: NDArray[np.bool_], outline: Outliner, found: Segmentation
) -> NDArray[np.bool_]:
    """The detection pixels (of a detection image of ``shape``) more than half
    of whose working pixels (``found``'s working grid) are ``taken``."""
    work, up, _ = outline.works[id(found)]
    to_row, to_col = outline.to_detect(work.shape[:2], up)
    cells = (to_row[:, None] * shape[1] + to_col[None, :]).ravel()
    counts = np.bincount(cells, minlength=shape[0] * shape[1])
    hits = np.bincount(cells, weights=taken.ravel(), minlength=shape[0] * shape[1])
    return (hits > 0.5 * np.maximum(counts, 1)).reshape(shape)


def _left_over(
    detection: _Detection,
    taken: NDArray[np.bool_],
    outline: Outliner,
    found: Segmentation,
    rocks: list[RockMask],
) -> _Detection | None:
    """The parts of the detection's regions that no rock took and that make a
    rock of their own, as a detection whose neighbours are the rocks taken;
    None if there are none.

    A part counts when it is at least ``LEFT_AREA`` of the median rock found so
    far, round (the disk inscribed in it at least ``LEFT_ROUND`` of the radius
    of a disk of its area) and solid (``LEFT_SOLIDITY``): the rim a rock's
    outline left out is a crescent along it, a piece of ground between rocks
    is ragged.
    """
    import cv2

    if not rocks:
        return None
    shape = detection.regions[0].shape
    seen = _taken_on_detection(shape, taken, outline, found)
    # An opening by a pixel parts what touches only along a thread.
    left = np.logical_or.reduce(detection.regions) & ~seen
    left = cv2.morphologyEx(left.astype(np.uint8), cv2.MORPH_OPEN, _disk(1))
    _, labels, stats, _ = cv2.connectedComponentsWithStats(left, connectivity=4)
    _, up, _ = outline.works[id(found)]
    least = LEFT_AREA * float(np.median([r.area for r in rocks])) / (up[0] * up[1])
    parts = []
    for index in np.flatnonzero(stats[1:, cv2.CC_STAT_AREA] >= least) + 1:
        part = labels == index
        inscribed = cv2.distanceTransform(np.pad(part, 1).astype(np.uint8), cv2.DIST_L2, 5).max()
        area = float(stats[index, cv2.CC_STAT_AREA])
        if inscribed >= LEFT_ROUND * math.sqrt(area / math.pi) and solidity(part) >= LEFT_SOLIDITY:
            parts.append(part)
    if not parts:
        return None
    return dataclasses.replace(detection, regions=parts, others=[seen])


#: A part of a detected region that no rock took is a rock of its own
#: (:func:`_left_over`) when its area is at least this share of the median
#: rock's, ...
LEFT_AREA = 0.3
#: ... the disk inscribed in it has at least this share of the radius of a
#: disk of its area ...
LEFT_ROUND = 0.7
#: ... and its solidity is at least this. Chosen on the development crowded
#: scenes 0-199 (exact counts 82 -> 84 of 200, one to one 93.63% -> 93.77%;
#: 84 and 93.79% at an inscribed share of 0.75, 82 and 94.07% at 0.5, where
#: more rims a rock's outline left out count as rocks) and checked on scenes
#: 600-799 (85 -> 86, 92.15% -> 92.55%).
LEFT_SOLIDITY = 0.9


def _unseen(
    detection: _Detection, taken: NDArray[np.bool_], outline: Outliner, found: Segmentation
) -> _Detection | None:
    """The detection with only the regions that lie mostly where no rock is yet
    (``taken``, on ``found``'s working grid), or None if none does; the others
    stay as neighbours that bound the territories of the rest.

    The distance from the ground's hue sees most rocks that brightness or the
    principal hue already outlined: outlining them again costs as much as
    finding them, only for each to be dropped as taken.
    """
    seen = _taken_on_detection(detection.regions[0].shape, taken, outline, found)
    new, old = [], []
    for region in detection.regions:
        inside = np.count_nonzero(region & seen)
        (old if inside > UNSEEN_SHARE * np.count_nonzero(region) else new).append(region)
    if not new:
        return None
    return dataclasses.replace(detection, regions=new, others=detection.others + old)


#: With ``all_rocks``, how far from the ground's level to a light rock's its
#: outline is drawn (0.5 for dark rocks and one rock). A light rock lit from
#: one side turns its far side from the light, and that side falls to the
#: ground's level or below: half-way leaves it out, and a rock whose shaded
#: side is a good part of it is found too small or in pieces. Chosen on the
#: development crowded scenes 0-199 (exact counts 81, 82, 82, 79 and 83 of 200
#: at 0.5, 0.42, 0.35, 0.3 and 0.25; rocks one to one 93.27%, 93.31%, 93.66%,
#: 93.61% and 93.61%; merges 67, 71, 70, 78 and 81); for dark rocks as well at
#: 0.35, 92.90% (merges 89), at 0.45, 80 exact and 93.61% (merges 80): a dark
#: rock's lit face is as often a neighbour's.
LIGHT_EDGE = 0.35


#: Largest share of a region of the hue's detection that may lie where a rock
#: is already outlined for it to be outlined itself (``FREE_SHARE`` keeps a
#: rock only where at least 0.8 of its outline is free).
UNSEEN_SHARE = 0.9


def _scene_grids(
    rocks: list[RockMask], outline: Outliner, found: Segmentation
) -> tuple[NDArray[np.int32], list[RockMask], NDArray[np.float32]]:
    """The rocks as labels on the working grid, the rocks in label order, and
    the working image's brightness: what the join reads of a scene."""
    work = outline.works[id(found)][0]
    labels = assemble(rocks, work.shape[:2], found.scale_rowcol, found.polarity, found.channel).labels
    ordered = sorted(rocks, key=lambda r: -r.area)  # assemble's label order
    unit = _unit(np.ascontiguousarray(work[..., :3] if work.ndim == 3 else work), outline.dtype)
    return labels, ordered, unit @ _LUMA if unit.ndim == 3 else unit


def _two_rocks_parted(rocks: list[RockMask], outline: Outliner, found: Segmentation) -> list[RockMask]:
    """The rocks with every large region that is two rocks cut in two
    (``join.parted``); each half keeps the coverage of its territory and the
    score of the outline it was cut from."""
    if len(rocks) < 2:
        return rocks
    labels, ordered, gray = _scene_grids(rocks, outline, found)
    cuts = join.parted(labels, gray)
    if not cuts:
        return rocks
    out = []
    for index, rock in enumerate(ordered, start=1):
        if index not in cuts:
            out.append(rock)
            continue
        half = cuts[index][rock.window] & rock.mask
        out.extend(_pieces(rock, [rock.mask & ~half, half]))
    return out


def _pieces_joined(rocks: list[RockMask], outline: Outliner, found: Segmentation) -> list[RockMask]:
    """The rocks with pieces of one rock joined (``rockscan.core.segment.join``),
    each joined rock scored anew on its whole outline."""
    if len(rocks) < 2:
        return rocks
    work, up, detection = outline.works[id(found)]
    labels, ordered, gray = _scene_grids(rocks, outline, found)
    owner = join.joined(labels, gray)
    if np.array_equal(owner, np.arange(owner.size)):
        return rocks
    to_detect = outline.to_detect(work.shape[:2], up)
    out = []
    for head in np.unique(owner[1:]):
        group = [ordered[k - 1] for k in np.flatnonzero(owner == head)]
        if len(group) == 1:
            out.append(group[0])
            continue
        rock = cropped(_union(group, work.shape[:2]))
        out.append(_scored(work, outline.dtype, rock, to_detect, up, detection, outline.config))
    return out


def _union(rocks: list[RockMask], shape: tuple[int, int]) -> RockMask:
    """Touching rocks as one: their masks joined and holes filled, the coverage
    of each kept at the outer edge and full along the contacts between them."""
    import cv2

    r0 = min(r.origin_rowcol[0] for r in rocks)
    c0 = min(r.origin_rowcol[1] for r in rocks)
    r1 = max(r.origin_rowcol[0] + r.mask.shape[0] for r in rocks)
    c1 = max(r.origin_rowcol[1] + r.mask.shape[1] for r in rocks)
    # A pixel of margin round the window, so that the filled mask's edge can be eroded.
    r0, c0, r1, c1 = max(r0 - 1, 0), max(c0 - 1, 0), min(r1 + 1, shape[0]), min(c1 + 1, shape[1])
    mask = np.zeros((r1 - r0, c1 - c0), bool)
    coverage = np.zeros(mask.shape, np.float32)
    for rock in rocks:
        o0, o1 = rock.origin_rowcol[0] - r0, rock.origin_rowcol[1] - c0
        h, w = rock.mask.shape
        mask[o0 : o0 + h, o1 : o1 + w] |= rock.mask
        np.maximum(coverage[o0 : o0 + h, o1 : o1 + w], rock.coverage, out=coverage[o0 : o0 + h, o1 : o1 + w])
    mask = _fill_holes(mask)
    inner = cv2.erode(mask.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    coverage[inner] = 1.0
    return RockMask(mask=mask, coverage=coverage, origin_rowcol=(r0, c0))


#: Fewest rocks whose median area ``SegmentConfig.min_median_area`` is judged against.
MEDIAN_LEAST = 3
#: Least share of a later channel's rock that must lie where no earlier rock
#: is for it to count. Chosen on the development crowded scenes, where 0.8 and
#: 0.95 find the same rocks within 0.2% of them; what overlaps more is a rock
#: already found, outlined again.
FREE_SHARE = 0.8


def _where_free(rock: RockMask, taken: NDArray[np.bool_]) -> RockMask | None:
    """The rock less what ``taken`` holds, if at least ``FREE_SHARE`` of it is free; else None."""
    free = ~taken[rock.window]
    if float(np.count_nonzero(rock.mask & free)) < FREE_SHARE * float(np.count_nonzero(rock.mask)):
        return None
    mask = largest_part(rock.mask & free)
    if mask is None:
        return None
    # Its outline stops where the earlier rock begins.
    return dataclasses.replace(rock, mask=mask, coverage=(rock.coverage * free).astype(np.float32))


def _parted(found: Segmentation, work: NDArray[np.generic], dtype: np.dtype) -> Segmentation:
    """Every outlined rock that is several rocks round pockets of ground
    (``split.split_pockets``; outlines of at least ``POCKET_LARGE`` times the
    median's area), several compact blobs (``split.split_blobs``), several
    rocks of clearly different colours (``split.split_colours``; colour
    photos), or several rocks with dark seams between them
    (``split.split_seams``), cut into them.

    A part keeps the coverage of its territory within the rock's window and
    the score of the outline it was cut from.
    """
    large = POCKET_LARGE * float(np.median([rock.area for rock in found.rocks])) if found.rocks else 0.0
    rocks = []
    for rock in found.rocks:
        pieces = [rock]
        if len(found.rocks) > 1 and rock.area >= large:
            pieces = _pieces(rock, split_pockets(rock.mask, _work_window(work, rock, dtype)))
        for piece in pieces:
            rocks.extend(_cut(piece, work, dtype))
    if len(rocks) == len(found.rocks):
        return found
    return assemble(rocks, found.labels.shape, found.scale_rowcol, found.polarity, found.channel)


#: An outline at least this many times the median outline's area (with
#: ``--all``) is looked at for pockets of ground: it may be a cluster of
#: rocks. Chosen on the development crowded scenes 0-199 (rocks one to one,
#: of 4,366: 91.2% from 1.5 times the median, 91.3% from 2, 91.2% from 2.5;
#: rocks split into pieces 253, 237 and 229).
POCKET_LARGE = 2.0


def _cut(rock: RockMask, work: NDArray[np.generic], dtype: np.dtype) -> list[RockMask]:
    """The rock cut by the cues of blobs, colours and seams (:func:`_parted`), or ``[rock]``."""
    # Every cue leaves a convex outline whole: most rocks need no window of the photo.
    if solidity(rock.mask) >= CONVEX_CELL:
        return [rock]
    parts = split_blobs(rock.mask)
    window = _work_window(work, rock, dtype)
    if work.ndim == 3:
        parts = [piece for part in parts for piece in split_colours(part, window)]
    gray = window @ _LUMA if window.ndim == 3 else window
    parts = [piece for part in parts for piece in split_seams(part, gray)]
    return _pieces(rock, parts)


def _work_window(work: NDArray[np.generic], rock: RockMask, dtype: np.dtype) -> NDArray[np.float32]:
    """The working image under a rock's window, in [0, 1] (colour or brightness)."""
    window = work[rock.window]
    return _unit(np.ascontiguousarray(window[..., :3] if window.ndim == 3 else window), dtype)


def _pieces(rock: RockMask, parts: list[NDArray[np.bool_]]) -> list[RockMask]:
    """The rock's parts as rocks, each with the coverage of its territory; ``[rock]`` for one part."""
    if len(parts) == 1:
        return [rock]
    owners = territories(parts)
    return [
        dataclasses.replace(rock, mask=part, coverage=(rock.coverage * (owners == index)).astype(np.float32))
        for index, part in enumerate(parts, start=1)
    ]
