"""An outline moved by the offsets the development photos teach (``rockscan.core.segment.offset``).

The rocks are drawn here (``test_segment_snap.drawn``: a disc or a lobed blob
through a Gaussian blur), with their coverage placed a few pixels inside or
outside the true edge, as an outline that missed it; and the trees are
checked against a walk through them one node at a time.
"""

from __future__ import annotations

import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_segment_snap import SHAPE, area, drawn, iou, off_outline

from rockscan.core.segment import offset_model
from rockscan.core.segment.offset import (
    RAYS,
    REACH,
    SAMPLES,
    offset_features,
    offset_moved,
    predicted_offsets,
)
from rockscan.core.segment.shadow import measured_region
from rockscan.core.segment.trees import Trees, tree_sum, trees_of

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
import bench_segment

#: Sensor noise added to a drawn photo (brightness in [0, 1]).
NOISE = 0.01


def inset(truth: np.ndarray, by: float) -> np.ndarray:
    """A coverage ramp a pixel wide whose 0.5 level lies ``by`` pixels inside the truth's edge."""
    rock = (truth >= 0.5).astype(np.uint8)
    inner = cv2.distanceTransform(rock, cv2.DIST_L2, 5)
    outer = cv2.distanceTransform(1 - rock, cv2.DIST_L2, 5)
    signed = np.where(rock > 0, inner - 0.5, 0.5 - outer)
    return np.clip(0.5 + signed - by, 0.0, 1.0).astype(np.float32)


def photo_and_levels(light: np.ndarray, coverage: np.ndarray, seed: int = 0):
    """The log brightness of a drawn photo with sensor noise, and the levels read round ``coverage``."""
    noisy = light + np.random.default_rng(seed).normal(0.0, NOISE, light.shape).astype(np.float32)
    gray = np.log(np.maximum(noisy, 1e-3) + 0.04)
    region = measured_region(gray, coverage >= 0.5, 50)
    assert region is not None
    return gray, region[3]


@pytest.mark.parametrize(("radius", "blur"), [(20.0, 1.5), (25.0, 2.0)])
def test_an_outline_inside_a_darkening_limb_moves_out_towards_the_edge(radius, blur):
    # An outline two and a half pixels inside the edge of a rock whose
    # brightness falls towards its rim, under a blur of a pixel or two: the
    # trees read the profile as an edge still to come.
    light, truth = drawn(radius=radius, limb=0.25, blur=blur)
    before = inset(truth, 2.5)
    gray, levels = photo_and_levels(light, before)
    after = offset_moved(gray, before, levels, 1.0)
    assert after is not None
    assert area(before) < area(after) <= truth.sum()
    assert iou(after >= 0.5, truth >= 0.5) > iou(before >= 0.5, truth >= 0.5) + 0.01


@pytest.mark.parametrize(("radius", "blur", "by"), [(20.0, 2.0, 4.5), (25.0, 2.5, 5.0), (30.0, 3.0, 6.0)])
def test_an_outline_further_off_than_the_reach_moves_again_when_read_again(radius, blur, by):
    # One move is clipped to the reach; read again from where it left the
    # outline, the profile still shows an edge to come, and the outline moves on.
    light, truth = drawn(radius=radius, limb=0.35, blur=blur)
    before = inset(truth, by)
    gray, levels = photo_and_levels(light, before)
    first = offset_moved(gray, before, levels, 1.0)
    assert first is not None
    gray, levels = photo_and_levels(light, first)
    second = offset_moved(gray, first, levels, 1.0)
    assert second is not None
    assert area(before) < area(first) < area(second) <= truth.sum()
    assert iou(second >= 0.5, truth >= 0.5) > iou(first >= 0.5, truth >= 0.5) + 0.01


