"""Photo -> rock masks.

The rock is found on a small copy of the photo, then outlined on a larger one
by a threshold half-way between the rock's level and the ground's. Every step
is a function of arrays.

Steps (see :func:`segment`):

1. **Sizes.** The photo is halved by area averaging as often as needed, then
   resized once more, to a detection image whose longer side is at most
   ``detect_size`` pixels (rocks are found there) and, after detection, to a
   working image (rocks are outlined there) on which the smallest rock found
   spans about ``outline_radius`` pixels, with a longer side of at most
   ``work_size`` and never coarser than the detection image. Time and memory
   are bounded for any photo size.
2. **Channel.** Luminance. Only if it shows no rock, the first principal
   component of the chromaticity ``rgb / (r + g + b)`` (a rock of another hue
   than its ground but of the same brightness); with ``all_rocks`` every
   channel, and last the distance of each pixel's chromaticity from the
   ground's (the median along the frame's border), which sees rocks of any
   hue, where the projection sees one side of one direction. An alpha channel that really
   cuts the rock out (5% to 98% of the frame transparent) is used directly.
3. **Lighting.** After a median filter and a Gaussian of ``detect_sigma``
   (sensor noise, JPEG blocks, fine texture), a polynomial surface of degree
   ``lighting_degree`` is fitted to the ground by least squares, leaving out
   pixels beyond 2.5 robust standard deviations of the fit: first to a band
   along the frame's border, where the rock is not, then ``iterations`` times
   to every pixel that is not part of a rock nor beyond ``z_grow`` from the
   ground. From the second round on, what the polynomial misses (a dark
   corner, a bright patch) is added as the ground's residual spread by a
   normalised Gaussian ``lighting_sigma`` of the longer side wide. Luminance
   is divided by the lighting (light multiplies reflectance); chromaticity,
   which light does not change, has it subtracted.
4. **Regions.** Each pixel's deviation from the ground is measured in robust
   standard deviations ``z`` (median and MAD of the ground pixels, the MAD
   taken as at least ``min_contrast / z_detect``, so that on a smooth ground
   noise and JPEG blocks are no rock). When no region stands out so, in any
   round, the MAD is taken as the median of the ground's MAD in the cells of
   an 8 x 8 grid, if smaller: neighbours reaching into a crop, or a ground
   whose texture varies across the frame, widen the whole ground's. A region
   grows from pixels beyond ``z_detect`` through connected pixels beyond
   ``z_grow`` (hysteresis), lighter or darker than the ground; regions smaller
   than ``min_area_fraction`` of the frame (pebbles, specks) are dropped.
5. **Choice of rock.** A region scores its area, times its edge step (mean
   ``z`` just inside its edge less just outside; a rock's edge is a step as
   high as its contrast, a blob of texture fades out), times its compactness
   ``4 pi area / perimeter**2`` (the ground between several rocks has a long
   ragged edge), times ``(1 - s)**2`` where ``s`` is the share of its edge
   that runs along the frame's (a rock lies inside the frame). The **main
   rock** is the region of highest score over both polarities; the photo's
   polarity is that of its main rock, whether the ground is lighter or darker
   (with ``all_rocks``, that of the rocks which together score most).
   A region whose contrast has two clear levels (Otsu's separation above 0.8:
   a rock and a faint halo, or rocks joined through the ground between them)
   is cut at Otsu's threshold, and its largest part kept. With ``all_rocks``,
   a region of the main rock's polarity is a rock if it looks as much like one
   per pixel as the best regions do (its score over its area at least half
   the median of the five best-scoring regions', and its median ``z`` beyond
   ``z_detect``) or scores at least a tenth of the main rock; and if less
   than half its edge runs along the frame's. A small rock so counts as well
   as a large one, and a band of ground that outscores every rock does not
   set the standard alone. Each is cut so, and so are the outlines below;
   then every rock whose area is at least ``min_relative_area`` of the
   largest rock's and, among three or more, ``min_median_area`` of the
   median rock's is kept, by decreasing area.
   Rocks of a later channel (chromaticity, after luminance) are added where
   they lie mostly (``FREE_SHARE``) outside every rock found before: a scene
   can hold rocks that differ from the ground in brightness and others that
   differ in hue only. After each channel, what of its regions no outline
   took, where it makes a round, solid part of a rock's size, is outlined at
   its own level (``_left_over``): a dimmer rock touching brighter ones grows
   into their region and lies under the level their outlines are drawn at.
   In a colour photo, an outline that is not convex and holds two clearly
   different colours, each in one piece, is cut between them
   (``split.split_colours``): touching rocks of different hues. An outline
   that is not convex and has a dark seam across it from end to end is cut
   along it (``split.split_seams``): touching rocks of one colour.
   Before those, an outline of at least ``POCKET_LARGE`` times the median
   outline's area that encloses pockets of the ground's colour is cut at
   its necks round them (``split.split_pockets``): rocks that touch round a
   patch of ground. Once every outline is cut, and before specks are
   judged, touching regions that are likely pieces of one rock (a textured
   skin broken along its veins) are joined again, the most probable pair
   first (``rockscan.core.segment.join``), and each joined rock is scored
   on its whole outline; then a large region that is not convex is cut
   between the two peaks of its distance to the ground when the same trees
   see two rocks in its halves (``join.parted``).
6. **Outline.** In a window around each rock, at working size, after a
   ``smooth_sigma`` Gaussian, the rock's level is the median inside the
   detected region (less a margin) and the ground's the median of a ring
   around it, away from other outliers. In gray photos the level is read from
   the flattened brightness; in colour along Fisher's discriminant of the
   flattened brightness and the smoothed hue (red and blue less luminance,
   over the brightness), so that a rock's hue counts as well as its
   brightness, on its shaded side too, and ground texture, which mostly
   varies the ground's brightness, counts less; brightness keeps at least a
   quarter of the step, so that the outline stays near its sharp edge
   rather than the smoothed hue's. Half-way between
   rock and ground is where a blurred step edge lies, whatever the blur.
   Pixels clipped by the sensor on a light rock count as rock. The connected
   part beyond half-way (with ``all_rocks``, beyond ``LIGHT_EDGE`` of the way
   for a light rock, whose side turned from the light falls to the ground's
   level) that overlaps the detection is the rock; its holes
   (texture, glints, engravings) are filled. If it reaches the window's edge,
   the window is widened around it and the step repeated (at most three
   times). If it still reaches it, or its area is under a quarter or over
   four times the detection's, the threshold has failed and the detection
   is kept. Besides the mask, a coverage map rising from 0 to 1
   across the edge lets :func:`rockscan.core.outline.trace_outline` place the
   outline between pixels.
7. **Candidates and choice** (photos of one rock): other cues outline the
   main rock too (``rockscan.core.segment.cues``: GrabCut, the Otsu class
   under the frame's centre, watershed basins; and the outlines opened), and
   a model fitted on the segmentation benchmark's
   development part chooses among them (``rockscan.core.segment.choose``).
   An easy photo stops at its first outline (the fast path): that of the
   region that stood out above all others, scoring at least ``FAST_SCORE``
   (an outline lobed all round, a star's, without its solidity counted),
   and for a rock lighter than its ground, with little darker than the
   ground just outside it (``SHADE_BESIDE``: a shaded side it left out);
   for a dark one, little lighter (``LIT_BESIDE``: a lit face left out
   of a rock's shade taken with its cast shadow).
   Otherwise the detection's own outlines are judged first, by trees
   fitted on such pools; when one is sure (probability
   ``FAST_PROBABILITY``) it stands, and the other cues' outlines, GrabCut
   above all, which cost most, are not made. Unless the choice is sure, a
   candidate inside the chosen outline replaces it when the part it leaves
   out is a cast shadow darker than the rock (``shadow.shadow_left_out``).
   A rock chosen among the whole pool is scored, once its outline is
   final, by how sure that choice is over the photo and by how well the
   offsets of step 12 agree with its outline
   (``rockscan.core.segment.confidence``).
8. **Pebbles and slivers off.** Round pieces that hang off the chosen outline
   at a neck (touching pebbles, which join every cue's region) are cut off
   along their contacts (``rockscan.core.segment.pebbles``); lobes all round
   it are the rock's own shape and stay. Then thin bands that run off the
   outline along a crevice, many times longer than wide and reaching well
   away from the rock's body, are cut off (``rockscan.core.segment.slivers``).
9. **Shadow off.** A cast shadow darker than half-way between the ground and
   a dark rock joins the rock's region; where the photo's log brightness,
   along rays from the rock's centre, rises a second time inside the
   outline (from the rock's shaded rim to the flat, darkened ground of the
   shadow) on one smooth arc away from the rock's lit side, what lies beyond
   that rise is cut off (``rockscan.core.segment.shadow``). Beside a light
   rock that a cue outlined with its shadow, the profile instead falls, last,
   from the rock's rim to a band well darker than the ground that keeps the
   ground's grain; what lies beyond that fall goes the same way.
10. **Rim on.** A light domed rock darkens towards its rim, below the
    ground's level, and the half-way threshold leaves that rim out; where,
    along rays from the rock's centre, the profile falls past the outline
    into a narrow valley darker than the ground and rises again to it, on
    at least 15% of the rays, the outline moves out to the valley's bottom,
    the rock's occluding edge (``rockscan.core.segment.rim``).
11. **Edge.** Unless the fast path took the photo, the outline of a rock
    found in luminance moves, along rays from its centre, to the steepest
    change of brightness within ``snap.REACH`` (1.5) photo pixels, where the
    half-way level missed it by about half that or more (a limb that darkens or
    brightens towards the edge, a neighbour or the ground's gradient beside
    it: ``rockscan.core.segment.snap``). Before the rim: a rim's valley lies
    past the edge's steepest fall.
12. **Offsets.** For a rock chosen among the whole pool of candidates (the
    choice was unsure), the outline moves along rays from its centre by
    what regression trees, fitted on the development part of the
    segmentation benchmark, read from the profile across it: how far the
    truth's edge lay beyond such an outline there. Only moves of a pixel or
    more count, in full from ``offset.MIN_MOVE`` (2) pixels of the working
    grid, up to ``offset.REACH`` (3) (``rockscan.core.segment.offset``).

Known limits: a shadow whose edge with the rock's shaded side the photo does
not show (the two as dark) stays with a dark rock; a light rock's smooth
facet in shade, on a ground as smooth, is cut off like a shadow; a pebble or a patch of
ground as light (or dark) as the rock and touching it joins it; a rock whose
contrast is within about three standard deviations of the ground's texture
may be found only in part; where the sensor clips a light rock its outline
lies up to a blur's width outside; a rock cut by the frame's border is
outlined along the border.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rockscan.core._threads import one_blas_thread
from rockscan.core.errors import NoRockFoundError
from rockscan.core.segment.channels import (
    _LUMA,
    _at_scale,
    _channels,
    _check_pixels,
    _pyramid,
    _unit,
    to_gray,
)
from rockscan.core.segment.choose import choose_ranked, rank
from rockscan.core.segment.confidence import confidence_features, offset_evidence, outline_confidence
from rockscan.core.segment.detect import _detect, _Detection
from rockscan.core.segment.offset import OffsetsRead, moved_by, offsets_read
from rockscan.core.segment.outliner import Outliner, cropped
from rockscan.core.segment.pebbles import lobed, pebbles_off
from rockscan.core.segment.rim import rim_on
from rockscan.core.segment.scene import rocks_of_every_channel
from rockscan.core.segment.score import WEIGHTS, OutlineEvidence, outline_score
from rockscan.core.segment.shadow import MIN_AREA as SHADOW_MIN_AREA
from rockscan.core.segment.shadow import Region, measured_region, shadow_left_out, shadow_off
from rockscan.core.segment.slivers import slivers_off
from rockscan.core.segment.snap import MARGIN as SNAP_MARGIN
from rockscan.core.segment.snap import REACH as SNAP_REACH
from rockscan.core.segment.snap import snapped
from rockscan.core.segment.split import largest_part
from rockscan.core.segment.stats import notch
from rockscan.core.segment.trace import RING, RING_PIXELS, _fill_holes, _from_alpha
from rockscan.core.segment.types import CONFIDENT_SCORE, RockMask, Segmentation, SegmentConfig

__all__ = ["CONFIDENT_SCORE", "RockMask", "SegmentConfig", "Segmentation", "segment", "to_gray"]


@one_blas_thread
def segment(
    pixels: NDArray[np.generic], config: SegmentConfig | None = None, *, all_rocks: bool = False
) -> Segmentation:
    """Find the rock (or rocks) in a photo.

    Parameters
    ----------
    pixels : (rows, cols) or (rows, cols, 1|3|4) ndarray
        The photo, gray or RGB(A), any integer type or float in [0, 1].
    config : SegmentConfig, optional
    all_rocks : bool
        Find every rock, not only the main one.

    Returns
    -------
    Segmentation

    Raises
    ------
    ParameterError
        If ``pixels`` is not a photo (wrong shape, too small, not numbers).
    NoRockFoundError
        If the photo is of one colour or no region stands out from the ground.

    Notes
    -----
    The steps and the rule that picks the main rock are in the module's
    docstring.
    """
    config = config or SegmentConfig()
    found, choice, easy = _chosen(pixels, config, all_rocks=all_rocks)
    if all_rocks:
        return found
    found, features = _completed(found, choice, pixels, easy=easy)
    if features is None:
        return found
    main = dataclasses.replace(found.rocks[0], score=outline_confidence(features))
    return dataclasses.replace(found, rocks=(main, *found.rocks[1:]))


def _completed(
    found: Segmentation,
    choice: NDArray[np.float64] | None,
    pixels: NDArray[np.generic],
    *,
    easy: bool,
) -> tuple[Segmentation, NDArray[np.float64] | None]:
    """The chosen segmentation after steps 8-12 (``easy``: the fast path
    took it), and for a rock chosen among the whole pool (``choice``, its
    score's features from the choice) all of the score's features
    (``confidence``), None otherwise."""
    found = _finished(found, pixels, full=not easy)
    if choice is None:
        return found, None
    before = _offsets_of(found, pixels)
    moved = None if before is None else _offset_moved(found, before[0][0], before[1])
    after = before if moved is None else _offsets_of(moved, pixels)
    evidence = offset_evidence(*(None if r is None else r[1].on_usable for r in (before, after)))
    return found if moved is None else moved, np.concatenate([choice, evidence])


def _offsets_of(found: Segmentation, pixels: NDArray[np.generic]) -> tuple[_OnWindow, OffsetsRead] | None:
    """What the offset step reads of the main rock (:func:`_offset_inputs`) and
    the trees' offsets across its outline; None where they cannot be read."""
    inputs = None if found.channel == "alpha" else _offset_inputs(found, pixels)
    read = None if inputs is None else offsets_read(*inputs[1:], _scale(found))
    return None if read is None else (inputs, read)


def _finished(found: Segmentation, pixels: NDArray[np.generic], *, full: bool = True) -> Segmentation:
    """The main rock with touching pebbles and slivers cut off and its edges seen to
    (steps 8-11), step 11 only with ``full`` (off the fast path); an
    outline an alpha channel gave stands as it is."""
    if found.channel == "alpha":
        return found
    return _edges(_slivers_off(_pebbles_off(found)), pixels, snap=full)


#: A window (rows r0:r1, cols c0:c1), the log brightness and a rock's coverage
#: on it, and the rock's level, the ground's and the ground's spread.
_OnWindow = tuple[
    tuple[int, int, int, int], NDArray[np.float32], NDArray[np.float32], tuple[float, float, float]
]


def _scale(found: Segmentation) -> float:
    """Photo pixels per pixel of the working grid."""
    return 0.5 * (found.scale_rowcol[0] + found.scale_rowcol[1])


def _offset_inputs(found: Segmentation, pixels: NDArray[np.generic]) -> _OnWindow | None:
    """What the offset step reads of the main rock: its window on the working
    grid, the photo's log brightness there, the rock's coverage placed on it,
    and the rock's and the ground's levels with the ground's spread; None when
    the rock does not fit its window or is too small to measure."""
    rock = found.rocks[0]
    # Read again, not taken over from the edge steps: the rim may have grown
    # the rock, and its levels are read round the outline as it now is. It
    # costs a millisecond or two, off the fast path only.
    window, gray = _rock_window(found, pixels)
    mask = _placed(rock, window, found.scale_rowcol)
    if mask is None:
        return None
    region = measured_region(gray, mask, SHADOW_MIN_AREA)
    if region is None:
        return None
    return window, gray, _main_coverage(rock, window, mask.shape), region[3]


def _offset_moved(
    found: Segmentation, window: tuple[int, int, int, int], read: OffsetsRead
) -> Segmentation | None:
    """The main rock with its outline moved by the offsets read across it on
    ``window`` (``offset.moved_by``); None when nothing moved."""
    moved = moved_by(read)
    agreed = None if moved is None else _agreed(moved)
    return None if agreed is None else _main_replaced(found, (window[0], window[2]), *agreed)


def _agreed(moved: NDArray[np.float32]) -> tuple[NDArray[np.bool_], NDArray[np.float32]] | None:
    """A moved coverage's rock (its largest piece past half-way, holes
    filled) and the coverage made to agree with it: filled holes are rock,
    anything else past half-way that is not the rock's one piece is ground;
    None when nothing is past half-way."""
    kept = largest_part(moved >= 0.5)
    if kept is None:
        return None
    kept = _fill_holes(kept)
    moved[kept & (moved < 0.5)] = 1.0
    moved[~kept & (moved >= 0.5)] = 0.49
    return kept, moved


def _chosen(
    pixels: NDArray[np.generic], config: SegmentConfig, *, all_rocks: bool = False
) -> tuple[Segmentation, NDArray[np.float64] | None, bool]:
    """The fast path's segmentation, or the candidate the choice takes; for a
    choice among the whole pool, what its score reads of that choice
    (``confidence.confidence_features``; None otherwise, the score set); and
    whether the fast path took the photo.
    """
    pool = _candidate_pool(pixels, config, all_rocks=all_rocks, fast=True)
    if isinstance(pool, Segmentation):
        return pool, None, True
    candidates = pool.candidates
    # The refinements (GrabCut) cost most: they are made only when the choice
    # among the detected candidates, by trees fitted on such pools, is not already sure.
    index, detected = choose_ranked(*zip(*candidates, strict=True), detected_only=True)
    if detected.max() >= FAST_PROBABILITY:
        return _main_scored(candidates[index][0], detected), None, False
    candidates = candidates + pool.refined()
    ranking = rank(*zip(*candidates, strict=True))
    found = _without_shadow(candidates, ranking.index, ranking.probabilities, pixels)
    return found, confidence_features(ranking, float(detected.max()), notch(found.rocks[0].mask)), False


def _without_shadow(
    candidates: list[tuple[Segmentation, float, str]],
    index: int,
    probabilities: NDArray[np.float64],
    pixels: NDArray[np.generic],
) -> Segmentation:
    """The chosen candidate, or the most probable candidate inside it that
    leaves out a cast shadow it took in (``shadow.shadow_left_out``).

    The rock is the same object, less its shadow: it keeps the chosen
    candidate's score.
    """
    found = candidates[index][0]
    # A choice already sure of its outline is not second-guessed.
    if probabilities.max() >= FAST_PROBABILITY:
        return found
    window, gray = _rock_window(found, pixels)
    outer = _placed(found.rocks[0], window, found.scale_rowcol)
    inners, which = [], []
    for k in np.argsort(-probabilities, kind="stable"):
        if k == index:
            continue
        other = candidates[k][0]
        inner = _placed(other.rocks[0], window, found.scale_rowcol, other.scale_rowcol)
        if inner is not None:
            inners.append(inner)
            which.append(int(k))
    if outer is None or not inners:
        return found
    chosen = shadow_left_out(gray, outer, inners)
    return found if chosen is None else candidates[which[chosen]][0]


def _pebbles_off(found: Segmentation) -> Segmentation:
    """The main rock with the pebbles that touch it cut off (``pebbles.pebbles_off``).

    The choice prefers outlines without pebbles, but the fast path and the
    best candidate may still carry one: a pebble as dark as the rock joins
    every cue's region. Cut off along its contact, it leaves the rock's own
    edge as it was outlined. Other rocks of the segmentation are left as
    they are.
    """
    rock = found.rocks[0]
    return _main_cut(found, pebbles_off(rock.mask))


def _slivers_off(found: Segmentation) -> Segmentation:
    """The main rock with the thin slivers that run off it along a crevice
    taken off (``slivers.slivers_off``); other rocks are left as they are."""
    return _main_cut(found, slivers_off(found.rocks[0].mask))


def _edges(found: Segmentation, pixels: NDArray[np.generic], *, snap: bool = True) -> Segmentation:
    """The main rock with a cast shadow that joined it taken off
    (``shadow.shadow_off``), with ``snap`` its outline moved to the steepest
    edge beside it (``snap.snapped``), then a dark rim its outline left out
    taken in (``rim.rim_on``).

    All are judged on the photo's log brightness around the rock, brought
    to the working grid the rock was outlined on, and on the rock's and the
    ground's levels, read once for all. A rock cut, moved or grown keeps its score.
    """
    rock = found.rocks[0]
    window, gray = _rock_window(found, pixels)
    mask = _placed(rock, window, found.scale_rowcol)
    region = measured_region(gray, mask, SHADOW_MIN_AREA)
    if region is None:
        return found
    kept = shadow_off(gray, mask, region)
    if kept is not mask:
        (r0, _, c0, _), (o0, o1), (h, w) = window, rock.origin_rowcol, rock.mask.shape
        found = _main_cut(found, kept[o0 - r0 : o0 - r0 + h, o1 - c0 : o1 - c0 + w])
        rock = found.rocks[0]
        window, gray = _rock_window(found, pixels)
        mask = _placed(rock, window, found.scale_rowcol)
        region = measured_region(gray, mask, SHADOW_MIN_AREA)
        if region is None:
            return found
    if snap and found.channel == "luminance":
        found, mask, region = _snapped(found, window, gray, mask, region)
    grown = rim_on(gray, mask, region)
    return found if grown is mask else _main_grown(found, window, mask, grown)


def _snapped(
    found: Segmentation,
    window: tuple[int, int, int, int],
    gray: NDArray[np.float32],
    mask: NDArray[np.bool_],
    region: Region,
) -> tuple[Segmentation, NDArray[np.bool_], Region]:
    """The main rock with its outline moved to the steepest edge beside it
    (``snap.snapped``), its mask on ``window`` and its region; as they were
    when nothing moved. The rock keeps its score."""
    import cv2

    rock = found.rocks[0]
    (r0, r1, c0, c1), (o0, o1), (h, w) = window, rock.origin_rowcol, rock.mask.shape
    reach = SNAP_REACH / (0.5 * (found.scale_rowcol[0] + found.scale_rowcol[1]))
    # The rock's own window, wide enough for its outline to move and be read across.
    pad = math.ceil(reach + SNAP_MARGIN) + 1
    R0, R1, C0, C1 = max(r0, o0 - pad), min(r1, o0 + h + pad), max(c0, o1 - pad), min(c1, o1 + w + pad)
    coverage = _main_coverage(rock, (R0, R1, C0, C1), (R1 - R0, C1 - C0))
    _, _, _, (rock_level, ground_level, _) = region
    # A blur spreads light, not its logarithm: the steepest change of the
    # log brightness lies towards the dark side of an edge.
    light = np.exp(gray[R0 - r0 : R1 - r0, C0 - c0 : C1 - c0])
    moved = snapped(light, coverage, rock_level > ground_level, reach)
    agreed = None if moved is None else _agreed(moved)
    if agreed is None:
        return found, mask, region
    kept, moved = agreed
    found = _main_replaced(found, (R0, C0), kept, moved)
    mask = np.zeros(mask.shape, bool)
    mask[R0 - r0 : R1 - r0, C0 - c0 : C1 - c0] = kept
    mask8 = mask.view(np.uint8)
    moments = cv2.moments(mask8, binaryImage=True)
    area = moments["m00"]
    return found, mask, (mask8, (moments["m01"] / area, moments["m10"] / area), area, region[3])


def _main_grown(
    found: Segmentation,
    window: tuple[int, int, int, int],
    mask: NDArray[np.bool_],
    grown: NDArray[np.bool_],
) -> Segmentation:
    """The segmentation with its main rock (``mask`` on ``window``) grown to
    ``grown``: what is added is rock in the coverage and the labels; other
    rocks are left as they are."""
    coverage = _main_coverage(found.rocks[0], window, mask.shape)
    coverage[grown & ~mask] = 1.0
    return _main_replaced(found, (window[0], window[2]), grown, coverage)


def _main_coverage(
    rock: RockMask, window: tuple[int, int, int, int], shape: tuple[int, int]
) -> NDArray[np.float32]:
    """A rock's coverage placed on a window (rows r0:r1, cols c0:c1) of its working grid."""
    (r0, _, c0, _), (o0, o1), (h, w) = window, rock.origin_rowcol, rock.mask.shape
    coverage = np.zeros(shape, np.float32)
    coverage[o0 - r0 : o0 - r0 + h, o1 - c0 : o1 - c0 + w] = rock.coverage
    return coverage


def _main_replaced(
    found: Segmentation, origin: tuple[int, int], mask: NDArray[np.bool_], coverage: NDArray[np.float32]
) -> Segmentation:
    """The segmentation with its main rock's mask and coverage replaced by
    ``mask`` and ``coverage`` on a window from ``origin``, in the labels too;
    other rocks are left as they are."""
    r0, c0 = origin
    main = cropped(dataclasses.replace(found.rocks[0], mask=mask, coverage=coverage, origin_rowcol=origin))
    labels = found.labels.copy()
    view = labels[r0 : r0 + mask.shape[0], c0 : c0 + mask.shape[1]]
    view[~mask & (view == 1)] = 0
    view[mask & (view == 0)] = 1
    return dataclasses.replace(found, labels=labels, rocks=(main, *found.rocks[1:]))


def _rock_window(
    found: Segmentation, pixels: NDArray[np.generic]
) -> tuple[tuple[int, int, int, int], NDArray[np.float32]]:
    """The window of the working grid around the main rock (rows r0:r1, cols
    c0:c1) with the ring its ground's level is read from, and the photo's log
    brightness on it."""
    rock = found.rocks[0]
    h, w = rock.mask.shape
    radius = math.sqrt(max(rock.area, 1) / math.pi)
    pad = math.ceil(max(RING_PIXELS[1], RING[1] * radius)) + 2
    rows, cols = found.labels.shape
    o0, o1 = rock.origin_rowcol
    window = (max(0, o0 - pad), min(rows, o0 + h + pad), max(0, o1 - pad), min(cols, o1 + w + pad))
    gray = _working_gray(pixels, window, found.scale_rowcol)
    return window, np.log(gray + np.float32(_LOG_FLOOR))


def _placed(
    rock: RockMask,
    window: tuple[int, int, int, int],
    scale_rowcol: tuple[float, float],
    grid_scale_rowcol: tuple[float, float] | None = None,
) -> NDArray[np.bool_] | None:
    """A rock's mask on a window of a working grid (photo pixels per grid pixel
    ``scale_rowcol``); None if it does not fit inside.

    The rock may have been outlined on another grid (``grid_scale_rowcol``,
    the same by default): each window pixel takes the value under its centre.
    """
    r0, r1, c0, c1 = window
    (o0, o1), (h, w) = rock.origin_rowcol, rock.mask.shape
    own = grid_scale_rowcol or scale_rowcol
    # The rock's extent in window pixels (fractional when the grids differ).
    top, left = o0 * own[0] / scale_rowcol[0], o1 * own[1] / scale_rowcol[1]
    bottom, right = (o0 + h) * own[0] / scale_rowcol[0], (o1 + w) * own[1] / scale_rowcol[1]
    if top < r0 - _FIT or left < c0 - _FIT or bottom > r1 + _FIT or right > c1 + _FIT:
        return None
    rows = np.floor((np.arange(r0, r1) + 0.5) * scale_rowcol[0] / own[0]).astype(np.int64) - o0
    cols = np.floor((np.arange(c0, c1) + 0.5) * scale_rowcol[1] / own[1]).astype(np.int64) - o1
    # The indices rise with the window's: the pixels over the rock are one
    # block, filled by a gather of rows, then of columns (a 2-D fancy index
    # would cost a hundred times more on the rock's own grid).
    on_rows = np.flatnonzero((rows >= 0) & (rows < h))
    on_cols = np.flatnonzero((cols >= 0) & (cols < w))
    mask = np.zeros((r1 - r0, c1 - c0), bool)
    if on_rows.size and on_cols.size:
        block = rock.mask.take(rows[on_rows], axis=0).take(cols[on_cols], axis=1)
        mask[on_rows[0] : on_rows[-1] + 1, on_cols[0] : on_cols[-1] + 1] = block
    return mask


#: How far, in pixels of the window's grid, a rock outlined on another grid
#: may reach past the window's edge and still be placed on it (rounding).
_FIT = 1.0


def _working_gray(
    pixels: NDArray[np.generic], window: tuple[int, int, int, int], scale_rowcol: tuple[float, float]
) -> NDArray[np.float32]:
    """Luminance in [0, 1] of a window (rows r0:r1, cols c0:c1) of the working
    image, from the photo's pixels under it, reduced as the working image was
    (exact halvings, then one resize) before the conversion to gray."""
    import cv2

    r0, r1, c0, c1 = window
    sr, sc = scale_rowcol
    photo = np.asarray(pixels)
    if photo.ndim == 3 and photo.shape[2] == 1:
        photo = photo[..., 0]
    p0, p1 = math.floor(r0 * sr), min(photo.shape[0], max(math.floor(r0 * sr) + 1, round(r1 * sr)))
    q0, q1 = math.floor(c0 * sc), min(photo.shape[1], max(math.floor(c0 * sc) + 1, round(c1 * sc)))
    size = (c1 - c0, r1 - r0)
    reduced, _ = _at_scale(_pyramid(photo[p0:p1, q0:q1], max(1, min(size))), max(sr, sc))
    gray = _unit(reduced[..., :3].astype(np.float32) @ _LUMA if reduced.ndim == 3 else reduced, photo.dtype)
    if gray.shape != size[::-1]:
        gray = cv2.resize(gray, size, interpolation=cv2.INTER_LINEAR)
    return gray


#: Added to brightness in [0, 1] before its logarithm (ten levels of eight
#: bits): near black, sensor noise and compression make ratios meaningless,
#: and the logarithm would stretch a dark rock's texture into steps. On the
#: development part any value from 0.008 to 0.08 gives the same outlines.
_LOG_FLOOR = 0.04


def _main_cut(found: Segmentation, kept: NDArray[np.bool_]) -> Segmentation:
    """The segmentation with its main rock's mask cut to ``kept`` (a part of it, on its window).

    What is cut goes from the coverage and the labels; other rocks are left as they are.
    """
    rock = found.rocks[0]
    if kept is rock.mask:
        return found
    cut = rock.mask & ~kept
    main = dataclasses.replace(rock, mask=kept, coverage=np.where(cut, 0.0, rock.coverage).astype(np.float32))
    labels = found.labels.copy()
    r0, c0 = rock.origin_rowcol
    view = labels[r0 : r0 + cut.shape[0], c0 : c0 + cut.shape[1]]
    view[cut & (view == 1)] = 0
    return dataclasses.replace(found, labels=labels, rocks=(main, *found.rocks[1:]))


#: The choice model's probability from which its choice is sure: among the
#: detected candidates, it stands unrefined (on development photos, cross-validated,
#: 39.5% of them stop so, 97.6% of those right); of the whole pool, it is not
#: second-guessed for a cast shadow.
FAST_PROBABILITY = 0.9


def _main_scored(found: Segmentation, probabilities: NDArray[np.float64]) -> Segmentation:
    """The segmentation with its main rock's score set to the choice's
    probability that its object is the rock (the candidates' largest).

    A main rock chosen among the detected candidates alone is scored so: the
    choice model's probability ranks right outlines above wrong ones better
    than the outline's own evidence. One chosen among the whole pool is
    scored by ``confidence.outline_confidence`` (:func:`segment`). An
    outline the fast path takes is supported all round and keeps its outline
    score (>= ``FAST_SCORE``, or less for a lobed rock's arms: see
    :func:`_fast_outline`).
    """
    main = dataclasses.replace(found.rocks[0], score=float(probabilities.max()))
    return dataclasses.replace(found, rocks=(main, *found.rocks[1:]))


@dataclass(frozen=True, eq=False)
class _Pool:
    """Candidate main rocks with their detection scores and sources (``choose.SOURCES``),
    and how to refine the best of them."""

    candidates: list[tuple[Segmentation, float, str]]
    outline: Outliner
    incumbent: tuple[Segmentation, float]

    def refined(self) -> list[tuple[Segmentation, float, str]]:
        """The other cues' outlines (``Outliner.refined``), started from the best-supported candidate."""
        found, detection_score = self.incumbent
        return [(refined, detection_score, source) for source, refined in self.outline.refined(found)]


def _candidate_pool(
    pixels: NDArray[np.generic], config: SegmentConfig, *, all_rocks: bool = False, fast: bool = True
) -> Segmentation | _Pool:
    """Candidate segmentations of the main rock with their detection scores, or a finished one.

    A finished segmentation comes back for an alpha channel, for
    ``all_rocks``, and (with ``fast``) for an easy photo: an outline the
    photo supports all round, of a detection without rival. Otherwise
    the candidates of each channel's detection, and their refinements on demand.
    """
    arr = _check_pixels(pixels)
    rows, cols = arr.shape[:2]
    color = arr[..., :3] if arr.ndim == 3 else arr
    detect_scale = max(1.0, max(rows, cols) / config.detect_size)
    largest_scale = max(1.0, max(rows, cols) / config.work_size)

    if arr.ndim == 3 and arr.shape[2] == 4:
        alpha, covered = _at_scale(_pyramid(arr[..., 3], config.work_size), largest_scale)
        alpha = _unit(alpha, arr.dtype)
        if 0.05 < float((alpha < 0.5).mean()) < 0.98:
            scale_rowcol = (covered[0] / alpha.shape[0], covered[1] / alpha.shape[1])
            return _from_alpha(alpha, scale_rowcol, config, all_rocks)

    levels = _pyramid(color, config.detect_size)
    small, detect_covered = _at_scale(levels, detect_scale)
    small = _unit(small, arr.dtype)
    outline = Outliner(
        levels, arr.dtype, small.shape[:2], detect_covered, detect_scale, largest_scale, config
    )
    best: tuple[float, Segmentation, float] | None = None
    pool: list[tuple[Segmentation, float, str]] = []
    if all_rocks:
        every = rocks_of_every_channel(small, outline, config)
        if every is None:
            raise NoRockFoundError(_NOTHING_FOUND)
        return every
    for channel in _channels(small):
        detection = _detect(channel.values(small), channel, config, all_rocks)
        if detection is None:
            continue
        rivals_seen = bool(pool)
        for candidate in _candidates(detection):
            found = outline(candidate)
            if found is None:
                continue
            # Fast path: an outline the photo supports all round, of a rock
            # that stood out clearly from every other region, needs no rival;
            # in the first channel that shows a rock only (a later channel's
            # rival to the first's outlines is for the choice to judge), and
            # for that region itself: a crisp pebble beside an unrivalled
            # rock is no reason to stop.
            if (
                fast
                and not rivals_seen
                and candidate is detection
                and _fast_outline(found)
                and _unrivalled(detection)
            ):
                return found
            pool.append((found, candidate.score, "detected"))
            key = _choice_key(found, candidate.score)
            if best is None or key > best[0]:
                best = (key, found, candidate.score)
    if best is None:
        raise NoRockFoundError(_NOTHING_FOUND)
    # The refinements start from the outline the photo supports best.
    _, incumbent, detection_score = best
    return _Pool(pool, outline, (incumbent, detection_score))


#: Why no rock was found when no channel shows a region standing out.
_NOTHING_FOUND = "no rock found: nothing stands out from the ground"

#: A main rock's segmentation score from which no other candidate is tried (the fast path).
#: Chosen on the development part: at 0.995 it stops on half the photos and
#: is right (IoU >= 0.9) on 90% of them, and the part as a whole scores
#: better than with no fast path (61.5% against 59.8%); at 0.95 it is right
#: on 66% of the photos it stops on, and the part scores 53.6%.
FAST_SCORE = 0.995


def _fast_outline(found: Segmentation) -> bool:
    """Whether the main rock's first outline scores enough for the fast path:
    its outline score, or for an outline lobed all round (``pebbles.lobed``)
    the score its evidence gives without solidity, at least ``FAST_SCORE``;
    and with little of the band just outside it beyond the ground from the
    rock (``score.OutlineEvidence.darker_outside``): less than
    ``SHADE_BESIDE`` darker than the ground beside a rock lighter than its
    ground, less than ``LIT_BESIDE`` lighter beside a dark rock in luminance.

    Solidity keeps the fast path off an outline that took in a pebble or a
    shadow, but a star's arms are its shape, and a lobed rock took nothing in.
    A light rock lit from one side darkens towards its far rim, below the
    ground's level; its lit part then steps against the ground and against
    that rim alike, and its outline, supported all round, may leave the
    shaded side out. Dark beside the outline is that side (or the cast
    shadow beyond it): the other candidates are worth judging. Under a low
    light the dark region is a rock's shaded side joined to its cast shadow,
    whose far edge steps against the lit ground as crisply as a rock's; the
    rock's lit face, lighter than the ground, then lies beside that outline.
    """
    rock = found.rocks[0]
    if found.polarity == "light" and rock.darker_outside >= SHADE_BESIDE:
        return False
    if found.polarity == "dark" and found.channel == "luminance" and rock.darker_outside >= LIT_BESIDE:
        return False
    if rock.score >= FAST_SCORE:
        return True
    if len(rock.evidence) != len(WEIGHTS):
        return False
    *support, _ = rock.evidence
    # The opening that tells lobes costs more than the score: it comes last.
    return outline_score(OutlineEvidence(*support, solidity=1.0)) >= FAST_SCORE and lobed(rock.mask)


#: Share of the band just outside a light rock's first outline, darker than
#: the ground (``score.OutlineEvidence.darker_outside``), from which it takes
#: no fast path. On the development part, every light rock's fast-path
#: outline had 12-36% (10 of 14 wrong, IoU < 0.9); the rocks rendered from
#: the default library and the coins of ``coins()`` at most 5%.
SHADE_BESIDE = 0.1

#: Share of the band just outside a dark rock's first outline (luminance),
#: lighter than the ground (``score.OutlineEvidence.darker_outside``), from
#: which it takes no fast path. On the development part (photos 0-79 of every
#: one-rock condition and crops, and shaded photos 200-679), 8 of the 10
#: shaded photos that took the fast path took a rock's shade with its cast
#: shadow (IoU 0.22-0.74), with 0.02-0.24 beside them; judged among the other
#: candidates, 6 of the 71 fast-path photos cross IoU 0.9 upwards and none
#: downwards. The dark rocks rendered from the default library (five seeds, PNG
#: and JPEG) have at most 0.035, and keep the fast path.
LIT_BESIDE = 0.05


def _unrivalled(detection: _Detection) -> bool:
    """Whether the main region's detection score is far above every other region's."""
    rivals = [
        score for score, region, _ in detection.alternatives if _overlap(region, detection.regions[0]) < 0.5
    ]
    return not rivals or max(rivals) <= _RIVAL_SHARE * detection.score


#: Share of the main region's detection score that a rival must stay under for the fast path.
_RIVAL_SHARE = 0.25


def _candidates(detection: _Detection) -> Iterator[_Detection]:
    """The detection's main rock, then its alternatives (whole regions, runners-up, the other polarity)."""
    yield detection
    seen = [detection.regions[0]]
    for score, region, polarity in detection.alternatives:
        if any(_overlap(region, other) > 0.9 for other in seen):
            continue
        seen.append(region)
        yield dataclasses.replace(detection, score=score, regions=[region], polarity=polarity, others=[])


def _overlap(a: NDArray[np.bool_], b: NDArray[np.bool_]) -> float:
    """Intersection over union of two masks."""
    union = int(np.count_nonzero(a | b))
    return float(np.count_nonzero(a & b)) / union if union else 0.0


def _choice_key(found: Segmentation, detection_score: float) -> float:
    """Rank of a candidate main rock: its segmentation score, a little for how it was detected.

    A pebble or a highlight can be outlined as crisply as the rock it lies
    on or by: of outlines about as well supported, the one whose region
    stood out more (larger, clearer, off the frame, nearer the centre) wins.
    """
    return found.rocks[0].score * max(detection_score, 0.0) ** _DETECTION_WEIGHT


#: Exponent of a candidate's detection score in its rank (a tenth of it costs a quarter of the rank).
_DETECTION_WEIGHT = 0.125
