"""Radii -> information face (paper Section III).

The face of a shape lives on a (theta, r) grid: ``n_angles`` rays, each cut
into sections of length ``resolution`` out to ``ray_length``. For the paper's
method it is

    face[theta, j] = H_ref[theta, j] * q[theta, j]

where ``H_ref = p_ref * log2(1/p_ref)`` is the Shannon information (bits) of
finding an obstruction in section j of ray theta if the object were the
reference shape (a circle of radius ``0.5*sqrt(2)``, variant 1, or a Superformula
shape, variant 2), and ``q`` is the probability of the obstruction in that
section under a normal sensor model centred on the sample's own radius. Both
probabilities are differences of the normal CDF over the section's ends.

Only ``q`` depends on the sample, and turning the sample shifts ``q`` along
theta: the matcher exploits this to score every rotation at once.

The "radii" face is the plain baseline: the mean-normalised radii themselves,
scaled by ``1/sqrt(n_angles)`` so that a distance between two faces is the RMS
difference of their radii as a fraction of the mean radius.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import ndtr

from rockscan.core.choices import FACE_KINDS, GRIDS, MAX_CARTESIAN, MAX_FACE_ANGLES
from rockscan.core.errors import ParameterError
from rockscan.core.superformula import SuperformulaParams

__all__ = [
    "FACE_KINDS",
    "GRIDS",
    "REFERENCE_RADIUS",
    "FaceConfig",
    "information_face",
    "information_face_cartesian",
    "normalize_radii",
    "reference_information",
    "sample_term",
    "section_edges",
    "section_probabilities",
    "shannon_bits",
]

#: Most sections along a ray (a face holds n_angles times as many values).
_MAX_SECTIONS = 100_000
#: Radius of the paper's reference circle, in units of the analysis map.
REFERENCE_RADIUS = 0.5 * math.sqrt(2.0)


@dataclass(frozen=True)
class FaceConfig:
    """How shapes are turned into faces.

    Parameters
    ----------
    kind : {"information", "information-shape", "radii"}
        ``"information"`` is the paper's variant 1 (reference circle),
        ``"information-shape"`` its variant 2 (reference Superformula shape,
        ``reference``), ``"radii"`` the mean-normalised radii (matched filter).
    sigma : float
        Standard deviation of the Gaussian sensor model, in map units (paper: 0.1).
    n_angles : int
        Number of rays; the rotation scan's step is ``360/n_angles`` degrees.
    resolution : float
        Length of one section of a ray, in map units.
    ray_length : float
        Length of each ray, in map units.
    grid : {"polar", "cartesian"}
        ``"polar"`` keeps the face on the (theta, r) grid. ``"cartesian"`` plots
        it onto the paper's square grid map of ``cartesian_size`` pixels a side;
        it is slower (a rotation needs a new face) and kept for reproduction.
    cartesian_size : int
        Side of the Cartesian grid map, in pixels.
    reference : SuperformulaParams or None
        The reference shape of variant 2; ignored otherwise.

    Notes
    -----
    Sizes are normalised so that the shape's mean radius equals the reference
    circle's radius ``0.5*sqrt(2)``: the paper's "correctly sized" sample, and
    a and b (which only scale) then never change a match. The rays reach 1.0, about
    three sigma beyond the circle, where the reference information has vanished.
    The paper's map "of side 1" would cut that circle at its corners; the
    Cartesian map here spans the rays, a square of half-side ``ray_length``.
    """

    kind: str = "information"
    sigma: float = 0.1
    n_angles: int = 360
    resolution: float = 0.02
    ray_length: float = 1.0
    grid: str = "polar"
    cartesian_size: int = 100
    reference: SuperformulaParams | None = field(default=None)

    def __post_init__(self) -> None:
        if self.kind not in FACE_KINDS:
            raise ParameterError(f"face kind must be one of {', '.join(FACE_KINDS)}; got {self.kind!r}")
        if self.grid not in GRIDS:
            raise ParameterError(f"grid must be one of {', '.join(GRIDS)}; got {self.grid!r}")
        for name in ("sigma", "resolution", "ray_length"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ParameterError(f"{name} must be a positive number, got {value!r}")
        if (ray_sections := self.ray_length / self.resolution) > _MAX_SECTIONS:
            # Checked before round(): ray_length / resolution may overflow to inf.
            raise ParameterError(
                f"ray_length / resolution gives {ray_sections:.3g} sections; at most {_MAX_SECTIONS}"
            )
        for name in ("n_angles", "cartesian_size"):
            value = getattr(self, name)
            if isinstance(value, bool) or (
                not isinstance(value, (int, np.integer))
                and not (isinstance(value, float) and value.is_integer())
            ):
                raise ParameterError(f"{name} must be an integer, got {value!r}")
        if (
            isinstance(self.n_angles, bool)
            or int(self.n_angles) != self.n_angles
            or not 8 <= self.n_angles <= MAX_FACE_ANGLES
        ):
            raise ParameterError(
                f"n_angles must be an integer >= 8 and <= {MAX_FACE_ANGLES}, got {self.n_angles!r}"
            )
        if int(self.cartesian_size) != self.cartesian_size or not 8 <= self.cartesian_size <= MAX_CARTESIAN:
            raise ParameterError(
                f"cartesian_size must be an integer >= 8 and <= {MAX_CARTESIAN}, got {self.cartesian_size!r}"
            )
        if self.n_sections < 2:
            raise ParameterError("resolution must be at most half of ray_length")
        if self.kind == "information-shape" and self.reference is None:
            raise ParameterError("face kind 'information-shape' needs a reference shape (reference=...)")
        if self.kind != "information-shape" and self.reference is not None:
            object.__setattr__(self, "reference", None)
        if self.kind == "radii" and self.grid != "polar":
            raise ParameterError("the radii face lives on the polar grid only")

    @property
    def n_sections(self) -> int:
        """Number of sections along each ray."""
        return round(self.ray_length / self.resolution)

    @property
    def face_shape(self) -> tuple[int, int]:
        """Shape of one face array."""
        if self.grid == "cartesian":
            return (self.cartesian_size, self.cartesian_size)
        if self.kind == "radii":
            return (self.n_angles, 1)
        return (self.n_angles, self.n_sections)

    def with_(self, **changes: object) -> FaceConfig:
        """A copy with some settings changed."""
        return replace(self, **changes)

    def to_dict(self) -> dict[str, object]:
        """Plain JSON-able form."""
        out: dict[str, object] = {
            "kind": self.kind,
            "sigma": self.sigma,
            "n_angles": self.n_angles,
            "resolution": self.resolution,
            "ray_length": self.ray_length,
            "grid": self.grid,
            "cartesian_size": self.cartesian_size,
        }
        if self.reference is not None:
            out["reference"] = self.reference.as_dict()
        return out

    @classmethod
    def from_dict(cls, data: dict[str, object]) -> FaceConfig:
        """Inverse of :meth:`to_dict`."""
        data = dict(data)
        ref = data.pop("reference", None)
        known = {"kind", "sigma", "n_angles", "resolution", "ray_length", "grid", "cartesian_size"}
        unknown = set(data) - known
        if unknown:
            raise ParameterError(f"unknown face settings: {', '.join(sorted(unknown))}")
        reference = SuperformulaParams(**ref) if isinstance(ref, dict) else None
        return cls(reference=reference, **data)  # type: ignore[arg-type]


def normalize_radii(radii: ArrayLike, *, target: float = REFERENCE_RADIUS) -> NDArray[np.float64]:
    """Scale radii so that their mean along the last axis equals ``target``.

    Parameters
    ----------
    radii : (..., n_angles) array_like of float
        Positive, finite radii.
    target : float, optional
        Mean radius after scaling.

    Returns
    -------
    radii_normalized : (..., n_angles) ndarray of float
    """
    radii = _check_radii(radii)
    mean = radii.mean(axis=-1, keepdims=True)
    if np.all(mean > 1e-300):
        return radii * (target / mean)
    # Subnormal radii (1e-310): target / mean overflows to inf. Scaled to their
    # largest first, they are an outline like any other.
    unit = radii / radii.max(axis=-1, keepdims=True)
    return unit * (target / unit.mean(axis=-1, keepdims=True))


def section_edges(config: FaceConfig) -> NDArray[np.float64]:
    """Ends of the sections along a ray: ``(n_sections + 1,)`` map units from the centre."""
    return np.linspace(0.0, config.n_sections * config.resolution, config.n_sections + 1)


def section_probabilities(centers: ArrayLike, edges: ArrayLike, sigma: float) -> NDArray[np.float64]:
    """Probability that a normal(center, sigma) point falls in each section.

    Parameters
    ----------
    centers : (...,) array_like of float
        Means of the sensor model, e.g. the radius along each ray.
    edges : (n_sections + 1,) array_like of float
        Increasing section ends.
    sigma : float
        Standard deviation.

    Returns
    -------
    p : (..., n_sections) ndarray of float
        ``Phi((e[j+1]-c)/sigma) - Phi((e[j]-c)/sigma)``, computed on the side of the
        distribution where it does not cancel, so tail values stay accurate.
    """
    centers = np.asarray(centers, dtype=np.float64)[..., None]
    z = (np.asarray(edges, dtype=np.float64) - centers) / sigma
    # The smaller tail at every edge is accurate; each section is a difference
    # or a complement of two such tails, so nothing cancels.
    tail = ndtr(-np.abs(z))
    lo, hi = tail[..., :-1], tail[..., 1:]
    # Both ends on one side of the mean: the difference of the tails; across it: the complement.
    straddle = (z[..., :-1] < 0) & (z[..., 1:] > 0)
    return np.where(straddle, 1.0 - lo - hi, np.abs(hi - lo))


def shannon_bits(p: ArrayLike) -> NDArray[np.float64]:
    """Shannon's ``p * log2(1/p)`` in bits, with 0 where ``p == 0``."""
    p = np.asarray(p, dtype=np.float64)
    out = np.zeros_like(p)
    positive = p > 0
    out[positive] = -p[positive] * np.log2(p[positive])
    return out


