"""Comparison methods: Hu moments and elliptic Fourier descriptors matched to library templates."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from rockscan.core.baselines import BaselineMatch, EllipticFourierMatcher, HuMomentsMatcher, template_contours
from rockscan.core.errors import ParameterError
from rockscan.core.polar import radii_to_xy
from rockscan.core.render import RenderConfig, render_photo
from rockscan.io import default_spec_path, read_spec
from rockscan.run.pipeline import measure_rocks

SPECS = {s.name: s.params for s in read_spec(default_spec_path())}
#: Library shapes whose first harmonic is an ellipse (or a circle drawn as
#: one): the elliptic Fourier normalisation is defined for them.
ELLIPTIC = ["circle", "ellipse", "elongated", "egg", "teardrop", "lens", "diamond"]


@pytest.fixture(scope="module")
def hu(default_lib) -> HuMomentsMatcher:
    return HuMomentsMatcher.from_library(default_lib)


@pytest.fixture(scope="module")
def efd(default_lib) -> EllipticFourierMatcher:
    return EllipticFourierMatcher.from_library(default_lib)


def placed(library, name, *, angle_deg=0.0, radius=1.0, roll=0, offset=(0.0, 0.0)):
    """A library shape's outline turned, scaled, started elsewhere and moved, as (row, col)."""
    xy = radii_to_xy(library.radii[library.index(name)] * radius, angle_deg)
    rowcol = np.column_stack([offset[0] - xy[:, 1], offset[1] + xy[:, 0]])
    return np.roll(rowcol, roll, axis=0)


def test_templates_are_the_library_radii_drawn_counter_clockwise(default_lib):
    contours = template_contours(default_lib, template_radius=50.0)
    assert len(contours) == len(default_lib)
    for radii, contour in zip(default_lib.radii, contours, strict=True):
        np.testing.assert_allclose(np.hypot(*contour.T), 50.0 * radii, rtol=1e-12)
    # Ray 0 points right (col up), a quarter of the way round points up (row down).
    egg = contours[default_lib.index("egg")]
    assert egg[0, 0] == pytest.approx(0.0, abs=1e-9) and egg[0, 1] > 0
    assert egg[90, 1] == pytest.approx(0.0, abs=1e-9) and egg[90, 0] < 0


def test_every_template_matches_itself_at_distance_zero(default_lib, hu, efd):
    for name, contour in zip(default_lib.names, template_contours(default_lib), strict=True):
        for matcher in (hu, efd):
            found = matcher.match(contour)
            assert isinstance(found, BaselineMatch)
            assert found.nearest == name and found.distance == pytest.approx(0.0, abs=1e-9)
            assert found.names == default_lib.names and found.distances.shape == (len(default_lib),)


@given(
    name=st.sampled_from(sorted(SPECS)),
    angle=st.floats(0.0, 360.0),
    radius=st.floats(5.0, 500.0),
    roll=st.integers(0, 359),
)
def test_hu_distances_ignore_turning_scaling_moving_and_start(default_lib, hu, name, angle, radius, roll):
    contour = placed(default_lib, name, angle_deg=angle, radius=radius, roll=roll, offset=(321.0, -45.0))
    # OpenCV computes the moments of a float32 contour: equal to ~1e-5.
    np.testing.assert_allclose(hu.distances(contour), hu.distances(placed(default_lib, name)), atol=1e-5)


@given(
    name=st.sampled_from(ELLIPTIC),
    angle=st.floats(0.0, 360.0),
    radius=st.floats(5.0, 500.0),
    roll=st.integers(0, 359),
)
def test_efd_distances_ignore_turning_scaling_moving_and_start(default_lib, efd, name, angle, radius, roll):
    """Including the half turns the normalisation cannot tell apart."""
    contour = placed(default_lib, name, angle_deg=angle, radius=radius, roll=roll, offset=(12.0, 700.0))
    assert efd.distances(contour)[default_lib.index(name)] == pytest.approx(0.0, abs=1e-6)


def test_efd_needs_all_four_normalised_forms(default_lib, efd):
    """A half turn of the egg, or starting its outline half way round, leaves
    the normalised descriptor in another of its forms."""
    egg = default_lib.index("egg")
    for contour in (placed(default_lib, "egg", angle_deg=180.0), placed(default_lib, "egg", roll=180)):
        plain = np.linalg.norm(efd.descriptor(contour) - efd.descriptors[egg])
        assert efd.distances(contour)[egg] == pytest.approx(0.0, abs=1e-9)
        assert plain < 1e-9 or plain > 0.1  # either form may come out; both are handled


def test_efd_orientation_is_undefined_for_many_fold_symmetric_shapes(default_lib, efd):
    """The documented weakness: a six-pointed star's first harmonic is a
    circle, so turning it changes its normalised descriptor."""
    star = default_lib.index("six-pointed-star")
    distances = [
        efd.distances(placed(default_lib, "six-pointed-star", angle_deg=a))[star] for a in (0, 33.3, 90)
    ]
    assert max(distances) > 0.1


@pytest.mark.parametrize("name", ["elongated", "circle", "teardrop"])
def test_rendered_rocks_with_a_clear_first_harmonic_are_matched(default_lib, hu, efd, name):
    photo = render_photo(SPECS[name], RenderConfig(rows=300, cols=400), rng=3, name=name)
    contour = measure_rocks(photo.pixels, 360)[1][0].outline.contour_rowcol
    assert hu.match(contour).nearest == name
    assert efd.match(contour).nearest == name


def test_bad_contours_and_settings_are_refused(default_lib, hu, efd):
    for matcher in (hu, efd):
        with pytest.raises(ParameterError, match="n_points"):
            matcher.match(np.zeros((2, 2)))
        with pytest.raises(ParameterError, match="finite"):
            matcher.match(np.array([[0.0, 0.0], [1.0, np.nan], [2.0, 0.0]]))
        with pytest.raises(ParameterError, match="no area"):
            matcher.match(np.array([[0.0, 0.0], [0.0, 1.0], [0.0, 2.0]]))
    with pytest.raises(ParameterError, match="CONTOURS_MATCH"):
        HuMomentsMatcher.from_library(default_lib, method=4)
    with pytest.raises(ParameterError, match="order"):
        EllipticFourierMatcher.from_library(default_lib, order=1)
    with pytest.raises(ParameterError, match="template_radius"):
        template_contours(default_lib, template_radius=-1.0)
