"""A cast shadow that joined a rock's outline, taken off (``rockscan.core.segment.shadow``).

The photos here are drawn from the physics the module's docstring relies on,
by a model of their own (not ``rockscan.render``, not ``scripts/scenes.py``):
a dome of one albedo on a ground of another, lit by a directional light and
the sky, its shadow cast by marching towards the light.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rockscan.core.segment.shadow import shadow_left_out, shadow_off

SHAPE = (220, 260)
CENTRE = (110.0, 130.0)


def lit_rock(
    radius: float = 55.0,
    rock_albedo: float = 0.25,
    ground_albedo: float = 0.7,
    azimuth: float = math.radians(200.0),
    elevation: float = math.radians(35.0),
    ambient: float = 0.3,
    texture: float = 0.0,
    blur: float = 1.0,
    seed: int = 0,
    ground_texture: float = 0.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A photo (brightness in [0, 1]), the rock's mask and the cast shadow's mask.

    ``texture`` and ``ground_texture`` vary the rock's and the ground's albedo
    (relative standard deviation; the ground's is grain a few pixels wide).
    """
    rng = np.random.default_rng(seed)
    rr, cc = np.mgrid[: SHAPE[0], : SHAPE[1]].astype(np.float64)
    dy, dx = rr - CENTRE[0], cc - CENTRE[1]
    f = np.hypot(dy, dx) / radius
    rock = f <= 1.0
    height = np.where(rock, 0.6 * radius * np.sqrt(np.clip(1.0 - f**2, 0.0, None)), 0.0)
    gy, gx = np.gradient(height)
    norm = np.sqrt(gx**2 + gy**2 + 1.0)
    light = (
        math.cos(elevation) * math.sin(azimuth),
        math.cos(elevation) * math.cos(azimuth),
        math.sin(elevation),
    )
    lambert = np.clip((-gy * light[0] - gx * light[1] + light[2]) / norm, 0.0, None)
    # Cast shadow: a ground pixel is shadowed when the dome rises above the
    # ray from it towards the light.
    lit = np.ones(SHAPE)
    slope = math.tan(elevation)
    for s in range(1, int(height.max() / slope) + 2):
        oy, ox = round(s * light[0] / math.cos(elevation)), round(s * light[1] / math.cos(elevation))
        shifted = np.zeros(SHAPE)
        ys = slice(max(0, -oy), SHAPE[0] - max(0, oy))
        xs = slice(max(0, -ox), SHAPE[1] - max(0, ox))
        yt = slice(max(0, oy), SHAPE[0] - max(0, -oy))
        xt = slice(max(0, ox), SHAPE[1] - max(0, -ox))
        shifted[ys, xs] = height[yt, xt]
        lit[(shifted - s * slope > height + 0.5)] = 0.0
    shadow = (lit == 0.0) & ~rock
    grain = cv2.GaussianBlur(rng.standard_normal(SHAPE).astype(np.float32), (0, 0), 1.5)
    grain /= max(float(grain.std()), 1e-9)
    albedo = np.where(
        rock,
        rock_albedo * (1.0 + texture * rng.standard_normal(SHAPE)),
        ground_albedo * np.exp(ground_texture * grain),
    )
    radiance = albedo * (ambient + (1.0 - ambient) * lambert * lit)
    radiance = cv2.GaussianBlur(radiance.astype(np.float32), (0, 0), blur)
    photo = np.clip(radiance + 0.005 * rng.standard_normal(SHAPE), 0.0, 1.0)
    return photo, rock, shadow


def log_brightness(photo: np.ndarray) -> np.ndarray:
    return np.log(photo + 0.04)


def iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / (a | b).sum())


def test_the_photos_cast_a_shadow_darker_than_half_way_to_the_rock():
    # The premise: a threshold half-way between ground and rock takes the
    # shadow in with the rock.
    photo, rock, shadow = lit_rock()
    ground = np.median(photo[~rock & ~shadow])
    half = 0.5 * (ground + np.median(photo[rock]))
    assert shadow.sum() > 0.1 * rock.sum()
    assert np.median(photo[shadow]) < half


@pytest.mark.parametrize("azimuth", [0.0, 100.0, 200.0, 300.0])
def test_a_shadow_that_joined_a_dark_rock_is_taken_off(azimuth):
    photo, rock, shadow = lit_rock(azimuth=math.radians(azimuth))
    joined = rock | shadow
    assert iou(joined, rock) < 0.9
    kept = shadow_off(log_brightness(photo), joined)
    assert not (kept & ~joined).any()
    assert iou(kept, rock) > 0.95, iou(kept, rock)


def test_a_textured_dark_rock_loses_its_shadow_too():
    photo, rock, shadow = lit_rock(texture=0.1, seed=3)
    kept = shadow_off(log_brightness(photo), rock | shadow)
    assert iou(kept, rock) > 0.95


