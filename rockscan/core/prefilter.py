"""Pruning the rotation scan of a large library: which shapes the exact scan looks at.

The exact scan (match.py) scores every rotation ``a`` of a sample against
every library shape ``k``: ``eps_k(a) = ||omega(a) - Omega_k||`` in face space,
where the FFT along theta gives the sample's coordinates ``omega(a)`` at all
rotations at once, in time independent of the library. What grows with the
library is the product of those coordinates with every shape's:
``n_angles x n_components x n_shapes`` multiplications.

A lower bound prunes it without changing the answer. Split the coordinates
into the ``d`` leading eigenfaces (the basis is ordered by eigenvalue, so they
carry most of the library's spread) and groups ``g`` of the others; since
``||x_g - y_g|| >= | ||x_g|| - ||y_g|| |``,

    eps_k(a)**2 >= ||lead(a) - Lead_k||**2 + sum_g (||omega_g(a)|| - ||Omega_k,g||)**2,

a Euclidean distance between short vectors (the leading coordinates, then
one norm per group). Its minimum over rotations, ``lb_k``, is at most
``min_a eps_k(a)**2`` (for the whole-face metric ``min_a dffs(a)**2`` is
added). All of it costs ``n_angles x n_features x n_shapes`` multiplications
in single precision, with 16 leading coordinates and groups of 8 (46 numbers
for a basis of 256 eigenfaces). The shapes of smallest bound are scanned
exactly first; every shape whose bound is below the best exact distance found
is then scanned too; the rest cannot be nearer. The nearest shape is therefore
the exhaustive scan's (up to the single-precision rounding the scan itself has).

Why not a rotation-invariant distance (magnitudes of the face's FFT along
theta)? Measured on random Superformula libraries with outline noise up to
20%, the nearest shape is decided among near-ties (the two nearest differ by
0.4% at 20% noise), which no lossy invariant ranks right: the exhaustive
scan's nearest was among the invariant's 64 nearest in 63-78% of samples
(docs/scale.md). A bound prunes only what cannot win.

MScore needs every shape's distance ``w``. Besides the pruned scan, a fixed
random sample of ``n_reference`` shapes is scanned exactly; each shape left
out gets ``sqrt(lb_k)`` times the ratio of exact distance to that bound over
the sample (a ratio estimate), and never less than the nearest distance.

Libraries of at most ``EXACT_SCAN_LIMIT`` shapes are scanned whole.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from rockscan.core.errors import ParameterError

if TYPE_CHECKING:
    from rockscan.core.library import Library

__all__ = ["EXACT_SCAN_LIMIT", "Prefilter", "Shortlist", "features_of"]

#: Libraries of at most this many shapes are scanned whole (no pruning).
EXACT_SCAN_LIMIT = 500
#: Leading eigenfaces of the bound, and the size of the groups of the others.
DEFAULT_LEAD = 16
DEFAULT_GROUP = 8
#: Shapes of smallest bound scanned first, to find a distance to prune with.
DEFAULT_FIRST = 32
#: Shapes drawn once at random and always scanned, to estimate the others' distances.
DEFAULT_REFERENCE = 64
#: Shapes whose bounds are computed at once (bounded memory for large libraries).
_BLOCK = 16384


@dataclass(frozen=True)
class Shortlist:
    """The shapes one sample's exact scan looks at.

    Attributes
    ----------
    index : (n_scanned,) ndarray of int
        Library positions, increasing: every shape that could be the nearest,
        and the reference sample.
    bound : (n_shapes,) ndarray of float
        Lower bound of each shape's distance at its best rotation.
    is_reference : (n_scanned,) ndarray of bool
        Which scanned shapes are there only as the reference sample.
    spectrum, omega : ndarray
        The sample's :meth:`rockscan.core.match.ScanTemplates.coordinates`, for the scan.
    """

    index: NDArray[np.int64]
    bound: NDArray[np.float64]
    is_reference: NDArray[np.bool_]
    spectrum: NDArray[np.complex128] = field(repr=False)
    omega: NDArray[np.float64] = field(repr=False)

    def widen(
        self, w: NDArray[np.float64], best_shift: NDArray[np.int64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Every library shape's distance and best rotation from the scanned ones'.

        Parameters
        ----------
        w : (n_scanned,) ndarray of float
            Exact distances of the scanned shapes at their best rotations.
        best_shift : (n_scanned,) ndarray of int
            Their best rotations, in rays.

        Returns
        -------
        w_all : (n_shapes,) ndarray of float
            Exact where scanned; elsewhere the bound times the ratio of exact
            distance to bound over the reference sample, never below the
            nearest shape's distance.
        shift_all : (n_shapes,) ndarray of float
            Best rotations where scanned, NaN elsewhere.
        """
        sample = self.is_reference if self.is_reference.any() else np.ones(w.size, dtype=bool)
        bound = self.bound[self.index[sample]]
        ratio = float(w[sample].sum() / bound.sum()) if bound.sum() > 0 else 1.0
        w_all = np.maximum(self.bound * ratio, float(w.min()))
        w_all[self.index] = w
        shift_all = np.full(self.bound.size, np.nan)
        shift_all[self.index] = best_shift
        return w_all, shift_all


