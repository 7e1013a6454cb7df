"""Calibration: the sensor model, the sensor distance, per-shape cutoffs, old library files."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import PAPER_SHAPES
from hypothesis import given
from hypothesis import strategies as st

from rockscan.cli import main
from rockscan.core.calibrate import (
    KEEP_CROWDED,
    Calibration,
    SensorMetric,
    calibrate,
    cutoff_at,
    log_noise_variance,
    simulate_radii,
)
from rockscan.core.errors import LibraryError, ParameterError
from rockscan.core.library import Library, ShapeSpec, noise_origins
from rockscan.core.match import MatchConfig, match_radii
from rockscan.core.polar import (
    contour_radii,
    polar_angles,
    polygon_centroid_xy,
    recenter_radii,
    rowcol_from_xy,
)
from rockscan.core.superformula import SuperformulaParams, shape_radii
from rockscan.io import RecalibratedWarning, load_library, save_library

STAR = shape_radii(SuperformulaParams(5, 5, 2, 7, 7), 360)
BLUNT = shape_radii(PAPER_SHAPES["three-faced-blunt"], 360)
EGG = shape_radii(SuperformulaParams(1, 1, 0.75, 0.75, 0.75), 360)


@pytest.fixture(scope="module")
def small_lib() -> Library:
    return Library.from_radii(["star", "blunt", "egg"], np.array([STAR, BLUNT, EGG]))


def test_log_noise_variance_is_the_noise_squared_when_small():
    assert log_noise_variance(0.0) == 0.0
    # log(1 + e) ~ e - e**2/2: variance sigma**2 (1 + sigma**2/2) to second order.
    assert log_noise_variance(0.01) == pytest.approx(1e-4, rel=1e-3)
    assert log_noise_variance(0.05) == pytest.approx(0.05**2, rel=0.02)


def test_a_noise_free_circle_is_measured_as_a_circle():
    measured = simulate_radii(np.ones(360), np.zeros(8), rng=1)
    # The polygon's chords sag by 1 - cos(pi/360) between vertices; blur and
    # a 0.3 px jitter at radii of 40-200 px add at most a few thousandths.
    np.testing.assert_allclose(measured / measured.mean(axis=1, keepdims=True), 1.0, atol=0.03)


def test_simulated_noise_has_the_asked_spread():
    measured = simulate_radii(STAR, np.full(64, 0.1), rng=2)
    spread = np.std(np.log(measured / STAR), axis=1)
    # Each vertex carries 10%; rays between vertices and the blur average a little of it away.
    assert 0.06 < np.median(spread) < 0.11


@given(shift=st.integers(0, 359), scale=st.floats(1e-3, 1e3))
def test_the_sensor_distance_finds_a_shape_at_any_rotation_and_scale(small_lib, shift, scale):
    metric = small_lib.sensor_metric
    dist, found = metric.distances(np.roll(STAR, shift) * scale)
    assert dist[0] == pytest.approx(0.0, abs=1e-6)
    assert dist[1] > 1.0 and dist[2] > 1.0
    assert (found[0] - shift) % 72 == 0  # the star's five-fold symmetry


@given(noise=st.floats(0.0, 0.3), seed=st.integers(0, 1000))
def test_one_sample_gives_what_each_method_gives(small_lib, noise, seed):
    """What a match asks of a sample, from one spectrum: the same numbers to the last bit."""
    metric = small_lib.sensor_metric
    radii = simulate_radii(BLUNT, noise, rng=seed)[0]
    sample = metric.sample(radii)
    np.testing.assert_array_equal(sample.spectrum, metric.sample_spectrum(radii))
    assert sample.noise_energy == float(metric.noise_energy(radii))
    assert sample.noise_level == float(metric.noise_level(radii))
    dist_sq = metric.squared_distances(radii)
    np.testing.assert_array_equal(metric.spectrum_distances(sample.spectrum), dist_sq)
    best = dist_sq.min(axis=0)
    np.testing.assert_array_equal(sample.corrected(best), metric.corrected(radii, best))
    assert np.all(sample.corrected(best) <= np.sqrt(best))


def test_with_every_weight_one_the_sensor_distance_is_the_log_radii_matched_filter():
    metric = SensorMetric.from_radii(np.array([STAR, EGG]))
    flat = SensorMetric(
        weights=np.ones_like(metric.weights),
        spectra=np.fft.rfft(np.log(np.array([STAR, EGG]) / 1.0), axis=1, norm="ortho"),
        norm_sq=np.array([np.sum(np.log(STAR) ** 2), np.sum(np.log(EGG) ** 2)]),
        tolerance=0.2,
    )
    sample = np.roll(BLUNT, 17)
    x = np.log(sample / sample.mean())
    direct = np.array([[np.sum((np.roll(x, -a) - np.log(r)) ** 2) for r in (STAR, EGG)] for a in range(360)])
    np.testing.assert_allclose(flat.squared_distances(sample), direct, rtol=1e-9, atol=1e-9)


def test_calibration_is_reproducible_and_per_shape(small_lib):
    again = calibrate(small_lib.radii)
    np.testing.assert_array_equal(again.cutoffs, small_lib.cutoffs)
    assert small_lib.calibration.tolerance == 0.2
    assert np.all(small_lib.cutoffs > 0) and np.unique(small_lib.cutoffs).size == 3
    assert np.all(np.isfinite(small_lib.calibration.spacing))


def test_samples_within_the_tolerance_are_accepted_and_far_shapes_rejected(small_lib):
    # Enough samples that the shares are measured, not drawn: at 200 a share's
    # standard error is under 2.5 points, and each bound lies 3 of them below
    # what the calibration promises.
    rng = np.random.default_rng(4)
    for k, radii in enumerate(small_lib.radii):
        for noise in (0.0, 0.1, 0.2):
            measured = simulate_radii(radii, np.full(200, noise), rng=rng)
            matches = [match_radii(np.roll(r, 31 * k), small_lib) for r in measured]
            assert np.mean([m.nearest == small_lib.names[k] for m in matches]) >= 0.97, (k, noise)
            # At the tolerance a cutoff keeps about 90% (crowded shapes) to 97% of
            # the calibration's own samples; a sample's noise is estimated, not known.
            accepted = np.mean([m.interesting for m in matches])
            assert accepted >= (0.98 if noise <= 0.1 else 0.8), (k, noise, accepted)
    far = shape_radii(SuperformulaParams(8, 8, 0.6, 3, 3), 360)
    m = match_radii(far, small_lib)
    assert not m.interesting and m.decided_by == "calibrated-cutoff"
    assert m.sensor_distance > m.cutoff_distance


def test_a_larger_tolerance_allows_more():
    lib = Library.from_radii(["star", "blunt", "egg"], np.array([STAR, BLUNT, EGG]), tolerance=0.1)
    wide = Library.from_radii(["star", "blunt", "egg"], np.array([STAR, BLUNT, EGG]), tolerance=0.3)
    assert lib.tolerance == 0.1 and wide.tolerance == 0.3
    sample = simulate_radii(STAR, 0.15, rng=5)[0]
    assert match_radii(sample, wide).cutoff_distance > match_radii(sample, lib).cutoff_distance


def test_the_spread_between_example_photos_counts():
    # Two examples of one rock that differ by a smooth 4% deformation.
    theta = 2 * np.pi * np.arange(360) / 360
    examples = np.array(
        [BLUNT * (1 + 0.04 * np.cos(3 * theta + 1)), BLUNT * (1 - 0.04 * np.cos(3 * theta + 1))]
    )
    radii = np.array([STAR, examples.mean(axis=0), EGG])
    plain = calibrate(radii)
    spread = calibrate(radii, examples=[None, examples, None])
    assert spread.cutoffs[1] > plain.cutoffs[1]
    with pytest.raises(ParameterError, match="one entry"):
        calibrate(radii, examples=[None])
    # An empty array of examples: an IndexError of a modulo by zero.
    with pytest.raises(ParameterError, match="one or more outlines"):
        calibrate(radii, examples=[None, np.zeros((0, 360)), None])


def test_a_one_shape_library_decides_by_its_cutoff():
    lib = Library.from_shapes([ShapeSpec("blunt", PAPER_SHAPES["three-faced-blunt"])])
    assert len(lib) == 1 and lib.basis.n_components == 0
    assert not np.isfinite(lib.calibration.spacing[0])
    same = match_radii(simulate_radii(lib.radii[0], 0.1, rng=7)[0], lib)
    assert same.nearest == "blunt" and same.interesting
    other = match_radii(STAR, lib)
    assert other.nearest == "blunt" and not other.interesting
    # MScore degenerates with one shape (w is its own mean): reported, not deciding.
    assert same.mscore == other.mscore == 1.0


def test_a_two_shape_library_flags_what_belongs():
    lib = Library.from_radii(["star", "egg"], np.array([STAR, EGG]))
    rng = np.random.default_rng(8)
    flagged = [match_radii(r, lib).interesting for r in simulate_radii(STAR, np.full(10, 0.15), rng=rng)]
    assert sum(flagged) >= 9
    long = shape_radii(SuperformulaParams(4, 4, 2, 2, 2, b=0.35), 360)
    assert not match_radii(long, lib).interesting


def test_bad_calibration_settings_are_refused():
    with pytest.raises(ParameterError, match="tolerance must be a number from 0 to 1"):
        calibrate(np.array([STAR]), tolerance=2.0)
    with pytest.raises(ParameterError, match="positive"):
        calibrate(np.array([-STAR]))
    with pytest.raises(ParameterError, match="all of one length"):
        Calibration(cutoffs=np.ones(2), spacing=np.ones(3), crowded=np.zeros(2), calibrated=np.ones(2))


def _old_format_file(path, lib: Library) -> None:
    """A library file as rockscan wrote it before cutoffs were stored (format version 1)."""
    meta = {
        "format": "rockscan-library",
        "version": 1,
        "rockscan": "0.1.0",
        "names": list(lib.names),
        "params": [p.as_dict() if p is not None else None for p in lib.params],
        "face": lib.face_config.to_dict(),
    }
    np.savez(
        path,
        metadata=np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8),
        radii=lib.radii,
        interest=lib.interest,
        symmetry=lib.symmetry,
        mean=lib.basis.mean,
        components=lib.basis.components,
        eigenvalues=lib.basis.eigenvalues,
        weights=lib.basis.weights,
    )


def test_a_library_file_from_before_cutoffs_loads_recalibrated(tmp_path, small_lib):
    path = tmp_path / "old.npz"
    _old_format_file(path, small_lib)
    with pytest.warns(RecalibratedWarning, match="calibrated them now"):
        old = load_library(path)
    np.testing.assert_array_equal(old.cutoffs, small_lib.cutoffs)
    assert old.calibration.note == "calibrated when loaded"
    result = CliRunner().invoke(main, ["library", "show", str(path)])
    assert result.exit_code == 0
    assert "rockscan: note:" in result.stderr and "cutoff" in result.stdout


def test_cutoffs_round_trip_through_a_library_file(tmp_path):
    lib = Library.from_radii(["star", "egg"], np.array([STAR, EGG]), tolerance=0.12)
    save_library(lib, tmp_path / "lib.npz")
    back = load_library(tmp_path / "lib.npz")
    np.testing.assert_array_equal(back.cutoffs, lib.cutoffs)
    np.testing.assert_array_equal(back.calibration.clean_cutoffs, lib.calibration.clean_cutoffs)
    np.testing.assert_array_equal(back.calibration.spacing, lib.calibration.spacing)
    assert back.tolerance == 0.12


def test_cutoffs_of_an_earlier_calibration_are_recalibrated_on_load(tmp_path):
    lib = Library.from_radii(["star", "egg"], np.array([STAR, EGG]), tolerance=0.12)
    save_library(lib, tmp_path / "lib.npz")
    with np.load(tmp_path / "lib.npz") as archive:
        arrays = {k: archive[k] for k in archive.files if k != "cutoff_clean"}
    meta = json.loads(arrays["metadata"].tobytes().decode("utf-8"))
    meta["calibration"]["version"] = 1
    arrays["metadata"] = np.frombuffer(json.dumps(meta).encode("utf-8"), dtype=np.uint8)
    arrays["cutoffs"] = arrays["cutoffs"] * 0.5  # version 1 meant another test
    np.savez(tmp_path / "v1.npz", **arrays)
    with pytest.warns(RecalibratedWarning, match="earlier calibration"):
        back = load_library(tmp_path / "v1.npz")
    np.testing.assert_array_equal(back.cutoffs, lib.cutoffs)
    assert back.tolerance == 0.12 and back.calibration.note == "calibrated when loaded"


def test_the_cutoff_runs_from_clean_to_the_tolerance_with_the_noise():
    cal = Calibration(
        cutoffs=np.array([2.0, 1.0]),
        clean_cutoffs=np.array([1.0, 1.0]),
        spacing=np.full(2, np.inf),
        crowded=np.zeros(2, bool),
        calibrated=np.ones(2, bool),
        tolerance=0.2,
    )
    assert [cutoff_at(cal, 0, v) for v in (0.0, 0.05, 0.1, 0.2, 0.5)] == [1.0, 1.25, 1.5, 2.0, 2.0]
    assert cutoff_at(cal, 1, 0.1) == 1.0
    # Without clean cutoffs, one cutoff for every noise.
    plain = Calibration(
        cutoffs=np.ones(1), spacing=np.ones(1), crowded=np.zeros(1, bool), calibrated=np.ones(1, bool)
    )
    assert plain.clean_cutoffs.tolist() == [1.0] and cutoff_at(plain, 0, 0.13) == 1.0


def test_both_ends_of_the_cutoff_lie_between_their_samples(small_lib):
    cal = calibrate(small_lib.radii, keep_samples=True)
    s = cal.samples
    clean_out, noisy_out = s.outside[:, 0::2], s.outside[:, 1::2]
    for i, k in enumerate(s.shapes):
        # Clean samples lie nearer their shape than noisy ones, and clean shapes at
        # the spacing are told apart: the clean cutoff keeps the one, refuses the other.
        assert np.mean(s.inside_clean[i]) < np.mean(s.inside[i])
        assert np.quantile(s.inside_clean[i], 0.97) <= cal.clean_cutoffs[k] <= np.quantile(clean_out[i], 0.03)
        if cal.crowded[k]:
            # The tolerance's noise reaches shapes at the spacing: its promise is kept.
            assert np.mean(s.inside[i] <= cal.cutoffs[k]) >= KEEP_CROWDED
            assert np.quantile(s.inside[i], 0.97) > np.quantile(noisy_out[i], 0.03)
        else:
            assert np.quantile(s.inside[i], 0.97) <= cal.cutoffs[k] <= np.quantile(noisy_out[i], 0.03)
    assert not cal.crowded.all()


def test_incomplete_stored_cutoffs_are_refused(tmp_path):
    lib = Library.from_radii(["star", "egg"], np.array([STAR, EGG]))
    save_library(lib, tmp_path / "lib.npz")
    with np.load(tmp_path / "lib.npz") as archive:
        arrays = {k: archive[k] for k in archive.files if k != "cutoff_spacing"}
    np.savez(tmp_path / "cut.npz", **arrays)
    with pytest.raises(LibraryError, match="cutoffs are incomplete"):
        load_library(tmp_path / "cut.npz")


def test_library_build_takes_a_tolerance_and_show_prints_the_cutoffs(tmp_path):
    spec = tmp_path / "spec.toml"
    spec.write_text(
        '[[shape]]\nname = "star"\nm1 = 5\nm2 = 5\nn1 = 2\nn2 = 7\nn3 = 7\n'
        '[[shape]]\nname = "egg"\nm1 = 1\nm2 = 1\nn1 = 0.75\nn2 = 0.75\nn3 = 0.75\n'
    )
    out = tmp_path / "lib.npz"
    runner = CliRunner()
    built = runner.invoke(main, ["library", "build", str(spec), "-o", str(out), "--tolerance", "0.1"])
    assert built.exit_code == 0, built.output
    assert "calibrated for 10% outline noise" in built.output
    shown = runner.invoke(main, ["library", "show", str(out), "--json"])
    rows = [json.loads(line) for line in shown.stdout.splitlines()]
    assert [r["tolerance"] for r in rows] == [0.1, 0.1]
    np.testing.assert_allclose([r["cutoff"] for r in rows], load_library(out).cutoffs)
    bad = runner.invoke(main, ["library", "build", str(spec), "-o", str(out), "--tolerance", "5"])
    assert bad.exit_code == 2 and "'--tolerance': 5 is not in the range 0 <= x <= 1" in bad.output


def test_an_explicit_distance_cutoff_replaces_the_calibrated_one(small_lib):
    m = match_radii(STAR, small_lib, MatchConfig(distance_cutoff=-1.0))
    assert not m.interesting and m.decided_by == "distance-cutoff" and m.cutoff_distance == -1.0
    assert match_radii(STAR, small_lib).decided_by == "calibrated-cutoff"


#: A drop (m = 1): its formula's origin lies far from its centroid, near the blunt end.
DROP = SuperformulaParams(1, 1, 2.4, 12, 12)


def _paper_noise(params: SuperformulaParams, noise: float, rng: np.random.Generator) -> np.ndarray:
    """The paper's Fig. 11 noise written out apart from the simulator: the formula's
    radii about its own origin times 1 + e, the polygon measured about its centroid."""
    theta = polar_angles(360)
    r = params.radii(theta) * np.maximum(1 + rng.normal(0, noise, 360), 0.05)
    turn = rng.uniform(0, 2 * np.pi)
    xy = np.column_stack([r * np.cos(theta + turn), r * np.sin(theta + turn)])
    xy = xy - polygon_centroid_xy(xy)
    return contour_radii(rowcol_from_xy(xy, (0.0, 0.0)), (0.0, 0.0), 360)


def test_a_formulas_origin_is_where_its_noise_is_drawn_about():
    radii = np.array([shape_radii(DROP, 360), STAR])
    origins = noise_origins([DROP, SuperformulaParams(5, 5, 2, 7, 7)], radii)
    centered, centroid = recenter_radii(DROP.radii(polar_angles(360)))
    np.testing.assert_allclose(origins[0], -centroid / centered.mean(), atol=1e-4)
    assert origins[0, 0] > 0.5  # far off the centroid
    np.testing.assert_array_equal(origins[1], 0.0)  # point symmetric: the centroid
    np.testing.assert_array_equal(noise_origins([DROP, None], radii)[1], 0.0)
    assert noise_origins([None, None], radii) is None and noise_origins(None, radii) is None


def test_noise_about_an_off_centre_origin_is_larger_on_its_far_side():
    drop = shape_radii(DROP, 360)
    origin = noise_origins([DROP], drop[None])[0]
    measured = simulate_radii(drop, np.full(400, 0.1), rng=12, origins=origin)
    # Per ray, the spread of log radii over the samples: rays pointing away from the
    # origin (+x side seen from the centroid is toward it) carry more of it.
    spread = np.std(np.log(measured / drop), axis=0)
    theta = polar_angles(360)
    toward, away = spread[np.cos(theta) > 0.7].mean(), spread[np.cos(theta) < -0.7].mean()
    assert away > 1.5 * toward
    centred = np.std(np.log(simulate_radii(drop, np.full(400, 0.1), rng=12) / drop), axis=0)
    assert centred[np.cos(theta) < -0.7].mean() < 1.2 * centred[np.cos(theta) > 0.7].mean()


def test_an_origin_outside_the_outline_falls_back_to_the_centroid():
    measured = simulate_radii(STAR, np.full(3, 0.2), rng=13, origins=(5.0, 0.0))
    assert np.all(np.isfinite(measured)) and np.all(measured > 0)
    with pytest.raises(ParameterError, match="origins"):
        simulate_radii(STAR, 0.2, rng=13, origins=(np.nan, 0.0))
    with pytest.raises(ParameterError, match="origins"):
        calibrate(np.array([STAR]), origins=np.zeros((2, 2)))


def test_a_drop_built_from_its_formula_accepts_the_papers_noise():
    specs = [ShapeSpec("drop", DROP), ShapeSpec("star", SuperformulaParams(5, 5, 2, 7, 7))]
    specs.append(ShapeSpec("blunt", SuperformulaParams(3, 3, 4.5, 10, 10)))
    lib = Library.from_shapes(specs)
    centroid_only = Library.from_radii(lib.names, lib.radii)  # no formula: noise about the centroid
    rng = np.random.default_rng(14)
    samples = [_paper_noise(DROP, 0.2, rng) for _ in range(200)]
    accepted = np.mean([match_radii(r, lib).interesting for r in samples])
    # Measured 0.995 (and 0.89 with the noise simulated about the centroid).
    assert accepted >= 0.95
    assert accepted > np.mean([match_radii(r, centroid_only).interesting for r in samples])
    assert lib.calibration.cutoffs[0] > centroid_only.calibration.cutoffs[0]


def test_one_spiky_shape_does_not_set_every_other_shapes_cutoff_to_zero(default_specs):
    # Its own harmonics filled the noise band: the noise it implied excused
    # every other shape's distance, and 12 of the 14 default shapes showed cutoff 0.
    from rockscan.run.pipeline import library_from_spec

    spiky = ShapeSpec("spiky", SuperformulaParams(m1=7.0, m2=7.0, n1=0.554, n2=7.945, n3=7.945))
    plain = library_from_spec(list(default_specs))
    lib = library_from_spec([*default_specs, spiky])
    n = len(plain)
    assert np.all(lib.cutoffs[:n] > 0.5 * plain.cutoffs)
    rng = np.random.default_rng(4)
    for k in range(n):
        samples = simulate_radii(np.repeat(lib.radii[k : k + 1], 8, axis=0), 0.1, rng=rng)
        matches = [match_radii(r, lib) for r in samples]
        assert sum(m.nearest == lib.names[k] for m in matches) >= 6
        assert sum(m.interesting and m.nearest == lib.names[k] for m in matches) >= 6
    # Nor is everything accepted now: a four-pointed star is none of them.
    far = shape_radii(SuperformulaParams(m1=4.0, m2=4.0, n1=0.3, n2=0.3, n3=0.3), 360)
    assert not match_radii(far, lib).interesting
