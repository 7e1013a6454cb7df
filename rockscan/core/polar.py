"""Outline -> polar radii, and the one place where image and polar coordinates meet.

Arrays stay in scikit-image's (row, col) order. The public interface's polar
frame is made here and nowhere else: for a pixel at (col, row) and a centroid
(cx, cy), ``x = col - cx``, ``y = cy - row`` (y points up, as the photo is seen on
screen) and ``theta = atan2(y, x)``, counter-clockwise from the +x axis.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from rockscan.core.errors import ParameterError

__all__ = [
    "contour_radii",
    "fold_angle",
    "polar_angles",
    "polygon_area_centroid",
    "polygon_centroid_xy",
    "radii_about",
    "radii_to_xy",
    "recenter_radii",
    "rotate_radii",
    "rowcol_from_xy",
    "symmetry_order",
    "xy_from_rowcol",
]


def polar_angles(n_angles: int) -> NDArray[np.float64]:
    """The matcher's ray angles: ``2*pi*i/n_angles`` for ``i = 0 .. n_angles-1``.

    Parameters
    ----------
    n_angles : int
        Number of rays; at least 8.

    Returns
    -------
    theta : (n_angles,) ndarray of float
        Angles in radians, counter-clockwise from +x.
    """
    n_angles = _check_n_angles(n_angles)
    return 2.0 * np.pi * np.arange(n_angles) / n_angles


def xy_from_rowcol(rowcol: ArrayLike, centroid_rowcol: ArrayLike) -> NDArray[np.float64]:
    """Convert (row, col) points to the interface's (x, y) about a centroid.

    Parameters
    ----------
    rowcol : (n, 2) array_like of float
        Points as (row, col) pixel coordinates.
    centroid_rowcol : (2,) array_like of float
        Centroid as (row, col).

    Returns
    -------
    xy : (n, 2) ndarray of float
        ``x = col - cx`` (right) and ``y = cy - row`` (up).
    """
    rowcol = np.asarray(rowcol, dtype=np.float64).reshape(-1, 2)
    cy, cx = np.asarray(centroid_rowcol, dtype=np.float64)
    return np.column_stack([rowcol[:, 1] - cx, cy - rowcol[:, 0]])


def rowcol_from_xy(xy: ArrayLike, centroid_rowcol: ArrayLike) -> NDArray[np.float64]:
    """Inverse of :func:`xy_from_rowcol`: (x, y) about a centroid to (row, col)."""
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    cy, cx = np.asarray(centroid_rowcol, dtype=np.float64)
    return np.column_stack([cy - xy[:, 1], xy[:, 0] + cx])


def contour_radii(
    contour_rowcol: ArrayLike, centroid_rowcol: ArrayLike, n_angles: int
) -> NDArray[np.float64]:
    """Polar radii of a closed outline about a centroid, at the matcher's angles.

    Parameters
    ----------
    contour_rowcol : (n_points, 2) array_like of float
        Closed outline as (row, col) vertices; the last vertex joins the first.
    centroid_rowcol : (2,) array_like of float
        Centre of the rays, (row, col).
    n_angles : int
        Number of rays, at the angles of :func:`polar_angles`.

    Returns
    -------
    radii : (n_angles,) ndarray of float
        Distance in pixels from the centroid to the outline along each ray.

    Notes
    -----
    A ray that crosses the outline more than once (a concave or hooked rock)
    takes its **farthest** crossing: the outer envelope seen from the centroid.
    Deep bays hidden behind a nearer part of the rock then do not make the
    radius jump inward, and the result does not depend on where the outline
    starts. A ray that crosses nothing (the centroid outside a crescent) gets 0.

    Each segment is intersected only with the rays inside its angular span, so
    the cost is linear in the number of vertices plus crossings.
    """
    n_angles = _check_n_angles(n_angles)
    contour = _numbers(contour_rowcol, "contour_rowcol")
    centroid = _numbers(centroid_rowcol, "centroid_rowcol")
    if contour.ndim != 2 or contour.shape[1] != 2:
        raise ParameterError(f"contour_rowcol must be (n, 2) (row, col) vertices, got shape {contour.shape}")
    if centroid.shape != (2,) or not np.all(np.isfinite(centroid)):
        raise ParameterError(
            f"centroid_rowcol must be two finite numbers (row, col), got {centroid_rowcol!r}"
        )
    xy = xy_from_rowcol(contour, centroid)
    if len(xy) < 3 or not np.all(np.isfinite(xy)):
        raise ParameterError("contour_rowcol needs at least 3 finite (row, col) vertices")
    p = xy
    q = np.roll(xy, -1, axis=0)
    step = 2.0 * np.pi / n_angles
    phi_p = np.arctan2(p[:, 1], p[:, 0])
    span = np.angle(np.exp(1j * (np.arctan2(q[:, 1], q[:, 0]) - phi_p)))
    lo = np.minimum(phi_p, phi_p + span)
    hi = np.maximum(phi_p, phi_p + span)
    first = np.ceil(lo / step - 1e-9).astype(np.int64)
    count = np.maximum(np.floor(hi / step + 1e-9).astype(np.int64) - first + 1, 0)
    seg = np.repeat(np.arange(len(p)), count)
    offsets = np.arange(seg.size) - np.repeat(np.cumsum(count) - count, count)
    ray = first[seg] + offsets
    theta = ray * step
    d = np.column_stack([np.cos(theta), np.sin(theta)])
    e = q[seg] - p[seg]
    denom = d[:, 0] * e[:, 1] - d[:, 1] * e[:, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (p[seg, 0] * e[:, 1] - p[seg, 1] * e[:, 0]) / denom
    # A ray grazing a segment (denom ~ 0) meets it at its nearer end's distance.
    graze = ~np.isfinite(t) | (np.abs(denom) < 1e-12)
    t[graze] = np.minimum(np.hypot(*p[seg[graze]].T), np.hypot(*q[seg[graze]].T))
    radii = np.zeros(n_angles)
    np.maximum.at(radii, np.mod(ray, n_angles), np.maximum(t, 0.0))
    return radii


def radii_to_xy(radii: ArrayLike, angle_deg: float = 0.0) -> NDArray[np.float64]:
    """Outline points (x, y) of radii sampled at :func:`polar_angles`.

    Parameters
    ----------
    radii : (n_angles,) array_like of float
        Radius along each ray.
    angle_deg : float, optional
        Turn the outline counter-clockwise by this angle.

    Returns
    -------
    xy : (n_angles, 2) ndarray of float
    """
    radii = np.asarray(radii, dtype=np.float64)
    theta = polar_angles(radii.size) + np.deg2rad(angle_deg)
    return np.column_stack([radii * np.cos(theta), radii * np.sin(theta)])


def polygon_area_centroid(points: ArrayLike) -> tuple[float, NDArray[np.float64]]:
    """Area and area centroid of a simple closed polygon (shoelace formula).

    Parameters
    ----------
    points : (n, 2) array_like of float
        Vertices in order, as (x, y) or (row, col); the last joins the first.

    Returns
    -------
    area : float
        Enclosed area, positive whatever the orientation.
    centroid : (2,) ndarray of float
        In the coordinates given; the vertex mean when the polygon has no area.
    """
    pts = np.asarray(points, dtype=np.float64)
    signed, cu, cv = polygon_area_centroids(pts[:, 0], pts[:, 1])
    if abs(signed) < 1e-12:
        return 0.0, pts.mean(axis=0)
    return abs(float(signed)), np.array([cu, cv])


def polygon_area_centroids(
    u: ArrayLike, v: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Signed area and area centroid of closed polygons, one per row (shoelace formula).

    Parameters
    ----------
    u, v : (..., n) array_like of float
        The vertices' two coordinates in order along the last axis; the last
        vertex joins the first.

    Returns
    -------
    signed_area, cu, cv : (...) ndarray of float
        Positive for counter-clockwise vertices in (x, y); the centroid is the
        vertex mean where the polygon has no area (``|signed_area| < 1e-12``).
    """
    u, v = np.asarray(u, dtype=np.float64), np.asarray(v, dtype=np.float64)
    u1, v1 = np.roll(u, -1, axis=-1), np.roll(v, -1, axis=-1)
    cross = u * v1 - u1 * v
    signed = cross.sum(axis=-1) / 2.0
    flat = np.abs(signed) < 1e-12
    with np.errstate(divide="ignore", invalid="ignore"):
        cu = np.where(flat, u.mean(axis=-1), ((u + u1) * cross).sum(axis=-1) / (6.0 * signed))
        cv = np.where(flat, v.mean(axis=-1), ((v + v1) * cross).sum(axis=-1) / (6.0 * signed))
    return signed, cu, cv


