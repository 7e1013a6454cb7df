"""A crop's rock walled in by its neighbours, found against a pocket of ground.

A crop is centred on its rock, and its neighbours reach in at every edge.
Detection learns the ground from the frame's border, which is then mostly
the neighbours'; what stands out from them may be a pocket of the ground
between the rocks, while the rock under the centre, of its neighbours' level,
stands out from nothing. Figure and ground have traded places.

When no region any channel's detection found (main, whole or runner-up)
covers the frame's centre, each detection's main region is taken for the
ground: each pixel's deviation from that region's level is
measured in its robust spreads, the pixels beyond ``z_grow`` on the side of
the centre's own deviation (which must itself lie beyond it) make regions, the
one under the centre is parted from touching neighbours as detection parts
rocks (``split.split_rocks``), and its part under the centre is the object
the crop is centred on. It is a candidate for the main rock (judged by the
choice among candidates like any other) when it lies inside the frame, as a
crop's rock lies whole in it, and stands out from the pocket more than the
pocket stood out from the border (their region scores,
``detect._region_scores``). A rock off the centre of a photo of one rock,
taken for ground so, leaves ground under the centre that reaches the frame,
or a patch of it (a brick between its mortar) that stands out from the rock
less than the rock did from the ground.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from rockscan.core.segment.detect import _Detection, _region_measures, _region_scores
from rockscan.core.segment.split import split_rocks
from rockscan.core.segment.stats import robust_spread
from rockscan.core.segment.types import SegmentConfig

__all__ = ["centre_object", "covers_centre"]


def covers_centre(detection: _Detection) -> bool:
    """Whether a region the detection found, its main rock's or an alternative, covers the frame's centre."""
    rows, cols = detection.flat.shape
    regions = [*detection.regions, *(region for _, region, _ in detection.alternatives)]
    return any(bool(region[rows // 2, cols // 2]) for region in regions)


def centre_object(detection: _Detection, config: SegmentConfig) -> _Detection | None:
    """The object under the frame's centre, found against the detection's main region
    taken for ground (module docstring), or None.

    Parameters
    ----------
    detection : _Detection
        A detection none of whose regions covers the frame's centre
        (:func:`covers_centre`).
    config : SegmentConfig

    Returns
    -------
    _Detection or None
        The detection with the object as its only region, scored against the
        pocket, its polarity, and the other parts and pixels beyond the
        pocket's spread as the neighbours that bound it; None when the centre
        is of the pocket's level, or the object reaches the frame or stands
        out from the pocket less than the pocket did from the border.
    """
    import cv2

    flat = detection.flat
    rows, cols = flat.shape
    pocket = detection.regions[0]
    if np.count_nonzero(pocket) < _MIN_POCKET:
        return None
    values = flat[pocket]
    level = float(np.median(values))
    spread = max(robust_spread(values, level), config.min_contrast / config.z_detect, 1e-6)
    z = ((flat - level) / spread).astype(np.float32)
    # The centre's deviation, over its 3 x 3 pixels: a speck of texture does not set it.
    centre = float(np.median(z[rows // 2 - 1 : rows // 2 + 2, cols // 2 - 1 : cols // 2 + 2]))
    if abs(centre) <= config.z_grow:
        return None
    signed = z if centre > 0 else -z
    _, labels = cv2.connectedComponents((signed > config.z_grow).astype(np.uint8), connectivity=8)
    label = labels[rows // 2, cols // 2]
    if label == 0:
        return None
    min_area = max(12.0, config.min_area_fraction * rows * cols)
    parts = split_rocks(signed, labels == label, min_area, config.z_grow)
    under = [part for part in parts if part[rows // 2, cols // 2]]
    if not under:
        return None
    found = under[0]
    if found[0].any() or found[-1].any() or found[:, 0].any() or found[:, -1].any():
        return None
    score = float(_region_scores(_region_measures(signed, [found]))[0])
    if score <= detection.score:
        return None
    others = [part for part in parts if part is not found and np.count_nonzero(part) >= min_area]
    return dataclasses.replace(
        detection,
        score=score,
        regions=[found],
        polarity="light" if centre > 0 else "dark",
        outliers=np.abs(z) > config.z_grow,
        others=others,
        alternatives=[],
    )


#: Fewest pixels (at detection size) of a main region whose level is taken for the ground's.
_MIN_POCKET = 50
