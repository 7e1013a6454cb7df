"""The watershed basins and the opening among the candidate outlines (rockscan.core.segment)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
import bench_segment

from rockscan.core.segment.cues import (
    basin,
    centre_basin,
    centre_disk,
    centre_part,
    colour_gradient,
    core_basin,
    edge_strength,
)
from rockscan.core.segment.split import opened as _opened
from rockscan.core.segment.types import RockMask


def dome(shape, centre, radius, level=0.35):
    """A lit dome: darkest at its rim, as a rounded rock is, so two that touch show an edge."""
    rr, cc = np.mgrid[: shape[0], : shape[1]]
    d = np.hypot(rr - centre[0], cc - centre[1]) / radius
    inside = d < 1.0
    shade = np.where(inside, level + 0.25 * np.sqrt(np.clip(1.0 - d**2, 0.0, 1.0)), 0.0)
    return inside, shade


def photo_of_domes(shape, domes, ground=0.85, seed=0):
    image = np.full(shape, ground)
    masks = []
    for centre, radius in domes:
        inside, shade = dome(shape, centre, radius)
        image[inside] = shade[inside]
        masks.append(inside)
    rng = np.random.default_rng(seed)
    return np.clip(image + rng.normal(0.0, 0.01, shape), 0.0, 1.0).astype(np.float32), masks


def iou(a, b):
    return (a & b).sum() / (a | b).sum()


def test_the_centre_basin_parts_a_rock_from_the_touching_neighbours_of_its_crop():
    # A crop centred on one rock, two rocks of its colour touching it: a
    # threshold joins all three, the edge between them still parts them.
    shape = (120, 120)
    image, (centre, *_neighbours) = photo_of_domes(shape, [((60, 60), 30), ((60, 8), 23), ((8, 95), 26)])
    joined = image < 0.7
    assert iou(joined, centre) < 0.7
    flooded = centre_basin(colour_gradient(image, np.dtype(np.float32)))
    assert flooded is not None
    assert iou(flooded, centre) > 0.9


@pytest.mark.parametrize("speck", [0, 3])
def test_the_otsu_part_under_the_centre_is_the_rock_round_a_speck_at_the_centre(speck):
    # A dark rock on light ground with a light speck of its own texture at the
    # frame's centre: the class under the centre is the rock's, not the speck's.
    shape = (120, 140)
    image, (rock,) = photo_of_domes(shape, [((60, 70), 35)])
    rr, cc = np.mgrid[: shape[0], : shape[1]]
    image[np.hypot(rr - 59.5, cc - 69.5) <= speck + 0.5] = 0.95
    part = centre_part(image, np.dtype(np.float32))
    assert part is not None and iou(part, rock) > 0.95


def test_the_core_basin_leaves_out_a_soft_cast_shadow():
    # A dark rock and its shadow (darker ground, a soft penumbra): a threshold
    # joins them; from the rock's core the flood stops at the rock's sharp edge.
    from scipy import ndimage

    shape = (160, 200)
    rr, cc = np.mgrid[: shape[0], : shape[1]]
    rock = np.hypot(rr - 80, cc - 70) < 35
    shadow = ndimage.gaussian_filter((np.hypot(rr - 90, (cc - 100) / 1.3) < 30).astype(float), 6.0)
    image = 0.85 - 0.3 * shadow
    image[rock] = 0.25
    image = image.astype(np.float32)
    joined = image < 0.7
    assert iou(joined, rock) < 0.8
    whole = RockMask(mask=joined, coverage=joined.astype(np.float32), origin_rowcol=(0, 0))
    flooded = core_basin(colour_gradient(image, np.dtype(np.float32)), whole)
    assert flooded is not None and iou(flooded, rock) > 0.95


def test_opening_takes_off_pebbles_that_touch_the_rock():
    # Pebbles under a fifth of the rock's radius: the opening's disk fits in no one of them.
    shape = (160, 160)
    image, (rock, *pebbles) = photo_of_domes(
        shape, [((80, 80), 40), ((80, 126), 7), ((33, 80), 8), ((117, 107), 6)]
    )
    joined = image < 0.7
    assert iou(joined, rock) < 0.95
    opened = _opened(joined)
    assert opened is not None and iou(opened, rock) > 0.95
    assert not any((opened & p).sum() > 0.2 * p.sum() for p in pebbles)


@pytest.mark.parametrize("index", [4044, 4070, 4112])
def test_the_centre_basin_keeps_a_crops_neighbours_out(index):
    # Development crops of the independent generator whose rock touches
    # neighbours of its colour: the plain flood crosses a contact and takes in
    # part of a neighbour (IoU 0.61, 0.87 and 0.80), the compact one stops at
    # the rock (0.90, 0.95 and 0.90) on an edge clear enough to be taken.
    pixels, truth, _ = bench_segment.photo("dev", "crop-neighbours", index)
    rock = truth == 1
    gradient = colour_gradient(pixels, pixels.dtype)
    border = np.ones(gradient.shape, bool)
    border[1:-1, 1:-1] = False
    plain = basin(gradient, centre_disk(gradient.shape), border)
    flooded = centre_basin(gradient)
    assert plain is not None and flooded is not None
    assert iou(flooded, rock) >= 0.88
    assert iou(flooded, rock) >= iou(plain, rock) + 0.03


@pytest.mark.parametrize(("condition", "index"), [("small", 4009), ("touching-pebbles", 4096)])
def test_the_centre_basin_is_the_plain_flood_where_the_compact_one_stops_on_no_edge(condition, index):
    # Development photos of one rock off the frame's centre: from the centre
    # the compact flood stops on the ground's texture, about half way to the
    # frame (edge strength 0.24 and 0.29), and the plain flood is kept.
    pixels, _, _ = bench_segment.photo("dev", condition, index)
    gradient = colour_gradient(pixels, pixels.dtype)
    border = np.ones(gradient.shape, bool)
    border[1:-1, 1:-1] = False
    disk = centre_disk(gradient.shape)
    compact = basin(gradient, disk, border, 0.15 / min(gradient.shape))
    plain = basin(gradient, disk, border)
    assert compact is not None and plain is not None and not np.array_equal(compact, plain)
    assert edge_strength(gradient, compact) < 0.4
    assert np.array_equal(centre_basin(gradient), plain)


def test_a_basin_over_flat_ground_is_no_outline():
    # Nothing but flat ground round the centre: the flood stops nowhere in particular.
    gradient = np.zeros((80, 100), np.float32)
    gradient[:, :3] = 1.0  # a rock cut by the frame, far from the centre
    assert centre_basin(gradient) is None
    inner = np.zeros(gradient.shape, bool)
    inner[40, 50] = True
    assert basin(gradient, inner, np.zeros(gradient.shape, bool)) is None  # no ground marker


@settings(max_examples=25, deadline=None)
@given(radius=st.integers(12, 40), row=st.integers(-15, 15), col=st.integers(-15, 15))
def test_opening_keeps_a_disk_whole_and_in_place(radius, row, col):
    rr, cc = np.mgrid[:120, :120]
    disk = (rr - 60 - row) ** 2 + (cc - 60 - col) ** 2 <= radius**2
    opened = _opened(disk)
    assert opened is not None
    # A disk is open already: only the digital disk's corner pixels may go.
    assert not (opened & ~disk).any()
    assert opened.sum() >= 0.97 * disk.sum()


@settings(max_examples=25, deadline=None)
@given(
    radius=st.integers(15, 45),
    share=st.sampled_from([0.2, 0.3]),
    pebbles=st.lists(st.tuples(st.floats(0, 2 * np.pi), st.floats(3, 12)), min_size=0, max_size=4),
)
def test_opening_by_distance_maps_is_the_disk_opening_up_to_pieces_as_wide_as_the_disk(
    radius, share, pebbles
):
    rr, cc = np.mgrid[:140, :140]
    mask = np.hypot(rr - 70, cc - 70) <= radius
    for angle, size in pebbles:
        mask |= (
            np.hypot(rr - 70 - (radius + 2) * np.sin(angle), cc - 70 - (radius + 2) * np.cos(angle)) <= size
        )
    kernel, distance = _opened(mask, share), _opened(mask, share, by_distance=True)
    assert (kernel is None) == (distance is None)
    if kernel is None:
        return
    assert not (distance & ~mask).any()
    # They differ by a pixel along the edge, and on a pebble about as wide as
    # the disk, which one keeps and the other takes off (IoU 0.94 at worst
    # in 2,000 random cases, median 0.996).
    assert (kernel & distance).sum() / (kernel | distance).sum() > 0.93
