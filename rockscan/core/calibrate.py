"""Library radii -> per-shape cutoffs, from the paper's own sensor model.

The paper accepts a sample when its distance to the nearest library shape does
not exceed a cutoff theta, and claims robustness to outline noise of up to 20%
(Section IV-A). It gives no value for theta, and one value cannot fit every
library: the spread of a shape's samples, and the room between a library's
shapes, differ from library to library and from shape to shape. This module
measures both for the library at hand.

The sensor model (:class:`SensorModel`) is the paper's Fig. 11 noise as a
photo shows it: an outline of ``n_points`` vertices, each radius times
``1 + e`` with ``e`` normal (standard deviation up to the library's
``tolerance``), at a random rotation that falls between the rays; the
outline's centroid moves with the noise; segmentation then blurs the outline
by about a pixel and jitters it by a fraction of one. :func:`simulate_radii`
draws such measurements from any outline, all at once. The radii the noise
multiplies are those about a Superformula's own origin, which is not the
centroid of a shape without point symmetry: a library built from formulas
passes each shape's origin (``origins``).

The distance that ranks and decides (:class:`SensorMetric`) compares log radii
(the noise multiplies each radius, so in logs it is the same on every ray)
frequency by frequency, each frequency weighed by what the sensor model says
it can tell: ``S / (S + N)``, with ``N`` the noise power at the tolerance and
``S`` the power rock outlines have there (the library's own, never less at a
lower frequency than at a higher one, and at least ``N`` on the coarse
harmonics 1 to ``COARSE_HARMONICS`` that tell any two rocks apart). Noise
spread over harmonics that no shape has is left out; where shapes differ, the
comparison is the matched filter's. All rotations are scored at once by FFT.

:func:`calibrate` then gives each shape two cutoffs on that distance (the
sample's own noise taken out, :meth:`SensorMetric.corrected`): one for a
sample at the tolerance's noise, one for a clean sample. A sample's cutoff
runs linearly between them with its estimated noise (:func:`cutoff_at`).
At each end:

* in-library: ``n_samples`` simulated measurements of the shape (at noise
  equal to the tolerance, the worst the library promises to accept; or
  clean) and, for a shape given by example photos, of each example (so the
  spread between examples counts); the ``accept_quantile`` of their
  distances to the shape. A clean sample is allowed at least what the
  tolerated noise alone would put between it and its shape: a real outline
  is never quite its shape;
* out-of-library: the library's geometry. ``s_k``, the distance from shape k
  to its nearest other shape, is the scale at which the library tells shapes
  apart; shapes at that distance around k (random smooth deformations of it,
  and the shape continued beyond k away from its nearest neighbour), measured
  clean or at the tolerance, must be refused; the ``reject_quantile`` of
  their distances to k bounds the cutoff from above.

The cutoff lies half-way (in log) between the two bounds. Where they cross
(the tolerance's noise reaches the next shape), it is where the two
empirical error rates, each over the share it is allowed, meet, and the
shape is marked ``crowded``. Libraries of more than ``max_shapes`` shapes
are calibrated on a seeded sample of that many shapes; every other shape
gets the median of their cutoffs (the log-radii spread hardly depends on the
shape), so the cost stays linear in the library's size with a small
constant.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from rockscan.core._frozen import freeze_arrays
from rockscan.core.choices import DEFAULT_TOLERANCE
from rockscan.core.errors import ParameterError
from rockscan.core.polar import radii_about

__all__ = [
    "CALIBRATION_VERSION",
    "COARSE_HARMONICS",
    "DEFAULT_TOLERANCE",
    "KEEP_CROWDED",
    "Calibration",
    "CalibrationSamples",
    "SensorMetric",
    "SensorModel",
    "SensorSample",
    "calibrate",
    "cutoff_at",
    "log_noise_variance",
    "simulate_radii",
]

#: Version of the calibration procedure, stored with its cutoffs.
CALIBRATION_VERSION = 2
#: Harmonics that always count at least half: elongation, triangularity,
#: squareness... where any two rocks differ first.
COARSE_HARMONICS = 8
#: Smallest radius of a simulated outline, as a fraction of the true one (as render.py).
_MIN_FACTOR = 0.05
#: Smallest radius, relative to the mean, that the log of a measurement takes.
_LOG_FLOOR = 0.05
#: Share of in-library samples a crowded shape's cutoff keeps at least, whatever
#: shapes at the library's spacing it then lets in.
KEEP_CROWDED = 0.9
#: Harmonics in the noise band, and the simulated samples that measure its gain.
_BAND = 24
_GAIN_SAMPLES = 64
_GAIN_SEED = 20260


@dataclass(frozen=True)
class SensorModel:
    """How a photo measures an outline (the paper's Fig. 11 noise, then segmentation).

    Parameters
    ----------
    tolerance : float
        Largest standard deviation of the outline noise ``e`` (radius times
        ``1 + e``) the library promises to accept; 0.2 is the paper's claim.
    n_points : int
        Outline vertices the noise is drawn at.
    radius_px : (float, float)
        Range of a rock's mean radius in the photo, pixels: sets how much a
        pixel of segmentation error weighs.
    jitter_px : float
        Standard deviation of segmentation's boundary error per ray, pixels.
    blur_px : float
        Standard deviation of the blur that photo and segmentation put on the
        outline, pixels along it.
    """

    tolerance: float = DEFAULT_TOLERANCE
    n_points: int = 360
    radius_px: tuple[float, float] = (40.0, 200.0)
    jitter_px: float = 0.3
    blur_px: float = 1.0

    def __post_init__(self) -> None:
        t = self.tolerance
        if isinstance(t, bool) or not isinstance(t, (int, float)) or not (math.isfinite(t) and 0 <= t <= 1):
            raise ParameterError(f"tolerance must be a number from 0 to 1 (0.2 is 20%), got {t!r}")
        if isinstance(self.n_points, bool) or int(self.n_points) != self.n_points or self.n_points < 8:
            raise ParameterError(f"n_points must be an integer >= 8, got {self.n_points!r}")
        lo, hi = (float(v) for v in self.radius_px)
        if not (0 < lo <= hi < math.inf):
            raise ParameterError(
                f"radius_px must be (low, high) with 0 < low <= high, got {self.radius_px!r}"
            )
        for name in ("jitter_px", "blur_px"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ParameterError(f"{name} must be a non-negative number, got {value!r}")


@functools.lru_cache(maxsize=64)
def log_noise_variance(noise: float) -> float:
    """Variance of ``log(max(1 + e, 0.05))`` for ``e`` normal with standard deviation ``noise``.

    The outline noise as the log radii see it (quadrature on a fine grid, exact
    to far below what matters here).
    """
    # A fine grid over the normal, not Gauss-Hermite nodes: those come from an
    # eigen solver whose threads would leave later results thread-dependent.
    nodes = np.linspace(-9.0, 9.0, 9001)
    values = np.log(np.maximum(1.0 + noise * nodes, _MIN_FACTOR))
    weights = np.exp(-0.5 * nodes**2)
    weights = weights / weights.sum()
    mean = float(np.sum(weights * values))
    return float(np.sum(weights * (values - mean) ** 2))


def simulate_radii(
    radii: ArrayLike,
    noise: ArrayLike,
    *,
    model: SensorModel | None = None,
    rng: np.random.Generator | int | None = None,
    origins: ArrayLike | None = None,
) -> NDArray[np.float64]:
    """Measurements of outlines as a photo and its segmentation would give them.

    Parameters
    ----------
    radii : (n_angles,) or (n_samples, n_angles) array_like of float
        True outlines: radii about their centroids at
        :func:`rockscan.core.polar.polar_angles`, any scale.
    noise : float or (n_samples,) array_like of float
        Standard deviation of each sample's outline noise ``e``.
    model : SensorModel, optional
        Its ``tolerance`` is not used here (``noise`` is).
    rng : numpy.random.Generator, int or None
    origins : (2,) or (n_samples, 2) array_like of float, optional
        The point each outline's noise is drawn about, (x, y) from its
        centroid in units of its mean radius: the paper's noise multiplies a
        Superformula's radii about the formula's own origin, which is not
        the centroid of a shape without point symmetry (m = 1), and there
        the noise is larger on the far side. Default: the centroid.

    Returns
    -------
    measured : (n_samples, n_angles) ndarray of float
        Radii about each noisy outline's own centroid, mean about 1, at a
        random sub-ray rotation (rays and outline vertices do not line up).

    Notes
    -----
    Each sample: vertices at ``n_points`` angles shifted by a random fraction
    of their spacing; radii there interpolated from the truth and multiplied
    by ``max(1 + e, 0.05)``; the polygon cut by the rays (the exact
    intersection with each edge); the rays moved to the polygon's area
    centroid to first order (``r - c . u_theta``); blurred by ``blur_px`` and
    jittered by ``jitter_px`` at a rock radius drawn from ``radius_px``.
    """
    model = model or SensorModel()
    rng = np.random.default_rng(rng)
    truth = np.asarray(radii, dtype=np.float64)
    noise_arr = np.atleast_1d(np.asarray(noise, dtype=np.float64))
    if truth.ndim == 1:
        truth = np.broadcast_to(truth, (noise_arr.size, truth.size))
    if truth.ndim != 2 or truth.shape[1] < 8 or not np.all(np.isfinite(truth)) or np.any(truth <= 0):
        raise ParameterError("radii must be positive and finite, (n_angles,) or (n_samples, n_angles)")
    noise_arr = np.broadcast_to(noise_arr, (truth.shape[0],))
    if not np.all(np.isfinite(noise_arr)) or np.any(noise_arr < 0):
        raise ParameterError("noise must be finite and non-negative")
    m, n = truth.shape
    p = int(model.n_points)
    truth = truth / truth.mean(axis=1, keepdims=True)
    truth, moved = _about_origins(truth, origins)
    offset = rng.random(m)
    # Vertex i sits at angle (i + offset) * 2 pi / p; its radius is read off the truth.
    position = (np.arange(p)[None, :] + offset[:, None]) * (n / p)
    lo = np.floor(position).astype(np.int64)
    frac = position - lo
    rows = np.arange(m)[:, None]
    vertex = truth[rows, lo % n] * (1.0 - frac) + truth[rows, (lo + 1) % n] * frac
    vertex = vertex * np.maximum(1.0 + noise_arr[:, None] * rng.standard_normal((m, p)), _MIN_FACTOR)
    phi = (np.arange(p)[None, :] + offset[:, None]) * (2.0 * np.pi / p)
    # Each ray meets the edge between the vertices on either side of it.
    theta = 2.0 * np.pi * np.arange(n) / n
    before = np.floor(theta[None, :] / (2.0 * np.pi / p) - offset[:, None]).astype(np.int64)
    r1, r2 = vertex[rows, before % p], vertex[rows, (before + 1) % p]
    a1 = theta[None, :] - (before + offset[:, None]) * (2.0 * np.pi / p)
    step = 2.0 * np.pi / p
    measured = r1 * r2 * math.sin(step) / (r1 * np.sin(a1) + r2 * np.sin(step - a1))
    # The polygon's area centroid: the rays start there in a photo.
    x, y = vertex * np.cos(phi), vertex * np.sin(phi)
    x1, y1 = np.roll(x, -1, axis=1), np.roll(y, -1, axis=1)
    cross = x * y1 - x1 * y
    area = cross.sum(axis=1) / 2.0
    cx = ((x + x1) * cross).sum(axis=1) / (6.0 * area)
    cy = ((y + y1) * cross).sum(axis=1) / (6.0 * area)
    shift = ~moved
    measured[shift] = measured[shift] - (cx[shift, None] * np.cos(theta) + cy[shift, None] * np.sin(theta))
    if moved.any():
        # A centroid far from the origin moves the rays too far for the first order.
        measured[moved] = radii_about(measured[moved], np.column_stack([cx[moved], cy[moved]]))
        measured[moved] /= measured[moved].mean(axis=1, keepdims=True)
    radius_px = rng.uniform(*model.radius_px, size=m)
    if model.blur_px > 0:
        freq = np.arange(n // 2 + 1)
        width = model.blur_px / radius_px  # radians along the outline
        measured = np.fft.irfft(
            np.fft.rfft(measured, axis=1) * np.exp(-0.5 * (freq[None, :] * width[:, None]) ** 2), n=n, axis=1
        )
    measured = measured + (model.jitter_px / radius_px)[:, None] * rng.standard_normal((m, n))
    return np.maximum(measured, 1e-3)


def _about_origins(
    truth: NDArray[np.float64], origins: ArrayLike | None
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """The outlines' radii about their noise origins, and which of them moved there.

    The noise is drawn about the origin, so the truth's radii are taken about it
    first; an origin outside its outline (a shape deformed away from it) keeps
    the centroid.
    """
    m = truth.shape[0]
    moved = np.zeros(m, dtype=bool)
    if origins is None:
        return truth, moved
    centre = np.broadcast_to(np.asarray(origins, dtype=np.float64), (m, 2))
    if not np.all(np.isfinite(centre)):
        raise ParameterError("origins must be finite (x, y) pairs, one per sample")
    moved = np.any(centre != 0.0, axis=1)
    if not moved.any():
        return truth, moved
    about = radii_about(truth[moved], centre[moved])
    inside = np.all(about > 0.05, axis=1)
    rows = np.flatnonzero(moved)
    moved[rows[~inside]] = False
    truth = truth.copy()
    truth[rows[inside]] = about[inside]
    return truth, moved


@dataclass(frozen=True, eq=False)
class SensorMetric:
    """The noise-aware distance between outlines, at every rotation at once.

    ``d(x, y_k)**2 = min_a sum_f w_f |X_f e^{-2 pi i f a / n} - Y_kf|**2`` over
    the full spectrum, with ``X`` the orthonormal DFT of the sample's log radii
    (mean radius 1), ``Y_k`` that of shape k and ``w_f = S_f / (S_f + N)`` (see
    the module docstring). With every ``w_f = 1`` it is the matched filter on
    log radii; in units of radius it is an RMS difference times ``sqrt(n_angles)``.

    Build with :meth:`from_radii`.

    Attributes
    ----------
    weights : (n_angles // 2 + 1,) ndarray of float
        ``w_f``.
    spectra : (n_shapes, n_angles // 2 + 1) ndarray of complex
        ``sqrt(w_f) Y_kf``.
    norm_sq : (n_shapes,) ndarray of float
        ``sum_f w_f |Y_kf|**2`` over the full spectrum.
    tolerance : float
        The noise the weights were set for.
    noise_band : (int, int)
        Harmonics ``[lo, hi)`` just above the library's, where a sample's power
        is its noise: they estimate how much noise a sample carries.
    noise_gain : float
        Expected noise part of ``d**2`` per unit of the band's median power,
        measured on simulated samples of the library's shapes.
    noise_floor : float
        The noise part of ``d**2`` at the tolerance: what
        :meth:`noise_level` scales by, and what a clean sample is allowed at
        least (a real outline is never quite the shape it resembles; a coin
        is not a circle to the pixel).
    """

    weights: NDArray[np.float64]
    spectra: NDArray[np.complex128]
    norm_sq: NDArray[np.float64]
    tolerance: float
    noise_band: tuple[int, int] = (0, 0)
    noise_gain: float = 0.0
    noise_floor: float = 0.0

    def __post_init__(self) -> None:
        freeze_arrays(self)

    @classmethod
    def from_radii(cls, radii: ArrayLike, tolerance: float = DEFAULT_TOLERANCE) -> SensorMetric:
        """The metric of a library.

        Parameters
        ----------
        radii : (n_shapes, n_angles) array_like of float
            The library's outlines, any scale.
        tolerance : float
            Outline noise the weights are set for.
        """
        radii = np.asarray(radii, dtype=np.float64)
        if radii.ndim != 2 or radii.shape[0] < 1:
            raise ParameterError("radii must be (n_shapes, n_angles)")
        raw = _log_spectrum(radii)
        power = np.mean(np.abs(raw) ** 2, axis=0)
        # A rock's outline has no less power at a lower harmonic than at a
        # higher one it has: the running maximum from above.
        envelope = np.maximum.accumulate(power[::-1])[::-1]
        noise_power = max(log_noise_variance(float(tolerance)), 1e-12)
        envelope[1 : COARSE_HARMONICS + 1] = np.maximum(envelope[1 : COARSE_HARMONICS + 1], noise_power)
        weights = envelope / (envelope + noise_power)
        spectra = raw * np.sqrt(weights)
        n_freq = weights.size
        above = np.flatnonzero((weights < 0.1) & (np.arange(n_freq) > COARSE_HARMONICS))
        # A coarse face (few rays) has few harmonics: the band shrinks to fit, never empty.
        width = max(1, min(_BAND, (n_freq - 1) // 3))
        lo = int(above[0]) if above.size else n_freq - 2 * width
        start = int(np.clip(lo, 1, n_freq - width))
        band = (start, start + width)
        metric = cls(
            weights=weights,
            spectra=spectra,
            norm_sq=_full_sum(np.abs(spectra) ** 2, radii.shape[1]),
            tolerance=float(tolerance),
            noise_band=band,
        )
        # How the band's power maps to the noise part of d**2: measured on the
        # library's own shapes at the tolerance (a fixed seed: same library,
        # same metric).
        rng = np.random.default_rng(_GAIN_SEED)
        pick = np.arange(_GAIN_SAMPLES) % radii.shape[0]
        measured = simulate_radii(radii[pick], max(float(tolerance), 0.02), rng=rng)
        own = metric.squared_distances(measured, pick).min(axis=1)
        band_power = metric._band_power(measured)
        usual = _usual_shapes(own, band_power, pick)
        gain = float(np.mean(own[usual]) / max(np.mean(band_power[usual]), 1e-300))
        return cls(
            weights=weights,
            spectra=spectra,
            norm_sq=metric.norm_sq,
            tolerance=float(tolerance),
            noise_band=band,
            noise_gain=gain,
            noise_floor=float(np.mean(own[usual])),
        )

    def _band_power(self, radii: ArrayLike) -> NDArray[np.float64]:
        """Median power of the noise band, ``(...)``: robust to a shape's few harmonics there."""
        return self._band_power_of(_log_spectrum(np.asarray(radii, dtype=np.float64)))

    def _band_power_of(self, raw: NDArray[np.complex128]) -> NDArray[np.float64]:
        """:meth:`_band_power` from the log radii's spectrum (:func:`_log_spectrum`)."""
        lo, hi = self.noise_band
        return np.median(np.abs(raw[..., lo:hi]) ** 2, axis=-1)

    def noise_energy(self, radii: ArrayLike) -> NDArray[np.float64]:
        """The expected noise part of a sample's ``d**2`` to its own shape, ``(...)``.

        Estimated from the sample itself (the power in ``noise_band``), so a
        clean sample far from every shape is not excused by the noise the
        library tolerates.
        """
        return self.noise_gain * self._band_power(radii)

    def corrected(self, radii: ArrayLike, dist_sq: ArrayLike) -> NDArray[np.float64]:
        """Distances with the sample's own noise taken out: ``sqrt(max(d**2 - noise, 0))``.

        Parameters
        ----------
        radii : (..., n_angles) array_like of float
        dist_sq : (..., k) array_like of float
            Squared distances of those samples (any trailing axis).
        """
        return _corrected(self.noise_energy(radii), dist_sq)

    def noise_level(self, radii: ArrayLike) -> NDArray[np.float64]:
        """A sample's outline noise as estimated from itself (standard deviation of ``e``), ``(...)``."""
        return self._noise_level_of(self.noise_energy(radii))

    def _noise_level_of(self, energy: NDArray[np.float64]) -> NDArray[np.float64]:
        return self.tolerance * np.sqrt(energy / max(self.noise_floor, 1e-300))

    def sample(self, radii: ArrayLike) -> SensorSample:
        """Everything the metric needs of one sample, from one spectrum of its log radii.

        A match asks for the sample's weighted spectrum, its noise energy and
        its noise level; each of :meth:`sample_spectrum`, :meth:`noise_energy`
        and :meth:`noise_level` would take the logarithm and the FFT again.

        Parameters
        ----------
        radii : (n_angles,) array_like of float

        Returns
        -------
        SensorSample
            The same numbers as those methods give.
        """
        raw = _log_spectrum(np.asarray(radii, dtype=np.float64))
        energy = self.noise_gain * self._band_power_of(raw)
        return SensorSample(
            spectrum=raw * np.sqrt(self.weights),
            noise_energy=float(energy),
            noise_level=float(self._noise_level_of(energy)),
        )

    @property
    def n_angles(self) -> int:
        """Number of rays."""
        return 2 * (self.weights.size - 1)

    def sample_spectrum(self, radii: ArrayLike) -> NDArray[np.complex128]:
        """``sqrt(w_f) X_f`` of samples, ``(..., n_freq)``."""
        return _log_spectrum(np.asarray(radii, dtype=np.float64)) * np.sqrt(self.weights)

    def squared_distances(self, radii: ArrayLike, shapes: ArrayLike | None = None) -> NDArray[np.float64]:
        """Squared distances at every rotation.

        Parameters
        ----------
        radii : (n_angles,) or (n_samples, n_angles) array_like of float
        shapes : (n_shapes,) or (n_samples,) array_like of int, optional
            Library shapes to compare with: all (default), or, per sample, one.

        Returns
        -------
        dist_sq : (n_angles, n_shapes) or (n_samples, n_angles, n_shapes) ndarray of float
            With ``shapes`` given per sample: ``(n_samples, n_angles)``. Row a
            is the sample turned back by ``a`` rays, as in
            :func:`rockscan.core.match.rotation_scores`.
        """
        return self.spectrum_distances(self.sample_spectrum(radii), shapes)

    def spectrum_distances(
        self, x: NDArray[np.complex128], shapes: ArrayLike | None = None
    ) -> NDArray[np.float64]:
        """:meth:`squared_distances` of samples given by their :meth:`sample_spectrum`."""
        n = self.n_angles
        own = _full_sum(np.abs(x) ** 2, n)
        if shapes is not None:
            index = np.asarray(shapes, dtype=np.int64)
            corr = np.fft.irfft(x * np.conj(self.spectra[index]), n=n, axis=-1) * n
            return np.maximum(own[..., None] + self.norm_sq[index][..., None] - 2.0 * corr, 0.0)
        corr = np.fft.irfft(x[..., None, :] * np.conj(self.spectra), n=n, axis=-1) * n
        dist_sq = own[..., None, None] + self.norm_sq[:, None] - 2.0 * corr
        return np.maximum(np.swapaxes(dist_sq, -1, -2), 0.0)

    def distances(self, radii: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        """Each shape's distance at its best rotation, and that rotation (rays).

        Returns
        -------
        dist : (..., n_shapes) ndarray of float
        shift : (..., n_shapes) ndarray of int
        """
        dist_sq = self.squared_distances(radii)
        shift = np.argmin(dist_sq, axis=-2)
        return np.sqrt(np.take_along_axis(dist_sq, shift[..., None, :], axis=-2)[..., 0, :]), shift


@dataclass(frozen=True, eq=False)
class SensorSample:
    """One sample as :class:`SensorMetric` sees it (:meth:`SensorMetric.sample`).

    Attributes
    ----------
    spectrum : (n_freq,) ndarray of complex
        :meth:`SensorMetric.sample_spectrum`, ``sqrt(w_f) X_f``.
    noise_energy : float
        :meth:`SensorMetric.noise_energy`.
    noise_level : float
        :meth:`SensorMetric.noise_level`.
    """

    spectrum: NDArray[np.complex128]
    noise_energy: float
    noise_level: float

    def corrected(self, dist_sq: ArrayLike) -> NDArray[np.float64]:
        """:meth:`SensorMetric.corrected` of this sample's squared distances."""
        return _corrected(np.asarray(self.noise_energy), dist_sq)


def _corrected(noise: NDArray[np.float64], dist_sq: ArrayLike) -> NDArray[np.float64]:
    """``sqrt(max(d**2 - noise, 0))``, ``noise`` broadcast over the trailing axis of ``dist_sq``."""
    dist_sq = np.asarray(dist_sq, dtype=np.float64)
    out = np.asarray(dist_sq - noise.reshape(noise.shape + (1,) * (dist_sq.ndim - noise.ndim)))
    np.maximum(out, 0.0, out=out)
    return np.sqrt(out, out=out)


def _log_spectrum(radii: NDArray[np.float64]) -> NDArray[np.complex128]:
    """Orthonormal DFT of log radii at mean radius 1, ``(..., n // 2 + 1)``."""
    if radii.shape[-1] < 8 or not np.all(np.isfinite(radii)) or np.any(radii < 0):
        raise ParameterError("radii must be finite and non-negative, at least 8 rays")
    mean = radii.mean(axis=-1, keepdims=True)
    if np.any(mean <= 0):
        raise ParameterError("radii must not be all zero")
    return np.fft.rfft(np.log(np.maximum(radii / mean, _LOG_FLOOR)), axis=-1, norm="ortho")


def _full_sum(values: NDArray[np.float64], n: int) -> NDArray[np.float64]:
    """Sum of a real signal's spectral values over the full spectrum from its half."""
    factor = np.full(values.shape[-1], 2.0)
    factor[0] = 1.0
    if n % 2 == 0:
        factor[-1] = 1.0
    # Elementwise, not BLAS: a threaded BLAS call here would make later results
    # depend on the thread count in the last digit.
    return np.sum(values * factor, axis=-1)


@dataclass(frozen=True, eq=False)
class CalibrationSamples:
    """The simulated distances a calibration chose from (for figures and checks).

    Attributes
    ----------
    inside : (n_calibrated, n_in) ndarray of float
        Distances of in-library measurements at the tolerance to their own shape.
    outside : (n_calibrated, n_out) ndarray of float
        Distances of out-of-library shapes (at the library's spacing) to the
        shape: even columns measured clean, odd ones at the tolerance.
    shapes : (n_calibrated,) ndarray of int
        The calibrated shapes, by library index.
    inside_clean : (n_calibrated, n_in) ndarray of float
        Distances of clean in-library measurements (blur and jitter only).
    """

    inside: NDArray[np.float64]
    outside: NDArray[np.float64]
    shapes: NDArray[np.int64]
    inside_clean: NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class Calibration:
    """Per-shape cutoffs of a library and how they were found.

    Attributes
    ----------
    cutoffs : (n_shapes,) ndarray of float
        Largest :class:`SensorMetric` distance (the sample's own noise taken
        out) at which a sample with outline noise at the tolerance still
        belongs to each shape.
    spacing : (n_shapes,) ndarray of float
        Distance from each shape to its nearest other shape (inf for a
        one-shape library or a shape that was not calibrated).
    crowded : (n_shapes,) ndarray of bool
        Shapes whose neighbours are closer than the tolerance's noise reaches:
        their cutoff balances the two errors instead of meeting both bounds.
    calibrated : (n_shapes,) ndarray of bool
        Shapes calibrated one by one (all, unless the library has more than
        ``max_shapes``); the others got the median cutoff.
    tolerance : float
    seed : int
    version : int
        :data:`CALIBRATION_VERSION` of the procedure.
    note : str
        Empty, or how the cutoffs came about when not from this procedure at build.
    samples : CalibrationSamples or None
        The simulated distances, when asked for.
    clean_cutoffs : (n_shapes,) ndarray of float or None
        The same for a sample without outline noise of its own; None: equal to
        ``cutoffs``. A sample's cutoff runs between the two with its estimated
        noise (:func:`cutoff_at`).
    """

    cutoffs: NDArray[np.float64]
    spacing: NDArray[np.float64]
    crowded: NDArray[np.bool_]
    calibrated: NDArray[np.bool_]
    tolerance: float = DEFAULT_TOLERANCE
    seed: int = 0
    version: int = CALIBRATION_VERSION
    note: str = ""
    samples: CalibrationSamples | None = field(default=None, repr=False)
    clean_cutoffs: NDArray[np.float64] | None = None

    def __post_init__(self) -> None:
        n = np.shape(self.cutoffs)[0] if np.ndim(self.cutoffs) == 1 else -1
        if self.clean_cutoffs is None:
            object.__setattr__(self, "clean_cutoffs", self.cutoffs)
        for name in ("cutoffs", "spacing", "crowded", "calibrated", "clean_cutoffs"):
            value = np.asarray(getattr(self, name))
            if value.shape != (n,):
                raise ParameterError("calibration arrays must be (n_shapes,), all of one length")
        cutoffs = np.concatenate([np.asarray(self.cutoffs, float), np.asarray(self.clean_cutoffs, float)])
        if not np.all(np.isfinite(cutoffs)) or np.any(cutoffs < 0):
            raise ParameterError("cutoffs must be finite and non-negative")
        for name, dtype in (
            ("cutoffs", np.float64),
            ("clean_cutoffs", np.float64),
            ("spacing", np.float64),
            ("crowded", bool),
            ("calibrated", bool),
        ):
            arr = np.array(getattr(self, name), dtype=dtype)
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    def to_dict(self) -> dict[str, object]:
        """The scalar settings, JSON-able (the arrays are stored beside them)."""
        return {"tolerance": self.tolerance, "seed": self.seed, "version": self.version, "note": self.note}


def _usual_shapes(
    own: NDArray[np.float64], band_power: NDArray[np.float64], pick: NDArray[np.intp]
) -> NDArray[np.bool_]:
    """The samples whose shape's noise reads as the library's does.

    A shape whose own harmonics fill the noise band (a spiky one among smooth
    ones) shows there far more power than its noise: its ratio of noise
    distance to band power lies ``_OWN_BAND`` times the shapes' median or more.
    Let into the gain, it made every other shape's noise seem larger than any
    distance, and their distances 0: one such shape in a library set the
    cutoffs of the rest to 0. Where no shape is so, every sample counts.
    """
    ratio = own / np.maximum(band_power, 1e-300)
    shapes = np.unique(pick)
    per_shape = np.array([np.median(ratio[pick == k]) for k in shapes])
    usual = shapes[per_shape <= _OWN_BAND * np.median(per_shape)]
    return np.isin(pick, usual)


#: How far past the shapes' median ratio of noise distance to band power a
#: shape's may lie for its samples to set the noise gain (:func:`_usual_shapes`):
#: the default library's shapes lie within 1.9 times it; a spiky shape among
#: them, 22 times.
_OWN_BAND = 4.0


def cutoff_at(calibration: Calibration, shape: int, noise: float) -> float:
    """The cutoff shape ``shape`` sets for a sample with estimated outline noise ``noise``.

    Linear in the noise from ``clean_cutoffs`` (no noise) to ``cutoffs`` (at
    the tolerance and beyond): the spread of either side's distances grows
    with the noise, so both ends are calibrated and the noise in between
    interpolates them.

    Parameters
    ----------
    calibration : Calibration
    shape : int
        Library index of the shape.
    noise : float
        The sample's outline noise (standard deviation of ``e``), as
        :meth:`SensorMetric.noise_level` estimates it.
    """
    assert calibration.clean_cutoffs is not None
    t = calibration.tolerance
    share = min(max(noise / t, 0.0), 1.0) if t > 0 else 1.0
    clean, noisy = float(calibration.clean_cutoffs[shape]), float(calibration.cutoffs[shape])
    return clean + share * (noisy - clean)


def calibrate(
    radii: ArrayLike,
    *,
    examples: Sequence[ArrayLike | None] | None = None,
    tolerance: float = DEFAULT_TOLERANCE,
    model: SensorModel | None = None,
    n_samples: int = 24,
    n_outside: int = 24,
    accept_quantile: float = 0.97,
    reject_quantile: float = 0.03,
    max_shapes: int = 100,
    seed: int = 0,
    keep_samples: bool = False,
    metric: SensorMetric | None = None,
    origins: ArrayLike | None = None,
) -> Calibration:
    """Per-shape cutoffs of a library from its radii (see the module docstring).

    Parameters
    ----------
    radii : (n_shapes, n_angles) array_like of float
        The library's outlines about their centroids, any scale.
    examples : sequence of (n_examples, n_angles) array_like or None, optional
        Per shape, the radii of the example photos it was made from (turned to
        one orientation), or None for a shape given by parameters.
    tolerance : float
        Largest outline noise a sample of the library may carry (0.2: 20%).
    model : SensorModel, optional
        Segmentation's share of the sensor model; its tolerance is replaced.
    n_samples : int
        Simulated in-library measurements per shape (and per example source).
    n_outside : int
        Simulated out-of-library shapes per shape, half of them clean.
    accept_quantile, reject_quantile : float
        The bounds at each end: this share of in-library measurements lies
        below the one, this share of out-of-library shapes below the other.
    max_shapes : int
        Shapes calibrated one by one; a larger library is calibrated on a
        seeded sample of this many.
    seed : int
        Seed of every simulated draw: the same library gets the same cutoffs.
    keep_samples : bool
        Keep the simulated distances (for figures).
    metric : SensorMetric, optional
        ``SensorMetric.from_radii(radii, tolerance)`` when the caller has it already.
    origins : (n_shapes, 2) array_like of float, optional
        Per shape, the point its outline noise is drawn about, from its
        centroid in units of its mean radius (:func:`simulate_radii`;
        a library built from Superformulas gives each formula's origin).
        Default: every centroid; a shape given by examples always uses its own.

    Returns
    -------
    Calibration
    """
    radii, example_list, n_samples, n_outside = _calibrate_iv(radii, examples, n_samples, n_outside)
    centres = _origins_iv(origins, radii.shape[0])
    if not (0.5 < accept_quantile < 1 and 0 < reject_quantile < 0.5):
        raise ParameterError("accept_quantile must be in (0.5, 1) and reject_quantile in (0, 0.5)")
    base = model or SensorModel()
    model = SensorModel(
        tolerance=tolerance,
        n_points=base.n_points,
        radius_px=base.radius_px,
        jitter_px=base.jitter_px,
        blur_px=base.blur_px,
    )
    if metric is None or metric.tolerance != model.tolerance or metric.spectra.shape[0] != radii.shape[0]:
        metric = SensorMetric.from_radii(radii, model.tolerance)
    rng = np.random.default_rng([seed, 11])
    n_shapes = radii.shape[0]
    chosen = np.arange(n_shapes)
    if n_shapes > max_shapes:
        chosen = np.sort(rng.choice(n_shapes, size=max_shapes, replace=False))
    spacing, neighbour = _spacing(metric, radii, chosen)
    inside, inside_clean, outside = _simulate(
        metric, radii, example_list, chosen, spacing, neighbour, n_samples, n_outside, model, rng, centres
    )
    cut, clean_cut, crowded = _both_ends(
        inside, inside_clean, outside, accept_quantile, reject_quantile, math.sqrt(metric.noise_floor)
    )
    # Shapes left out of a large library's sample take the median of those calibrated.
    cutoffs = _every_shape(cut, chosen, n_shapes, float(np.median(cut)))
    clean_cutoffs = _every_shape(clean_cut, chosen, n_shapes, float(np.median(clean_cut)))
    full_spacing = _every_shape(spacing, chosen, n_shapes, np.inf)
    full_crowded = _every_shape(crowded, chosen, n_shapes, False)
    calibrated = _every_shape(np.ones(chosen.size, dtype=bool), chosen, n_shapes, False)
    samples = CalibrationSamples(inside, outside, chosen, inside_clean) if keep_samples else None
    return Calibration(
        cutoffs=cutoffs,
        spacing=full_spacing,
        crowded=full_crowded,
        calibrated=calibrated,
        tolerance=float(model.tolerance),
        seed=int(seed),
        samples=samples,
        clean_cutoffs=clean_cutoffs,
    )


def _both_ends(
    inside: NDArray[np.float64],
    inside_clean: NDArray[np.float64],
    outside: NDArray[np.float64],
    accept_quantile: float,
    reject_quantile: float,
    floor: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
    """Each shape's cutoff at the tolerance and clean, and whether it is crowded at the tolerance."""
    # Out-of-library shapes alternate: even columns measured clean, odd at the tolerance.
    outside_clean, outside_noisy = outside[:, 0::2], outside[:, 1::2]
    n = inside.shape[0]
    cut, clean_cut, crowded = np.empty(n), np.empty(n), np.zeros(n, dtype=bool)
    for i in range(n):
        cut[i], crowded[i] = _cutoff(inside[i], outside_noisy[i], accept_quantile, reject_quantile)
        # A real outline is never quite its shape: a clean sample is allowed at
        # least the distance the tolerated noise alone would put it at.
        clean_cut[i], _ = _cutoff(inside_clean[i], outside_clean[i], accept_quantile, reject_quantile, floor)
    return cut, clean_cut, crowded


def _simulate(
    metric: SensorMetric,
    radii: NDArray[np.float64],
    example_list: list[NDArray[np.float64] | None],
    chosen: NDArray[np.int64],
    spacing: NDArray[np.float64],
    neighbour: NDArray[np.int64],
    n_samples: int,
    n_outside: int,
    model: SensorModel,
    rng: np.random.Generator,
    centres: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Distances of the simulated samples of the chosen shapes, 64 shapes at a time:
    in library at the tolerance, in library clean, and out of library."""
    rows: list[tuple[NDArray[np.float64], ...]] = []
    for start in range(0, chosen.size, 64):
        block = chosen[start : start + 64]
        noisy_in, clean_in = _inside(metric, radii, example_list, block, n_samples, model, rng, centres)
        outside = _outside(
            metric,
            radii,
            block,
            spacing[start : start + 64],
            neighbour[start : start + 64],
            spacing,
            n_outside,
            model,
            rng,
            centres,
        )
        rows.append((noisy_in, clean_in, outside))
    inside, inside_clean, outside = (np.concatenate([r[i] for r in rows]) for i in range(3))
    return inside, inside_clean, outside


def _every_shape(values: NDArray, chosen: NDArray[np.int64], n_shapes: int, fill: object) -> NDArray:
    """Per-shape values of the chosen shapes spread over the library, ``fill`` elsewhere."""
    full = np.full(n_shapes, fill, dtype=np.asarray(values).dtype)
    full[chosen] = values
    return full


def _cutoff(
    inside: NDArray[np.float64],
    outside: NDArray[np.float64],
    accept_quantile: float,
    reject_quantile: float,
    floor: float = 0.0,
) -> tuple[float, bool]:
    """One end's cutoff from its in- and out-of-library distances, and whether the shape is crowded.

    With ``accept`` the ``accept_quantile`` of the in-library distances (at
    least ``floor`` when that is below ``reject``) and ``reject`` the
    ``reject_quantile`` of the others:
    half-way between them in log when ``accept <= reject``, a margin on both
    sides; otherwise (crowded) where the two error rates, each over the share
    it is allowed, meet.
    """
    accept = float(np.quantile(inside, accept_quantile))
    reject = float(np.quantile(outside, reject_quantile))
    accept = max(accept, min(floor, reject))
    if accept <= reject:
        return (math.sqrt(accept * reject) if accept > 0 else reject / 2.0), False
    # The tolerance is a promise: a crowded shape still keeps KEEP_CROWDED of its samples.
    return max(_balanced(inside, outside), float(np.quantile(inside, KEEP_CROWDED))), True


def _calibrate_iv(
    radii: ArrayLike, examples: Sequence[ArrayLike | None] | None, n_samples: int, n_outside: int
) -> tuple[NDArray[np.float64], list[NDArray[np.float64] | None], int, int]:
    radii = np.asarray(radii, dtype=np.float64)
    if radii.ndim != 2 or radii.shape[0] < 1 or radii.shape[1] < 8:
        raise ParameterError("radii must be (n_shapes, n_angles) with at least one shape and 8 rays")
    if not np.all(np.isfinite(radii)) or np.any(radii <= 0):
        raise ParameterError("library radii must be finite and positive")
    example_list: list[NDArray[np.float64] | None] = [None] * radii.shape[0]
    if examples is not None:
        if len(examples) != radii.shape[0]:
            raise ParameterError("examples must give one entry (or None) per shape")
        for k, ex in enumerate(examples):
            if ex is None:
                continue
            arr = np.atleast_2d(np.asarray(ex, dtype=np.float64))
            bad = arr.ndim != 2 or arr.shape[0] == 0 or arr.shape[1] != radii.shape[1]
            if bad or not np.all(np.isfinite(arr)) or np.any(arr <= 0):
                # An empty array of examples divided by zero when each sample picked one.
                rays = radii.shape[1]
                raise ParameterError(
                    f"examples of shape {k} must be one or more outlines of positive radii at {rays} rays"
                )
            example_list[k] = arr
    for name, value in (("n_samples", n_samples), ("n_outside", n_outside)):
        if isinstance(value, bool) or int(value) != value or value < 4:
            raise ParameterError(f"{name} must be an integer >= 4, got {value!r}")
    return radii, example_list, int(n_samples), int(n_outside)


def _origins_iv(origins: ArrayLike | None, n_shapes: int) -> NDArray[np.float64]:
    if origins is None:
        return np.zeros((n_shapes, 2))
    centres = np.asarray(origins, dtype=np.float64)
    if centres.shape != (n_shapes, 2) or not np.all(np.isfinite(centres)):
        raise ParameterError("origins must be finite, (n_shapes, 2): one (x, y) per shape")
    return centres


def _spacing(
    metric: SensorMetric, radii: NDArray[np.float64], chosen: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Distance from each chosen shape to its nearest other shape, and which one.

    A rotation-invariant lower bound (the spectra's magnitudes) picks a few
    candidates; their exact distances at every rotation decide.
    """
    n_shapes = radii.shape[0]
    if n_shapes == 1:
        return np.full(chosen.size, np.inf), np.zeros(chosen.size, dtype=np.int64)
    n = metric.n_angles
    factor = np.sqrt(
        np.where((np.arange(metric.weights.size) == 0) | (np.arange(metric.weights.size) == n // 2), 1.0, 2.0)
    )
    mags = np.abs(metric.spectra) * factor
    sq = np.einsum("kf,kf->k", mags, mags)
    spacing = np.empty(chosen.size)
    neighbour = np.empty(chosen.size, dtype=np.int64)
    n_candidates = min(8, n_shapes - 1)
    for start in range(0, chosen.size, 256):
        block = chosen[start : start + 256]
        bound = sq[block, None] + sq[None, :] - 2.0 * np.einsum("bf,kf->bk", mags[block], mags)
        bound[np.arange(block.size), block] = np.inf
        candidates = np.argpartition(bound, n_candidates - 1, axis=1)[:, :n_candidates]
        for i, k in enumerate(block):
            dist_sq = metric.squared_distances(np.repeat(radii[k][None], n_candidates, axis=0), candidates[i])
            best = dist_sq.min(axis=1)
            j = int(np.argmin(best))
            spacing[start + i] = math.sqrt(best[j])
            neighbour[start + i] = candidates[i, j]
    return spacing, neighbour


def _inside(
    metric: SensorMetric,
    radii: NDArray[np.float64],
    examples: list[NDArray[np.float64] | None],
    block: NDArray[np.int64],
    n_samples: int,
    model: SensorModel,
    rng: np.random.Generator,
    centres: NDArray[np.float64],
) -> NDArray[np.float64]:
    """(len(block), n_samples) distances to their shape of measurements at the tolerance, and clean ones."""
    picks, about = [], []
    for k in block:
        sources = examples[k] if examples[k] is not None else radii[k][None]
        # Every example is a source in turn: the spread between them counts.
        picks.append(sources[np.arange(n_samples) % sources.shape[0]])
        # An example photo's outline has no formula origin: its noise is about its centroid.
        about.append(np.broadcast_to(centres[k] if examples[k] is None else 0.0, (n_samples, 2)))
    picked = np.concatenate(picks)
    origins = np.concatenate(about)
    own = np.repeat(block, n_samples)
    # At the tolerance itself, the worst the library promises to accept; and
    # clean (the photo's blur and jitter only), where the cutoff's other end is.
    out = []
    for noise in (model.tolerance, 0.0):
        measured = simulate_radii(picked, noise, model=model, rng=rng, origins=origins)
        out.append(_scores(metric, measured, own).reshape(block.size, n_samples))
    return out[0], out[1]


def _scores(
    metric: SensorMetric, measured: NDArray[np.float64], own: NDArray[np.int64]
) -> NDArray[np.float64]:
    """What a cutoff meets: each measurement's distance to its shape with its own noise taken out."""
    dist_sq = metric.squared_distances(measured, own).min(axis=1)
    return metric.corrected(measured, dist_sq[:, None])[:, 0]


def _outside(
    metric: SensorMetric,
    radii: NDArray[np.float64],
    block: NDArray[np.int64],
    spacing: NDArray[np.float64],
    neighbour: NDArray[np.int64],
    spacing_all: NDArray[np.float64],
    n_outside: int,
    model: SensorModel,
    rng: np.random.Generator,
    centres: NDArray[np.float64],
) -> NDArray[np.float64]:
    """(len(block), n_outside) distances to shape k of shapes at the library's spacing around it.

    Half are random smooth deformations of k (spectra shaped like the metric's
    weights), half k continued beyond itself away from its nearest neighbour
    (with a smaller random deformation); each is scaled so that its distance
    to k is the spacing, then measured clean (even columns) or at the
    tolerance (odd columns).
    """
    n = radii.shape[1]
    n_freq = n // 2 + 1
    b = block.size
    n_random = n_outside // 2
    log_k = np.log(radii[block] / radii[block].mean(axis=1, keepdims=True))
    spectrum = rng.standard_normal((b, n_outside, n_freq)) + 1j * rng.standard_normal((b, n_outside, n_freq))
    spectrum *= np.sqrt(metric.weights) * (np.arange(n_freq) > 0)
    fields = np.fft.irfft(spectrum, n=n, axis=-1)
    fields /= np.sqrt(np.sum(fields**2, axis=-1, keepdims=True))
    if radii.shape[0] > 1:
        # k continued beyond itself, away from its neighbour at its best rotation.
        shift = np.argmin(metric.squared_distances(radii[neighbour], block), axis=1)
        turned = np.stack([np.roll(radii[j], -int(s)) for j, s in zip(neighbour, shift, strict=True)])
        away = log_k - np.log(turned / turned.mean(axis=1, keepdims=True))
        away /= np.maximum(np.sqrt(np.sum(away**2, axis=1, keepdims=True)), 1e-12)
        fields[:, n_random:] = away[:, None, :] + 0.3 * fields[:, n_random:]
    # Out-of-library shapes lie at least the library's typical spacing from every
    # shape, and no farther from k than that on some side of it, however far
    # k's own neighbour is: every shape is measured at that spacing.
    finite = spacing_all[np.isfinite(spacing_all)]
    typical = float(np.median(finite)) if finite.size else np.inf
    size = np.full(spacing.shape, typical)
    alone = ~np.isfinite(size)
    # A shape alone: twice what the tolerance's noise reaches in the weighted harmonics.
    size[alone] = 2.0 * math.sqrt(log_noise_variance(model.tolerance) * float(_full_sum(metric.weights, n)))
    own = np.repeat(block, n_outside)
    amplitude = np.full((b, n_outside), 0.1)
    for _ in range(3):
        # The distance grows about linearly with the deformation: rescale to the spacing.
        shapes = np.exp(log_k[:, None, :] + amplitude[..., None] * fields).reshape(-1, n)
        d = np.sqrt(metric.squared_distances(shapes, own).min(axis=1)).reshape(b, n_outside)
        amplitude *= size[:, None] / np.maximum(d, 1e-12)
    shapes = np.exp(log_k[:, None, :] + amplitude[..., None] * fields).reshape(-1, n)
    # Even columns clean, odd at the tolerance: the two ends of the cutoff.
    noise = np.tile(np.arange(n_outside) % 2 * model.tolerance, b)
    # Shapes around k are drawn like k, about k's noise origin.
    measured = simulate_radii(shapes, noise, model=model, rng=rng, origins=centres[own])
    return _scores(metric, measured, own).reshape(b, n_outside)


def _balanced(inside: NDArray[np.float64], outside: NDArray[np.float64], ratio: float = 1.0) -> float:
    """The cutoff where the share of in-library samples refused is ``ratio`` times the share of others
    let in (the ratio of the shares each error is allowed)."""
    candidates = np.unique(np.concatenate([inside, outside]))
    refused = 1.0 - np.searchsorted(np.sort(inside), candidates, side="right") / inside.size
    let_in = np.searchsorted(np.sort(outside), candidates, side="right") / outside.size
    i = int(np.argmin(np.abs(refused - ratio * let_in)))
    return float(candidates[i])