def reference_information(config: FaceConfig) -> NDArray[np.float64]:
    """The fixed factor of every face: the reference information ``H_ref``.

    Returns
    -------
    weights : ndarray of float, ``config.face_shape``
        Bits per section for the information faces; ones for the radii face.
    """
    if config.kind == "radii":
        return np.ones(config.face_shape)
    if config.grid == "cartesian":
        rho, theta = _cartesian_polar(config)
        section = np.minimum((rho / config.resolution).astype(np.int64), config.n_sections - 1)
        ref = _reference_radius(config, theta)
        edges = section_edges(config)
        p = ndtr((edges[section + 1] - ref) / config.sigma) - ndtr((edges[section] - ref) / config.sigma)
        return np.where(rho <= config.ray_length, shannon_bits(p), 0.0)
    theta = 2.0 * np.pi * np.arange(config.n_angles) / config.n_angles
    ref = _reference_radius(config, theta)
    return shannon_bits(section_probabilities(ref, section_edges(config), config.sigma))


def sample_term(radii: ArrayLike, config: FaceConfig) -> NDArray[np.float64]:
    """The factor of a face that belongs to the sample, on the polar grid.

    Parameters
    ----------
    radii : (..., n_angles) array_like of float
        Radii at :func:`rockscan.core.polar.polar_angles`, any scale.
    config : FaceConfig

    Returns
    -------
    q : (..., n_angles, n_sections) ndarray of float
        Section probabilities about the normalised radii; for the radii face,
        ``(..., n_angles, 1)`` normalised radii over ``sqrt(n_angles)``.
    """
    radii = _check_radii(radii, config.n_angles)
    if config.kind == "radii":
        return (normalize_radii(radii, target=1.0) / math.sqrt(config.n_angles))[..., None]
    return section_probabilities(normalize_radii(radii), section_edges(config), config.sigma)


