"""Novelty against the shapes observed so far (paper Section V)."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from conftest import PAPER_SHAPES
from hypothesis import given
from hypothesis import strategies as st

from rockscan.core.errors import LibraryError, ParameterError
from rockscan.core.information import FaceConfig, information_face
from rockscan.core.library import Library, ShapeSpec
from rockscan.core.match import MatchConfig, match_radii
from rockscan.core.novelty import (
    NoveltyConfig,
    ObservedShapes,
    default_threshold,
    observed_name,
)
from rockscan.core.render import RenderConfig, random_superformula, render_photo
from rockscan.core.superformula import SuperformulaParams, shape_radii
from rockscan.io import load_library, save_library
from rockscan.run.pipeline import classify_image

#: Shapes unlike every shape of the default library (novelty 0.46 to 0.62 at 360 rays).
NEW_SHAPES = {
    "four-lobe": SuperformulaParams(4, 4, 0.6, 1, 1),
    "eight-lobe": SuperformulaParams(8, 8, 6, 10, 10),
}


@pytest.fixture(scope="module")
def small_lib() -> Library:
    """The paper's three shapes at 72 rays: small enough for brute-force oracles."""
    config = FaceConfig(n_angles=72)
    return Library.from_shapes([ShapeSpec(n, p) for n, p in PAPER_SHAPES.items()], face_config=config)


def _brute_force_distances(radii, library):
    """min over rotations of ||face(sample turned) - face_k|| for each shape k, from faces alone."""
    config = library.face_config
    turned = np.stack([np.roll(radii, -a) for a in range(config.n_angles)])
    faces = information_face(turned, config).reshape(config.n_angles, -1)
    targets = library.faces().reshape(len(library), -1)
    diff = faces[:, None, :] - targets[None, :, :]
    return np.sqrt(np.einsum("akp,akp->ak", diff, diff)).min(axis=0)


# ---------------------------------------------------------------- tiny exact cases


@pytest.mark.parametrize(
    ("stem", "taken", "expected"),
    [
        ("0012-Rounded Triangle", set(), "seen-0012-rounded-triangle"),
        ("IMG_0001", {"seen-img-0001"}, "seen-img-0001-2"),
        ("IMG_0001", {"seen-img-0001", "seen-img-0001-2"}, "seen-img-0001-3"),
        ("__", set(), "seen-rock"),
        ("é€", set(), "seen-rock"),
    ],
)
def test_observed_names_are_valid_and_unique(stem, taken, expected):
    assert observed_name(stem, taken) == expected


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"metric": "cosine"}, "novelty metric must be one of face, eigenspace"),
        ({"metric": "auto"}, "novelty metric must be one of face, eigenspace"),
        ({"threshold": -0.1}, "non-negative number"),
        ({"threshold": float("nan")}, "non-negative number"),
    ],
)
def test_novelty_config_names_the_fix(kwargs, message):
    with pytest.raises(ParameterError, match=message):
        NoveltyConfig(**kwargs)


def test_a_new_observed_library_starts_with_the_library_shapes(small_lib):
    observed = ObservedShapes.from_library(small_lib)
    assert observed.library.names == small_lib.names
    assert observed.n_seed == 3 and observed.n_observed == 0
    np.testing.assert_allclose(observed.library.faces(), small_lib.faces(), atol=1e-12)


def test_a_known_shape_is_not_new_and_its_distance_is_zero(small_lib):
    observed = ObservedShapes.from_library(small_lib)
    for k, name in enumerate(small_lib.names):
        novelty = observed.assess(small_lib.radii[k])
        assert novelty.nearest == name
        assert novelty.score == pytest.approx(0.0, abs=1e-6)
        assert not novelty.novel


# ---------------------------------------------------------------- oracles and theory


def test_score_is_the_whole_face_distance_to_the_nearest_shape(small_lib):
    observed = ObservedShapes.from_library(small_lib, NoveltyConfig(threshold=0.1))
    rng = np.random.default_rng(3)
    for _ in range(3):
        radii = shape_radii(random_superformula(rng), 72)
        expected = _brute_force_distances(radii, observed.library)
        novelty = observed.assess(radii)
        assert novelty.score == pytest.approx(expected.min(), rel=1e-9, abs=1e-12)
        assert novelty.nearest == small_lib.names[int(np.argmin(expected))]
        assert novelty.novel == (expected.min() > 0.1)


