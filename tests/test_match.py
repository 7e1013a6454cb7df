"""Matching: the paper's tables, the rotation scan, invariances, cutoffs."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import PAPER_NEAR, PAPER_SHAPES
from hypothesis import given
from hypothesis import strategies as st

from rockscan.core.errors import ParameterError
from rockscan.core.information import FaceConfig, information_face
from rockscan.core.library import Library, ShapeSpec
from rockscan.core.match import MatchConfig, match_radii, rotation_scores
from rockscan.core.polar import polar_angles, recenter_radii
from rockscan.core.superformula import SuperformulaParams, shape_radii

PAPER_EXACT = MatchConfig.paper()


def turned_radii(params: SuperformulaParams, alpha_deg: float, n: int = 360) -> np.ndarray:
    """The shape turned counter-clockwise by alpha, sampled exactly, about its centroid."""
    raw = params.radii(polar_angles(n) - np.radians(alpha_deg))
    return recenter_radii(raw)[0]


def folded_error(angle: float, truth: float, order: int) -> float:
    period = 360.0 / max(order, 1)
    d = (angle - truth) % period
    return min(d, period - d)


@pytest.mark.parametrize("config", [MatchConfig(), PAPER_EXACT, MatchConfig(scan=False)])
def test_table_1_library_shapes_match_themselves(paper_lib, config):
    for name, params in PAPER_SHAPES.items():
        m = match_radii(shape_radii(params, 360), paper_lib, config)
        assert m.nearest == name and m.match == name and m.interesting
        assert m.mscore == pytest.approx(1.0, abs=1e-9)
        assert m.distance == pytest.approx(0.0, abs=1e-7)
        others = np.delete(m.distances, paper_lib.index(name))
        assert others.min() > 0.1  # the "Nearest Match" column: clearly apart


def test_table_5_near_shapes_match_their_base_in_the_papers_order(paper_lib):
    scores = {}
    for config in (MatchConfig(), PAPER_EXACT, MatchConfig(scan=False, metric="eigenspace")):
        for name, params in PAPER_NEAR.items():
            m = match_radii(shape_radii(params, 360), paper_lib, config)
            assert m.nearest == name
            scores[name] = m.mscore
        # Paper: 1, 1 and 0.92; the smooth shapes stay near 1 and the star, whose
        # many features feel any change most, scores lowest.
        assert scores["rounded-triangle"] > 0.99 and scores["three-faced-blunt"] > 0.99
        assert 0.8 < scores["six-pointed-star"] < min(scores["rounded-triangle"], scores["three-faced-blunt"])


@given(alpha=st.floats(0, 360, exclude_max=True), index=st.integers(0, 13))
def test_a_turned_shape_comes_back_with_its_angle(default_lib, default_specs, alpha, index):
    spec = default_specs[index]
    m = match_radii(turned_radii(spec.params, alpha), default_lib)
    assert m.nearest == spec.name
    order = int(default_lib.symmetry[index])
    if order != 0:
        assert folded_error(m.angle_deg, alpha, order) <= 1.0
    # The smallest of the equally good angles: under the symmetry's period.
    assert 0.0 <= m.angle_deg < (360.0 / order if order else 360.0)


@pytest.fixture(scope="module")
def few_eigenfaces(default_specs):
    return {n: Library.from_shapes(default_specs, n_components=n) for n in (1, 2, 3)}


@pytest.mark.parametrize("n_components", [1, 2, 3])
@pytest.mark.parametrize("alpha", [0.0, 10.0, 33.0, 50.0])
def test_a_library_of_few_eigenfaces_finds_the_angle_of_its_own_shapes(
    few_eigenfaces, default_specs, n_components, alpha
):
    # Its face space holds blurred copies of its faces: an unturned shape came
    # back at 34 degrees, MScore 1 (the blunt three-faced shape, one eigenface).
    lib = few_eigenfaces[n_components]
    assert not lib.holds_its_faces
    for index in (1, 0, 13):
        spec = default_specs[index]
        m = match_radii(turned_radii(spec.params, alpha), lib)
        assert m.nearest == spec.name
        assert folded_error(m.angle_deg, alpha, int(lib.symmetry[index])) <= 1.0


@pytest.mark.parametrize("index", range(14))
def test_a_shape_as_it_lies_is_at_angle_zero_not_just_under_its_period(default_lib, default_specs, index):
    # The parabola's offset at 0 may be a hair negative; the modulo then gave
    # 119.999997 for the rounded triangle and 71.9999996 for the five-armed star.
    spec = default_specs[index]
    m = match_radii(shape_radii(spec.params, 360), default_lib)
    assert m.nearest == spec.name
    assert m.angle_deg == pytest.approx(0.0, abs=1e-3)


@given(scale=st.floats(1e-3, 1e5), alpha=st.floats(0, 360))
def test_scale_never_changes_a_match(default_lib, scale, alpha):
    radii = turned_radii(SuperformulaParams(5, 5, 2, 7, 7), alpha)
    a, b = match_radii(radii, default_lib), match_radii(radii * scale, default_lib)
    assert a.nearest == b.nearest
    assert a.mscore == pytest.approx(b.mscore, abs=1e-9)
    # Equally good angles of a symmetric shape may swap on rounding.
    assert folded_error(a.angle_deg, b.angle_deg, a.symmetry) < 1e-6
    np.testing.assert_allclose(a.distances, b.distances, rtol=1e-7, atol=1e-12)


@pytest.mark.parametrize(
    "face_config",
    [
        FaceConfig(),
        FaceConfig(kind="radii"),
        FaceConfig(kind="information-shape", reference=PAPER_SHAPES["six-pointed-star"]),
    ],
)
def test_fourier_scan_equals_scoring_every_rotation(face_config):
    shapes = [ShapeSpec(n, p) for n, p in PAPER_SHAPES.items()] + [
        ShapeSpec("egg", SuperformulaParams(1, 1, 0.75, 0.75, 0.75))
    ]
    lib = Library.from_shapes(shapes, face_config=face_config)
    rng = np.random.default_rng(3)
    sample = shape_radii(SuperformulaParams(5, 5, 2, 7, 7), 360) * (1 + 0.05 * rng.normal(size=360))
    faces = information_face(np.stack([np.roll(sample, -a) for a in range(360)]), face_config)
    eps = lib.basis.distances(faces)
    dffs = lib.basis.residual(faces)
    # The scan's products run in single precision: squared distances agree to
    # about 1e-7 of the largest.
    scale_sq = float(np.abs(eps).max()) ** 2
    scanned = rotation_scores(sample, lib, metric="eigenspace")
    np.testing.assert_allclose(scanned**2, eps**2, atol=1e-6 * scale_sq)
    whole_sq = eps**2 + dffs[:, None] ** 2
    np.testing.assert_allclose(
        rotation_scores(sample, lib, metric="face") ** 2, whole_sq, atol=1e-6 * scale_sq
    )
    assert np.array_equal(np.argmin(scanned, axis=0), np.argmin(eps, axis=0))


def test_cartesian_grid_agrees_with_the_polar_grid(default_specs):
    shapes = default_specs[:6]
    polar = Library.from_shapes(shapes)
    cartesian = Library.from_shapes(shapes, face_config=FaceConfig(grid="cartesian", cartesian_size=48))
    rng = np.random.default_rng(11)
    for spec in shapes:
        noisy = turned_radii(spec.params, 40.0) * (1 + 0.05 * rng.normal(size=360))
        a, b = match_radii(noisy, polar), match_radii(noisy, cartesian)
        assert a.nearest == b.nearest == spec.name
        assert abs(a.mscore - b.mscore) < 0.1


def test_without_the_scan_the_sample_is_matched_as_it_lies(paper_lib):
    radii = shape_radii(PAPER_SHAPES["six-pointed-star"], 360)
    m = match_radii(np.roll(radii, 30), paper_lib, MatchConfig(scan=False))
    # A star turned half its period is far from itself (paper Fig. 13's dip)...
    assert m.mscore < 0.9 and m.angle_deg == 0.0
    # ...and the scan finds it again.
    scanned = match_radii(np.roll(radii, 30), paper_lib)
    assert scanned.mscore == pytest.approx(1.0, abs=1e-9)
    assert folded_error(scanned.angle_deg, 30.0, 6) < 1e-6


def test_cutoffs_decide_interesting_but_not_nearest(paper_lib):
    radii = shape_radii(PAPER_NEAR["six-pointed-star"], 360)
    strict = match_radii(radii, paper_lib, MatchConfig(mscore_cutoff=0.99))
    assert strict.nearest == "six-pointed-star" and strict.match is None and not strict.interesting
    assert strict.decided_by == "mscore-cutoff"
    tight = match_radii(radii, paper_lib, MatchConfig(distance_cutoff=1e-6, mscore_cutoff=0.0))
    assert not tight.interesting
    loose = match_radii(radii, paper_lib, MatchConfig(distance_cutoff=1.0, mscore_cutoff=0.5))
    assert loose.interesting and loose.match == "six-pointed-star"


def test_match_record_has_the_interface_keys(paper_lib):
    record = match_radii(shape_radii(PAPER_SHAPES["rounded-triangle"], 360), paper_lib).to_dict()
    assert {"match", "nearest", "mscore", "distance", "angle_deg", "interesting"} <= set(record)
    assert isinstance(record["interesting"], bool) and isinstance(record["mscore"], float)


@pytest.mark.parametrize(
    ("radii", "message"),
    [
        (np.ones(100), "360 values"),
        (np.ones((2, 360)), "1-D array"),
        (np.full(360, np.nan), "finite"),
        (-np.ones(360), "non-negative"),
        (np.zeros(360), "not all zero"),
    ],
)
def test_bad_samples_are_rejected(paper_lib, radii, message):
    with pytest.raises(ParameterError, match=message):
        match_radii(radii, paper_lib)


def test_bad_match_settings_are_rejected():
    with pytest.raises(ParameterError, match="metric must be one of"):
        MatchConfig(metric="cosine")
    with pytest.raises(ParameterError, match="distance_cutoff"):
        MatchConfig(distance_cutoff=float("nan"))


def test_reported_distance_is_the_ranked_distance(default_lib, default_specs):
    rng = np.random.default_rng(5)
    for spec in default_specs[:5]:
        noisy = turned_radii(spec.params, 70.0) * (1 + 0.05 * rng.normal(size=360))
        m = match_radii(noisy, default_lib, PAPER_EXACT)
        k = default_lib.index(m.nearest)
        assert m.distance == m.distances[k] == m.distances.min()
        assert m.mscore == pytest.approx(1 - m.distances[k] / m.distances.mean())
        # The default ranks by the sensor distance and keeps the paper's outWeights for MScore.
        d = match_radii(noisy, default_lib)
        assert d.nearest == spec.name
        assert d.mscore == pytest.approx(1 - d.distances.min() / d.distances.mean())
        assert d.sensor_distance == d.sensor_distances[default_lib.index(d.nearest)]


def test_a_two_shape_library_is_matched_by_the_sensor_distance():
    # One eigenface: a turned sample's projection can reach either shape, so
    # "auto" ranks by the sensor distance, which does not thin out with size.
    lib = Library.from_shapes(
        [
            ShapeSpec("disc", SuperformulaParams(0, 0, 1, 1, 1)),
            ShapeSpec("blunt", PAPER_SHAPES["three-faced-blunt"]),
        ]
    )
    assert lib.basis.n_components == 1
    assert MatchConfig().resolved_metric(lib) == "sensor"
    rng = np.random.default_rng(8)
    for alpha in (0.0, 17.0, 45.0, 90.0):
        noisy = turned_radii(PAPER_SHAPES["three-faced-blunt"], alpha) * (1 + 0.01 * rng.normal(size=360))
        assert match_radii(noisy, lib).nearest == "blunt"
        assert match_radii(turned_radii(SuperformulaParams(0, 0, 1, 1, 1), alpha), lib).nearest == "disc"


def test_the_residual_cutoff_rejects_samples_far_from_face_space(default_lib, default_specs):
    radii = turned_radii(default_specs[4].params, 10.0)
    rng = np.random.default_rng(2)
    noisy = radii * (1 + 0.08 * rng.normal(size=360))
    m = match_radii(noisy, default_lib)
    assert m.residual > 0
    cut = match_radii(noisy, default_lib, MatchConfig(residual_cutoff=0.5 * m.residual))
    assert not cut.interesting and cut.decided_by == "residual-cutoff"
    kept = match_radii(
        noisy,
        default_lib,
        MatchConfig(residual_cutoff=2 * m.residual, distance_cutoff=10.0, mscore_cutoff=-1.0),
    )
    assert kept.interesting


def test_the_paper_preset_is_the_papers_exact_method_with_changes_on_top():
    assert MatchConfig.paper() == MatchConfig(metric="eigenspace", angle_metric="eigenspace")
    assert MatchConfig.paper(scan=False) == MatchConfig(
        metric="eigenspace", angle_metric="eigenspace", scan=False
    )
    assert MatchConfig.paper() != MatchConfig()


@pytest.mark.parametrize("scale", [1e-310, 1e300])
def test_scale_never_changes_a_match_at_the_ends_of_the_floats(default_lib, scale):
    # Subnormal radii overflowed the face's scaling to inf: "elongated", not interesting.
    radii = turned_radii(SuperformulaParams(5, 5, 2, 7, 7), 20.0)
    a, b = match_radii(radii, default_lib), match_radii(radii * scale, default_lib)
    assert b.nearest == a.nearest == "five-armed-star" and b.interesting
    assert b.distance == pytest.approx(a.distance, rel=1e-6, abs=1e-9)


@pytest.mark.parametrize(("metric", "mscore"), [("eigenspace", 1.0), ("face", 0.0)])
def test_a_one_shape_librarys_mscore_is_fixed_by_its_distance(metric, mscore):
    # Face space of one shape is a point: every eigenspace distance is 0 (MScore 1),
    # and any other distance equals its own mean (MScore 0), whatever the sample.
    lib = Library.from_shapes([ShapeSpec("egg", SuperformulaParams(1, 1, 0.75, 0.75, 0.75))])
    for params in (PAPER_SHAPES["rounded-triangle"], SuperformulaParams(1, 1, 0.75, 0.75, 0.75)):
        m = match_radii(turned_radii(params, 30.0), lib, MatchConfig(metric=metric))
        assert m.mscore == pytest.approx(mscore, abs=1e-12)


def test_a_given_distance_cutoff_tests_the_distance_that_ranked_the_sample(default_lib):
    # "auto" ranks a clean sample by the eigenspace w, and the cutoff tested the
    # sensor distance anyway: a sample within the cutoff by w was refused.
    sample = turned_radii(PAPER_SHAPES["six-pointed-star"], 20.0) * (
        1 + 0.002 * np.cos(7 * polar_angles(360))
    )
    clean = match_radii(sample, default_lib)
    w, sensor = clean.distance, clean.sensor_distance
    assert w < sensor
    cutoff = (w + sensor) / 2
    auto = match_radii(sample, default_lib, MatchConfig(distance_cutoff=cutoff))
    assert auto.interesting and auto.decided_by == "distance-cutoff"
    assert not match_radii(
        sample, default_lib, MatchConfig(distance_cutoff=cutoff, metric="sensor")
    ).interesting


def test_every_shapes_angle_follows_the_angle_convention(default_lib):
    # Only the nearest shape's angle was folded: a circle got 69 degrees and a
    # 3-fold shape 332 degrees for an egg turned by 30.
    egg = turned_radii(SuperformulaParams(1, 1, 0.75, 0.75, 0.75), 30.0)
    m = match_radii(egg, default_lib)
    for name, angle, order in zip(default_lib.names, m.angles_deg, default_lib.symmetry, strict=True):
        period = 360.0 / order if order else 0.0
        assert (angle == 0.0) if not order else (0.0 <= angle < period), (name, angle, order)
    assert m.angles_deg[default_lib.index(m.nearest)] == m.angle_deg


def test_matches_compare_by_identity_without_raising(default_lib):
    a = match_radii(turned_radii(PAPER_SHAPES["rounded-triangle"], 10.0), default_lib)
    b = match_radii(turned_radii(PAPER_SHAPES["rounded-triangle"], 10.0), default_lib)
    # Generated over the arrays, == raised "truth value of an array is ambiguous".
    assert a == a and a != b and len({a, b}) == 2