def information_face(radii: ArrayLike, config: FaceConfig | None = None) -> NDArray[np.float64]:
    """The face of a shape: reference information times the sample's probabilities.

    Parameters
    ----------
    radii : (..., n_angles) array_like of float
        Radii at :func:`rockscan.core.polar.polar_angles`, any scale.
    config : FaceConfig, optional
        Defaults to the paper's variant 1 on the polar grid.

    Returns
    -------
    face : (..., *config.face_shape) ndarray of float
        In bits for the information kinds.

    Examples
    --------
    >>> import numpy as np
    >>> face = information_face(np.ones(360))
    >>> face.shape
    (360, 50)
    """
    config = FaceConfig() if config is None else config
    if config.grid == "cartesian":
        return information_face_cartesian(radii, config)
    return reference_information(config) * sample_term(radii, config)


def information_face_cartesian(radii: ArrayLike, config: FaceConfig) -> NDArray[np.float64]:
    """The face plotted onto the paper's square grid map.

    Each pixel takes the section its centre falls in along the ray at its angle;
    the sample's radius at that angle is interpolated (periodic, linear).

    Returns
    -------
    face : (..., cartesian_size, cartesian_size) ndarray of float
        Row 0 is the top of the map (y up), as an image.
    """
    config = config.with_(grid="cartesian") if config.grid != "cartesian" else config
    radii = normalize_radii(_check_radii(radii, config.n_angles))
    rho, theta = _cartesian_polar(config)
    section = np.minimum((rho / config.resolution).astype(np.int64), config.n_sections - 1)
    edges = section_edges(config)
    sample = _at_angles(radii, theta)
    q = ndtr((edges[section + 1] - sample) / config.sigma) - ndtr((edges[section] - sample) / config.sigma)
    return reference_information(config) * q


