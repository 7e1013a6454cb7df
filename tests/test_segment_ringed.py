"""With ``--all``, a rock of the ground's own colour is found by the ring of
edge round it (``rockscan.core.segment.ringed``)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_segment import coverage

import rockscan.core.segment.scene as scene
from rockscan.core.segment import segment
from rockscan.core.segment.channels import cielab
from rockscan.core.segment.ringed import lab_gradient, ringed_regions

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
import bench_segment

SHAPE = (240, 480)
GROUND = 0.35


def iou(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.count_nonzero(a & b) / np.count_nonzero(a | b))


def rimmed(shape, centre, radius, rim=0.25, fade=4.0):
    """A rock of the ground's level in its middle, darker towards its rim
    (light falls off its sides): its median is near the ground's, but its
    edge is a step of ``rim``."""
    rows, cols = np.indices(shape)
    r = np.hypot(rows - centre[0], cols - centre[1])
    cover = coverage(shape, centre, (radius, radius))
    level = GROUND - rim * np.exp(-np.clip(radius - r, 0.0, None) / fade)
    return cover, level


def scene_of(found_centres, ringed_centres, radius=22.0, found_level=0.6, seed=0):
    """Gray image: rocks of ``found_level`` (returned as labels, as found
    rocks) and rimmed rocks of the ground's level (their masks)."""
    image = np.full(SHAPE, GROUND)
    labels = np.zeros(SHAPE, np.int32)
    for number, centre in enumerate(found_centres, start=1):
        cover = coverage(SHAPE, centre, (radius, radius))
        image = image * (1 - cover) + found_level * cover
        labels[cover >= 0.5] = number
    masks = []
    for centre in ringed_centres:
        cover, level = rimmed(SHAPE, centre, radius)
        image = image * (1 - cover) + level * cover
        masks.append(cover >= 0.5)
    image = image + np.random.default_rng(seed).normal(0.0, 0.005, SHAPE)
    return np.clip(image, 0, 1).astype(np.float32), labels, masks


FOUND = [(60, 60), (180, 60), (60, 420), (180, 420)]


def test_a_rock_of_the_grounds_level_with_a_rim_is_found():
    image, labels, (truth,) = scene_of(FOUND, [(120, 240)])
    (region,) = ringed_regions(lab_gradient(cielab(image)), labels, 0.2)
    assert iou(region, truth) >= 0.85


def test_a_rock_in_colour_is_ringed_by_its_colour_edge():
    # On a brown ground, a rock of the ground's colour in its middle, bluer
    # towards its rim at the ground's brightness.
    gray, labels, (truth,) = scene_of(FOUND, [(120, 240)])
    ground = np.array([0.45, 0.35, 0.25], np.float32)
    image = np.broadcast_to(ground, (*SHAPE, 3)).copy()
    image[labels > 0] = (0.8, 0.7, 0.6)
    towards_rim = ((GROUND - gray) / 0.25).clip(0, 1)[..., None] * truth[..., None]
    image = image + towards_rim * (np.array([0.3, 0.36, 0.5], np.float32) - ground)
    (region,) = ringed_regions(lab_gradient(cielab(image)), labels, 0.2)
    assert iou(region, truth) >= 0.8


def test_a_pocket_of_ground_walled_in_by_rocks_is_no_rock():
    # Eight rocks in a ring close a patch of plain ground between them.
    centre = (120, 240)
    angles = np.linspace(0, 2 * np.pi, 9)[:-1]
    ring = [(centre[0] + 40 * np.sin(a), centre[1] + 40 * np.cos(a)) for a in angles]
    image, labels, _ = scene_of([*ring, *FOUND], [], radius=18.0)
    assert ringed_regions(lab_gradient(cielab(image)), labels, 0.2) == []


def test_a_ring_open_to_the_frame_is_ground():
    image, labels, _ = scene_of(FOUND, [(120, 0)])
    assert ringed_regions(lab_gradient(cielab(image)), labels, 0.2) == []


