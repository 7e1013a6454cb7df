"""A light rock's dark rim, taken back into its outline (``rockscan.core.segment.rim``).

The domed rocks are drawn by the lit-dome model of ``test_segment_shadow``
(its own physics, not ``rockscan.render``, not ``scripts/scenes.py``); the
masks rim_on starts from are the threshold half-way between the rock's level
and the ground's, which is where a light rock's first outline runs.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import ndimage
from test_segment_shadow import CENTRE, SHAPE, lit_rock

from rockscan.core.segment.rim import MIN_WIDTH, WIDTH, rim_on


def iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / (a | b).sum())


def half_way(photo: np.ndarray, rock: np.ndarray, shadow: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The photo's log brightness and the region above half-way from the ground to the rock."""
    gray = np.log(photo + 0.04).astype(np.float32)
    level = (np.median(gray[rock]) + np.median(gray[~rock & ~shadow])) / 2
    labels, _ = ndimage.label(gray > level)
    mask = ndimage.binary_fill_holes(labels == labels[round(CENTRE[0]), round(CENTRE[1])])
    return gray, mask


@pytest.mark.parametrize("azimuth", [0.0, 120.0, 250.0])
def test_a_light_rocks_dark_rim_is_taken_in(azimuth):
    # Lit from nearly overhead, a dome darkens all round its rim, below the
    # ground's level: the half-way outline runs inside the rim (IoU 0.87)
    # and moves out to the rim's darkest line (0.96), never more than the
    # blur's few pixels past the rock's edge.
    photo, rock, shadow = lit_rock(
        rock_albedo=0.8, ground_albedo=0.4, elevation=math.radians(85.0), azimuth=math.radians(azimuth)
    )
    gray, mask = half_way(photo, rock, shadow)
    assert iou(mask, rock) < 0.9
    grown = rim_on(gray, mask)
    assert iou(grown, rock) >= 0.95
    assert not (grown & ~ndimage.binary_dilation(rock, iterations=3)).any()


@pytest.mark.parametrize("azimuth", [0.0, 120.0, 250.0])
@pytest.mark.parametrize("elevation", [45.0, 60.0, 75.0])
def test_the_cast_shadow_stays_out(azimuth, elevation):
    # Lower light casts a shadow as dark as the rim beside it: the rays there
    # stay low past their window, so the outline stays out of the shadow,
    # and it never gets worse.
    photo, rock, shadow = lit_rock(
        rock_albedo=0.8,
        ground_albedo=0.4,
        elevation=math.radians(elevation),
        azimuth=math.radians(azimuth),
    )
    gray, mask = half_way(photo, rock, shadow)
    grown = rim_on(gray, mask)
    # The shadow's pixels within the edge's blur of the rock are the rim's valley too.
    assert not (grown & shadow & (ndimage.distance_transform_edt(~rock) > 2.0)).any()
    assert iou(grown, rock) >= iou(mask, rock)


def test_a_dark_rocks_mask_is_left_alone():
    photo, rock, shadow = lit_rock(rock_albedo=0.25, ground_albedo=0.7, elevation=math.radians(85.0))
    gray, mask = half_way(photo, rock, shadow)
    assert rim_on(gray, mask) is mask


