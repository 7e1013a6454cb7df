"""Outline polygons for reports: simplification, orientation, moments and sizes."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from rockscan.core.errors import ParameterError
from rockscan.core.measure import outline_sizes, polygon_moments, report_outline_xy
from rockscan.core.outline import polygon_area_centroid, trace_outline


def screen_signed_area(xy):
    x, y = np.asarray(xy, dtype=float).T
    return 0.5 * np.sum(x * np.roll(-y, -1) - np.roll(x, -1) * -y)


def test_moments_of_a_rectangle_are_exact():
    # 6 x 2 rectangle with corners (1, 3) .. (7, 5): area 12, centroid (4, 4).
    xy = np.array([[1.0, 3.0], [7.0, 3.0], [7.0, 5.0], [1.0, 5.0]])
    for pts in (xy, xy[::-1]):
        area, centroid, cov = polygon_moments(pts)
        assert area == pytest.approx(12.0, rel=1e-12)
        np.testing.assert_allclose(centroid, (4.0, 4.0), rtol=1e-12)
        np.testing.assert_allclose(cov, [[36.0 / 12, 0.0], [0.0, 4.0 / 12]], atol=1e-12)
    sizes = outline_sizes(xy, 2.0)
    assert sizes.area_mm2 == pytest.approx(3.0, rel=1e-12)
    assert sizes.equivalent_diameter_mm == pytest.approx(np.sqrt(48.0 / np.pi) / 2.0, rel=1e-12)
    # The ellipse of equal second moments: 4*sqrt(36/12) = 2*sqrt(12) long, 4/sqrt(3) wide.
    assert sizes.major_axis_mm == pytest.approx(4.0 * np.sqrt(3.0) / 2.0, rel=1e-12)
    assert sizes.minor_axis_mm == pytest.approx(4.0 * np.sqrt(1.0 / 3.0) / 2.0, rel=1e-12)


def test_a_turned_rectangle_has_the_same_covariance_eigenvalues():
    xy = np.array([[0.0, 0.0], [6.0, 0.0], [6.0, 2.0], [0.0, 2.0]])
    t = np.deg2rad(37.0)
    rot = np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])
    _, _, cov = polygon_moments(xy @ rot.T + 500.0)
    np.testing.assert_allclose(np.linalg.eigvalsh(cov), [4.0 / 12, 36.0 / 12], rtol=1e-9)


def test_a_sampled_ellipse_has_its_axes():
    theta = np.linspace(0, 2 * np.pi, 20000, endpoint=False)
    xy = np.column_stack([30 * np.cos(theta), 10 * np.sin(theta)])
    sizes = outline_sizes(xy, 1.0)
    assert sizes.major_axis_mm == pytest.approx(60.0, rel=1e-6)
    assert sizes.minor_axis_mm == pytest.approx(20.0, rel=1e-6)


@given(
    n=st.integers(3, 40),
    seed=st.integers(0, 2**32 - 1),
    reverse=st.booleans(),
)
def test_the_report_outline_is_the_same_polygon_counter_clockwise(n, seed, reverse):
    # A random star-shaped polygon in (row, col), either orientation.
    rng = np.random.default_rng(seed)
    theta = np.sort(rng.uniform(0, 2 * np.pi, n))
    radius = rng.uniform(5, 50, n)
    rowcol = np.column_stack([100 + radius * np.sin(theta), 200 + radius * np.cos(theta)])
    if reverse:
        rowcol = rowcol[::-1]
    xy = report_outline_xy(rowcol, min_points=64, tolerance=1e-9)
    assert len(xy) >= 64 and screen_signed_area(xy) > 0
    area, centroid = polygon_area_centroid(xy)
    area_in, centroid_in = polygon_area_centroid(rowcol[:, ::-1])
    assert area == pytest.approx(area_in, rel=1e-9)
    np.testing.assert_allclose(centroid, centroid_in, atol=1e-9)


def test_a_traced_disc_is_simplified_within_its_area():
    rr, cc = np.mgrid[0:400, 0:400]
    disc = (rr - 200.3) ** 2 + (cc - 190.6) ** 2 <= 150.0**2
    outline = trace_outline(disc)
    xy = report_outline_xy(outline.contour_rowcol)
    assert 64 <= len(xy) < len(outline.contour_rowcol) / 4
    area, centroid = polygon_area_centroid(xy)
    assert area == pytest.approx(outline.area_px, rel=0.002)
    np.testing.assert_allclose(centroid, outline.centroid_rowcol[::-1], atol=0.05)


def test_bad_inputs_name_the_parameter():
    with pytest.raises(ParameterError, match="contour_rowcol"):
        report_outline_xy(np.zeros((2, 2)))
    with pytest.raises(ParameterError, match="px_per_mm"):
        outline_sizes([[0, 0], [1, 0], [0, 1]], 0.0)
    with pytest.raises(ParameterError, match="no area"):
        polygon_moments([[0, 0], [1, 1], [2, 2]])
