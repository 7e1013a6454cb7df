"""Pebbles that touch a rock, cut off its outline (``rockscan.core.segment.pebbles``)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rockscan.core.segment.pebbles import lobed, pebbles_off

SHAPE = (200, 240)


def disk(row: float, col: float, radius: float, shape: tuple[int, int] = SHAPE) -> np.ndarray:
    rr, cc = np.mgrid[: shape[0], : shape[1]]
    return np.hypot(rr - row, cc - col) <= radius


def star(arms: int, depth: float, radius: float = 55.0) -> np.ndarray:
    rr, cc = np.mgrid[: SHAPE[0], : SHAPE[1]]
    angle = np.arctan2(rr - 100, cc - 120)
    return np.hypot(rr - 100, cc - 120) <= radius * (1 + depth * np.cos(arms * angle))


def iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / (a | b).sum())


def test_a_pebble_pressed_against_a_rock_is_cut_off_along_its_contact():
    rock = disk(100, 120, 50)
    # Its centre 6 px inside the pebble's own radius from the rock's edge:
    # the contact is nearly as wide as the pebble.
    pebble = disk(100, 120 + 50 + 6, 12)
    kept = pebbles_off(rock | pebble)
    assert not (kept & ~(rock | pebble)).any()
    # The rock keeps its own edge: only the pebble's pixels and a sliver of
    # the rock along the cut (at most a few pixels deep) go.
    assert (rock & ~kept).sum() < 0.01 * rock.sum()
    assert (pebble & ~rock & kept).sum() < 0.1 * (pebble & ~rock).sum()
    assert iou(kept, rock) > 0.98


def test_a_pebble_pressed_broadly_against_a_rock_is_cut_off_at_the_notches_beside_it():
    from rockscan.core.segment.pebbles import CUT_SHARE, _pieces

    rock = disk(100, 120, 50)
    # Sunk 0.3 of its diameter into the rock: what the opening takes off meets
    # the body along a contact too broad for the neck rule alone.
    pebble = disk(100, 120 + 50 + 16 * 0.3, 16)
    joined = rock | pebble
    found = _pieces(joined, CUT_SHARE, by_distance=True)
    assert found is not None and not found.round_necked.any() and found.round_broad.sum() == 1
    assert iou(joined, rock) < 0.94
    assert iou(pebbles_off(joined), rock) > 0.98


@pytest.mark.parametrize(("arm", "angle"), [(10, 90.0), (10, 180.0), (6, 45.0)])
def test_the_wedge_is_the_angle_between_the_outline_two_radii_either_side(arm, angle):
    from rockscan.core.segment.pebbles import _wedge

    # Two straight arms of an outline meeting at the point at index ``arm``.
    t = np.arange(arm + 1)[::-1]
    first = np.column_stack([t, np.zeros_like(t)])
    a = np.radians(angle)
    second = np.column_stack([np.round(t[::-1][1:] * np.cos(a)), np.round(t[::-1][1:] * np.sin(a))])
    outline = np.vstack([first, second]).astype(np.int32)
    assert _wedge(outline, arm, arm / 2) == pytest.approx(angle, abs=1.0)


def test_several_pebbles_on_one_side_are_all_cut_off():
    rock = disk(100, 120, 50)
    joined = rock.copy()
    for angle in (-0.6, 0.0, 0.6):
        joined |= disk(100 + 58 * np.sin(angle), 120 + 58 * np.cos(angle), 11)
    assert iou(pebbles_off(joined), rock) > 0.97
    # Before the cut, the pebbles cost the outline more than that.
    assert iou(joined, rock) < 0.93


@pytest.mark.parametrize(
    "mask",
    [
        disk(100, 120, 50),
        star(5, 0.4),
        star(6, 0.35),
        star(3, 0.3),
        star(4, 0.45),
        star(8, 0.4),
        np.zeros(SHAPE, bool),
    ],
    ids=["disk", "star-5", "star-6", "star-3", "star-4", "star-8", "empty"],
)
def test_a_rock_alone_and_the_arms_of_a_star_are_left_alone(mask):
    assert pebbles_off(mask) is mask


def ellipse(row: float, col: float, half_rows: float, half_cols: float, angle: float = 0.0) -> np.ndarray:
    rr, cc = np.mgrid[: SHAPE[0], : SHAPE[1]]
    u = (rr - row) * np.cos(angle) + (cc - col) * np.sin(angle)
    v = -(rr - row) * np.sin(angle) + (cc - col) * np.cos(angle)
    return (u / half_rows) ** 2 + (v / half_cols) ** 2 <= 1


def ring_of_lobes(angles: list[float]) -> np.ndarray:
    mask = disk(100, 120, 45)
    for a in angles:
        mask |= disk(100 + 54 * np.sin(a), 120 + 54 * np.cos(a), 9)
    return mask


def test_alike_lobes_all_round_are_the_rocks_own_shape():
    lobes = ring_of_lobes([2 * np.pi * k / 8 for k in range(8)])
    assert pebbles_off(lobes) is lobes
    # Three of those lobes on one side are pebbles.
    side = ring_of_lobes([2 * np.pi * k / 8 for k in range(3)])
    assert pebbles_off(side).sum() < side.sum()


def test_pebbles_all_round_a_rock_where_they_happen_to_lie_are_cut_off():
    """Four pebbles whose directions from the rock's centre all but cancel
    (resultant 0.1), at uneven angles (gaps spread by 0.37 of their mean):
    pebbles, not lobes."""
    rock = disk(100, 120, 45)
    scattered = ring_of_lobes([0.0, 0.7, 2.9, 4.3])
    assert iou(scattered, rock) < 0.93
    assert iou(pebbles_off(scattered), rock) > 0.97
    assert not lobed(scattered)


def test_lobes_at_even_angles_count_whatever_their_size():
    """Six lobes at even angles, two of them small (a star's arms on its narrow
    side): the four of the pebbles' size alone lie at uneven angles (gaps of
    60 and 120 degrees), but every lobe counts towards the spacing, and
    nothing is cut."""
    lobes = disk(100, 120, 45)
    for k, radius in enumerate([9, 9, 5, 9, 9, 5]):
        a = 2 * np.pi * k / 6
        lobes |= disk(100 + (45 + radius) * np.sin(a), 120 + (45 + radius) * np.cos(a), radius)
    assert pebbles_off(lobes) is lobes


@settings(max_examples=25, deadline=None)
@given(count=st.integers(3, 12), turn=st.floats(0, 2 * np.pi))
def test_alike_lobes_at_even_angles_are_left_alone_at_any_count_and_turn(count, turn):
    lobes = ring_of_lobes([turn + 2 * np.pi * k / count for k in range(count)])
    assert pebbles_off(lobes) is lobes
    assert lobed(lobes)


def test_stars_and_lobes_all_round_are_lobed():
    for mask in (star(5, 0.4), star(6, 0.35), star(4, 0.45), star(8, 0.4)):
        assert lobed(mask)
    assert lobed(ring_of_lobes([2 * np.pi * k / 8 for k in range(8)]))


@pytest.mark.parametrize(
    "mask",
    [
        disk(100, 120, 50),
        star(5, 0.1),
        disk(100, 120, 50) | disk(100, 176, 12),
        ring_of_lobes([2 * np.pi * k / 8 for k in range(3)]),
        # A rock with its shadow joined: a tail on one side.
        disk(100, 100, 40) | ellipse(100, 150, 25, 45),
        np.zeros(SHAPE, bool),
    ],
    ids=["disk", "shallow-star", "pebble", "lobes-on-one-side", "shadow-tail", "empty"],
)
def test_a_rock_alone_or_with_what_joined_it_on_one_side_is_not_lobed(mask):
    assert not lobed(mask)


@settings(max_examples=40, deadline=None)
@given(a=st.floats(15, 95), b=st.floats(15, 95), angle=st.floats(0, np.pi))
def test_an_ellipse_is_never_lobed(a, b, angle):
    assert not lobed(ellipse(100, 120, a, b, angle))


def test_the_default_librarys_shapes_are_left_alone():
    from skimage.draw import polygon2mask

    from rockscan.core.superformula import shape_radii
    from rockscan.io import default_spec_path, read_spec

    theta = np.linspace(0, 2 * np.pi, 720, endpoint=False)
    for spec in read_spec(default_spec_path()):
        radii = shape_radii(spec.params, 720)
        # 40 and 60: the teardrop's tip, broad at its base between hollow
        # flanks, is the case the notch's angle (WEDGE) keeps.
        for size in (40, 60, 90):
            r = radii / radii.max() * size
            outline = np.column_stack([100 + r * np.sin(theta), 120 + r * np.cos(theta)])
            mask = polygon2mask(SHAPE, outline)
            assert pebbles_off(mask) is mask, (spec.name, size)


def test_the_cut_does_not_depend_on_resolution():
    """Regions larger than the measuring radius are measured scaled down."""
    big = disk(400, 480, 200, (800, 960)) | disk(400, 480 + 200 + 24, 48, (800, 960))
    small = big[::4, ::4]
    assert iou(pebbles_off(big)[::4, ::4], pebbles_off(small)) > 0.98
    assert pebbles_off(big).sum() < 0.97 * big.sum()


@settings(max_examples=40, deadline=None)
@given(
    radius=st.floats(20, 70),
    pebbles=st.lists(
        st.tuples(st.floats(0, 2 * np.pi), st.floats(0.1, 0.35), st.floats(-0.3, 0.3)), min_size=0, max_size=5
    ),
)
def test_the_rock_left_is_one_piece_of_the_region_holding_its_body(radius, pebbles):
    rock = disk(100, 120, radius)
    mask = rock.copy()
    for angle, size, depth in pebbles:
        r = size * radius
        d = radius + r * (1 + depth)
        mask |= disk(100 + d * np.sin(angle), 120 + d * np.cos(angle), r)
    kept = pebbles_off(mask)
    assert not (kept & ~mask).any()
    from scipy import ndimage as ndi

    assert ndi.label(kept)[1] == 1
    # Pebbles are at most a third of the rock's radius: the rock's body stays.
    assert (kept & rock).sum() >= 0.9 * rock.sum()