def flat_disc(line: float, line_width: int = 1, band: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A flat light disc (no rim) on darker ground, blurred by a pixel, with a
    dark line ``line_width`` pixels wide right outside its edge (brightness
    ``line``) and optionally a flat dark band ``band`` pixels wide on its right."""
    rr, cc = np.mgrid[: SHAPE[0], : SHAPE[1]].astype(np.float64)
    distance = np.hypot(rr - CENTRE[0], cc - CENTRE[1])
    disc = distance <= 50.0
    dark = (distance > 50.0) & (distance <= 50.0 + line_width)
    if band:
        dark |= ~disc & (distance <= 50.0 + band) & (cc > CENTRE[1] + 10)
    return flat_photo(disc, dark, line), disc


def flat_photo(flat: np.ndarray, dark: np.ndarray, line: float) -> np.ndarray:
    """Log brightness of a flat light object (``flat``, 0.8) on darker ground
    (0.4) with ``dark`` pixels at brightness ``line``, blurred by a pixel."""
    photo = np.where(flat, 0.8, 0.4)
    photo[dark] = line
    photo = cv2.GaussianBlur(photo.astype(np.float32), (0, 0), 1.0)
    return np.log(photo + 0.04).astype(np.float32)


def test_a_dark_line_right_at_a_sharp_edge_is_outside_the_object():
    # A coin's side or a contact shadow: a dark line hugging a sharp edge.
    # The valley is within a pixel or two of the outline, too near to be a
    # rim's: the outline stays.
    gray, disc = flat_disc(0.1)
    assert np.array_equal(rim_on(gray, disc), disc)


def test_a_flat_dark_band_beside_a_sharp_edge_is_no_rim():
    gray, disc = flat_disc(0.1, band=12)
    assert np.array_equal(rim_on(gray, disc), disc)


@pytest.mark.parametrize(
    ("radius", "elevation", "ground"), [(25.0, 80.0, 0.4), (25.0, 85.0, 0.5), (30.0, 85.0, 0.5)]
)
def test_a_small_rocks_narrow_rim_is_taken_in(radius, elevation, ground):
    # On a small dome the rim's valley lies under 2.5 px past the half-way
    # outline, which a thin dark line beside a sharp edge could be too;
    # read across the outline, 1.75 px is a rim's (IoU up by 0.04-0.10).
    photo, rock, shadow = lit_rock(
        radius=radius, rock_albedo=0.8, ground_albedo=ground, elevation=math.radians(elevation), azimuth=0.0
    )
    gray, mask = half_way(photo, rock, shadow)
    grown = rim_on(gray, mask)
    assert iou(grown, rock) >= iou(mask, rock) + 0.03
    assert not (grown & ~ndimage.binary_dilation(rock, iterations=3)).any()


def flat_star(depth: float, line: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
    """A flat light five-armed star (no rim) on darker ground, blurred by a
    pixel, with a dark line a pixel wide right outside its edge; its arms are
    ``depth`` of its outer radius deep."""
    rr, cc = np.mgrid[: SHAPE[0], : SHAPE[1]].astype(np.float64)
    dy, dx = rr - CENTRE[0], cc - CENTRE[1]
    edge = 60.0 * (1.0 - depth * (1.0 - np.cos(5.0 * np.arctan2(dy, dx))) / 2.0)
    star = np.hypot(dy, dx) <= edge
    return flat_photo(star, ndimage.binary_dilation(star) & ~star, line), star


@pytest.mark.parametrize("depth", [0.3, 0.6])
def test_a_thin_line_seen_aslant_beside_a_stars_arm_is_outside_the_object(depth):
    # A ray from the centre meets an arm's side aslant and crosses the thin
    # line beside it over 2-3 px; across the outline it is a pixel wide, as
    # beside a round object's edge, and the outline stays.
    gray, star = flat_star(depth)
    assert np.array_equal(rim_on(gray, star), star)


def test_small_and_empty_masks_are_left_alone():
    gray = np.zeros(SHAPE, np.float32)
    empty = np.zeros(SHAPE, bool)
    assert rim_on(gray, empty) is empty
    dot = empty.copy()
    dot[100:105, 100:105] = True
    assert rim_on(gray, dot) is dot


@settings(max_examples=20, deadline=None)
@given(
    azimuth=st.floats(0.0, 360.0),
    elevation=st.floats(40.0, 88.0),
    radius=st.floats(25.0, 70.0),
    texture=st.floats(0.0, 0.15),
    seed=st.integers(0, 2**16),
)
def test_the_rim_only_adds_a_band_round_the_outline(azimuth, elevation, radius, texture, seed):
    photo, rock, shadow = lit_rock(
        radius=radius,
        rock_albedo=0.8,
        ground_albedo=0.4,
        azimuth=math.radians(azimuth),
        elevation=math.radians(elevation),
        texture=texture,
        seed=seed,
    )
    gray, mask = half_way(photo, rock, shadow)
    grown = rim_on(gray, mask)
    assert (grown >= mask).all()
    reach = max(MIN_WIDTH, WIDTH * math.sqrt(mask.sum() / math.pi)) + 2.0
    assert (ndimage.distance_transform_edt(~mask)[grown] <= reach).all()


@pytest.mark.parametrize(("name", "seed"), [("circle", 2), ("three-faced-blunt", 2), ("six-pointed-star", 3)])
def test_a_light_rock_without_a_rim_on_textured_ground_is_left_alone(monkeypatch, name, seed):
    # Rendered by rockscan.render: a light rock with a sharp edge on a
    # textured ground. Dark blobs of the ground's texture just past the edge
    # look like a rim's valley on a few rays (2-6% of them); a rim darkens a
    # good part of the outline (23-39% of the rays on the development photos
    # it put right), so the outline stays.
    import rockscan.core.segment as segmentation
    import rockscan.core.segment.finish as finish
    from rockscan.core.render import RenderConfig, render_photo
    from rockscan.io.data import default_spec_path
    from rockscan.io.spec import read_spec

    params = {spec.name: spec.params for spec in read_spec(default_spec_path())}[name]
    photo = render_photo(params, RenderConfig(rows=768, cols=1024), rng=seed, name=name)
    assert photo.truth["rock_lighter"]
    grown = segmentation.segment(photo.pixels).rocks[0]
    monkeypatch.setattr(finish, "rim_on", lambda gray, mask, region=None: mask)
    alone = segmentation.segment(photo.pixels).rocks[0]
    assert alone.origin_rowcol == grown.origin_rowcol
    assert np.array_equal(alone.mask, grown.mask)
