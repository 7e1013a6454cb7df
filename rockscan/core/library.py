"""A library of shapes of interest and its eigenface basis.

A library is built from named shapes, each a Superformula (the paper's way) or
radii measured from example rocks. Every shape is put in the frame a photo's
rock is measured in: radii about the outline's own area centroid, normalised to
a mean radius of 1. Their faces train the eigenface basis, and the library
calibrates its own per-shape cutoffs (:mod:`rockscan.core.calibrate`) for the
outline noise it is meant to tolerate.

Large libraries. A library of at most ``EXACT_LIMIT`` shapes gets the exact
basis of the paper (every eigenface with a non-zero eigenvalue). A larger one
is built in chunks: radii, symmetry and faces of a chunk of shapes at once
(vectorised over the chunk, with each face's section probabilities read off a
cubic Hermite table in the radius, within 1e-11 of the direct normal CDF),
and streamed through a truncated basis
(:meth:`rockscan.core.eigen.EigenBasis.from_face_stream`). Memory is linear in the
number of shapes; no array of every face exists. Matching such a library is
pruned by a lower bound (rockscan/core/prefilter.py).
"""

from __future__ import annotations

import re
from collections import deque
from collections.abc import Collection, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from rockscan.core._threads import one_blas_thread
from rockscan.core.calibrate import DEFAULT_TOLERANCE, Calibration, SensorMetric, calibrate
from rockscan.core.eigen import STREAM_COMPONENTS, STREAM_FIT_FACES, EigenBasis
from rockscan.core.errors import LibraryError, ParameterError, SpecError
from rockscan.core.information import (
    FaceConfig,
    information_face,
    normalize_radii,
    reference_information,
    section_edges,
    section_probabilities,
)
from rockscan.core.polar import polar_angles, polygon_area_centroids, radii_about, symmetry_order
from rockscan.core.superformula import SuperformulaParams, degenerate_rays, log_superformula, shape_radii

if TYPE_CHECKING:
    from rockscan.core.match import ScanTemplates
    from rockscan.core.prefilter import Prefilter, SensorPrefilter

__all__ = [
    "EXACT_LIMIT",
    "NAME_PATTERN",
    "Library",
    "ShapeSpec",
    "closed_shapes_radii",
    "noise_origins",
    "sanitize_name",
    "shape_radii",
    "shapes_radii",
    "symmetry_orders",
    "unique_name",
]

#: Allowed shape names.
NAME_PATTERN = re.compile(r"^[a-z0-9-]+$")
#: Libraries of at most this many shapes get the exact basis (every non-zero eigenface).
EXACT_LIMIT = 1000
#: Shapes whose radii and faces a large build computes at once.
_CHUNK = 256
#: Step of the radius table of section probabilities (map units); see _FaceTable.
_TABLE_STEP = 5e-4
#: Threads that make a large build's faces (the machine's two cores).
_BUILD_THREADS = 2


def sanitize_name(text: str, *, fallback: str = "shape") -> str:
    """A shape name from free text: lower case, every run of other characters to one '-'.

    Parameters
    ----------
    text : str
        E.g. a photo's file name stem.
    fallback : str
        The name when nothing is left.

    Returns
    -------
    name : str
        Matches ``[a-z0-9-]+``.

    Examples
    --------
    >>> sanitize_name("Rock_07 (left).JPG")
    'rock-07-left-jpg'
    """
    name = re.sub(r"[^a-z0-9]+", "-", str(text).lower()).strip("-")
    return name or fallback


def unique_name(name: str, taken: Collection[str]) -> str:
    """``name``, or ``name-2``, ``name-3``, ... : the first not in ``taken``.

    Examples
    --------
    >>> unique_name("egg", {"egg", "egg-2"})
    'egg-3'
    """
    if name not in taken:
        return name
    k = 2
    while f"{name}-{k}" in taken:
        k += 1
    return f"{name}-{k}"