@pytest.mark.parametrize(
    ("blur", "limb", "line"),
    [
        *((blur, limb, False) for limb in (0.0, 0.35) for blur in (0.7, 1.0, 2.0)),
        (0.7, 0.0, True),
    ],
)
def test_an_outline_on_the_edge_stays_where_it_is(blur, limb, line):
    # With ``line``, a coin's edge: a sharp step, and just outside it a dark
    # line a pixel wide on the ground (the coin's side, its contact shadow),
    # which a domed rock's dark rim, inside its edge, resembles.
    light, truth = drawn(radius=25.0, limb=limb, blur=blur)
    if line:
        rock = (truth >= 0.5).astype(np.uint8)
        beside = (cv2.dilate(rock, np.ones((3, 3), np.uint8)) > 0) & (rock == 0)
        light = np.where(beside, 0.15, light).astype(np.float32)
    before = inset(truth, 0.0)
    gray, levels = photo_and_levels(light, before)
    after = offset_moved(gray, before, levels, 1.0)
    assert after is None or abs(area(after) - area(before)) <= 0.01 * area(before)


def test_the_features_read_the_profile_as_a_share_of_the_step():
    light, truth = drawn(radius=25.0, limb=0.0, blur=1.0)
    before = inset(truth, 0.0)
    gray, levels = photo_and_levels(light, before)
    rays = offset_features(gray, before, levels, 1.0)
    assert rays is not None and rays.features.shape[0] == RAYS
    assert rays.usable.all()
    own = np.median(rays.features[:, : SAMPLES.size], axis=0)
    # Deep inside the rock its level (1), far outside the ground's (0),
    # and half-way at the outline itself.
    assert own[0] == pytest.approx(1.0, abs=0.05)
    assert own[-1] == pytest.approx(0.0, abs=0.05)
    assert own[np.flatnonzero(SAMPLES == 0.0)[0]] == pytest.approx(0.5, abs=0.15)
    # The rock's equivalent radius and its outline's distance on every ray over their median.
    assert rays.features[0, 2 * SAMPLES.size + 1] == pytest.approx(25.0, abs=0.5)
    assert np.median(rays.features[:, -1]) == pytest.approx(1.0)


def test_nothing_to_read_gives_none():
    light, truth = drawn()
    gray, levels = photo_and_levels(light, inset(truth, 0.0))
    assert offset_features(gray, np.zeros(SHAPE, np.float32), levels, 1.0) is None
    assert offset_moved(gray, np.zeros(SHAPE, np.float32), levels, 1.0) is None
    # A rock at its ground's level has no step to read shares of.
    assert offset_features(gray, inset(truth, 0.0), (0.2, 0.2, 0.01), 1.0) is None


@settings(max_examples=40, deadline=None)
@given(
    radius=st.floats(10.0, 40.0),
    lobes=st.integers(0, 6),
    depth=st.floats(0.0, 0.3),
    limb=st.floats(0.0, 0.45),
    blur=st.floats(0.5, 3.0),
    by=st.floats(-3.0, 3.0),
    seed=st.integers(0, 2**16),
)
def test_a_moved_outline_stays_a_coverage_within_reach(radius, lobes, depth, limb, blur, by, seed):
    light, truth = drawn(radius=radius, lobes=lobes, depth=depth, limb=limb, blur=blur, supersample=2)
    before = inset(truth, by)
    if area(before) < 60:
        return
    gray, levels = photo_and_levels(light, before, seed)
    after = offset_moved(gray, before, levels, 1.0)
    if after is None:
        return
    assert after.shape == before.shape and after.dtype == np.float32
    assert after.min() >= 0.0 and after.max() <= 1.0
    # Only the ramp across the outline moves, by at most the reach.
    assert off_outline(before, after) <= REACH + 2.0 + 1.5


def _walk(x: np.ndarray, m: Trees) -> float:
    """The offset of one feature row, tree by tree, node by node."""
    total = m.bias
    for root in m.roots:
        node = int(root)
        while m.feature[node] >= 0:
            k = m.feature[node]
            node = int(m.left[node] if x[k] <= m.threshold[node] else m.right[node])
        total += m.value[node]
    return total


