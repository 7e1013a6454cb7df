"""Outlines: sub-pixel tracing, centroid and area, the working-image map, and the
farthest-crossing rule for outlines a ray crosses more than once."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from rockscan.core.errors import NoRockFoundError, ParameterError
from rockscan.core.outline import polygon_area_centroid, trace_outline, work_to_photo
from rockscan.core.polar import contour_radii, polar_angles


def disc_coverage(shape, center_rowcol, radius, supersample=16):
    """Exact-enough area coverage of a disc: the share of each pixel inside it."""
    rows, cols = shape
    offsets = (np.arange(supersample) + 0.5) / supersample - 0.5
    rr = np.arange(rows)[:, None, None, None] + offsets[None, None, :, None]
    cc = np.arange(cols)[None, :, None, None] + offsets[None, None, None, :]
    inside = (rr - center_rowcol[0]) ** 2 + (cc - center_rowcol[1]) ** 2 <= radius**2
    return inside.mean(axis=(2, 3)).astype(np.float32)


# ---------------------------------------------------------------- tiny exact cases


def test_polygon_area_and_centroid_are_exact():
    square = np.array([[0, 0], [0, 4], [4, 4], [4, 0]], float)  # (row, col)
    area, centroid = polygon_area_centroid(square)
    assert area == 16.0
    np.testing.assert_array_equal(centroid, [2.0, 2.0])
    # Orientation does not change either; a right triangle's centroid is a third in.
    triangle = np.array([[0, 0], [0, 6], [3, 0]], float)
    area, centroid = polygon_area_centroid(triangle[::-1])
    assert area == 9.0
    np.testing.assert_allclose(centroid, [1.0, 2.0], atol=1e-12)
    # No area: the vertex mean.
    assert polygon_area_centroid(np.array([[1, 1], [2, 2], [3, 3]], float))[0] == 0.0


def test_work_to_photo_maps_pixel_centres():
    # Working pixel 0 covers photo pixels [0, 4): its centre is 1.5.
    np.testing.assert_allclose(work_to_photo([[0, 0], [1, 2]], 4.0), [[1.5, 1.5], [5.5, 9.5]])
    # Separate scales for rows and columns, and a window's origin.
    np.testing.assert_allclose(work_to_photo([[0, 0]], (2.0, 3.0), origin_rowcol=(10, 20)), [[20.5, 61.0]])
    np.testing.assert_allclose(work_to_photo([[3.25, 7.5]], 1.0), [[3.25, 7.5]])


def test_a_drawn_disc_has_its_centroid_and_area_to_a_fraction_of_a_pixel():
    center, radius = (31.3, 40.7), 17.0
    outline = trace_outline(disc_coverage((70, 80), center, radius))
    np.testing.assert_allclose(outline.centroid_rowcol, center, atol=0.01)
    assert outline.area_px == pytest.approx(np.pi * radius**2, rel=0.003)
    # Every outline point lies on the circle, to a tenth of a pixel (the 0.5
    # level is interpolated linearly between pixels whose coverage is not).
    distance = np.hypot(*(outline.contour_rowcol - center).T)
    np.testing.assert_allclose(distance, radius, atol=0.1)


def test_a_boolean_mask_is_smoothed_into_a_sub_pixel_outline():
    rr, cc = np.mgrid[0:64, 0:64]
    center, radius = (30.0, 33.0), 20.0
    mask = (rr - center[0]) ** 2 + (cc - center[1]) ** 2 <= radius**2
    outline = trace_outline(mask)
    np.testing.assert_allclose(outline.centroid_rowcol, center, atol=1e-6)  # symmetric staircase
    assert outline.area_px == pytest.approx(mask.sum(), rel=0.01)
    # No staircase left: consecutive points turn gently.
    steps = np.diff(outline.contour_rowcol, axis=0)
    heading = np.unwrap(np.arctan2(steps[:, 0], steps[:, 1]))
    assert np.abs(np.diff(heading)).max() < np.radians(60)


def test_the_largest_piece_is_outlined_and_holes_are_ignored():
    coverage = disc_coverage((60, 100), (30, 30), 20) + disc_coverage((60, 100), (30, 80), 8)
    coverage[28:33, 28:33] = 0.0  # a hole inside the big disc
    outline = trace_outline(coverage)
    np.testing.assert_allclose(outline.centroid_rowcol, (30, 30), atol=0.05)
    assert outline.area_px == pytest.approx(np.pi * 400, rel=0.005)


def test_scale_and_origin_carry_the_outline_to_photo_pixels():
    coverage = disc_coverage((40, 40), (20.0, 18.0), 12.0)
    outline = trace_outline(coverage, scale=(2.0, 3.0), origin_rowcol=(5, 7))
    # Centre (20, 18) in a window at (5, 7) of a working image reduced (2, 3) times.
    np.testing.assert_allclose(
        outline.centroid_rowcol, [(25 + 0.5) * 2 - 0.5, (25 + 0.5) * 3 - 0.5], atol=0.03
    )
    assert outline.area_px == pytest.approx(np.pi * 144 * 6, rel=0.01)


def test_bad_masks_are_refused():
    with pytest.raises(NoRockFoundError, match="empty"):
        trace_outline(np.zeros((10, 10), bool))
    with pytest.raises(ParameterError, match="2-D"):
        trace_outline(np.ones((4, 4, 3)))
    with pytest.raises(ParameterError, match="finite"):
        trace_outline(np.full((5, 5), np.nan))
    with pytest.raises(ParameterError, match="smooth_sigma"):
        trace_outline(np.ones((5, 5), bool), smooth_sigma=-1.0)


@pytest.mark.parametrize(
    ("options", "message"),
    [
        # nan gave an outline of nan vertices, -1 one of negative coordinates.
        ({"scale": np.nan}, "scale must be positive and finite"),
        ({"scale": -1.0}, "scale must be positive and finite"),
        ({"scale": 0.0}, "scale must be positive and finite"),
        ({"scale": (1.0, np.inf)}, "scale must be positive and finite"),
        ({"scale": (1, 2, 3)}, "scale must be one or two numbers"),
        ({"scale": "a"}, "scale must be one or two numbers"),
        ({"origin_rowcol": (np.nan, 0)}, "origin_rowcol must be two finite numbers"),
        ({"origin_rowcol": (1, 2, 3)}, "origin_rowcol must be two finite numbers"),
    ],
)
def test_a_scale_or_origin_that_places_no_outline_is_refused(options, message):
    disc = np.hypot(*np.mgrid[-32:32, -32:32]) <= 20
    with pytest.raises(ParameterError, match=message):
        trace_outline(disc, **options)


def test_a_smoothing_wider_than_the_rock_says_so_at_once():
    # OpenCV's kernel of 6 sigma took minutes at a sigma of a million.
    disc = np.hypot(*np.mgrid[-32:32, -32:32]) <= 20
    with pytest.raises(NoRockFoundError, match="a smoothing of 1e"):
        trace_outline(disc, smooth_sigma=1e6)
    assert trace_outline(disc, smooth_sigma=2.0).area_px == pytest.approx(np.pi * 400, rel=0.03)


# ---------------------------------------------------------------- rays that cross more than once


def test_a_hooked_outline_takes_the_farthest_crossing():
    """A C-shaped rock seen from a centroid inside its back: rays through the
    opening's rim cross the outline three times; the radius is the farthest."""
    t = np.linspace(np.radians(40), np.radians(320), 600)
    outer = np.column_stack([-30 * np.sin(t), 30 * np.cos(t)])  # (row, col), y up
    inner = np.column_stack([-18 * np.sin(t[::-1]), 18 * np.cos(t[::-1])])
    c_shape = np.concatenate([outer, inner])  # a ring cut open towards +x
    centroid = np.array([0.0, -24.0])  # in the back of the C, inside the ring's band
    radii = contour_radii(c_shape, centroid, 360)
    theta = polar_angles(360)
    direction = np.column_stack([-np.sin(theta), np.cos(theta)])
    # Independent oracle: march along every ray and keep the last crossing of the outline.
    from matplotlib.path import Path

    polygon = Path(c_shape)
    steps = np.linspace(0, 80, 16001)
    crossings = []  # edges of the outline each ray passes
    for i in range(0, 360, 5):
        inside = polygon.contains_points(centroid + steps[:, None] * direction[i])
        crossings.append(int(np.count_nonzero(np.diff(inside.astype(int)))))
        assert radii[i] == pytest.approx(steps[np.flatnonzero(inside)[-1]], abs=0.02), i
    # The rule is exercised: rays that leave the back, cross the gap and pass
    # through an arm cross the outline three times.
    assert max(crossings) >= 3


