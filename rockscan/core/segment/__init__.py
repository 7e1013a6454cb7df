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
   cuts the rock out (5% to 98% of the frame transparent) is used directly;
   one that hides part of a scene (a photo turned or padded in an editor, a
   round field of view, ground erased) is not: with each transparent pixel
   painted the colour of the nearest opaque one, a rock that stands out away
   from the opaque part's rim, outlined with confidence, is the rock
   (``rockscan.core.segment.cutout``).
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
   median rock's is kept, by decreasing area; and, among three or more, a
   region whose median colour lies nearer the ground's round it than
   ``scene.GROUND_LIKE`` of the median rock's distance is dropped: a patch
   of ground between rocks, lit or shaded differently from the rest. Last,
   a rock of the ground's own colour is looked for by its rim: a patch of
   the ground the rocks leave that an edge as steep as theirs closes all
   round, compact and of a rock's size (``rockscan.core.segment.ringed``).
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
   under the frame's centre, watershed basins; and the outlines opened).
   When no region any channel found covers the frame's centre, the main
   region may be a pocket of ground between a crop's rocks, learnt against
   a border of neighbours: the object under the centre, found against that
   region taken for ground, is a candidate too when it lies inside the frame
   and stands out from the pocket more than the pocket did from the border
   (``rockscan.core.segment.pocket``), and is refined as the best-supported
   candidate is. A model fitted on the segmentation benchmark's
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
   out is a cast shadow darker than the rock (``shadow.shadow_left_out``)
   and, in colour, not of the rock's own hue (``finish.rock_hued``).
   A rock chosen among the whole pool is scored, once its outline is
   final, by how sure that choice is over the photo and by how well the
   offsets of step 12 agree with its outline
   (``rockscan.core.segment.confidence``).
8. **Pebbles and slivers off.** Round pieces that hang off the chosen outline
   at a neck (touching pebbles, which join every cue's region) are cut off
   along their contacts (``rockscan.core.segment.pebbles``); lobes all round
   it at even angles are the rock's own shape and stay. Then thin bands that run off the
   outline along a crevice, many times longer than wide and reaching well
   away from the rock's body, are cut off (``rockscan.core.segment.slivers``).
9. **Shadow off.** A cast shadow darker than half-way between the ground and
   a dark rock joins the rock's region; where the photo's log brightness,
   along rays from the rock's centre, rises a second time inside the
   outline (from the rock's shaded rim to the flat, darkened ground of the
   shadow) on one smooth arc away from the rock's lit side, what lies beyond
   that rise is cut off (``rockscan.core.segment.shadow``). A long shadow,
   of which those rays see only a wedge, floods from that wedge up to its
   edge with the rock (a watershed of the photo's slope). Beside a light
   rock that a cue outlined with its shadow, the profile instead falls, last,
   from the rock's rim to a band well darker than the ground that keeps the
   ground's grain; what lies beyond that fall goes the same way. Under
   little sky light, where the outline is both lighter and darker than the
   ground (a light rock and its near-black shadow), its darkest part, when
   it keeps the ground's grain and lit ground lies past it, floods up to
   its edge with the rock the same way. In colour,
   a part to be cut that lies at least ``hued.ROCK_HUE`` of the way in hue
   from the ground's chromaticity to the rest of the rock's is a darker band
   of the rock itself, and stays: a shadow is darkened ground, of the
   ground's hue.
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
    The trees are read again on the moved outline, and it moves once more
    by what they read there: a wide blur over a darkening limb leaves an
    outline further off the edge than one move reaches.
13. **Shaded side on.** Unless the fast path took the photo: under a low
    light a light rock's far side, lit by the sky alone like its cast
    shadow beyond it, is left out with the shadow. In sky light the two keep
    the ratio of their albedos: of the pixels darker than the ground beside
    the rock, the lighter of two levels, when they lie apart by about the
    rock's step above the ground, is its shaded side, taken in when the rock
    stays as compact and grows by 3-35% (``rockscan.core.segment.shade``).
14. **A part of the ground's hue parted off.** Unless the fast path took
    the photo, in colour: an outline that took more of a cast shadow, or of a
    patch of ground, than of the rock is cut between its two colours
    (``split.split_colours``, the colour cue of ``--all``); when every part
    but the one farthest in hue from the ground's (read in a ring just past
    the outline) lies near the ground's hue, at least twice as near, and no
    lighter than the ground, the rock is that farthest part
    (``hued.hue_parted``), and steps 8-11 are read again on its outline.
15. **A side of the rock's hue on.** Then, in colour: a side of the rock
    that brightness left out keeps the rock's hue, where a cast shadow
    keeps the ground's. The pixels beside the
    outline at least ``hued.ROCK_HUE`` of the way in chromaticity from the
    ground's hue to the rock's join it, where hue tells the two apart and
    the rock stays as compact and grows by 3-150%
    (``rockscan.core.segment.hued``).
16. **A part of the ground's hue off.** Last, in colour, a part of the
    outline that lies near the ground's hue and reaches its edge (a cast
    shadow, a patch of ground, a pebble of the ground's hue taken in with the
    rock) is cut off, the rock's hue read on the half of the outline
    farthest from the ground's, where the rest stays as compact and loses
    3-60% of its area (``hued.hue_off``).