def test_rocks_that_fill_the_frame_leave_nothing_to_look_in():
    labels = np.repeat(np.arange(1, 4, dtype=np.int32), SHAPE[1] // 3)[None, :].repeat(SHAPE[0], axis=0)
    image = np.random.default_rng(0).uniform(0, 1, SHAPE).astype(np.float32)
    assert ringed_regions(lab_gradient(cielab(image)), labels, 0.2) == []


def test_too_few_rocks_to_judge_by_finds_nothing():
    image, labels, _ = scene_of(FOUND[:2], [(120, 240)])
    assert ringed_regions(lab_gradient(cielab(image)), labels, 0.2) == []


@pytest.mark.parametrize(("radius", "kept"), [(12.0, 1), (8.5, 0)])
def test_a_small_ringed_region_is_a_speck(radius, kept):
    # The median rock has a radius of 22 px: a ring of 12 px holds 0.3 of
    # its area and is kept at 0.2, one of 8.5 px holds 0.15 and is a speck.
    image, labels, _ = scene_of(FOUND, [])
    small, level = rimmed(SHAPE, (120, 240), radius)
    image = (image * (1 - small) + level * small).astype(np.float32)
    assert len(ringed_regions(lab_gradient(cielab(image)), labels, 0.2)) == kept


@pytest.mark.parametrize(("half_size", "kept"), [((9, 60), 0), ((22, 26), 1)])
def test_a_strip_closed_by_edges_is_no_rock_but_a_block_is(half_size, kept):
    # A strip of ground between bricks has a rim all round too, but is thin:
    # 18 x 120 px (thickness 0.36), against a block of 44 x 52 px (0.81).
    image, labels, _ = scene_of(FOUND, [])
    rows, cols = np.indices(SHAPE)
    inside = (np.abs(rows - 120) < half_size[0]) & (np.abs(cols - 240) < half_size[1])
    image[inside] = GROUND - 0.2
    image[inside & (np.abs(rows - 120) < half_size[0] - 3) & (np.abs(cols - 240) < half_size[1] - 3)] = GROUND
    assert len(ringed_regions(lab_gradient(cielab(image)), labels, 0.2)) == kept


@settings(max_examples=20, deadline=None)
@given(
    st.lists(
        st.tuples(st.integers(30, 210), st.integers(30, 450)),
        min_size=3,
        max_size=7,
        unique=True,
    ),
    st.integers(0, 2**16),
)
def test_no_region_found_lies_on_a_rock_found_before(centres, seed):
    found, ringed = centres[:-1], centres[-1:]
    image, labels, _ = scene_of(found, ringed, radius=18.0, seed=seed)
    regions = ringed_regions(lab_gradient(cielab(image)), labels, 0.2)
    for region in regions:
        assert not np.any(region & (labels > 0))
    assert len(regions) <= 1 + len(found)


def test_the_gradient_of_a_step_is_its_height_in_lab_units():
    # 100 times a step in brightness, spread by the blur: its peak is the
    # step over the blur's width, and its sum across the step the step.
    image = np.zeros((40, 40), np.float32)
    image[:, 20:] = 0.5
    row = lab_gradient(cielab(image), sigma=1.0)[20]
    assert row.sum() == pytest.approx(50.0, rel=0.02)
    assert row.argmax() in (19, 20)


def test_every_rock_of_a_photo_with_rocks_of_the_grounds_level_is_found(monkeypatch):
    # Six light rocks and, between them, six of the ground's level that only
    # their darker rims show.
    image = np.full(SHAPE, GROUND)
    truths = []
    for i in range(12):
        centre = (60 + 120 * (i // 6), 40 + 80 * (i % 6))
        if i % 2 == 0:
            cover, level = coverage(SHAPE, centre, (24, 24)), 0.75
        else:
            cover, level = rimmed(SHAPE, centre, 24.0)
        image = image * (1 - cover) + level * cover
        truths.append(cover >= 0.5)
    image = image + np.random.default_rng(0).normal(0.0, 0.01, SHAPE)
    pixels = np.round(np.clip(image, 0, 1) * 255).astype(np.uint8)
    found = segment(pixels, all_rocks=True)
    assert found.n_rocks == 12
    labels = bench_segment.segmentation_labels(found, SHAPE)
    for truth in truths:
        assert max(iou(labels == k, truth) for k in range(1, 13)) >= 0.85
    monkeypatch.setattr(scene, "_ringed", lambda *args: [])
    assert segment(pixels, all_rocks=True).n_rocks == 6


@pytest.mark.parametrize(("index", "without"), [(4066, 28), (4154, 8), (4353, 26)])
def test_development_scenes_are_counted_right_once_ringed_rocks_are_found(monkeypatch, index, without):
    # Gray rocks on gray ground beside coloured ones (development crowded
    # scenes; counts without the step).
    pixels, truth, _ = bench_segment.photo("dev", "crowded", index)
    n_true = len(np.unique(truth)) - 1
    assert segment(pixels, all_rocks=True).n_rocks == n_true
    monkeypatch.setattr(scene, "_ringed", lambda *args: [])
    assert segment(pixels, all_rocks=True).n_rocks == without
