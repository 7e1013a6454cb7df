"""Faces -> eigenface basis (Turk & Pentland 1991), as the paper uses it.

The mean face ``Psi`` is removed from the L library faces; the eigenvectors of
their covariance with non-zero eigenvalue (at most L - 1) span "face space".
With fewer faces than pixels they come from the small L x L matrix of inner
products, as Turk and Pentland do. A face ``Gamma`` projects to
``omega_k = u_k^T (Gamma - Psi)``; its distance to library shape k is
``eps_k = ||Omega - Omega_k||``, the paper's outWeight.

With every non-zero eigenvector kept these distances equal the distances
between the faces less their common part outside face space: eigenfaces buy
speed and compactness, not different answers.

Large libraries (:meth:`EigenBasis.from_face_stream`). The L x L matrix grows
as L**2 and its eigenproblem as L**3, while the faces' rank is bounded by the
face grid (360 x 50 values) and, in practice, far below it: for random
Superformula shapes all but 4e-5 of the variance lies in 256 directions. A
large library's basis is therefore fitted on a random sample of its faces
(exact, as above), truncated to ``n_components``, and every face of the
library is then streamed through it in chunks: memory is linear in L and no
face array of the whole library ever exists. A final Rayleigh-Ritz step turns
the kept directions to the whole library's principal axes (eigenvalues of the
whole library, mean of the whole library). What the truncation changes in the
answers is measured by scripts/bench_scale.py (docs/scale.md).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from rockscan.core._threads import one_blas_thread
from rockscan.core.errors import ParameterError

__all__ = ["STREAM_COMPONENTS", "EigenBasis"]

#: Eigenfaces a basis fitted by :meth:`EigenBasis.from_face_stream` keeps by default.
STREAM_COMPONENTS = 128
#: Faces a streamed basis is fitted on, at least (a random sample of the library).
STREAM_FIT_FACES = 1024


@dataclass(frozen=True, eq=False)
class EigenBasis:
    """An eigenface basis fitted to a set of library faces; immutable.

    Attributes
    ----------
    mean : (n_pixels,) ndarray of float
        The mean face ``Psi``.
    components : (n_components, n_pixels) ndarray of float
        Orthonormal eigenfaces ``u_k`` as rows, by decreasing eigenvalue.
    eigenvalues : (n_components,) ndarray of float
        Their eigenvalues (sums of squares along each eigenface).
    weights : (n_faces, n_components) ndarray of float
        The library faces in face space, ``Omega_k``.
    """

    mean: NDArray[np.float64]
    components: NDArray[np.float64]
    eigenvalues: NDArray[np.float64]
    weights: NDArray[np.float64]

    def __post_init__(self) -> None:
        for name in ("mean", "components", "eigenvalues", "weights"):
            arr = np.asarray(getattr(self, name), dtype=np.float64)
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        n_pixels = self.mean.size
        n_comp = self.eigenvalues.size
        if self.mean.ndim != 1 or self.components.shape != (n_comp, n_pixels):
            raise ParameterError("EigenBasis: components must be (n_components, n_pixels)")
        if self.weights.ndim != 2 or self.weights.shape[1] != n_comp:
            raise ParameterError("EigenBasis: weights must be (n_faces, n_components)")

    @classmethod
    @one_blas_thread
    def from_faces(
        cls, faces: ArrayLike, *, rtol: float = 1e-10, n_components: int | None = None
    ) -> EigenBasis:
        """Fit the basis to library faces.

        Parameters
        ----------
        faces : (n_faces, ...) array_like of float
            One face per library shape; trailing axes are flattened.
        rtol : float, optional
            Eigenvalues below ``rtol`` times the largest count as zero.
        n_components : int, optional
            Keep at most this many eigenfaces. The default keeps all with a
            non-zero eigenvalue, which changes no distance ranking.

        Returns
        -------
        EigenBasis

        Raises
        ------
        ParameterError
            With fewer than two faces, or non-finite values.
        """
        mean, components, values, centered = _fit(faces, rtol, n_components)
        weights = centered @ components.T
        return cls(mean=mean, components=components, eigenvalues=values, weights=weights)

    @classmethod
    @one_blas_thread
    def from_face_stream(
        cls, fit_faces: ArrayLike, chunks: Iterable[ArrayLike], *, n_components: int = STREAM_COMPONENTS
    ) -> EigenBasis:
        """Fit a truncated basis to a sample of faces, then stream a whole library through it.

        Parameters
        ----------
        fit_faces : (n_fit, ...) array_like of float
            A sample of the library's faces (e.g. drawn at random): the basis
            directions are their exact eigenfaces (:meth:`from_faces`).
        chunks : iterable of (n_chunk, ...) array_like of float
            Every face of the library, in library order, a chunk at a time.
        n_components : int, optional
            Eigenfaces kept (at most ``n_fit - 1``, fewer if the sample's rank
            is lower).

        Returns
        -------
        EigenBasis
            ``mean`` is the whole library's mean face; ``components`` the kept
            directions turned to the library's principal axes within them,
            ``eigenvalues`` the library's sums of squares along them, by
            decreasing value; ``weights`` every library face's coordinates.

        Notes
        -----
        Memory is one chunk of faces plus ``n_faces x n_components``
        coordinates. A library face's part outside the kept directions is
        dropped: its distance to itself stays 0, its distance from face space
        (DFFS) is that part's norm.
        """
        if isinstance(n_components, bool) or int(n_components) < 1:
            raise ParameterError("n_components must be at least 1")
        # The sample's basis, without its coordinates (the stream makes every face's).
        start_mean, directions, _, _ = _fit(fit_faces, 1e-10, int(n_components))
        n_pixels = start_mean.size
        face_sum = np.zeros(n_pixels)
        # (face - mean) . u as face . u - mean . u: no centred copy of each chunk.
        offsets = directions @ start_mean
        coords = []
        for chunk in chunks:
            flat = np.asarray(chunk, dtype=np.float64).reshape(-1, n_pixels)
            face_sum += flat.sum(axis=0)
            coords.append(flat @ directions.T - offsets)
        # A non-finite value anywhere makes the sum non-finite: one test for all faces.
        if not np.all(np.isfinite(face_sum)):
            raise ParameterError("faces must be finite")
        omega = np.concatenate(coords) if coords else np.zeros((0, directions.shape[0]))
        if omega.shape[0] < 2:
            raise ParameterError("an eigenface basis needs at least two faces")
        # Rayleigh-Ritz: the library's own covariance within the kept directions.
        # Their coordinates about the library mean are omega minus its mean, since
        # directions @ (mean - start_mean) is the mean of omega.
        centered = omega - omega.mean(axis=0)
        values, vectors = np.linalg.eigh(centered.T @ centered)
        order = np.argsort(values)[::-1]
        values, vectors = np.maximum(values[order], 0.0), vectors[:, order]
        return cls(
            mean=face_sum / omega.shape[0],
            components=vectors.T @ directions,
            eigenvalues=values,
            weights=centered @ vectors,
        )

    @property
    def n_components(self) -> int:
        """Number of eigenfaces kept."""
        return int(self.eigenvalues.size)

    @one_blas_thread
    def project(self, faces: ArrayLike) -> NDArray[np.float64]:
        """Coordinates ``Omega`` of faces in face space.

        Parameters
        ----------
        faces : (..., *face_shape) array_like of float
            Faces of the same pixel count as the library's.

        Returns
        -------
        omega : (..., n_components) ndarray of float
        """
        faces = np.asarray(faces, dtype=np.float64)
        flat = faces.reshape(-1, self.mean.size) if faces.size % self.mean.size == 0 else None
        if flat is None or faces.size == 0:
            raise ParameterError(f"faces must have {self.mean.size} pixels each")
        batch = faces.shape[: faces.ndim - _trailing_dims(faces.shape, self.mean.size)]
        return ((flat - self.mean) @ self.components.T).reshape(*batch, self.n_components)

    def distances(self, faces: ArrayLike) -> NDArray[np.float64]:
        """Distances ``eps_k`` of faces to every library face, in face space.

        Returns
        -------
        eps : (..., n_faces) ndarray of float
        """
        return self.distances_and_residual(faces)[0]

    def residual(self, faces: ArrayLike) -> NDArray[np.float64]:
        """Distance of faces from face space (Turk & Pentland's DFFS).

        Returns
        -------
        dffs : (...) ndarray of float
        """
        return self.distances_and_residual(faces)[1]

    @one_blas_thread
    def distances_and_residual(
        self, faces: ArrayLike, *, shapes: ArrayLike | None = None
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Both :meth:`distances` and :meth:`residual`, from one projection.

        Parameters
        ----------
        faces : (..., *face_shape) array_like of float
        shapes : (n,) array_like of int, optional
            Only the distances to these library faces (default: all).

        Returns
        -------
        eps : (..., n_faces) or (..., n) ndarray of float
        dffs : (...) ndarray of float
        """
        faces = np.asarray(faces, dtype=np.float64)
        omega = self.project(faces)
        weights = self.weights if shapes is None else self.weights[np.asarray(shapes, dtype=np.int64)]
        diff = omega[..., None, :] - weights
        eps = np.sqrt(np.einsum("...kc,...kc->...k", diff, diff))
        flat = faces.reshape(*omega.shape[:-1], self.mean.size) - self.mean
        inside = np.einsum("...c,...c->...", omega, omega)
        total = np.einsum("...p,...p->...", flat, flat)
        return eps, np.sqrt(np.maximum(total - inside, 0.0))


def _fit(
    faces: ArrayLike, rtol: float, n_components: int | None
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """:meth:`EigenBasis.from_faces` up to the faces' coordinates: the mean face, the
    eigenfaces, their eigenvalues and the centred faces."""
    faces = np.asarray(faces, dtype=np.float64)
    if faces.ndim < 2 or faces.shape[0] < 2:
        raise ParameterError("an eigenface basis needs at least two faces")
    flat = faces.reshape(faces.shape[0], -1)
    if not np.all(np.isfinite(flat)):
        raise ParameterError("faces must be finite")
    mean = flat.mean(axis=0)
    centered = flat - mean
    n_faces, n_pixels = centered.shape
    if n_faces <= n_pixels:
        # Turk & Pentland: eigenvectors of the small n_faces x n_faces matrix.
        gram = centered @ centered.T
        values, vectors = np.linalg.eigh(gram)
        order = np.argsort(values)[::-1]
        values, vectors = values[order], vectors[:, order]
        keep = values > rtol * max(values[0], np.finfo(float).tiny)
        if n_components is not None:  # only the eigenfaces kept are made
            keep[int(max(n_components, 1)) :] = False
        values, vectors = values[keep], vectors[:, keep]
        components = (vectors.T @ centered) / np.sqrt(values)[:, None]
    else:
        values, vectors = np.linalg.eigh(centered.T @ centered)
        order = np.argsort(values)[::-1]
        values, vectors = values[order], vectors[:, order]
        keep = values > rtol * max(values[0], np.finfo(float).tiny)
        values, components = values[keep], vectors[:, keep].T
    if n_components is not None:
        if int(n_components) < 1:
            raise ParameterError("n_components must be at least 1")
        values, components = values[: int(n_components)], components[: int(n_components)]
    return mean, components, values, centered


def _trailing_dims(shape: tuple[int, ...], n_pixels: int) -> int:
    """How many trailing axes of ``shape`` make up one face of ``n_pixels``."""
    size = 1
    for count, extent in enumerate(reversed(shape), start=1):
        size *= extent
        if size == n_pixels:
            return count
    raise ParameterError(f"faces must have {n_pixels} pixels each")