def test_default_threshold_is_half_the_median_library_spacing(small_lib):
    spacing = []
    for k in range(len(small_lib)):
        dist = _brute_force_distances(small_lib.radii[k], small_lib)
        dist[k] = np.inf
        spacing.append(dist.min())
    # rel 1e-7: numpy before 2.0 computes the scan's complex64 FFTs in double.
    assert default_threshold(small_lib) == pytest.approx(0.5 * np.median(spacing), rel=1e-7)


def test_default_threshold_of_a_large_library_is_the_median_of_evenly_spaced_shapes(monkeypatch):
    # A 20,000-shape library's threshold scanned every shape against every other one.
    rng = np.random.default_rng(5)
    config = FaceConfig(n_angles=72)
    radii = [shape_radii(random_superformula(rng), 72) for _ in range(21)]
    library = Library.from_radii([f"s{i}" for i in range(21)], radii, face_config=config)
    spacing = []
    for k in range(len(library)):
        dist = _brute_force_distances(library.radii[k], library)
        dist[k] = np.inf
        spacing.append(dist.min())
    monkeypatch.setattr("rockscan.core.novelty.THRESHOLD_SHAPES", 6)
    # Shapes 0, 4, 8, 12, 16 and 20 of 21.
    expected = 0.5 * np.median(np.array(spacing)[[0, 4, 8, 12, 16, 20]])
    # rel 1e-5: the scan's complex64 spectra against faces compared directly, at distances of 0.02.
    assert default_threshold(library) == pytest.approx(expected, rel=1e-5)
    assert default_threshold(library) != pytest.approx(0.5 * np.median(spacing), rel=1e-3)


def test_default_threshold_of_the_builtin_library(default_lib):
    # The figure docs/triage.md quotes.
    assert default_threshold(default_lib) == pytest.approx(0.133, abs=0.002)


@given(seed=st.integers(0, 2**32 - 1))
def test_the_eigenspace_distance_never_exceeds_the_face_distance(small_lib, seed):
    # eps leaves out the distance from face space, which is what makes a shape new.
    radii = shape_radii(random_superformula(seed), 72)
    face = ObservedShapes.from_library(small_lib, NoveltyConfig(metric="face")).assess(radii)
    eps = ObservedShapes.from_library(small_lib, NoveltyConfig(metric="eigenspace")).assess(radii)
    assert eps.score <= face.score + 1e-9


def test_the_eigenspace_distance_misses_what_the_library_does_not_span():
    # A two-shape library spans one direction of face space: a shape unlike
    # both can sit close to that line while its face is far from both faces.
    config = FaceConfig(n_angles=72)
    pair = Library.from_shapes(
        [
            ShapeSpec("circle", SuperformulaParams(0, 0, 1, 1, 1)),
            ShapeSpec(*next(iter(PAPER_SHAPES.items()))),
        ],
        face_config=config,
    )
    radii = shape_radii(NEW_SHAPES["eight-lobe"], 72)
    face = ObservedShapes.from_library(pair, NoveltyConfig(metric="face")).assess(radii)
    eps = ObservedShapes.from_library(pair, NoveltyConfig(metric="eigenspace")).assess(radii)
    assert face.score > 3 * eps.score


# ---------------------------------------------------------------- invariance and round trips


@given(shift=st.integers(0, 71), scale=st.floats(0.2, 50.0))
def test_novelty_ignores_turn_and_size(small_lib, shift, scale):
    observed = ObservedShapes.from_library(small_lib)
    radii = shape_radii(NEW_SHAPES["four-lobe"], 72)
    base = observed.assess(radii)
    moved = observed.assess(scale * np.roll(radii, shift))
    assert moved.score == pytest.approx(base.score, rel=1e-7)
    assert moved.nearest == base.nearest


def test_adding_a_shape_returns_a_new_object_that_knows_it(small_lib):
    observed = ObservedShapes.from_library(small_lib, NoveltyConfig(threshold=0.1))
    radii = shape_radii(NEW_SHAPES["four-lobe"], 72)
    first = observed.assess(radii)
    assert first.novel
    grown = observed.with_shape("seen-four-lobe", radii)
    assert observed.library.names == small_lib.names
    assert grown.library.names == (*small_lib.names, "seen-four-lobe")
    assert grown.n_seed == 3 and grown.n_observed == 1
    again = grown.assess(np.roll(radii, 17))
    assert again.nearest == "seen-four-lobe" and again.score == pytest.approx(0.0, abs=1e-6)
    assert not again.novel


