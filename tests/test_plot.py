"""Plots: the overlay lies on the rock, outlines land right on reduced photos, files are written."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.figure import Figure
from PIL import Image

from rockscan.core.errors import ParameterError, WriteError
from rockscan.core.information import FaceConfig
from rockscan.core.match import MatchConfig, match_radii
from rockscan.core.polar import contour_radii
from rockscan.core.render import RenderConfig, render_photo, render_scene
from rockscan.core.superformula import SuperformulaParams
from rockscan.draw.plot import (
    classification_figure,
    decision_tests,
    library_outline_rowcol,
    match_cutoffs,
    plot_classification,
    plot_library,
)
from rockscan.io import default_library
from rockscan.run.pipeline import RockResult, classify_image

BLUNT = SuperformulaParams(6, 6, 60, 55, 10)
SHARD = SuperformulaParams(3, 3, 0.7, 0.7, 0.7)


@pytest.fixture(scope="module")
def classified():
    photo = render_photo(SHARD, RenderConfig(angle_deg=50.0, area_fraction=0.15), rng=4, name="shard")
    library = default_library()
    return photo, library, classify_image(photo.pixels, library)


def test_library_shape_is_drawn_on_the_rock_at_the_found_angle_and_scale(classified):
    _, library, rocks = classified
    rock = rocks[0]
    assert rock.match.nearest == "shard"
    drawn = library_outline_rowcol(library, rock)
    # Radii of the drawn shape about the rock's centroid against the rock's own radii.
    drawn_radii = contour_radii(drawn[:-1], rock.outline.centroid_rowcol, rock.radii.size)
    error = np.abs(drawn_radii - rock.radii) / rock.radii.mean()
    # Within 1% along most rays; the shard's three sharp corners, rounded by the
    # camera's blur, stay within 8%.
    assert np.median(error) < 0.01 and np.percentile(error, 95) < 0.03 and error.max() < 0.08


def test_drawn_shape_turns_with_the_angle(classified):
    """A wrong angle would not lie on the rock: the check above can fail."""
    _, library, rocks = classified
    rock = rocks[0]
    turned = type(rock.match)(**{**rock.match.__dict__, "angle_deg": rock.match.angle_deg + 60.0})
    wrong = type(rock)(index=0, outline=rock.outline, radii=rock.radii, match=turned)
    drawn_radii = contour_radii(
        library_outline_rowcol(library, wrong)[:-1], rock.outline.centroid_rowcol, 360
    )
    assert np.median(np.abs(drawn_radii - rock.radii) / rock.radii.mean()) > 0.05


def test_figure_shows_photo_outline_centroid_shape_faces_and_distances(classified):
    photo, library, rocks = classified
    fig = classification_figure(photo.pixels, rocks, library, title="shard")
    assert isinstance(fig, Figure)
    ax_photo, ax_zoom, ax_face, ax_lib, ax_bar, ax_dist = fig.axes
    assert ax_photo.images[0].get_extent() == [-0.5, 639.5, 479.5, -0.5]
    labels = [line.get_label() for line in ax_zoom.get_lines()]
    assert labels[:4] == ["outline", "library shape 'shard'", "centroid", "angle"]
    outline = ax_zoom.get_lines()[0].get_xydata()
    np.testing.assert_allclose(outline[:-1, ::-1], rocks[0].outline.contour_rowcol)
    assert "shard" in ax_zoom.get_title() and "MScore" in ax_zoom.get_title()
    # The faces on the matcher's (theta, r) grid, their axes labelled.
    n_angles, n_sections = library.face_config.face_shape
    assert ax_face.images[0].get_array().shape == (n_sections, n_angles) and ax_lib.images
    assert ax_face.images[0].get_extent() == [0.0, 360.0, 0.0, float(n_sections)]
    for ax in (ax_face, ax_lib):
        assert ax.get_xlabel().startswith("theta (degrees") and ax.get_ylabel() == "r (sections of 0.02)"
    assert len(ax_dist.patches) == len(library)
    assert ax_bar.get_ylabel() == "H·q (bits)"
    ax_face_image, ax_lib_image = ax_face.images[0].get_array(), ax_lib.images[0].get_array()
    # The rock's face and the matched shape's face, turned, nearly coincide.
    assert np.abs(ax_face_image - ax_lib_image).sum() < 0.2 * ax_face_image.sum()


def test_outlines_land_right_on_a_photo_read_reduced(classified):
    """Pixels reduced by k, with scale=k, span the same photo coordinates."""
    photo, library, rocks = classified
    reduced = np.asarray(Image.fromarray(photo.pixels).reduce(4))
    fig = classification_figure(reduced, rocks, library, scale=4.0)
    assert fig.axes[0].images[0].get_extent() == [-0.5, 160 * 4 - 0.5, 120 * 4 - 0.5, -0.5]


def test_plot_writes_png_for_many_rocks_and_for_none(tmp_path, classified):
    _, library, _ = classified
    scene = render_scene([BLUNT, SHARD, BLUNT], RenderConfig(area_fraction=0.15), rng=2)
    many = classify_image(scene.pixels, library, all_rocks=True)
    assert len(many) == 3
    plot_classification(scene.pixels, many, library, tmp_path / "many.png")
    plot_classification(scene.pixels, [], library, tmp_path / "none.png")
    for name in ("many", "none"):
        with Image.open(tmp_path / f"{name}.png") as im:
            assert im.size == (1200, 960)
            assert np.asarray(im.convert("L")).std() > 10
    fig = classification_figure(scene.pixels, many, library)
    outlines = [line for line in fig.axes[0].get_lines() if line.get_color() == "#ff3b30"]
    assert len(outlines) == 3


def test_plot_handles_sixteen_bit_gray_and_radii_faces(tmp_path):
    photo = render_photo(BLUNT, RenderConfig(color=False, bit_depth=16), rng=1)
    library = default_library(FaceConfig(kind="radii"))
    rocks = classify_image(photo.pixels, library)
    fig = classification_figure(photo.pixels, rocks, library)
    shown = fig.axes[0].images[0].get_array()
    np.testing.assert_allclose(shown, np.round(photo.pixels / 257.0), atol=1)
    assert fig.axes[2].get_lines()[0].get_label() == "rock"
    plot_classification(photo.pixels, rocks, library, tmp_path / "radii.png")
    assert (tmp_path / "radii.png").stat().st_size > 10_000


def test_plot_errors_are_one_line_rockscan_errors(tmp_path, classified):
    photo, library, rocks = classified
    with pytest.raises(WriteError, match="cannot write the plot"):
        plot_classification(photo.pixels, rocks, library, tmp_path / "missing" / "p.png")
    with pytest.raises(ParameterError, match="cannot write the plot"):
        plot_classification(photo.pixels, rocks, library, tmp_path / "p.unknown-format")
    with pytest.raises(ParameterError, match="scale must be a positive number"):
        classification_figure(photo.pixels, rocks, library, scale=0.0)
    with pytest.raises(ParameterError, match="gray, RGB or RGBA"):
        classification_figure(np.zeros((4, 4, 2), np.uint8), rocks, library)


def test_plot_library_draws_every_shape(tmp_path):
    library = default_library()
    plot_library(library, tmp_path / "lib.png", columns=5)
    with Image.open(tmp_path / "lib.png") as im:
        # 11 x 7.2 inches at 100 dpi; matplotlib 3.10 rounds the 720 rows down to 719.
        assert im.size[0] == 1100 and im.size[1] in (719, 720)
    with pytest.raises(ParameterError, match="columns"):
        plot_library(library, tmp_path / "lib.png", columns=0)


# ---------------------------------------------------------------- the verdict and why


def _texts(fig):
    return [t.get_text() for t in fig.texts]


def test_the_figure_says_interesting_and_draws_the_cutoff_on_the_bars(classified):
    photo, library, rocks = classified
    fig = classification_figure(photo.pixels, rocks, library)
    headline, why = _texts(fig)
    assert headline == "INTERESTING: shard" and why.startswith("passes every test: distance ")
    theta = rocks[0].match.cutoff_distance
    ax_dist = fig.axes[5]
    cutoffs = [line for line in ax_dist.get_lines() if line.get_label().startswith("cutoff")]
    assert len(cutoffs) == 1 and list(cutoffs[0].get_xdata()) == [theta, theta]
    assert ax_dist.get_xlim()[1] > theta


@pytest.mark.parametrize(
    ("config", "decider"),
    [
        (MatchConfig(distance_cutoff=1e-4), "distance"),
        (MatchConfig(mscore_cutoff=0.9999), "MScore"),
        (MatchConfig(residual_cutoff=1e-4), "DFFS"),
    ],
)
def test_a_rejected_rock_says_which_test_decided(classified, config, decider):
    photo, library, rocks = classified
    rock = rocks[0]
    rematched = RockResult(
        index=0, outline=rock.outline, radii=rock.radii, match=match_radii(rock.radii, library, config)
    )
    assert not rematched.match.interesting
    tests = decision_tests(rematched, library, config)
    assert [t.name for t in tests if not t.passed] == [decider]
    fig = classification_figure(photo.pixels, [rematched], library, match_config=config)
    headline, why = _texts(fig)
    assert headline == "NOT INTERESTING: nearest shape 'shard' rejected"
    assert why.startswith(f"decided by {decider} ")
    # The bar of the nearest shape turns red when the distance test fails.
    colors = {tuple(p.get_facecolor()) for p in fig.axes[5].patches}
    assert (decider == "distance") == any(c[0] > 0.8 and c[1] < 0.3 for c in colors)


def test_decision_tests_agree_with_the_matchers_verdict(classified, default_specs):
    _, library, _ = classified
    for spec in default_specs[:8]:
        photo = render_photo(spec.params, RenderConfig(rows=160, cols=200, outline_noise=0.08), rng=3)
        rock = classify_image(photo.pixels, library)[0]
        tests = decision_tests(rock, library)
        # With the calibrated cutoffs only the distance test is in force by default.
        assert [t.name for t in tests] == ["distance"]
        assert all(t.passed for t in tests) == rock.match.interesting, spec.name
        assert tests[0].value == pytest.approx(rock.match.sensor_distance)
        assert tests[0].cutoff == pytest.approx(rock.match.cutoff_distance)


def test_cutoffs_carried_by_the_match_win():
    class Carrying:
        cutoff_distance = 0.5
        cutoff_segmentation = 0.3

    library = default_library()
    cutoffs = match_cutoffs(Carrying(), library, MatchConfig(mscore_cutoff=0.7, residual_cutoff=0.4))
    assert cutoffs == {"distance": 0.5, "MScore": 0.7, "DFFS": 0.4, "segmentation": 0.3}
    # MScore and DFFS decide only when a cutoff is set for them.
    assert match_cutoffs(Carrying(), library) == {"distance": 0.5, "segmentation": 0.3}
