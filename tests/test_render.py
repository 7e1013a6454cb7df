"""The renderer: ground truth that holds, conventions, reproducibility, formats, speed."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import PAPER_SHAPES
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import ndimage

from rockscan.core.errors import NoRockFoundError, ParameterError, WriteError
from rockscan.core.polar import polar_angles
from rockscan.core.render import RenderConfig, random_superformula, render_photo, render_scene
from rockscan.core.superformula import SuperformulaParams, shape_radii
from rockscan.io import default_library, read_image
from rockscan.io.photos import write_photo
from rockscan.run.pipeline import classify_image

TEARDROP = SuperformulaParams(1, 1, 0.5, 0.5, 0.5)
STAR = PAPER_SHAPES["six-pointed-star"]
#: A clean photo: a flat rock on a flat ground, no camera effects, 16 bits.
CLEAN = RenderConfig(
    rows=200,
    cols=260,
    color=False,
    bit_depth=16,
    noise=0.0,
    blur=0.0,
    gradient=0.0,
    rock_texture=0.0,
    ground_texture=0.0,
    rock_lighter=True,
)


def coverage(pixels: np.ndarray) -> np.ndarray:
    """Fraction of each pixel the rock covers, in a clean photo (two flat levels)."""
    values = pixels.astype(np.float64)
    ground, rock = values[0, 0], values.max()
    return np.clip((values - ground) / (rock - ground), 0.0, 1.0)


def test_seed_reproduces_photo_exactly_and_other_seeds_differ():
    config = RenderConfig(rows=96, cols=128, pebbles=5, shadow=0.3, jpeg_quality=85, outline_noise=0.03)
    a, b = render_photo(STAR, config, rng=7), render_photo(STAR, config, rng=7)
    np.testing.assert_array_equal(a.pixels, b.pixels)
    assert a.truth == b.truth
    assert a.encode(".jpg") == b.encode(".jpg")
    c = render_photo(STAR, config, rng=8)
    assert not np.array_equal(a.pixels, c.pixels)
    scene = [render_scene([STAR, TEARDROP], config.with_(jpeg_quality=None), rng=3) for _ in range(2)]
    np.testing.assert_array_equal(scene[0].pixels, scene[1].pixels)
    assert scene[0].truth == scene[1].truth


@settings(max_examples=12)
@given(
    name=st.sampled_from([*sorted(PAPER_SHAPES), "teardrop"]),
    angle=st.floats(0.0, 360.0),
    area=st.floats(0.02, 0.4),
)
def test_truth_centroid_and_area_are_those_of_the_drawn_rock(name, angle, area):
    shape = TEARDROP if name == "teardrop" else PAPER_SHAPES[name]
    photo = render_photo(shape, CLEAN.with_(angle_deg=angle, area_fraction=area), rng=1)
    cover = coverage(photo.pixels)
    rows, cols = np.indices(cover.shape)
    centroid = [(cover * cols).sum() / cover.sum(), (cover * rows).sum() / cover.sum()]
    np.testing.assert_allclose(centroid, photo.truth["centroid_xy"], atol=0.1)
    assert cover.sum() == pytest.approx(photo.truth["area_px"], rel=2e-3)
    assert photo.truth["area_fraction"] == pytest.approx(photo.truth["area_px"] / (200 * 260))
    assert photo.truth["angle_deg"] == pytest.approx(angle % 360.0)


def test_a_turn_of_many_whole_turns_draws_the_same_rock():
    # The radians of 1e20 degrees swamped every ray's own angle: a rock of 3 pixels.
    many, once = (render_photo(TEARDROP, CLEAN.with_(angle_deg=a), rng=1) for a in (1e20, 1e20 % 360.0))
    assert many.truth["area_px"] == pytest.approx(once.truth["area_px"], rel=1e-9)
    assert many.truth["angle_deg"] == once.truth["angle_deg"] == 1e20 % 360.0


@pytest.mark.parametrize("angle", [0.0, 30.0, 90.0, 200.0])
def test_angle_turns_the_rock_counter_clockwise_on_screen(angle):
    """The outline point at polar angle theta of the shape lies at theta + angle,
    measured counter-clockwise from +x with y pointing up (interface.md)."""
    photo = render_photo(TEARDROP, CLEAN.with_(angle_deg=angle, area_fraction=0.25), rng=2)
    cover = coverage(photo.pixels)
    cx, cy = photo.truth["center_xy"]
    theta = polar_angles(36)
    dense = TEARDROP.radii(polar_angles(2048))
    scale = photo.truth["scale_px"] / dense.mean()
    radius = scale * TEARDROP.radii(theta)
    direction = theta + math.radians(angle)
    for factor, expected in ((0.9, 1.0), (1.1, 0.0)):
        cols = cx + factor * radius * np.cos(direction)
        rows = cy - factor * radius * np.sin(direction)
        inside = ndimage.map_coordinates(cover, [rows, cols], order=1)
        np.testing.assert_allclose(inside, expected, atol=0.02)


def test_symmetry_is_read_from_the_outline():
    orders = {name: render_photo(p, CLEAN, rng=0).truth["symmetry"] for name, p in PAPER_SHAPES.items()}
    assert orders == {"rounded-triangle": 3, "three-faced-blunt": 3, "six-pointed-star": 6}
    assert render_photo(SuperformulaParams(0, 0, 1, 1, 1), CLEAN, rng=0).truth["symmetry"] == 0
    assert render_photo(TEARDROP, CLEAN, rng=0).truth["symmetry"] == 1


def test_sixteen_bit_photo_is_the_eight_bit_photo_at_finer_steps():
    config = RenderConfig(rows=64, cols=80)
    eight = render_photo(STAR, config, rng=5).pixels
    sixteen = render_photo(STAR, config.with_(bit_depth=16), rng=5).pixels
    assert eight.dtype == np.uint8 and sixteen.dtype == np.uint16
    assert sixteen.max() > 255
    np.testing.assert_allclose(sixteen / 257.0, eight, atol=0.51)


def test_gray_photo_is_two_dimensional():
    photo = render_photo(STAR, RenderConfig(rows=64, cols=80, color=False), rng=5)
    assert photo.pixels.shape == (64, 80) and photo.pixels.dtype == np.uint8


WRITABLE = [
    (suffix, color, depth)
    for suffix in (".png", ".tif", ".bmp", ".jpg")
    for color in (False, True)
    for depth in (8, 16)
    if not (suffix in (".bmp", ".jpg") and depth == 16)
]


@pytest.mark.parametrize(("suffix", "color", "depth"), WRITABLE)
def test_every_format_writes_and_reads_back(tmp_path, suffix, color, depth):
    jpeg = 80 if suffix == ".jpg" else None
    config = RenderConfig(rows=64, cols=80, color=color, bit_depth=depth, jpeg_quality=jpeg)
    photo = render_photo(STAR, config, rng=4)
    path = tmp_path / f"photo{suffix}"
    write_photo(photo, path)
    image = read_image(path)
    assert image.bit_depth == depth
    # JPEG too: the photo's pixels are the decoded JPEG, as a reader sees them.
    np.testing.assert_array_equal(image.pixels, photo.pixels)


@pytest.mark.parametrize("suffix", [".jpg", ".bmp"])
def test_sixteen_bit_photos_refuse_eight_bit_formats(suffix):
    photo = render_photo(STAR, RenderConfig(rows=32, cols=32, bit_depth=16), rng=0)
    with pytest.raises(ParameterError, match="8 bits"):
        photo.encode(suffix)


def test_unknown_suffix_is_a_parameter_error_and_unwritable_path_a_write_error(tmp_path):
    photo = render_photo(STAR, RenderConfig(rows=32, cols=32), rng=0)
    with pytest.raises(ParameterError, match=r"cannot write '\.gif'"):
        photo.encode(".gif")
    with pytest.raises(WriteError, match="cannot write the photo"):
        write_photo(photo, tmp_path / "no-such-folder" / "p.png")


def _vertex_radii(photo, shape: SuperformulaParams, n: int) -> np.ndarray:
    """Measured radius of the drawn outline at each of its ``n`` vertices' directions."""
    cover = coverage(photo.pixels)
    cx, cy = photo.truth["center_xy"]
    direction = polar_angles(n) + math.radians(photo.truth["angle_deg"])
    steps = np.arange(0.0, 400.0, 0.05)
    cols = cx + steps[None, :] * np.cos(direction)[:, None]
    rows = cy - steps[None, :] * np.sin(direction)[:, None]
    along = ndimage.map_coordinates(cover, [rows.ravel(), cols.ravel()], order=1).reshape(rows.shape)
    return steps[np.argmax(along < 0.5, axis=1)] / shape.radii(polar_angles(n))


