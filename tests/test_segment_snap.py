"""An outline moved to the steepest edge beside it (``rockscan.core.segment.snap``).

The rocks are drawn here, a disc or a lobed blob whose brightness falls
towards its rim (a domed rock's limb turning away from the light) and then
steps down to the ground through a Gaussian blur: the half-way level runs
inside the limb, short of the edge, while the edge itself is where the
brightness falls fastest.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rockscan.core.segment.snap import MARGIN, REACH, snapped

SHAPE = (120, 140)
CENTRE = (60.0, 70.0)
#: Width of the darkening limb, in pixels.
LIMB = 7.0


def iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / (a | b).sum())


def drawn(
    radius: float = 30.0,
    lobes: int = 0,
    depth: float = 0.0,
    limb: float = 0.35,
    blur: float = 1.0,
    supersample: int = 8,
    hole: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """A light rock's brightness and its true coverage (area share of each pixel).

    The rock's edge lies at ``radius * (1 + depth cos(lobes theta))`` from
    ``CENTRE``; with ``hole``, it is a ring from ``hole * radius`` out, open
    over a sixth of its turn (a C, whose inner edge no ray from its centre
    reaches before its outer one). Its brightness falls from 0.8 by ``limb``
    over the outer ``LIMB`` pixels of its edge, and the ground is 0.3.
    """
    k = supersample
    rr, cc = np.mgrid[: SHAPE[0] * k, : SHAPE[1] * k].astype(np.float64)
    dy, dx = (rr + 0.5) / k - 0.5 - CENTRE[0], (cc + 0.5) / k - 0.5 - CENTRE[1]
    theta, rho = np.arctan2(dy, dx), np.hypot(dy, dx)
    rock = rho <= radius * (1.0 + depth * np.cos(lobes * theta))
    if hole:
        rock &= (rho >= hole * radius) & (np.abs(theta) > math.pi / 6)
    depth_in = cv2.distanceTransform(rock.astype(np.uint8), cv2.DIST_L2, 5) / k
    shade = np.clip(1.0 - depth_in / LIMB, 0.0, 1.0)
    fine = np.where(rock, 0.8 - limb * shade, 0.3).astype(np.float32)
    light = cv2.resize(fine, (SHAPE[1], SHAPE[0]), interpolation=cv2.INTER_AREA)
    truth = cv2.resize(rock.astype(np.float32), (SHAPE[1], SHAPE[0]), interpolation=cv2.INTER_AREA)
    return cv2.GaussianBlur(light, (0, 0), blur), truth


def half_way(light: np.ndarray) -> np.ndarray:
    """A coverage whose 0.5 level is half-way between the rock's middle (0.8) and the ground (0.3)."""
    rock, ground = 0.8, 0.3
    return np.clip(0.5 + (light - (rock + ground) / 2) / (rock - ground), 0.0, 1.0).astype(np.float32)


def off_outline(before: np.ndarray, after: np.ndarray) -> float:
    """How far from the outline of ``before`` (its 0.5 level) ``after`` differs from it, in pixels."""
    changed = np.abs(after - before) > 1e-6
    if not changed.any():
        return 0.0
    inside = (before >= 0.5).astype(np.uint8)
    edge = inside - cv2.erode(inside, np.ones((3, 3), np.uint8), borderType=cv2.BORDER_REPLICATE)
    return float(cv2.distanceTransform(1 - edge, cv2.DIST_L2, 5)[changed].max())


def area(coverage: np.ndarray) -> float:
    return float((coverage >= 0.5).sum())


@pytest.mark.parametrize("limb", [0.25, 0.3, 0.35])
def test_an_outline_inside_a_darkening_limb_moves_out_to_the_edge(limb):
    # The half-way level lies in the limb, a pixel or so inside the edge:
    # the steepest fall is the edge, and the outline moves there.
    light, truth = drawn(limb=limb)
    before = half_way(light)
    after = snapped(light, before, lighter=True)
    assert after is not None
    assert area(before) < 0.95 * truth.sum()
    assert abs(area(after) - truth.sum()) < 0.6 * abs(area(before) - truth.sum())
    assert iou(after >= 0.5, truth >= 0.5) > iou(before >= 0.5, truth >= 0.5) + 0.02


