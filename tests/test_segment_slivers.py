"""Thin slivers that run off a rock's outline along a crevice (``rockscan.core.segment.slivers``)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rockscan.core.render import random_superformula
from rockscan.core.segment import segment
from rockscan.core.segment.slivers import slivers_off
from rockscan.core.superformula import SuperformulaParams, shape_radii
from rockscan.io import default_spec_path, read_spec

SHAPE = (200, 240)


def disk(row: float, col: float, radius: float, shape: tuple[int, int] = SHAPE) -> np.ndarray:
    rr, cc = np.mgrid[: shape[0], : shape[1]]
    return np.hypot(rr - row, cc - col) <= radius


def arc(
    row: float, col: float, radius: float, width: float, angles: tuple[float, float], shape=SHAPE
) -> np.ndarray:
    """A band ``width`` wide along a circle, between two angles (radians, counter-clockwise from +col)."""
    rr, cc = np.mgrid[: shape[0], : shape[1]]
    angle = np.arctan2(-(rr - row), cc - col)
    lo, hi = angles
    within = (angle >= lo) & (angle <= hi)
    return within & (np.abs(np.hypot(rr - row, cc - col) - radius) <= width / 2)


def star(arms: int, depth: float, radius: float = 55.0) -> np.ndarray:
    rr, cc = np.mgrid[: SHAPE[0], : SHAPE[1]]
    angle = np.arctan2(rr - 100, cc - 120)
    return np.hypot(rr - 100, cc - 120) <= radius * (1 + depth * np.cos(arms * angle))


def ellipse(row: float, col: float, half_rows: float, half_cols: float, angle: float = 0.0) -> np.ndarray:
    rr, cc = np.mgrid[: SHAPE[0], : SHAPE[1]]
    u = (rr - row) * np.cos(angle) + (cc - col) * np.sin(angle)
    v = -(rr - row) * np.sin(angle) + (cc - col) * np.cos(angle)
    return (u / half_rows) ** 2 + (v / half_cols) ** 2 <= 1


def superformula_mask(params: SuperformulaParams, mean_radius: float = 45.0) -> np.ndarray:
    """A Superformula shape filled on the grid, its centroid at the grid's centre."""
    radii = mean_radius * shape_radii(params, 720)
    theta = np.linspace(0, 2 * np.pi, radii.size, endpoint=False)
    points = np.stack([SHAPE[1] / 2 + radii * np.cos(theta), SHAPE[0] / 2 - radii * np.sin(theta)], axis=1)
    mask = np.zeros(SHAPE, np.uint8)
    cv2.fillPoly(mask, [np.round(points * 16).astype(np.int32)], 1, shift=4)
    return mask > 0


def iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / (a | b).sum())


def crevice(rock_radius: float = 45.0) -> tuple[np.ndarray, np.ndarray]:
    """A rock, and a band 6 px wide that leaves its edge along the rim of a
    neighbour below it (the shaded crevice between two touching rocks)."""
    rock = disk(90, 120, rock_radius)
    # The neighbour's centre lies below the rock, its rim just touching the rock's edge.
    band = arc(90 + rock_radius + 60, 120, 60, 6, (np.pi / 2 - 1.0, np.pi / 2 + 1.0))
    return rock, band


def test_a_band_along_a_crevice_is_cut_off_and_the_rock_keeps_its_edge():
    rock, band = crevice()
    joined = rock | band
    # The band costs the outline this much before the cut.
    assert iou(joined, rock) < 0.93
    kept = slivers_off(joined)
    assert not (kept & ~joined).any()
    # Where the band meets the rock the opening's disk still fits: the cut
    # runs there, and beyond a few pixels from the rock nothing of it is left.
    rr, cc = np.mgrid[: SHAPE[0], : SHAPE[1]]
    away = band & (np.hypot(rr - 90, cc - 120) > 45 + 8)
    assert away.sum() > 0.6 * (band & ~rock).sum()
    assert not (kept & away).any()
    assert (rock & ~kept).sum() < 0.01 * rock.sum()
    assert iou(kept, rock) > 0.98


def test_a_straight_band_running_away_from_the_rock_is_cut_off():
    rock = disk(100, 90, 45)
    rr, cc = np.mgrid[: SHAPE[0], : SHAPE[1]]
    # A band 5 px wide from the rock's edge to the upper right, 70 px long.
    along = (cc - 90) * np.cos(0.6) - (rr - 100) * np.sin(0.6)
    across = (cc - 90) * np.sin(0.6) + (rr - 100) * np.cos(0.6)
    band = (along >= 30) & (along <= 115) & (np.abs(across) <= 2.5)
    assert iou(slivers_off(rock | band), rock) > 0.98


