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

from rockscan.errors import ParameterError

__all__ = ["SuperformulaParams", "superformula"]

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
    # Huge exponents overflow to inf, which callers refuse as an unbounded curve.
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        log_cos = np.log(np.abs(np.cos(params.m1 * theta / 4.0))) - math.log(params.a)
        log_sin = np.log(np.abs(np.sin(params.m2 * theta / 4.0))) - math.log(params.b)
        term_cos = np.zeros_like(theta) if params.n2 == 0 else params.n2 * log_cos
        term_sin = np.zeros_like(theta) if params.n3 == 0 else params.n3 * log_sin
        log_sum = np.logaddexp(term_cos, term_sin)
        return np.exp(-log_sum / params.n1)