def test_a_dark_rock_is_read_the_other_way():
    # The same rock inverted: its edge rises going out.
    light, truth = drawn(limb=0.35)
    dark = 1.1 - light
    before = half_way(light)
    assert snapped(dark, before, lighter=False) is not None
    assert iou(snapped(dark, before, lighter=False) >= 0.5, truth >= 0.5) > iou(before >= 0.5, truth >= 0.5)
    # Read with the wrong polarity, the steepest "fall" is no edge of this rock.
    wrong = snapped(dark, before, lighter=True)
    assert wrong is None or iou(wrong >= 0.5, truth >= 0.5) <= iou(before >= 0.5, truth >= 0.5)


@pytest.mark.parametrize("blur", [0.7, 1.0, 2.0])
def test_a_clean_step_is_left_where_half_way_put_it(blur):
    # No limb: half-way is the edge, and nothing moves by a reach's share.
    light, _ = drawn(limb=0.0, blur=blur)
    before = half_way(light)
    after = snapped(light, before, lighter=True)
    assert after is None or abs(area(after) - area(before)) <= 0.01 * area(before)


def test_a_lobed_rock_moves_out_all_round():
    light, truth = drawn(radius=32.0, lobes=5, depth=0.3, limb=0.35)
    before = half_way(light)
    after = snapped(light, before, lighter=True)
    assert after is not None
    assert off_outline(before, after) <= REACH + MARGIN + 1.5
    assert iou(after >= 0.5, truth >= 0.5) > iou(before >= 0.5, truth >= 0.5) + 0.02


def test_the_bays_no_ray_from_the_centre_sees_stay_as_they_are():
    # A C-shaped rock, open to the right: rays from its centre towards its
    # back leave it by its outer edge, which moves out; its inner edge
    # there, a bay they cross first, is left alone.
    light, _ = drawn(radius=40.0, hole=0.55, limb=0.35)
    before = half_way(light)
    after = snapped(light, before, lighter=True)
    assert after is not None
    rr, cc = np.mgrid[: SHAPE[0], : SHAPE[1]]
    rho = np.hypot(rr - CENTRE[0], cc - CENTRE[1])
    back = (cc - CENTRE[1]) < -0.5 * rho
    inner = back & (rho < 0.55 * 40.0 + 4.0)
    assert np.array_equal(after[inner], before[inner])
    outer = back & (rho > 40.0 - 4.0)
    assert (after[outer] >= 0.5).sum() > (before[outer] >= 0.5).sum()


def test_nothing_to_move_gives_none():
    light, _ = drawn()
    assert snapped(light, np.zeros(SHAPE, np.float32), lighter=True) is None
    assert snapped(light, half_way(light), lighter=True, reach=0.0) is None


@settings(max_examples=40, deadline=None)
@given(
    radius=st.floats(8.0, 40.0),
    lobes=st.integers(0, 6),
    depth=st.floats(0.0, 0.3),
    limb=st.floats(0.0, 0.45),
    blur=st.floats(0.5, 3.0),
    noise=st.floats(0.0, 0.05),
    seed=st.integers(0, 2**16),
    lighter=st.booleans(),
)
def test_a_moved_outline_stays_a_coverage_within_reach(
    radius, lobes, depth, limb, blur, noise, seed, lighter
):
    light, _ = drawn(radius=radius, lobes=lobes, depth=depth, limb=limb, blur=blur, supersample=2)
    light = light + np.random.default_rng(seed).normal(0.0, noise, SHAPE).astype(np.float32)
    before = half_way(light)
    after = snapped(light, before, lighter=lighter)
    if after is None:
        return
    assert after.shape == before.shape and after.dtype == np.float32
    assert after.min() >= 0.0 and after.max() <= 1.0
    # Only the ramp across the outline moves, by at most the reach.
    assert off_outline(before, after) <= REACH + MARGIN + 1.5


def test_an_easy_photo_keeps_the_outline_the_fast_path_gave(monkeypatch):
    # The fast path's outline stood out above every other region and steps
    # against the ground all round: it is not moved.
    import rockscan.core.segment as segmentation
    import rockscan.core.segment.finish as finish
    from rockscan.core.render import RenderConfig, render_photo
    from rockscan.io import default_spec_path, read_spec

    spec = next(iter(read_spec(default_spec_path())))
    pixels = render_photo(spec.params, RenderConfig(rows=240, cols=320), rng=3, name=spec.name).pixels
    _, _, easy = segmentation._chosen(pixels, segmentation.SegmentConfig())
    assert easy
    moved = segmentation.segment(pixels)
    monkeypatch.setattr(finish, "SNAP_REACH", 0.0)
    kept = segmentation.segment(pixels)
    assert np.array_equal(moved.rocks[0].coverage, kept.rocks[0].coverage)
