"""Novelty (paper Section V): how far a sample is from every shape seen so far.

The paper proposes a second library, "created during the mission of observed
shapes", against which each new sample is compared; the distance to the
nearest of them quantifies its novelty. rockscan builds it from the same
parts as the library of interest: an :class:`ObservedShapes` holds a
:class:`rockscan.core.library.Library` (and so an :class:`rockscan.core.eigen.EigenBasis`)
of the known shapes, is saved with :func:`rockscan.io.save_library`, and grows
by one shape each time a sample lies farther than a threshold from all of them.

Choices (documented in docs/triage.md, "Novelty"):

* **Seed.** A new observed library starts from the library of interest's
  shapes: Section V compares a sample "both to that library and a library
  created during the mission", and a rock that one of the library's shapes
  already describes is not new. It also gives the observed library the two
  shapes a library needs from the start.
* **Distance.** The novelty score is the distance between the sample's face
  and the nearest known shape's face, each at its best rotation:
  ``sqrt(eps**2 + dffs**2)``, the eigenspace distance ``eps`` plus the distance
  from face space (``metric="face"``). The eigenspace distance alone is blind to
  whatever the known shapes do not span, and that part is exactly what makes
  a shape new; ``metric="eigenspace"`` gives the paper's ``eps`` alone.
* **Threshold.** By default half the median distance from each library shape
  to its nearest other library shape (:func:`default_threshold`): a sample is
  new when it lies farther from everything known than the library's own
  shapes lie, halfway, from each other.
* **Growth without a rebuild.** :meth:`ObservedShapes.with_shape` projects
  the new face onto the known basis and adds the part outside it as one more
  eigenface (Gram-Schmidt), so every face stays exactly in face space and
  whole-face distances equal a rebuilt library's; past
  ``MAX_GROWN_COMPONENTS`` eigenfaces a new shape is projected only. The
  arrays grow in place with room to spare: an addition costs time independent
  of the library's size (scripts/bench_scale.py measures 1,000 against
  100,000 shapes). A grown basis is not ordered by eigenvalue.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from rockscan.core._threads import one_blas_thread
from rockscan.core.calibrate import CALIBRATION_VERSION, Calibration
from rockscan.core.choices import NOVELTY_METRICS
from rockscan.core.eigen import EigenBasis
from rockscan.core.errors import LibraryError, ParameterError
from rockscan.core.information import information_face, sample_term
from rockscan.core.library import EXACT_LIMIT, NAME_PATTERN, Library, sanitize_name, unique_name
from rockscan.core.match import MatchConfig, _template_spectra, match_radii, nearest_other_distance
from rockscan.core.polar import symmetry_order
from rockscan.core.prefilter import (
    EXACT_SCAN_LIMIT,
    Prefilter,
    SensorPrefilter,
    _sensor_magnitudes,
    features_of,
)

__all__ = [
    "NOVELTY_METRICS",
    "Novelty",
    "NoveltyConfig",
    "ObservedShapes",
    "default_threshold",
    "observed_name",
]

#: Prefix of the names of shapes added to an observed library.
OBSERVED_PREFIX = "seen-"
#: :func:`default_threshold` takes the median over at most this many shapes.
THRESHOLD_SHAPES = 1000


@dataclass(frozen=True)
class NoveltyConfig:
    """Settings of the novelty score.

    Parameters
    ----------
    threshold : float or None
        A sample whose novelty exceeds this is flagged novel and added to the
        observed library. None takes :func:`default_threshold` of the library
        of interest.
    metric : {"face", "eigenspace"}
        ``"face"``: distance between whole faces (eigenspace distance and
        distance from face space); ``"eigenspace"``: the paper's ``eps`` only.
    """

    threshold: float | None = None
    metric: str = "face"

    def __post_init__(self) -> None:
        if self.metric not in NOVELTY_METRICS:
            raise ParameterError(
                f"novelty metric must be one of {', '.join(NOVELTY_METRICS)}; got {self.metric!r}"
            )
        if self.threshold is not None and not (
            isinstance(self.threshold, (int, float)) and math.isfinite(self.threshold) and self.threshold >= 0
        ):
            raise ParameterError(
                f"novelty threshold must be a non-negative number, got {self.threshold!r}; "
                "leave it unset for the library's default"
            )


@dataclass(frozen=True)
class Novelty:
    """How new one sample is.

    Attributes
    ----------
    score : float
        Distance to the nearest known shape at its best rotation (face units).
    nearest : str
        That shape's name.
    novel : bool
        ``score > threshold``.
    """

    score: float
    nearest: str
    novel: bool


def default_threshold(library: Library, *, metric: str = "face") -> float:
    """Half the median distance from each library shape to its nearest other one.

    Parameters
    ----------
    library : Library
        The library of interest.
    metric : {"face", "eigenspace"}

    Returns
    -------
    threshold : float
        In the units of the novelty score.

    Raises
    ------
    ParameterError
        For a one-shape library, which has no spacing: give a threshold.

    Notes
    -----
    The library's shapes are the scale at which rockscan tells shapes apart: a
    sample closer to a known shape than half their typical spacing would be
    taken for that shape by the nearest-neighbour rule, and one farther from all
    of them is new. Each distance is taken at the best rotation, as the score is.
    For the built-in library this is about 0.13; photos of a library shape at
    480 x 640 pixels lie within 0.05 of it (docs/triage.md, "Novelty").

    A library of more than ``THRESHOLD_SHAPES`` shapes takes the median over
    that many of its shapes, evenly spaced in library order (within 2% of the
    median over all shapes for random libraries of 2,000 and 20,000 shapes,
    docs/triage.md), and each shape's nearest neighbour costs about one match.
    """
    if metric not in NOVELTY_METRICS:
        raise ParameterError(f"metric must be one of {', '.join(NOVELTY_METRICS)}; got {metric!r}")
    n = len(library)
    if n < 2:
        raise ParameterError(
            "a one-shape library has no spacing between shapes to set the novelty threshold from; "
            "give one (NoveltyConfig(threshold=...), --novelty-threshold)"
        )
    shapes = np.unique(np.linspace(0, n - 1, min(n, THRESHOLD_SHAPES)).round().astype(np.int64))
    nearest = [nearest_other_distance(library, int(k), metric=metric) for k in shapes]
    return 0.5 * float(np.median(nearest))


def observed_name(stem: str, taken: tuple[str, ...] | set[str]) -> str:
    """A library name for a shape first seen in the photo ``stem``: ``seen-<stem>``,
    lower case letters, digits and dashes, made unique with ``-2``, ``-3``, ...

    Parameters
    ----------
    stem : str
        The photo's file name without its extension.
    taken : collection of str
        Names already in use.
    """
    return unique_name(OBSERVED_PREFIX + sanitize_name(stem, fallback="rock")[:60], taken)


@dataclass(frozen=True, eq=False)
class ObservedShapes:
    """The shapes known so far and the novelty settings; immutable.

    Build one with :meth:`from_library` (a new mission: the library of interest's
    shapes) or :meth:`from_file` (one kept from earlier runs); grow it with
    :meth:`with_shape`, which returns a new object.

    Attributes
    ----------
    library : Library
        The known shapes and their eigenface basis.
    threshold : float
        Novelty above which a sample is novel.
    metric : {"face", "eigenspace"}
    n_seed : int
        How many of ``library``'s shapes came from the library of interest
        (the first ones); the rest were observed.
    """

    library: Library
    threshold: float
    metric: str = "face"
    n_seed: int = 0
    _growth: _Growth | None = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        NoveltyConfig(threshold=self.threshold, metric=self.metric)

    @classmethod
    def from_library(cls, library: Library, config: NoveltyConfig | None = None) -> ObservedShapes:
        """A new observed library seeded with the shapes of the library of interest.

        Parameters
        ----------
        library : Library
            The library of interest.
        config : NoveltyConfig, optional
        """
        config = config or NoveltyConfig()
        threshold = (
            default_threshold(library, metric=config.metric) if config.threshold is None else config.threshold
        )
        if len(library) > EXACT_LIMIT:
            # A large library's faces are not kept; its shapes and basis seed it as they are.
            return cls(library=library, threshold=float(threshold), metric=config.metric, n_seed=len(library))
        seed = Library.from_radii(
            library.names,
            library.radii,
            face_config=library.face_config,
            params=library.params,
            interest=library.interest,
            faces=library.faces(),
        )
        return cls(library=seed, threshold=float(threshold), metric=config.metric, n_seed=len(seed))

    @classmethod
    def from_file(
        cls, observed: Library, library: Library, config: NoveltyConfig | None = None
    ) -> ObservedShapes:
        """An observed library kept from earlier runs.

        Parameters
        ----------
        observed : Library
            As read by :func:`rockscan.io.load_library`.
        library : Library
            The library of interest; sets the default threshold and must share
            the observed library's face settings.
        config : NoveltyConfig, optional

        Raises
        ------
        LibraryError
            If the two libraries' faces are made differently.
        """
        config = config or NoveltyConfig()
        if observed.face_config.to_dict() != library.face_config.to_dict():
            raise LibraryError(
                "the observed library was built with other face settings than the library "
                f"({observed.face_config.to_dict()} vs {library.face_config.to_dict()}); "
                "start a new observed library file"
            )
        threshold = (
            default_threshold(library, metric=config.metric) if config.threshold is None else config.threshold
        )
        n_seed = sum(not name.startswith(OBSERVED_PREFIX) for name in observed.names)
        return cls(library=observed, threshold=float(threshold), metric=config.metric, n_seed=n_seed)

    @property
    def n_observed(self) -> int:
        """Number of shapes added from samples."""
        return len(self.library) - self.n_seed

    def assess(self, radii: ArrayLike) -> Novelty:
        """Novelty of one sample.

        Parameters
        ----------
        radii : (n_angles,) array_like of float
            The sample's radii at :func:`rockscan.core.polar.polar_angles`, any scale.

        Returns
        -------
        Novelty
        """
        # match_radii gives every shape's distance at its best rotation, the
        # nearest one recomputed exactly (a known shape scores 0, not ~1e-6).
        match = match_radii(radii, self.library, MatchConfig(metric=self.metric))
        # The nearest shape's w is the least (its exact recomputation differs from
        # the scan's by rounding); no search of the names, which grow with the mission.
        score = float(np.min(match.distances))
        return Novelty(score=score, nearest=match.nearest, novel=score > self.threshold)

    def with_shape(self, name: str, radii: ArrayLike) -> ObservedShapes:
        """A copy that also knows one more shape.

        Parameters
        ----------
        name : str
            Unique shape name of ``[a-z0-9-]+`` starting ``seen-`` (see
            :func:`observed_name`), so that the observed library's file loads
            and counts it as observed.
        radii : (n_angles,) array_like of float
            The shape's radii, any scale.

        Returns
        -------
        ObservedShapes
        """
        lib = self.library
        if not isinstance(name, str) or not NAME_PATTERN.match(name) or not name.startswith(OBSERVED_PREFIX):
            # Saved, any other name was lost: a file that does not load, or a shape
            # counted among the library of interest's when it was read again.
            raise ParameterError(
                f"an observed shape's name must match [a-z0-9-]+ and start with {OBSERVED_PREFIX!r} "
                f"(observed_name() makes one), got {name!r}"
            )
        radii = np.asarray(radii, dtype=np.float64)
        if radii.shape != (lib.face_config.n_angles,):
            raise ParameterError(
                f"radii must be {lib.face_config.n_angles} values (the library's n_angles), got {radii.shape}"
            )
        if not np.all(np.isfinite(radii)) or np.any(radii <= 0):
            raise ParameterError("radii must be finite and positive")
        growth = self._growth if self._growth is not None and self._growth.latest is lib else _Growth(lib)
        grown = growth.append(name, radii)
        return ObservedShapes(
            library=grown, threshold=self.threshold, metric=self.metric, n_seed=self.n_seed, _growth=growth
        )


#: An observed library's basis grows by one eigenface per new shape (the part
#: of its face outside face space) until it has this many; later shapes are
#: projected onto it.
MAX_GROWN_COMPONENTS = 256
#: A new face whose part outside face space is below this fraction of its
#: distance from the mean adds no eigenface (it is already spanned).
_SPANNED = 1e-9


class _Growth:
    """Arrays with room to grow that successive observed libraries share.

    Each library made by :meth:`append` sees the first rows of the buffers
    (views); only the newest may grow in place, so a library made earlier
    never changes. Growing any other copies the buffers first (once).
    Capacity doubles when full, so an addition costs, on average, time
    independent of the library's size.
    """

    def __init__(self, library: Library) -> None:
        n = len(library)
        basis = library.basis
        self.n, self.n_components = n, basis.n_components
        self.max_components = max(self.n_components, MAX_GROWN_COMPONENTS)
        cap = max(2 * n, n + 64)
        self.radii = _grown(library.radii, cap)
        self.interest = _grown(library.interest, cap)
        self.symmetry = _grown(library.symmetry, cap)
        self.weights = np.zeros((cap, self.max_components))
        self.weights[:n, : self.n_components] = basis.weights
        self.components = np.zeros((self.max_components, basis.mean.size))
        self.components[: self.n_components] = basis.components
        self.eigenvalues = _grown(basis.eigenvalues, self.max_components)
        templates = library.scan_templates
        self.templates = templates
        self.spectra = np.zeros((*templates.spectra.shape[:2], self.max_components), templates.spectra.dtype)
        self.spectra[:, :, : self.n_components] = templates.spectra
        self.eigen_offsets = _grown(templates.eigen_offsets, self.max_components)
        self.omega_norm_sq = _grown(templates.omega_norm_sq, cap)
        # Names and parameters in lists that grow in place; each library sees its first rows.
        self.names, self.params = list(library.names), list(library.params)
        self.taken = set(library.names)
        self.prefilter: Prefilter | None = None
        self._start_prefilter(library.prefilter, cap)
        # The sensor distance keeps the seed's weights: a new shape adds its spectrum.
        self.metric = library.sensor_metric
        self.sensor_spectra = _grown(self.metric.spectra, cap)
        self.sensor_norm_sq = _grown(self.metric.norm_sq, cap)
        # Cutoffs (an observed library stores none): the seed's, and their median for new shapes.
        self.new_cutoff = float(np.median(library.cutoffs))
        self.cutoffs = _grown(library.cutoffs, cap)
        self.cutoffs[n:] = self.new_cutoff
        seed_clean = library.calibration_in_force.clean_cutoffs
        self.new_clean_cutoff = float(np.median(seed_clean))
        self.clean_cutoffs = _grown(seed_clean, cap)
        self.clean_cutoffs[n:] = self.new_clean_cutoff
        self.sensor_filter: SensorPrefilter | None = None
        self._start_sensor_filter(library.sensor_prefilter, cap)
        self.latest = library

    def _start_sensor_filter(self, sensor_filter: SensorPrefilter | None, cap: int) -> None:
        """Buffers for the sensor prefilter's rows, once the library has one."""
        self.sensor_filter = sensor_filter
        if sensor_filter is not None:
            # Feature by feature, as SensorPrefilter keeps them: one column per shape.
            self.sensor_columns = _grown(sensor_filter.features, cap).T.copy()
            self.sensor_feature_sq = _grown(sensor_filter.norm_sq, cap)

    def _start_prefilter(self, prefilter: Prefilter | None, cap: int) -> None:
        """Buffers for the prefilter's rows, once the library has one."""
        self.prefilter = prefilter
        if prefilter is not None:
            width = prefilter.n_lead + -(-(self.max_components - prefilter.n_lead) // prefilter.group)
            self.features = np.zeros((cap, width), np.float32)
            self.features[: prefilter.n_shapes, : prefilter.features.shape[1]] = prefilter.features
            self.feature_norm_sq = _grown(prefilter.norm_sq, cap)

    @one_blas_thread
    def append(self, name: str, radii: NDArray[np.float64]) -> Library:
        """The library with one more shape, grown in place (see the class docstring)."""
        lib = self.latest
        if name in self.taken:
            raise LibraryError(f"shape names must be unique; repeated: {name}")
        config, mean = lib.face_config, lib.basis.mean
        if config.grid == "polar":  # the reference information is at hand: only q is new
            face = (lib.reference_map * sample_term(radii, config)).ravel()
        else:
            face = information_face(radii, config).ravel()
        n, c = self.n, self.n_components
        if n == self.radii.shape[0]:
            self._enlarge()
        components = self.components[:c]
        centered = face - mean
        omega = components @ centered
        residual = centered - omega @ components if c < self.max_components else np.zeros(0)
        rho = float(np.linalg.norm(residual))
        if c < self.max_components and rho > _SPANNED * max(float(np.linalg.norm(centered)), 1e-300):
            # Gram-Schmidt (twice, for orthogonality to rounding) adds the new direction.
            residual -= (components @ residual) @ components
            direction = residual / np.linalg.norm(residual)
            self.components[c] = direction
            self.eigenvalues[c] = rho**2
            channel = (direction.reshape(config.face_shape) * lib.reference_map)[None]
            self.spectra[:, :, c] = _template_spectra(channel, self.spectra.dtype)[:, :, 0]
            self.eigen_offsets[c] = direction @ mean
            omega = np.append(omega, direction @ centered)
            c += 1
        self.weights[n, :c] = omega
        self.omega_norm_sq[n] = omega @ omega
        spectrum = self.metric.sample_spectrum(radii)
        self.sensor_spectra[n] = spectrum
        self.sensor_norm_sq[n] = float(np.sum(_sensor_magnitudes(spectrum[None], radii.size) ** 2))
        self.radii[n] = radii / radii.mean()
        self.interest[n] = 1.0
        self.symmetry[n] = symmetry_order(radii)
        self.names.append(name)
        self.params.append(None)
        self.taken.add(name)
        self.n, self.n_components = n + 1, c
        self.latest = self._library()
        return self.latest

    def _library(self) -> Library:
        n, c, lib = self.n, self.n_components, self.latest
        basis = EigenBasis(
            mean=lib.basis.mean,
            components=self.components[:c],
            eigenvalues=self.eigenvalues[:c],
            weights=self.weights[:n, :c],
        )
        grown = Library._unchecked(
            names=_Rows(self.names, n),
            radii=self.radii[:n],
            params=_Rows(self.params, n),
            interest=self.interest[:n],
            symmetry=self.symmetry[:n],
            face_config=lib.face_config,
            basis=basis,
        )
        self.templates = replace(
            self.templates,
            spectra=self.spectra[:, :, :c],
            eigen_offsets=self.eigen_offsets[:c],
            shape_weights=self.weights[:n, :c],
            omega_norm_sq=self.omega_norm_sq[:n],
        )
        object.__setattr__(grown, "reference_map", lib.reference_map)
        object.__setattr__(grown, "scan_templates", self.templates)
        self._grow_sensor(grown)
        if self.prefilter is None:
            if n > EXACT_SCAN_LIMIT:  # grown past the size scanned whole: built once
                self._start_prefilter(grown.prefilter, self.radii.shape[0])
            else:
                grown.set_prefilter(None)
            return grown
        row = features_of(basis.weights[n - 1][None], self.prefilter.n_lead, self.prefilter.group)[0]
        self.features[n - 1] = 0.0
        self.features[n - 1, : row.size] = row
        self.feature_norm_sq[n - 1] = row @ row
        # The prefilter's own constructor would re-derive every row's norm: O(n).
        grown_filter = object.__new__(Prefilter)
        for key, value in (
            ("features", self.features[:n]),
            ("n_lead", self.prefilter.n_lead),
            ("group", self.prefilter.group),
            ("reference", self.prefilter.reference),
            ("n_first", self.prefilter.n_first),
            ("norm_sq", self.feature_norm_sq[:n]),
        ):
            object.__setattr__(grown_filter, key, value)
        self.prefilter = grown_filter
        grown.set_prefilter(grown_filter)
        return grown

    def _grow_sensor(self, grown: Library) -> None:
        """The grown library's sensor metric, cutoffs and sensor prefilter, as views of the buffers."""
        n = self.n
        metric = replace(self.metric, spectra=self.sensor_spectra[:n], norm_sq=self.sensor_norm_sq[:n])
        object.__setattr__(grown, "sensor_metric", metric)
        # Not stored with the library (calibration stays None): what cutoffs reads.
        calibration = object.__new__(Calibration)
        for key, value in (
            ("cutoffs", self.cutoffs[:n]),
            ("clean_cutoffs", self.clean_cutoffs[:n]),
            ("spacing", np.broadcast_to(np.inf, (n,))),
            ("crowded", np.broadcast_to(False, (n,))),
            ("calibrated", np.broadcast_to(False, (n,))),
            ("tolerance", metric.tolerance),
            ("seed", 0),
            ("version", CALIBRATION_VERSION),
            ("note", "the seed library's cutoffs; their median for observed shapes"),
            ("samples", None),
        ):
            object.__setattr__(calibration, key, value)
        object.__setattr__(grown, "_calibrated_on_use", calibration)
        if self.sensor_filter is None:
            if n > EXACT_SCAN_LIMIT:  # grown past the size scanned whole: built once
                self._start_sensor_filter(grown.sensor_prefilter, self.radii.shape[0])
            else:
                object.__setattr__(grown, "sensor_prefilter", None)
            return
        sf = self.sensor_filter
        mags = _sensor_magnitudes(self.sensor_spectra[n - 1][None], grown.face_config.n_angles)
        row = (features_of(mags, sf.n_lead, sf.group)[0].astype(np.float64) - sf.centre).astype(np.float32)
        self.sensor_columns[:, n - 1] = row
        self.sensor_feature_sq[n - 1] = row @ row
        grown_filter = object.__new__(SensorPrefilter)
        for key in ("centre", "n_lead", "group", "n_first"):
            object.__setattr__(grown_filter, key, getattr(sf, key))
        object.__setattr__(grown_filter, "features", self.sensor_columns[:, :n].T)
        object.__setattr__(grown_filter, "norm_sq", self.sensor_feature_sq[:n])
        self.sensor_filter = grown_filter
        object.__setattr__(grown, "sensor_prefilter", grown_filter)

    def _enlarge(self) -> None:
        cap = 2 * self.radii.shape[0]
        for name in ("radii", "interest", "symmetry", "weights", "omega_norm_sq"):
            setattr(self, name, _grown(getattr(self, name), cap))
        for name in ("sensor_spectra", "sensor_norm_sq", "cutoffs", "clean_cutoffs"):
            setattr(self, name, _grown(getattr(self, name), cap))
        self.cutoffs[self.n :] = self.new_cutoff
        self.clean_cutoffs[self.n :] = self.new_clean_cutoff
        if self.sensor_filter is not None:
            self.sensor_columns = _grown(self.sensor_columns.T, cap).T.copy()
            self.sensor_feature_sq = _grown(self.sensor_feature_sq, cap)
        if self.prefilter is not None:
            self.features = _grown(self.features, cap)
            self.feature_norm_sq = _grown(self.feature_norm_sq, cap)


class _Rows(Sequence):
    """The first ``n`` items of a list that only grows at its end: an immutable tuple-like
    view, made in constant time (a tuple of 100,000 names costs 2 ms to copy).

    Compares equal to the tuple of the same items, hashes as it, and pickles as it.
    """

    __slots__ = ("_items", "_n")

    def __init__(self, items: list, n: int) -> None:
        self._items, self._n = items, n

    def __len__(self) -> int:
        return self._n

    def __getitem__(self, index):  # type: ignore[no-untyped-def]
        if isinstance(index, slice):
            return tuple(self._items[: self._n][index])
        if not -self._n <= index < self._n:
            raise IndexError("tuple index out of range")
        return self._items[index % self._n]

    def __iter__(self) -> Iterator:
        return itertools.islice(self._items, self._n)

    def __eq__(self, other: object) -> bool:
        if isinstance(other, (tuple, _Rows)):
            return len(other) == self._n and all(a == b for a, b in zip(self, other, strict=True))
        return NotImplemented

    def __hash__(self) -> int:
        return hash(tuple(self))

    def __repr__(self) -> str:
        return repr(tuple(self))

    def __reduce__(self):  # type: ignore[no-untyped-def]
        return (tuple, (tuple(self),))


def _grown(array: NDArray, rows: int) -> NDArray:
    """A zero-padded copy of ``array`` with ``rows`` rows."""
    out = np.zeros((rows, *np.shape(array)[1:]), dtype=np.asarray(array).dtype)
    out[: len(array)] = array
    return out
