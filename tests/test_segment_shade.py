"""A light rock's shaded side, taken back into its outline (``rockscan.core.segment.shade``).

The photos are drawn here under sky light: a disc lit from one side keeps its
albedo on its lit part, and on its far side, as on its cast shadow, only the
sky's share of the light. The domes of ``test_segment_shadow`` (their own
physics: Lambert shading of a height field, a traced shadow) check that a
whole rock beside its shadow keeps its outline.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import ndimage
from test_segment_shadow import iou, lit_rock

from rockscan.core.segment.shade import MAX_GROWTH, shade_on

SIZE = 200


def sky_lit(
    radius: float = 30.0,
    turn: float = 0.0,
    lit_from: float = -0.5,
    rock: float = 0.8,
    ground: float = 0.5,
    sky: float = 0.25,
    shadow: float = 2.0,
    noise: float = 0.01,
    seed: int = 0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The log brightness of a light disc lit from direction ``turn`` (radians),
    the disc, its lit part (from ``lit_from`` radii behind its centre towards
    the light) and its cast shadow (the disc swept ``shadow`` radii away from
    the light). In the shade, rock and ground keep ``sky`` of their light.
    """
    size = SIZE if radius <= 40 else 400
    rr, cc = np.mgrid[:size, :size].astype(np.float64)
    dy, dx = rr - size / 2, cc - size / 2
    towards = dx * math.cos(turn) + dy * math.sin(turn)
    disc = np.hypot(dy, dx) <= radius
    lit = disc & (towards > lit_from * radius)
    cast = np.zeros(disc.shape, bool)
    for s in np.linspace(0.0, shadow * radius, 80):
        cast |= np.hypot(dy + s * math.sin(turn), dx + s * math.cos(turn)) <= radius
    cast &= ~disc
    light = np.where(disc, rock, ground)
    light = np.where(disc & ~lit, rock * sky, light)
    light = np.where(cast, ground * sky, light).astype(np.float32)
    light = cv2.GaussianBlur(light, (0, 0), 1.0)
    light += np.random.default_rng(seed).normal(0.0, noise, light.shape).astype(np.float32)
    gray = np.log(np.clip(light, 0.0, 1.0) + 0.04)
    return gray, disc, lit, cast


@pytest.mark.parametrize(
    "drawn",
    [
        {},
        {"turn": 2.0},
        {"turn": 4.0, "noise": 0.02},
        {"sky": 0.35},
        {"radius": 60.0, "turn": 1.0},
    ],
)
def test_a_light_rocks_shaded_side_is_taken_in(drawn):
    # Its lit part alone stands out from the ground; its far side, in sky
    # light, is as much lighter than its shadow as the rock than the ground.
    gray, disc, lit, cast = sky_lit(**drawn)
    grown = shade_on(gray, lit)
    assert iou(lit, disc) < 0.9
    assert iou(grown, disc) >= 0.95
    # Nothing of the shadow past the blur of its edge with the rock.
    assert not (grown & cast & (ndimage.distance_transform_edt(~disc) > 2.0)).any()


@settings(max_examples=15, deadline=None)
@given(
    turn=st.floats(0.0, 2.0 * math.pi),
    sky=st.floats(0.15, 0.4),
    shadow=st.floats(0.5, 3.0),
    seed=st.integers(0, 2**16),
)
def test_a_whole_light_rock_beside_its_shadow_is_left_alone(turn, sky, shadow, seed):
    gray, disc, _, _ = sky_lit(turn=turn, sky=sky, shadow=shadow, seed=seed)
    assert shade_on(gray, disc) is disc


@pytest.mark.parametrize("elevation", [10.0, 20.0, 35.0])
@pytest.mark.parametrize("azimuth", [0.0, 120.0, 250.0])
def test_a_whole_dome_beside_its_shadow_is_left_alone(elevation, azimuth):
    photo, rock, _ = lit_rock(
        rock_albedo=0.8,
        ground_albedo=0.4,
        elevation=math.radians(elevation),
        azimuth=math.radians(azimuth),
        ambient=0.15,
        texture=0.05,
        ground_texture=0.1,
    )
    assert shade_on(np.log(photo + 0.04), rock) is rock


def test_a_dark_rock_is_left_alone():
    gray, _, lit, _ = sky_lit(rock=0.2)
    assert shade_on(gray, lit) is lit


def test_a_shaded_side_larger_than_a_domes_is_left_alone():
    # Half the disc in shade would double the rock: more than a dome's far
    # side, and as much as a shadow cast beside it.
    gray, disc, lit, _ = sky_lit(lit_from=0.0)
    assert np.count_nonzero(disc & ~lit) > MAX_GROWTH * np.count_nonzero(lit)
    assert shade_on(gray, lit) is lit


def test_a_shaded_side_the_frame_cuts_is_left_out():
    # The frame cuts the rock and its far side: the photo shows neither the
    # side whole nor the ground round it, and a dark patch of ground in a
    # corner of the frame beside a rock reads alike. Left out, right or not.
    gray, _, lit, _ = sky_lit()
    assert shade_on(gray, lit) is not lit
    cut = np.s_[SIZE // 2 - 18 :, :]
    mask = lit[cut]
    assert mask[0].any()
    assert shade_on(gray[cut], mask) is mask
