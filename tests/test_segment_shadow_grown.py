"""A long shadow, flooded from the part of it the rays see
(``rockscan.core.segment.shadow``).

The photos are the physical model of ``test_segment_shadow.py`` with the sun
low: the dome's shadow is half the rock's size or more.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_segment_shadow import assert_one_piece_never_worse, iou, lit_rock, log_brightness
from test_segment_shadow_hue import outlined

import rockscan.core.segment.shadow as shadow_module
from rockscan.core.segment.shadow import shadow_off

LOW_SUN = [(elevation, azimuth) for elevation in (15.0, 18.0) for azimuth in (0.0, 100.0, 200.0, 300.0)]


def long_shadow(elevation: float, azimuth: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    photo, rock, cast = lit_rock(
        radius=35.0, elevation=math.radians(elevation), azimuth=math.radians(azimuth)
    )
    return log_brightness(photo), rock, rock | cast


@pytest.mark.parametrize(("elevation", "azimuth"), LOW_SUN)
def test_a_shadow_longer_than_half_the_rock_is_taken_off(elevation, azimuth):
    gray, rock, joined = long_shadow(elevation, azimuth)
    assert iou(joined, rock) < 0.7
    kept = shadow_off(gray, joined)
    assert not (kept & ~joined).any()
    assert iou(kept, rock) > 0.97, iou(kept, rock)


@pytest.mark.parametrize(("elevation", "azimuth"), LOW_SUN[::3])
def test_the_rays_alone_leave_such_a_shadow(monkeypatch, elevation, azimuth):
    # Cast from the centre of rock and shadow together, the rays cross the
    # edge between them on part of it only, and the shadow's light draws the
    # lit side found towards it: without the flood nothing is cut.
    monkeypatch.setattr(shadow_module, "_grown_off", lambda gray, mask, *args: mask)
    gray, rock, joined = long_shadow(elevation, azimuth)
    assert iou(shadow_off(gray, joined), rock) < 0.7


@settings(max_examples=30, deadline=None)
@given(
    azimuth=st.floats(0.0, 360.0),
    elevation=st.floats(12.0, 22.0),
    radius=st.floats(25.0, 45.0),
    texture=st.floats(0.0, 0.15),
    seed=st.integers(0, 2**16),
    ground_texture=st.floats(0.0, 0.3),
)
def test_under_a_low_sun_the_result_is_one_piece_of_the_mask_never_worse(
    azimuth, elevation, radius, texture, seed, ground_texture
):
    photo, rock, cast = lit_rock(
        radius=radius,
        azimuth=math.radians(azimuth),
        elevation=math.radians(elevation),
        texture=texture,
        seed=seed,
        ground_texture=ground_texture,
    )
    joined = rock | cast
    assert_one_piece_never_worse(shadow_off(log_brightness(photo), joined), joined, rock)


def test_a_rock_outlined_right_under_a_low_sun_is_left_alone():
    gray, rock, _ = long_shadow(15.0, 100.0)
    assert iou(shadow_off(gray, rock), rock) > 0.99


# Development photos whose outline took a shadow larger than the rock (IoU
# 0.580, 0.601, 0.558 and 0.580 before the flood; the last is lit on the side
# away from its shadow only with the shadow's light), and one whose shadow's
# light drew the lit side found towards it (0.602) ...
GROWN = [("shaded", 4059), ("shaded", 4094), ("shaded", 4518), ("shaded", 4505), ("shaded", 4494)]
# ... one of a rock with a pit, whose rays show a shadow in the pit: the
# flood from it stops in the rock's smooth shading (0.541 without the edge
# the cut must follow) ...
PIT = ("plain", 4034)
# ... one of a textured rock whose darker half the flood reaches (0.452
# without the flatness the part cut off must have, 0.873 with it) ...
HALF = ("touching-pebbles", 4191)
# ... and one of a small smooth rock with a pit, where the flood from the pit
# takes two thirds of the rock along the pit's dark rim (0.325 without the
# share the rock must keep).
SMALL_PIT = ("small", 4026)


@pytest.mark.parametrize(("condition", "index"), [*GROWN, PIT, SMALL_PIT])
def test_the_outline_is_the_rocks(condition, index):
    assert outlined(condition, index) >= 0.9


def test_half_a_textured_rock_is_no_shadow(monkeypatch):
    assert outlined(*HALF) >= 0.85
    monkeypatch.setattr(shadow_module, "GROWN_FLAT", 10.0)
    assert outlined(*HALF) < 0.6


def test_without_the_flood_the_shadow_stays(monkeypatch):
    monkeypatch.setattr(shadow_module, "_grown_off", lambda gray, mask, *args: mask)
    assert outlined(*GROWN[0]) < 0.8


def test_a_flood_that_follows_no_edge_is_refused(monkeypatch):
    monkeypatch.setattr(shadow_module, "GROWN_EDGE", 0.0)
    assert outlined(*PIT) < 0.8


def test_a_flood_that_takes_most_of_the_outline_is_refused(monkeypatch):
    monkeypatch.setattr(shadow_module, "GROWN_KEEP", 0.0)
    assert outlined(*SMALL_PIT) < 0.5