def test_a_shadow_on_a_grainy_ground_is_taken_off():
    # The ground's grain spreads it by about half the step from ground to
    # rock: the rise from the rock's rim to the shadow is under twice that
    # spread, yet plainly a shadow's (flat, on one arc, away from the light).
    # Which photos pass depends on the grain at the arc's ends (and on the
    # OpenCV release's blur), so six photos are judged together: with a rise
    # of twice the spread required, none lost its shadow.
    cut = 0
    for seed in range(6):
        photo, rock, shadow = lit_rock(
            ground_texture=0.4, seed=seed, azimuth=math.radians(90.0 * seed + 20.0)
        )
        joined = rock | shadow
        assert iou(joined, rock) < 0.87
        kept = shadow_off(log_brightness(photo), joined)
        assert not (kept & ~joined).any()
        assert iou(kept, rock) >= iou(joined, rock) - 0.005
        cut += iou(kept, rock) > 0.88
    assert cut >= 4, cut


@pytest.mark.parametrize("seed", range(4))
def test_a_rock_outlined_right_on_a_grainy_ground_is_left_alone(seed):
    photo, rock, _ = lit_rock(
        texture=0.15, ground_texture=0.4, seed=seed, azimuth=math.radians(90.0 * seed + 20.0)
    )
    assert shadow_off(log_brightness(photo), rock) is rock


@pytest.mark.parametrize("azimuth", [0.0, 100.0, 200.0, 300.0])
@pytest.mark.parametrize("ground_texture", [0.0, 0.3])
def test_a_shadow_that_joined_a_light_rock_is_taken_off(azimuth, ground_texture):
    # A cue that takes in whatever differs from the lit ground runs round a
    # light rock and its shadow; the rock's rim falls to the shadow, darker
    # than the ground and keeping its grain, at the occluding edge.
    photo, rock, shadow = lit_rock(
        rock_albedo=0.9,
        ground_albedo=0.3,
        azimuth=math.radians(azimuth),
        ground_texture=ground_texture,
        seed=1,
    )
    joined = rock | shadow
    assert iou(joined, rock) < 0.87
    kept = shadow_off(log_brightness(photo), joined)
    assert not (kept & ~joined).any()
    assert iou(kept, rock) > 0.92, iou(kept, rock)


def faceted_light_rock(seed: int, turn: float, ground_texture: float = 0.3) -> tuple[np.ndarray, np.ndarray]:
    """A smooth light rock (a disc) with a facet turned from the light: the
    lit part ends at a sharp edge, past which the rock, in sky light alone,
    is darker than the lit ground. No shadow is drawn."""
    rng = np.random.default_rng(seed)
    rr, cc = np.mgrid[: SHAPE[0], : SHAPE[1]].astype(np.float64)
    dy, dx = rr - CENTRE[0], cc - CENTRE[1]
    rock = np.hypot(dy, dx) <= 55.0
    facet = rock & ((dx * math.cos(turn) + dy * math.sin(turn)) > 28.0)
    grain = cv2.GaussianBlur(rng.standard_normal(SHAPE).astype(np.float32), (0, 0), 1.5)
    grain /= max(float(grain.std()), 1e-9)
    albedo = np.where(rock, 0.6, 0.35 * np.exp(ground_texture * grain))
    ambient = 0.15
    light = np.where(facet, ambient, ambient + (1.0 - ambient) * np.where(rock, 0.8, 0.6))
    photo = cv2.GaussianBlur((albedo * light).astype(np.float32), (0, 0), 1.0)
    return np.clip(photo + 0.005 * rng.standard_normal(SHAPE), 0.0, 1.0), rock


@pytest.mark.parametrize("seed", range(4))
def test_a_light_rocks_smooth_facet_in_shade_is_no_shadow(seed):
    # The facet falls from the lit part at a sharp edge to a flat band
    # darker than the ground, as a shadow does; but it is smooth where the
    # ground is grainy, and a shadow keeps the ground's grain (without that
    # rule the facet was cut off: IoU 0.815).
    photo, rock = faceted_light_rock(seed, math.radians(90.0 * seed + 20.0))
    assert np.percentile(photo[rock], 10) < np.median(photo[~rock])
    assert shadow_off(log_brightness(photo), rock) is rock


@pytest.mark.parametrize("seed", range(4))
def test_a_rock_outlined_right_is_left_alone(seed):
    # Its own shaded side (a dark rim) and its texture are no shadow.
    photo, rock, _ = lit_rock(texture=0.15, seed=seed, azimuth=math.radians(90.0 * seed))
    assert shadow_off(log_brightness(photo), rock) is rock


@pytest.mark.parametrize(("arms", "depth", "blur"), [(6, 0.3, 1.5), (5, 0.45, 2.5), (8, 0.6, 3.5)])
def test_a_blurred_stars_arms_are_no_shadow(arms, depth, blur):
    # A ray along an arm runs through pixels half rock, half ground under
    # the blur: a band between their levels, like a shadow's, but no wider
    # than the blur, and cutting it would notch the arm.
    rr, cc = np.mgrid[: SHAPE[0], : SHAPE[1]]
    angle = np.arctan2(rr - CENTRE[0], cc - CENTRE[1])
    star = np.hypot(rr - CENTRE[0], cc - CENTRE[1]) <= 60.0 * (1 + depth * np.cos(arms * angle))
    photo = cv2.GaussianBlur(np.where(star, 0.1, 0.6).astype(np.float32), (0, 0), blur)
    assert shadow_off(log_brightness(photo), star) is star


