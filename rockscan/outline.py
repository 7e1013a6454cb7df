"""Rock mask -> outline and centroid, in the photo's own pixel coordinates.

The centroid is the mask's first image moment. The outline is traced with
sub-pixel precision by marching squares (scikit-image's ``find_contours``) on
the mask smoothed by a narrow Gaussian, so that a rock segmented at a reduced
working size still gets a smooth outline.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rockscan.errors import NoRockFoundError

__all__ = ["Outline", "trace_outline", "work_to_photo"]


@dataclass(frozen=True, eq=False)
class Outline:
    """A rock's outline.

    Attributes
    ----------
    contour_rowcol : (n_points, 2) ndarray of float
        Closed outline, (row, col) in photo pixels (pixel centres at integers).
    centroid_rowcol : (2,) ndarray of float
        Area centroid (image moments of the mask), (row, col) in photo pixels.
    area_px : float
        Area in photo pixels.
    """

    contour_rowcol: NDArray[np.float64]
    centroid_rowcol: NDArray[np.float64]
    area_px: float


def work_to_photo(rowcol: NDArray[np.float64], scale: float) -> NDArray[np.float64]:
    """Map (row, col) from a working image reduced by ``scale`` to the photo.

    Working pixel i covers photo pixels ``[i*scale, (i+1)*scale)``, so its centre
    is at ``(i + 0.5) * scale - 0.5``.
    """
    return (np.asarray(rowcol, dtype=np.float64) + 0.5) * scale - 0.5


def trace_outline(mask: NDArray[np.bool_], *, scale: float = 1.0, smooth_sigma: float = 0.7) -> Outline:
    """Outline and centroid of one rock mask.

    Parameters
    ----------
    mask : (rows, cols) ndarray of bool
        The rock at working resolution (one connected region, holes filled).
    scale : float
        Photo pixels per working pixel.
    smooth_sigma : float
        Gaussian smoothing of the mask before tracing, in working pixels.

    Returns
    -------
    Outline

    Raises
    ------
    NoRockFoundError
        If the mask is empty.
    """
    import cv2
    from skimage.measure import find_contours

    mask = np.asarray(mask, dtype=bool)
    moments = cv2.moments(mask.astype(np.uint8), binaryImage=True)
    if moments["m00"] <= 0:
        raise NoRockFoundError("no rock found: the rock's mask is empty")
    centroid = np.array([moments["m01"] / moments["m00"], moments["m10"] / moments["m00"]])
    padded = np.pad(mask.astype(np.float32), 2)
    if smooth_sigma > 0:
        padded = cv2.GaussianBlur(padded, (0, 0), smooth_sigma)
    contours = find_contours(padded, 0.5)
    if not contours:
        raise NoRockFoundError("no rock found: the rock has no outline")
    contour = max(contours, key=_enclosed_area) - 2.0
    return Outline(
        contour_rowcol=work_to_photo(contour, scale),
        centroid_rowcol=work_to_photo(centroid, scale),
        area_px=float(moments["m00"]) * scale * scale,
    )


def _enclosed_area(contour: NDArray[np.float64]) -> float:
    r, c = contour[:, 0], contour[:, 1]
    return abs(float(np.dot(r, np.roll(c, -1)) - np.dot(c, np.roll(r, -1)))) / 2.0
