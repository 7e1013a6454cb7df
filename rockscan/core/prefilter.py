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
out gets the least-squares line of exact distance against ``sqrt(lb_k)`` over
the sample, at its own bound, and never less than the nearest distance.

Two refinements keep the bound's own cost low. The rotations are first cut
into ``_ARCS`` arcs: over an arc the sample's vectors lie in a ball of centre
``c`` and radius ``r``, so ``max(||c - S_k|| - r, 0)**2`` bounds every rotation
of it (:meth:`Prefilter.coarse_bounds`); the full bound is computed only for
the shapes that one leaves. The sensor distance (rockscan.core.calibrate), which
ranks noisy samples, has its own bound (:class:`SensorPrefilter`): the
magnitudes of the log radii's harmonics, which turning leaves alone. When it
ranks, the eigenspace distances only feed MScore and are scanned for the
sensor's nearest shapes and the reference sample alone.

Libraries of at most ``EXACT_SCAN_LIMIT`` shapes are scanned whole.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from rockscan.core._frozen import freeze_arrays
from rockscan.core.errors import ParameterError

if TYPE_CHECKING:
    from rockscan.core.calibrate import SensorMetric
    from rockscan.core.library import Library
    from rockscan.core.match import ScanTemplates

__all__ = ["EXACT_SCAN_LIMIT", "Prefilter", "SensorPrefilter", "SensorShortlist", "Shortlist", "features_of"]

