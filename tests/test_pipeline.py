"""The stages composed: photos in, interface records out."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from PIL import Image

from rockscan.core.errors import NoRockFoundError, ParameterError
from rockscan.core.outline import polygon_area_centroid
from rockscan.core.render import RenderConfig, render_photo
from rockscan.core.segment import SegmentConfig
from rockscan.core.superformula import shape_radii
from rockscan.io import default_spec_path, read_spec
from rockscan.io.photos import write_photo
from rockscan.run.pipeline import ClassifyConfig, align_radii, classify_image, classify_path, measure_rocks

SPECS = {s.name: s.params for s in read_spec(default_spec_path())}
INTERFACE_KEYS = {"match", "nearest", "mscore", "distance", "angle_deg", "interesting", "centroid"}
ROCK_KEYS = INTERFACE_KEYS | {"outline", "area_px", "segmentation_score"}
MM_KEYS = {"area_mm2", "equivalent_diameter_mm", "major_axis_mm", "minor_axis_mm"}


def angle_error(found: float, truth: float, symmetry: int) -> float:
    if symmetry == 0:
        return 0.0
    period = 360.0 / symmetry
    diff = (found - truth) % period
    return min(diff, period - diff)


@pytest.mark.parametrize("name", ["teardrop", "three-faced-blunt", "five-armed-star", "shard"])
def test_rendered_rocks_are_classified_with_angle_and_centroid(default_lib, name):
    photo = render_photo(SPECS[name], RenderConfig(rows=360, cols=480), rng=5, name=name)
    rock = classify_image(photo.pixels, default_lib)[0]
    assert rock.match.nearest == name
    assert angle_error(rock.match.angle_deg, photo.truth["angle_deg"], rock.match.symmetry) < 1.0
    np.testing.assert_allclose(rock.centroid_xy, photo.truth["centroid_xy"], atol=1.0)
    assert rock.outline.area_px == pytest.approx(photo.truth["area_px"], rel=0.02)
    # The radii are the outline's, in photo pixels, at the library's angles.
    assert rock.radii.shape == (default_lib.face_config.n_angles,)
    assert rock.radii.mean() == pytest.approx(photo.truth["scale_px"], rel=0.03)


def test_records_hold_the_interface_keys(tmp_path, default_lib):
    photo = render_photo(SPECS["egg"], RenderConfig(rows=240, cols=320), rng=1, name="egg")
    path = tmp_path / "egg.png"
    write_photo(photo, path)
    result = classify_path(path, default_lib)
    assert result.ok and result.error is None and len(result.rocks) == 1
    (record,) = result.records()
    assert ROCK_KEYS <= set(record) and record["path"] == str(path)
    assert not MM_KEYS & set(record)
    assert record["nearest"] == "egg" and isinstance(record["interesting"], bool)
    assert isinstance(record["centroid"], list) and len(record["centroid"]) == 2
    assert record["index"] == 0 and record["area_px"] > 0


def test_a_bad_photo_is_an_error_result_never_an_exception(tmp_path, default_lib):
    missing = classify_path(tmp_path / "nothing.png", default_lib)
    assert not missing.ok and missing.rocks == () and "not found" in missing.error
    flat = tmp_path / "flat.png"
    Image.fromarray(np.full((64, 96, 3), 90, np.uint8)).save(flat)
    result = classify_path(flat, default_lib)
    assert result.records() == [{"path": str(flat), "error": result.error}]
    assert result.error.startswith("no rock found")
    with pytest.raises(NoRockFoundError):
        classify_image(np.full((50, 50), 40, np.uint8), default_lib)


def test_a_photo_decoded_at_reduced_size_reports_full_size_pixels(default_lib):
    photo = render_photo(SPECS["lens"], RenderConfig(rows=480, cols=640), rng=2, name="lens")
    full = measure_rocks(photo.pixels, 360)[1][0].outline
    # As a reader decoding at half size: each pixel the mean of a 2 x 2 block.
    reduced = cv2.resize(photo.pixels, (320, 240), interpolation=cv2.INTER_AREA)
    half = measure_rocks(reduced, 360, scale=2.0)[1][0].outline
    np.testing.assert_allclose(half.centroid_rowcol, full.centroid_rowcol, atol=0.3)
    assert half.area_px == pytest.approx(full.area_px, rel=0.02)


def test_all_rocks_come_back_main_first(default_lib):
    from rockscan.core.render import render_scene

    names = ["egg", "diamond", "pentagonal"]
    scene = render_scene([SPECS[n] for n in names], RenderConfig(area_fraction=0.18), rng=8, names=names)
    rocks = classify_image(scene.pixels, default_lib, all_rocks=True)
    assert [r.index for r in rocks] == [0, 1, 2]
    assert sorted(r.match.nearest for r in rocks) == sorted(names)
    areas = [r.outline.area_px for r in rocks]
    assert areas == sorted(areas, reverse=True)


def test_the_segmentation_settings_are_used(default_lib):
    photo = render_photo(SPECS["egg"], RenderConfig(rows=240, cols=320, rock_lighter=True), rng=4)
    # In gray: in colour, the hue steps may cut a wrong region back to the
    # rock of another hue inside it, whatever its brightness.
    gray = cv2.cvtColor(photo.pixels, cv2.COLOR_RGB2GRAY)
    config = ClassifyConfig(segment=SegmentConfig(polarity="dark"))
    # Told the rock is dark, the light rock is not found (a darker patch of ground may be).
    rocks = classify_image(gray, default_lib)
    assert rocks[0].match.nearest == "egg"
    try:
        wrong = classify_image(gray, default_lib, config)
    except NoRockFoundError:
        wrong = []
    assert not wrong or np.hypot(*np.subtract(wrong[0].centroid_xy, rocks[0].centroid_xy)) > 5


def test_align_radii_turns_every_row_to_the_first():
    radii = shape_radii(SPECS["teardrop"], 360)
    rows = np.stack([radii, np.roll(radii, 40), np.roll(radii, -123) * 3.0])
    aligned = align_radii(rows)
    np.testing.assert_allclose(aligned[1], radii, rtol=1e-12)
    np.testing.assert_allclose(aligned[2], 3.0 * radii, rtol=1e-12)


# ---------------------------------------------------------------- outlines and sizes


def screen_signed_area(xy):
    """Shoelace area with y up (as on screen): positive for counter-clockwise."""
    x, y = np.asarray(xy, dtype=float).T
    y = -y
    return 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)


def distance_to_polygon(points, polygon):
    """Each point's distance from the closed polygon's edges."""
    start = polygon[None, :, :]
    edge = np.roll(polygon, -1, axis=0)[None, :, :] - start
    rel = points[:, None, :] - start
    t = np.clip((rel * edge).sum(-1) / np.maximum((edge * edge).sum(-1), 1e-12), 0.0, 1.0)
    return np.min(np.hypot(*(rel - t[..., None] * edge).transpose(2, 0, 1)), axis=1)


@pytest.mark.parametrize("name", ["teardrop", "five-armed-star", "shard", "egg"])
@pytest.mark.parametrize("size", [(64, 64, 0.01), (240, 320, None), (1200, 1600, None)])
def test_the_reported_outline_has_the_rocks_area_and_centroid(default_lib, name, size):
    # A rock of 1% of a 64 x 64 photo (about 40 px): simplification cut 4-5% off its outline's area.
    rows, cols, share = size
    config = RenderConfig(rows=rows, cols=cols, **({} if share is None else {"area_fraction": share}))
    photo = render_photo(SPECS[name], config, rng=3, name=name)
    rock = classify_image(photo.pixels, default_lib)[0]
    record = rock.to_dict()
    outline = np.array(record["outline"])
    assert outline.ndim == 2 and outline.shape[1] == 2 and 64 <= len(outline) <= 400
    assert not np.allclose(outline[0], outline[-1])  # closed implicitly
    area, centroid = polygon_area_centroid(outline)
    # Within the simplification's 0.2% and the 0.01 px rounding of the vertices (0.3% at 40 px).
    assert area == pytest.approx(record["area_px"], rel=0.005)
    assert np.hypot(*(centroid - record["centroid"])) < 1.0
    assert screen_signed_area(outline) > 0
    # Every reported vertex lies on the traced outline, within a quarter of its vertex spacing
    # (about a quarter of a working pixel), to the 0.01 px of the report.
    traced = rock.outline.contour_rowcol[:, ::-1]
    spacing = np.median(np.hypot(*np.diff(traced, axis=0).T))
    assert distance_to_polygon(outline, traced).max() < 0.25 * spacing + 0.01
    assert 0.0 <= record["segmentation_score"] <= 1.0


def test_every_rock_of_a_scene_has_its_outline(default_lib):
    from rockscan.core.render import render_scene

    names = ["egg", "diamond", "pentagonal"]
    scene = render_scene([SPECS[n] for n in names], RenderConfig(area_fraction=0.18), rng=8, names=names)
    for rock in classify_image(scene.pixels, default_lib, all_rocks=True):
        record = rock.to_dict()
        area, centroid = polygon_area_centroid(record["outline"])
        assert area == pytest.approx(record["area_px"], rel=0.02)
        assert np.hypot(*(centroid - record["centroid"])) < 1.0
        assert screen_signed_area(record["outline"]) > 0


def ellipse_photo(rows, cols, center_xy, a, b, angle_deg, supersample=4):
    """An anti-aliased ellipse (semi-axes a, b px, major axis turned angle_deg CCW on screen)."""
    r = (np.arange(rows * supersample) + 0.5) / supersample - 0.5
    c = (np.arange(cols * supersample) + 0.5) / supersample - 0.5
    rr, cc = np.meshgrid(r, c, indexing="ij")
    x, y = cc - center_xy[0], center_xy[1] - rr
    t = np.deg2rad(angle_deg)
    u, v = x * np.cos(t) + y * np.sin(t), -x * np.sin(t) + y * np.cos(t)
    inside = (u / a) ** 2 + (v / b) ** 2 <= 1.0
    coverage = inside.reshape(rows, supersample, cols, supersample).mean(axis=(1, 3))
    return (0.25 + 0.5 * coverage).astype(np.float32)


@pytest.mark.parametrize(("a", "b", "angle"), [(60.0, 60.0, 0.0), (80.0, 40.0, 30.0), (100.0, 35.0, -70.0)])
def test_sizes_in_millimetres_are_those_of_a_drawn_ellipse(default_lib, a, b, angle):
    px_per_mm = 4.0
    pixels = ellipse_photo(300, 400, (210.3, 140.7), a, b, angle)
    (rock,) = classify_image(pixels, default_lib, ClassifyConfig(px_per_mm=px_per_mm))
    record = rock.to_dict()
    assert record["area_mm2"] == pytest.approx(np.pi * a * b / px_per_mm**2, rel=0.005)
    assert record["area_mm2"] == pytest.approx(record["area_px"] / px_per_mm**2, rel=1e-4)
    assert record["equivalent_diameter_mm"] == pytest.approx(2 * np.sqrt(a * b) / px_per_mm, rel=0.005)
    assert record["major_axis_mm"] == pytest.approx(2 * a / px_per_mm, rel=0.005)
    assert record["minor_axis_mm"] == pytest.approx(2 * b / px_per_mm, rel=0.005)
    np.testing.assert_allclose(record["centroid"], (210.3, 140.7), atol=0.05)


@pytest.mark.parametrize("bad", [0, -2.0, float("nan"), float("inf"), "3", True, 1e-300, 1e300])
def test_px_per_mm_must_be_a_positive_number(bad):
    # 1e-300 gave an area of inf mm2, which no JSON report can hold (a traceback in triage).
    with pytest.raises(ParameterError, match="px_per_mm must be a positive number"):
        ClassifyConfig(px_per_mm=bad)


def test_a_faint_rock_scores_lower_than_a_clear_one(default_lib):
    def score(contrast):
        settings = RenderConfig(rows=240, cols=320, contrast=contrast, noise=0.03, rock_lighter=True)
        photo = render_photo(SPECS["egg"], settings, rng=11)
        return classify_image(photo.pixels, default_lib)[0].to_dict()["segmentation_score"]

    faint, clear = score(0.08), score(0.5)
    assert 0.0 <= faint < clear <= 1.0 and clear > 0.8


# ---------------------------------------------------------------- invariance


@given(angle=st.floats(0.0, 360.0))
def test_turning_the_rock_turns_the_reported_angle(default_lib, angle):
    photo = render_photo(
        SPECS["egg"], RenderConfig(rows=240, cols=320, angle_deg=angle, center_xy=(160.0, 120.0)), rng=3
    )
    match = classify_image(photo.pixels, default_lib)[0].match
    assert match.nearest == "egg"
    assert angle_error(match.angle_deg, angle, match.symmetry) < 1.5


@given(dx=st.floats(-60.0, 60.0), dy=st.floats(-40.0, 40.0))
def test_moving_the_rock_moves_the_centroid_and_nothing_else(default_lib, dx, dy):
    def rock(center):
        settings = RenderConfig(rows=240, cols=320, angle_deg=20.0, area_fraction=0.08, center_xy=center)
        return classify_image(render_photo(SPECS["diamond"], settings, rng=6).pixels, default_lib)[0]

    base, moved = rock((160.0, 120.0)), rock((160.0 + dx, 120.0 + dy))
    np.testing.assert_allclose(np.subtract(moved.centroid_xy, base.centroid_xy), (dx, dy), atol=0.5)
    assert moved.match.nearest == base.match.nearest == "diamond"
    assert angle_error(moved.match.angle_deg, base.match.angle_deg, base.match.symmetry) < 1.0
    # The outline is the same up to where the pixels fall: within 1% of the
    # mean radius along most rays, 5% at the diamond's sharp corners.
    change = np.abs(moved.radii / moved.radii.mean() - base.radii / base.radii.mean())
    assert np.median(change) < 0.01 and change.max() < 0.05