@pytest.mark.parametrize("noise", [0.0, 0.1])
def test_outline_noise_is_the_papers_radial_model(noise):
    """Each vertex radius is the clean radius times 1 + e, e ~ N(0, noise) (paper Fig. 11)."""
    circle = SuperformulaParams(0, 0, 1, 1, 1)
    config = CLEAN.with_(rows=400, cols=400, area_fraction=0.3, outline_noise=noise, outline_points=96)
    photo = render_photo(circle, config, rng=9)
    ratio = _vertex_radii(photo, circle, 96)
    relative = ratio / ratio.mean() - 1.0
    # 96 draws estimate the spread to about noise/sqrt(192) = 0.007; half a pixel of
    # anti-aliasing in 120 adds 0.004.
    assert relative.std() == pytest.approx(noise, abs=0.02)
    assert photo.truth["render"]["outline_noise"] == noise


def test_scene_rocks_are_apart_and_where_the_truth_says():
    shapes = [
        PAPER_SHAPES["three-faced-blunt"],
        TEARDROP,
        PAPER_SHAPES["rounded-triangle"],
        SuperformulaParams(0, 0, 1, 1, 1),
    ]
    photo = render_scene(
        shapes, CLEAN.with_(rows=300, cols=400, area_fraction=0.2), rng=6, names=list("abcd")
    )
    # 8-connected: the teardrop's tail thins to a diagonal line of pixels.
    labels, count = ndimage.label(coverage(photo.pixels) > 0.5, structure=np.ones((3, 3)))
    assert count == 4
    found = ndimage.center_of_mass(np.ones_like(labels), labels, range(1, count + 1))
    for rock in photo.truth["rocks"]:
        cx, cy = rock["centroid_xy"]
        assert min(math.hypot(col - cx, row - cy) for row, col in found) < 0.5
    assert [r["shape"] for r in photo.truth["rocks"]] == list("abcd")


