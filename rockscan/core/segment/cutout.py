"""Whether a photo's alpha channel cuts its rock out, or only hides part of a scene.

An alpha channel is made for two reasons. A rock cut out of its photo is opaque
where the rock is and transparent around it: the alpha is the outline. But a
photo turned in an editor (transparent corners), pasted on a larger transparent
canvas, seen through a round field of view, or with part of its ground erased,
is transparent too, and its opaque part is a scene: ground with the rock in it.

The two are told apart by what the opaque part holds. Its rim (the band just
inside the transparent region) is ground in a scene and the rock's own edge in
a cut-out. With each transparent pixel painted the colour of the nearest opaque
one, a scene shows its rock standing out of its ground, away from the rim; a
cut-out shows at most its rock's own shading, a region that runs into the rim
or is outlined with little confidence.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from rockscan.core.segment.channels import _unit
from rockscan.core.segment.types import CONFIDENT_SCORE, Segmentation

#: Share of the photo's transparent pixels, at least and at most, for its alpha to
#: be read at all (less: a few clipped corners; more: nothing left to see).
TRANSPARENT_SHARE = (0.05, 0.98)

#: Width of the rim, as a share of the photo's longer side (at least ``_RIM_PIXELS``).
RIM = 0.02
_RIM_PIXELS = 3

#: Largest share of a rock found in the painted photo that may lie in the rim or the
#: transparent region, for that rock to stand inside a scene. On 42 development
#: photos of the segmentation benchmark cut out by their truth, the region found
#: in the painted photo had at least 3.7% there (a lit face or a highlight, inside
#: the rock but reaching its rim); the rocks of the same photos padded or with
#: ground erased, at most 3.1%, most of them none. Then, on photos 6-13 of ten
#: conditions: of 160 cut-outs (hard and feathered alpha) none lost its alpha
#: outline; of 240 scenes (ground erased, a round field of view, padded) 201 give
#: their rock, and the rest keep the alpha as before (a rock cut by the erased
#: part, or one outlined with little confidence).
EDGE_SHARE = 0.01


def partly_transparent(share: float) -> bool:
    """Whether an alpha channel that leaves ``share`` of the photo transparent hides
    enough of it to be read."""
    low, high = TRANSPARENT_SHARE
    return low < share < high


#: Longer side of the grid the transparent pixels' paint is worked out on: the
#: paint is a blurred continuation of the ground, and a large photo's own size
#: would cost its nearest-pixel map 16 bytes a pixel.
PAINT_SIZE = 1024

#: Rows of the photo painted at a time (the paint, brought to the photo's size, a band at a time).
_BAND = 256


#: Transparent regions smaller than this share of the photo are specks, not a
#: cut: pixels a tool left transparent here and there, or a palette's
#: transparent colour falling on grains of the ground. They are painted, and
#: otherwise the photo is read as if they were opaque.
SPECK_SHARE = 0.002


def painted(pixels: NDArray[np.generic]) -> tuple[NDArray[np.generic], NDArray[np.bool_] | None] | None:
    """The colour of a partly transparent RGBA photo with each transparent pixel
    painted the colour of the nearest opaque one, blurred there, and where the
    rim and the transparent region lie; None for a photo without such an alpha.

    Parameters
    ----------
    pixels : (rows, cols, 4) ndarray
        RGBA, of the dtypes ``segment`` takes (checked).

    Returns
    -------
    (rows, cols, 3) ndarray of ``pixels``' dtype
        The painted photo.
    (r, c) ndarray of bool, or None
        Its edge zone, the transparent pixels and the rim, on a grid of at most
        ``PAINT_SIZE`` on its longer side; None when the transparent pixels
        are specks (``SPECK_SHARE``) that cut nothing out: the painted photo
        is then the photo.
    """
    import cv2
    from scipy import ndimage

    if pixels.ndim != 3 or pixels.shape[2] != 4:
        return None
    # Half-way in the alpha's own type: a float copy of a large photo's alpha costs 4 bytes a pixel.
    half = np.iinfo(pixels.dtype).max / 2 if pixels.dtype.kind in "ui" else 0.5
    opaque = pixels[..., 3] >= half
    if not partly_transparent(1.0 - float(opaque.mean())):
        return None
    rows, cols = opaque.shape
    step = max(1, math.ceil(max(rows, cols) / PAINT_SIZE))
    size = (max(1, cols // step), max(1, rows // step))
    colour = np.ascontiguousarray(pixels[..., :3])
    unit = colour if colour.dtype in (np.uint8, np.uint16, np.float32) else _unit(colour, colour.dtype)
    small = cv2.resize(unit, size, interpolation=cv2.INTER_AREA).astype(np.float32)
    opaque8 = opaque.view(np.uint8) * np.uint8(255)
    small_opaque = cv2.resize(opaque8, size, interpolation=cv2.INTER_AREA) >= 128
    hidden = ~small_opaque
    if hidden.all() or not hidden.any():
        return None
    rim_width = max(_RIM_PIXELS, round(RIM * max(size)))
    cut = _without_specks(hidden)
    # Distance inside the opaque part (specks count as opaque) to the nearest cut.
    depth = cv2.distanceTransform((~cut).view(np.uint8), cv2.DIST_L2, 3)
    rim = ~cut & (depth <= rim_width)
    # The rim's ground runs on past the alpha's edge, with no edge of its own there.
    _, (near_rows, near_cols) = ndimage.distance_transform_edt(hidden, return_indices=True)
    paint = cv2.GaussianBlur(small[near_rows, near_cols], (0, 0), rim_width)
    if unit is not colour and colour.dtype.kind in "ui":
        # Back from [0, 1] to the photo's own integers (a wide type segment also takes).
        paint = paint * float(np.iinfo(colour.dtype).max)
    if colour.dtype.kind in "ui":
        info = np.iinfo(colour.dtype)
        paint = np.clip(np.rint(paint), info.min, info.max)
    paint = paint.astype(colour.dtype)
    # The colour is a copy already (the alpha's plane cut off): painted in place.
    out = colour
    on_rows = np.minimum(np.arange(rows) // step, size[1] - 1)
    on_cols = np.minimum(np.arange(cols) // step, size[0] - 1)
    for r0 in range(0, rows, _BAND):
        band = ~opaque[r0 : r0 + _BAND]
        if band.any():
            out[r0 : r0 + _BAND][band] = paint[on_rows[r0 : r0 + _BAND]][:, on_cols][band]
    if not partly_transparent(float(cut.mean())):
        return out, None
    return out, cut | rim


def _without_specks(hidden: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """The transparent regions of at least ``SPECK_SHARE`` of the grid."""
    import cv2

    _, labels, stats, _ = cv2.connectedComponentsWithStats(hidden.view(np.uint8), connectivity=8)
    large = stats[:, cv2.CC_STAT_AREA] >= SPECK_SHARE * hidden.size
    large[0] = False
    return large[labels]


def stands_inside(found: Segmentation, edge_zone: NDArray[np.bool_]) -> bool:
    """Whether the main rock of a painted photo's segmentation is a rock of the
    scene: outlined with confidence (``CONFIDENT_SCORE``), and with at most
    ``EDGE_SHARE`` of it in the edge zone (:func:`painted`).

    A doubtful outline leaves the alpha in force: inside a cut-out rock, a lit
    face or a dark band can stand out of its rim too, and is outlined poorly.
    """
    import cv2

    if found.rocks[0].score < CONFIDENT_SCORE:
        return False
    labels = found.labels == 1
    # The zone brought to the labels' grid: a cell touched by the zone counts as in it.
    zone = cv2.resize(edge_zone.astype(np.float32), labels.shape[::-1], interpolation=cv2.INTER_AREA) > 0
    area = np.count_nonzero(labels)
    return area > 0 and np.count_nonzero(labels & zone) <= EDGE_SHARE * area