def test_the_offset_trees_are_walked_all_at_once_as_one_by_one():
    m = trees_of(offset_model)
    assert m.roots.size >= 10 and m.depth >= 1
    # Every node is a leaf or points at two nodes of its own tree, deeper down.
    inner = np.flatnonzero(m.feature >= 0)
    assert np.all(m.left[inner] > inner) and np.all(m.right[inner] > inner)
    assert m.feature.max() < 2 * SAMPLES.size + 6
    rng = np.random.default_rng(0)
    x = np.empty((200, 2 * SAMPLES.size + 6))
    for k in range(x.shape[1]):
        cuts = m.threshold[m.feature == k]
        low, high = (cuts.min() - 1.0, cuts.max() + 1.0) if cuts.size else (-1.0, 1.0)
        x[:, k] = rng.uniform(low, high, x.shape[0])
    expected = np.array([_walk(row, m) for row in x])
    np.testing.assert_allclose(predicted_offsets(x), expected, rtol=1e-12, atol=1e-12)


def test_tree_sum_adds_the_bias_and_each_trees_leaf():
    # Two trees: the first splits feature 0 at 0.5 (leaves 1, 2), the second
    # feature 1 at -1 and then feature 0 at 2 (leaves 10, 20, 30).
    trees = Trees(
        bias=0.25,
        depth=2,
        roots=np.array([0, 3]),
        feature=np.array([0, -1, -1, 1, -1, 0, -1, -1]),
        left=np.array([1, 0, 0, 4, 0, 6, 0, 0]),
        right=np.array([2, 0, 0, 5, 0, 7, 0, 0]),
        threshold=np.array([0.5, 0, 0, -1.0, 0, 2.0, 0, 0]),
        value=np.array([0, 1.0, 2.0, 0, 10.0, 0, 20.0, 30.0]),
    )
    x = np.array([[0.5, -1.0], [0.6, -1.0], [0.0, 0.0], [3.0, 5.0]])
    np.testing.assert_array_equal(tree_sum(x, trees), [11.25, 12.25, 21.25, 32.25])


def test_an_easy_photo_keeps_the_outline_the_fast_path_gave(monkeypatch):
    # The fast path's outline stood out above every other region and steps
    # against the ground all round: the step does not run there.
    import rockscan.core.segment as segmentation
    import rockscan.core.segment.finish as finish
    from rockscan.core.render import RenderConfig, render_photo
    from rockscan.io import default_spec_path, read_spec

    spec = next(iter(read_spec(default_spec_path())))
    pixels = render_photo(spec.params, RenderConfig(rows=240, cols=320), rng=3, name=spec.name).pixels
    _, _, easy = segmentation._chosen(pixels, segmentation.SegmentConfig())
    assert easy

    def never(*args, **kwargs):
        raise AssertionError("the offset step ran on the fast path")

    monkeypatch.setattr(finish, "offsets_read", never)
    monkeypatch.setattr(finish, "moved_by", never)
    segmentation.segment(pixels)


def test_a_rock_chosen_among_the_whole_pool_is_read_again_where_its_first_move_left_it(monkeypatch):
    # Development photo "vignette-blur-jpeg" 4046 is decided by the whole
    # pool: a light rock under a wide blur, its outline short of the edge all round.
    import rockscan.core.segment as segmentation
    import rockscan.core.segment.finish as finish

    pixels, _, _ = bench_segment.photo("dev", "vignette-blur-jpeg", 4046)
    found, choice, easy = segmentation._chosen(pixels, segmentation.SegmentConfig())
    assert choice is not None
    calls, move = [], finish._offset_moved

    def recorded(rock, window, read):
        moved = move(rock, window, read)
        calls.append((rock, moved))
        return moved

    monkeypatch.setattr(finish, "_offset_moved", recorded)
    final, _ = finish.completed(found, choice, pixels, easy=easy)
    assert len(calls) == 2
    (_, first), (again, second) = calls
    assert first is not None and again is first
    assert final is (second or first)
    assert area(final.rocks[0].mask) > area(first.rocks[0].mask) > 0
