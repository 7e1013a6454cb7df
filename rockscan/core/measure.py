"""A found rock measured for reports: its outline as a polygon, second moments and sizes.

The traced outline (:mod:`rockscan.core.outline`) has a vertex on every edge of the
working image's pixel grid, thousands for a large rock. Reports carry a
simplified copy: Douglas-Peucker at a fraction of the trace's own vertex
spacing, so that it stays within a fraction of a working pixel of the trace,
then its longest edges split until it has at least ``min_points`` vertices
(splitting an edge leaves the polygon, its area and centroid unchanged).

Sizes come from the polygon's second moments of area (Green's theorem), so
they are those of the outline itself, not of a pixel count:

* ``equivalent_diameter = sqrt(4 * area / pi)``, the diameter of the disc of
  equal area;
* ``major_axis`` and ``minor_axis`` are the full axis lengths of the ellipse
  with the same area-normalised second central moments: ``4 * sqrt(lambda)``
  for the eigenvalues ``lambda`` of the covariance ``[[m20, m11], [m11, m02]]``
  (as scikit-image's ``regionprops``). An ellipse of semi-axes a >= b gives
  exactly 2a and 2b.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from rockscan.core.choices import PX_PER_MM_RANGE
from rockscan.core.errors import ParameterError

__all__ = [
    "OutlineSizes",
    "outline_sizes",
    "polygon_moments",
    "report_outline_xy",
]


#: Largest share of its area a reported outline may lose or gain by simplification
#: (a rock of 45 px lost 4-5% to it).
SIMPLIFIED_AREA = 0.002


def report_outline_xy(
    contour_rowcol: ArrayLike, *, min_points: int = 64, tolerance: float | None = None
) -> NDArray[np.float64]:
    """A traced outline simplified for reports, as (x, y) = (col, row) vertices.

    Parameters
    ----------
    contour_rowcol : (n_points, 2) array_like of float
        Closed outline as (row, col) photo pixels; the last vertex joins the first.
    min_points : int
        Fewest vertices returned (at least 3).
    tolerance : float, optional
        Largest distance, in photo pixels, of the simplified polygon from the
        trace. Default: a quarter of the trace's median vertex spacing (about a
        quarter of a working pixel), halved (up to four times, then none) while
        the simplified area is more than ``SIMPLIFIED_AREA`` off the trace's.

    Returns
    -------
    xy : (n, 2) ndarray of float
        (col, row) photo pixels, ``n >= min_points``, closed implicitly (the
        first vertex is not repeated), counter-clockwise as the photo is seen
        on screen (the interface's y axis points up).
    """
    from skimage.measure import approximate_polygon

    pts = np.asarray(contour_rowcol, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 3:
        raise ParameterError(f"contour_rowcol must be (n >= 3, 2), got shape {pts.shape}")
    if min_points < 3:
        raise ParameterError(f"min_points must be at least 3, got {min_points}")
    xy = pts[:, ::-1].copy()
    if np.allclose(xy[0], xy[-1]):
        xy = xy[:-1]
    if tolerance is None:
        spacing = np.hypot(*np.diff(np.vstack([xy, xy[:1]]), axis=0).T)
        tolerance = 0.25 * float(np.median(spacing))
    closed = np.vstack([xy, xy[:1]])
    full = abs(_signed_area(xy))
    # A small rock's few vertices, cut by chords, lost 4-5% of its area: the
    # tolerance halves until the area stays the area_px reported beside it.
    for _ in range(4):
        simple = approximate_polygon(closed, tolerance)[:-1]
        if len(simple) >= 3 and abs(abs(_signed_area(simple)) - full) <= SIMPLIFIED_AREA * full:
            break
        tolerance /= 2.0
    else:
        simple = xy
    # Screen counter-clockwise is clockwise in (col, row), whose row axis points down:
    # a negative shoelace sum in (col, row).
    if _signed_area(simple) > 0:
        simple = simple[::-1]
    return _densify(simple, min_points)


def _signed_area(xy: NDArray[np.float64]) -> float:
    x, y = xy[:, 0], xy[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def _densify(xy: NDArray[np.float64], min_points: int) -> NDArray[np.float64]:
    """Split edges, each into pieces of at most perimeter / min_points, keeping every vertex."""
    if len(xy) >= min_points:
        return xy
    ends = np.roll(xy, -1, axis=0)
    lengths = np.hypot(*(ends - xy).T)
    pieces = np.maximum(1, np.ceil(lengths / (lengths.sum() / min_points))).astype(int)
    out = [
        start + (end - start) * (np.arange(k)[:, None] / k)
        for start, end, k in zip(xy, ends, pieces, strict=True)
    ]
    return np.vstack(out)


def polygon_moments(xy: ArrayLike) -> tuple[float, NDArray[np.float64], NDArray[np.float64]]:
    """Area, centroid and area-normalised second central moments of a polygon.

    Parameters
    ----------
    xy : (n, 2) array_like of float
        Vertices of a simple closed polygon in order, either orientation; the
        last joins the first.

    Returns
    -------
    area : float
        Enclosed area (positive).
    centroid : (2,) ndarray of float
    covariance : (2, 2) ndarray of float
        ``[[m20, m11], [m11, m02]]``: the mean of ``(u - cu)**2``, ``(u - cu)(v - cv)``
        and ``(v - cv)**2`` over the enclosed area.
    """
    pts = np.asarray(xy, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 3:
        raise ParameterError(f"polygon must be (n >= 3, 2) vertices, got shape {pts.shape}")
    # Moments about the vertex mean keep the sums small for a rock far from the origin.
    origin = pts.mean(axis=0)
    u, v = (pts - origin).T
    u1, v1 = np.roll(u, -1), np.roll(v, -1)
    cross = u * v1 - u1 * v
    signed = cross.sum() / 2.0
    if abs(signed) < 1e-12:
        raise ParameterError("the polygon encloses no area")
    cu = ((u + u1) * cross).sum() / (6.0 * signed)
    cv = ((v + v1) * cross).sum() / (6.0 * signed)
    suu = ((u * u + u * u1 + u1 * u1) * cross).sum() / (12.0 * signed)
    svv = ((v * v + v * v1 + v1 * v1) * cross).sum() / (12.0 * signed)
    suv = ((u * v1 + 2 * u * v + 2 * u1 * v1 + u1 * v) * cross).sum() / (24.0 * signed)
    covariance = np.array([[suu - cu * cu, suv - cu * cv], [suv - cu * cv, svv - cv * cv]])
    return abs(float(signed)), origin + np.array([cu, cv]), covariance


@dataclass(frozen=True)
class OutlineSizes:
    """Physical sizes of an outline (see the module's notes for the definitions).

    Attributes
    ----------
    area_mm2 : float
    equivalent_diameter_mm : float
    major_axis_mm : float
    minor_axis_mm : float
    """

    area_mm2: float
    equivalent_diameter_mm: float
    major_axis_mm: float
    minor_axis_mm: float


def outline_sizes(xy: ArrayLike, px_per_mm: float) -> OutlineSizes:
    """Area, equivalent diameter and ellipse axes of an outline, in millimetres.

    Parameters
    ----------
    xy : (n, 2) array_like of float
        The outline's vertices in photo pixels (square pixels).
    px_per_mm : float
        Photo pixels per millimetre on the ground.

    Returns
    -------
    OutlineSizes
    """
    low_px, high_px = PX_PER_MM_RANGE
    if not (isinstance(px_per_mm, (int, float)) and low_px <= px_per_mm <= high_px):
        raise ParameterError(f"px_per_mm must be a number from {low_px:g} to {high_px:g}, got {px_per_mm!r}")
    area, _, covariance = polygon_moments(xy)
    low, high = np.clip(np.linalg.eigvalsh(covariance), 0.0, None)
    mm = 1.0 / float(px_per_mm)
    return OutlineSizes(
        area_mm2=area * mm * mm,
        equivalent_diameter_mm=float(np.sqrt(4.0 * area / np.pi)) * mm,
        major_axis_mm=4.0 * float(np.sqrt(high)) * mm,
        minor_axis_mm=4.0 * float(np.sqrt(low)) * mm,
    )