def test_empty_scene_is_bare_ground_and_has_no_rock(default_lib):
    photo = render_scene([], RenderConfig(rows=120, cols=160, ground_texture=0.0, gradient=0.3), rng=0)
    assert photo.truth["rocks"] == []
    with pytest.raises(NoRockFoundError, match="no rock found"):
        classify_image(photo.pixels, default_lib)


def test_gradient_spans_the_stated_brightness_ratio():
    """Light falls off linearly across the frame: brightness times 1 +- gradient/2."""
    for gradient in (0.2, 0.8):
        config = CLEAN.with_(gradient=gradient, rows=300, cols=300)
        ground = render_scene([], config, rng=3).pixels.astype(np.float64)
        expected = (1 + gradient / 2) / (1 - gradient / 2)
        # The extremes lie at corner pixel centres, half a pixel inside the frame.
        assert ground.max() / ground.min() == pytest.approx(expected, rel=0.01)


def test_polarity_and_shadow():
    base = RenderConfig(rows=120, cols=160, noise=0.0, area_fraction=0.15, gradient=0.0, rock_texture=0.0)
    for lighter in (True, False):
        photo = render_photo(STAR, base.with_(rock_lighter=lighter, color=False), rng=1)
        cx, cy = (round(v) for v in photo.truth["centroid_xy"])
        inside, outside = float(photo.pixels[cy, cx]), float(np.median(photo.pixels))
        assert (inside > outside) == lighter
        assert photo.truth["rock_lighter"] is lighter
    plain = render_photo(STAR, base.with_(color=False), rng=1).pixels.astype(float)
    shaded = render_photo(STAR, base.with_(color=False, shadow=0.8), rng=1).pixels.astype(float)
    assert (shaded <= plain + 1).all() and (plain - shaded).max() > 20


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"rows": 8}, "at least 16"),
        ({"rows": 100.5}, "rows must be an integer"),
        ({"area_fraction": 0.9}, "area_fraction must be between"),
        ({"area_fraction": "big"}, "area_fraction must be a number"),
        ({"noise": -0.1}, "noise must be a non-negative number"),
        ({"blur": float("nan")}, "blur must be a non-negative number"),
        ({"shadow": 1.5}, "shadow must be at most 1"),
        ({"contrast": 5.0}, "contrast must be from 0 to 1"),
        ({"jpeg_quality": 0}, "jpeg_quality must be between 1 and 100"),
        ({"bit_depth": 12}, "bit_depth must be 8 or 16"),
        ({"bit_depth": 16, "jpeg_quality": 90}, "JPEG photos are 8 bits"),
        ({"pebbles": -1}, "pebbles must be from 0 to"),
        ({"outline_points": 4}, "outline_points must be at least 8"),
        ({"angle_deg": float("inf")}, "angle_deg must be a finite number"),
        ({"center_xy": (1.0,)}, "center_xy must be"),
    ],
)
def test_bad_settings_name_the_setting(change, message):
    with pytest.raises(ParameterError, match=message):
        RenderConfig(**change)


