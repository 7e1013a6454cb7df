"""Outlines at working size: each detected rock thresholded at its own level,
scored by the evidence along its outline, and its holes filled.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numpy.typing import NDArray

from rockscan.core.errors import NoRockFoundError
from rockscan.core.segment.channels import _Channel, _unit
from rockscan.core.segment.detect import _Detection, _flatten, _smooth, _window_of
from rockscan.core.segment.score import outline_evidence, outline_score
from rockscan.core.segment.stats import bounding_box, robust_spread
from rockscan.core.segment.types import RockMask, Segmentation, SegmentConfig

#: Smoothing of the hue before it joins the brightness, in working pixels.
_HUE_SIGMA = 3.0
#: Red and blue less luminance (BT.601): divided by the brightness, the two hue coordinates.
_HUE_MATRIX = np.array([[0.701, -0.587, -0.114], [-0.299, -0.587, 0.886]], np.float32)
#: Added to the mean of the three channels (photo in [0, 1]) before the colour
#: differences are divided by it, so that the hue of a black pixel is no noise.
_HUE_FLOOR = 0.03
#: ``_HUE_MATRIX`` and the mean of the three channels plus ``_HUE_FLOOR``, for one ``cv2.transform``.
_HUE_AND_BRIGHTNESS = np.array(
    [[*_HUE_MATRIX[0], 0.0], [*_HUE_MATRIX[1], 0.0], [1 / 3, 1 / 3, 1 / 3, _HUE_FLOOR]], np.float32
)
#: Largest share of the step between rock and ground that hue may carry, as a
#: multiple of brightness's. Chosen on the development part (one-rock photos,
#: 40 a condition, at IoU >= 0.9: 388 of 480 with the colour differences not
#: divided and hue at most brightness's share; divided: 389 at 1, 395 at 3,
#: 394 at 10).
_HUE_SHARE = 3.0

#: Pixel value (photo in [0, 1]) from which a pixel counts as clipped by the sensor.
_CEILING = 0.98


def _outline_rock(
    work: NDArray[np.generic],
    dtype: np.dtype,
    region: NDArray[np.bool_],
    territory: NDArray[np.bool_],
    up: tuple[float, float],
    detection: _Detection,
    config: SegmentConfig,
    edge: float = 0.5,
) -> RockMask | None:
    """Outline one detected rock at working size (module docstring, step 6),
    ``edge`` of the way from the ground's level to the rock's."""
    rows, cols = work.shape[:2]
    # Working pixel -> nearest detection pixel, along each axis.
    to_row = np.minimum(((np.arange(rows) + 0.5) / up[0]).astype(np.int64), region.shape[0] - 1)
    to_col = np.minimum(((np.arange(cols) + 0.5) / up[1]).astype(np.int64), region.shape[1] - 1)
    top, bottom, left, right = bounding_box(region)
    r0, r1 = math.floor(top * up[0]), min(rows, math.ceil(bottom * up[0]))
    c0, c1 = math.floor(left * up[1]), min(cols, math.ceil(right * up[1]))
    detected = region[to_row[r0:r1, None], to_col[None, c0:c1]]
    estimate, origin = detected, (r0, c0)
    rock, reaches_edge = None, False
    # A rock only partly detected reaches its window's edge: look again in a
    # window around what was found. What still reaches it after three looks,
    # or has grown past four times the detection, has flooded the ground.
    for _ in range(3):
        rock, reaches_edge = _threshold_rock(
            work, dtype, estimate, origin, territory, (to_row, to_col), up, detection, config, edge
        )
        if rock is None or not reaches_edge:
            break
        estimate, origin = rock.mask, rock.origin_rowcol
    if rock is None or reaches_edge or rock.area > 4.0 * float(np.count_nonzero(detected)):
        rock = _fallback(detected, (r0, c0))
    if rock is None:
        return None
    return _scored(work, dtype, rock, (to_row, to_col), up, detection, config)


def _scored(
    work: NDArray[np.generic],
    dtype: np.dtype,
    rock: RockMask,
    to_detect: tuple[NDArray[np.int64], NDArray[np.int64]],
    up: tuple[float, float],
    detection: _Detection,
    config: SegmentConfig,
) -> RockMask:
    """The rock with its segmentation score (rockscan.core.segment.score).

    The evidence is read on the flattened channel the rock was found in,
    as a level from the ground's (0, the median of a ring around the
    outline) to the rock's (1, the median inside). Where the ground is
    lighter than the rock on one side and darker on another, its level is
    read sector by sector round the outline (:func:`_two_sided_ground`).
    """

    rows, cols = work.shape[:2]
    o0, o1 = rock.origin_rowcol
    h, w = rock.mask.shape
    radius = math.sqrt(max(rock.area, 1) / math.pi)
    pad = round(max(6.0, 0.4 * radius))
    r0, r1 = max(0, o0 - pad), min(rows, o0 + h + pad)
    c0, c1 = max(0, o1 - pad), min(cols, o1 + w + pad)
    mask = np.zeros((r1 - r0, c1 - c0), bool)
    mask[o0 - r0 : o0 - r0 + h, o1 - c0 : o1 - c0 + w] = rock.mask
    window = _unit(np.ascontiguousarray(work[r0:r1, c0:c1]), dtype)
    values = _smooth(detection.channel.values(window), 1, config.smooth_sigma)
    lighting = _window_of(detection.lighting, up, (r0, r1, c0, c1))
    flat = _flatten(values, lighting, detection.channel.multiplicative)
    mask8 = mask.astype(np.uint8)
    inside, ring = _core_and_ring(mask8, radius)
    core = flat[inside] if np.count_nonzero(inside) >= 4 else flat[mask]
    rock_level = float(np.median(core))
    sides = (r0 == 0, r1 == rows, c0 == 0, c1 == cols)
    two_sided = _two_sided_ground(flat, ring, mask, rock_level)
    if two_sided is not None:
        level = _two_sided_level(flat, two_sided, rock_level)
    else:
        ground = float(np.median(flat[ring])) if np.count_nonzero(ring) >= 8 else 0.0
        step = rock_level - ground
        if not math.isfinite(step) or abs(step) < 1e-6:
            return dataclasses.replace(rock, score=0.0, evidence=())
        level = ((flat - np.float32(ground)) / np.float32(step)).astype(np.float32)
    evidence = outline_evidence(level, mask, sides)
    return dataclasses.replace(
        rock,
        score=outline_score(evidence),
        evidence=tuple(float(v) for v in evidence.as_array()),
        darker_outside=evidence.darker_outside,
        inner_spread=evidence.inner_spread,
    )


#: Sectors round an outline in which the ground's level is read apart, when
#: the ground is lighter than the rock on one side and darker on the other.
SECTORS = 8
#: How far, in robust spreads of the ground within its sectors, the ground
#: must lie above the rock on one side and below it on another to be two-sided.
TWO_SIDED = 3.0


def _two_sided_ground(
    flat: NDArray[np.float32], ring: NDArray[np.bool_], mask: NDArray[np.bool_], rock_level: float
) -> NDArray[np.float32] | None:
    """The ground's level at every pixel, read sector by sector in the ring round
    an outline, when the ground is lighter than the rock on one side and darker on
    another; None for a ground on one side of the rock's level.

    One median of the whole ring lies near the rock's own level there: the
    step across the outline would be lost.
    """
    values = flat[ring]
    # A sector's median beyond the rock's level has at least 4 of its 8 or more pixels there.
    if (
        values.size < 8 * SECTORS
        or min(np.count_nonzero(values > rock_level), np.count_nonzero(values < rock_level)) < 4
    ):
        return None
    ys, xs = np.nonzero(ring)
    my, mx = np.nonzero(mask)
    centre = (float(my.mean()), float(mx.mean()))
    turns = (np.arctan2(ys - centre[0], xs - centre[1]) + math.pi) / (2.0 * math.pi)
    sector = np.minimum((turns * SECTORS).astype(np.int64), SECTORS - 1)
    counts = np.bincount(sector, minlength=SECTORS)
    if counts.min() < 8:
        return None
    levels = np.array([np.median(values[sector == k]) for k in range(SECTORS)])
    spread = robust_spread(values - levels[sector], 0.0)
    if min(levels.max() - rock_level, rock_level - levels.min()) < TWO_SIDED * max(spread, 1e-6):
        return None
    # Between sector centres the level is interpolated along the angle.
    yy, xx = np.mgrid[: flat.shape[0], : flat.shape[1]]
    at = (np.arctan2(yy - centre[0], xx - centre[1]) + math.pi) / (2.0 * math.pi) * SECTORS - 0.5
    k = np.floor(at).astype(np.int64)
    t = (at - k).astype(np.float32)
    ground = levels[k % SECTORS] * (1.0 - t) + levels[(k + 1) % SECTORS] * t
    return ground.astype(np.float32)


def _two_sided_level(
    flat: NDArray[np.float32], ground: NDArray[np.float32], rock_level: float
) -> NDArray[np.float32]:
    """The level from the ground's (0, as read round the outline) to the rock's (1),
    the step taken at least a quarter of the largest, with its own sign on each side."""
    step = np.float32(rock_level) - ground
    least = np.float32(0.25) * float(np.abs(step).max())
    step = np.where(step >= 0, np.maximum(step, least), np.minimum(step, -least))
    return ((flat - ground) / step).astype(np.float32)


#: An outline's core lies over this share of the rock's equivalent radius
#: inside it (at least a pixel); its ring between these shares outside it
#: (at least the pixels in ``RING_PIXELS``): where a rock's and its ground's
#: levels are read once the rock is outlined.
CORE = 0.15
RING = (0.12, 0.35)
RING_PIXELS = (3.0, 6.0)


def _core_and_ring(mask8: NDArray[np.uint8], radius: float) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """The core of an outlined rock and the ring of ground around it (``CORE``, ``RING``)."""
    import cv2

    inside = cv2.distanceTransform(mask8, cv2.DIST_L2, 3)
    outside = cv2.distanceTransform(1 - mask8, cv2.DIST_L2, 3)
    near, far = max(RING_PIXELS[0], RING[0] * radius), max(RING_PIXELS[1], RING[1] * radius)
    return inside > max(1.0, CORE * radius), (outside > near) & (outside <= far)


def _threshold_rock(
    work: NDArray[np.generic],
    dtype: np.dtype,
    estimate: NDArray[np.bool_],
    origin: tuple[int, int],
    territory: NDArray[np.bool_],
    to_detect: tuple[NDArray[np.int64], NDArray[np.int64]],
    up: tuple[float, float],
    detection: _Detection,
    config: SegmentConfig,
    edge: float = 0.5,
) -> tuple[RockMask | None, bool]:
    """Threshold ``edge`` of the way from ground to rock (half-way by default)
    in a window around an estimate of the rock.

    Returns the rock and whether it reaches an edge of the window that is not
    the frame's. Its coverage is the level scaled so that ``edge`` is 0.5 and
    the rock 1: the outline traced at 0.5 of it lies at ``edge``.
    """
    import cv2

    rows, cols = work.shape[:2]
    ys, xs = np.nonzero(estimate)
    if ys.size == 0:
        return None, False
    radius = math.sqrt(ys.size / math.pi)
    pad = round(max(6.0, 0.5 * radius))
    r0 = max(0, origin[0] + int(ys.min()) - pad)
    r1 = min(rows, origin[0] + int(ys.max()) + 1 + pad)
    c0 = max(0, origin[1] + int(xs.min()) - pad)
    c1 = min(cols, origin[1] + int(xs.max()) + 1 + pad)
    detected = np.zeros((r1 - r0, c1 - c0), bool)
    detected[ys + origin[0] - r0, xs + origin[1] - c0] = True
    to_row, to_col = to_detect
    others = detection.outliers[to_row[r0:r1, None], to_col[None, c0:c1]] & ~detected

    window = _unit(np.ascontiguousarray(work[r0:r1, c0:c1]), dtype)
    values = _smooth(detection.channel.values(window), 1, config.smooth_sigma)
    lighting = _window_of(detection.lighting, up, (r0, r1, c0, c1))
    flat = _flatten(values, lighting, detection.channel.multiplicative)

    # Distances to the detection's edge, inside and outside, give the core and
    # the ring without large structuring elements.
    det8 = detected.astype(np.uint8)
    inside_dist = cv2.distanceTransform(det8, cv2.DIST_L2, 3)
    outside_dist = cv2.distanceTransform(1 - det8, cv2.DIST_L2, 3)
    margin = max(2.0, 0.15 * radius)
    core = inside_dist > margin
    if np.count_nonzero(core) < 4:
        core = detected
    ring = (outside_dist > margin) & (outside_dist <= margin + max(3.0, 0.3 * radius))
    ring &= cv2.dilate(others.astype(np.uint8), np.ones((5, 5), np.uint8)) == 0
    if np.count_nonzero(ring) < 8:
        ring = outside_dist > margin
    if np.count_nonzero(ring) < 8:
        return _fallback(detected, (r0, c0)), False
    level = _level(window, flat, core, ring, detection.channel)
    if level is None:
        return _fallback(detected, (r0, c0)), False
    if detection.channel.multiplicative and detection.polarity == "light":
        # A sensor's ceiling hides how much brighter than its ground a light
        # rock is; where it clips, the rock is at least at its own level.
        ceiling = (window.max(axis=2) if window.ndim == 3 else window) >= _CEILING
        # Clipped ground (a glaring corner) stays ground: only what already rises is lifted.
        ceiling &= level > 0.25
        level[ceiling] = np.maximum(level[ceiling], 1.0)
    # A touching neighbour beyond half-way is not this rock: keep to its territory.
    own = territory[to_row[r0:r1, None], to_col[None, c0:c1]]
    count, labels = cv2.connectedComponents(((level > edge) & own).astype(np.uint8), connectivity=4)
    overlap = np.bincount(labels[core], minlength=count)
    overlap[0] = 0
    if overlap.max() == 0:
        return _fallback(detected, (r0, c0)), False
    mask = _fill_holes(labels == int(np.argmax(overlap)))
    if np.count_nonzero(mask) < 0.25 * np.count_nonzero(detected):
        return _fallback(detected, (r0, c0)), False
    coverage = np.clip(0.5 + (level - edge) * (0.5 / (1.0 - edge)), 0.0, 1.0).astype(np.float32)
    # Only this rock's own edge: filled holes count as rock, anything beyond
    # a pixel of its mask as ground.
    coverage[mask & (coverage < 0.5)] = 1.0
    coverage[~(cv2.dilate(mask.astype(np.uint8), _disk(1)) > 0)] = 0.0
    coverage[~mask & (coverage >= 0.5)] = 0.49
    touching = (
        (r0 > 0 and mask[0].any())
        or (r1 < rows and mask[-1].any())
        or (c0 > 0 and mask[:, 0].any())
        or (c1 < cols and mask[:, -1].any())
    )
    return RockMask(mask=mask, coverage=coverage, origin_rowcol=(r0, c0)), bool(touching)


def _level(
    window: NDArray[np.float32],
    flat: NDArray[np.float32],
    core: NDArray[np.bool_],
    ring: NDArray[np.bool_],
    channel: _Channel,
) -> NDArray[np.float32] | None:
    """Where each pixel lies from the ground's level (0) to the rock's (1).

    A gray photo is measured by its flattened brightness. In colour, rock and
    ground are told apart along Fisher's discriminant of the flattened
    brightness and the smoothed hue (two colour differences over the
    brightness), from the core's and the ring's means and pooled covariance:
    a rock's hue then counts as well as its brightness, also on its shaded
    side, and ground texture, which mostly varies the ground's brightness,
    counts less; brightness keeps at least a quarter of the step between the
    two (``_HUE_SHARE``). Either way the levels are medians over the core and
    the ring.
    """
    import cv2

    core_at, ring_at = _sample_at(core), _sample_at(ring)
    projected = flat
    flat_values = flat.ravel()
    rock_lum, ground_lum = flat_values[core_at], flat_values[ring_at]
    if window.ndim == 3 and channel.name == "luminance":
        # Red and blue less luminance, over the brightness: a rock's shaded
        # side keeps its hue where its brightness falls to the ground's, and
        # the lighting divides out. Hue varies slowly on a rock and JPEG stores
        # it in coarse blocks: it is smoothed, and the outline's position is
        # left mostly to the brightness, whose edge is sharp.
        # One pass gives both colour differences and the brightness (plus
        # the floor): numpy's mean over the channel axis costs three times more.
        first, second, brightness = cv2.split(cv2.transform(window, _HUE_AND_BRIGHTNESS))
        # Plane by plane: a division broadcast along the channel axis costs three times more.
        hue = cv2.merge([first / brightness, second / brightness])
        hue = cv2.GaussianBlur(hue, (0, 0), _HUE_SIGMA).reshape(-1, 2)
        features_r = np.column_stack([rock_lum, hue[core_at]]).astype(np.float64)
        features_g = np.column_stack([ground_lum, hue[ring_at]]).astype(np.float64)
        if features_r.shape[0] > 8 and features_g.shape[0] > 8:
            pooled = 0.5 * (_covariance(features_r) + _covariance(features_g))
            pooled[np.diag_indices(3)] += 1e-6 * max(float(np.trace(pooled)), 1e-9)
            difference = features_r.mean(axis=0) - features_g.mean(axis=0)
            weights = np.linalg.solve(pooled, difference)
            # Brightness carries at least a quarter of the step, so that the
            # outline stays near its sharp edge (hue is smoothed, and on a
            # black ground it would otherwise take over).
            from_brightness, from_hue = weights[0] * difference[0], weights[1:] @ difference[1:]
            if from_hue > _HUE_SHARE * from_brightness > 0:
                weights[1:] *= _HUE_SHARE * from_brightness / from_hue
            elif from_brightness <= 0:
                weights = np.array([1.0, 0.0, 0.0])
            weights = weights.astype(np.float32)
            projected = flat * weights[0] + (hue @ weights[1:]).reshape(flat.shape)
    values = projected.ravel()
    rock_level = float(np.median(values[core_at]))
    ground_level = float(np.median(values[ring_at]))
    step = rock_level - ground_level
    if not math.isfinite(step) or abs(step) < 1e-9:
        return None
    return ((projected - np.float32(ground_level)) / np.float32(step)).astype(np.float32)


def _covariance(samples: NDArray[np.float64]) -> NDArray[np.float64]:
    """Sample covariance of the rows' features (``np.cov`` of the transpose, without its checks)."""
    centred = samples - samples.mean(axis=0)
    return centred.T @ centred / (samples.shape[0] - 1)