def test_small_and_empty_masks_are_left_alone():
    photo, _, _ = lit_rock()
    empty = np.zeros(SHAPE, bool)
    assert shadow_off(log_brightness(photo), empty) is empty
    dot = np.zeros(SHAPE, bool)
    dot[100:105, 100:105] = True
    assert shadow_off(log_brightness(photo), dot) is dot


@settings(max_examples=40, deadline=None)
@given(
    azimuth=st.floats(0.0, 360.0),
    elevation=st.floats(20.0, 60.0),
    radius=st.floats(30.0, 60.0),
    texture=st.floats(0.0, 0.15),
    seed=st.integers(0, 2**16),
    rock_albedo=st.sampled_from([0.25, 0.9]),
    ground_texture=st.floats(0.0, 0.3),
)
def test_the_result_is_one_piece_of_the_mask_that_keeps_the_rock(
    azimuth, elevation, radius, texture, seed, rock_albedo, ground_texture
):
    # Dark rocks and light ones (whose shadow is darker than the ground).
    photo, rock, shadow = lit_rock(
        radius=radius,
        rock_albedo=rock_albedo,
        ground_albedo=0.7 if rock_albedo < 0.5 else 0.3,
        azimuth=math.radians(azimuth),
        elevation=math.radians(elevation),
        texture=texture,
        seed=seed,
        ground_texture=ground_texture,
    )
    joined = rock | shadow
    assert_one_piece_never_worse(shadow_off(log_brightness(photo), joined), joined, rock)


def assert_one_piece_never_worse(kept: np.ndarray, joined: np.ndarray, rock: np.ndarray) -> None:
    """``kept`` is one 4-connected piece of ``joined``, no worse a fit to the rock
    than ``joined`` by more than a sliver."""
    assert not (kept & ~joined).any()
    count, _ = cv2.connectedComponents(kept.astype(np.uint8), connectivity=4)
    assert count == 2
    assert iou(kept, rock) >= iou(joined, rock) - 0.02


# A rock lighter than its own shadow (a mid-toned rock: the shadow is the
# ground in sky light alone) shows no rise from rim to shadow; the inner
# outline another cue drew is the rock.


@pytest.mark.parametrize("azimuth", [0.0, 100.0, 200.0, 300.0])
@pytest.mark.parametrize("rock_albedo", [0.4, 0.5])
def test_an_inner_outline_that_leaves_out_the_shadow_is_the_rock(azimuth, rock_albedo):
    photo, rock, shadow = lit_rock(
        rock_albedo=rock_albedo,
        texture=0.1,
        azimuth=math.radians(azimuth),
        seed=int(azimuth),
        ground_texture=0.08,
    )
    gray = log_brightness(photo)
    lit_half = rock & (photo > np.median(photo[rock]))
    assert shadow_left_out(gray, rock | shadow, [rock]) == 0
    # The most probable inner outline that qualifies wins; others are passed over.
    assert shadow_left_out(gray, rock | shadow, [lit_half, rock]) == 1


@pytest.mark.parametrize("azimuth", [0.0, 100.0, 200.0, 300.0])
@pytest.mark.parametrize("texture", [0.05, 0.15])
def test_a_rocks_own_shaded_side_is_no_shadow(azimuth, texture):
    # Left out by an outline of the lit half, the shaded half keeps the
    # rock's shading and texture: it is not darkened ground.
    photo, rock, _ = lit_rock(
        rock_albedo=0.4, texture=texture, azimuth=math.radians(azimuth), seed=7, ground_texture=0.08
    )
    lit_half = rock & (photo > np.median(photo[rock]))
    assert shadow_left_out(log_brightness(photo), rock, [lit_half]) is None


def test_a_dark_rocks_shadow_is_left_to_the_rays():
    # Beside a dark rock the shadow is lighter than the rock's core: the
    # rule does not apply (``shadow_off`` sees the rise instead).
    photo, rock, shadow = lit_rock(rock_albedo=0.2, texture=0.1, ground_texture=0.08)
    assert shadow_left_out(log_brightness(photo), rock | shadow, [rock]) is None


def test_a_light_rock_and_outlines_that_are_not_inside_are_passed_over():
    photo, rock, shadow = lit_rock(rock_albedo=0.9, ground_albedo=0.3, ground_texture=0.08)
    gray = log_brightness(photo)
    assert shadow_left_out(gray, rock | shadow, [rock]) is None
    photo, rock, shadow = lit_rock(rock_albedo=0.45, texture=0.1, ground_texture=0.08)
    gray = log_brightness(photo)
    # Reaching out of the outline, or too small a part of it, or the outline itself.
    beyond = np.roll(rock, 40, axis=1)
    core = rock & (np.hypot(*(np.mgrid[: SHAPE[0], : SHAPE[1]] - np.array(CENTRE)[:, None, None])) < 25)
    assert shadow_left_out(gray, rock | shadow, [beyond, core, rock | shadow]) is None
    assert shadow_left_out(gray, rock | shadow, []) is None