17. **A clipped face on.** Last, off the fast path: a light rock's face
    turned to a strong light may be brighter than the sensor records, every
    channel at its ceiling, and white whatever the rock's colour; an outline
    drawn along the rock's hue leaves it out. The clipped pixels that touch
    the outline, grown to half-way in brightness from the ground to the
    ceiling, join the rock where it stays as compact and grows by 3-70%
    (``rockscan.core.segment.clipped``).

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
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rockscan.core._threads import one_blas_thread
from rockscan.core.errors import NoRockFoundError
from rockscan.core.segment.channels import _at_scale, _channels, _check_pixels, _pyramid, _unit, to_gray
from rockscan.core.segment.choose import choose_ranked, rank
from rockscan.core.segment.confidence import confidence_features, outline_confidence
from rockscan.core.segment.cutout import painted, partly_transparent, stands_inside
from rockscan.core.segment.detect import _detect, _Detection
from rockscan.core.segment.finish import completed, placed, rock_hued, rock_window
from rockscan.core.segment.outliner import Outliner
from rockscan.core.segment.pebbles import lobed
from rockscan.core.segment.pocket import centre_object, covers_centre
from rockscan.core.segment.scene import rocks_of_every_channel
from rockscan.core.segment.score import WEIGHTS, OutlineEvidence, outline_score
from rockscan.core.segment.shadow import shadow_left_out
from rockscan.core.segment.stats import notch
from rockscan.core.segment.trace import _from_alpha
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
    inside = _scene_behind_alpha(pixels, config, all_rocks)
    if inside is not None:
        return inside
    found, choice, easy = _chosen(pixels, config, all_rocks=all_rocks)
    if all_rocks:
        return found
    found, features = completed(found, choice, pixels, easy=easy)
    if features is None:
        return found
    main = dataclasses.replace(found.rocks[0], score=outline_confidence(features))
    return dataclasses.replace(found, rocks=(main, *found.rocks[1:]))


def _scene_behind_alpha(
    pixels: NDArray[np.generic], config: SegmentConfig, all_rocks: bool
) -> Segmentation | None:
    """For a partly transparent photo whose alpha does not cut its rock out (a
    turned, padded or vignetted scene, ``rockscan.core.segment.cutout``), the
    segmentation of the scene's colour, its transparent pixels painted as its
    ground; so too for a photo whose transparent pixels are only specks; None
    for any other photo (a cut-out's alpha is its outline)."""
    # Only an RGBA photo has an alpha to read: any other skips the checks that
    # _candidate_pool makes of every photo (a float or 16-bit photo's full passes).
    if np.ndim(pixels) != 3 or np.shape(pixels)[2] != 4:
        return None
    scene = painted(_check_pixels(pixels))
    if scene is None:
        return None
    colour, edge_zone = scene
    if edge_zone is None:
        # Only specks are transparent: the photo is its colour, the specks painted.
        return segment(colour, config, all_rocks=all_rocks)
    try:
        found = segment(colour, config)
    except NoRockFoundError:
        return None
    if not stands_inside(found, edge_zone):
        return None
    return segment(colour, config, all_rocks=True) if all_rocks else found


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
    leaves out a cast shadow it took in (``shadow.shadow_left_out``), in
    colour a part of the ground's hue (``finish.rock_hued``).

    The rock is the same object, less its shadow: it keeps the chosen
    candidate's score.
    """
    found = candidates[index][0]
    # A choice already sure of its outline is not second-guessed.
    if probabilities.max() >= FAST_PROBABILITY:
        return found
    window, gray = rock_window(found, pixels)
    outer = placed(found.rocks[0], window, found.scale_rowcol)
    inners, which = [], []
    for k in np.argsort(-probabilities, kind="stable"):
        if k == index:
            continue
        other = candidates[k][0]
        inner = placed(other.rocks[0], window, found.scale_rowcol, other.scale_rowcol)
        if inner is not None:
            inners.append(inner)
            which.append(int(k))
    if outer is None or not inners:
        return found
    chosen = shadow_left_out(gray, outer, inners)
    # A part of the rock's own hue is a darker band of the rock, not its shadow.
    if chosen is None or rock_hued(pixels, window, found.scale_rowcol, outer, outer & ~inners[chosen]):
        return found
    return candidates[which[chosen]][0]


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
    #: The objects under the frame's centre found against a pocket of ground
    #: (``pocket.centre_object``), each refined too.
    pockets: list[tuple[Segmentation, float]] = dataclasses.field(default_factory=list)

    def refined(self) -> list[tuple[Segmentation, float, str]]:
        """The other cues' outlines (``Outliner.refined``), started from the best-supported
        candidate and from each object found against a pocket of ground."""
        return [
            (refined, detection_score, source)
            for found, detection_score in (self.incumbent, *self.pockets)
            for source, refined in self.outline.refined(found)
        ]


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
        if partly_transparent(float((alpha < 0.5).mean())):
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
    detections = []
    for channel in _channels(small):
        detection = _detect(channel.values(small), channel, config, all_rocks)
        if detection is None:
            continue
        detections.append(detection)
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
    pockets = _pocket_candidates(detections, outline, config)
    # The refinements start from the outline the photo supports best, and from
    # each object under the centre: the best-supported outline is then likely a
    # pocket of ground, whose refinements outline that pocket again.
    _, incumbent, detection_score = best
    return _Pool(
        pool + [(found, score, "detected") for found, score in pockets],
        outline,
        (incumbent, detection_score),
        pockets,
    )


def _pocket_candidates(
    detections: list[_Detection], outline: Outliner, config: SegmentConfig
) -> list[tuple[Segmentation, float]]:
    """When no region any channel found covers the frame's centre, the object under it,
    found against each channel's main region taken for ground (``pocket.centre_object``),
    outlined, with its detection score."""
    if any(covers_centre(detection) for detection in detections):
        return []
    found = []
    for detection in detections:
        candidate = centre_object(detection, config)
        outlined = outline(candidate) if candidate is not None else None
        if outlined is not None:
            found.append((outlined, candidate.score))
    return found


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