#: Libraries of at most this many shapes are scanned whole (no pruning).
EXACT_SCAN_LIMIT = 500
#: Leading eigenfaces of the bound, and the size of the groups of the others.
DEFAULT_LEAD = 16
DEFAULT_GROUP = 8
#: Harmonics of the sensor bound kept one by one (the weights fall fast above them).
DEFAULT_SENSOR_LEAD = 32
#: Shapes of smallest bound scanned first, to find a distance to prune with.
DEFAULT_FIRST = 32
#: Shapes drawn once at random and always scanned, to estimate the others' distances.
DEFAULT_REFERENCE = 64
#: Shapes whose bounds are computed at once (bounded memory for large libraries).
_BLOCK = 16384
#: Shapes of the sensor pass scanned exactly at a time, by increasing bound.
_SENSOR_BATCH = 64
#: Arcs of consecutive rotations of the coarse bound (see Prefilter.coarse_bounds).
_ARCS = 24


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
            Exact where scanned; elsewhere the least-squares line of exact
            distance against bound over the reference sample, at the shape's
            bound, never below the nearest shape's distance.
        shift_all : (n_shapes,) ndarray of float
            Best rotations where scanned, NaN elsewhere.
        """
        sample = self.is_reference if self.is_reference.any() else np.ones(w.size, dtype=bool)
        x, y = self.bound[self.index[sample]], w[sample]
        # A straight line through the reference sample's (bound, distance) pairs:
        # the bound tracks the distance closely but not in proportion.
        spread = float(np.sum((x - x.mean()) ** 2))
        slope = float(np.sum((x - x.mean()) * (y - y.mean())) / spread) if spread > 0 else 0.0
        w_all = self.bound - float(x.mean())
        w_all *= slope
        w_all += float(y.mean())
        np.maximum(w_all, float(w.min()), out=w_all)
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
        freeze_arrays(self)

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
        self,
        omega: NDArray[np.float64],
        extra_sq: NDArray[np.float64] | None = None,
        rows: NDArray[np.int64] | None = None,
    ) -> NDArray[np.float64]:
        """Lower bounds of every shape's squared distance at its best rotation.

        Parameters
        ----------
        omega : (n_rotations, n_components) ndarray of float
            The sample's face-space coordinates at every rotation.
        extra_sq : (n_rotations,) ndarray of float, optional
            A term every shape's squared distance adds at each rotation (the
            squared distance from face space, for the whole-face metric).
        rows : (n,) ndarray of int, optional
            Only these shapes (default: all).

        Returns
        -------
        lb : (n_shapes,) or (n,) ndarray of float
        """
        sample, sample_sq = self._sample(omega, extra_sq)
        features = self.features if rows is None else self.features[rows]
        norm_sq = self.norm_sq if rows is None else self.norm_sq[rows]
        out = np.empty(features.shape[0])
        for start in range(0, features.shape[0], _BLOCK):
            block = slice(start, start + _BLOCK)
            # min over rotations of ||s(a)||**2 - 2 s(a) . S_k, then + ||S_k||**2.
            cross = sample @ features[block].T
            cross *= -2.0
            cross += sample_sq[:, None]
            out[block] = cross.min(axis=0) + norm_sq[block]
        # Single-precision products: keep the bound a bound by the size of their rounding.
        slack = 1e-5 * (float(sample_sq.max()) + norm_sq)
        return np.maximum(out - slack, 0.0)

    def coarse_bounds(
        self, omega: NDArray[np.float64], extra_sq: NDArray[np.float64] | None = None
    ) -> NDArray[np.float64]:
        """Cheaper, looser lower bounds than :meth:`bounds`, of every shape.

        The rotations are cut into ``_ARCS`` arcs of consecutive ones; the
        sample's vectors over an arc lie in a ball of centre ``c`` and radius
        ``r``, so by the triangle inequality every rotation of the arc is at
        least ``max(||c - S_k|| - r, 0)`` from shape k. The work is ``_ARCS``
        vectors per shape instead of one per rotation.
        """
        sample, _ = self._sample(omega, None)
        n_rot = sample.shape[0]
        arcs = min(_ARCS, n_rot)
        edges = np.linspace(0, n_rot, arcs + 1).astype(np.int64)
        sizes = np.diff(edges)
        centres = np.add.reduceat(sample, edges[:-1], axis=0) / sizes[:, None].astype(np.float32)
        arc_of = np.repeat(np.arange(arcs), sizes)
        spread = np.sqrt(np.einsum("ad,ad->a", sample - centres[arc_of], sample - centres[arc_of]))
        # Rounding of single precision: the radius taken larger, the distance smaller.
        radius = np.maximum.reduceat(spread, edges[:-1]) * np.float32(1.0 + 1e-4)
        extra = np.zeros(arcs) if extra_sq is None else np.minimum.reduceat(extra_sq, edges[:-1])
        extra = np.maximum(extra, 0.0).astype(np.float32)
        centre_sq = np.einsum("md,md->m", centres, centres)
        slack = (1e-5 * (float(centre_sq.max()) + self.norm_sq)).astype(np.float32)
        out = np.empty(self.n_shapes)
        for start in range(0, self.n_shapes, _BLOCK):
            block = slice(start, start + _BLOCK)
            dist_sq = centres @ self.features[block].T
            dist_sq *= -2.0
            dist_sq += centre_sq[:, None]
            dist_sq += (self.norm_sq[block] - slack[block])[None, :]
            np.maximum(dist_sq, 0.0, out=dist_sq)
            gap = np.sqrt(dist_sq, out=dist_sq)
            gap -= radius[:, None]
            np.maximum(gap, 0.0, out=gap)
            gap *= gap
            gap += extra[:, None]
            out[block] = gap.min(axis=0)
        return out

    def _sample(
        self, omega: NDArray[np.float64], extra_sq: NDArray[np.float64] | None
    ) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
        sample = features_of(omega, self.n_lead, self.group)
        if sample.shape[1] < self.features.shape[1]:  # groups of eigenfaces not yet in use
            sample = np.pad(sample, ((0, 0), (0, self.features.shape[1] - sample.shape[1])))
        sample_sq = np.einsum("ad,ad->a", sample, sample)
        if extra_sq is not None:
            sample_sq = sample_sq + extra_sq.astype(np.float32)
        return sample, sample_sq

    def first(self, lb: NDArray[np.float64]) -> NDArray[np.int64]:
        """The ``n_first`` shapes of smallest bound, increasing."""
        k = min(self.n_first, lb.size)
        return np.sort(np.argpartition(lb, k - 1)[:k]) if k < lb.size else np.arange(lb.size)

    def select(
        self, q: NDArray[np.float64], library: Library, metric: str, *, exclude: int | None = None
    ) -> Shortlist:
        """The shortlist of one sample: the shapes that could be its nearest.

        Parameters
        ----------
        q : (n_angles, n_sections) ndarray of float
            The sample term of its face (polar grid).
        library : Library
            The library this prefilter belongs to.
        metric : {"eigenspace", "face"}
            The distance the nearest shape minimises.
        exclude : int, optional
            A shape that may not be the nearest (the sample's own, when the
            sample is a library shape and its nearest other one is wanted).

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
        # The coarse bound of every shape, then the fine one of those it leaves in:
        # any shape whose bound exceeds a distance already found cannot be nearest.
        coarse = self.coarse_bounds(omega, extra_sq)
        if exclude is not None:
            coarse[exclude] = np.inf
        best = self._best_of(omega, norm_sq, templates, self.first(coarse))
        left = np.flatnonzero(coarse <= best)
        fine = self.bounds(omega, extra_sq, rows=left)
        if left.size > self.n_first:
            # The shapes of smallest fine bound lower the distance to prune with.
            best = min(best, self._best_of(omega, norm_sq, templates, left[self.first(fine)]))
        index, is_reference = self._with_reference(left[fine <= best])
        return Shortlist(index, np.sqrt(coarse), is_reference, spectrum, omega)

    def _with_reference(self, kept: NDArray[np.int64]) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
        """``kept`` and the reference sample, increasing; which are there only as reference."""
        mask = np.zeros(self.n_shapes, dtype=bool)
        mask[self.reference] = True
        mask[kept] = True
        index = np.flatnonzero(mask)
        mask[:] = True
        mask[kept] = False
        return index, mask[index]

    @staticmethod
    def _best_of(
        omega: NDArray[np.float64],
        norm_sq: NDArray[np.float64],
        templates: ScanTemplates,
        rows: NDArray[np.int64],
    ) -> float:
        """The least exact squared distance, over rotations, of some shapes."""
        cross = omega @ templates.shape_weights[rows].T
        return float((norm_sq[:, None] + templates.omega_norm_sq[None, rows] - 2.0 * cross).min())

    def around(
        self,
        q: NDArray[np.float64],
        library: Library,
        shapes: NDArray[np.int64],
        estimate: NDArray[np.float64],
    ) -> Shortlist:
        """A shortlist of given shapes and the reference sample, not pruned by a bound.

        For a sample whose nearest shape another distance decides
        (:class:`SensorPrefilter`): only the scanned shapes' distances are exact,
        the others are ``estimate`` times the ratio over the reference sample.
        """
        spectrum, omega = library.scan_templates.coordinates(q)
        index, is_reference = self._with_reference(np.asarray(shapes, dtype=np.int64))
        return Shortlist(index, np.asarray(estimate, dtype=np.float64), is_reference, spectrum, omega)


