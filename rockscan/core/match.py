"""Face, basis -> match: distances, MScore, cutoffs and the rotation scan.

For a sample with radii r and every library shape k this computes the paper's
eigenspace distance ``eps_k`` (outWeight) at every rotation of the sample, keeps
each shape's best rotation ``w_k = min_alpha eps_k(alpha)``, and reports

* the nearest shape and its refined angle,
* ``MScore = 1 - min(w) / mean(w)`` (docs/paper.md),
* whether the sample belongs to the library (``interesting``).

The decision, for a library of any size (docs/decision.md): the sample is
interesting when its distance to the nearest shape k under the sensor model
(:class:`rockscan.core.calibrate.SensorMetric`) is at most k's own cutoff, which
the library calibrated for itself at build from simulated samples
(:func:`rockscan.core.calibrate.calibrate`). A cutoff given in :class:`MatchConfig`
replaces it (``distance_cutoff``, the paper's theta on the ranked distance w)
or adds a test (``mscore_cutoff``, the paper's gamma; ``residual_cutoff``, Turk
& Pentland's distance from face space). MScore is reported as the paper
defines it but decides nothing by default: with one shape it is 0 or 1 by
construction and with two it only compares two distances.

The default (``metric="auto"``) ranks a noisy sample by the sensor distance too,
and a clean one by the paper's eigenspace distance; the paper's exact method is
``MatchConfig.paper()``.

Turning a sample shifts its face's sample term ``q`` along theta, so the scan
correlates ``q`` with Fourier templates of the eigenfaces: all ``n_angles``
rotations cost a few times one (see scripts/bench_core.py).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from rockscan.core._frozen import freeze_arrays
from rockscan.core._threads import one_blas_thread
from rockscan.core.calibrate import cutoff_at
from rockscan.core.choices import METRICS, RANK_METRICS
from rockscan.core.errors import ParameterError
from rockscan.core.information import information_face, sample_term
from rockscan.core.polar import fold_angle

if TYPE_CHECKING:
    from rockscan.core.calibrate import SensorSample
    from rockscan.core.library import Library
    from rockscan.core.prefilter import Prefilter, SensorPrefilter, SensorShortlist, Shortlist


__all__ = [
    "DECIDERS",
    "METRICS",
    "Match",
    "MatchConfig",
    "ScanTemplates",
    "match_radii",
    "rotation_scores",
]

#: "auto" ranks by the eigenspace distance samples whose estimated noise is
#: below this fraction of the library's tolerance, in a face space of at least
#: AUTO_MIN_COMPONENTS dimensions (thinner ones let a turned sample's projection
#: land on any shape); all others by the sensor distance.
AUTO_CLEAN_FRACTION = 0.25
AUTO_MIN_COMPONENTS = 3

#: What decided a match (``Match.decided_by``): the library's calibrated cutoff
#: of the nearest shape, or a cutoff given in MatchConfig.
DECIDERS = ("calibrated-cutoff", "distance-cutoff", "mscore-cutoff", "residual-cutoff")


@dataclass(frozen=True)
class MatchConfig:
    """Settings of the matcher.

    Parameters
    ----------
    distance_cutoff : float or None
        The paper's theta: the best shape must be within this distance of the
        metric that ranked the sample (with ``"auto"``, ``w`` for a clean sample
        and the sensor distance for a noisy one). None (default) takes the
        library's calibrated cutoff of the nearest shape on the sensor distance.
    mscore_cutoff : float or None
        The paper's gamma: MScore must also exceed it. None: no MScore test.
    residual_cutoff : float or None
        Largest distance of the sample's face from face space (Turk &
        Pentland's second test, ``Match.residual``). None: no such test.
    scan : bool
        Scan all rotations (default). False matches the sample as it stands,
        as in the paper's Fig. 13.
    refine : bool
        Refine the best angle below the scan step by a parabola through the
        three best rotations' squared distances.
    metric : {"auto", "sensor", "eigenspace", "face"}
        What ranks the shapes. ``"sensor"`` is the distance of the sensor
        model (:class:`rockscan.core.calibrate.SensorMetric`): log radii compared
        harmonic by harmonic, each weighed by how much of it the outline noise
        up to the library's tolerance leaves; it is also what decides.
        ``"eigenspace"`` is the paper's ``eps_k``, the distance inside face
        space: what the library's shapes cannot express is left out.
        ``"face"`` adds the distance from face space (Turk & Pentland's second
        measure), ``sqrt(eps_k**2 + dffs**2)``: the distance between whole
        faces. ``"auto"`` (default) is ``"eigenspace"`` for a sample whose own
        noise (estimated from it) is below ``AUTO_CLEAN_FRACTION`` of the
        library's tolerance, in a face space of ``AUTO_MIN_COMPONENTS`` or more
        dimensions, and ``"sensor"`` otherwise: what measured best
        (docs/decision.md). ``Match.distances`` holds the
        ranking metric's ``w``, except with ``"sensor"``, where it holds the
        paper's outWeights ``eps_k`` so that MScore stays the paper's.
    angle_metric : {"face", "eigenspace"}
        What the nearest shape's angle minimises. A turned sample leaves face
        space, where ``eps`` alone can find spurious alignments; the whole-face
        distance ``"face"`` measures the angle best (docs/accuracy.md).
        The paper's exact method is :meth:`MatchConfig.paper`.
    """

    distance_cutoff: float | None = None
    mscore_cutoff: float | None = None
    residual_cutoff: float | None = None
    scan: bool = True
    refine: bool = True
    metric: str = "auto"
    angle_metric: str = "face"

    def __post_init__(self) -> None:
        if self.metric not in RANK_METRICS:
            raise ParameterError(f"metric must be one of {', '.join(RANK_METRICS)}; got {self.metric!r}")
        _check_metric(self.angle_metric)
        for name in ("distance_cutoff", "mscore_cutoff", "residual_cutoff"):
            value = getattr(self, name)
            if value is not None and (not isinstance(value, (int, float)) or math.isnan(value)):
                raise ParameterError(f"{name} must be a number or None, got {value!r}")

    @classmethod
    def paper(cls, **changes: object) -> MatchConfig:
        """The paper's exact method: the eigenspace distance ``eps_k`` ranks the shapes
        and finds the angle (``metric="eigenspace", angle_metric="eigenspace"``).

        Parameters
        ----------
        **changes
            Other settings, e.g. ``scan=False`` for the paper's Fig. 13.
        """
        return cls(**{"metric": "eigenspace", "angle_metric": "eigenspace", **changes})

    def resolved_metric(self, library: Library) -> str:
        """The metric in force for a library before a sample is seen (``"auto"``: ``"sensor"``;
        a clean sample may still be ranked by ``"eigenspace"``, see ``metric``)."""
        return "sensor" if self.metric == "auto" else self.metric


@dataclass(frozen=True, eq=False)
class Match:
    """The result of matching one sample against a library.

    Attributes
    ----------
    nearest : str
        The closest library shape, whether or not it passes the cutoffs.
    match : str or None
        ``nearest`` if the sample passed the cutoffs, else None.
    mscore : float
        ``1 - min(w) / mean(w)``.
    distance : float
        Eigenspace distance to the nearest shape at its best rotation (outWeight).
    angle_deg : float
        Rotation of the sample from the nearest shape, counter-clockwise, in
        [0, 360/symmetry): the smallest of the equally good angles (0 for a circle).
    interesting : bool
        Whether the sample passed the cutoffs (see the module docstring).
    residual : float
        Distance of the sample's face from face space at that rotation (DFFS).
    symmetry : int
        The nearest shape's order of rotational symmetry (0: circle); the angle
        is defined modulo ``360/symmetry``.
    names : tuple of str
        Library shape names, in library order.
    distances : (n_shapes,) ndarray of float
        ``w_k`` for every library shape, each at its own best rotation: the
        paper's outWeights when the sensor distance ranks (see MatchConfig).
    angles_deg : (n_shapes,) ndarray of float
        Each shape's best rotation, by the convention of ``angle_deg`` (the
        smallest of its symmetry's equal turns, 0 for a circle); NaN for a shape
        of a large library whose scan the prefilter left out.
    sensor_distance : float
        Sensor-model distance to the nearest shape (what the calibrated cutoff tests).
    cutoff_distance : float
        The cutoff the distance test used: the nearest shape's calibrated
        cutoff on ``sensor_distance``, or ``MatchConfig.distance_cutoff`` on the
        distance that ranked the sample.
    decided_by : str
        The test that decided (one of ``DECIDERS``): for a rejection the first
        that failed, for an acceptance the distance test.
    sensor_distances : (n_shapes,) ndarray of float
        Sensor-model distance to every shape at its own best rotation.
    """

    nearest: str
    match: str | None
    mscore: float
    distance: float
    angle_deg: float
    interesting: bool
    residual: float
    symmetry: int
    names: tuple[str, ...] = field(repr=False)
    distances: NDArray[np.float64] = field(repr=False)
    angles_deg: NDArray[np.float64] = field(repr=False)
    sensor_distance: float = math.nan
    cutoff_distance: float = math.nan
    decided_by: str = "calibrated-cutoff"
    sensor_distances: NDArray[np.float64] | None = field(default=None, repr=False)

    def to_dict(self) -> dict[str, object]:
        """The interface's JSON keys (without path and centroid), plus extras."""
        return {
            "match": self.match,
            "nearest": self.nearest,
            "mscore": self.mscore,
            "distance": self.distance,
            "angle_deg": self.angle_deg,
            "interesting": self.interesting,
            "residual": self.residual,
            "symmetry": self.symmetry,
        }


