"""Information faces (paper Section III): probabilities, bits, invariances, grids."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.stats import norm

from rockscan.core.errors import ParameterError
from rockscan.core.information import (
    REFERENCE_RADIUS,
    FaceConfig,
    information_face,
    information_face_cartesian,
    normalize_radii,
    reference_information,
    sample_term,
    section_edges,
    section_probabilities,
    shannon_bits,
)
from rockscan.core.superformula import SuperformulaParams, shape_radii

STAR = SuperformulaParams(6, 6, 0.2, 1.7, 1.7)
EGG = SuperformulaParams(1, 1, 0.75, 0.75, 0.75)


def test_section_probabilities_are_cdf_differences():
    edges = np.linspace(0, 1, 11)
    p = section_probabilities(np.array([0.4]), edges, 0.1)[0]
    np.testing.assert_allclose(p, np.diff(norm.cdf(edges, 0.4, 0.1)), rtol=1e-12, atol=1e-15)
    # The sections of a ray hold the mass of the normal that falls on the ray.
    assert p.sum() == pytest.approx(norm.cdf(1, 0.4, 0.1) - norm.cdf(0, 0.4, 0.1), rel=1e-14)


def test_tail_probabilities_keep_their_precision():
    # Sections 8-9 sigma away: a naive CDF difference would cancel to 0.
    edges = np.array([0.8, 0.9])
    p = section_probabilities(np.array([0.0]), edges, 0.1)[0, 0]
    exact = math.exp(norm.logsf(8)) - math.exp(norm.logsf(9))
    assert p == pytest.approx(exact, rel=1e-10)
    assert section_probabilities(np.array([1.7]), edges, 0.1)[0, 0] == pytest.approx(exact, rel=1e-10)


def test_shannon_bits():
    np.testing.assert_allclose(shannon_bits([0.5, 0.25, 1.0, 0.0]), [0.5, 0.5, 0.0, 0.0])
    # p log2(1/p) peaks at 1/e with log2(e)/e bits.
    assert shannon_bits([1 / math.e])[0] == pytest.approx(math.log2(math.e) / math.e)


def test_reference_information_of_the_circle():
    config = FaceConfig()
    w = reference_information(config)
    assert w.shape == (360, 50)
    np.testing.assert_array_equal(w, np.broadcast_to(w[0], w.shape))  # same on every ray
    edges = section_edges(config)
    peak = int(np.argmax(w[0]))
    # The circle's radius 0.5*sqrt(2) lies in the most informative section's neighbourhood.
    assert edges[peak] - config.resolution <= REFERENCE_RADIUS <= edges[peak + 1] + config.resolution
    p = np.diff(norm.cdf(edges, REFERENCE_RADIUS, 0.1))
    np.testing.assert_allclose(w[0], -p * np.log2(p), rtol=1e-9, atol=1e-300)


def test_face_is_reference_information_times_sample_probability():
    config = FaceConfig()
    radii = shape_radii(STAR, 360)
    face = information_face(radii, config)
    rho = normalize_radii(radii)
    q = np.diff(norm.cdf(section_edges(config)[None, :], rho[:, None], 0.1), axis=1)
    np.testing.assert_allclose(face, reference_information(config) * q, rtol=1e-9, atol=1e-18)
    assert rho.mean() == pytest.approx(REFERENCE_RADIUS)


@given(scale=st.floats(1e-3, 1e4), shift=st.integers(0, 359))
def test_scale_never_changes_a_face_and_turning_shifts_it(scale, shift):
    radii = shape_radii(EGG, 360)
    face = information_face(radii)
    np.testing.assert_allclose(information_face(radii * scale), face, rtol=1e-9, atol=1e-15)
    # Equal but for the order of summation in the mean radius.
    np.testing.assert_allclose(
        information_face(np.roll(radii, shift)), np.roll(face, shift, axis=0), rtol=1e-12, atol=1e-300
    )


def test_variant_two_compares_with_a_reference_shape():
    config = FaceConfig(kind="information-shape", reference=STAR)
    w = reference_information(config)
    assert w.shape == (360, 50)
    assert not np.allclose(w, w[:1])  # depends on the ray, unlike the circle
    # A sample equal to the reference gets H(p) * p with the same p.
    radii = shape_radii(STAR, 360)
    q = sample_term(radii, config)
    raw = STAR.radii(np.arange(360) * 2 * np.pi / 360)
    p = section_probabilities(normalize_radii(raw), section_edges(config), 0.1)
    np.testing.assert_allclose(information_face(raw, config), shannon_bits(p) * p, rtol=1e-9, atol=1e-18)
    assert q.shape == (360, 50)


def test_radii_face_is_normalised_radii():
    config = FaceConfig(kind="radii")
    radii = shape_radii(EGG, 360) * 7
    face = information_face(radii, config)
    assert face.shape == (360, 1)
    np.testing.assert_allclose(face[:, 0] * math.sqrt(360), radii / radii.mean())


def test_cartesian_map_turns_with_the_shape():
    config = FaceConfig(grid="cartesian", cartesian_size=64)
    radii = shape_radii(EGG, 360)
    face = information_face(radii, config)
    assert face.shape == (64, 64)
    # Turning the shape 90 degrees counter-clockwise turns the map the same way.
    np.testing.assert_allclose(
        information_face_cartesian(np.roll(radii, 90), config), np.rot90(face), atol=1e-9
    )
    np.testing.assert_allclose(information_face(radii * 3, config), face, rtol=1e-9, atol=1e-15)
    # The egg's point is on the +x side: the map's right half holds the far radii.
    heavy = np.argmax(radii)
    assert abs((heavy + 180) % 360 - 180) < 30


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"kind": "bogus"}, "face kind must be one of"),
        ({"grid": "hex"}, "grid must be one of"),
        ({"sigma": 0}, "sigma must be a positive number"),
        ({"resolution": 0.9}, "resolution must be at most half"),
        ({"n_angles": 4}, "n_angles must be an integer >= 8"),
        ({"kind": "information-shape"}, "needs a reference shape"),
        ({"kind": "radii", "grid": "cartesian"}, "radii face lives on the polar grid"),
    ],
)
def test_face_config_validation(kwargs, message):
    with pytest.raises(ParameterError, match=message):
        FaceConfig(**kwargs)


def test_face_config_round_trip():
    for config in (
        FaceConfig(),
        FaceConfig(kind="information-shape", reference=STAR, sigma=0.2),
        FaceConfig(kind="radii", n_angles=180),
    ):
        assert FaceConfig.from_dict(config.to_dict()) == config
    with pytest.raises(ParameterError, match="unknown face settings"):
        FaceConfig.from_dict({"kind": "information", "colour": 3})


@pytest.mark.parametrize("bad", [np.array([]), np.array([1.0, np.nan] * 180), -np.ones(360), np.zeros(360)])
def test_bad_radii_are_rejected(bad):
    with pytest.raises(ParameterError, match="radii"):
        information_face(bad)


def test_wrong_number_of_angles_names_the_fix():
    with pytest.raises(ParameterError, match="resample them"):
        information_face(np.ones(100))
