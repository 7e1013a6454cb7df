"""A library of shapes of interest and its eigenface basis.

A library is built from named shapes, each a Superformula (the paper's way) or
radii measured from example rocks. Every shape is put in the frame a photo's
rock is measured in: radii about the outline's own area centroid, normalised to
a mean radius of 1. Their faces train the eigenface basis, and the library
calibrates its own per-shape cutoffs (:mod:`rockscan.calibrate`) for the
outline noise it is meant to tolerate.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from rockscan._threads import one_blas_thread
from rockscan.calibrate import DEFAULT_TOLERANCE, Calibration, SensorMetric, calibrate
from rockscan.eigen import EigenBasis
from rockscan.errors import LibraryError, ParameterError, SpecError
from rockscan.information import FaceConfig, information_face, reference_weights
from rockscan.polar import polar_angles, recenter_radii, symmetry_order
from rockscan.superformula import SuperformulaParams

if TYPE_CHECKING:
    from rockscan.match import ScanTemplates

__all__ = ["NAME_PATTERN", "Library", "ShapeSpec", "shape_radii"]

#: Allowed shape names.
NAME_PATTERN = re.compile(r"^[a-z0-9-]+$")
#: A radius this many times the median marks an unbounded curve.
_MAX_SPIKE = 1e4


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
        if (self.params is None) == (not self.images):
            raise SpecError(f"shape {self.name!r}: give either Superformula parameters or images, not both")


def shape_radii(params: SuperformulaParams, n_angles: int) -> NDArray[np.float64]:
    """Radii of a Superformula shape in the matcher's frame.

    Parameters
    ----------
    params : SuperformulaParams
    n_angles : int

    Returns
    -------
    radii : (n_angles,) ndarray of float
        About the shape's area centroid, mean radius 1.

    Raises
    ------
    ParameterError
        When the curve is unbounded or passes through its centre at some ray.
    """
    theta = polar_angles(n_angles)
    radii = params.radii(theta)
    with np.errstate(invalid="ignore", divide="ignore"):
        # A pole that the rays straddle shows as an absurd spike rather than inf.
        spike = radii > _MAX_SPIKE * np.nanmedian(radii)
    if not np.all(np.isfinite(radii)) or np.any(radii <= 0) or np.any(spike):
        bad = np.flatnonzero(~np.isfinite(radii) | (radii <= 0) | spike)
        raise ParameterError(
            f"Superformula {params.as_dict()} is unbounded or degenerate at "
            f"{np.rad2deg(theta[bad[0]]):.1f} degrees; choose parameters whose curve is closed"
        )
    centered, _ = recenter_radii(radii)
    if np.any(centered <= 0):
        raise ParameterError(
            f"Superformula {params.as_dict()} does not enclose its own centroid; "
            "it cannot be matched by radii"
        )
    return centered / centered.mean()


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
        if self.calibration is not None and self.calibration.cutoffs.shape != (n,):
            raise LibraryError("library cutoffs must be one per shape")
        radii.setflags(write=False)
        object.__setattr__(self, "radii", radii)
        object.__setattr__(self, "names", tuple(self.names))
        object.__setattr__(self, "interest", np.asarray(self.interest, dtype=np.float64))
        object.__setattr__(self, "symmetry", np.asarray(self.symmetry, dtype=np.int64))

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
            Keep at most this many eigenfaces (default: all non-zero).
        tolerance : float
            Outline noise (standard deviation, 0.2 = 20%) a sample of a shape
            may carry and still belong to it; the cutoffs are calibrated for it
            (:func:`rockscan.calibrate.calibrate`).
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
        face_array = information_face(radii, config) if faces is None else np.asarray(faces, dtype=np.float64)
        if face_array.shape != (len(names), *config.face_shape):
            raise LibraryError(f"faces must be (n_shapes, {', '.join(map(str, config.face_shape))})")
        try:
            if len(names) == 1:
                flat = face_array.reshape(1, -1)
                basis = EigenBasis(
                    mean=flat[0],
                    components=np.empty((0, flat.shape[1])),
                    eigenvalues=np.empty(0),
                    weights=np.zeros((1, 0)),
                )
            else:
                basis = EigenBasis.from_faces(face_array, n_components=n_components)
            if calibration is None:
                calibration = calibrate(radii, examples=examples, tolerance=tolerance)
        except ParameterError as exc:
            raise LibraryError(str(exc)) from None
        return cls(
            names=names,
            radii=radii,
            params=tuple(params) if params is not None else (None,) * len(names),
            interest=np.ones(len(names)) if interest is None else np.asarray(interest, dtype=np.float64),
            symmetry=np.array([symmetry_order(r) for r in radii], dtype=np.int64),
            face_config=config,
            basis=basis,
            calibration=calibration,
        )

    @classmethod
    def from_shapes(
        cls, shapes: Sequence[ShapeSpec], *, face_config: FaceConfig | None = None, **kwargs: object
    ) -> Library:
        """Build a library from Superformula shapes of a spec.

        Shapes given by example photos must be turned into radii first
        (:func:`rockscan.pipeline.library_from_spec` does it).
        """
        config = face_config or FaceConfig()
        names, radii, params, interest = [], [], [], []
        for shape in shapes:
            if shape.params is None:
                raise LibraryError(
                    f"shape {shape.name!r} is given by images; build it with rockscan.pipeline"
                )
            try:
                radii.append(shape_radii(shape.params, config.n_angles))
            except ParameterError as exc:
                raise LibraryError(f"shape {shape.name!r}: {exc}") from None
            names.append(shape.name)
            params.append(shape.params)
            interest.append(shape.interest)
        return cls.from_radii(
            names,
            np.array(radii).reshape(len(names), config.n_angles),
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
        """The sensor-model distance of this library (see :mod:`rockscan.calibrate`)."""
        return SensorMetric.from_radii(self.radii, self.tolerance)

    @property
    def tolerance(self) -> float:
        """The outline noise the library's cutoffs are calibrated for."""
        return self.calibration.tolerance if self.calibration is not None else DEFAULT_TOLERANCE

    @cached_property
    def _calibrated_on_use(self) -> Calibration:
        return calibrate(self.radii)

    @property
    def cutoffs(self) -> NDArray[np.float64]:
        """Per-shape cutoffs on the sensor distance (over the sample's allowance), ``(n_shapes,)``."""
        calibration = self.calibration if self.calibration is not None else self._calibrated_on_use
        return calibration.cutoffs

    @cached_property
    def weights_map(self) -> NDArray[np.float64]:
        """The reference information ``H_ref`` of every face (see information.py)."""
        return reference_weights(self.face_config)

    @cached_property
    def scan_templates(self) -> ScanTemplates:
        """Fourier templates that score all rotations at once (see match.py)."""
        from rockscan.match import ScanTemplates

        return ScanTemplates.from_library(self)
