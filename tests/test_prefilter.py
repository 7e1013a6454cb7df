"""The bound that prunes the rotation scan of large libraries (prefilter.py)."""

from __future__ import annotations

import numpy as np
import pytest

from rockscan.core.information import FaceConfig, sample_term
from rockscan.core.library import Library
from rockscan.core.match import MatchConfig, match_radii, nearest_other_distance, rotation_scores
from rockscan.core.prefilter import Prefilter, SensorPrefilter, features_of

#: Coarse faces (72 rays of 20 sections) keep a library of hundreds of shapes fast.
SMALL_FACE = FaceConfig(n_angles=72, resolution=0.05)


def _random_radii(rng: np.random.Generator, n: int, n_angles: int = 72) -> np.ndarray:
    """Smooth random outlines: a few Fourier harmonics of random size and phase."""
    theta = 2 * np.pi * np.arange(n_angles) / n_angles
    harmonics = np.arange(1, 7)
    size = rng.uniform(0, 0.12, (n, harmonics.size)) / np.sqrt(harmonics)
    phase = rng.uniform(0, 2 * np.pi, (n, harmonics.size))
    return 1 + np.einsum("nh,nha->na", size, np.cos(harmonics[None, :, None] * theta + phase[..., None]))


@pytest.fixture(scope="module")
def large_lib() -> Library:
    """200 shapes, pruned as a library of more than ``EXACT_SCAN_LIMIT`` shapes is."""
    rng = np.random.default_rng(3)
    n = 200
    library = Library.from_radii([f"s{i}" for i in range(n)], _random_radii(rng, n), face_config=SMALL_FACE)
    library.set_prefilter(Prefilter.from_library(library, min_shapes=0, n_first=8, n_reference=16))
    library.set_sensor_prefilter(SensorPrefilter.from_metric(library.sensor_metric, min_shapes=0, n_first=8))
    return library


def _queries(library: Library, rng: np.random.Generator, n: int, noise: float = 0.2) -> list[np.ndarray]:
    """Library shapes turned at random, with radial noise up to ``noise``."""
    out = []
    for _ in range(n):
        radii = np.roll(library.radii[rng.integers(len(library))], int(rng.integers(72)))
        out.append(radii * (1 + rng.uniform(0, noise) * rng.standard_normal(72)))
    return out


def test_small_libraries_are_scanned_whole(default_lib, paper_lib):
    assert default_lib.prefilter is None and paper_lib.prefilter is None


def test_the_bound_is_below_every_shapes_best_distance(large_lib):
    prefilter = large_lib.prefilter
    assert prefilter is not None
    templates = large_lib.scan_templates
    for radii in _queries(large_lib, np.random.default_rng(1), 2, noise=0.05):
        q = sample_term(radii, SMALL_FACE)
        _, omega = templates.coordinates(q)
        exact = rotation_scores(radii, large_lib, metric="eigenspace").min(axis=0) ** 2
        bound = prefilter.bounds(omega)
        assert np.all(bound <= exact + 1e-9)
        # and it is tight enough to prune: most shapes are bounded above the nearest one
        assert np.mean(bound > exact.min()) > 0.5


@pytest.mark.parametrize("metric", ["eigenspace", "face"])
def test_pruned_scan_finds_the_exhaustive_nearest(large_lib, metric):
    whole = large_lib.scanned_whole()
    config = MatchConfig(metric=metric)
    for radii in _queries(large_lib, np.random.default_rng(2), 8):
        pruned, full = match_radii(radii, large_lib, config), match_radii(radii, whole, config)
        assert pruned.nearest == full.nearest
        assert pruned.distance == pytest.approx(full.distance, rel=1e-6, abs=1e-9)
        assert pruned.angle_deg == pytest.approx(full.angle_deg, abs=1e-6)
        # MScore's mean uses estimates for the shapes left out: close, not equal.
        assert pruned.mscore == pytest.approx(full.mscore, abs=0.03)
        k = large_lib.index(pruned.nearest)
        assert pruned.distances[k] == pytest.approx(full.distances[k], rel=1e-6, abs=1e-9)
        assert np.all(pruned.distances >= pruned.distances[k])


def test_a_library_shape_matches_itself_through_the_pruned_scan(large_lib):
    for k in (0, 123, len(large_lib) - 1):
        m = match_radii(np.roll(large_lib.radii[k], 5), large_lib)
        assert m.nearest == large_lib.names[k]
        assert m.distance == pytest.approx(0.0, abs=1e-6)


