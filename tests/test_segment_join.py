"""Pieces of one rock joined again (``rockscan.core.segment.join``)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rockscan.core.segment import join


def _disk(shape: tuple[int, int], centre: tuple[float, float], radius: float) -> np.ndarray:
    rows, cols = np.indices(shape)
    return (rows - centre[0]) ** 2 + (cols - centre[1]) ** 2 <= radius**2


def test_the_features_of_two_squares_side_by_side_are_exact():
    labels = np.zeros((30, 40), np.int32)
    labels[10:20, 10:20] = 1
    labels[10:20, 20:30] = 2
    gray = np.full(labels.shape, 0.2)
    gray[labels == 1] = 0.8
    gray[labels == 2] = 0.6
    pairs, features = join.pair_features(labels, gray)
    assert pairs.tolist() == [[1, 2]]
    got = dict(zip(join.FEATURES, features[0], strict=True))
    assert got["union"] == 2.0  # two regions of the median's area
    assert got["smaller"] == 1.0
    assert got["ratio"] == 1.0
    # The contact is 10 pixels long (a column on each side), against an
    # equivalent diameter of 2 sqrt(100 / pi).
    assert got["contact"] == pytest.approx(10.0 / (2.0 * math.sqrt(100.0 / math.pi)), rel=1e-12)
    assert got["level_difference"] == pytest.approx(0.2 / (0.5 + 1e-3), rel=1e-9)
    # The seam's median lies half-way between the two levels: no darker line.
    assert got["seam"] == pytest.approx(0.0, abs=1e-12)
    # The hull runs through the outer pixels' centres: 9 x 19 for the two, 9 x 9 for each.
    # The step between two flat skins is far sharper than either skin.
    assert got["seam_sharpness"] > 10
    assert got["solidity"] == pytest.approx(200 / 171, rel=1e-12)
    assert got["solidity_gain"] == pytest.approx(200 / 171 - 100 / 81, rel=1e-12)
    assert got["least_solidity"] == pytest.approx(100 / 81, rel=1e-12)


def test_a_cut_through_one_textured_skin_is_no_sharper_than_the_skin():
    rng = np.random.default_rng(5)
    labels = np.zeros((60, 80), np.int32)
    labels[10:50, 10:40] = 1
    labels[10:50, 40:70] = 2
    gray = np.full(labels.shape, 0.2)
    skin = labels > 0
    gray[skin] = 0.7 + 0.05 * rng.standard_normal(np.count_nonzero(skin))
    sharpness = join.pair_features(labels, gray)[1][0, join.FEATURES.index("seam_sharpness")]
    assert 0.5 < sharpness < 2.0
    # The same skin, the right half darker by a step: an edge between two rocks.
    gray[labels == 2] -= 0.3
    sharper = join.pair_features(labels, gray)[1][0, join.FEATURES.index("seam_sharpness")]
    assert sharper > 3 * sharpness


def test_regions_apart_make_no_pair():
    labels = np.zeros((30, 40), np.int32)
    labels[5:10, 5:10] = 1
    labels[5:10, 12:17] = 2  # two pixels of ground between them
    pairs, features = join.pair_features(labels, np.zeros(labels.shape))
    assert pairs.shape == (0, 2)
    assert features.shape == (0, len(join.FEATURES))
    assert join.joined(labels, np.zeros(labels.shape)).tolist() == [0, 1, 2]


def _scene() -> tuple[np.ndarray, np.ndarray]:
    """Six disks of one size apart, a seventh cut in two along its diameter,
    and two more that touch each other; all of one level on a darker ground."""
    shape = (200, 260)
    labels = np.zeros(shape, np.int32)
    centres = [(30, 30), (30, 90), (30, 150), (30, 210), (100, 30), (100, 90)]
    for k, centre in enumerate(centres, start=1):
        labels[_disk(shape, centre, 20)] = k
    cut = _disk(shape, (100, 160), 20)
    cols = np.indices(shape)[1]
    labels[cut & (cols < 160)] = 7
    labels[cut & (cols >= 160)] = 8
    labels[_disk(shape, (165, 60), 20)] = 9
    labels[_disk(shape, (165, 99), 20)] = 10  # 39 px apart: the two touch
    gray = np.where(labels > 0, 0.7, 0.3)
    return labels, gray


def test_two_halves_of_one_rock_are_joined_and_two_touching_rocks_are_not():
    labels, gray = _scene()
    pairs, features = join.pair_features(labels, gray)
    assert pairs.tolist() == [[7, 8], [9, 10]]
    halves, touching = join.join_probabilities(features)
    assert halves >= join.JOIN_PROBABILITY > touching
    owner = join.joined(labels, gray)
    assert owner.tolist() == [0, 1, 2, 3, 4, 5, 6, 7, 7, 9, 10]


def test_nothing_is_joined_below_a_probability_of_one():
    labels, gray = _scene()
    assert join.joined(labels, gray, probability=1.0 + 1e-9).tolist() == list(range(11))


@settings(max_examples=40, deadline=None)
@given(
    st.lists(
        st.tuples(st.integers(0, 30), st.integers(0, 30), st.integers(2, 14), st.integers(2, 14)),
        min_size=1,
        max_size=8,
    )
)
def test_each_region_joins_a_touching_group_under_its_smallest_label(boxes):
    labels = np.zeros((44, 44), np.int32)
    for k, (r, c, h, w) in enumerate(boxes, start=1):
        labels[r : r + h, c : c + w] = k
    present = np.unique(labels)
    gray = np.random.default_rng(len(boxes)).uniform(0.0, 1.0, labels.shape)
    owner = join.joined(labels, gray, probability=0.0)
    assert owner[0] == 0
    assert np.all(owner <= np.arange(owner.size))
    assert np.array_equal(owner[owner], owner)
    # At probability 0 every touching pair is joined: what is left apart does not touch.
    merged = owner[labels]
    pairs, _ = join.pair_features(merged, gray)
    assert pairs.shape[0] == 0
    # A label drawn over entirely joins nothing and is joined by nothing.
    for k in set(range(1, owner.size)) - set(present.tolist()):
        assert owner[k] == k and np.count_nonzero(owner == k) == 1


def test_the_join_trees_keep_their_signs():
    # scripts/fit_segment_join.py holds the probability of one rock falling
    # with the pair's size and rising with its contact, whatever the rest.
    from rockscan.core.segment import join_model
    from rockscan.core.segment.trees import trees_of

    trees = trees_of(join_model)
    assert trees.roots.size >= 10 and trees.feature.max() < len(join.FEATURES)
    rng = np.random.default_rng(0)
    low = np.array([0.2, 0.05, 0.0, 0.5, -0.4, 0.5, 0.0, 0.0, -1.0, 0.0])
    high = np.array([4.0, 2.0, 1.0, 1.2, 0.2, 1.2, 2.0, 1.0, 1.0, 5.0])
    x = rng.uniform(low, high, (500, len(join.FEATURES)))
    before = join.join_probabilities(x)
    for name, sign in (("union", -1), ("smaller", -1), ("contact", 1), ("seam_sharpness", -1)):
        moved = x.copy()
        moved[:, join.FEATURES.index(name)] += rng.uniform(0.0, 1.0, len(x))
        assert np.all(sign * (join.join_probabilities(moved) - before) >= -1e-12), name


def _textured_scene(merged: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Six disks apart, and two more that touch, each of its own level with a
    grain; the two touching ones labelled as one region when ``merged``."""
    rng = np.random.default_rng(3)
    shape = (200, 300)
    labels = np.zeros(shape, np.int32)
    gray = np.full(shape, 0.3)
    centres = [(35, 35), (35, 100), (35, 165), (35, 230), (110, 35), (110, 100)]
    for k, centre in enumerate(centres, start=1):
        labels[_disk(shape, centre, 22)] = k
    left, right = _disk(shape, (120, 190), 22), _disk(shape, (120, 232), 22) & ~_disk(shape, (120, 190), 22)
    labels[left] = 7
    labels[right] = 7 if merged else 8
    for k, level in enumerate([0.7, 0.75, 0.68, 0.72, 0.74, 0.69, 0.76, 0.6], start=1):
        gray[labels == k] = level
    gray[right] = 0.6
    gray = gray + np.where(labels > 0, 0.02 * rng.standard_normal(shape), 0.0)
    return labels, gray, right


def test_two_touching_rocks_outlined_as_one_are_cut_apart():
    labels, gray, right = _textured_scene(merged=True)
    cuts = join.parted(labels, gray)
    assert list(cuts) == [7]
    cut = cuts[7]
    iou = np.count_nonzero(cut & right) / np.count_nonzero(cut | right)
    assert iou > 0.9, iou


def test_a_convex_rock_or_a_small_one_is_not_cut():
    labels, gray, _ = _textured_scene(merged=False)
    # Every region is a disk or a disk less a sliver: convex, and none is large.
    assert join.parted(labels, gray) == {}
    # Nothing is cut when the halves must be less likely one rock than nothing.
    merged, gray_merged, _ = _textured_scene(merged=True)
    assert join.parted(merged, gray_merged, probability=0.0) == {}