def test_observed_library_survives_save_and_load(tmp_path, small_lib):
    grown = ObservedShapes.from_library(small_lib).with_shape(
        "seen-four-lobe", shape_radii(NEW_SHAPES["four-lobe"], 72)
    )
    path = tmp_path / "observed.npz"
    save_library(grown.library, path)
    loaded = ObservedShapes.from_file(load_library(path), small_lib)
    assert loaded.library.names == grown.library.names
    assert (loaded.n_seed, loaded.n_observed) == (3, 1)
    assert loaded.threshold == grown.threshold
    probe = shape_radii(NEW_SHAPES["eight-lobe"], 72)
    assert loaded.assess(probe).score == pytest.approx(grown.assess(probe).score, rel=1e-9)


def test_an_observed_library_of_other_face_settings_is_refused(small_lib, paper_lib):
    with pytest.raises(LibraryError, match=r"other face settings.*start a new observed library"):
        ObservedShapes.from_file(paper_lib, small_lib)


def test_radii_of_the_wrong_length_are_refused(small_lib):
    with pytest.raises(ParameterError, match="72 values"):
        ObservedShapes.from_library(small_lib).with_shape("seen-x", np.ones(360))


# ---------------------------------------------------------------- rendered truth


def test_rendered_rocks_new_shapes_are_novel_once(default_lib):
    """Photos of library shapes are not new; the first photo of an unknown
    shape is, and a second photo of it (turned, lit differently) is not."""
    config = RenderConfig(rows=240, cols=320)
    observed = ObservedShapes.from_library(default_lib)

    def radii(params, seed):
        (rock,) = classify_image(render_photo(params, config, rng=seed).pixels, default_lib)
        return rock.radii

    for name in ("egg", "three-faced-blunt", "six-pointed-star"):
        params = default_lib.params[default_lib.index(name)]
        novelty = observed.assess(radii(params, 11))
        assert not novelty.novel, (name, novelty)
        assert novelty.nearest == name
    for name, params in NEW_SHAPES.items():
        first = observed.assess(radii(params, 21))
        assert first.novel and first.score > 2 * observed.threshold, (name, first)
        grown = observed.with_shape(f"seen-{name}", radii(params, 21))
        second = grown.assess(radii(params, 22))
        assert not second.novel and second.nearest == f"seen-{name}", (name, second)


# ---------------------------------------------------------------- growth without a rebuild


def _grown(lib: Library, count: int, seed: int) -> ObservedShapes:
    observed = ObservedShapes.from_library(lib, NoveltyConfig(threshold=0.1))
    rng = np.random.default_rng(seed)
    for i in range(count):
        radii = shape_radii(random_superformula(rng), lib.face_config.n_angles)
        observed = observed.with_shape(f"seen-{i}", radii)
    return observed


def test_growing_equals_a_rebuild(small_lib):
    observed = _grown(small_lib, 12, seed=4)
    grown = observed.library
    rebuilt = Library.from_radii(grown.names, grown.radii, face_config=small_lib.face_config)
    assert len(grown) == len(small_lib) + 12
    assert grown.basis.n_components == rebuilt.basis.n_components == len(grown) - 1
    np.testing.assert_allclose(
        grown.basis.components @ grown.basis.components.T, np.eye(len(grown) - 1), atol=1e-9
    )
    rng = np.random.default_rng(9)
    for _ in range(4):
        sample = np.roll(shape_radii(random_superformula(rng), 72), 11) * (1 + 0.05 * rng.standard_normal(72))
        ours = match_radii(sample, grown, MatchConfig(metric="face"))
        theirs = match_radii(sample, rebuilt, MatchConfig(metric="face"))
        assert ours.nearest == theirs.nearest
        # The scan's templates are single precision: distances agree to their rounding.
        np.testing.assert_allclose(ours.distances, theirs.distances, atol=1e-5)
        np.testing.assert_allclose(ours.distances, _brute_force_distances(sample, rebuilt), atol=1e-5)