# ---------------------------------------------------------------- invariants


@given(
    shift_row=st.floats(-9.0, 9.0),
    shift_col=st.floats(-9.0, 9.0),
    radius=st.floats(6.0, 14.0),
)
def test_moving_a_disc_moves_its_outline_and_keeps_its_area(shift_row, shift_col, radius):
    base = trace_outline(disc_coverage((50, 50), (25.0, 25.0), radius, supersample=8))
    moved = trace_outline(
        disc_coverage((50, 50), (25.0 + shift_row, 25.0 + shift_col), radius, supersample=8)
    )
    np.testing.assert_allclose(
        moved.centroid_rowcol - base.centroid_rowcol, [shift_row, shift_col], atol=0.05
    )
    # Marching squares misplaces the outline by a small fraction of a pixel
    # depending on the sub-pixel position: an area error that shrinks as 1/radius.
    assert moved.area_px == pytest.approx(base.area_px, rel=0.1 / radius)


@given(k=st.integers(1, 3))
def test_turning_a_mask_by_quarter_turns_turns_its_outline(k):
    rr, cc = np.mgrid[0:41, 0:41]
    # An asymmetric blob: an ellipse with a bump, about the array's centre.
    mask = ((rr - 20) / 14.0) ** 2 + ((cc - 20) / 8.0) ** 2 <= 1
    mask |= (rr - 10) ** 2 + (cc - 27) ** 2 <= 25
    base = trace_outline(mask)
    turned = trace_outline(np.rot90(mask, k))
    # np.rot90 turns (row, col) about the centre (20, 20) by k quarter turns counter-clockwise.
    r, c = base.centroid_rowcol - 20.0
    for _ in range(k):
        r, c = -c, r
    np.testing.assert_allclose(turned.centroid_rowcol, [20.0 + r, 20.0 + c], atol=1e-6)
    assert turned.area_px == pytest.approx(base.area_px, rel=1e-6)
