"""Superformula: exact values, validation, and numerical robustness."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from rockscan.core.errors import ParameterError
from rockscan.core.superformula import SuperformulaParams, superformula


def _direct(theta, m1, m2, n1, n2, n3, a=1.0, b=1.0):
    """The formula exactly as printed, for moderate exponents."""
    return (np.abs(np.cos(m1 * theta / 4) / a) ** n2 + np.abs(np.sin(m2 * theta / 4) / b) ** n3) ** (-1 / n1)


def test_circle_and_ellipse_are_exact():
    theta = np.linspace(0, 2 * np.pi, 37)
    np.testing.assert_allclose(superformula(theta, 4, 4, 2, 2, 2), 1.0, rtol=1e-15)
    # m = 4, n = 2 is an ellipse with semi-axes a and b.
    r = superformula(theta, 4, 4, 2, 2, 2, a=2.0, b=0.5)
    x, y = r * np.cos(theta), r * np.sin(theta)
    np.testing.assert_allclose((x / 2.0) ** 2 + (y / 0.5) ** 2, 1.0, rtol=1e-12)


def test_known_values_of_the_papers_shapes():
    # theta = 0: cos term is 1, sin term 0, so r = 1 for a = b = 1.
    for params in [(3, 3, 1500, 1500, 1500), (6, 6, 60, 55, 10), (6, 6, 0.2, 1.7, 1.7)]:
        assert superformula(np.array([0.0]), *params)[0] == pytest.approx(1.0, abs=1e-15)
    # Six-pointed star at theta = pi/6 (phi = pi/4): (2 * 2**-0.85)**-5.
    expected = (2 * 2 ** (-1.7 / 2)) ** -5
    assert superformula(np.array([np.pi / 6]), 6, 6, 0.2, 1.7, 1.7)[0] == pytest.approx(expected, rel=1e-12)


@given(
    m=st.integers(0, 8),
    n1=st.floats(0.2, 30),
    n2=st.floats(0.2, 30),
    n3=st.floats(0.2, 30),
    a=st.floats(0.5, 2),
    b=st.floats(0.5, 2),
)
def test_log_space_equals_the_printed_formula(m, n1, n2, n3, a, b):
    theta = np.linspace(0.01, 2 * np.pi - 0.01, 50)
    direct = _direct(theta, m, m, n1, n2, n3, a, b)
    ok = np.isfinite(direct)
    np.testing.assert_allclose(superformula(theta, m, m, n1, n2, n3, a, b)[ok], direct[ok], rtol=1e-9)


def test_large_exponents_do_not_underflow():
    theta = np.linspace(0, 2 * np.pi, 721)
    r = superformula(theta, 3, 3, 1500, 1500, 1500)
    assert np.all(np.isfinite(r)) and r.min() >= 1.0 - 1e-12
    # n -> infinity makes the curve 1 / max(|cos|, |sin|) of m*theta/4.
    phi = 3 * theta / 4
    limit = 1 / np.maximum(np.abs(np.cos(phi)), np.abs(np.sin(phi)))
    np.testing.assert_allclose(r, limit, rtol=1e-3)
    # Exponents far past float range still give a finite curve.
    assert np.all(np.isfinite(superformula(theta, 4, 4, 1e5, 1e5, 1e5)))


def test_unbounded_points_blow_up():
    # m1 = 2, m2 = 4: cos(theta/2) and sin(theta) both vanish at theta = pi
    # (to within the rounding of pi), so the radius is unbounded there.
    assert superformula(np.array([np.pi]), 2, 4, 1, 1, 1)[0] > 1e12
    # A zero term (sin 0) is handled in log space without floating-point errors.
    with np.errstate(all="raise"):
        assert superformula(np.array([0.0]), 4, 4, 2, 2, 2)[0] == 1.0


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"n1": 0}, "n1 must be non-zero"),
        ({"a": 0}, "a must be positive"),
        ({"b": -1}, "b must be positive"),
        ({"n2": float("nan")}, "n2 must be finite"),
        ({"m1": float("inf")}, "m1 must be finite"),
        ({"n3": "3"}, "n3 must be a number"),
        ({"m2": True}, "m2 must be a number"),
    ],
)
def test_invalid_parameters_name_the_problem(kwargs, message):
    values = {"m1": 3, "m2": 3, "n1": 1, "n2": 1, "n3": 1, **kwargs}
    with pytest.raises(ParameterError, match=message):
        SuperformulaParams(**values)
    with pytest.raises(ParameterError, match=message):
        superformula(np.zeros(3), **values)


def test_non_finite_theta_is_rejected():
    with pytest.raises(ParameterError, match="theta must be finite"):
        superformula(np.array([0.0, np.nan]), 4, 4, 2, 2, 2)


def test_params_round_trip_and_radii_method():
    p = SuperformulaParams(5, 5, 2, 7, 7, a=1.0, b=1.0)
    assert SuperformulaParams(**p.as_dict()) == p
    assert SuperformulaParams.names() == ("m1", "m2", "n1", "n2", "n3", "a", "b")
    theta = np.linspace(0, 6, 11)
    np.testing.assert_array_equal(p.radii(theta), superformula(theta, 5, 5, 2, 7, 7))
