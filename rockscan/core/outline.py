"""Rock mask -> outline and centroid, in the photo's own pixel coordinates.

The outline is the 0.5 level of the rock's coverage, traced with sub-pixel
precision by marching squares (scikit-image's ``find_contours``). A coverage
map from :mod:`rockscan.core.segment` rises from 0 to 1 across the rock's edge, so
its 0.5 level lies between pixels where the photo crosses the threshold; a
plain boolean mask is smoothed by a narrow Gaussian first, so that its outline
is not a staircase.

The centroid and area are those of the outline polygon (shoelace formulas):
the same curve the radii are measured from.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from rockscan.core.errors import NoRockFoundError, ParameterError
from rockscan.core.polar import polygon_area_centroid

__all__ = ["Outline", "polygon_area_centroid", "trace_outline", "work_to_photo"]


@dataclass(frozen=True, eq=False)
class Outline:
    """A rock's outline.

    Attributes
    ----------
    contour_rowcol : (n_points, 2) ndarray of float
        Closed outline, (row, col) in photo pixels (pixel centres at integers);
        the last vertex joins the first.
    centroid_rowcol : (2,) ndarray of float
        Area centroid of the outline polygon, (row, col) in photo pixels.
    area_px : float
        Area enclosed by the outline, in photo pixels.
    """

    contour_rowcol: NDArray[np.float64]
    centroid_rowcol: NDArray[np.float64]
    area_px: float


def work_to_photo(
    rowcol: ArrayLike, scale: float | ArrayLike, origin_rowcol: ArrayLike = (0.0, 0.0)
) -> NDArray[np.float64]:
    """Map (row, col) from a working image reduced by ``scale`` to the photo.

    Parameters
    ----------
    rowcol : (..., 2) array_like of float
        Points in a window of the working image.
    scale : float or (2,) array_like of float
        Photo pixels per working pixel (one value, or one for rows and one for
        columns).
    origin_rowcol : (2,) array_like of float
        The window's top-left pixel in the working image.

    Returns
    -------
    rowcol_photo : (..., 2) ndarray of float

    Notes
    -----
    Working pixel i covers photo pixels ``[i*scale, (i+1)*scale)``, so its
    centre is at ``(i + 0.5) * scale - 0.5``.
    """
    try:
        scale = np.broadcast_to(np.asarray(scale, dtype=np.float64), (2,))
        origin = np.asarray(origin_rowcol, dtype=np.float64)
    except (TypeError, ValueError):
        raise ParameterError(
            f"scale must be one or two numbers and origin_rowcol two, got {scale!r} and {origin_rowcol!r}"
        ) from None
    if not (np.all(np.isfinite(scale)) and np.all(scale > 0)):
        raise ParameterError(f"scale must be positive and finite, got {scale.tolist()}")
    if origin.shape != (2,) or not np.all(np.isfinite(origin)):
        raise ParameterError(f"origin_rowcol must be two finite numbers, got {origin_rowcol!r}")
    return (np.asarray(rowcol, dtype=np.float64) + origin + 0.5) * scale - 0.5


def trace_outline(
    mask: ArrayLike,
    *,
    scale: float | ArrayLike = 1.0,
    origin_rowcol: ArrayLike = (0, 0),
    smooth_sigma: float | None = None,
) -> Outline:
    """Outline and centroid of one rock.

    Parameters
    ----------
    mask : (rows, cols) array_like of bool or float
        The rock: a boolean mask, or a coverage in [0, 1] whose 0.5 level is
        the edge (:class:`rockscan.core.segment.RockMask`). Where several pieces
        are present, the one enclosing the largest area is outlined.
    scale : float or (2,) array_like of float
        Photo pixels per pixel of ``mask`` (rows, cols).
    origin_rowcol : (2,) array_like of int
        Position of ``mask``'s top-left pixel in the working image.
    smooth_sigma : float, optional
        Gaussian smoothing before tracing, in pixels of ``mask``. Default:
        0.7 for a boolean mask, none for a coverage.

    Returns
    -------
    Outline

    Raises
    ------
    ParameterError
        If ``mask`` is not a 2-D array of booleans or numbers.
    NoRockFoundError
        If the mask is empty.

    Examples
    --------
    >>> import numpy as np
    >>> rr, cc = np.mgrid[0:64, 0:64]
    >>> disc = (rr - 30.0) ** 2 + (cc - 40.0) ** 2 <= 20.0**2
    >>> outline = trace_outline(disc)
    >>> np.round(outline.centroid_rowcol, 1)
    array([30., 40.])
    """
    import cv2
    from skimage.measure import find_contours

    arr = np.asarray(mask)
    if arr.ndim != 2 or arr.dtype.kind not in "biuf":
        raise ParameterError(f"mask must be a 2-D array of booleans or numbers, got {arr.dtype} {arr.shape}")
    is_bool = arr.dtype.kind == "b"
    values = arr.astype(np.float32)
    if not np.all(np.isfinite(values)):
        raise ParameterError("mask must be finite")
    if not np.any(values > 0.5):
        raise NoRockFoundError("no rock found: the rock's mask is empty")
    sigma = (0.7 if is_bool else 0.0) if smooth_sigma is None else float(smooth_sigma)
    if not (np.isfinite(sigma) and sigma >= 0):
        raise ParameterError(f"smooth_sigma must be a non-negative number, got {smooth_sigma!r}")
    # Only the part where the rock is matters; a margin of ground lets every
    # contour close inside the array.
    rows_in = np.flatnonzero((values > 0).any(axis=1))
    cols_in = np.flatnonzero((values > 0).any(axis=0))
    top, left = int(rows_in[0]), int(cols_in[0])
    values = values[top : rows_in[-1] + 1, left : cols_in[-1] + 1]
    padded = np.pad(np.clip(values, 0.0, 1.0), 2)
    if sigma > max(padded.shape):
        # Blurred wider than it is, a rock leaves no level at 0.5 (and OpenCV's
        # kernel of 6 sigma would take minutes to say so).
        raise NoRockFoundError(
            f"no rock found: a smoothing of {sigma:g} pixels leaves no outline of a rock "
            f"{max(values.shape)} pixels across"
        )
    if sigma > 0:
        padded = cv2.GaussianBlur(padded, (0, 0), sigma)
    contours = [c for c in find_contours(padded, 0.5) if len(c) >= 4]
    if not contours:
        raise NoRockFoundError("no rock found: the rock has no outline")
    contour = max(contours, key=lambda c: polygon_area_centroid(c)[0]) - 2.0 + np.array([top, left])
    if np.allclose(contour[0], contour[-1]):
        contour = contour[:-1]
    photo = work_to_photo(contour, scale, origin_rowcol)
    area, centroid = polygon_area_centroid(photo)
    if area <= 0:
        raise NoRockFoundError("no rock found: the rock's outline encloses no area")
    return Outline(contour_rowcol=photo, centroid_rowcol=centroid, area_px=area)