def test_growing_keeps_earlier_libraries_and_branches(small_lib):
    first = _grown(small_lib, 3, seed=5)
    names = first.library.names
    radii = shape_radii(SuperformulaParams(5, 5, 2, 7, 7), 72)
    a = first.with_shape("seen-a", radii)
    b = first.with_shape("seen-b", radii * 1.1)  # from the same parent: copies, leaves a alone
    assert first.library.names == names and len(first.library.radii) == len(names)
    assert a.library.names[-1] == "seen-a" and b.library.names[-1] == "seen-b"
    np.testing.assert_allclose(a.library.radii[-1], b.library.radii[-1])
    assert a.assess(radii).score == pytest.approx(0.0, abs=1e-6)
    with pytest.raises(LibraryError, match="unique"):
        a.with_shape("seen-a", radii)


def test_a_grown_library_names_its_shapes_as_a_tuple_does(small_lib):
    names = _grown(small_lib, 3, seed=8).library.names  # shares its list with later growth
    as_tuple = tuple(list(names))
    assert len(names) == len(small_lib) + 3 and names[-1] == "seen-2" == as_tuple[-1]
    assert names == as_tuple and as_tuple == names and hash(names) == hash(as_tuple)
    assert names[1:3] == as_tuple[1:3] and names.index("seen-1") == as_tuple.index("seen-1")
    assert "seen-0" in names and "seen-3" not in names and names != as_tuple[:-1]
    assert repr(names) == repr(as_tuple) and pickle.loads(pickle.dumps(names)) == as_tuple
    assert type(pickle.loads(pickle.dumps(names))) is tuple
    with pytest.raises(IndexError):
        names[len(as_tuple)]


def test_saved_grown_library_loads(small_lib, tmp_path):
    observed = _grown(small_lib, 4, seed=6)
    save_library(observed.library, tmp_path / "seen.npz")
    loaded = load_library(tmp_path / "seen.npz")
    again = ObservedShapes.from_file(loaded, small_lib, NoveltyConfig(threshold=0.1))
    sample = observed.library.radii[-1]
    assert again.assess(sample).score == pytest.approx(observed.assess(sample).score, abs=1e-6)
    assert again.n_observed == 4


def test_a_grown_library_carries_its_sensor_metric_and_cutoffs(small_lib):
    observed = _grown(small_lib, 5, seed=7)
    grown = observed.library
    seed_metric = small_lib.sensor_metric
    metric = grown.sensor_metric
    # The seed's weights; each new shape's spectrum as the seed's metric measures it.
    np.testing.assert_array_equal(metric.weights, seed_metric.weights)
    assert metric.spectra.shape[0] == len(grown)
    np.testing.assert_allclose(metric.spectra[-1], seed_metric.sample_spectrum(grown.radii[-1]), atol=1e-12)
    own = metric.squared_distances(grown.radii[-1])
    assert own[:, -1].min() == pytest.approx(0.0, abs=1e-9)
    # Cutoffs without a calibration of the grown library: the seed's, then their median.
    assert grown.calibration is None
    np.testing.assert_array_equal(grown.cutoffs[: len(small_lib)], small_lib.cutoffs)
    np.testing.assert_array_equal(grown.cutoffs[len(small_lib) :], np.median(small_lib.cutoffs))


def test_a_one_shape_library_asks_for_a_threshold(tmp_path):
    # Its default was inf, refused as if the user had given it.
    lib = Library.from_shapes([ShapeSpec("egg", SuperformulaParams(1, 1, 0.75, 0.75, 0.75))])
    with pytest.raises(ParameterError, match=r"one-shape library has no spacing.*--novelty-threshold"):
        ObservedShapes.from_library(lib)
    assert ObservedShapes.from_library(lib, NoveltyConfig(threshold=0.1)).threshold == 0.1


@pytest.mark.parametrize("name", ["Seen Rock #1", "rock-1", "", 7])
def test_an_observed_shape_needs_a_name_its_file_keeps(small_lib, name):
    # Saved, "Seen Rock #1" made a file that did not load (every observed shape lost),
    # and "rock-1" was read back as a shape of the library of interest.
    with pytest.raises(ParameterError, match=r"must match .* and start with 'seen-'"):
        ObservedShapes.from_library(small_lib).with_shape(name, small_lib.radii[0])