def _sample_at(mask: NDArray[np.bool_], limit: int = 4096) -> NDArray[np.int64]:
    """Flat indices of at most about ``limit`` evenly spaced pixels of a mask:
    the statistics of a window need no more."""
    at = np.flatnonzero(mask)
    return at[:: max(1, at.size // limit)]


def _disk(radius: int) -> NDArray[np.uint8]:
    import cv2

    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))


def _fallback(detected: NDArray[np.bool_], origin: tuple[int, int]) -> RockMask | None:
    mask = _fill_holes(detected)
    if not mask.any():
        return None
    return RockMask(mask=mask, coverage=mask.astype(np.float32), origin_rowcol=origin)


def _fill_holes(mask: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """The mask with every enclosed hole filled (flood fill of the ground from outside)."""
    import cv2

    padded = np.zeros((mask.shape[0] + 2, mask.shape[1] + 2), np.uint8)
    padded[1:-1, 1:-1] = mask
    flood = np.zeros((padded.shape[0] + 2, padded.shape[1] + 2), np.uint8)
    cv2.floodFill(padded, flood, (0, 0), 2)
    return padded[1:-1, 1:-1] != 2


def _from_alpha(
    alpha: NDArray[np.float32], scale_rowcol: tuple[float, float], config: SegmentConfig, all_rocks: bool
) -> Segmentation:
    """Rocks cut out by an alpha channel: its opaque regions, alpha as coverage."""
    import cv2

    rows, cols = alpha.shape
    min_area = max(12.0, config.min_area_fraction * rows * cols)
    _, labels, stats, _ = cv2.connectedComponentsWithStats((alpha >= 0.5).astype(np.uint8), connectivity=8)
    areas = stats[1:, cv2.CC_STAT_AREA]
    order = [int(i) for i in np.argsort(-areas, kind="stable") if areas[i] >= min_area]
    if not order:
        raise NoRockFoundError("no rock found: the alpha channel cuts out nothing large enough")
    if all_rocks:
        order = [i for i in order if areas[i] >= config.min_relative_area * areas[order[0]]]
    else:
        order = order[:1]
    rocks, out = [], np.zeros((rows, cols), np.int32)
    for index, i in enumerate(order, start=1):
        mask = _fill_holes(labels == i + 1)
        coverage = np.where(mask, np.maximum(alpha, 0.5), np.minimum(alpha, 0.49)).astype(np.float32)
        coverage[~(cv2.dilate(mask.astype(np.uint8), _disk(1)) > 0)] = 0.0
        rocks.append(RockMask(mask=mask, coverage=coverage, origin_rowcol=(0, 0)))
        out[mask & (out == 0)] = index
    return Segmentation(
        labels=out, rocks=tuple(rocks), scale_rowcol=scale_rowcol, polarity="light", channel="alpha"
    )
