"""An outline moved to the steepest edge beside it.

The outline is traced half-way between the rock's level and the ground's,
each read once for the whole rock (``rockscan.core.segment.trace``). Half-way
is where a clean step lies under any blur; but a rock's edge is seldom one
step. Its rim turns away from the light and darkens, or catches it and
brightens; a neighbour or the ground's own gradient beside it moves the
level the edge climbs to. There the half-way level runs a pixel or two off
the edge, and on a small rock (a crop of a crowded scene, a pebble) a pixel
all round is a tenth of its IoU.

The edge itself is where the brightness changes fastest across it, whatever
the levels on either side. Along rays from the rock's centre, each point
of the outline moves to the steepest change from rock to ground within
``REACH`` photo pixels of it, when that change is steeper than at the
outline itself (every gate a ramp, so that the outline is a continuous
function of the photo); the moves are median-smoothed over ``SMOOTH_RAYS`` rays, so
that one ray across the texture of a rock or of its ground moves nothing.
Only the band between the outline and its moved copy changes: a concave
outline's bays, which rays from the centre do not see, stay as they are.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rockscan.core.segment.shadow import ray_profiles

__all__ = ["Across", "across_outline", "last_crossing", "snapped"]

#: How far an outline point may move, in photo pixels, inward or outward.
#: A rim or a level off by the blur's width moves the half-way level by a
#: pixel or two; farther away lie other edges (a shadow's, a neighbour's, the
#: rock's own texture). On development photos of one rock (0-39 of every
#: condition) and crops 0-199, 1.0, 1.5, 2.0 and 2.5 px put 369, 372, 371
#: and 370 of 440 and 165, 166, 166 and 165 of 200 at IoU >= 0.9 (367 and 163
#: without; an earlier form that read the log brightness and moved every
#: outline).
REACH = 1.5
#: Rays cast from the rock's centre, and the spacing of samples along them (pixels).
RAYS = 360
SPACING = 0.25
#: Rays over which the moves are median-smoothed.
SMOOTH_RAYS = 5
#: Gaussian blur of the brightness before its slope is read, in pixels of
#: the grid: sensor noise and JPEG blocks make steep steps a pixel wide.
BLUR = 0.5
#: Moves under this share of the reach are no move: on a clean step the
#: steepest point and the half-way level lie within a fraction of a pixel,
#: and where they differ by so little which one is the edge is moot. A move
#: counts in full from here, in part from half of it. As a hard threshold
#: at 0, 0.5 and 0.67: development crops 200-399 at IoU >= 0.9, 150, 151 and
#: 147 of 200 (142 without); the real coins' median IoU against their
#: reference (traced at half-way), 0.974, 0.986 and 0.987 (0.989 without).
MIN_MOVE = 0.5
#: The edge must be steeper than at the outline by this share of its
#: slope for the outline to move there in full (less: in proportion). With
#: hard gates (any steeper edge, moves from MIN_MOVE), the bundled JPEG of a
#: three-faced rock matched its shape at distance 0.00229 with the latest
#: releases of the libraries and 0.00273 with the oldest declared: a ray
#: either side of a gate. With these ramps, 0.00259 and 0.00261 (at 0.1,
#: 0.00267 and 0.00281). Development crops 200-399: 151 of 200 with hard
#: gates, 152 at 0.1, 149 at 0.25; crops 0-199 163, 162, 162.
STEEPER = 0.25
#: How far past the reach, in pixels, the profiles run on either side of
#: the outline: the half-way level is found again on them between samples.
MARGIN = 2.0


def snapped(
    brightness: NDArray[np.floating],
    coverage: NDArray[np.floating],
    lighter: bool,
    reach: float = REACH,
) -> NDArray[np.float32] | None:
    """A rock's coverage with its outline moved to the steepest edge beside it (module docstring).

    Parameters
    ----------
    brightness : (rows, cols) ndarray of float
        The photo's brightness around the rock (pixel values, not their
        logarithm: a blur spreads light, and the steepest change of the log
        brightness lies towards the dark side of an edge), on the coverage's
        grid, with a margin of a few pixels round the rock.
    coverage : (rows, cols) ndarray of float
        The rock's coverage: 1 on the rock, 0 on the ground, its 0.5 level the outline.
    lighter : bool
        Whether the rock is lighter than its ground (its edge falls going out).
    reach : float
        How far a point may move, in pixels of the grid (``REACH`` photo pixels
        over the grid's scale).

    Returns
    -------
    (rows, cols) ndarray of float32 or None
        The coverage with its outline moved; None when nothing moved.
    """
    import cv2
    from scipy import ndimage

    if reach <= 0:
        return None
    # Profiles across the outline only: a band of the reach and a margin round it.
    span = reach + MARGIN
    image = cv2.GaussianBlur(np.asarray(brightness, np.float32), (0, 0), BLUR)
    rays = across_outline(coverage, image, span)
    if rays is None:
        return None
    profiles, at, seen, offsets = rays.profiles, rays.at, rays.seen, rays.offsets
    ray = np.arange(RAYS)

    # The fall from rock to ground along each ray, per pixel, and its
    # steepest point within the reach, between samples (the vertex of the
    # parabola through it and its neighbours).
    fall = np.gradient(profiles, SPACING, axis=1)
    if lighter:
        fall = -fall
    near = math.ceil(reach / SPACING)
    index = np.round(at).astype(np.int64)[:, None] + np.arange(-near, near + 1)[None, :]
    index = np.clip(index, 1, offsets.size - 2)
    window = np.take_along_axis(fall, index, axis=1)
    peak = index[ray, np.argmax(window, axis=1)]
    steepest, left, right = fall[ray, peak], fall[ray, peak - 1], fall[ray, peak + 1]
    curve = left - 2.0 * steepest + right
    bent = curve < 0
    vertex = np.where(bent, 0.5 * (left - right) / np.where(bent, curve, -1.0), 0.0)
    here = _at(fall, at)
    move = np.where(seen & (steepest > 0), np.clip((peak + vertex - at) * SPACING, -reach, reach), 0.0)
    # Every gate is a ramp, not a step, so that the outline is a continuous
    # function of the photo: a photo decoded or blurred a little differently
    # (another release of a library) moves it a little, not by a pixel.
    # A move counts fully from MIN_MOVE of the reach, not at all under half of that ...
    least = MIN_MOVE * reach
    move *= np.clip((np.abs(move) - 0.5 * least) / (0.5 * least), 0.0, 1.0)
    # ... and only where the edge is clearly steeper than at the outline.
    move *= np.clip((steepest - here) / np.maximum(STEEPER * steepest, 1e-12), 0.0, 1.0)
    move = ndimage.median_filter(move, size=SMOOTH_RAYS, mode="wrap")
    if not np.any(np.abs(move) > 1e-3):
        return None
    return _moved(rays.coverage, rays.inside, rays.centre, rays.edge, move, span)


@dataclass(frozen=True)
class Across:
    """Profiles across a rock's outline, along ``RAYS`` rays from its centre
    (:func:`across_outline`)."""

    #: The rock's coverage (float32) and its region as 0/1 bytes.
    coverage: NDArray[np.float32]
    inside: NDArray[np.uint8]
    #: The region's centre (row, col).
    centre: tuple[float, float]
    #: Each ray's outermost edge of the region, to a pixel (0: none).
    outline: NDArray[np.float64]
    #: Where the samples lie along each ray, from ``outline``, in pixels.
    offsets: NDArray[np.float64]
    #: The samples' columns and rows on the grid (rays, samples).
    map_x: NDArray[np.float32]
    map_y: NDArray[np.float32]
    #: The image along each ray (rays, samples).
    profiles: NDArray[np.float32]
    #: Where the coverage falls through 0.5 for the last time on each ray
    #: (sample units), and whether it does, on a ray that meets the rock.
    at: NDArray[np.float64]
    seen: NDArray[np.bool_]

    @property
    def edge(self) -> NDArray[np.float64]:
        """The outline's last crossing on each ray, in pixels from the centre."""
        return self.outline + self.offsets[0] + self.at * SPACING


def across_outline(coverage: NDArray[np.floating], image: NDArray[np.float32], span: float) -> Across | None:
    """The profiles of ``image`` across a rock's outline (its coverage's 0.5
    level), ``span`` pixels either side of its outermost edge on each ray,
    every ``SPACING``; None for an empty coverage."""
    import cv2

    coverage = np.ascontiguousarray(coverage, np.float32)
    inside = (coverage >= 0.5).view(np.uint8)
    moments = cv2.moments(inside, binaryImage=True)
    if moments["m00"] < 1:
        return None
    centre = (moments["m01"] / moments["m00"], moments["m10"] / moments["m00"])
    outline = _outermost(coverage, inside, centre)
    offsets = np.arange(-span, span + SPACING / 2, SPACING)
    angles = np.arange(RAYS) * (2.0 * math.pi / RAYS)
    radii = np.maximum(outline[:, None] + offsets[None, :], 0.0)
    map_x = (centre[1] + np.cos(angles)[:, None] * radii).astype(np.float32)
    map_y = (centre[0] + np.sin(angles)[:, None] * radii).astype(np.float32)
    cover = cv2.remap(coverage, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    profiles = cv2.remap(image, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    at, seen = last_crossing(cover)
    return Across(
        coverage, inside, centre, outline, offsets, map_x, map_y, profiles, at, seen & (outline > 0)
    )


def last_crossing(cover: NDArray[np.floating]) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Where each row of a coverage profile falls through 0.5 for the last
    time, between samples (sample units), and whether it does: the row
    reaches 0.5 somewhere and ends below it."""
    over = cover >= 0.5
    seen = over.any(axis=1) & ~over[:, -1]
    last = cover.shape[1] - 1 - np.argmax(over[:, ::-1], axis=1)
    ray = np.arange(cover.shape[0])
    after = np.minimum(last + 1, cover.shape[1] - 1)
    a, b = cover[ray, last], cover[ray, after]
    at = last + np.clip(np.where(a > b, (a - 0.5) / np.maximum(a - b, 1e-6), 0.0), 0.0, 1.0)
    return at, seen


def _outermost(
    coverage: NDArray[np.float32], inside: NDArray[np.uint8], centre: tuple[float, float]
) -> NDArray[np.float64]:
    """The distance from ``centre`` of the region's outermost edge along each
    ray, to a pixel (0 where a ray meets no rock); a ray that leaves the
    window on the rock finds none either."""
    _, radii, _, cover = ray_profiles(coverage, inside, centre, 1.0, RAYS, 1.0, 0.0)
    over = cover >= 0.5
    last = radii.size - 1 - np.argmax(over[:, ::-1], axis=1)
    return np.where(over.any(axis=1) & ~over[:, -1], radii[last] + 0.5, 0.0)


def _moved(
    coverage: NDArray[np.float32],
    inside: NDArray[np.uint8],
    centre: tuple[float, float],
    outline: NDArray[np.float64],
    move: NDArray[np.float64],
    span: float,
) -> NDArray[np.float32]:
    """The coverage with its ramp across the outline shifted out by ``move``
    along each ray (in), within ``span`` pixels of the outline."""
    import cv2

    contours, _ = cv2.findContours(inside, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    band = np.zeros(coverage.shape, np.uint8)
    cv2.drawContours(band, contours, -1, 1, thickness=2 * math.ceil(span) + 1)
    cols, rows = cv2.findNonZero(band).reshape(-1, 2).T
    dy, dx = rows - centre[0], cols - centre[1]
    turn = (np.arctan2(dy, dx) * (RAYS / (2.0 * math.pi))) % RAYS
    shift = np.interp(turn, np.arange(RAYS + 1), np.r_[move, move[0]])
    # Only near the outer edge along each ray: a concave outline's bays,
    # which rays from the centre do not see, stay as they are.
    distance = np.hypot(dy, dx)
    edge = np.interp(turn, np.arange(RAYS + 1), np.r_[outline, outline[0]])
    shift[np.abs(distance - edge) > span + 1.0] = 0.0
    scale = shift / np.maximum(distance, 1e-9)
    source_x = (cols - dx * scale).astype(np.float32)[None, :]
    source_y = (rows - dy * scale).astype(np.float32)[None, :]
    out = coverage.copy()
    out[rows, cols] = cv2.remap(
        coverage, source_x, source_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE
    )[0]
    return out


def _at(values: NDArray[np.floating], at: NDArray[np.float64]) -> NDArray[np.float64]:
    """Each row of ``values`` read at its own fractional index, linearly."""
    low = np.clip(np.floor(at).astype(np.int64), 0, values.shape[1] - 1)
    high = np.minimum(low + 1, values.shape[1] - 1)
    t = np.clip(at - low, 0.0, 1.0)
    ray = np.arange(values.shape[0])
    return (1.0 - t) * values[ray, low] + t * values[ray, high]
