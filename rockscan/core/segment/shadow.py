"""A cast shadow that joins a rock's outline, and taking it off.

Lit from one side, a rock casts a shadow on the ground beside it. The
shadow is the ground's own surface, darkened. Beside a light rock it is
darker than the ground and never looks like rock; beside a dark rock it
may lie past half-way from the ground's level to the rock's, and the
outline (``rockscan.core.segment.trace``) then runs round rock and shadow
together. Every cue's region takes it in: the shadow differs from the lit
ground as much as the rock does.

What gives it away is the profile across it, along rays from the rock's
centre. Where rock and shadow meet, both are lit by the sky alone: the
rock's shaded rim is darker than the shadow by the ratio of their albedos,
and the rock's occluding edge is sharp. Going out along a ray on that side,
the profile *rises* from the rock's dark rim to the shadow, stays flat
across the shadow (darkened ground), and rises again at the shadow's edge
to the lit ground. On a ray without a shadow, the one rise is at the outline.

A ray shows a shadow when it rises, at least ``MIN_BAND`` pixels inside the
outline's own blurred edge, by at least ``RISE`` of the step from the
rock's level to the ground's (and ``NOISE`` times the ground's spread), from
a valley no lighter than a little above the rock's level to a band that is
flat (its interquartile range under ``FLAT`` of the step) and darker than
the ground all the way to that edge. The shadow is taken off only when such
rays form one arc of the outline (``MIN_ARC`` to ``MAX_ARC`` of it), along
which the shadow's width changes smoothly (``ROUGH``), on the side away from
the rock's lit side: texture on a rock makes such rises too, but at
scattered depths and on any side. Along the arc, everything beyond the rise
goes, unless that would lengthen the outline (``LONGER``): a cut along a
rock's edge shortens it, while rays that graze the outline (near a sharp
corner, along a star's arm) would notch it.

A long shadow, half the rock's size or more (a low sun), defeats the rays.
Cast from the centre of rock and shadow together, near the edge between
them, they cross that edge on part of it only, and a cut along that part
notches the outline; the shadow's light also draws the lit side found
towards it. There, beside a rock darker than the ground, the shadow the arc
shows seeds a flood of the photo's slope inside the outline (a watershed),
against seeds of rock on the far side of the centre: the shadow's flat band
fills up to its edge with the rock wherever it reaches. The cut is kept when
the rock keeps at least ``GROWN_KEEP`` of the outline, the cut runs along an
edge (its median slope at least ``GROWN_EDGE`` of the step per pixel: a
flood from a pit that stopped in the rock's own smooth shading does not),
cuts off a part about as flat as a band (interquartile range under
``GROWN_FLAT`` of the step: half a textured rock is not), leaves the outline
no longer (``LONGER``), and leaves the shadow away from the lit side of rock
and shadow together or, where their light misleads, of the rock that
remains.

Beside a light rock the shadow is darker than the ground and never looks
like rock, but a cue that takes in whatever differs from the lit ground
(GrabCut from a box, a basin of the gradient) runs round both. There the
occluding edge *falls*: the rock's rim in sky light is lighter than the
ground in sky light by their albedos' ratio. Going out along a ray, the
profile falls, last, from the rock's rim to a band darker than the ground
by at least ``LIGHT_DEEP`` of the step, which keeps the ground's texture
(its spread at least ``LIGHT_TEXTURE`` of the ground's), and rises to the
lit ground at the outline. The rock's own shaded side, which also lies away
from the light and may be as dark, differs on both counts: it is darker than
the ground by less (its albedo is the rock's) and carries the rock's
shading, smooth where the ground is textured. Along the arc, the median
fall must reach ``LIGHT_FALL`` of the step; the arc, its smoothness, the
side away from the light and the cut are as for a dark rock.

Under little sky light a light rock's shadow is near black, and rock and
shadow together make an outline both lighter and darker than the ground:
its core's median may lie near the ground's level or below it, so that the
rays take it for a dark rock or see no fall, and on a grainy ground the
fall from the rock's rim hides in the grain. There, when at least
``TWO_SHARES`` of the outline lies well below the ground's level and above
it (``TWO_DARK``, ``TWO_LIGHT``), the darker class (Otsu's) of its largest
dark part seeds a watershed of the photo's slope against seeds of rock
(lighter than that class by ``TWO_SEED`` of its depth below the ground).
The cut is kept when the rock keeps at least ``GROWN_KEEP`` of the outline,
the cut runs along an edge (``GROWN_EDGE``), the part cut off is darker than
the ground and keeps the ground's grain (``TWO_GRAIN``: a smooth facet
turned from the light does not) without being more varied than grain
(``TWO_FLAT``), the ground just past it is lit (``TWO_PAST``: past a light
rock's own shaded side lies its cast shadow, darker still), the outline gets
no longer, and the part lies away from the rock's lit side. This flood is
tried before the rays, which run only where it cuts nothing: on such an
outline the rays may cut part of a black shadow and leave the rest.

A rock lighter than its own shadow (mid-toned, or textured with light
patches: the shadow is the ground in sky light alone) shows no rise from
rim to shadow, and the rays find nothing. There another cue may have drawn
the rock alone, inside the chosen outline: :func:`shadow_left_out` takes
such an inner outline when the part it leaves out looks like darkened
ground and not like rock (darker than the rock's core, no more varied than
it, and on the side away from its light).

A rock's own darker band (its shaded side, a vein of its skin) can show a
rise or a fall like a shadow's. In colour the two differ in hue: a shadow
keeps the ground's chromaticity, the band the rock's.
:func:`hue_from_ground` places a part in hue between the ground and the
rest of the rock, for the callers to keep on the rock a part that lies
near the rock's hue, whether the rays would cut it off or an inner outline
leaves it out (``rockscan.core.segment.finish.rock_hued``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rockscan.core.segment.channels import median_chromaticity
from rockscan.core.segment.split import largest_part
from rockscan.core.segment.stats import robust_spread
from rockscan.core.segment.trace import _core_and_ring, _fill_holes, _sample_at

__all__ = ["Region", "hue_from_ground", "measured_region", "ray_profiles", "shadow_left_out", "shadow_off"]

#: Rays cast from the rock's centre.
RAYS = 256
#: Spacing of the samples along a ray, in pixels.
SPACING = 0.5
#: Half the distance a rise is measured over, in pixels (the occluding edge
#: is sharp: a few pixels of blur at most).
HALF_RISE = 2.0
#: Smallest rise, as a share of the step from the rock's level to the ground's.
RISE = 0.35
#: ... and in units of the ground's robust spread around the rock. On a
#: textured ground that spread is much of the step, and at 2 a shadow's
#: rises were refused. Development photos 0-39 at IoU >= 0.9: 397 at 2;
#: 398 at 1.5; 399 at 1.25, 1 and 0.5, none across the line downward (1
#: kept; one photo 0.925 -> 0.909); photos 200-259,
#: not used to choose: one up, none down. The flat band and the smooth arc
#: away from the light still keep texture on a rock from passing as a shadow.
NOISE = 1.0
#: Least width of a shadow band, in pixels.
MIN_BAND = 3.0
#: Largest interquartile range of a band's profile, as a share of the step:
#: a shadow is the ground darkened, flat beside the rock's own texture.
FLAT = 0.3
#: Shortest and longest arc of the outline a shadow lies along, as shares
#: of the rays. (0.05 gained one more development photo with ``NOISE`` at 1,
#: but notched rocks of the rockscan renderer: a fitted outline 3% off.)
MIN_ARC, MAX_ARC = 0.08, 0.8
#: Least share of an arc's rays that show a rise of their own.
SHOWN = 0.6
#: How far, as a share of the step, the valley before a rise may lie above
#: the rock's level, and the band beyond it must lie below the ground's.
MARGIN = 0.25
#: Largest median change of the shadow's width from one ray to the next, as
#: a share of its median width (at least a pixel).
ROUGH = 0.15
#: For a rock lighter than the ground: the least median fall along the arc
#: from the rock's rim to the shadow, the least median depth of the shadow's
#: band below the ground, both as shares of the step from the ground's level
#: to the rock's, and the least median spread (interquartile range) of the
#: band as a share of the ground's robust spread. Chosen on development
#: photos 0-39 and 200-239 of every one-rock condition and crops (960): of
#: the rocks whose rays show a fall, a cut by these rules moves 10 outlines
#: above IoU 0.9 and one below it (0.901 -> 0.889), for any spread share
#: from 0.2 to 0.25 (0.28: none below, 0.3: 8 above; 0 or 0.1: 5 below,
#: smooth shaded sides cut off on textured ground) and any depth from 0.6 to 1.0
#: (0.5: 2 below). The depth is held low, at 0.6: the shadows of the
#: physical model in ``tests/test_segment_shadow.py``, in soft light, lie
#: 0.73 deep. On development photos 240-279, not used to choose: 5 above,
#: 2 below (a textured rock's dark rim cut off).
LIGHT_FALL, LIGHT_DEEP, LIGHT_TEXTURE = 0.6, 0.6, 0.25
#: Longest outline after the cut, as a share of the outline before it.
LONGER = 1.05
#: Smallest region, in pixels, that is looked at.
MIN_AREA = 50
#: A shadow seen on part of its arc only, flooded from there: how far off the
#: rise on the arc, and off the outline, its seeds lie (pixels); where the
#: rock's seeds begin on the far side of the centre (a share of the rock's
#: equivalent radius); and the least median slope along the cut, as a share of
#: the step from the rock's level to the ground's per pixel (of the log
#: brightness smoothed by a pixel, by Sobel's operator).
GROWN_GAP = 2.0
GROWN_ROCK = 0.3
GROWN_EDGE = 0.5
#: Largest interquartile range of the part cut off, as a share of the step.
GROWN_FLAT = 0.45
#: Least share of the outline's area the rock keeps: a flood that took most
#: of it ran into the rock (from a pit).
GROWN_KEEP = 0.4
#: A region both lighter and darker than the ground (a light rock and its
#: black shadow): how far below the ground's level (log brightness, and in
#: units of the ground's spread) and above it a pixel counts as dark or
#: light; the least shares of the region's area that are dark and light;
#: where the rock's seeds begin, as a share of the way from the shadow's
#: level up to the ground's; and the least and largest interquartile range
#: of the part cut off, in units of the ground's spread.
TWO_DARK, TWO_NOISE, TWO_LIGHT = 0.3, 3.0, 0.1
TWO_SHARES = (0.1, 0.15)
TWO_SEED = 0.5
TWO_GRAIN, TWO_FLAT = 0.5, 3.0
#: How far past the part cut off the ground is looked at (pixels), and how
#: much lighter than that part it must be there, as a share of its depth
#: below the ground's level.
TWO_RING = 4
TWO_PAST = 0.5
#: Area of an outline inside the chosen one, as a share of the chosen's, for
#: it to be the rock without a shadow the chosen one took in.
INNER_SHARE = (0.4, 0.92)
#: Least share of such an outline that lies inside the chosen one.
INNER_INSIDE = 0.95
#: Largest spread (interquartile range of the log brightness) of the part
#: left out, as a multiple of the ground's: a shadow is the ground darkened.
GROUND_LIKE = 2.0
#: Smallest part left out, in pixels (after one pixel's erosion).
MIN_LEFT = 20
#: How much darker than the rock's core the part left out must be, as a
#: share of the step from the rock's level to the ground's (sensor noise
#: alone makes a rock's shaded side a little darker than its core).
DARKER = 0.25
#: Least share of the ground's brightness that a shadow keeps: it is lit by
#: the sky. Darker than that, a part is the rock's own black (or the
#: sensor's), whose spread says nothing.
SKY = 0.2


def shadow_off(
    gray: NDArray[np.floating], mask: NDArray[np.bool_], region: Region | None = None
) -> NDArray[np.bool_]:
    """The rock's mask with a cast shadow that joined it taken off (module docstring).

    Parameters
    ----------
    gray : (rows, cols) ndarray of float
        Log brightness of the photo around the rock, on the mask's grid,
        with a margin of at least a third of the rock's radius.
    mask : (rows, cols) ndarray of bool
        The rock's region (one piece, holes filled).
    region : Region, optional
        ``measured_region(gray, mask, MIN_AREA)``, when already measured.

    Returns
    -------
    (rows, cols) ndarray of bool
        The rock without its shadow: one 4-connected piece, holes filled.
        ``mask`` itself, unchanged, when no shadow was found.
    """
    if region is None:
        region = measured_region(gray, mask, MIN_AREA)
    if region is None:
        return mask
    # The flood first: where the outline is both lighter and darker than the
    # ground, the rays may cut part of a black shadow and leave the rest.
    kept = _two_sided_off(gray, mask, region)
    return kept if kept is not mask else _rays_off(gray, mask, region)


def _rays_off(gray: NDArray[np.floating], mask: NDArray[np.bool_], region: Region) -> NDArray[np.bool_]:
    """The mask with the shadow the rays show taken off, or flooded from
    where they show it (module docstring); ``mask`` itself when they show none."""
    import cv2

    mask8, centre, area, (rock, ground, noise) = region
    step = ground - rock
    if step == 0:
        return mask
    angles, radii, inside, profiles = ray_profiles(
        gray, mask8, centre, 2.0 * HALF_RISE + 2.0, RAYS, SPACING, 1.0
    )
    reach = float(radii[-1]) + SPACING
    if step > 0:
        edges = _inner_edges(profiles, inside, rock, ground, step, noise)
    else:
        edges = _inner_falls(profiles, inside, ground, -step, noise)
    if edges is None:
        return mask
    arc, limit, depth = edges
    if not _smooth_arc(depth):
        return mask
    start = limit * SPACING + 0.5
    away = _away_from_light(gray, mask8, centre, angles[arc])
    if away:
        kept = mask & (_beyond(mask.shape, centre, angles[arc], start, reach) == 0)
        if cv2.countNonZero(kept.view(np.uint8)) == area:
            return mask
        kept = largest_part(kept)
        if kept is None:
            return mask
        kept = _fill_holes(kept)
        # Cut off along the rock's edge, a shadow leaves an outline no longer
        # than before; a cut that lengthens it has notched the rock (teeth at a
        # sharp corner, a slit along an arm), where rays cross its edge obliquely.
        if _perimeter(kept) <= LONGER * _perimeter(mask):
            return kept
    # A long shadow: the rays cross its edge with the rock on part of it
    # only, and its light weighs on the lit side found.
    return _grown_off(gray, mask, region, angles[arc], start, reach, away) if step > 0 else mask


def _grown_off(
    gray: NDArray[np.floating],
    mask: NDArray[np.bool_],
    region: Region,
    angles: NDArray[np.float64],
    limit: NDArray[np.float64],
    reach: float,
    away: bool,
) -> NDArray[np.bool_]:
    """The mask with a shadow seen on part of its arc only taken off, as far as
    the shadow reaches (module docstring); ``mask`` itself when the rock would
    keep too little of it, the cut does not follow an edge, the part cut off
    is not flat, or the outline would lengthen.

    ``angles`` and ``limit`` are the arc's rays and where on each the rock
    ends (pixels from the centre); ``away``, whether the arc lies away from
    the lit side of rock and shadow together.
    """
    import cv2

    mask8, centre, area, (rock_level, ground, _) = region
    step = ground - rock_level
    radius = math.sqrt(area / math.pi)
    inside = cv2.distanceTransform(mask8, cv2.DIST_L2, 3)
    # Seeds a little off the rock's edge and off the outline's own blurred
    # edge: the shadow beyond the rise on the arc, the rock on the far side
    # of the centre, away from the arc.
    shadow = (_beyond(mask.shape, centre, angles, limit + GROWN_GAP, reach) > 0) & (inside > GROWN_GAP)
    rock = _beyond(mask.shape, centre, angles + math.pi, np.full(angles.size, GROWN_ROCK * radius), reach) > 0
    rock &= (inside > max(GROWN_GAP, 0.1 * radius)) & ~shadow
    if np.count_nonzero(shadow) < MIN_LEFT or np.count_nonzero(rock) < MIN_LEFT:
        return mask
    flooded = _flooded(gray, mask, rock, shadow, inside, area)
    if flooded is None:
        return mask
    kept, cut, slope_along = flooded
    # The line between rock and shadow is an edge; a flood that stopped in
    # the rock's own smooth shading (a pit, a fold) is not.
    if slope_along < GROWN_EDGE * step:
        return mask
    # A shadow is the ground darkened, flat beside a textured rock's own
    # darker half.
    if _median_and_iqr(gray, cut)[1] > GROWN_FLAT * step:
        return mask
    if _perimeter(kept) > LONGER * _perimeter(mask):
        return mask
    if away:
        return kept
    kept8 = kept.astype(np.uint8)
    return kept if _away_from_light(gray, kept8, _centre(kept8), angles) else mask


def _two_sided_off(gray: NDArray[np.floating], mask: NDArray[np.bool_], region: Region) -> NDArray[np.bool_]:
    """The mask with a black shadow beside a light rock taken off, where the
    region is both lighter and darker than the ground (module docstring);
    ``mask`` itself when it is not, or when the cut fails a rule."""
    import cv2

    mask8, _, area, (_, ground, noise) = region
    inside = cv2.distanceTransform(mask8, cv2.DIST_L2, 3)
    core = inside > GROWN_GAP
    dark = core & (gray < ground - max(TWO_DARK, TWO_NOISE * noise))
    light = core & (gray > ground + max(TWO_LIGHT, noise))
    if np.count_nonzero(dark) < TWO_SHARES[0] * area or np.count_nonzero(light) < TWO_SHARES[1] * area:
        return mask
    shadow = largest_part(dark)
    if shadow is None:
        return mask
    # Imported here: most outlines are not two-sided and never need it.
    from skimage.filters import threshold_otsu

    shadow8 = shadow.astype(np.uint8)
    # The dark part may hold the rock's shaded side beside its shadow; the
    # shadow is the darker of the two (a light rock's albedo is the higher).
    seeds = cv2.distanceTransform(shadow8, cv2.DIST_L2, 3) > GROWN_GAP
    seeds &= gray <= threshold_otsu(gray[shadow])
    if np.count_nonzero(seeds) < MIN_LEFT:
        return mask
    level = float(np.median(gray[seeds]))
    # Rock seeds: lighter than the shadow by a share of its depth below the
    # ground (a light rock's shaded side is, by the ratio of the albedos),
    # and a little off the shadow's seeds.
    rock = core & (gray > level + TWO_SEED * (ground - level))
    rock &= cv2.dilate(seeds.astype(np.uint8), np.ones((5, 5), np.uint8)) == 0
    if np.count_nonzero(rock) < MIN_LEFT:
        return mask
    flooded = _flooded(gray, mask, rock, seeds, inside, area)
    if flooded is None:
        return mask
    kept, cut, slope_along = flooded
    # A shadow is darker than the ground it lies on.
    depth = ground - float(np.median(gray[cut]))
    if depth <= 0 or slope_along < GROWN_EDGE * depth:
        return mask
    # The shadow is the ground darkened: its grain is the ground's, no
    # coarser (the rock's own shaded side carries its texture and shading)
    # and no finer (a smooth facet of the rock turned from the light has none).
    flat = cut & core
    if not flat.any() or not TWO_GRAIN * noise <= _median_and_iqr(gray, flat)[1] <= TWO_FLAT * noise:
        return mask
    # Past a shadow's outer edge the ground is lit; past a light rock's own
    # shaded side lies its cast shadow, darker still.
    cut8 = cut.astype(np.uint8)
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * TWO_RING + 1, 2 * TWO_RING + 1))
    past = (cv2.dilate(cut8, disc) > 0) & (cv2.dilate(mask8, np.ones((3, 3), np.uint8)) == 0)
    if not past.any() or float(np.median(gray[past])) - (ground - depth) < TWO_PAST * depth:
        return mask
    if _perimeter(kept) > LONGER * _perimeter(mask):
        return mask
    kept8 = kept.astype(np.uint8)
    kept_centre, cut_centre = _centre(kept8), _centre(cut8)
    towards = math.atan2(cut_centre[0] - kept_centre[0], cut_centre[1] - kept_centre[1])
    return kept if _away_from_light(gray, kept8, kept_centre, np.array([towards])) else mask


def _flooded(
    gray: NDArray[np.floating],
    mask: NDArray[np.bool_],
    rock: NDArray[np.bool_],
    shadow: NDArray[np.bool_],
    inside: NDArray[np.float32],
    area: float,
) -> tuple[NDArray[np.bool_], NDArray[np.bool_], float] | None:
    """A watershed of the photo's slope inside ``mask`` from seeds of rock
    and of shadow: the rock (its largest piece, holes filled), the part cut
    off, and the median slope along the line between them, away from the
    outline's own blurred edge (``inside``: distance to the outline). None
    when nothing is cut, the rock would keep under ``GROWN_KEEP`` of
    ``area``, or no part of that line lies away from the outline's edge.

    The slope is Sobel's magnitude of ``gray`` smoothed by a pixel.
    """
    import cv2
    from skimage.segmentation import watershed

    smooth = cv2.GaussianBlur(gray.astype(np.float32), (0, 0), 1.0)
    slope = cv2.magnitude(cv2.Sobel(smooth, cv2.CV_32F, 1, 0), cv2.Sobel(smooth, cv2.CV_32F, 0, 1))
    markers = rock.astype(np.int32) + 2 * shadow.astype(np.int32)
    kept = largest_part(mask & (watershed(slope, markers, mask=mask) != 2))
    if kept is None:
        return None
    kept = _fill_holes(kept)
    cut = mask & ~kept
    if not cut.any() or np.count_nonzero(kept) < GROWN_KEEP * area:
        return None
    kept8 = kept.astype(np.uint8)
    line = (kept8 > cv2.erode(kept8, np.ones((3, 3), np.uint8))) & (inside > GROWN_GAP)
    if not line.any():
        return None
    return kept, cut, float(np.median(slope[line]))


def _centre(mask8: NDArray[np.uint8]) -> tuple[float, float]:
    """The centre (row, col) of a non-empty region of 0/1 bytes."""
    import cv2

    moments = cv2.moments(mask8, binaryImage=True)
    return moments["m01"] / moments["m00"], moments["m10"] / moments["m00"]


#: A region as 0/1 bytes, its centre (row, col), its area and its levels
#: (the rock's, the ground's, the ground's spread).
Region = tuple[NDArray[np.uint8], tuple[float, float], float, tuple[float, float, float]]


def measured_region(gray: NDArray[np.floating], mask: NDArray[np.bool_], min_area: int) -> Region | None:
    """A region as 0/1 bytes, its centre (row, col), its area and its levels
    (the rock's, the ground's and the ground's spread, ``_levels``); None
    when it is smaller than ``min_area`` pixels or has too little core or ring."""
    import cv2

    mask8 = mask.astype(np.uint8)
    moments = cv2.moments(mask8, binaryImage=True)
    area = moments["m00"]
    if area < min_area:
        return None
    levels = _levels(gray, mask8, math.sqrt(area / math.pi))
    if levels is None:
        return None
    return mask8, (moments["m01"] / area, moments["m10"] / area), area, levels


def ray_profiles(
    gray: NDArray[np.floating],
    mask8: NDArray[np.uint8],
    centre: tuple[float, float],
    beyond: float,
    rays: int,
    spacing: float,
    blur: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_], NDArray[np.float32]]:
    """Profiles of ``gray`` and of a region along rays from ``centre``.

    The rays (``rays`` of them, evenly turned) reach ``beyond`` pixels past the
    farthest corner of the region's bounding box, sampled every ``spacing``
    pixels; ``gray`` is smoothed by a Gaussian of ``blur`` pixels first (0:
    not at all). Returns the rays' angles, the samples' distances from the
    centre, whether each sample is in the region, and the profiles (the
    window's edge value repeated past it).
    """
    import cv2

    x, y, w, h = cv2.boundingRect(mask8)
    corners = np.array([[y, x], [y, x + w], [y + h, x], [y + h, x + w]], np.float64)
    reach = float(np.hypot(*(corners - centre).T).max()) + beyond
    angles = np.arange(rays) * (2.0 * math.pi / rays)
    radii = np.arange(0.0, reach, spacing)
    map_x = (centre[1] + np.outer(np.cos(angles), radii)).astype(np.float32)
    map_y = (centre[0] + np.outer(np.sin(angles), radii)).astype(np.float32)
    inside = cv2.remap(mask8, map_x, map_y, cv2.INTER_NEAREST, borderValue=0) > 0
    image = gray.astype(np.float32)
    if blur > 0:
        image = cv2.GaussianBlur(image, (0, 0), blur)
    profiles = cv2.remap(image, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    return angles, radii, inside, profiles


def shadow_left_out(
    gray: NDArray[np.floating], outer: NDArray[np.bool_], inners: list[NDArray[np.bool_]]
) -> int | None:
    """Which of several outlines inside a chosen one leaves out a cast shadow that it took in.

    When the rock is lighter than its shadow (a textured rock, a dark rock
    in sky light), the ray test of :func:`shadow_off` sees no rise from rim
    to shadow; but other cues may have outlined the rock alone. The part of
    the chosen outline that such an inner outline leaves out is a shadow if
    it is what the ground's shadow is and the rock is not:

    * darker than the ground (the rock being darker than the ground too)
      and than the rock's core, which the light reaches, by at least
      ``DARKER`` of the rock's step to the ground; but keeping at least
      ``SKY`` of the ground's brightness, as ground in sky light does;
    * no more varied than the rock's core, and at most ``GROUND_LIKE``
      times the ground's spread: darkened ground keeps the ground's texture,
      a rock's own shaded side keeps the rock's shading and texture;
    * on the side of the inner outline away from its lit side.

    Parameters
    ----------
    gray : (rows, cols) ndarray of float
        Log brightness of the photo around the rock, on the masks' grid,
        with a margin of at least a third of the rock's radius.
    outer : (rows, cols) ndarray of bool
        The chosen outline's region.
    inners : list of (rows, cols) ndarray of bool
        Other outlines' regions, the most probable first.

    Returns
    -------
    int or None
        Index in ``inners`` of the first that is the rock without a shadow
        ``outer`` took in; None if none is.
    """
    import cv2

    outer8 = outer.astype(np.uint8)
    area = cv2.countNonZero(outer8)
    if area < MIN_AREA:
        return None
    _, ring = _core_and_ring(outer8, math.sqrt(area / math.pi))
    if np.count_nonzero(ring) < 8:
        return None
    ground, ground_spread = _median_and_iqr(gray, ring)
    for index, inner in enumerate(inners):
        inner8 = inner.astype(np.uint8)
        size = cv2.countNonZero(inner8)
        if not INNER_SHARE[0] * area <= size <= INNER_SHARE[1] * area:
            continue
        if cv2.countNonZero(inner8 & outer8) < INNER_INSIDE * size:
            continue
        left = cv2.erode(outer8 & (1 - inner8), np.ones((3, 3), np.uint8)) > 0
        core, _ = _core_and_ring(inner8, math.sqrt(size / math.pi))
        if np.count_nonzero(left) < MIN_LEFT or np.count_nonzero(core) < 8:
            continue
        rock, rock_spread = _median_and_iqr(gray, core)
        level, spread = _median_and_iqr(gray, left)
        darker = level <= rock - DARKER * (ground - rock) and level >= ground + math.log(SKY)
        if not (rock < ground and darker and spread <= min(rock_spread, GROUND_LIKE * ground_spread)):
            continue
        centre = _centre(inner8)
        ys, xs = np.nonzero(left)
        towards = np.array([math.atan2(ys.mean() - centre[0], xs.mean() - centre[1])])
        if _away_from_light(gray, inner8, centre, towards):
            return index
    return None


def hue_from_ground(
    colour: NDArray[np.floating], rock: NDArray[np.bool_], part: NDArray[np.bool_]
) -> float | None:
    """Where a part of a rock's region, taken for its cast shadow, lies in hue
    from the ground's (0) to the rest of the rock's (1).

    A cast shadow is the ground's own surface, darkened: its chromaticity
    ``rgb / (r + g + b)`` stays the ground's, while a rock's own shaded side
    or a darker band of its skin keeps the rock's. The part's median
    chromaticity is compared with that of the core of the rock without it
    and of the ring of ground round the whole region (``trace``'s core and
    ring); pixels too dark to have a hue do not count
    (``channels.median_chromaticity``).

    Parameters
    ----------
    colour : (rows, cols, 3) ndarray of float
        Red, green and blue in [0, 1] around the rock, on the masks' grid.
    rock : (rows, cols) ndarray of bool
        The rock's region with the part.
    part : (rows, cols) ndarray of bool
        The part taken for a shadow, inside ``rock``.

    Returns
    -------
    float or None
        ``0.5 + (d_ground - d_rock) / (2 d)``, from the part's distances in
        chromaticity to the ground's and the rock's and theirs to each other:
        the part's place along the line from ground to rock (1 at the rock's
        hue, 0 at the ground's, 0.5 as near either). None when any of the
        three has too few pixels with a hue, or the rock and the ground have
        the same.
    """
    rock8 = rock.astype(np.uint8)
    rest8 = rock8 & (1 - part.astype(np.uint8))
    _, ring = _core_and_ring(rock8, math.sqrt(np.count_nonzero(rock8) / math.pi))
    core, _ = _core_and_ring(rest8, math.sqrt(np.count_nonzero(rest8) / math.pi))
    hues = [_chromaticity(colour, where) for where in (part, core, ring)]
    if any(hue is None for hue in hues):
        return None
    hue, rest, ground = hues
    apart = float(np.hypot(*(rest - ground)))
    if apart == 0.0:
        return None
    return 0.5 + float(np.hypot(*(hue - ground)) - np.hypot(*(hue - rest))) / (2.0 * apart)


#: Least pixels with a hue for a median chromaticity.
MIN_HUED = 10


def _chromaticity(colour: NDArray[np.floating], where: NDArray[np.bool_]) -> NDArray[np.float64] | None:
    """Median red and green shares ``(r, g) / (r + g + b)`` of the pixels
    where ``where`` holds that are bright enough to have a hue; None when
    fewer than ``MIN_HUED`` are."""
    hue = median_chromaticity(colour.reshape(-1, 3)[_sample_at(where)].astype(np.float64), MIN_HUED)
    return None if hue is None else hue[:2]


def _median_and_iqr(gray: NDArray[np.floating], where: NDArray[np.bool_]) -> tuple[float, float]:
    """Median and interquartile range of ``gray`` where ``where`` holds (sampled evenly)."""
    low, middle, high = np.percentile(gray.ravel()[_sample_at(where)], (25, 50, 75))
    return float(middle), float(high - low)


def _perimeter(mask: NDArray[np.bool_]) -> float:
    """Length of the outer outline of a mask, in pixels."""
    import cv2

    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    return float(sum(cv2.arcLength(c, True) for c in contours))


def _levels(
    gray: NDArray[np.floating], mask8: NDArray[np.uint8], radius: float
) -> tuple[float, float, float] | None:
    """The rock's level (median of its core), the ground's (median of a ring
    round it) and the ground's robust spread; None without enough of either."""

    core, ring = _core_and_ring(mask8, radius)
    if np.count_nonzero(core) < 8 or np.count_nonzero(ring) < 8:
        return None
    # Medians of a few thousand evenly spaced pixels: the levels need no more.
    ground_values = gray.ravel()[_sample_at(ring)]
    rock, ground = float(np.median(gray.ravel()[_sample_at(core)])), float(np.median(ground_values))
    noise = robust_spread(ground_values, ground)
    return rock, ground, noise


@dataclass(frozen=True)
class _Rises:
    """Along each ray: the first sample outside the region (``leaves``), the
    steepest rise inside it (``at``, ``height``), the lowest level just
    before the rise (``valley``), and where the outline's own blurred edge
    begins (``edge``)."""

    leaves: NDArray[np.int64]
    at: NDArray[np.int64]
    height: NDArray[np.float32]
    valley: NDArray[np.float32]
    edge: NDArray[np.int64]
    room: NDArray[np.bool_]


def _rises(
    profiles: NDArray[np.float32], inside: NDArray[np.bool_], outermost: float | None = None
) -> _Rises:
    """The steepest rise of each ray's profile, far enough inside the outline
    to leave room for a band of ``MIN_BAND`` pixels before its blurred edge;
    with ``outermost``, the steepest of the outermost run of rises of at
    least that height (the steepest where a ray has none)."""
    rays, length = profiles.shape
    half = max(1, round(HALF_RISE / SPACING))
    # First sample outside the region along each ray; a ray that starts
    # outside (a concave region's centre) shows nothing.
    leaves = np.argmax(~inside, axis=1)
    index = np.arange(length)
    rise = np.full(profiles.shape, -np.inf, np.float32)
    rise[:, half : length - half] = profiles[:, 2 * half :] - profiles[:, : length - 2 * half]
    lo = np.maximum((0.4 * leaves).astype(np.int64), half)
    # The outline's own edge is blurred over half a rise's width inside it.
    edge = leaves - 1 - half
    hi = edge - half - round(MIN_BAND / SPACING)
    rise = np.where((index >= lo[:, None]) & (index < hi[:, None]), rise, -np.inf)
    if outermost is None:
        at = np.argmax(rise, axis=1)
    else:
        at = _outermost_run_top(rise, outermost)
    before = (index >= (at - 3 * half)[:, None]) & (index <= at[:, None])
    return _Rises(
        leaves=leaves,
        at=at,
        height=rise[np.arange(rays), at],
        valley=np.where(before, profiles, np.inf).min(axis=1),
        edge=edge,
        room=(~inside).any(axis=1) & (leaves >= 4) & (hi - lo > 2),
    )


def _outermost_run_top(rise: NDArray[np.float32], least: float) -> NDArray[np.int64]:
    """On each row, the index of the largest value of the last run of values
    of at least ``least``; of the row's largest value where there is none."""
    length = rise.shape[1]
    index = np.arange(length)
    big = rise >= least
    last = np.where(big.any(axis=1), length - 1 - np.argmax(big[:, ::-1], axis=1), length - 1)
    first = np.where(~big & (index <= last[:, None]), index, -1).max(axis=1) + 1
    run = (index >= first[:, None]) & (index <= last[:, None])
    at = np.argmax(np.where(run, rise, -np.inf), axis=1)
    return np.where(big.any(axis=1), at, np.argmax(rise, axis=1))


def _flat_bands(
    profiles: NDArray[np.float32], rises: _Rises, rays: NDArray[np.int64], ground: float, step: float
) -> NDArray[np.bool_]:
    """Whether, on each of ``rays``, the band from the rise to the outline's
    edge is flat, well above the valley and darker than the ground."""
    low, middle, high = _band_quartiles(profiles, rises, rays)
    return (
        (high - low <= FLAT * step)
        & (middle >= rises.valley[rays] + RISE * step)
        & (middle <= ground - MARGIN * step)
    )


def _band_quartiles(
    profiles: NDArray[np.float32], rises: _Rises, rays: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Quartiles of the band from the rise to the outline's edge on each of ``rays``."""
    half = max(1, round(HALF_RISE / SPACING))
    # Only samples inside the outline can be in a band.
    span = int(rises.edge[rays].max())
    index = np.arange(span)
    band = (index >= (rises.at[rays] + half)[:, None]) & (index < rises.edge[rays][:, None])
    return _row_quantiles(profiles[rays, :span], band, (0.25, 0.5, 0.75))


#: Along the arc of rays that shows a shadow: the rays, where on each the rock
#: ends (sample index) and how wide the shadow is there (pixels).
_ArcEdges = tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]


def _inner_edges(
    profiles: NDArray[np.float32],
    inside: NDArray[np.bool_],
    rock: float,
    ground: float,
    step: float,
    noise: float,
) -> _ArcEdges | None:
    """The arc of rays that show a shadow, where on each the rock ends
    (sample index) and how wide the shadow is there (pixels); None without one."""
    rays = profiles.shape[0]
    rises = _rises(profiles, inside)
    shows = (
        rises.room
        & (rises.height >= RISE * step)
        & (rises.height >= NOISE * noise)
        & (rises.valley <= rock + MARGIN * step)
    )
    if np.count_nonzero(shows) < SHOWN * MIN_ARC * rays:
        return None
    # The bands are looked at on the rays still in question only (their
    # quantiles sort every sample of a ray).
    asked = np.flatnonzero(shows)
    shows[asked] = _flat_bands(profiles, rises, asked, ground, step)
    arc = _shown_arc(shows)
    return None if arc is None else _arc_edges(rises, arc, shows[arc])


def _shown_arc(shows: NDArray[np.bool_]) -> NDArray[np.int64] | None:
    """The rays of the one arc that shows a shadow (``MIN_ARC`` to ``MAX_ARC``
    of them, ``SHOWN`` of its rays showing one of their own); None without one."""
    rays = shows.size
    arc = _longest_arc(shows)
    if arc is None or not MIN_ARC * rays <= arc.size <= MAX_ARC * rays:
        return None
    if np.count_nonzero(shows[arc]) < SHOWN * arc.size:
        return None
    return arc


def _arc_edges(rises: _Rises, arc: NDArray[np.int64], found: NDArray[np.bool_]) -> _ArcEdges | None:
    """Along an arc, where the rock ends (sample index, smoothed) and how wide
    the shadow is (pixels); None when it is narrower than ``MIN_BAND``."""
    # Rays of the arc without a rise of their own take their neighbours'.
    steps = np.arange(arc.size)
    limit = np.interp(steps, steps[found], rises.at[arc][found].astype(np.float64))
    depth = (rises.leaves[arc] - limit) * SPACING
    if np.median(depth) < MIN_BAND:
        return None
    from scipy.ndimage import median_filter

    return arc, median_filter(limit, size=5, mode="nearest"), depth


def _inner_falls(
    profiles: NDArray[np.float32],
    inside: NDArray[np.bool_],
    ground: float,
    step: float,
    noise: float,
) -> _ArcEdges | None:
    """For a rock lighter than the ground (``step`` its level above the
    ground's): the arc of rays whose last fall leads from the rock's rim to a
    shadow's band, where on each the rock ends (sample index) and how wide
    the shadow is there (pixels); None without one (module docstring)."""
    rays = profiles.shape[0]
    # A fall is a rise of the negated profile; the occluding edge is the
    # last fall before the outline, the rock's own shading lies inside it.
    falls = _rises(-profiles, inside, outermost=RISE * step)
    shows = falls.room & (falls.height >= RISE * step) & (falls.height >= NOISE * noise)
    if np.count_nonzero(shows) < SHOWN * MIN_ARC * rays:
        return None
    asked = np.flatnonzero(shows)
    low, middle, high = _band_quartiles(profiles, falls, asked)
    rim = -falls.valley[asked]
    shows[asked] = (
        (high - low <= FLAT * step) & (middle <= rim - RISE * step) & (middle <= ground - MARGIN * step)
    )
    arc = _shown_arc(shows)
    if arc is None:
        return None
    spread, level = np.full(rays, np.nan), np.full(rays, np.nan)
    spread[asked], level[asked] = high - low, middle
    if not (
        np.nanmedian(falls.height[arc]) >= LIGHT_FALL * step
        and ground - np.nanmedian(level[arc]) >= LIGHT_DEEP * step
        and np.nanmedian(spread[arc]) >= LIGHT_TEXTURE * noise
    ):
        return None
    return _arc_edges(falls, arc, shows[arc])


def _row_quantiles(
    values: NDArray[np.float32], where: NDArray[np.bool_], quantiles: tuple[float, ...]
) -> tuple[NDArray[np.float64], ...]:
    """Quantiles of each row's values where ``where`` holds (at least one per row),
    taken from the sorted values (lower order statistic)."""
    ordered = np.sort(np.where(where, values, np.inf), axis=1)
    count = where.sum(axis=1)
    rows = np.arange(values.shape[0])
    return tuple(
        ordered[rows, np.clip(np.floor(q * (count - 1)).astype(np.int64), 0, None)].astype(np.float64)
        for q in quantiles
    )


def _longest_arc(flags: NDArray[np.bool_]) -> NDArray[np.int64] | None:
    """Ray indices of the longest circular run of ``flags`` after a majority
    vote of five neighbours (a lone ray neither makes nor breaks an arc)."""
    wrapped = np.concatenate([flags[-2:], flags, flags[:2]]).astype(np.int8)
    held = np.convolve(wrapped, np.ones(5, np.int8), mode="valid") >= 3
    if not held.any() or held.all():
        return None
    start = int(np.argmin(held))
    rolled = np.roll(held, -start)
    # Runs of the rolled flags (it starts with a False, so none wraps round).
    edges = np.diff(np.concatenate([[0], rolled.astype(np.int8), [0]]))
    begins, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    longest = int(np.argmax(ends - begins))
    return (np.arange(begins[longest], ends[longest]) + start) % flags.size


def _smooth_arc(depth: NDArray[np.float64]) -> bool:
    """Whether the shadow's width changes smoothly along the arc."""
    width = float(np.median(depth))
    return float(np.median(np.abs(np.diff(depth)))) <= max(1.0, ROUGH * width)


def _away_from_light(
    gray: NDArray[np.floating],
    mask8: NDArray[np.uint8],
    centre: tuple[float, float],
    angles: NDArray[np.float64],
) -> bool:
    """Whether the arc lies on the side away from the rock's lit side.

    The lit side is where the rock's brightness (above its darkest pixel) is
    centred, off the rock's centre; a shadow falls the other way.
    """
    import cv2

    darkest = cv2.minMaxLoc(gray.astype(np.float32), mask=mask8)[0]
    weights = np.where(mask8 > 0, gray - darkest, 0.0).astype(np.float32)
    moments = cv2.moments(weights)
    if moments["m00"] <= 0:
        return True
    lit_y = moments["m01"] / moments["m00"] - centre[0]
    lit_x = moments["m10"] / moments["m00"] - centre[1]
    middle = math.atan2(float(np.sin(angles).mean()), float(np.cos(angles).mean()))
    return math.cos(middle) * lit_x + math.sin(middle) * lit_y <= 0


def _beyond(
    shape: tuple[int, int],
    centre: tuple[float, float],
    angles: NDArray[np.float64],
    limit: NDArray[np.float64],
    reach: float,
) -> NDArray[np.uint8]:
    """The part of the plane beyond ``limit`` along an arc of rays (non-zero there).

    The arc's ends reach half a ray's spacing past its first and last rays,
    so that consecutive arcs would tile the plane.
    """
    import cv2

    half = math.pi / RAYS
    turns = np.concatenate([[angles[0] - half], angles, [angles[-1] + half]])
    near = np.concatenate([[limit[0]], limit, [limit[-1]]])
    # A shadow's far side, out of the region: the outline lies within ``reach``.
    radii = np.concatenate([near, np.full(turns.size, reach + 2.0)])
    turns = np.concatenate([turns, turns[::-1]])
    points = np.column_stack([centre[1] + radii * np.cos(turns), centre[0] + radii * np.sin(turns)])
    out = np.zeros(shape, np.uint8)
    # Fixed point with 4 fractional bits: the cut runs between pixels.
    cv2.fillPoly(out, [np.round(points * 16).astype(np.int32)], 1, lineType=cv2.LINE_8, shift=4)
    return out