@dataclass(frozen=True, eq=False)
class ScanTemplates:
    """Fourier-domain templates that score every rotation of a sample at once.

    With ``q_a`` the sample term turned back by ``a`` rays and ``W`` the
    reference information, the face is ``Gamma_a = W * q_a``. Its coordinates in
    face space, ``omega_c(a) = u_c . (Gamma_a - Psi)``, are circular
    cross-correlations of ``q`` along theta with the fixed templates ``W * u_c``,
    done for every rotation at once by FFT. Then, with ``Omega_k`` the library's
    coordinates,

    * ``eps_k(a)**2 = ||omega(a)||**2 + ||Omega_k||**2 - 2 omega(a) . Omega_k``,
      the paper's distance inside face space;
    * ``d_k(a)**2 = ||Gamma_a - Psi||**2 + ||Omega_k||**2 - 2 omega(a) . Omega_k``,
      the distance between whole faces (``F_k - Psi`` lies in face space, so its
      product with ``Gamma_a - Psi`` is ``omega(a) . Omega_k``), where
      ``||Gamma_a - Psi||**2`` correlates ``q**2`` with ``W**2`` and ``q`` with
      ``W * Psi``.

    The FFT work grows with the number of eigenfaces (at most one fewer than the
    library's shapes) and the products with ``Omega_k`` with eigenfaces times
    shapes. The eigenface channels run in single precision (see ``_correlate``).
    """

    spectra: NDArray[np.complex64]
    mean_spectrum: NDArray[np.complex128]
    weight_sq_spectrum: NDArray[np.complex128] | None
    weight_sq_rays: NDArray[np.float64] | None
    eigen_offsets: NDArray[np.float64]
    mean_norm_sq: float
    shape_weights: NDArray[np.float64]
    omega_norm_sq: NDArray[np.float64]
    n_angles: int

    def __post_init__(self) -> None:
        freeze_arrays(self)

    @classmethod
    @one_blas_thread
    def from_library(cls, library: Library) -> ScanTemplates:
        """Precompute the templates of a library (polar grid only)."""
        config = library.face_config
        if config.grid != "polar":
            raise ParameterError("Fourier scan templates need the polar grid")
        basis = library.basis
        shape = config.face_shape
        w_map = library.reference_map
        # One stack of channels against the sample term, one per eigenface; the
        # mean face and the squared weights feed the whole-face norm, where large
        # terms cancel, so they keep double precision.
        channels = basis.components.reshape(-1, *shape) * w_map
        same_rays = bool(np.array_equal(w_map, np.broadcast_to(w_map[:1], w_map.shape)))
        return cls(
            spectra=_template_spectra(channels, np.complex64),
            mean_spectrum=_template_spectra((w_map * basis.mean.reshape(shape))[None], np.complex128),
            # The same reference information on every ray (the circle, the radii
            # face) makes ||Gamma_a||**2 the same at every rotation: no FFT needed.
            weight_sq_spectrum=None if same_rays else _template_spectra((w_map**2)[None], np.complex128),
            weight_sq_rays=(w_map[0] ** 2) if same_rays else None,
            eigen_offsets=basis.components @ basis.mean,
            mean_norm_sq=float(basis.mean @ basis.mean),
            shape_weights=np.asarray(basis.weights),
            omega_norm_sq=np.einsum("kc,kc->k", basis.weights, basis.weights),
            n_angles=config.n_angles,
        )

    @property
    def n_components(self) -> int:
        """Number of eigenfaces."""
        return int(self.eigen_offsets.size)

    @one_blas_thread
    def squared_distances(
        self,
        q: NDArray[np.float64],
        metrics: tuple[str, ...] = ("eigenspace",),
        shapes: ArrayLike | None = None,
        coordinates: tuple[NDArray[np.complex128], NDArray[np.float64]] | None = None,
    ) -> dict[str, NDArray[np.float64]]:
        """Squared distances for every rotation a and shape k.

        Parameters
        ----------
        q : (n_angles, n_sections) ndarray of float
            The sample term of the face.
        metrics : tuple of {"eigenspace", "face"}
            ``"eigenspace"``: ``eps_k(a)**2``, the paper's distance inside face
            space; ``"face"``: ``d_k(a)**2``, the distance between whole faces.
        shapes : (n,) array_like of int, optional
            Only these library shapes (default: all), as columns in this order.
        coordinates : (spectrum, omega), optional
            :meth:`coordinates` of ``q`` when already at hand.

        Returns
        -------
        dist_sq : dict of str to (n_angles, n_shapes) ndarray of float
            Row a is the sample turned back by a rays (``a * 360/n_angles`` deg).
        """
        spectrum, omega = self.coordinates(q) if coordinates is None else coordinates
        rows = slice(None) if shapes is None else np.asarray(shapes, dtype=np.int64)
        base = self.omega_norm_sq[None, rows] - 2.0 * (omega @ self.shape_weights[rows].T)
        out = {}
        for metric in metrics:
            if metric == "eigenspace":
                norm_sq = np.einsum("ac,ac->a", omega, omega)
            else:
                norm_sq = self.centered_norm_sq(q, spectrum)
            dist_sq = np.add(norm_sq[:, None], base)
            out[metric] = np.maximum(dist_sq, 0.0, out=dist_sq)
        return out

    def coordinates(self, q: NDArray[np.float64]) -> tuple[NDArray[np.complex128], NDArray[np.float64]]:
        """The spectrum of ``q`` along theta and the face-space coordinates ``omega(a)``
        of the sample at every rotation, ``(n_angles, n_components)``."""
        spectrum = np.fft.rfft(q, axis=0)
        return spectrum, self._correlate(spectrum, self.spectra)[:, : self.n_components] - self.eigen_offsets

    def centered_norm_sq(
        self, q: NDArray[np.float64], spectrum: NDArray[np.complex128] | None = None
    ) -> NDArray[np.float64]:
        """``||Gamma_a - Psi||**2`` for every rotation a.

        Parameters
        ----------
        q : (n_angles, n_sections) ndarray of float
            The sample term of the face.
        spectrum : (n_angles // 2 + 1, n_sections) ndarray of complex, optional
            ``np.fft.rfft(q, axis=0)`` when already at hand.

        Returns
        -------
        norm_sq : (n_angles,) ndarray of float
        """
        spectrum = np.fft.rfft(q, axis=0) if spectrum is None else spectrum
        with_mean = self._correlate(spectrum, self.mean_spectrum)[:, 0]
        return self._face_norm_sq(q) - 2.0 * with_mean + self.mean_norm_sq

    def distances_to_face(
        self, q: NDArray[np.float64], weighted: NDArray[np.float64], target: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """``||Gamma_a - F||**2`` for every rotation a, to any face ``F``.

        Parameters
        ----------
        q : (n_angles, n_sections) ndarray of float
            The sample term of the face.
        weighted : (n_angles, n_sections) ndarray of float
            ``W * F``: the target face times the reference information.
        target : (n_angles, n_sections) ndarray of float
            ``F``, which face space need not hold (a library shape's own face
            when the library keeps fewer eigenfaces than its shapes need).

        Returns
        -------
        dist_sq : (n_angles,) ndarray of float
        """
        with_target = self._correlate(
            np.fft.rfft(q, axis=0), _template_spectra(weighted[None], np.complex128)
        )
        dist_sq = self._face_norm_sq(q) - 2.0 * with_target[:, 0] + float(np.sum(target * target))
        return np.maximum(dist_sq, 0.0, out=dist_sq)

    def _face_norm_sq(self, q: NDArray[np.float64]) -> NDArray[np.float64]:
        """``||Gamma_a||**2`` for every rotation a."""
        if self.weight_sq_rays is not None:
            return np.full(q.shape[0], float(np.sum(q * q @ self.weight_sq_rays)))
        assert self.weight_sq_spectrum is not None
        return self._correlate(np.fft.rfft(q * q, axis=0), self.weight_sq_spectrum)[:, 0]

    def _correlate(
        self, spectrum: NDArray[np.complex128], templates: NDArray[np.complexfloating]
    ) -> NDArray[np.float64]:
        # The eigenface channels run in single precision: their per-frequency
        # products are then several times faster (BLAS cgemm), at a relative
        # error near 1e-7 of values that are themselves differences from the
        # mean; match_radii recomputes the nearest shape's distance in double.
        product = (spectrum.astype(templates.dtype)[:, None, :] @ templates)[:, 0, :]
        return np.fft.irfft(product, n=self.n_angles, axis=0).astype(np.float64)


def _template_spectra(
    stack: NDArray[np.float64], dtype: type[np.complexfloating]
) -> NDArray[np.complexfloating]:
    """(n_freq, n_sections, n_channels) conjugate spectra along theta: correlation, not convolution."""
    spectra = np.conj(np.fft.rfft(stack, axis=1)).transpose(1, 2, 0)
    return np.ascontiguousarray(spectra.astype(dtype))


@one_blas_thread
def rotation_scores(radii: ArrayLike, library: Library, *, metric: str = "eigenspace") -> NDArray[np.float64]:
    """Distances of a sample to every library shape at every rotation.

    Parameters
    ----------
    radii : (n_angles,) array_like of float
        The sample's radii at :func:`rockscan.core.polar.polar_angles`, any scale.
    library : Library
    metric : {"eigenspace", "face"}
        See :class:`MatchConfig`.

    Returns
    -------
    dist : (n_angles, n_shapes) ndarray of float
        Row a: the sample turned back by ``a * 360/n_angles`` degrees, i.e. the
        distance to each shape turned by that angle (interface convention).
    """
    config = require_library(library).face_config
    radii = _check_sample(radii, config.n_angles)
    return _scan(radii, library, (_check_metric(metric),), scan=True)[metric]


def _scan(
    radii: NDArray[np.float64],
    library: Library,
    metrics: tuple[str, ...],
    *,
    scan: bool,
    q: NDArray[np.float64] | None = None,
    shapes: Shortlist | None = None,
) -> dict[str, NDArray[np.float64]]:
    """Distances (not squared) per metric, (n_rotations, n_shapes).

    ``q`` is the sample term on the polar grid when the caller has it already;
    ``shapes`` limits the polar scan to those library shapes.
    """
    config = library.face_config
    if config.grid == "polar" and q is None:
        q = sample_term(radii, config)
    if not scan:
        face = _face_at(radii, library, 0, q)
        eps, residual = library.basis.distances_and_residual(face)
        eps = eps[None, :]
        return {m: eps if m == "eigenspace" else np.sqrt(eps**2 + residual**2) for m in metrics}
    if config.grid == "polar":
        assert q is not None
        templates = library.scan_templates
        if shapes is None:
            squared = templates.squared_distances(q, metrics)
        else:
            squared = templates.squared_distances(q, metrics, shapes.index, (shapes.spectrum, shapes.omega))
        return {m: np.sqrt(v, out=v) for m, v in squared.items()}
    # The paper's Cartesian grid map: every rotation needs its own face.
    turned = np.stack([np.roll(radii, -a) for a in range(config.n_angles)])
    faces = information_face(turned, config)
    eps, residual = library.basis.distances_and_residual(faces)
    residual = residual[:, None]
    return {m: eps if m == "eigenspace" else np.sqrt(eps**2 + residual**2) for m in metrics}


@one_blas_thread
def nearest_other_distance(library: Library, k: int, *, metric: str = "eigenspace") -> float:
    """Distance from a library shape to the nearest other one, each at its best rotation.

    Parameters
    ----------
    library : Library
    k : int
        The shape's position in the library.
    metric : {"eigenspace", "face"}

    Returns
    -------
    distance : float
        As :func:`rotation_scores` gives it; inf for a one-shape library.

    Notes
    -----
    A large library scans only the shapes its prefilter cannot rule out, as a
    match does, so that all shapes' nearest neighbours cost about one match
    each, not one scan of the whole library each.
    """
    radii = require_library(library).radii[k]
    config = library.face_config
    metric = _check_metric(metric)
    prefilter = library.prefilter
    if prefilter is None or config.grid != "polar" or len(library) < 2:
        dist = rotation_scores(radii, library, metric=metric).min(axis=0)
        dist[k] = np.inf
        return float(dist.min())
    q = sample_term(radii, config)
    shortlist = prefilter.select(q, library, metric, exclude=k)
    dist = _scan(radii, library, (metric,), scan=True, q=q, shapes=shortlist)[metric].min(axis=0)
    dist[shortlist.is_reference | (shortlist.index == k)] = np.inf
    return float(dist.min())


@one_blas_thread
def match_radii(radii: ArrayLike, library: Library, config: MatchConfig | None = None) -> Match:
    """Match a sample outline, given as radii, against a library.

    Parameters
    ----------
    radii : (n_angles,) array_like of float
        Radii about the sample's centroid at :func:`rockscan.core.polar.polar_angles`
        (``n_angles`` of the library's face settings), any scale.
    library : Library
    config : MatchConfig, optional

    Returns
    -------
    Match

    Notes
    -----
    Each shape is scored at its own best rotation, so ``w`` and MScore do not
    depend on how the sample lies. The nearest shape's angle is then taken
    where ``angle_metric`` is least, refined below the scan step by a parabola
    through the squared distances at that rotation and its two neighbours.
    """
    config = config or MatchConfig()
    face_config = require_library(library).face_config
    radii = _check_sample(radii, face_config.n_angles)
    metric = config.resolved_metric(library)
    # With the sensor distance ranking, w stays the paper's outWeights (for MScore).
    w_metric = "eigenspace" if metric == "sensor" else metric
    metrics = tuple(dict.fromkeys((w_metric, config.angle_metric)))
    # The sample term is computed once: for the scan and for the nearest shape's face.
    q = sample_term(radii, face_config) if face_config.grid == "polar" else None
    # So is what the sensor model needs of it (one spectrum of the log radii).
    sensed = library.sensor_metric.sample(radii)
    if config.metric == "auto" and _clean_enough(radii, library, sensed.noise_level):
        metric = "eigenspace"
    # A large library scans only the shapes a lower bound cannot rule out
    # (prefilter.py); None: every shape.
    prefilter = library.prefilter if config.scan else None
    sensor_filter = library.sensor_prefilter if config.scan else None
    sensor_list = None
    if sensor_filter is not None and metric == "sensor":
        sensor_list = sensor_filter.select(radii, library.sensor_metric, spectrum=sensed.spectrum)
    shortlist = _shortlist(prefilter, sensor_list, config, q, library, w_metric)
    dist = _scan(radii, library, metrics, scan=config.scan, q=q, shapes=shortlist)
    chosen = dist[w_metric]
    best_shift = np.argmin(chosen, axis=0)
    w = chosen[best_shift, np.arange(chosen.shape[1])]
    # The nearest by w among the shapes scanned: an estimate never wins.
    nearest_w = int(np.argmin(w)) if shortlist is None else int(shortlist.index[int(np.argmin(w))])
    if shortlist is not None:  # every shape's w, estimated where not scanned
        w, best_shift = shortlist.widen(w, best_shift)
    # The sensor distance with the sample's own noise taken out (rockscan.core.calibrate):
    # the ranking is the same, and the cutoffs were calibrated on it.
    k, sensor_sq = _sensor_pass(
        radii, library, config.scan, metric, sensor_filter, sensor_list, nearest_w, sensed
    )
    sensor = sensed.corrected(sensor_sq)
    noise = sensed.noise_level
    col = k  # the nearest shape's column of dist
    if shortlist is not None:
        hit = np.flatnonzero(shortlist.index == k)
        if hit.size:
            col = int(hit[0])
        else:
            # The sensor distance chose a shape the eigenspace bound left out: scan it alone.
            alone = dataclasses.replace(shortlist, index=np.array([k]), is_reference=np.array([False]))
            dist = _scan(radii, library, metrics, scan=config.scan, q=q, shapes=alone)
            col = 0
            best_shift[k] = int(np.argmin(dist[w_metric][:, 0]))
    angles, angle_deg = _angles(config, library, dist, col, best_shift, k, q)
    face = _face_at(radii, library, int(best_shift[k]), q)
    eps_k, dffs = library.basis.distances_and_residual(face, shapes=[k])
    eps_best, residual = float(eps_k[0]), float(dffs)
    # The scan's distances come from expanded squares, whose rounding leaves
    # ~1e-8 where the truth is 0; the nearest shape's is recomputed directly
    # so that a library shape matched to itself scores exactly w = 0, MScore 1.
    w[k] = eps_best if w_metric == "eigenspace" else float(np.hypot(eps_best, residual))
    mean_w = float(w.mean())
    mscore = 1.0 - float(w.min()) / mean_w if mean_w > 0 else 1.0
    ranked = float(sensor[k]) if metric == "sensor" else float(w[k])  # what a given cutoff tests
    interesting, cutoff, decided_by = _decide(
        config, library, k, float(sensor[k]), noise, ranked, mscore, residual
    )
    return Match(
        nearest=library.names[k],
        match=library.names[k] if interesting else None,
        mscore=mscore,
        distance=eps_best,
        angle_deg=angle_deg,
        interesting=interesting,
        residual=residual,
        symmetry=int(library.symmetry[k]),
        names=library.names,
        distances=w,
        angles_deg=angles,
        sensor_distance=float(sensor[k]),
        cutoff_distance=cutoff,
        decided_by=decided_by,
        sensor_distances=sensor,
    )


def _shortlist(
    prefilter: Prefilter | None,
    sensor_list: SensorShortlist | None,
    config: MatchConfig,
    q: NDArray[np.float64] | None,
    library: Library,
    w_metric: str,
) -> Shortlist | None:
    """The shapes the eigenspace scan must score exactly; None: every shape."""
    if prefilter is None:
        return None
    if sensor_list is not None and config.mscore_cutoff is None:
        # The sensor distance ranks: the eigenspace distances only feed MScore, which
        # decides nothing here, so they are exact for the sensor's candidates alone.
        return prefilter.around(q, library, sensor_list.nearest_few(), np.sqrt(sensor_list.bound))
    return prefilter.select(q, library, w_metric)


def _sensor_pass(
    radii: NDArray[np.float64],
    library: Library,
    scan: bool,
    metric: str,
    sensor_filter: SensorPrefilter | None,
    sensor_list: SensorShortlist | None,
    nearest_w: int,
    sensed: SensorSample,
) -> tuple[int, NDArray[np.float64]]:
    """The nearest shape and every shape's squared sensor distance (at its best
    rotation with ``scan``): exact where it could decide, a lower bound elsewhere."""
    if sensor_list is not None:
        # Exact for every shape that could be nearest, a lower bound for the others.
        return sensor_list.nearest, sensor_list.bound
    if sensor_filter is not None:
        return nearest_w, sensor_filter.bounds_with(
            radii, library.sensor_metric, np.array([nearest_w]), spectrum=sensed.spectrum
        )
    sensor_sq = library.sensor_metric.spectrum_distances(sensed.spectrum)
    sensor_sq = sensor_sq.min(axis=0) if scan else sensor_sq[0]
    # Ranked before the noise is taken out: distances below the noise would tie at 0.
    return (int(np.argmin(sensor_sq)) if metric == "sensor" else nearest_w), sensor_sq


def _angles(
    config: MatchConfig,
    library: Library,
    dist: dict[str, NDArray[np.float64]],
    col: int,
    best_shift: NDArray[np.int64],
    k: int,
    q: NDArray[np.float64] | None = None,
) -> tuple[NDArray[np.float64], float]:
    """Every shape's best angle, and the nearest shape's refined on ``angle_metric``.

    Every angle alpha + j*360/order fits a shape of that symmetry: each is
    reported as the smallest, so that equal photos give equal numbers; a circle
    fits at every angle and gets 0 (:func:`rockscan.core.polar.fold_angle`).

    A library of fewer eigenfaces than its shapes need holds in face space
    only blurred copies of its faces, which fit a turned sample about as well
    at many angles: the nearest shape's whole-face distance (``"face"``) is
    then taken to its own face, from its radii (``q``: the sample's polar term).
    """
    step_deg = 360.0 / library.face_config.n_angles
    if not config.scan:
        return np.zeros(best_shift.size), 0.0
    # NaN where a shape's shift was estimated, not scanned: it stays NaN.
    angles = fold_angle(best_shift * step_deg, library.symmetry)
    if config.angle_metric == "face" and q is not None and not library.holds_its_faces:
        own = information_face(library.radii[k], library.face_config)
        along = np.sqrt(library.scan_templates.distances_to_face(q, library.reference_map * own, own))
    else:
        along = dist[config.angle_metric][:, col]
    shift_k = int(np.argmin(along))
    shift = float(shift_k) + (_parabola_offset(along**2, shift_k) if config.refine else 0.0)
    angle_deg = float(fold_angle(shift * step_deg, library.symmetry[k]))
    angles[k] = angle_deg
    return angles, angle_deg


def _clean_enough(radii: NDArray[np.float64], library: Library, noise: float | None = None) -> bool:
    """Whether "auto" ranks this sample by the paper's eigenspace distance.

    A sample whose own noise (estimated from it, ``SensorMetric.noise_level``)
    is below ``AUTO_CLEAN_FRACTION`` of the library's tolerance, in a face space
    of at least ``AUTO_MIN_COMPONENTS`` dimensions: the eigenspace distance then
    leaves out irregularities no library shape has (real coins stay circles).
    Noisier samples are ranked by the sensor distance, which weighs what the
    noise leaves of each harmonic. ``noise``: that estimate, when at hand.
    """
    if library.basis.n_components < AUTO_MIN_COMPONENTS:
        return False
    noise = library.sensor_metric.noise_level(radii) if noise is None else noise
    return bool(noise < AUTO_CLEAN_FRACTION * library.tolerance)


def _decide(
    config: MatchConfig,
    library: Library,
    k: int,
    sensor: float,
    noise: float,
    ranked: float,
    mscore: float,
    residual: float,
) -> tuple[bool, float, str]:
    """(interesting, the distance test's cutoff, the deciding test) for nearest shape k.

    The distance test: the sensor distance against shape k's calibrated
    cutoff at the sample's estimated noise (:func:`rockscan.core.calibrate.cutoff_at`), or, when
    ``distance_cutoff`` is given, the ``ranked`` distance (the sensor distance, or
    ``w`` of the metric that ranked this sample) against it. Then the MScore and
    residual tests, only when their cutoffs are given.
    """
    if config.distance_cutoff is None:
        cutoff = cutoff_at(library.calibration_in_force, k, noise)
        value, decider = sensor, "calibrated-cutoff"
    else:
        cutoff, value, decider = float(config.distance_cutoff), ranked, "distance-cutoff"
    if not value <= cutoff:
        return False, cutoff, decider
    if config.mscore_cutoff is not None and not mscore > config.mscore_cutoff:
        return False, cutoff, "mscore-cutoff"
    if config.residual_cutoff is not None and not residual <= config.residual_cutoff:
        return False, cutoff, "residual-cutoff"
    return True, cutoff, decider


def _face_at(
    radii: NDArray[np.float64], library: Library, shift: int, q: NDArray[np.float64] | None
) -> NDArray[np.float64]:
    """The sample's face turned back by ``shift`` rays (``q``: its polar sample term)."""
    if q is None:
        return information_face(np.roll(radii, -shift), library.face_config)
    return library.reference_map * np.roll(q, -shift, axis=0)


def _parabola_offset(values: NDArray[np.float64], index: int) -> float:
    """Sub-step offset of a periodic minimum from a parabola through 3 points."""
    n = values.size
    left, mid, right = values[(index - 1) % n], values[index], values[(index + 1) % n]
    curvature = left - 2.0 * mid + right
    if curvature <= 0:
        return 0.0
    return float(np.clip(0.5 * (left - right) / curvature, -0.5, 0.5))


def _check_metric(metric: str) -> str:
    if metric not in METRICS:
        raise ParameterError(f"metric must be one of {', '.join(METRICS)}; got {metric!r}")
    return metric


def _check_sample(radii: ArrayLike, n_angles: int) -> NDArray[np.float64]:
    radii = np.asarray(radii, dtype=np.float64)
    if radii.ndim != 1 or radii.size != n_angles:
        raise ParameterError(
            f"sample radii must be a 1-D array of {n_angles} values (the library's n_angles), "
            f"got shape {radii.shape}"
        )
    if not np.all(np.isfinite(radii)) or np.any(radii < 0) or radii.max() <= 0:
        raise ParameterError("sample radii must be finite, non-negative and not all zero")
    return radii


def require_library(value: Library) -> Library:
    """``value`` if it is a library, else a ``TypeError`` that says how to get one.

    The command line takes ``default`` or a file name where a library goes; the
    functions take the library itself, and a name given there failed deep inside
    with an ``AttributeError`` on a string. (Checked by its face settings, not
    its class: :mod:`rockscan.core.library` builds on this module.)
    """
    if not hasattr(value, "face_config") or not hasattr(value, "names"):
        raise TypeError(
            "library must be a Library (rockscan.default_library() or rockscan.load_library(path)), "
            f"not {type(value).__name__}"
        )
    return value