def polygon_centroid_xy(xy: ArrayLike) -> NDArray[np.float64]:
    """Area centroid of a simple closed polygon given as (x, y) vertices.

    Parameters
    ----------
    xy : (n, 2) array_like of float
        Vertices in order; the last joins the first.

    Returns
    -------
    centroid : (2,) ndarray of float
        The vertex mean when the polygon has no area.
    """
    return polygon_area_centroid(xy)[1]


def radii_about(radii: ArrayLike, centres: ArrayLike) -> NDArray[np.float64]:
    """Radii of many outlines about new centres, all at once.

    Parameters
    ----------
    radii : (n_outlines, n_angles) array_like of float
        Each outline's radii at :func:`polar_angles` about its present origin:
        the polygon of those points.
    centres : (n_outlines, 2) array_like of float
        The new centre of each, (x, y) in the present frame.

    Returns
    -------
    radii : (n_outlines, n_angles) ndarray of float
        Along each ray from the new centre, the **farthest** crossing of the
        polygon (as :func:`contour_radii`); 0 where a ray crosses nothing.
    """
    radii = np.asarray(radii, dtype=np.float64)
    centres = np.asarray(centres, dtype=np.float64)
    n_shapes, n_angles = radii.shape
    theta = polar_angles(n_angles)
    x, y = radii * np.cos(theta), radii * np.sin(theta)
    cx, cy = centres[:, 0], centres[:, 1]
    px, py = x - cx[:, None], y - cy[:, None]
    # contour_radii, every outline's segments in one flat list.
    qx, qy = np.roll(px, -1, axis=1).ravel(), np.roll(py, -1, axis=1).ravel()
    n_points = px.shape[1]
    px, py = px.ravel(), py.ravel()
    step = 2.0 * np.pi / n_angles
    phi = np.arctan2(y - cy[:, None], x - cx[:, None])
    phi_p = phi.ravel()
    # Each segment's end is the next one's start: its angle is the start's, rolled.
    span = np.angle(np.exp(1j * (np.roll(phi, -1, axis=1).ravel() - phi_p)))
    lo, hi = np.minimum(phi_p, phi_p + span), np.maximum(phi_p, phi_p + span)
    first = np.ceil(lo / step - 1e-9).astype(np.int64)
    count = np.maximum(np.floor(hi / step + 1e-9).astype(np.int64) - first + 1, 0)
    seg = np.repeat(np.arange(px.size), count)
    offsets = np.arange(seg.size) - np.repeat(np.cumsum(count) - count, count)
    ray = first[seg] + offsets
    # The rays' directions from a table over the whole rays met (the same numbers as
    # the cosine and sine of every crossing's ray, for a fraction of the work).
    low = int(ray.min()) if ray.size else 0
    turns = np.arange(low, int(ray.max()) + 1 if ray.size else low) * step
    dx, dy = np.cos(turns)[ray - low], np.sin(turns)[ray - low]
    ex, ey = qx[seg] - px[seg], qy[seg] - py[seg]
    denom = dx * ey - dy * ex
    with np.errstate(divide="ignore", invalid="ignore"):
        along = (px[seg] * ey - py[seg] * ex) / denom
    graze = ~np.isfinite(along) | (np.abs(denom) < 1e-12)
    along[graze] = np.minimum(
        np.hypot(px[seg[graze]], py[seg[graze]]), np.hypot(qx[seg[graze]], qy[seg[graze]])
    )
    out = np.zeros(n_shapes * n_angles)
    np.maximum.at(out, (seg // n_points) * n_angles + np.mod(ray, n_angles), np.maximum(along, 0.0))
    return out.reshape(n_shapes, n_angles)


def recenter_radii(radii: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Re-sample radii about the outline's own area centroid.

    A photo's radii are measured about the rock's centroid, so library shapes are
    put in the same frame: a Superformula's origin is not its centroid when the
    shape is not point-symmetric.

    Parameters
    ----------
    radii : (n_angles,) array_like of float
        Radii about some origin, at :func:`polar_angles`.

    Returns
    -------
    radii_centered : (n_angles,) ndarray of float
        Radii about the area centroid, same angles.
    offset_xy : (2,) ndarray of float
        Where the centroid lies in the original frame.
    """
    radii = _checked_radii(radii)
    xy = radii_to_xy(radii)
    # A dense outline keeps the re-sampled radii exact to well below a pixel.
    fine = 8
    t = np.arange(fine) / fine
    dense = xy[:, None, :] * (1 - t)[None, :, None] + np.roll(xy, -1, axis=0)[:, None, :] * t[None, :, None]
    dense = dense.reshape(-1, 2)
    centroid = polygon_centroid_xy(xy)
    rowcol = np.column_stack([-dense[:, 1], dense[:, 0]])
    centered = contour_radii(rowcol, [-centroid[1], centroid[0]], radii.size)
    return centered, centroid


def rotate_radii(radii: ArrayLike, angle_deg: float) -> NDArray[np.float64]:
    """Turn an outline counter-clockwise by ``angle_deg``, exactly, via Fourier.

    Parameters
    ----------
    radii : (n_angles,) array_like of float
        Radii at :func:`polar_angles`.
    angle_deg : float
        Counter-clockwise turn, degrees.

    Returns
    -------
    turned : (n_angles,) ndarray of float
        ``r(theta_i - alpha)``: exact for band-limited radii, and an exact
        circular shift for whole multiples of the ray step.
    """
    radii = _checked_radii(radii)
    if (
        isinstance(angle_deg, bool)
        or not isinstance(angle_deg, (int, float, np.number))
        or not np.isfinite(angle_deg)
    ):
        raise ParameterError(f"angle_deg must be a finite number, got {angle_deg!r}")
    n = radii.size
    shift = float(angle_deg) % 360.0 / 360.0 * n
    if abs(shift - round(shift)) < 1e-9:
        return np.roll(radii, int(np.round(shift)))
    spectrum = np.fft.rfft(radii)
    freq = np.arange(spectrum.size)
    phase = np.exp(-2j * np.pi * freq * shift / n)
    if n % 2 == 0:
        # The Nyquist term of a real signal cannot carry a phase; keep it real.
        phase[-1] = np.cos(np.pi * shift)
    return np.fft.irfft(spectrum * phase, n=n)


def resample_radii(radii: ArrayLike, n_angles: int) -> NDArray[np.float64]:
    """Radii sampled at other equal angles, by periodic linear interpolation.

    Parameters
    ----------
    radii : (n,) array_like of float
        Radii at ``2*pi*i/n``, i = 0 .. n-1.
    n_angles : int
        Number of rays wanted.

    Returns
    -------
    resampled : (n_angles,) ndarray of float
        Radii at :func:`polar_angles` ``(n_angles)``.
    """
    radii = _checked_radii(radii)
    position = np.arange(_check_n_angles(n_angles)) * radii.size / n_angles
    return np.interp(position, np.arange(radii.size), radii, period=radii.size)


def symmetry_order(radii: ArrayLike, *, tol: float = 1e-4, max_order: int = 36) -> int:
    """Order of rotational symmetry of an outline, read from its radii.

    Parameters
    ----------
    radii : (n_angles,) array_like of float
        Radii at :func:`polar_angles`.
    tol : float, optional
        Largest fraction of the radii's non-constant energy allowed at Fourier
        harmonics that are not multiples of the order.
    max_order : int, optional
        Largest order tried.

    Returns
    -------
    order : int
        The largest k such that turning the outline by 360/k degrees leaves it
        unchanged (1 for no symmetry), or 0 for a circle (every angle fits).

    Notes
    -----
    A k-fold symmetric curve has Fourier harmonics only at multiples of k. The
    order is read from the radii, never from the Superformula's m: with m/4
    inside the formula an odd m does not give an m-fold curve.
    """
    radii = _checked_radii(radii)
    energy = np.abs(np.fft.rfft(radii)[1:]) ** 2
    total = energy.sum()
    if total <= (1e-9 * radii.mean()) ** 2 * radii.size**2:
        return 0
    harmonic = np.arange(1, energy.size + 1)
    for k in range(min(max_order, energy.size), 1, -1):
        if energy[harmonic % k != 0].sum() <= tol * total:
            return k
    return 1


def fold_angle(angle_deg: ArrayLike, order: ArrayLike) -> NDArray[np.float64]:
    """The smallest of the equally good turns of a shape of rotational symmetry ``order``.

    Parameters
    ----------
    angle_deg : float or array_like of float
        Counter-clockwise turns, degrees.
    order : int or array_like of int
        Orders of symmetry (:func:`symmetry_order`; 0 for a circle).

    Returns
    -------
    ndarray of float
        Each turn modulo ``360/order``, in [0, 360/order); 0 for a circle, and
        0 for a turn within ``ANGLE_ROUNDING`` of the period (a hair below 0
        comes back from the modulo as the period less a rounding). A NaN turn
        (not known) stays NaN, except a circle's.
    """
    angle = np.asarray(angle_deg, dtype=np.float64)
    order = np.asarray(order)
    period = np.where(order > 0, 360.0 / np.maximum(order, 1), 0.0)
    folded = np.mod(angle, np.where(period > 0, period, 1.0))
    folded = np.where(folded < period - ANGLE_ROUNDING, folded, 0.0)
    return np.where(period > 0, np.where(np.isnan(angle), np.nan, folded), 0.0)


#: Degrees under a symmetry's period within which a turn is the period itself, i.e. 0.
ANGLE_ROUNDING = 1e-4


def _checked_radii(radii: ArrayLike) -> NDArray[np.float64]:
    """``radii`` of one outline as floats: a 1-D array of at least 3 finite,
    non-negative numbers, or a ParameterError."""
    radii = _numbers(radii, "radii")
    if radii.ndim != 1 or radii.size < 3:
        raise ParameterError(f"radii must be a 1-D array of at least 3 values, got shape {radii.shape}")
    if not np.all(np.isfinite(radii)) or np.any(radii < 0):
        raise ParameterError("radii must be finite and non-negative")
    return radii


def _numbers(values: ArrayLike, name: str) -> NDArray[np.float64]:
    """``values`` as an array of float, or a ParameterError naming them."""
    try:
        return np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be numbers, got {type(values).__name__}") from None


#: Most rays an outline is sampled at (a degree is 360; a million rays are 8 MB of radii).
MAX_ANGLES = 1 << 20


def _check_n_angles(n_angles: int) -> int:
    if (
        isinstance(n_angles, bool)
        or not isinstance(n_angles, (int, float, np.integer, np.floating))
        or not np.isfinite(n_angles)
        or int(n_angles) != n_angles
        or not 8 <= n_angles <= MAX_ANGLES
    ):
        raise ParameterError(f"n_angles must be an integer from 8 to {MAX_ANGLES}, got {n_angles!r}")
    return int(n_angles)
