"""Comparison methods: classic shape descriptors matched to the same library.

rockscan's accuracy is measured against two standard descriptors of a closed
outline, each matching a sample to the nearest library template:

* **Hu moments** (Hu 1962) through OpenCV's ``cv2.matchShapes``: seven moment
  invariants of the region, invariant to translation, scale and rotation.
* **Elliptic Fourier descriptors** (Kuhl & Giardina 1982) through ``pyefd``,
  normalised for scale, rotation and starting point.

The third reference, the matched filter (rotation-aligned least squares on
mean-normalised radii), needs no code here: it is rockscan's own matcher with
``FaceConfig(kind="radii")`` and ``MatchConfig(metric="face")``.

Each library shape becomes a template contour: its radii (about its area
centroid, mean radius 1) drawn at ``template_radius`` pixels. Contours are
(row, col) as everywhere in rockscan; both matchers turn them into image
(x=col, y=row) points themselves, so sample and template share a handedness
(Hu's seventh invariant changes sign under reflection).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from rockscan.core.errors import ParameterError
from rockscan.core.polar import radii_to_xy

if TYPE_CHECKING:
    from rockscan.core.library import Library

__all__ = ["BaselineMatch", "EllipticFourierMatcher", "HuMomentsMatcher", "template_contours"]


@dataclass(frozen=True, eq=False)
class BaselineMatch:
    """The nearest library template of a baseline matcher.

    Attributes
    ----------
    nearest : str
        Name of the closest template.
    distance : float
        Its distance (in the matcher's own units).
    names : tuple of str
        Template names, in library order.
    distances : (n_shapes,) ndarray of float
        Distance to every template.
    """

    nearest: str
    distance: float
    names: tuple[str, ...] = field(repr=False)
    distances: NDArray[np.float64] = field(repr=False)


def template_contours(library: Library, *, template_radius: float = 200.0) -> list[NDArray[np.float64]]:
    """Every library shape drawn as a closed contour.

    Parameters
    ----------
    library : Library
    template_radius : float
        Mean radius of the drawn templates, in pixels.

    Returns
    -------
    contours : list of (n_angles, 2) ndarray of float
        (row, col) vertices about the origin, one per shape, in library order.
    """
    if not (np.isfinite(template_radius) and template_radius > 0):
        raise ParameterError(f"template_radius must be a positive number, got {template_radius!r}")
    out = []
    for radii in library.radii:
        xy = radii_to_xy(radii * template_radius)
        # Interface convention: y points up, rows point down.
        out.append(np.column_stack([-xy[:, 1], xy[:, 0]]))
    return out


def _check_contour(contour_rowcol: ArrayLike) -> NDArray[np.float64]:
    contour = np.asarray(contour_rowcol, dtype=np.float64)
    if contour.ndim != 2 or contour.shape[1] != 2 or contour.shape[0] < 3:
        raise ParameterError(
            f"contour_rowcol must be an (n_points, 2) array of (row, col) with n_points >= 3, "
            f"got shape {contour.shape}"
        )
    if not np.all(np.isfinite(contour)):
        raise ParameterError("contour_rowcol must be finite")
    if np.ptp(contour[:, 0]) == 0 or np.ptp(contour[:, 1]) == 0:
        raise ParameterError("contour_rowcol encloses no area")
    return contour


def _nearest(names: tuple[str, ...], distances: NDArray[np.float64]) -> BaselineMatch:
    k = int(np.argmin(distances))
    return BaselineMatch(nearest=names[k], distance=float(distances[k]), names=names, distances=distances)


@dataclass(frozen=True, eq=False)
class HuMomentsMatcher:
    """Nearest template by OpenCV's Hu-moment distance (``cv2.matchShapes``).

    Build with :meth:`from_library`.

    Attributes
    ----------
    names : tuple of str
    templates : tuple of (n_points, 1, 2) ndarray of float32
        Template contours as OpenCV points (x=col, y=row).
    method : int
        ``cv2.CONTOURS_MATCH_I1`` (1), ``I2`` (2) or ``I3`` (3).

    Notes
    -----
    ``I1`` compares ``1/m_i`` with ``m_i = sign(h_i) log10|h_i|`` summed over the
    seven invariants; it is OpenCV's default and the usual choice. Hu moments
    are rotation invariant, so they give no angle.
    """

    names: tuple[str, ...]
    templates: tuple[NDArray[np.float32], ...]
    method: int = 1

    @classmethod
    def from_library(
        cls, library: Library, *, method: int = 1, template_radius: float = 200.0
    ) -> HuMomentsMatcher:
        """Templates from a library's shapes.

        Parameters
        ----------
        library : Library
        method : {1, 2, 3}
            Which of OpenCV's Hu-moment distances.
        template_radius : float
            Mean radius of the drawn templates, pixels.
        """
        if method not in (1, 2, 3):
            raise ParameterError(f"method must be 1, 2 or 3 (cv2.CONTOURS_MATCH_I1..I3), got {method!r}")
        templates = tuple(_cv_points(c) for c in template_contours(library, template_radius=template_radius))
        return cls(names=library.names, templates=templates, method=method)

    def distances(self, contour_rowcol: ArrayLike) -> NDArray[np.float64]:
        """Hu-moment distance of a contour to every template.

        Parameters
        ----------
        contour_rowcol : (n_points, 2) array_like of float
            Closed outline, (row, col).

        Returns
        -------
        distances : (n_shapes,) ndarray of float
        """
        import cv2

        sample = _cv_points(_check_contour(contour_rowcol))
        return np.array([cv2.matchShapes(sample, t, self.method, 0.0) for t in self.templates])

    def match(self, contour_rowcol: ArrayLike) -> BaselineMatch:
        """The nearest template to a contour (see :meth:`distances`)."""
        return _nearest(self.names, self.distances(contour_rowcol))


def _cv_points(contour_rowcol: NDArray[np.float64]) -> NDArray[np.float32]:
    return np.ascontiguousarray(contour_rowcol[:, ::-1], dtype=np.float32).reshape(-1, 1, 2)


@dataclass(frozen=True, eq=False)
class EllipticFourierMatcher:
    """Nearest template by normalised elliptic Fourier descriptors (``pyefd``).

    Build with :meth:`from_library`.

    Attributes
    ----------
    names : tuple of str
    descriptors : (n_shapes, order, 4) ndarray of float
        The templates' normalised descriptors.
    order : int
        Number of harmonics.

    Notes
    -----
    Kuhl and Giardina's normalisation turns the first harmonic's ellipse to a
    fixed orientation and a fixed starting point, each only up to a half turn:
    moving the start half way round flips the sign of every odd harmonic,
    turning by half a turn flips them all. The distance to a template is the
    smallest Euclidean distance to its four forms.
    When the first harmonic is a circle (a shape with 3-fold or higher
    symmetry) its orientation is undefined and the normalisation follows the
    noise; this is the method's known weakness, kept here as it is.
    """

    names: tuple[str, ...]
    descriptors: NDArray[np.float64]
    order: int = 16

    @classmethod
    def from_library(
        cls, library: Library, *, order: int = 16, template_radius: float = 200.0
    ) -> EllipticFourierMatcher:
        """Templates from a library's shapes.

        Parameters
        ----------
        library : Library
        order : int
            Harmonics kept, at least 2.
        template_radius : float
            Mean radius of the drawn templates, pixels.
        """
        if isinstance(order, bool) or int(order) != order or order < 2:
            raise ParameterError(f"order must be an integer >= 2, got {order!r}")
        contours = template_contours(library, template_radius=template_radius)
        descriptors = np.stack([_efd(c, int(order)) for c in contours])
        return cls(names=library.names, descriptors=descriptors, order=int(order))

    def descriptor(self, contour_rowcol: ArrayLike) -> NDArray[np.float64]:
        """Normalised descriptors of a contour, ``(order, 4)``."""
        return _efd(_check_contour(contour_rowcol), self.order)

    def distances(self, contour_rowcol: ArrayLike) -> NDArray[np.float64]:
        """Descriptor distance of a contour to every template, ``(n_shapes,)``."""
        sample = self.descriptor(contour_rowcol).ravel()
        odd = np.where(np.arange(1, self.order + 1) % 2 == 1, -1.0, 1.0)[:, None]
        forms = [np.ones((self.order, 1)), odd, -np.ones((self.order, 1)), -odd]
        flat = self.descriptors.reshape(len(self.names), -1)
        return np.min(
            [
                np.linalg.norm(flat * np.broadcast_to(f, (self.order, 4)).ravel() - sample, axis=1)
                for f in forms
            ],
            axis=0,
        )

    def match(self, contour_rowcol: ArrayLike) -> BaselineMatch:
        """The nearest template to a contour (see :meth:`distances`)."""
        return _nearest(self.names, self.distances(contour_rowcol))


def _efd(contour_rowcol: NDArray[np.float64], order: int) -> NDArray[np.float64]:
    from pyefd import elliptic_fourier_descriptors

    xy = contour_rowcol[:, ::-1]
    return np.asarray(elliptic_fourier_descriptors(xy, order=order, normalize=True), dtype=np.float64)
