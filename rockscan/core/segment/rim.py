"""A light rock's dark rim, left out of its outline, and taking it back in.

A domed rock lit from above darkens towards its rim, where its surface
turns away from the light (limb darkening): at the occluding edge the
surface is vertical and gets little direct light. On a rock lighter than
its ground the rim may be darker than the ground, and the threshold
half-way between the rock's level and the ground's
(``rockscan.core.segment.trace``) then runs inside the rim, a few pixels
short of the rock's edge all round. On a small rock those pixels are much
of its area: 2 px on a radius of 30 px cost 0.12 of IoU.

The rock's edge is the rim's darkest line. Going out along a ray from the
rock's centre, the profile falls from the rock's level through its shaded
rim to a valley, darker than the ground, and rises again to the ground's
level at the occluding edge, blurred by the camera. Where the valley is
narrow (the profile is back at the threshold within ``WIDTH`` of the
rock's radius past the outline), the outline moves out to the valley's
bottom. A cast shadow is darker ground beside the rock, as dark as its rim:
there the profile stays low past the window and the ray is left alone. A
dark blob of the ground's texture just past a sharp edge makes a valley too,
but past a stretch of ground (the profile rises on its way down to it) and on
a few rays only; a rim darkens a good part of the outline, so nothing moves
unless ``MIN_SHARE`` of the rays do. A thin dark line hugging a sharp edge (a
coin's side, a contact shadow) is a valley too, but within ``MIN_SHIFT`` of
the outline. That distance is read across the outline, not along the ray: a
ray that meets the outline aslant, beside a star's arm, crosses a line a
pixel wide over two or three.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from rockscan.core.segment.shadow import MIN_AREA, Region, measured_region, ray_profiles

__all__ = ["rim_on"]

#: How far past the outline a rim's valley may end, in equivalent radii of
#: the region (at least ``MIN_WIDTH`` pixels).
WIDTH = 0.15
MIN_WIDTH = 5.0
#: A valley counts when it lies below the ground's level by this share of
#: the step from the ground to the rock ...
DEPTH = 0.15
#: ... and by this many robust spreads of the ground.
NOISE = 2.0
#: The valley's lower half is at most this wide, in equivalent radii (at
#: least ``MIN_VALLEY`` pixels).
VALLEY = 0.04
MIN_VALLEY = 3.0
#: Least share of the rays that move for the outline to move at all.
MIN_SHARE = 0.15
#: On its way down to the valley the profile rises by at most this many
#: robust spreads of the ground.
RISE = 1.0
#: Shifts under this many pixels, across the outline, are no rim's.
MIN_SHIFT = 1.75
#: Rays over which the outline's distance is smoothed before its slope is read.
INCIDENCE_RAYS = 5
#: Rays cast from the rock's centre, and the spacing of samples along them (pixels).
RAYS = 360
SPACING = 0.5
#: Rays whose shift is the median of this many neighbours: a lone ray that
#: finds a valley in the ground's texture moves nothing.
SMOOTH_RAYS = 7


def rim_on(
    gray: NDArray[np.floating], mask: NDArray[np.bool_], region: Region | None = None
) -> NDArray[np.bool_]:
    """A light rock's mask grown out to the bottom of its dark rim (module docstring).

    Parameters
    ----------
    gray : (rows, cols) ndarray of float
        Log brightness of the photo around the rock, on the mask's grid,
        with a margin of at least a third of the rock's radius.
    mask : (rows, cols) ndarray of bool
        The rock's region (one piece, holes filled).
    region : Region, optional
        ``shadow.measured_region(gray, mask, shadow.MIN_AREA)``, when already
        measured.

    Returns
    -------
    (rows, cols) ndarray of bool
        The rock with its rim: ``mask`` and the band between its outline and
        the rim's valley where one was found. ``mask`` itself, unchanged,
        when the rock is not lighter than its ground or has no dark rim.
    """
    from scipy import ndimage

    if region is None:
        region = measured_region(gray, mask, MIN_AREA)
    if region is None:
        return mask
    mask8, centre, area, (rock, ground, noise) = region
    step = rock - ground
    # A dark rock's rim is darker still: it is inside the outline already.
    if step <= 0:
        return mask
    threshold = ground - max(NOISE * noise, DEPTH * step)
    radius = math.sqrt(area / math.pi)
    width = max(MIN_WIDTH, WIDTH * radius)
    angles, radii, inside, profiles = ray_profiles(gray, mask8, centre, width + 2.0, RAYS, SPACING, 0.0)
    length = radii.size
    # The outline's last crossing along each ray (its farthest).
    any_inside = inside.any(axis=1)
    last = np.where(any_inside, length - 1 - np.argmax(inside[:, ::-1], axis=1), 0)
    steps = math.ceil(width / SPACING) + 3
    index = np.clip(last[:, None] - 2 + np.arange(steps)[None, :], 0, length - 1)
    window = np.take_along_axis(profiles, index, axis=1)
    # A window that runs off the photo reads no rim.
    end = radii[np.minimum(last - 3 + steps, length - 1)]
    end_row, end_col = centre[0] + end * np.sin(angles), centre[1] + end * np.cos(angles)
    rows, cols = gray.shape
    whole = any_inside & (last - 3 + steps < length)
    whole &= (end_row >= 0) & (end_row <= rows - 1) & (end_col >= 0) & (end_col <= cols - 1)
    bottom = np.argmin(window, axis=1)
    deep = window[np.arange(RAYS), bottom] < threshold
    back = ((window >= threshold) & (np.arange(steps)[None, :] > bottom[:, None])).any(axis=1)
    # A rim's valley is a V at the occluding edge; a shadow's is flat-bottomed.
    low = window[np.arange(RAYS), bottom]
    half = (low + threshold) / 2.0
    narrow = (window <= half[:, None]).sum(axis=1) * SPACING <= max(MIN_VALLEY, VALLEY * radius)
    # The profile falls from the outline into the valley without rising on
    # the way: a dip of the ground's texture beyond the rock's edge lies past
    # a stretch of ground, where the profile rose again.
    falling = window - np.minimum.accumulate(window, axis=1) <= RISE * noise
    descends = (falling | (np.arange(steps)[None, :] > bottom[:, None])).all(axis=1)
    found = whole & deep & back & narrow & descends
    shift = np.where(found, np.maximum(radii[index[np.arange(RAYS), bottom]] - radii[last], 0.0), 0.0)
    # A valley right at the outline is a dark line beside a sharp edge (a
    # coin's side, a contact shadow), outside the object. Its distance is
    # read across the outline: a ray that meets the outline aslant (a star's
    # arm) sees a thin line beside it as a wide one.
    shift[shift * _incidence(radii[last]) < MIN_SHIFT] = 0.0
    shift = ndimage.median_filter(shift, size=SMOOTH_RAYS, mode="wrap")
    # A rim darkens a good part of the outline; a dip of the ground's
    # texture beside it, a few rays.
    if np.count_nonzero(shift) < MIN_SHARE * RAYS:
        return mask
    outer = _star(mask.shape, centre, angles, radii[last] + shift)
    before = _star(mask.shape, centre, angles, radii[last])
    # Only the band between the two stars is new: a concave outline's bays,
    # which rays from the centre do not see, stay out.
    return mask | (outer & ~before)


def _incidence(outline: NDArray[np.float64]) -> NDArray[np.float64]:
    """The cosine of the angle between each ray and the outline's normal
    where the ray leaves it, from the outline's distances along evenly turned rays."""
    from scipy import ndimage

    r = ndimage.median_filter(outline, size=INCIDENCE_RAYS, mode="wrap")
    slope = (np.roll(r, -1) - np.roll(r, 1)) * (r.size / (4.0 * math.pi))
    return r / np.maximum(np.hypot(r, slope), 1e-9)


def _star(
    shape: tuple[int, int],
    centre: tuple[float, float],
    angles: NDArray[np.float64],
    radii: NDArray[np.float64],
) -> NDArray[np.bool_]:
    """The polygon through points at ``radii`` from ``centre`` along ``angles``."""
    import cv2

    points = np.column_stack([centre[1] + radii * np.cos(angles), centre[0] + radii * np.sin(angles)])
    out = np.zeros(shape, np.uint8)
    # Fixed point with 4 fractional bits, as the shadow's cut.
    cv2.fillPoly(out, [np.round(points * 16).astype(np.int32)], 1, lineType=cv2.LINE_8, shift=4)
    return out.view(bool)