@dataclass(frozen=True, eq=False)
class Prefilter:
    """Short vectors of every library shape whose distances bound the scan's from below.

    Build one with :meth:`from_library`.

    Attributes
    ----------
    features : (n_shapes, n_features) ndarray of float32
        ``Omega_k`` on the leading eigenfaces, then its norm on each group.
    n_lead : int
        Leading eigenfaces kept whole.
    group : int
        Eigenfaces per group after them.
    reference : (n_reference,) ndarray of int
        Shapes always scanned (a fixed random sample).
    n_first : int
        Shapes of smallest bound scanned before pruning.
    """

    features: NDArray[np.float32]
    n_lead: int
    group: int
    reference: NDArray[np.int64]
    n_first: int = DEFAULT_FIRST
    norm_sq: NDArray[np.float32] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        features = np.ascontiguousarray(self.features, dtype=np.float32)
        if features.ndim != 2 or features.shape[1] < int(self.n_lead):
            raise ParameterError("prefilter features must be (n_shapes, n_features)")
        if int(self.n_first) < 1 or int(self.group) < 1:
            raise ParameterError("n_first and group must be at least 1")
        object.__setattr__(self, "features", features)
        object.__setattr__(self, "reference", np.asarray(self.reference, dtype=np.int64))
        object.__setattr__(self, "norm_sq", np.einsum("kd,kd->k", features, features))

    @classmethod
    def from_library(
        cls,
        library: Library,
        *,
        n_lead: int = DEFAULT_LEAD,
        group: int = DEFAULT_GROUP,
        n_first: int = DEFAULT_FIRST,
        n_reference: int = DEFAULT_REFERENCE,
        seed: int = 0,
        min_shapes: int = EXACT_SCAN_LIMIT,
    ) -> Prefilter | None:
        """The prefilter of a library, or None for one scanned whole.

        None when the library has at most ``min_shapes`` shapes, its faces
        are not on the polar grid, or its basis has no more than ``n_lead``
        eigenfaces. Built from the basis alone (no faces).
        """
        n = len(library)
        weights = library.basis.weights
        if n <= min_shapes or library.face_config.grid != "polar" or weights.shape[1] <= n_lead:
            return None
        rng = np.random.default_rng(seed)
        reference = np.sort(rng.choice(n, size=min(n, int(n_reference)), replace=False))
        return cls(
            features=features_of(weights, int(n_lead), int(group)),
            n_lead=int(n_lead),
            group=int(group),
            reference=reference,
            n_first=int(n_first),
        )

    @property
    def n_shapes(self) -> int:
        """Number of library shapes."""
        return int(self.features.shape[0])

    def with_shape(self, omega: NDArray[np.float64]) -> Prefilter:
        """A copy that also holds one more shape, of coordinates ``omega`` (appended last)."""
        row = features_of(np.asarray(omega, dtype=np.float64)[None], self.n_lead, self.group)
        return Prefilter(
            np.concatenate([self.features, row]), self.n_lead, self.group, self.reference, self.n_first
        )

    def bounds(
        self, omega: NDArray[np.float64], extra_sq: NDArray[np.float64] | None = None
    ) -> NDArray[np.float64]:
        """Lower bounds of every shape's squared distance at its best rotation.

        Parameters
        ----------
        omega : (n_rotations, n_components) ndarray of float
            The sample's face-space coordinates at every rotation.
        extra_sq : (n_rotations,) ndarray of float, optional
            A term every shape's squared distance adds at each rotation (the
            squared distance from face space, for the whole-face metric).

        Returns
        -------
        lb : (n_shapes,) ndarray of float
        """
        sample = features_of(omega, self.n_lead, self.group)
        if sample.shape[1] < self.features.shape[1]:  # groups of eigenfaces not yet in use
            sample = np.pad(sample, ((0, 0), (0, self.features.shape[1] - sample.shape[1])))
        sample_sq = np.einsum("ad,ad->a", sample, sample)
        if extra_sq is not None:
            sample_sq = sample_sq + extra_sq.astype(np.float32)
        out = np.empty(self.n_shapes)
        for start in range(0, self.n_shapes, _BLOCK):
            rows = slice(start, start + _BLOCK)
            # min over rotations of ||s(a)||**2 - 2 s(a) . S_k, then + ||S_k||**2.
            cross = sample @ self.features[rows].T
            cross *= -2.0
            cross += sample_sq[:, None]
            out[rows] = cross.min(axis=0) + self.norm_sq[rows]
        # Single-precision products: keep the bound a bound by the size of their rounding.
        slack = 1e-5 * (float(sample_sq.max()) + self.norm_sq)
        return np.maximum(out - slack, 0.0)

    def first(self, lb: NDArray[np.float64]) -> NDArray[np.int64]:
        """The ``n_first`` shapes of smallest bound, increasing."""
        k = min(self.n_first, lb.size)
        return np.sort(np.argpartition(lb, k - 1)[:k]) if k < lb.size else np.arange(lb.size)

    def select(self, q: NDArray[np.float64], library: Library, metric: str) -> Shortlist:
        """The shortlist of one sample: the shapes that could be its nearest.

        Parameters
        ----------
        q : (n_angles, n_sections) ndarray of float
            The sample term of its face (polar grid).
        library : Library
            The library this prefilter belongs to.
        metric : {"eigenspace", "face"}
            The distance the nearest shape minimises.

        Returns
        -------
        Shortlist
        """
        templates = library.scan_templates
        spectrum, omega = templates.coordinates(q)
        norm_sq = np.einsum("ac,ac->a", omega, omega)
        extra_sq = None
        if metric == "face":
            extra_sq = np.maximum(templates.centered_norm_sq(q, spectrum) - norm_sq, 0.0)
            norm_sq = norm_sq + extra_sq
        lb = self.bounds(omega, extra_sq)
        first = self.first(lb)
        weights = templates.shape_weights[first]
        exact_sq = norm_sq[:, None] + templates.omega_norm_sq[None, first] - 2.0 * (omega @ weights.T)
        index = np.union1d(np.flatnonzero(lb <= float(exact_sq.min())), self.reference)
        is_reference = np.isin(index, self.reference) & (lb[index] > float(exact_sq.min()))
        return Shortlist(index, np.sqrt(lb), is_reference, spectrum, omega)


def features_of(omega: NDArray[np.float64], n_lead: int, group: int) -> NDArray[np.float32]:
    """Leading coordinates, then the norm of each group of the others: (n, n_features) float32.

    Parameters
    ----------
    omega : (n, n_components) ndarray of float
    n_lead, group : int
    """
    omega = np.asarray(omega, dtype=np.float64)
    rest = omega[:, n_lead:]
    n_groups = -(-rest.shape[1] // group)
    padded = np.zeros((omega.shape[0], n_groups * group))
    padded[:, : rest.shape[1]] = rest
    norms = np.sqrt(
        np.einsum("ngc,ngc->ng", padded.reshape(-1, n_groups, group), padded.reshape(-1, n_groups, group))
    )
    return np.hstack([omega[:, :n_lead], norms]).astype(np.float32)