def test_bad_shapes_are_refused():
    with pytest.raises(ParameterError, match="unbounded or degenerate"):
        render_photo(SuperformulaParams(4, 0, 1, 1, 1), rng=0)
    with pytest.raises(ParameterError, match="at least 8 values"):
        render_photo([1.0, 1.0, 1.0], rng=0)
    with pytest.raises(ParameterError, match="one name per shape"):
        render_scene([STAR], rng=0, names=["a", "b"])
    with pytest.raises(ParameterError, match="without overlap"):
        render_scene([STAR] * 6, RenderConfig(area_fraction=0.8), rng=0)


def test_radii_outline_renders_like_its_superformula():
    """A shape given as radii draws the same rock as its parameters."""
    radii = STAR.radii(polar_angles(2048))
    a = render_photo(STAR, CLEAN.with_(angle_deg=10.0), rng=4)
    b = render_photo(radii, CLEAN.with_(angle_deg=10.0), rng=4)
    assert np.abs(coverage(a.pixels) - coverage(b.pixels)).max() < 0.02
    assert b.truth["params"] is None


def test_random_superformula_is_rock_like_and_seeded():
    for seed in range(8):
        params = random_superformula(seed)
        assert params == random_superformula(seed)
        radii = shape_radii(params, 360)
        assert radii.max() / radii.min() < 3.5


def test_rendered_rocks_classify_as_themselves():
    library = default_library()
    for i, name in enumerate(["rounded-triangle", "three-faced-blunt", "six-pointed-star"]):
        photo = render_photo(PAPER_SHAPES[name], RenderConfig(), rng=i)
        assert classify_image(photo.pixels, library)[0].match.nearest == name


@pytest.mark.parametrize("size", [16, 32, 48, 64, 96])
def test_small_photos_have_a_ground_of_the_set_brightness(size):
    # Texture scales coarser than a small frame must not shift its brightness.
    photo = render_photo(
        SuperformulaParams(4, 4, 2, 2, 2),
        RenderConfig(rows=size, cols=size, gradient=0.0, noise=0.0, ground_texture=0.08),
        rng=3,
    )
    border = np.concatenate([photo.pixels[0], photo.pixels[-1]]).astype(float) / 255
    assert 0.2 < np.median(border) < 0.7


@pytest.mark.parametrize("center", [(10.0, 100.0), (250.0, 5.0)])
def test_a_rock_partly_outside_the_frame_gets_the_truth_the_photo_shows(center):
    """Area and centroid are those of the part inside the frame, and the truth says it is clipped."""
    egg = SuperformulaParams(1, 1, 1, 1, 1, 0.5, 1)
    photo = render_photo(egg, CLEAN.with_(area_fraction=0.1, angle_deg=30.0, center_xy=center), rng=0)
    cover = coverage(photo.pixels)
    rows, cols = np.indices(cover.shape)
    assert photo.truth["clipped"] is True
    assert photo.truth["area_px"] == pytest.approx(cover.sum(), rel=1e-3)
    seen = [(cover * cols).sum() / cover.sum(), (cover * rows).sum() / cover.sum()]
    assert photo.truth["centroid_xy"] == pytest.approx(seen, abs=0.05)


def test_a_rock_inside_the_frame_is_not_clipped_and_one_outside_is_refused():
    inside = render_photo(STAR, CLEAN.with_(area_fraction=0.1, center_xy=(130.0, 100.0)), rng=0)
    assert inside.truth["clipped"] is False
    with pytest.raises(ParameterError, match="outside the frame"):
        render_photo(STAR, CLEAN.with_(center_xy=(-500.0, 100.0)), rng=0)