@dataclass(frozen=True)
class SensorShortlist:
    """The shapes whose sensor distance one sample's exact pass computed.

    Attributes
    ----------
    index : (n_scanned,) ndarray of int
        Library positions, increasing: every shape that could be the nearest.
    dist_sq : (n_scanned,) ndarray of float
        Their exact squared sensor distances at their best rotations.
    bound : (n_shapes,) ndarray of float
        Every shape's lower bound of the squared distance; exact where scanned.
    """

    index: NDArray[np.int64]
    dist_sq: NDArray[np.float64]
    bound: NDArray[np.float64]

    @property
    def nearest(self) -> int:
        """The library position of the nearest shape (the exhaustive pass's)."""
        return int(self.index[int(np.argmin(self.dist_sq))])

    def nearest_few(self, count: int = DEFAULT_FIRST) -> NDArray[np.int64]:
        """The ``count`` nearest shapes by their exact distances, increasing library positions."""
        if self.index.size <= count:
            return self.index
        return np.sort(self.index[np.argpartition(self.dist_sq, count - 1)[:count]])


@dataclass(frozen=True, eq=False)
class SensorPrefilter:
    """Rotation-invariant vectors of every shape that bound its sensor distance from below.

    Turning a sample multiplies each harmonic ``X_f`` of its log radii by a
    phase, so ``|X_f e^{-i phi_f} - Y_f| >= | |X_f| - |Y_f| |`` at every
    rotation: with ``w_f`` the sensor weights and ``c_f`` the harmonic's
    count in the full spectrum (1 or 2),

        min_a d(x, y)**2 >= sum_f c_f w_f (|X_f| - |Y_f|)**2,

    and the same per group of harmonics of their norms (``features_of``).
    The bound of every shape is one short product (``n_lead`` harmonics, then
    groups of ``group``); the ``n_first`` smallest are scanned exactly, then,
    by increasing bound and ``_SENSOR_BATCH`` at a time, every shape whose
    bound is below the best distance found so far. No other shape can be
    nearer: the nearest shape is the exhaustive pass's.

    Build one with :meth:`from_metric`.

    Attributes
    ----------
    features : (n_shapes, n_features) ndarray of float32
        Each shape's weighted magnitudes less their mean over the library.
    centre : (n_features,) ndarray of float64
        That mean.
    n_lead, group : int
    n_first : int
    """

    features: NDArray[np.float32]
    centre: NDArray[np.float64]
    n_lead: int = DEFAULT_SENSOR_LEAD
    group: int = DEFAULT_GROUP
    n_first: int = DEFAULT_FIRST
    norm_sq: NDArray[np.float32] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        # Kept feature by feature (the transpose of a contiguous (n_features, n_shapes)
        # array): the product with a sample is then a pass down long rows, three times
        # faster than one short dot product per shape.
        columns = np.ascontiguousarray(np.asarray(self.features, dtype=np.float32).T)
        features = columns.T
        object.__setattr__(self, "features", features)
        object.__setattr__(self, "norm_sq", np.einsum("kd,kd->k", features, features))
        freeze_arrays(self)

    @classmethod
    def from_metric(
        cls,
        metric: SensorMetric,
        *,
        n_lead: int = DEFAULT_SENSOR_LEAD,
        group: int = DEFAULT_GROUP,
        n_first: int = DEFAULT_FIRST,
        min_shapes: int = EXACT_SCAN_LIMIT,
    ) -> SensorPrefilter | None:
        """The prefilter of a library's sensor metric, or None for one scanned whole."""
        if metric.spectra.shape[0] <= min_shapes:
            return None
        mags = _sensor_magnitudes(metric.spectra, metric.n_angles)
        raw = features_of(mags, int(n_lead), int(group)).astype(np.float64)
        centre = raw.mean(axis=0)
        return cls(
            features=(raw - centre).astype(np.float32),
            centre=centre,
            n_lead=int(n_lead),
            group=int(group),
            n_first=int(n_first),
        )

    @property
    def n_shapes(self) -> int:
        """Number of library shapes."""
        return int(self.features.shape[0])

    def bounds(self, spectrum: NDArray[np.complex128], n_angles: int) -> NDArray[np.float64]:
        """Lower bounds of every shape's squared sensor distance at its best rotation.

        Parameters
        ----------
        spectrum : (n_freq,) ndarray of complex
            The sample's :meth:`rockscan.core.calibrate.SensorMetric.sample_spectrum`.
        n_angles : int
        """
        sample = features_of(_sensor_magnitudes(spectrum[None], n_angles), self.n_lead, self.group)[0]
        sample = (sample.astype(np.float64) - self.centre).astype(np.float32)
        sample_sq = float(sample @ sample)
        out = sample @ self.features.T
        out *= -2.0
        out += self.norm_sq
        out += sample_sq
        # Single-precision products: keep the bound a bound by the size of their rounding.
        slack = 1e-5 * (sample_sq + self.norm_sq)
        return np.maximum(out.astype(np.float64) - slack, 0.0)

    def bounds_with(
        self,
        radii: NDArray[np.float64],
        metric: SensorMetric,
        shapes: NDArray[np.int64],
        *,
        spectrum: NDArray[np.complex128] | None = None,
    ) -> NDArray[np.float64]:
        """Every shape's bound of one sample, with the exact squared distance for ``shapes``
        (``spectrum``: the sample's ``metric.sample_spectrum(radii)`` when at hand)."""
        spectrum = metric.sample_spectrum(radii) if spectrum is None else spectrum
        lb = self.bounds(spectrum, metric.n_angles)
        lb[shapes] = _sensor_min_sq(metric, spectrum, shapes)
        return lb

    def select(
        self,
        radii: NDArray[np.float64],
        metric: SensorMetric,
        *,
        spectrum: NDArray[np.complex128] | None = None,
    ) -> SensorShortlist:
        """The shapes that could be nearest by the sensor distance, and their exact distances.

        Parameters
        ----------
        radii : (n_angles,) ndarray of float
            The sample.
        metric : SensorMetric
            The library's metric this prefilter was made from.
        spectrum : (n_freq,) ndarray of complex, optional
            ``metric.sample_spectrum(radii)`` when already at hand.
        """
        spectrum = metric.sample_spectrum(radii) if spectrum is None else spectrum
        lb = self.bounds(spectrum, metric.n_angles)
        own = _own_sq(spectrum, metric.n_angles)
        k = min(self.n_first, lb.size)
        first = np.argpartition(lb, k - 1)[:k] if k < lb.size else np.arange(lb.size)
        first_sq = _sensor_min_sq(metric, spectrum, first, own)
        best = float(first_sq.min())
        below = lb <= best
        below[first] = False
        rest = np.flatnonzero(below)
        rest = rest[np.argsort(lb[rest], kind="stable")]
        # By increasing bound, a batch at a time: each batch lowers the distance to
        # prune with, and a shape whose bound exceeds it is never scanned.
        done, found = [first], [first_sq]
        for start in range(0, rest.size, _SENSOR_BATCH):
            batch = rest[start : start + _SENSOR_BATCH]
            batch = batch[lb[batch] <= best]
            if batch.size == 0:
                break
            batch_sq = _sensor_min_sq(metric, spectrum, batch, own)
            best = min(best, float(batch_sq.min()))
            done.append(batch)
            found.append(batch_sq)
        index, dist_sq = np.concatenate(done), np.concatenate(found)
        order = np.argsort(index)
        index, dist_sq = index[order], dist_sq[order]
        lb[index] = dist_sq
        return SensorShortlist(index, dist_sq, lb)