def test_group_norms_bound_the_coordinates_distance(rng):
    a, b = rng.normal(size=(2, 40))
    fa, fb = features_of(a[None], 8, 5)[0], features_of(b[None], 8, 5)[0]
    assert fa.shape == (8 + 32 // 5 + 1,)
    assert np.linalg.norm(fa - fb) <= np.linalg.norm(a - b) * (1 + 1e-6)
    np.testing.assert_allclose(fa[:8], a[:8], rtol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(fa), np.linalg.norm(a), rtol=1e-6)


def test_prefilter_grows_by_one_shape(large_lib, rng):
    prefilter = large_lib.prefilter
    omega = rng.normal(size=large_lib.basis.n_components)
    grown = prefilter.with_shape(omega)
    assert grown.n_shapes == prefilter.n_shapes + 1
    np.testing.assert_allclose(
        grown.features[-1], features_of(omega[None], prefilter.n_lead, prefilter.group)[0]
    )
    assert isinstance(grown, Prefilter)


def test_the_coarse_bound_is_below_the_fine_one_and_the_truth(large_lib):
    prefilter = large_lib.prefilter
    templates = large_lib.scan_templates
    for radii in _queries(large_lib, np.random.default_rng(4), 3):
        q = sample_term(radii, SMALL_FACE)
        spectrum, omega = templates.coordinates(q)
        extra = np.maximum(templates.centered_norm_sq(q, spectrum) - np.einsum("ac,ac->a", omega, omega), 0.0)
        for metric, extra_sq in (("eigenspace", None), ("face", extra)):
            exact = rotation_scores(radii, large_lib, metric=metric).min(axis=0) ** 2
            coarse = prefilter.coarse_bounds(omega, extra_sq)
            assert np.all(coarse <= exact + 1e-9)
            assert np.all(coarse <= prefilter.bounds(omega, extra_sq) + 1e-6)


def test_the_sensor_bound_is_below_every_shapes_sensor_distance(large_lib):
    metric = large_lib.sensor_metric
    sensor_filter = large_lib.sensor_prefilter
    for radii in _queries(large_lib, np.random.default_rng(5), 4):
        exact = metric.squared_distances(radii).min(axis=0)
        bound = sensor_filter.bounds(metric.sample_spectrum(radii), metric.n_angles)
        assert np.all(bound <= exact + 1e-9)
        assert np.mean(bound > exact.min()) > 0.5  # and it prunes
        chosen = sensor_filter.select(radii, metric)
        assert chosen.nearest == int(np.argmin(exact))
        np.testing.assert_allclose(chosen.dist_sq, exact[chosen.index], rtol=1e-9, atol=1e-12)
        assert np.all(chosen.bound[np.setdiff1d(np.arange(len(large_lib)), chosen.index)] > exact.min())


@pytest.mark.parametrize("metric", ["auto", "sensor"])
def test_pruned_sensor_ranking_finds_the_exhaustive_nearest(large_lib, metric):
    whole = large_lib.scanned_whole()
    assert whole.sensor_prefilter is None
    config = MatchConfig(metric=metric)
    for radii in _queries(large_lib, np.random.default_rng(6), 8):
        pruned, full = match_radii(radii, large_lib, config), match_radii(radii, whole, config)
        assert pruned.nearest == full.nearest
        assert pruned.sensor_distance == pytest.approx(full.sensor_distance, rel=1e-9, abs=1e-12)
        assert pruned.interesting == full.interesting
        assert pruned.angle_deg == pytest.approx(full.angle_deg, abs=1e-6)
        # Shapes left out carry a lower bound of their sensor distance, above the nearest one.
        assert np.all(pruned.sensor_distances <= full.sensor_distances + 1e-9)
        assert pruned.mscore == pytest.approx(full.mscore, abs=0.05)


def test_a_large_librarys_file_keeps_its_sensor_metric(large_lib, tmp_path, monkeypatch):
    import rockscan.core.library
    from rockscan.core.errors import LibraryError
    from rockscan.io import load_library, save_library

    monkeypatch.setattr(rockscan.core.library, "EXACT_LIMIT", 100)  # 200 shapes count as large
    save_library(large_lib, tmp_path / "large.npz")
    loaded = load_library(tmp_path / "large.npz")
    assert "sensor_metric" in loaded.__dict__  # read, not made on first use
    stored, made = loaded.sensor_metric, large_lib.sensor_metric
    for name in ("weights", "spectra", "norm_sq"):
        np.testing.assert_array_equal(getattr(stored, name), getattr(made, name))
    assert (stored.noise_band, stored.noise_gain, stored.noise_floor, stored.tolerance) == (
        made.noise_band,
        made.noise_gain,
        made.noise_floor,
        made.tolerance,
    )
    radii = _queries(large_lib, np.random.default_rng(8), 1)[0]
    assert match_radii(radii, loaded).sensor_distance == match_radii(radii, large_lib).sensor_distance
    # A file whose stored metric does not fit its shapes is refused in one line.
    with np.load(tmp_path / "large.npz") as archive:
        arrays = {k: archive[k] for k in archive.files}
    arrays["sensor_spectra"] = arrays["sensor_spectra"][:-1]
    np.savez(tmp_path / "bad.npz", **arrays)
    with pytest.raises(LibraryError, match="inconsistent"):
        load_library(tmp_path / "bad.npz")


@pytest.mark.parametrize("metric", ["eigenspace", "face"])
def test_the_nearest_other_shape_through_the_pruned_scan_is_the_exhaustive_one(large_lib, metric):
    # A library shape is its own nearest (distance 0); the pruning must leave it
    # out and still find the nearest of the others, as a scan of every shape does.
    for k in range(0, len(large_lib), 9):
        whole = rotation_scores(large_lib.radii[k], large_lib, metric=metric).min(axis=0)
        whole[k] = np.inf
        assert nearest_other_distance(large_lib, k, metric=metric) == pytest.approx(whole.min(), rel=1e-6)


def test_what_a_library_caches_is_read_only(large_lib):
    # The caches are shared by every later match (default_library() is one
    # object): an edit of one would change every later answer.
    cached = {
        "reference_map": large_lib.reference_map,
        "sensor_metric.spectra": large_lib.sensor_metric.spectra,
        "sensor_metric.weights": large_lib.sensor_metric.weights,
        "scan_templates.spectra": large_lib.scan_templates.spectra,
        "scan_templates.omega_norm_sq": large_lib.scan_templates.omega_norm_sq,
        "prefilter.features": large_lib.prefilter.features,
        "prefilter.reference": large_lib.prefilter.reference,
        "sensor_prefilter.features": large_lib.sensor_prefilter.features,
        "sensor_prefilter.centre": large_lib.sensor_prefilter.centre,
    }
    for name, array in cached.items():
        with pytest.raises(ValueError, match="read-only"):
            array.flat[0] = 0
        assert not array.flags.writeable, name
