"""With ``--all``, a region as near its ground's colour as the ground's own
patches is no rock (``rockscan.core.segment.scene._unlike_ground``)."""

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
from rockscan.core.segment.types import RockMask

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
import bench_segment

SHAPE = (240, 480)


def as_rock(mask: np.ndarray) -> RockMask:
    """A frame-sized mask as a rock in the window round it."""
    rows, cols = np.nonzero(mask)
    r0, r1, c0, c1 = rows.min(), rows.max() + 1, cols.min(), cols.max() + 1
    window = mask[r0:r1, c0:c1]
    return RockMask(mask=window, coverage=window.astype(np.float32), origin_rowcol=(int(r0), int(c0)))


def discs(centres, radius=22.0):
    return [coverage(SHAPE, centre, (radius, radius)) for centre in centres]


CENTRES = [(60 + 120 * (i % 2), 40 + 57 * i) for i in range(8)]


def graded(levels, ground=0.35, strength=0.0, noise=0.01, seed=0):
    """Gray photo in [0, 1]: discs of the given levels on a ground lit
    ``1 + strength * (x - 0.5)`` across the frame, and their masks."""
    light = 1.0 + strength * (np.arange(SHAPE[1]) / SHAPE[1] - 0.5)[None, :]
    image = np.full(SHAPE, ground) * light
    covers = discs(CENTRES[: len(levels)])
    for cover, level in zip(covers, levels, strict=True):
        image = image * (1 - cover) + level * light * cover
    image = image + np.random.default_rng(seed).normal(0.0, noise, SHAPE)
    return np.clip(image, 0.0, 1.0).astype(np.float32), [cover >= 0.5 for cover in covers]


def kept_indices(rocks, kept):
    return [next(i for i, rock in enumerate(rocks) if rock is k) for k in kept]


def test_a_patch_of_lighter_ground_among_rocks_is_dropped_and_every_rock_kept():
    # The sixth region is ground lit a tenth brighter: a step from the ground,
    # but a twentieth of the rocks' own.
    image, masks = graded([0.8, 0.75, 0.85, 0.8, 0.7, 0.385, 0.8, 0.78])
    rocks = [as_rock(m) for m in masks]
    kept = scene._unlike_ground(rocks, cielab(image))
    assert kept_indices(rocks, kept) == [0, 1, 2, 3, 4, 6, 7]


def test_a_patch_in_colour_is_judged_by_its_colour_not_its_brightness():
    # On a brown ground, a blue rock of the ground's brightness stays; a patch
    # of the ground's hue a little lighter goes.
    ground = np.array([0.45, 0.35, 0.25], np.float32)
    image = np.broadcast_to(ground, (*SHAPE, 3)).copy()
    colours = [(0.8, 0.6, 0.5), (0.7, 0.7, 0.6), (0.3, 0.35, 0.55), (0.48, 0.375, 0.27), (0.85, 0.8, 0.7)]
    masks = [m >= 0.5 for m in discs(CENTRES[:5])]
    for mask, colour in zip(masks, colours, strict=True):
        image[mask] = colour
    image += np.random.default_rng(1).normal(0.0, 0.01, image.shape).astype(np.float32)
    rocks = [as_rock(m) for m in masks]
    kept = scene._unlike_ground(rocks, cielab(np.clip(image, 0, 1)))
    assert kept_indices(rocks, kept) == [0, 1, 2, 4]


@pytest.mark.parametrize("strength", [1.0, 1.4])
def test_a_rock_in_the_dim_side_of_strong_light_is_kept(monkeypatch, strength):
    # Light falls to 0.5 (0.3 at 1.4) of the middle's at the frame's edge: the
    # rock on the dim side is about as bright as the ground of the frame's
    # middle, but as far from its own ground as any rock is from its own.
    image, masks = graded([0.7] * 8, strength=strength)
    rocks = [as_rock(m) for m in masks]
    assert len(scene._unlike_ground(rocks, cielab(image))) == 8
    # Against the ground of the whole frame, it would go: with no reach, no
    # region has ground of its own.
    monkeypatch.setattr(scene, "GROUND_REACH", 0.0)
    assert len(scene._unlike_ground(rocks, cielab(image))) < 8


def test_every_rock_of_a_strongly_graded_photo_is_found():
    image, _ = graded([0.7] * 8, strength=1.4)
    assert segment(np.round(image * 255).astype(np.uint8), all_rocks=True).n_rocks == 8


def test_a_region_hemmed_in_by_rocks_is_judged_against_all_the_free_ground():
    # A ring of rocks round a patch of ground: no free ground of its own.
    image, _ = graded([])
    centre = (120, 240)
    angles = np.linspace(0, 2 * np.pi, 9)[:-1]
    ring = [
        coverage(SHAPE, (centre[0] + 34 * np.sin(a), centre[1] + 34 * np.cos(a)), (16, 16)) for a in angles
    ]
    masks = [c >= 0.5 for c in ring]
    for mask in masks:
        image[mask] = 0.8
    hole = (coverage(SHAPE, centre, (14, 14)) >= 0.5) & ~np.logical_or.reduce(masks)
    image[hole] = 0.37
    rocks = [as_rock(m) for m in masks] + [as_rock(hole)]
    kept = scene._unlike_ground(rocks, cielab(image))
    assert kept_indices(rocks, kept) == list(range(8))


def test_too_little_free_ground_keeps_every_region():
    image, _ = graded([])
    third = SHAPE[1] // 3
    masks = [np.zeros(SHAPE, bool) for _ in range(3)]
    for i, mask in enumerate(masks):
        mask[:, i * third : (i + 1) * third] = True
    rocks = [as_rock(m) for m in masks]
    assert scene._unlike_ground(rocks, cielab(image)) == rocks


@settings(max_examples=25, deadline=None)
@given(st.lists(st.floats(0.36, 0.95), min_size=3, max_size=8), st.floats(0.0, 1.2))
def test_the_regions_farthest_from_the_ground_are_always_kept(levels, strength):
    image, masks = graded(levels, strength=strength)
    rocks = [as_rock(m) for m in masks]
    kept = scene._unlike_ground(rocks, cielab(image))
    # A sub-list in order, holding at least half: every region at least as
    # far from its ground as the median one stays.
    indices = kept_indices(rocks, kept)
    assert indices == sorted(indices)
    assert 2 * len(kept) >= len(rocks)


@pytest.mark.parametrize(("index", "without"), [(4004, 25), (4104, 24), (4135, 18)])
def test_development_scenes_are_counted_right_once_ground_patches_go(monkeypatch, index, without):
    # Patches of ground between the rocks, lighter or in another hue than the
    # rest of the ground (development crowded scenes; counts without the rule).
    pixels, truth, _ = bench_segment.photo("dev", "crowded", index)
    n_true = len(np.unique(truth)) - 1
    assert segment(pixels, all_rocks=True).n_rocks == n_true
    monkeypatch.setattr(scene, "GROUND_LIKE", 0.0)
    assert segment(pixels, all_rocks=True).n_rocks == without