@dataclass(frozen=True)
class ShapeSpec:
    """One named shape of a library spec.

    Parameters
    ----------
    name : str
        Unique, lower case letters, digits and dashes.
    params : SuperformulaParams or None
        The shape's Superformula; None when it is given by example photos.
    interest : float
        How much a match to this shape is worth (triage ranks by it); default 1.
    images : tuple of str
        Example photos defining the shape instead of ``params``.
    """

    name: str
    params: SuperformulaParams | None = None
    interest: float = 1.0
    images: tuple[str, ...] = field(default=())

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not NAME_PATTERN.match(self.name):
            raise SpecError(f"shape name {self.name!r} must match [a-z0-9-]+")
        if not (
            isinstance(self.interest, (int, float)) and np.isfinite(self.interest) and self.interest >= 0
        ):
            raise SpecError(f"shape {self.name!r}: interest must be a non-negative number")
        if self.params is not None and self.images:
            raise SpecError(f"shape {self.name!r}: give either Superformula parameters or images, not both")
        if self.params is None and not self.images:
            raise SpecError(f"shape {self.name!r}: give Superformula parameters or example images")


@dataclass(frozen=True, eq=False)
class Library:
    """Named shapes, their radii and the eigenface basis of their faces; immutable.

    Build one with :meth:`from_shapes` (Superformula spec) or :meth:`from_radii`;
    load and save with :func:`rockscan.io.load_library` and
    :func:`rockscan.io.save_library`.

    Attributes
    ----------
    names : tuple of str
    radii : (n_shapes, n_angles) ndarray of float
        Radii about each outline's centroid, mean 1.
    params : tuple of SuperformulaParams or None
    interest : (n_shapes,) ndarray of float
    symmetry : (n_shapes,) ndarray of int
        Order of rotational symmetry (0 for a circle).
    face_config : FaceConfig
    basis : EigenBasis
    calibration : Calibration or None
        Per-shape cutoffs; None calibrates them on first use (at the default
        tolerance), as for a library file written before cutoffs were stored.
    """

    names: tuple[str, ...]
    radii: NDArray[np.float64]
    params: tuple[SuperformulaParams | None, ...]
    interest: NDArray[np.float64]
    symmetry: NDArray[np.int64]
    face_config: FaceConfig
    basis: EigenBasis
    calibration: Calibration | None = None

    def __post_init__(self) -> None:
        n = len(self.names)
        if n < 1:
            raise LibraryError("a library needs at least one shape")
        if len(set(self.names)) != n:
            dupes = sorted({x for x in self.names if self.names.count(x) > 1})
            raise LibraryError(f"shape names must be unique; repeated: {', '.join(dupes)}")
        radii = np.asarray(self.radii, dtype=np.float64)
        if radii.shape != (n, self.face_config.n_angles):
            raise LibraryError("library radii must be (n_shapes, n_angles)")
        if len(self.params) != n or np.shape(self.interest) != (n,) or np.shape(self.symmetry) != (n,):
            raise LibraryError("library arrays disagree on the number of shapes")
        if self.basis.weights.shape[0] != n or self.basis.mean.size != int(
            np.prod(self.face_config.face_shape)
        ):
            raise LibraryError("library basis does not fit its shapes and face settings")
        for name, value in (("radii", radii), ("interest", self.interest)):
            if not np.all(np.isfinite(value)):
                raise LibraryError(f"library {name} must be finite")
        if np.any(radii < 0) or np.any(np.asarray(self.interest) < 0):
            raise LibraryError("library radii and interest must be non-negative")
        symmetry = np.asarray(self.symmetry)
        if (
            symmetry.dtype.kind not in "iu"
            or np.any(symmetry < 0)
            or np.any(symmetry > self.face_config.n_angles)
        ):
            # The order of a turn that maps a shape onto itself: a count of rays.
            rays = self.face_config.n_angles
            raise LibraryError(f"library symmetry must be whole orders from 0 to {rays}")
        if not np.all(np.isfinite(self.basis.eigenvalues)):
            raise LibraryError("library eigenvalues must be finite")
        if self.calibration is not None and self.calibration.cutoffs.shape != (n,):
            raise LibraryError("library cutoffs must be one per shape")
        # Read-only copies: a library is shared (default_library() is one object), and
        # one caller's edit of its symmetry changed every later match's angle.
        interest = np.array(self.interest, dtype=np.float64)
        symmetry = np.array(self.symmetry, dtype=np.int64)
        for array in (radii, interest, symmetry):
            array.setflags(write=False)
        object.__setattr__(self, "radii", radii)
        object.__setattr__(self, "names", tuple(self.names))
        object.__setattr__(self, "interest", interest)
        object.__setattr__(self, "symmetry", symmetry)

    @classmethod
    def from_radii(
        cls,
        names: Sequence[str],
        radii: ArrayLike,
        *,
        face_config: FaceConfig | None = None,
        params: Sequence[SuperformulaParams | None] | None = None,
        interest: ArrayLike | None = None,
        faces: ArrayLike | None = None,
        n_components: int | None = None,
        tolerance: float = DEFAULT_TOLERANCE,
        examples: Sequence[ArrayLike | None] | None = None,
        calibration: Calibration | None = None,
        exact_limit: int = EXACT_LIMIT,
    ) -> Library:
        """Build a library from radii (one row per shape, at the matcher's angles).

        Parameters
        ----------
        names : sequence of str
        radii : (n_shapes, n_angles) array_like of float
            Radii about each outline's centroid; any scale.
        face_config : FaceConfig, optional
        params : sequence of SuperformulaParams or None, optional
        interest : (n_shapes,) array_like of float, optional
            Default 1 for every shape.
        faces : (n_shapes, *face_shape) array_like of float, optional
            Faces to train on instead of the radii's own (e.g. the mean face of
            several examples).
        n_components : int, optional
            Keep at most this many eigenfaces. Default: all non-zero for a
            library of at most ``EXACT_LIMIT`` shapes, else
            :data:`rockscan.core.eigen.STREAM_COMPONENTS` (a truncated basis fitted
            on a random sample and streamed; see the module docstring).
        exact_limit : int, optional
            Largest library given the exact basis (default ``EXACT_LIMIT``).
        tolerance : float
            Outline noise (standard deviation, 0.2 = 20%) a sample of a shape
            may carry and still belong to it; the cutoffs are calibrated for it
            (:func:`rockscan.core.calibrate.calibrate`).
        examples : sequence of (n_examples, n_angles) array_like or None, optional
            Per shape, the radii of the example photos it was made from (one
            orientation), so that the spread between them counts in its cutoff.
        calibration : Calibration, optional
            Cutoffs to use as they are instead of calibrating.

        Notes
        -----
        A one-shape library has no eigenface (the face space of one face is a
        point): every eigenspace distance is 0 and MScore is 1 by
        construction; the calibrated sensor distance decides, as for any size.
        """
        config = face_config or FaceConfig()
        names = tuple(names)
        if len(names) < 1:
            raise LibraryError("a library needs at least one shape")
        for name in names:
            if not isinstance(name, str) or not NAME_PATTERN.match(name):
                raise LibraryError(f"shape name {name!r} must match [a-z0-9-]+")
        radii = np.asarray(radii, dtype=np.float64)
        if radii.ndim != 2 or radii.shape[0] != len(names):
            raise LibraryError("radii must be (n_shapes, n_angles), one row per name")
        if not np.all(np.isfinite(radii)) or np.any(radii <= 0):
            raise LibraryError("library radii must be finite and positive")
        radii = radii / radii.mean(axis=1, keepdims=True)
        face_array = None if faces is None else np.asarray(faces, dtype=np.float64)
        if face_array is not None and face_array.shape != (len(names), *config.face_shape):
            raise LibraryError(f"faces must be (n_shapes, {', '.join(map(str, config.face_shape))})")
        try:
            metric = None
            with ThreadPoolExecutor(max_workers=1) as pool:
                # The cutoffs need the radii alone: they are calibrated beside the basis
                # (whose eigen solver leaves a core idle), the same numbers as in turn.
                cutoffs = None
                if calibration is None:
                    cutoffs = pool.submit(_cutoffs, radii, examples, tolerance, noise_origins(params, radii))
                basis = _basis(radii, config, face_array, n_components, exact_limit)
                if cutoffs is not None:
                    metric, calibration = cutoffs.result()
        except ParameterError as exc:
            raise LibraryError(str(exc)) from None
        library = cls(
            names=names,
            radii=radii,
            params=tuple(params) if params is not None else (None,) * len(names),
            interest=np.ones(len(names)) if interest is None else np.asarray(interest, dtype=np.float64),
            symmetry=symmetry_orders(radii) if len(names) > EXACT_LIMIT else _symmetry_each(radii),
            face_config=config,
            basis=basis,
            calibration=calibration,
        )
        if calibration is not None and (same := np.flatnonzero(calibration.spacing < _SAME_SHAPE)).size:
            # Two shapes no turn tells apart: no cutoff can take a sample to one of them.
            raise LibraryError(
                f"shapes {', '.join(names[i] for i in same)} have one outline (up to a turn); "
                "give each shape once"
            )
        if metric is not None:
            object.__setattr__(library, "sensor_metric", metric)
        return library

    @classmethod
    def from_shapes(
        cls, shapes: Sequence[ShapeSpec], *, face_config: FaceConfig | None = None, **kwargs: object
    ) -> Library:
        """Build a library from Superformula shapes of a spec.

        Shapes given by example photos must be turned into radii first
        (:func:`rockscan.run.pipeline.library_from_spec` does it).
        """
        config = face_config or FaceConfig()
        names, params, interest = [], [], []
        for shape in shapes:
            if shape.params is None:
                raise LibraryError(
                    f"shape {shape.name!r} is given by images; build it with rockscan.run.pipeline"
                )
            names.append(shape.name)
            params.append(shape.params)
            interest.append(shape.interest)
        if len(params) > EXACT_LIMIT:
            _retain_freed_memory()
        radii = np.empty((len(params), config.n_angles))
        # A small library's radii one shape at a time, as they always were (to the
        # last bit); a large one's in vectorised chunks (to rounding, 1e-15).
        if len(params) <= EXACT_LIMIT:
            for i, p in enumerate(params):
                try:
                    radii[i] = shape_radii(p, config.n_angles)
                except ParameterError as exc:
                    raise LibraryError(f"shape {names[i]!r}: {exc}") from None
        else:
            starts = range(0, len(params), _CHUNK)
            chunks = _in_threads(
                lambda start: closed_shapes_radii(params[start : start + _CHUNK], config.n_angles),
                starts,
                _BUILD_THREADS,
            )
            for start, (values, closed) in zip(starts, chunks, strict=True):
                radii[start : start + values.shape[0]] = values
                for bad in start + np.flatnonzero(~closed):  # the one-shape check says why
                    try:
                        radii[bad] = shape_radii(params[bad], config.n_angles)
                    except ParameterError as exc:
                        raise LibraryError(f"shape {names[bad]!r}: {exc}") from None
        return cls.from_radii(
            names,
            radii,
            face_config=config,
            params=params,
            interest=interest,
            **kwargs,  # type: ignore[arg-type]
        )

    def __len__(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        """Position of a shape by name."""
        try:
            return self.names.index(name)
        except ValueError:
            raise LibraryError(f"no shape named {name!r} in the library") from None

    @one_blas_thread
    def faces(self) -> NDArray[np.float64]:
        """The library faces as the basis holds them: ``Psi + Omega_k U``."""
        flat = self.basis.mean + self.basis.weights @ self.basis.components
        return flat.reshape(len(self), *self.face_config.face_shape)

    @cached_property
    def sensor_metric(self) -> SensorMetric:
        """The sensor-model distance of this library (see :mod:`rockscan.core.calibrate`)."""
        return SensorMetric.from_radii(self.radii, self.tolerance)

    @property
    def tolerance(self) -> float:
        """The outline noise the library's cutoffs are calibrated for."""
        return self.calibration.tolerance if self.calibration is not None else DEFAULT_TOLERANCE

    @cached_property
    def _calibrated_on_use(self) -> Calibration:
        return calibrate(self.radii, origins=noise_origins(self.params, np.asarray(self.radii)))

    @property
    def calibration_in_force(self) -> Calibration:
        """The calibration that decides: the stored one, or one made on first use."""
        return self.calibration if self.calibration is not None else self._calibrated_on_use

    @property
    def cutoffs(self) -> NDArray[np.float64]:
        """Per-shape cutoffs on the sensor distance at the tolerance's noise, ``(n_shapes,)``."""
        return self.calibration_in_force.cutoffs

    @property
    def holds_its_faces(self) -> bool:
        """Whether face space holds the library's faces well enough to turn a
        sample against: all of them (as many eigenfaces as the shapes' faces
        span, one fewer than the shapes), or a large library's streamed basis
        of ``STREAM_COMPONENTS`` (on 2,000 shapes its angles err as little as
        the shapes' own faces give: median 0.10 against 0.09 degrees). A
        library built with fewer (``n_components`` of 1-3 for the default
        shapes) holds blurred projections that fit a turned sample at
        spurious angles."""
        return self.basis.n_components >= min(len(self) - 1, STREAM_COMPONENTS)

    @cached_property
    def reference_map(self) -> NDArray[np.float64]:
        """The reference information ``H_ref`` of every face (see information.py)."""
        reference = reference_information(self.face_config)
        reference.setflags(write=False)
        return reference

    @cached_property
    def scan_templates(self) -> ScanTemplates:
        """Fourier templates that score all rotations at once (see match.py)."""
        from rockscan.core.match import ScanTemplates

        return ScanTemplates.from_library(self)

    @cached_property
    def prefilter(self) -> Prefilter | None:
        """What prunes the rotation scan of a large library; None for a small one,
        scanned whole (see prefilter.py)."""
        from rockscan.core.prefilter import Prefilter

        return Prefilter.from_library(self)

    @cached_property
    def sensor_prefilter(self) -> SensorPrefilter | None:
        """What prunes the sensor pass of a large library; None for a small one
        (see prefilter.py)."""
        from rockscan.core.prefilter import SensorPrefilter

        return SensorPrefilter.from_metric(self.sensor_metric)

    def set_prefilter(self, prefilter: Prefilter | None) -> None:
        """Attach a prefilter computed elsewhere (at build, or read from a file), or
        None to scan every shape. Only the shortlist of later matches changes."""
        if prefilter is not None and prefilter.n_shapes != len(self):
            raise LibraryError("the prefilter does not fit the library's shapes")
        # A cached property is a plain attribute of the instance once computed.
        object.__setattr__(self, "prefilter", prefilter)

    def set_sensor_prefilter(self, sensor_prefilter: SensorPrefilter | None) -> None:
        """Attach the sensor pass's prefilter (or None: every shape's sensor distance is computed)."""
        if sensor_prefilter is not None and sensor_prefilter.n_shapes != len(self):
            raise LibraryError("the sensor prefilter does not fit the library's shapes")
        object.__setattr__(self, "sensor_prefilter", sensor_prefilter)

    def scanned_whole(self) -> Library:
        """The same library without a prefilter: every match scans every shape (the
        exhaustive answer a pruned scan is measured against)."""
        copy = Library._unchecked(**{name: getattr(self, name) for name in self.__dataclass_fields__})
        for cached in ("reference_map", "scan_templates"):
            if cached in self.__dict__:
                object.__setattr__(copy, cached, self.__dict__[cached])
        copy.set_prefilter(None)
        copy.set_sensor_prefilter(None)
        if "sensor_metric" in self.__dict__:
            object.__setattr__(copy, "sensor_metric", self.__dict__["sensor_metric"])
        return copy

    @classmethod
    def _unchecked(cls, **fields: object) -> Library:
        """A library from fields already checked, in time independent of its size
        (novelty.py grows an observed library one shape at a time)."""
        library = object.__new__(cls)
        for name, value in fields.items():
            object.__setattr__(library, name, value)
        return library


# ---------------------------------------------------------------- large libraries


def shapes_radii(params: Sequence[SuperformulaParams], n_angles: int) -> NDArray[np.float64]:
    """:func:`shape_radii` of many shapes at once (vectorised; the same values).

    Parameters
    ----------
    params : sequence of SuperformulaParams
    n_angles : int

    Returns
    -------
    radii : (n_shapes, n_angles) ndarray of float
        About each shape's area centroid, mean radius 1.

    Raises
    ------
    ParameterError
        As :func:`shape_radii`, for the first shape that fails.
    """
    radii, closed = closed_shapes_radii(params, n_angles)
    if not closed.all():
        shape_radii(params[int(np.flatnonzero(~closed)[0])], n_angles)  # raises that shape's error
        raise ParameterError("a Superformula of the list is unbounded or degenerate")
    return radii


def closed_shapes_radii(
    params: Sequence[SuperformulaParams], n_angles: int
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Radii of many shapes, and which of them :func:`shape_radii` accepts.

    Returns
    -------
    radii : (n_shapes, n_angles) ndarray of float
        As :func:`shape_radii` where ``closed``; ones elsewhere.
    closed : (n_shapes,) ndarray of bool
        Bounded curves that enclose their own centroid.
    """
    if len(params) == 0:
        return np.zeros((0, n_angles)), np.zeros(0, dtype=bool)
    theta = polar_angles(n_angles)
    table = np.array([[p.m1, p.m2, p.n1, p.n2, p.n3, p.a, p.b] for p in params])
    m1, m2, n1, n2, n3, a, b = (column[:, None] for column in table.T)
    with np.errstate(over="ignore"):
        radii = np.exp(log_superformula(theta, m1, m2, n1, n2, n3, a, b))
    closed = ~degenerate_rays(radii).any(axis=1)
    radii[~closed] = 1.0
    centered = _recentered(radii)
    closed &= (centered > 0).all(axis=1)
    centered[~closed] = 1.0
    return centered / centered.mean(axis=1, keepdims=True), closed


def _retain_freed_memory() -> None:
    """Let the C allocator keep the memory a large build frees, to take it again.

    glibc's malloc gives the free memory at the top of its heap back to the
    kernel once more than twice its mmap threshold is free; the threshold
    starts at 128 KiB and rises to the largest block freed so far (up to 32
    MiB). Each chunk of a build frees some 25 MB of temporaries of about a
    megabyte and takes them again for the next: with the thresholds at their
    start, every 4 KiB page is faulted in again (280,000 page faults in a
    10,000-shape build, a tenth of its time). Freeing one 24 MiB block raises
    both for the process; other allocators ignore it. No result depends on it.
    """
    block = np.empty(24 << 20, dtype=np.uint8)
    del block


def _recentered(radii: NDArray[np.float64]) -> NDArray[np.float64]:
    """:func:`rockscan.core.polar.recenter_radii` of many outlines, (n, n_angles) -> (n, n_angles).

    The same steps: the area centroid of the rays' polygon and the farthest
    crossing of every ray about it. recenter_radii's dense outline puts its
    points on the polygon's own edges, so the rays cross the same lines: the
    polygon alone gives the same radii (to rounding, 1e-15) at an eighth of
    the work.
    """
    theta = polar_angles(radii.shape[1])
    _, cx, cy = polygon_area_centroids(radii * np.cos(theta), radii * np.sin(theta))
    return radii_about(radii, np.column_stack([cx, cy]))


#: Sensor distance under which two shapes of a library are one outline: a copy measures
#: 3e-8 (rounding), a variant 1% off its base 0.014, a turn between two rays 0.03.
_SAME_SHAPE = 1e-6


@one_blas_thread
def _cutoffs(
    radii: NDArray[np.float64],
    examples: Sequence[ArrayLike | None] | None,
    tolerance: float,
    origins: NDArray[np.float64] | None = None,
) -> tuple[SensorMetric, Calibration]:
    """A library's sensor metric and the cutoffs calibrated on it (the metric is the
    library's own: made once, kept)."""
    metric = SensorMetric.from_radii(radii, tolerance)
    return metric, calibrate(radii, examples=examples, tolerance=tolerance, metric=metric, origins=origins)


def noise_origins(
    params: Sequence[SuperformulaParams | None] | None, radii: NDArray[np.float64]
) -> NDArray[np.float64] | None:
    """Per shape, the point the paper's outline noise is drawn about: its formula's origin.

    The paper's noise multiplies a Superformula's radii about the formula's
    origin, which is not the centroid of a shape without point symmetry
    (m = 1, a drop): such a shape's noise is larger on the side far from the
    origin, and its calibration simulates it so
    (:func:`rockscan.core.calibrate.simulate_radii`).

    Parameters
    ----------
    params : sequence of SuperformulaParams or None, or None
        Each shape's formula, None for a shape without one.
    radii : (n_shapes, n_angles) ndarray of float
        The shapes' radii about their centroids, as the library holds them.

    Returns
    -------
    origins : (n_shapes, 2) ndarray of float or None
        (x, y) of each origin from the centroid, in units of the mean radius
        (``radii``' scale); (0, 0) for a shape without a formula or with point
        symmetry. None when no shape has a formula.
    """
    if params is None or all(p is None for p in params):
        return None
    n_shapes, n_angles = radii.shape
    theta = polar_angles(n_angles)
    origins = np.zeros((n_shapes, 2))
    given = np.array([p is not None for p in params])
    for start in range(0, n_shapes, _CHUNK):
        rows = np.flatnonzero(given[start : start + _CHUNK]) + start
        if rows.size == 0:
            continue
        table = np.array(
            [[getattr(params[i], k) for k in ("m1", "m2", "n1", "n2", "n3", "a", "b")] for i in rows]
        )
        with np.errstate(over="ignore"):
            raw = np.exp(log_superformula(theta, *(column[:, None] for column in table.T)))
        area, cx, cy = polygon_area_centroids(raw * np.cos(theta), raw * np.sin(theta))
        # The same outline at the library's scale: its area fixes the ratio.
        unit, _, _ = polygon_area_centroids(radii[rows] * np.cos(theta), radii[rows] * np.sin(theta))
        scale = np.sqrt(np.abs(area) / np.maximum(np.abs(unit), 1e-300))
        origins[rows] = -np.column_stack([cx, cy]) / scale[:, None]
    # A point-symmetric shape's origin is its centroid: rounding is no offset.
    origins[np.hypot(origins[:, 0], origins[:, 1]) < 1e-9] = 0.0
    return origins


def _symmetry_each(radii: NDArray[np.float64]) -> NDArray[np.int64]:
    return np.array([symmetry_order(r) for r in radii], dtype=np.int64)


def symmetry_orders(radii: ArrayLike, *, tol: float = 1e-4, max_order: int = 36) -> NDArray[np.int64]:
    """:func:`rockscan.core.polar.symmetry_order` of many outlines at once.

    Parameters
    ----------
    radii : (n_shapes, n_angles) array_like of float

    Returns
    -------
    orders : (n_shapes,) ndarray of int
    """
    radii = np.asarray(radii, dtype=np.float64)
    if radii.shape[0] == 0:
        return np.zeros(0, dtype=np.int64)
    energy = np.abs(np.fft.rfft(radii, axis=1)[:, 1:]) ** 2
    total = energy.sum(axis=1)
    orders = np.arange(min(max_order, energy.shape[1]), 1, -1)
    # The energy off the multiples of k: all of it less that on them (a strided view, no copy).
    off = np.stack([total - energy[:, k - 1 :: k].sum(axis=1) for k in orders], axis=1)
    fits = off <= tol * total[:, None]
    out = np.where(fits.any(axis=1), orders[np.argmax(fits, axis=1)], 1)
    out[total <= (1e-9 * radii.mean(axis=1)) ** 2 * radii.shape[1] ** 2] = 0
    return out.astype(np.int64)


class _FaceTable:
    """Faces of many radii at once, read off a table in the radius.

    On the polar grid ``q[theta, j]`` depends on the ray's normalised radius
    alone. Each section's probability is tabulated with its exact derivative
    (the normal density) every ``_TABLE_STEP`` of radius; the cubic Hermite
    interpolant between the table's rows is within 1e-11 of the direct normal
    CDF (its error bound, step**4 / 384 times the largest fourth derivative,
    under 3e4 for sigma 0.1, is 5e-12; measured 1e-13). Radii beyond the
    table's end (past every section by ten sigma) read its last row.
    """

    def __init__(self, config: FaceConfig) -> None:
        edges = section_edges(config)
        self.r_max = float(edges[-1] + 10.0 * config.sigma)
        grid = np.arange(0.0, self.r_max + 2 * _TABLE_STEP, _TABLE_STEP)
        values = section_probabilities(grid, edges, config.sigma)
        z = (edges[None, :] - grid[:, None]) / config.sigma
        density = np.exp(-0.5 * z**2) / np.sqrt(2.0 * np.pi)
        # d/dr [Phi((e_{j+1} - r)/sigma) - Phi((e_j - r)/sigma)], in units of the step.
        slopes = (density[:, :-1] - density[:, 1:]) / config.sigma * _TABLE_STEP
        v0, v1, s0, s1 = values[:-1], values[1:], slopes[:-1], slopes[1:]
        # Each cell's Hermite cubic as a polynomial in t, lowest power first:
        # (4, n_cells, n_sections), one contiguous table per power.
        self.coefficients = np.stack([v0, s0, 3 * (v1 - v0) - 2 * s0 - s1, 2 * (v0 - v1) + s0 + s1])
        self.weights = reference_information(config)

    def __call__(self, radii: NDArray[np.float64]) -> NDArray[np.float64]:
        return self.faces(radii)

    def faces(
        self, radii: NDArray[np.float64], out: NDArray[np.float64] | None = None
    ) -> NDArray[np.float64]:
        """(n, n_angles) radii -> (n, n_angles, n_sections) faces (written into ``out`` if given)."""
        u = np.minimum(normalize_radii(radii), self.r_max) / _TABLE_STEP
        cell = np.minimum(np.floor(u).astype(np.int64), self.coefficients.shape[1] - 1)
        t = u - cell
        c0, c1, c2, c3 = self.coefficients
        if out is None:
            out = np.empty((*radii.shape, c0.shape[1]))
        # Two working rows per ray of a block, made once: memory freed and taken again
        # every block is handed back to the kernel and faulted in again (glibc trims
        # the top of a thread's heap), which cost more than the arithmetic.
        work = np.empty((2, 8 * radii.shape[1], c0.shape[1]))
        for start in range(0, radii.shape[0], 8):  # blocks that stay in cache
            block = slice(start, start + 8)
            rows, tb = cell[block].ravel(), t[block].reshape(-1, 1)
            q, term = work[0, : rows.size], work[1, : rows.size]
            # Horner's rule, one row of the table per ray and power at a time.
            np.take(c3, rows, axis=0, out=q)
            q *= tb
            q += np.take(c2, rows, axis=0, out=term)
            q *= tb
            q += np.take(c1, rows, axis=0, out=term)
            q *= tb
            q += np.take(c0, rows, axis=0, out=term)
            np.multiply(q.reshape(-1, *self.weights.shape), self.weights, out=out[block])
        return out


class _DirectFaces:
    """Radii -> faces by :func:`rockscan.core.information.information_face` (no table)."""

    def __init__(self, config: FaceConfig) -> None:
        self.config = config

    def __call__(self, radii: NDArray[np.float64]) -> NDArray[np.float64]:
        return information_face(radii, self.config)


def _face_function(config: FaceConfig) -> _FaceTable | _DirectFaces:
    """Radii -> faces for a large build: the table on the polar information grids."""
    if config.grid == "polar" and config.kind != "radii":
        return _FaceTable(config)
    return _DirectFaces(config)


def _basis(
    radii: NDArray[np.float64],
    config: FaceConfig,
    faces: NDArray[np.float64] | None,
    n_components: int | None,
    exact_limit: int,
) -> EigenBasis:
    """The eigenface basis of a library's faces: none for one shape (its face space is
    a point), exact up to ``exact_limit`` shapes, streamed and truncated beyond."""
    if radii.shape[0] == 1:
        flat = (information_face(radii, config) if faces is None else faces).reshape(1, -1)
        return EigenBasis(
            mean=flat[0],
            components=np.empty((0, flat.shape[1])),
            eigenvalues=np.empty(0),
            weights=np.zeros((1, 0)),
        )
    if radii.shape[0] <= exact_limit:
        faces = information_face(radii, config) if faces is None else faces
        return EigenBasis.from_faces(faces, n_components=n_components)
    return _streamed_basis(radii, config, faces, n_components)


def _streamed_basis(
    radii: NDArray[np.float64],
    config: FaceConfig,
    faces: NDArray[np.float64] | None,
    n_components: int | None,
    *,
    seed: int = 0,
) -> EigenBasis:
    """The truncated basis of a large library, one chunk of faces at a time."""
    n = radii.shape[0]
    make = _face_function(config)

    def faces_of(rows: NDArray[np.int64] | slice) -> NDArray[np.float64]:
        return make(radii[rows]) if faces is None else faces[rows]

    n_keep = STREAM_COMPONENTS if n_components is None else int(n_components)
    rng = np.random.default_rng(seed)
    sample = np.sort(rng.choice(n, size=min(n, max(STREAM_FIT_FACES, 2 * n_keep)), replace=False))
    starts = range(0, n, _CHUNK)
    if faces is None and isinstance(make, _FaceTable) and _BUILD_THREADS > 1:
        # A chunk of faces (37 MB) in fresh memory costs the kernel a page fault every
        # 4 KiB, more than making the faces: chunks take turns in a few buffers instead.
        # At most _BUILD_THREADS + 1 chunks are alive at once (_in_threads), and the
        # stream is done with one before it asks for the next; one buffer more is slack.
        buffers = np.empty((_BUILD_THREADS + 2, min(_CHUNK, n), *config.face_shape))

        def chunk_faces(start: int) -> NDArray[np.float64]:
            rows = slice(start, start + _CHUNK)
            size = len(range(n)[rows])
            return make.faces(radii[rows], out=buffers[(start // _CHUNK) % buffers.shape[0], :size])

        chunks = _in_threads(chunk_faces, starts, _BUILD_THREADS)
    else:
        chunks = (faces_of(slice(start, start + _CHUNK)) for start in starts)
    return EigenBasis.from_face_stream(faces_of(sample), chunks, n_components=n_keep)


def _in_threads(function, items, workers: int):  # type: ignore[no-untyped-def]
    """``function`` of each item, in order, computed ``workers`` at a time in threads.

    NumPy's loops release the interpreter lock, so the faces of the next chunks
    are made while the caller projects the last one; at most ``workers + 1``
    results exist at once (memory stays one chunk per thread), and the results
    come in order, so the sums over them are the same as in one thread.
    """
    with ThreadPoolExecutor(max_workers=workers) as pool:
        pending: deque = deque()
        for item in items:
            pending.append(pool.submit(function, item))
            if len(pending) > workers:
                yield pending.popleft().result()
        while pending:
            yield pending.popleft().result()
