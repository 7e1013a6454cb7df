"""A rock's face that the sensor clipped white, left out of its outline, and taking it back in.

Under a low, strong light a rock's face turned to it can be brighter than
the sensor records: every channel sits at its ceiling and the face is white,
whatever the rock's colour. The outline drawn along the rock's hue (the
colour cue, or the discriminant of brightness and hue) then leaves that face
out, for white lies as near a gray ground's hue as the ground itself; the
outline drawn on brightness alone may keep the face and lose the rock's
shaded side instead, and the choice among them takes one or the other.

Around the outline (within ``REACH`` equivalent radii), the pixels at the
sensor's ceiling (any channel at least ``CEILING``) that touch the rock are
its clipped face. The face grows out to the pixels past half-way in
brightness from the ground to the ceiling, where a blurred edge of a rock
brighter than the sensor records lies at the latest. It joins the rock when
the rock comes out about as compact as it was (``shade.stays_compact``),
grown by ``shade.MIN_GROWTH`` to ``MAX_GROWTH`` of its area: a clipped
neighbour or a glaring patch of ground beside the rock leaves it lobed, or
more than doubles it. A face that reaches the edge of the window where the
frame cuts it is not taken: the photo shows neither it whole nor the ground
round it. The outline kept may be the rock's darker, coloured part, no
lighter than the ground: how light that part is tells nothing here.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from rockscan.core.segment.channels import _LUMA
from rockscan.core.segment.shade import _touching, side_joined
from rockscan.core.segment.trace import _CEILING, _disk

__all__ = ["clipped_on"]

#: How far past the outline the clipped face is looked for, in equivalent
#: radii of the rock.
REACH = 1.2
#: Pixel value (photo in [0, 1]) from which a channel counts as clipped: the
#: outline's threshold counts such a pixel as rock too (``trace``).
CEILING = _CEILING
#: Fewest clipped pixels touching the rock that make a face worth reading.
MIN_CLIPPED = 20
#: The rock grows by at most this share of its area. Set on development photos
#: 4160-4319, where 0.45 refused a face of half the rest of the rock (shaded
#: 4272, IoU 0.61 -> 0.97 at 0.7), and checked on 4000-4159 (no outline moves)
#: and 4320-4479 (two move, both up; one across 0.9).
MAX_GROWTH = 0.7
#: Where the ground's level is read: a ring from ``RING[0]`` (plus 2 pixels)
#: to ``RING[1]`` equivalent radii past the outline, at its median.
RING = (0.1, 0.4)
#: The face and the rock are closed across the seam between them by a disc
#: of this share of the rock's equivalent radius (at least ``MIN_CLOSE`` pixels).
CLOSE = 0.08
MIN_CLOSE = 2


def clipped_on(colour: NDArray[np.floating], mask: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """A rock's mask with a clipped face beside it taken in (module docstring).

    Parameters
    ----------
    colour : (rows, cols) or (rows, cols, 3) ndarray of float
        Brightness, or red, green and blue, in [0, 1] around the rock, on the
        mask's grid, with a margin of at least ``REACH`` of the rock's
        equivalent radius (less where the frame cuts it: a face reaching its
        edge is not taken).
    mask : (rows, cols) ndarray of bool
        The rock's region (one piece, holes filled).

    Returns
    -------
    (rows, cols) ndarray of bool
        The rock with its clipped face, or ``mask`` itself, unchanged, when
        no clipped face touches it or the face would not leave it compact.
    """
    from scipy import ndimage

    area = int(np.count_nonzero(mask))
    if area < 50:
        return mask
    values = np.asarray(colour, dtype=np.float32)
    top = values
    if values.ndim == 3:
        # Pairwise, not ``max(axis=2)``: a reduction over three values a pixel is slow.
        top = np.maximum(np.maximum(values[..., 0], values[..., 1]), values[..., 2])
    outside = ~mask
    clipped = (top >= CEILING) & outside
    # Nothing clipped beside the rock costs one comparison: most photos stop here.
    if np.count_nonzero(clipped) < MIN_CLIPPED:
        return mask
    radius = math.sqrt(area / math.pi)
    distance = ndimage.distance_transform_edt(outside)
    near = (distance > 0) & (distance <= REACH * radius)
    touching = distance <= 2.0
    # Along a blurred edge a face's clipped pixels may meet at their corners only.
    face = _touching(clipped & near, touching, connectivity=2)
    if np.count_nonzero(face) < MIN_CLIPPED:
        return mask
    bright = values @ _LUMA if values.ndim == 3 else values
    ring = (distance > RING[0] * radius + 2.0) & (distance <= RING[1] * radius) & ~face
    if np.count_nonzero(ring) < 50:
        return mask
    ground = float(np.median(bright[ring]))
    # A blurred edge of a face brighter than the sensor records lies past
    # half-way from the ground to the ceiling.
    side = _touching(near & (bright >= 0.5 * (ground + 1.0)), face, connectivity=2)
    # Past the outline by less than ``REACH``, the face reaches the window's
    # edge only where the frame cuts the window.
    if side[[0, -1], :].any() or side[:, [0, -1]].any():
        return mask
    disk = _disk(max(MIN_CLOSE, round(CLOSE * radius)))
    return side_joined(mask, side, disk, MAX_GROWTH)
