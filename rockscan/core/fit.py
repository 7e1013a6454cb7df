"""Outline -> Superformula: fit a library shape to an example rock.

The paper's library may be "extrapolated by the shape matching system using the
Superformula" from example samples. :func:`fit_superformula` finds the
parameters and the rotation of the Superformula whose outline best matches a
rock's radii; :mod:`rockscan.core.family` makes near variants of a shape (the
paper's Section IV-C sweeps).

Frames. A rock's radii are measured about its area centroid; a Superformula
is written about its own origin, which is not its centroid unless the shape is
point- or k-fold symmetric. The fit therefore works in two frames:

* The global search compares the sample with a bank of Superformula shapes
  already put in the centroid frame (:func:`rockscan.core.superformula.shape_radii`'s
  frame), at every rotation at once by FFT cross-correlation.
* The local least squares measure the sample's outline points about a free
  origin ``o``: the residual of point ``p_i`` is
  ``|p_i - o| - s * r((phi_i - alpha) mod 2 pi)`` with ``phi_i`` its angle about
  ``o``. Exact for any Superformula (its outline is star-shaped about its
  origin), and cheap: one evaluation of the formula per residual vector.

The quality reported, ``rms_percent``, is judged in the centroid frame: the
root mean square difference between the sample's radii and the fitted shape's
radii turned by ``angle_deg``, both scaled to a mean radius of 1, in percent.

Parameterisation. The overall size is free (a fitted shape is normalised to
``a = 1``). Exponents span decades, so ``n1, n2, n3`` and the aspect ``b/a``
are fitted as logarithms. ``m1 = m2`` is the natural family (integer ``m``
keeps the curve closed); ``b != a`` and ``m1 != m2`` are kept only when they
cut the RMS error by the factor ``FitConfig.gain``.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from rockscan.core._threads import one_blas_thread
from rockscan.core.errors import ParameterError
from rockscan.core.polar import (
    fold_angle,
    polar_angles,
    polygon_area_centroids,
    recenter_radii,
    resample_radii,
    symmetry_order,
)
from rockscan.core.superformula import (
    SuperformulaParams,
    degenerate_rays,
    log_superformula,
    round_significant,
    shape_radii,
)

if TYPE_CHECKING:
    pass

__all__ = [
    "FitConfig",
    "FitResult",
    "fit_superformula",
]

_TWO_PI = 2.0 * math.pi
#: Rays of the global search's bank of shapes.
_BANK_ANGLES = 128
#: Exponents of the bank: log-spaced over the range rocks need.
_BANK_N = (0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 40.0)
#: Aspects b/a of the bank (b = a is the main family).
_BANK_ASPECT = (0.75, 0.55, 0.4)
#: Bounds of the fitted exponents and aspect.
_N_BOUNDS = (0.1, 2000.0)
_B_BOUNDS = (0.1, 10.0)
#: Significant digits of the reported parameters.
_DIGITS = 4
#: Largest |log radius| the model takes (beyond it the curve is clipped).
_LOG_CLIP = 40.0
#: Fitted aspects b/a within this log-distance of 1 are refitted with b = a.
_ASPECT_SNAP = 0.05
#: Residual (fraction of the mean radius) where the soft-L1 loss turns from square to linear.
_LOSS_SCALE = 0.02
#: Largest m the global search may try (the bank grows with it).
_M_MAX = 24


@dataclass(frozen=True)
class FitConfig:
    """Settings of :func:`fit_superformula`.

    Parameters
    ----------
    m_max : int
        The global search tries ``m = 1 .. m_max`` (integers, ``m1 = m2``); at most 24.
    n_starts : int
        Models (m, aspect free or not) whose best shapes of the global search
        start a local least-squares fit.
    n_best : int
        Shapes of the best model that start a local fit (the bank's best shape
        may lie in another basin of the exponents than the sample).
    aspect : bool
        Allow ``b != a`` (an elongated shape) when it pays.
    unequal_m : bool
        Allow ``m1 != m2`` (neighbours of the best m) when it pays.
    gain : float
        A richer model (free aspect, ``m1 != m2``) replaces a simpler one only
        if its RMS error is below ``gain`` times the simpler one's.
    good_percent : float
        An RMS error (percent) below which no richer model or restart is tried.
    restarts : int
        Random restarts around the best fit when it is not good (drawn from ``rng``).
    robust : bool
        Least squares with a soft-L1 loss, so that a few rays far off the
        curve (a tip lost to blur, a shadow joined to the rock) pull less.
    """

    m_max: int = 12
    n_starts: int = 4
    n_best: int = 4
    aspect: bool = True
    unequal_m: bool = True
    gain: float = 0.7
    good_percent: float = 1.0
    restarts: int = 3
    robust: bool = True

    def __post_init__(self) -> None:
        for name, low in (("m_max", 1), ("n_starts", 1), ("n_best", 1), ("restarts", 0)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
                raise ParameterError(f"FitConfig.{name} must be an integer >= {low}, got {value!r}")
        if self.m_max > _M_MAX:
            raise ParameterError(f"FitConfig.m_max must be at most {_M_MAX}, got {self.m_max}")
        for name in ("aspect", "unequal_m", "robust"):
            if not isinstance(getattr(self, name), bool):
                raise ParameterError(f"FitConfig.{name} must be True or False, got {getattr(self, name)!r}")
        if not (isinstance(self.gain, (int, float)) and 0 < self.gain <= 1):
            raise ParameterError(f"FitConfig.gain must be in (0, 1], got {self.gain!r}")
        if not (isinstance(self.good_percent, (int, float)) and self.good_percent >= 0):
            raise ParameterError(f"FitConfig.good_percent must be >= 0, got {self.good_percent!r}")


@dataclass(frozen=True)
class FitResult:
    """A Superformula fitted to an outline.

    Attributes
    ----------
    params : SuperformulaParams
        The fitted shape, ``a = 1`` (the size is free), 4 significant digits.
    angle_deg : float
        The sample is the shape turned counter-clockwise by this angle (the
        interface's convention), in ``[0, 360/k)`` for a k-fold symmetric shape.
    rms_percent : float
        RMS difference of the sample's and the turned shape's radii about their
        centroids, both scaled to mean 1, in percent of the mean radius.
    mean_radius : float
        The sample's mean radius, in the units of the radii given.
    """

    params: SuperformulaParams
    angle_deg: float
    rms_percent: float
    mean_radius: float

    def curve(self, n_angles: int) -> NDArray[np.float64]:
        """The fitted shape in the sample's frame.

        Parameters
        ----------
        n_angles : int
            Rays, at :func:`rockscan.core.polar.polar_angles`.

        Returns
        -------
        radii : (n_angles,) ndarray of float
            About the shape's centroid, turned by ``angle_deg`` and scaled to the
            sample's mean radius.
        """
        return _centered_model(self.params, math.radians(self.angle_deg), n_angles) * self.mean_radius


@one_blas_thread
def fit_superformula(
    radii: ArrayLike,
    *,
    rng: np.random.Generator | int | None = None,
    config: FitConfig | None = None,
) -> FitResult:
    """Fit Superformula parameters and a rotation to an outline.

    Parameters
    ----------
    radii : (n_angles,) array_like of float
        Radii about the outline's area centroid at
        :func:`rockscan.core.polar.polar_angles` (as :func:`rockscan.run.pipeline.measure_rocks`
        returns them), any scale; at least 16 rays.
    rng : numpy.random.Generator, int or None
        Source of the random restarts.
    config : FitConfig, optional

    Returns
    -------
    FitResult

    Raises
    ------
    ParameterError
        If the radii are not a 1-D array of at least 16 finite, non-negative
        numbers with a positive mean.

    Notes
    -----
    1. Global search: the sample, resampled to 128 rays, is compared with a bank
       of shapes (every ``m`` up to ``m_max``; ``n1, n2, n3`` on a log grid from
       0.25 to 40; aspects ``b/a`` of 1, 0.75, 0.55, 0.4 with ``n2 = n3``) at
       every rotation, by FFT cross-correlation of the mean-normalised
       centroid-frame radii.
    2. Local least squares (:func:`scipy.optimize.least_squares`, trust region
       with bounds, analytic Jacobian, soft-L1 loss of scale 2% of the mean
       radius) over ``log n1, log n2, log n3``, the rotation, the origin, the
       size and, for the free-aspect model, ``log b``. They start from the
       ``n_best`` best bank shapes of the best model, the best shape of each of
       the next ``n_starts - 1`` models, each free-aspect start again with
       ``a = b``, and, for an odd ``m``, the two most promising placements of
       the formula's kink on another lobe. A fitted aspect within 5% of 1 is
       refitted with ``a = b``.
    3. The fit with the least centroid-frame RMS error wins; a free aspect or
       ``m1 != m2`` only if it beats the best ``a = b``, ``m1 = m2`` fit by the
       factor ``gain``. Above ``good_percent``, ``restarts`` random restarts
       around the winner (exponents jittered by a factor ``exp(N(0, 0.5))``)
       and ``m2 = m1 +- 1, 2`` are tried.

    The parameters need not be unique (very different exponents can draw
    nearly the same curve); the curve is what is fitted.

    Examples
    --------
    >>> from rockscan.core.superformula import shape_radii
    >>> true = SuperformulaParams(5, 5, 2.0, 7.0, 7.0)
    >>> fit = fit_superformula(shape_radii(true, 360), rng=0)
    >>> fit.rms_percent < 0.5
    True
    """
    radii, mean_radius = _fit_iv(radii)
    config = config or FitConfig()
    rng = np.random.default_rng(rng)
    sample = radii / mean_radius
    theta = polar_angles(radii.size)
    points = np.column_stack([sample * np.cos(theta), sample * np.sin(theta)])[sample > 0]

    run = functools.partial(_fit_from, points, sample, config)
    starts = _global_search(sample, config)
    # A free aspect may settle in a poor basin where a = b would not: try both.
    starts += [(replace(start, b=1.0), False) for start, free_b in starts if free_b]
    fits = [run(start, free_b) for start, free_b in starts]
    # An odd m draws a kink where theta wraps; the same lobes with the kink on
    # another lobe are other local minima (turn by 2 pi j / m, swap n2 and n3).
    for _, local, free_b in sorted(fits, key=lambda f: f[0])[:2]:
        for sibling in _siblings(points, local, free_b)[:2]:
            fits.append(run(sibling, free_b))
    best_rms, best = _select(fits, config.gain)
    best_rms, best = _polish(run, best_rms, best, config, rng)
    params = _rounded(best.params)
    angle_deg = _canonical_angle(params, math.degrees(best.alpha))
    return FitResult(
        params=params,
        angle_deg=angle_deg,
        rms_percent=_rms_percent(sample, params, math.radians(angle_deg)),
        mean_radius=mean_radius,
    )


def _fit_from(
    points: NDArray[np.float64], sample: NDArray[np.float64], config: FitConfig, start: _Local, free_b: bool
) -> tuple[float, _Local, bool]:
    """Refine one start: (RMS percent, fit, whether the aspect stayed free)."""
    local = _refine(points, start, free_b=free_b, robust=config.robust)
    if free_b and abs(math.log(local.b)) < _ASPECT_SNAP:
        # An aspect within a few percent of 1 is no elongation: only the
        # needle tips of a spiky shape, which no photo shows, can tell it.
        local, free_b = _refine(points, replace(local, b=1.0), free_b=False, robust=config.robust), False
    rms = _rms_percent(sample, local.params, local.alpha)
    if config.robust and rms > config.good_percent:
        # The soft-L1 loss lets far rays go; where the curve really reaches
        # them (needle tips of a spiky shape), plain least squares from
        # there fits them too. The RMS error decides, as it does everywhere.
        plain = _refine(points, local, free_b=free_b, robust=False)
        plain_rms = _rms_percent(sample, plain.params, plain.alpha)
        if plain_rms < rms:
            local, rms = plain, plain_rms
    return rms, local, free_b


def _polish(
    run: Callable[[_Local, bool], tuple[float, _Local, bool]],
    best_rms: float,
    best: _Local,
    config: FitConfig,
    rng: np.random.Generator,
) -> tuple[float, _Local]:
    """Restarts from jittered exponents, then unequal m, while the fit is not yet good."""
    if best_rms > config.good_percent:
        free_b = best.b != 1.0
        for _ in range(config.restarts):
            jitter = rng.normal(0.0, 0.5, 3)
            log_n = np.clip(np.array(best.log_n) + jitter, *np.log(_N_BOUNDS))
            rms, local, _ = run(replace(best, log_n=tuple(log_n)), free_b)
            if rms < best_rms:
                best_rms, best = rms, local
    if config.unequal_m and best_rms > config.good_percent:
        for m2 in (best.m1 - 2, best.m1 - 1, best.m1 + 1, best.m1 + 2):
            if 1 <= m2 <= config.m_max:
                rms, local, _ = run(replace(best, m2=m2), best.b != 1.0)
                if rms < config.gain * best_rms:
                    best_rms, best = rms, local
    return best_rms, best


def _select(fits: list[tuple[float, _Local, bool]], gain: float) -> tuple[float, _Local]:
    """The best plain fit, unless a free-aspect fit beats it by the factor ``gain``."""
    plain = [f for f in fits if not f[2]]
    best_rms, best, _ = min(plain or fits, key=lambda f: f[0])
    for rms, local, free_b in fits:
        if free_b and rms < gain * best_rms:
            best_rms, best = rms, local
    return best_rms, best


# ---------------------------------------------------------------- the fit's parts


@dataclass(frozen=True)
class _Local:
    """A fit in progress: shape, rotation (rad), origin and size in the sample frame."""

    m1: float
    m2: float
    log_n: tuple[float, float, float]
    b: float
    alpha: float
    origin: tuple[float, float]
    size: float

    @property
    def params(self) -> SuperformulaParams:
        n1, n2, n3 = np.exp(self.log_n)
        return SuperformulaParams(self.m1, self.m2, n1, n2, n3, 1.0, self.b)


def _fit_iv(radii: ArrayLike) -> tuple[NDArray[np.float64], float]:
    try:
        radii = np.asarray(radii, dtype=np.float64)
    except (TypeError, ValueError):
        raise ParameterError("radii must be numbers: the outline's radius along each ray") from None
    if radii.ndim != 1 or radii.size < 16:
        raise ParameterError(
            f"radii must be a 1-D array of at least 16 rays (one outline), got shape {radii.shape}"
        )
    if not np.all(np.isfinite(radii)) or np.any(radii < 0) or radii.mean() <= 0:
        raise ParameterError("radii must be finite and non-negative with a positive mean")
    if np.count_nonzero(radii) < 16:
        raise ParameterError(
            "the outline must surround its centroid: at least 16 rays need a positive radius"
        )
    return radii, float(radii.mean())


def _centered_model(params: SuperformulaParams, alpha: float, n_angles: int) -> NDArray[np.float64]:
    """A shape turned by ``alpha`` (rad) about its centroid, mean radius 1, at n_angles rays.

    Turning the shape and then re-centring is exact for any angle: the outline
    is drawn at ``theta`` with the formula read at ``(theta - alpha) mod 2 pi``.
    """
    theta = polar_angles(n_angles)
    with np.errstate(over="ignore"):
        about_origin = params.radii(np.mod(theta - alpha, _TWO_PI))
    # A pole between the rays shows as an absurd spike: no usable model (the
    # search moves on), rather than an overflow in the centroid.
    if np.any(degenerate_rays(about_origin)):
        return np.zeros(n_angles)
    centered, _ = recenter_radii(about_origin)
    mean = centered.mean()
    return centered / mean if mean > 0 else centered


def _rms_percent(sample: NDArray[np.float64], params: SuperformulaParams, alpha: float) -> float:
    model = _centered_model(params, alpha, sample.size)
    return float(np.sqrt(np.mean((sample / sample.mean() - model) ** 2)) * 100.0)


@lru_cache(maxsize=4)
def _bank(m_max: int, aspect: bool) -> tuple[NDArray[np.float64], ...]:
    """The global search's shapes: parameters, centroid-frame radii spectra, centroids.

    Returns (params (k, 6): m, n1, n2, n3, b, mean; spectra (k, n_freq); norms (k,);
    centroids (k, 2) as fractions of the mean radius).
    """
    theta = polar_angles(_BANK_ANGLES)
    rows = []
    for m in range(1, m_max + 1):
        for n1 in _BANK_N:
            for n2 in _BANK_N:
                for n3 in _BANK_N:
                    rows.append((m, n1, n2, n3, 1.0))
                if aspect:
                    for b in _BANK_ASPECT:
                        rows.append((m, n1, n2, n2, b))
    table = np.array(rows)
    m, n1, n2, n3, b = (table[:, i : i + 1] for i in range(5))
    log_r = log_superformula(theta, m, m, n1, n2, n3, 1.0, b)
    # Shapes far from rock-like (needle tips, radius ratios over 20) only
    # slow the search down.
    keep = (log_r.max(axis=1) - log_r.min(axis=1)) < math.log(20.0)
    table, radii = table[keep], np.exp(log_r[keep])
    centered, centroids = _recenter_rows(radii, theta)
    good = np.all(centered > 0, axis=1)
    table, centered, centroids = table[good], centered[good], centroids[good]
    mean = centered.mean(axis=1)
    normalized = centered / mean[:, None]
    spectra = np.fft.rfft(normalized, axis=1)
    norms = np.einsum("kn,kn->k", normalized, normalized)
    out = (np.column_stack([table, mean]), spectra, norms, centroids / mean[:, None])
    for arr in out:
        arr.setflags(write=False)
    return out


def _recenter_rows(
    radii: NDArray[np.float64], theta: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Rows of radii re-sampled about their area centroids, and the centroids.

    Interpolation along the outline where it is star-shaped about its centroid
    (nearly always); :func:`rockscan.core.polar.recenter_radii` elsewhere.
    """
    x, y = radii * np.cos(theta), radii * np.sin(theta)
    _, cx, cy = polygon_area_centroids(x, y)
    centered = radii.copy()
    moved = np.flatnonzero(np.hypot(cx, cy) > 1e-9 * radii.mean(axis=1))
    dx, dy = x[moved] - cx[moved, None], y[moved] - cy[moved, None]
    phi = np.unwrap(np.arctan2(dy, dx), axis=1)
    rho = np.hypot(dx, dy)
    star = np.all(np.diff(phi, axis=1) > 0, axis=1) & (phi[:, -1] - phi[:, 0] < _TWO_PI)
    for j, i in enumerate(moved):
        if star[j]:
            centered[i] = np.interp(theta, phi[j], rho[j], period=_TWO_PI)
        else:
            centered[i] = recenter_radii(radii[i])[0]
    return centered, np.column_stack([cx, cy])


def _global_search(sample: NDArray[np.float64], config: FitConfig) -> list[tuple[_Local, bool]]:
    """Starts for the local fits: the ``n_best`` best bank shapes of the best model
    (m, aspect free or not), then the best shape of each next model, ``n_starts`` models."""
    table, spectra, norms, centroids = _bank(config.m_max, config.aspect)
    coarse = resample_radii(sample, _BANK_ANGLES)
    coarse = coarse / coarse.mean()
    # SSE(k, j) = |s|^2 + |z_k|^2 - 2 sum_i s_i z_k[i - j]: sample = shape k turned by j rays.
    corr = np.fft.irfft(np.fft.rfft(coarse)[None, :] * np.conj(spectra), n=_BANK_ANGLES, axis=1)
    shift = np.argmax(corr, axis=1)
    sse = norms - 2.0 * corr[np.arange(len(corr)), shift]
    model = table[:, 0] * 2 + (table[:, 4] != 1.0)
    order = np.argsort(sse)
    chosen = list(order[model[order] == model[order[0]]][: config.n_best])
    for k in order:
        if len(chosen) >= config.n_best + config.n_starts - 1:
            break
        if model[k] not in {model[j] for j in chosen}:
            chosen.append(k)
    starts: list[tuple[_Local, bool]] = []
    for k in chosen:
        m, n1, n2, n3, b, mean = table[k]
        alpha = _TWO_PI * shift[k] / _BANK_ANGLES
        rot = np.array([[math.cos(alpha), -math.sin(alpha)], [math.sin(alpha), math.cos(alpha)]])
        origin = -(rot @ centroids[k])
        start = _Local(m, m, tuple(np.log([n1, n2, n3])), b, alpha, tuple(origin), 1.0 / mean)
        starts.append((start, bool(b != 1.0)))
    return starts


def _siblings(points: NDArray[np.float64], local: _Local, free_b: bool) -> list[_Local]:
    """Starts with the kink of an odd-m fit moved to each other lobe, best first.

    Turning by ``2 pi / m`` swaps the cosine and sine terms, so ``n2`` and
    ``n3`` swap at odd steps. Ranked by the robust cost at the start.
    """
    m = local.m1
    if m != local.m2 or m != round(m) or round(m) % 2 == 0:
        return []
    starts = []
    for j in range(1, round(m)):
        n1, n2, n3 = local.log_n
        log_n = (n1, n3, n2) if j % 2 else (n1, n2, n3)
        starts.append(replace(local, log_n=log_n, alpha=local.alpha + _TWO_PI * j / m))
    costs = []
    for start in starts:
        problem = _Problem(points, start.m1, start.m2, start.b, free_b=False)
        x = np.array([*start.log_n, start.alpha, *start.origin, math.log(start.size)])
        res = problem.residuals(x)
        costs.append(float(np.sum(np.sqrt(1.0 + (res / _LOSS_SCALE) ** 2) - 1.0)))
    return [starts[i] for i in np.argsort(costs)]


class _Problem:
    """Residuals ``|p_i - o| - s F((phi_i - alpha) mod 2 pi)`` and their Jacobian.

    ``x = [log n1, log n2, log n3, alpha, ox, oy, log s(, log b)]``; ``F`` is the
    Superformula with ``a = 1`` evaluated in log space, so exponents in the
    thousands stay finite; the Jacobian is analytic. The optimiser asks for
    residuals at every trial step and for the Jacobian only at accepted ones,
    so the Jacobian reuses the residuals' intermediate arrays.
    """

    def __init__(self, points: NDArray[np.float64], m1: float, m2: float, b: float, free_b: bool) -> None:
        self.points, self.m1, self.m2, self.b, self.free_b = points, m1, m2, b, free_b
        self._x: NDArray[np.float64] | None = None
        self._parts: dict[str, NDArray[np.float64]] = {}

    def residuals(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        if self._x is not None and np.array_equal(x, self._x):
            return self._parts["res"]
        n1, n2, n3 = np.exp(x[:3])
        log_b = x[7] if self.free_b else math.log(self.b)
        d = self.points - x[4:6]
        rho_sq = np.maximum(np.einsum("ij,ij->i", d, d), 1e-24)
        rho = np.sqrt(rho_sq)
        psi = np.mod(np.arctan2(d[:, 1], d[:, 0]) - x[3], _TWO_PI)
        k1, k2 = self.m1 * psi / 4.0, self.m2 * psi / 4.0
        cos1, sin2 = np.cos(k1), np.sin(k2)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            log_cos = np.log(np.abs(cos1))
            log_sin = np.log(np.abs(sin2)) - log_b
            term_a, term_b = n2 * log_cos, n3 * log_sin
            total = np.logaddexp(term_a, term_b)
            log_f = -total / n1
        inside = np.abs(log_f) < _LOG_CLIP
        model = math.exp(x[6]) * np.exp(np.clip(log_f, -_LOG_CLIP, _LOG_CLIP))
        self._x = x.copy()
        self._parts = {
            "res": rho - model,
            "model": model,
            "inside": inside,
            "d": d,
            "rho": rho,
            "rho_sq": rho_sq,
            "k1": k1,
            "k2": k2,
            "cos1": cos1,
            "sin2": sin2,
            "log_cos": log_cos,
            "log_sin": log_sin,
            "term_a": term_a,
            "term_b": term_b,
            "total": total,
            "log_b": np.array(log_b),
        }
        return self._parts["res"]

    def jacobian(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        self.residuals(x)
        p = self._parts
        n1, n2, n3 = np.exp(x[:3])
        term_a, term_b, total = p["term_a"], p["term_b"], p["total"]
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            w_a = np.exp(term_a - total)
            w_b = np.exp(term_b - total)
            # w_a tan(k1) and w_b cot(k2), written to stay finite at the zeros of cos and sin.
            tan_a = (
                np.sign(p["cos1"])
                * np.sin(p["k1"])
                * np.exp(np.minimum(term_a - total - p["log_cos"], _LOG_CLIP))
            )
            cot_b = (
                np.sign(p["sin2"])
                * np.cos(p["k2"])
                * np.exp(np.minimum(term_b - total - p["log_sin"] - p["log_b"], _LOG_CLIP))
            )
            g_n = np.stack([total / n1, -w_a * term_a / n1, -w_b * term_b / n1])
            g_psi = (n2 * self.m1 / 4.0 * tan_a - n3 * self.m2 / 4.0 * cot_b) / n1
            g_b = w_b * n3 / n1
        model, d, rho, rho_sq = p["model"], p["d"], p["rho"], p["rho_sq"]
        scale = np.where(p["inside"], model, 0.0)
        g_n = np.nan_to_num(g_n, nan=0.0, posinf=0.0, neginf=0.0)
        g_psi = np.nan_to_num(g_psi, nan=0.0, posinf=0.0, neginf=0.0)
        jac = np.empty((len(rho), 8 if self.free_b else 7))
        jac[:, :3] = -(scale * g_n).T
        jac[:, 3] = scale * g_psi
        jac[:, 4] = -d[:, 0] / rho - scale * g_psi * d[:, 1] / rho_sq
        jac[:, 5] = -d[:, 1] / rho + scale * g_psi * d[:, 0] / rho_sq
        jac[:, 6] = -model
        if self.free_b:
            jac[:, 7] = -scale * np.nan_to_num(g_b, nan=0.0)
        return jac


def _refine(points: NDArray[np.float64], start: _Local, *, free_b: bool, robust: bool) -> _Local:
    """Local least squares of the radial distance about a free origin."""
    from scipy.optimize import least_squares

    lo_n, hi_n = np.log(_N_BOUNDS)
    x0 = [*start.log_n, start.alpha, *start.origin, math.log(start.size)]
    lower = [lo_n] * 3 + [-np.inf] * 4
    upper = [hi_n] * 3 + [np.inf] * 4
    if free_b:
        x0.append(math.log(start.b))
        lower.append(math.log(_B_BOUNDS[0]))
        upper.append(math.log(_B_BOUNDS[1]))
    lower_a, upper_a = np.array(lower), np.array(upper)
    x0 = np.clip(np.array(x0, dtype=np.float64), lower_a + 1e-9, upper_a - 1e-9)
    problem = _Problem(points, start.m1, start.m2, start.b, free_b)
    result = least_squares(
        problem.residuals,
        x0,
        jac=problem.jacobian,
        bounds=(lower_a, upper_a),
        loss="soft_l1" if robust else "linear",
        f_scale=_LOSS_SCALE,
        ftol=1e-6,
        xtol=1e-6,
        max_nfev=100,
    )
    x = result.x
    return _Local(
        start.m1,
        start.m2,
        (float(x[0]), float(x[1]), float(x[2])),
        float(math.exp(x[7])) if free_b else start.b,
        float(x[3]),
        (float(x[4]), float(x[5])),
        float(math.exp(x[6])),
    )


def _rounded(params: SuperformulaParams) -> SuperformulaParams:
    values = {k: round_significant(v, _DIGITS) for k, v in params.as_dict().items()}
    return SuperformulaParams(**values)


def _canonical_angle(params: SuperformulaParams, angle_deg: float) -> float:
    try:
        order = symmetry_order(shape_radii(params, 360))
    except ParameterError:
        order = 1
    # A turn a hair below a period is 0, as a match reports it (fold_angle); a
    # circle's fit keeps its turn of the ellipse's axes (order 1 here).
    return float(fold_angle(angle_deg, max(order, 1)))
