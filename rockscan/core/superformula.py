"""The Superformula of Gielis (2003), the paper's shape generator.

The radius at polar angle ``theta`` is::

    r(theta) = (|cos(m1*theta/4)/a|**n2 + |sin(m2*theta/4)/b|**n3) ** (-1/n1)

exactly as written in the paper and in the public interface. It is evaluated in
log space so that the large exponents of the paper's shapes (n = 1500) neither
underflow nor overflow.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from rockscan.core.errors import ParameterError
from rockscan.core.polar import polar_angles, recenter_radii

__all__ = [
    "SuperformulaParams",
    "log_superformula",
    "superformula",
]

_PARAM_NAMES = ("m1", "m2", "n1", "n2", "n3", "a", "b")


@dataclass(frozen=True)
class SuperformulaParams:
    """Parameters of one Superformula shape.

    Parameters
    ----------
    m1, m2 : float
        Angular frequencies of the cosine and sine terms.
    n1 : float
        Overall exponent; must be non-zero.
    n2, n3 : float
        Exponents of the cosine and sine terms.
    a, b : float
        Scales of the cosine and sine terms; must be positive. With ``a == b``
        they only scale the shape.

    Raises
    ------
    ParameterError
        If a value is not finite, ``n1 == 0`` or ``a``/``b`` are not positive.
    """

    m1: float
    m2: float
    n1: float
    n2: float
    n3: float
    a: float = 1.0
    b: float = 1.0

    def __post_init__(self) -> None:
        for name in _PARAM_NAMES:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
                raise ParameterError(f"Superformula parameter {name} must be a number, got {value!r}")
            value = float(value)
            if not math.isfinite(value):
                raise ParameterError(f"Superformula parameter {name} must be finite, got {value}")
            object.__setattr__(self, name, value)
        if self.n1 == 0:
            raise ParameterError("Superformula parameter n1 must be non-zero (it is the exponent -1/n1)")
        for name in ("a", "b"):
            if getattr(self, name) <= 0:
                raise ParameterError(
                    f"Superformula parameter {name} must be positive, got {getattr(self, name)}"
                )

    def radii(self, theta: ArrayLike) -> NDArray[np.float64]:
        """Evaluate the shape's radius at the angles ``theta`` (radians)."""
        return superformula(theta, **asdict(self))

    def as_dict(self) -> dict[str, float]:
        """The parameters as a plain ``{name: value}`` dictionary."""
        return asdict(self)

    @classmethod
    def names(cls) -> tuple[str, ...]:
        """Names of the parameters in their canonical order."""
        return _PARAM_NAMES


def superformula(
    theta: ArrayLike,
    m1: float,
    m2: float,
    n1: float,
    n2: float,
    n3: float,
    a: float = 1.0,
    b: float = 1.0,
) -> NDArray[np.float64]:
    """Radius of the Superformula at polar angles ``theta``.

    Parameters
    ----------
    theta : array_like of float
        Polar angles in radians, any shape.
    m1, m2, n1, n2, n3, a, b : float
        Shape parameters (see :class:`SuperformulaParams`).

    Returns
    -------
    radius : ndarray of float, same shape as ``theta``
        ``inf`` where both terms vanish (the curve is unbounded there).

    Raises
    ------
    ParameterError
        On invalid parameters, as :class:`SuperformulaParams`.

    Notes
    -----
    ``log r = -logaddexp(n2 log|cos(m1 theta/4)/a|, n3 log|sin(m2 theta/4)/b|) / n1``
    is exact and stays finite for exponents in the thousands, where the direct
    powers underflow to zero. A zero exponent makes its term 1, as ``x**0`` does.

    Examples
    --------
    >>> import numpy as np
    >>> superformula(np.array([0.0, 1.0]), 4, 4, 2, 2, 2)  # the unit circle
    array([1., 1.])
    """
    params = SuperformulaParams(m1, m2, n1, n2, n3, a, b)
    theta = np.asarray(theta, dtype=np.float64)
    if not np.all(np.isfinite(theta)):
        raise ParameterError("theta must be finite")
    p = params
    # Huge exponents overflow to inf, which callers refuse as an unbounded curve.
    with np.errstate(over="ignore"):
        return np.exp(log_superformula(theta, p.m1, p.m2, p.n1, p.n2, p.n3, p.a, p.b))


def log_superformula(
    theta: ArrayLike,
    m1: ArrayLike,
    m2: ArrayLike,
    n1: ArrayLike,
    n2: ArrayLike,
    n3: ArrayLike,
    a: ArrayLike = 1.0,
    b: ArrayLike = 1.0,
) -> NDArray[np.float64]:
    """Logarithm of the Superformula's radius, broadcast over angles and parameters.

    The one evaluation every part of rockscan uses (see :func:`superformula`'s
    Notes); parameters are not checked, so a table of shapes (one row each,
    angles along the columns) is evaluated at once.

    Parameters
    ----------
    theta : array_like of float
        Polar angles in radians.
    m1, m2, n1, n2, n3, a, b : array_like of float
        Shape parameters, broadcast against ``theta``.

    Returns
    -------
    log_radius : ndarray of float
        ``+inf`` where both terms vanish (an unbounded curve).
    """
    theta = np.asarray(theta, dtype=np.float64)
    n2, n3 = np.asarray(n2, dtype=np.float64), np.asarray(n3, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        log_cos = np.log(np.abs(np.cos(np.multiply(m1, theta) / 4.0))) - np.log(a)
        log_sin = np.log(np.abs(np.sin(np.multiply(m2, theta) / 4.0))) - np.log(b)
        # A zero exponent makes its term 1 (log 0), as x**0 does, even where x is 0.
        term_cos = np.where(n2 == 0, 0.0, n2 * log_cos)
        term_sin = np.where(n3 == 0, 0.0, n3 * log_sin)
        return -np.logaddexp(term_cos, term_sin) / n1


#: A radius this many times the median marks a pole that the rays straddle
#: (it shows as an absurd spike rather than inf).
MAX_SPIKE = 1e4


def degenerate_rays(radii: ArrayLike) -> NDArray[np.bool_]:
    """Rays at which a curve's radii cannot be a closed outline.

    Parameters
    ----------
    radii : (..., n) array_like of float
        One curve per row.

    Returns
    -------
    bad : (..., n) ndarray of bool
        Radii that are not finite, not positive, or over :data:`MAX_SPIKE`
        times their row's median.
    """
    radii = np.asarray(radii, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        spike = radii > MAX_SPIKE * np.nanmedian(radii, axis=-1, keepdims=True)
        return ~np.isfinite(radii) | (radii <= 0) | spike


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
    bad = np.flatnonzero(degenerate_rays(radii))
    if bad.size:
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


def round_significant(value: float, digits: int) -> float:
    """``value`` rounded to ``digits`` significant digits, as a spec writes it.

    Examples
    --------
    >>> round_significant(1650.0000000000002, 12)
    1650.0
    """
    return float(f"{value:.{digits}g}")