def _sensor_magnitudes(spectra: NDArray[np.complex128], n_angles: int) -> NDArray[np.float64]:
    """``sqrt(c_f) |spectra|``: their squared differences sum over the full spectrum."""
    count = np.full(spectra.shape[-1], 2.0)
    count[0] = 1.0
    if n_angles % 2 == 0:
        count[-1] = 1.0
    return np.abs(spectra) * np.sqrt(count)


def _own_sq(spectrum: NDArray[np.complex128], n_angles: int) -> float:
    """A sample's own squared norm over the full spectrum, from its half."""
    count = np.full(spectrum.size, 2.0)
    count[0] = 1.0
    if n_angles % 2 == 0:
        count[-1] = 1.0
    return float(np.sum(count * np.abs(spectrum) ** 2))


def _sensor_min_sq(
    metric: SensorMetric,
    spectrum: NDArray[np.complex128],
    shapes: NDArray[np.int64],
    own: float | None = None,
) -> NDArray[np.float64]:
    """Exact squared sensor distances of one sample to some shapes, each at its best rotation
    (``own``: :func:`_own_sq` of the sample, when at hand)."""
    if shapes.size == 0:
        return np.zeros(0)
    n = metric.n_angles
    own = _own_sq(spectrum, n) if own is None else own
    corr = np.fft.irfft(spectrum[None, :] * np.conj(metric.spectra[shapes]), n=n, axis=-1)
    return np.maximum(own + metric.norm_sq[shapes] - 2.0 * n * corr.max(axis=1), 0.0)


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
