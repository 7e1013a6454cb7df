"""Polar radii: the coordinate convention, ray casting, centring, turning, symmetry."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rockscan.core.errors import ParameterError
from rockscan.core.polar import (
    contour_radii,
    fold_angle,
    polar_angles,
    polygon_centroid_xy,
    radii_about,
    radii_to_xy,
    recenter_radii,
    rotate_radii,
    rowcol_from_xy,
    symmetry_order,
    xy_from_rowcol,
)
from rockscan.core.superformula import SuperformulaParams, shape_radii


def test_angles_are_counter_clockwise_from_x():
    theta = polar_angles(8)
    np.testing.assert_allclose(theta, np.arange(8) * np.pi / 4)
    with pytest.raises(ParameterError, match="n_angles"):
        polar_angles(4)


def test_convention_with_an_asymmetric_shape():
    # A point right of the centroid is theta = 0; above it (smaller row) is 90 deg.
    centroid = np.array([50.0, 40.0])  # (row, col)
    pts = np.array([[50.0, 47.0], [43.0, 40.0], [50.0, 38.0], [55.0, 40.0]])
    xy = xy_from_rowcol(pts, centroid)
    np.testing.assert_allclose(xy, [[7, 0], [0, 7], [-2, 0], [0, -5]])
    np.testing.assert_allclose(np.degrees(np.arctan2(xy[:, 1], xy[:, 0])), [0, 90, 180, -90])
    np.testing.assert_allclose(rowcol_from_xy(xy, centroid), pts)
    # A kite, long to the right (7) and short below (5): radii read it back.
    radii = contour_radii(pts, centroid, 360)
    assert radii[0] == pytest.approx(7) and radii[90] == pytest.approx(7)
    assert radii[180] == pytest.approx(2) and radii[270] == pytest.approx(5)


def test_radii_of_a_polygonal_circle_and_square():
    t = np.linspace(0, 2 * np.pi, 4000, endpoint=False)
    circle = np.column_stack([30 - 12 * np.sin(t), 20 + 12 * np.cos(t)])
    np.testing.assert_allclose(contour_radii(circle, [30, 20], 360), 12, rtol=1e-5)
    square = np.array([[-1, -1], [-1, 1], [1, 1], [1, -1]], float) * 10  # (row, col)
    radii = contour_radii(square, [0, 0], 360)
    theta = polar_angles(360)
    expected = 10 / np.maximum(np.abs(np.cos(theta)), np.abs(np.sin(theta)))
    np.testing.assert_allclose(radii, expected, rtol=1e-12)
    # The outline's start and direction do not matter.
    np.testing.assert_allclose(contour_radii(np.roll(square[::-1], 2, axis=0), [0, 0], 360), radii)


def test_bad_contours_are_rejected():
    with pytest.raises(ParameterError, match="at least 3"):
        contour_radii(np.zeros((2, 2)), [0, 0], 360)
    with pytest.raises(ParameterError, match="finite"):
        contour_radii(np.array([[0, 0], [1, np.nan], [1, 1]]), [0, 0], 360)


@pytest.mark.parametrize(
    ("contour", "centroid", "n_angles", "message"),
    [
        # A (2, n) contour was read as n/2 points of scrambled coordinates, an
        # (n, 3) one as 3n/2 points: radii of a circle of 10 from 0.4 to 14.
        ("transposed", (0, 0), 360, r"must be \(n, 2\)"),
        ("three columns", (0, 0), 360, r"must be \(n, 2\)"),
        ("flat", (0, 0), 360, r"must be \(n, 2\)"),
        ("words", (0, 0), 360, "must be numbers"),
        ("circle", (0, 0, 0), 360, "two finite numbers"),
        ("circle", (np.nan, 0), 360, "two finite numbers"),
        ("circle", (0, 0), 10**10, "n_angles must be an integer from 8"),
        ("circle", (0, 0), 7.5, "n_angles must be an integer from 8"),
    ],
)
def test_contours_centroids_and_ray_counts_of_the_wrong_form_are_refused(
    contour, centroid, n_angles, message
):
    t = np.linspace(0, 2 * np.pi, 100, endpoint=False)
    circle = np.c_[10 * np.sin(t), 10 * np.cos(t)]
    given = {
        "transposed": circle.T,
        "three columns": np.c_[circle, circle[:, 0]],
        "flat": circle.ravel(),
        "words": "a circle",
        "circle": circle,
    }[contour]
    with pytest.raises(ParameterError, match=message):
        contour_radii(given, centroid, n_angles)
    np.testing.assert_allclose(contour_radii(circle, (0, 0), 360), 10.0, rtol=1e-3)


def test_polygon_centroid_of_a_triangle():
    tri = np.array([[0.0, 0.0], [3.0, 0.0], [0.0, 3.0]])
    np.testing.assert_allclose(polygon_centroid_xy(tri), [1.0, 1.0])
    np.testing.assert_allclose(polygon_centroid_xy(tri[::-1]), [1.0, 1.0])


def test_recenter_moves_the_origin_to_the_area_centroid():
    # The egg (m = 1) is not point-symmetric: its origin is not its centroid.
    raw = SuperformulaParams(1, 1, 0.75, 0.75, 0.75).radii(polar_angles(360))
    centered, offset = recenter_radii(raw)
    assert np.hypot(*offset) > 0.05
    np.testing.assert_allclose(polygon_centroid_xy(radii_to_xy(centered)), 0, atol=2e-3)
    # A symmetric shape stays put.
    star = SuperformulaParams(6, 6, 0.2, 1.7, 1.7).radii(polar_angles(360))
    again, offset = recenter_radii(star)
    np.testing.assert_allclose(offset, 0, atol=1e-12)
    np.testing.assert_allclose(again, star, rtol=1e-9)


@pytest.mark.parametrize("angle", [np.nan, np.inf, "ten", True])
def test_a_turn_that_is_no_finite_number_is_refused(angle):
    radii = shape_radii(SuperformulaParams(3, 3, 2, 2, 2), 360)
    with pytest.raises(ParameterError, match="angle_deg must be a finite number"):
        rotate_radii(radii, angle)


def test_a_turn_and_the_same_turn_plus_whole_turns_agree():
    radii = shape_radii(SuperformulaParams(5, 5, 2, 7, 7), 360)
    np.testing.assert_allclose(rotate_radii(radii, -10.25), rotate_radii(radii, 349.75), atol=1e-12)
    np.testing.assert_allclose(rotate_radii(radii, 720.5 + 1e6 * 360), rotate_radii(radii, 0.5), atol=1e-9)


@given(shift=st.integers(-720, 720))
def test_rotate_by_whole_steps_is_a_shift(shift):
    radii = shape_radii(SuperformulaParams(5, 5, 2, 7, 7), 360)
    np.testing.assert_array_equal(rotate_radii(radii, float(shift)), np.roll(radii, shift))


@given(angle=st.floats(0, 360))
def test_rotate_by_any_angle_samples_the_turned_curve(angle):
    # A band-limited outline turns exactly: r(theta - alpha).
    theta = polar_angles(360)
    radii = 1 + 0.2 * np.cos(3 * theta) + 0.1 * np.sin(2 * theta + 0.3)
    alpha = np.radians(angle)
    expected = 1 + 0.2 * np.cos(3 * (theta - alpha)) + 0.1 * np.sin(2 * (theta - alpha) + 0.3)
    np.testing.assert_allclose(rotate_radii(radii, angle), expected, atol=1e-12)


@pytest.mark.parametrize(
    ("params", "order"),
    [
        ((0, 0, 1, 1, 1), 0),
        ((3, 3, 1500, 1500, 1500), 3),  # odd m, yet 3-fold: theta/4 inside the formula
        ((6, 6, 60, 55, 10), 3),  # m = 6 with n2 != n3: only 3-fold
        ((6, 6, 0.2, 1.7, 1.7), 6),
        ((5, 5, 2, 7, 7), 5),
        ((1, 1, 0.75, 0.75, 0.75), 1),
        ((4, 4, 2, 2, 2, 1, 0.6), 2),
    ],
)
def test_symmetry_is_read_from_the_radii(params, order):
    radii = shape_radii(SuperformulaParams(*params), 360)
    assert symmetry_order(radii) == order
    if order >= 1:
        # The shape really is unchanged by a turn of 360/order degrees.
        np.testing.assert_allclose(rotate_radii(radii, 360 / max(order, 1)), radii, atol=5e-3)


@settings(max_examples=30, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    dx=st.floats(-0.3, 0.3),
    dy=st.floats(-0.3, 0.3),
)
def test_radii_about_a_new_centre_are_contour_radii_from_there(seed, dx, dy):
    # A smooth random outline, and its radii seen from a point inside it.
    theta = polar_angles(120)
    rng = np.random.default_rng(seed)
    radii = 1.0 + 0.15 * np.cos(2 * theta + rng.uniform(0, 6)) + 0.1 * np.sin(3 * theta + rng.uniform(0, 6))
    xy = np.column_stack([radii * np.cos(theta), radii * np.sin(theta)])
    # In (row, col) about a frame centre at (0, 0): the new centre is at row -dy, col dx.
    expected = contour_radii(rowcol_from_xy(xy, (0.0, 0.0)), (-dy, dx), 120)
    got = radii_about(radii[None], np.array([[dx, dy]]))[0]
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-12)


def test_radii_about_the_origin_change_nothing():
    radii = shape_radii(SuperformulaParams(3, 3, 2, 5, 5), 90)
    np.testing.assert_allclose(radii_about(radii[None], np.zeros((1, 2)))[0], radii, rtol=1e-12)


@pytest.mark.parametrize(
    ("angle", "order", "folded"),
    [
        (130.0, 3, 10.0),
        (-1e-6, 3, 0.0),
        (119.99999, 3, 0.0),
        (45.0, 0, 0.0),
        (350.0, 1, 350.0),
        (-30.0, 4, 60.0),
    ],
)
def test_fold_angle_gives_the_smallest_equivalent_turn(angle, order, folded):
    assert float(fold_angle(angle, order)) == pytest.approx(folded, abs=1e-9)


def test_fold_angle_keeps_an_unknown_turn_unknown_and_folds_arrays():
    out = fold_angle([np.nan, 250.0, 250.0], [3, 3, 0])
    assert np.isnan(out[0]) and out[1:].tolist() == pytest.approx([10.0, 0.0])


@pytest.mark.parametrize(
    "radii", [np.zeros(0), np.ones((2, 360)), np.full(360, np.nan), -np.ones(360), ["a"] * 8]
)
@pytest.mark.parametrize("func", [symmetry_order, recenter_radii, lambda r: rotate_radii(r, 10.0)])
def test_radii_that_are_no_outline_are_a_parameter_error(radii, func):
    # numpy's FFT and broadcasting errors escaped, and nan or negative radii had an order.
    with pytest.raises(ParameterError, match="radii must"):
        func(radii)