#: Each shape of the default library, drawn as a mask.
LIBRARY = {spec.name: spec.params for spec in read_spec(default_spec_path()) if spec.params is not None}


@pytest.mark.parametrize(
    "mask",
    [
        *(superformula_mask(params) for params in LIBRARY.values()),
        star(8, 0.4),
        ellipse(100, 120, 20, 90, 0.3),
        # A pebble at a neck is for pebbles_off: it is round, not a sliver.
        disk(100, 120, 50) | disk(100, 176, 12),
        np.zeros(SHAPE, bool),
    ],
    ids=[*LIBRARY, "star-8", "thin-ellipse", "pebble", "empty"],
)
def test_the_librarys_shapes_a_stars_arms_and_a_pebble_are_left_alone(mask):
    assert slivers_off(mask) is mask


def test_the_thin_arms_of_a_star_all_round_are_left_alone():
    # Eight needles, each long and reaching far from the body (a random rock
    # the renderer draws): one alone would be a sliver, but they lie all round,
    # so they are the rock's own arms. (Without that test, two thirds of the
    # area would go.)
    needles = superformula_mask(SuperformulaParams(8, 8, 0.53, 3.77, 3.77), 40)
    assert not (needles[0].any() or needles[-1].any() or needles[:, 0].any() or needles[:, -1].any())
    assert slivers_off(needles) is needles


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_the_renderers_random_rocks_are_left_alone(seed):
    # Stars of 1-8 arms, needles, spindles, blobs: nothing of their own shape is a sliver.
    mask = superformula_mask(random_superformula(np.random.default_rng(seed)))
    assert slivers_off(mask) is mask


def test_a_lip_of_the_rocks_own_edge_beside_a_dent_is_left_alone():
    # A dent 3 px wide just inside the edge, open to the ground at one end:
    # the edge beyond it is a thin lip, long, but no farther from the body than the dent.
    rock = disk(100, 120, 50)
    dent = arc(100, 120, 43.5, 3, (0.0, np.pi / 2)) | arc(100, 120, 47, 7, (-0.05, 0.05))
    mask = rock & ~dent
    assert slivers_off(mask) is mask


@settings(max_examples=30, deadline=None)
@given(a=st.floats(15, 95), b=st.floats(15, 95), angle=st.floats(0, np.pi))
def test_an_ellipse_is_left_alone(a, b, angle):
    mask = ellipse(100, 120, a, b, angle)
    assert slivers_off(mask) is mask


@settings(max_examples=15, deadline=None)
@given(radius=st.floats(30, 60), scale=st.sampled_from([0.5, 1.0, 2.0]))
def test_a_crevice_is_cut_off_at_any_size(radius, scale):
    rock, band = crevice(radius)
    size = (round(SHAPE[1] * scale), round(SHAPE[0] * scale))
    rock = cv2.resize(rock.astype(np.uint8), size, interpolation=cv2.INTER_NEAREST) > 0
    band = cv2.resize(band.astype(np.uint8), size, interpolation=cv2.INTER_NEAREST) > 0
    # Before the cut 0.80-0.95 (the band is 6 px wide on rocks of 30-60 px).
    assert iou(slivers_off(rock | band), rock) > max(0.96, iou(rock | band, rock) + 0.04)


def test_a_dark_rocks_outline_leaves_the_dark_crevice_beside_it():
    """A photo: a dark rock, and a crevice as dark as the rock running off its
    edge along a light neighbour's rim (drawn, blurred, with sensor noise)."""
    shape = (240, 320)
    rr, cc = np.mgrid[: shape[0], : shape[1]]
    rock = np.hypot(rr - 110, cc - 160) <= 50
    neighbour = np.hypot(rr - 110 - 50 - 66, cc - 160) <= 63
    rim = (np.hypot(rr - 110 - 50 - 66, cc - 160) <= 69) & ~neighbour & ~rock
    photo = np.full(shape, 0.7, np.float32)
    photo[neighbour] = 0.62
    photo[rim] = 0.3
    photo[rock] = 0.3
    photo = cv2.GaussianBlur(photo, (0, 0), 1.2)
    photo += np.random.default_rng(3).normal(0, 0.01, shape).astype(np.float32)
    seg = segment(np.clip(photo, 0, 1))
    main = seg.labels == 1
    assert iou(main, rock) > 0.95
    # Of the crevice farther than a few pixels from the rock, almost nothing is kept.
    away = rim & (np.hypot(rr - 110, cc - 160) > 56)
    assert (main & away).sum() < 0.05 * away.sum()