def _cartesian_polar(config: FaceConfig) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    size = config.cartesian_size
    centers = (np.arange(size) + 0.5) / size * 2.0 * config.ray_length - config.ray_length
    x = centers[None, :]
    y = -centers[:, None]
    rho = np.broadcast_to(np.hypot(x, y), (size, size))
    theta = np.broadcast_to(np.arctan2(y, x), (size, size))
    return rho, theta


def _reference_radius(config: FaceConfig, theta: NDArray[np.float64]) -> NDArray[np.float64]:
    if config.kind == "information-shape":
        assert config.reference is not None
        grid = 2.0 * np.pi * np.arange(config.n_angles) / config.n_angles
        ref = normalize_radii(config.reference.radii(grid))
        return _at_angles(ref, theta)
    return np.full(np.shape(theta), REFERENCE_RADIUS)


def _at_angles(radii: NDArray[np.float64], theta: ArrayLike) -> NDArray[np.float64]:
    """Radii sampled at the matcher's angles, read at any angles ``theta`` (radians) by
    periodic linear interpolation; ``radii`` may hold several outlines (last axis)."""
    n = radii.shape[-1]
    position = np.mod(theta, 2.0 * np.pi) / (2.0 * np.pi) * n
    lo = np.floor(position).astype(np.int64) % n
    frac = position - np.floor(position)
    return radii[..., lo] * (1.0 - frac) + radii[..., (lo + 1) % n] * frac


def _check_radii(radii: ArrayLike, n_angles: int | None = None) -> NDArray[np.float64]:
    radii = np.asarray(radii, dtype=np.float64)
    if radii.ndim == 0 or radii.shape[-1] == 0:
        raise ParameterError("radii must be a non-empty array of shape (..., n_angles)")
    if n_angles is not None and radii.shape[-1] != n_angles:
        raise ParameterError(
            f"radii have {radii.shape[-1]} angles but the face expects {n_angles}; "
            "resample them at rockscan.core.polar.polar_angles(n_angles)"
        )
    if not np.all(np.isfinite(radii)) or np.any(radii < 0) or np.any(radii.max(axis=-1) <= 0):
        raise ParameterError("radii must be finite, non-negative and not all zero")
    return radii
