"""Touching rocks parted (with the per-label maxima it reads), the segmentation score, and the confident-outline rule.

Drawn photos with exact answers: touching discs (the count is known), an
outline that is right, shrunk, grown or half of the rock (the score must
order them), and the pipeline's rule that an unsupported outline is never
interesting.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from skimage.draw import polygon2mask
from test_segment import coverage, photo_of

import rockscan.core.segment.scene
import rockscan.run.pipeline
from rockscan.core.outline import trace_outline
from rockscan.core.segment import CONFIDENT_SCORE, SegmentConfig, segment
from rockscan.core.segment.score import outline_evidence, outline_score
from rockscan.core.segment.split import (
    pockets,
    rejoined,
    split_colours,
    split_necks,
    split_pockets,
    split_rocks,
    split_seams,
    territories,
)
from rockscan.core.segment.stats import touching_pairs
from rockscan.run.pipeline import classify_image, measure_rocks

# ---------------------------------------------------------------- touching rocks


def chain(shape, centers, radius):
    """Coverage of discs of one radius at the given centres (touching where they are 2 r apart)."""
    return [coverage(shape, c, (radius, radius)) for c in centers]


@pytest.mark.parametrize("n", [2, 3, 5])
def test_touching_discs_are_parted_one_rock_each(n):
    shape = (160, 60 + 40 * n)
    # Centres 1.9 radii apart: each disc overlaps the next a little, no ground between them.
    centers = [(80, 40 + 38 * i) for i in range(n)]
    pixels = photo_of([(c, 0.85) for c in chain(shape, centers, 20)], shape=shape)
    seg, rocks = measure_rocks(pixels, 360, all_rocks=True)
    assert seg.n_rocks == n
    found = sorted(r.outline.centroid_rowcol[1] for r in rocks)
    np.testing.assert_allclose(found, [c[1] for c in centers], atol=1.5)
    for outline in (r.outline for r in rocks):
        # Each is about one disc: the cut takes a sliver of the overlap at most.
        assert outline.area_px == pytest.approx(np.pi * 20**2, rel=0.12)


def test_touching_rocks_of_different_contrast_are_parted():
    shape = (160, 200)
    faint, clear = coverage(shape, (80, 70), (28, 28)), coverage(shape, (80, 125), (28, 28))
    pixels = photo_of([(faint, 0.62), (clear, 0.9)], shape=shape)
    seg = segment(pixels, all_rocks=True)
    assert seg.n_rocks == 2


def test_a_single_elongated_or_textured_rock_stays_whole():
    shape = (200, 300)
    rng = np.random.default_rng(3)
    ellipse = coverage(shape, (100, 150), (30, 95))
    pixels = photo_of([(ellipse, 0.85)], shape=shape).astype(np.float64)
    # Dark relief across the rock, as deep as a gap between two rocks, but short.
    pixels[ellipse > 0.5] -= 90 * (rng.random(int((ellipse > 0.5).sum())) < 0.08)
    seg = segment(np.clip(pixels, 0, 255).astype(np.uint8), all_rocks=True)
    assert seg.n_rocks == 1


def test_split_necks_cuts_a_dumbbell_and_not_a_disc():
    yy, xx = np.mgrid[:80, :140]
    left = (yy - 40) ** 2 + (xx - 40) ** 2 <= 25**2
    right = (yy - 40) ** 2 + (xx - 100) ** 2 <= 25**2
    bar = (abs(yy - 40) <= 4) & (xx > 40) & (xx < 100)
    parts = split_necks(left | right | bar, 50)
    assert len(parts) == 2
    assert sorted(int(p.sum()) for p in parts) == pytest.approx([left.sum() + 150] * 2, rel=0.15)
    assert len(split_necks(left, 50)) == 1


def test_split_rocks_parts_two_humps_of_contrast_across_a_dip():
    yy, xx = np.mgrid[:60, :120]
    signed = (
        10 * np.exp(-((yy - 30) ** 2 + (xx - 35) ** 2) / 300.0)
        + 6 * np.exp(-((yy - 30) ** 2 + (xx - 85) ** 2) / 300.0)
    ).astype(np.float32)
    region = signed > 0.5
    parts = split_rocks(signed, region, 50, 0.5)
    assert len(parts) == 2
    assert np.array_equal(np.logical_or.reduce(parts), region)
    # One hump, however textured, is one rock.
    single = (10 * np.exp(-((yy - 30) ** 2 + (xx - 60) ** 2) / 500.0)).astype(np.float32)
    assert len(split_rocks(single, single > 0.5, 50, 0.5)) == 1


def test_two_pieces_of_one_disc_are_rejoined_and_two_touching_discs_are_not():
    yy, xx = np.mgrid[:80, :160]
    disc = (yy - 40) ** 2 + (xx - 40) ** 2 <= 30**2
    # A disc cut along a shading line, beside a disc that touches it.
    top, bottom = disc & (yy < 35), disc & (yy >= 35)
    other = ((yy - 40) ** 2 + (xx - 100) ** 2 <= 30**2) & ~disc
    parts = rejoined([top, other, bottom])
    assert len(parts) == 2
    assert np.array_equal(parts[0], disc) and np.array_equal(parts[1], other)
    # Apart, the pieces of the disc stay apart: only touching parts are joined.
    gap = disc & (yy < 30)
    assert len(rejoined([gap, bottom])) == 2


def test_a_thin_piece_between_its_rock_and_a_neighbour_is_rejoined_to_its_rock():
    # Labels in list order: a strip a pixel thick (1) lies along the whole of the
    # neighbour (3) above it and along the rest of its square (2) below. A
    # maximum filter over the labels saw only each strip pixel's higher
    # neighbour, 3, and the strip was never joined to the rest of its square.
    yy, xx = np.mgrid[:100, :80]
    square = (yy >= 40) & (yy < 80) & (xx >= 20) & (xx <= 60)
    strip, rest = square & (yy == 40), square & (yy > 40)
    neighbour = (yy >= 20) & (yy < 40) & ~((yy < 31) & (xx >= 35) & (xx <= 45))
    parts = rejoined([strip, rest, neighbour])
    assert len(parts) == 2
    assert np.array_equal(parts[0], square) and np.array_equal(parts[1], neighbour)


def test_touching_pairs_are_every_pair_of_8_neighbours_once():
    labels = np.zeros((6, 5), np.int32)
    labels[1, :], labels[2, :], labels[3:5, :] = 3, 1, 2
    labels[5, 4] = 4  # touches 2 across a corner only
    assert touching_pairs(labels).tolist() == [[1, 2], [1, 3], [2, 4]]


@settings(max_examples=40, deadline=None)
@given(st.lists(st.integers(0, 4), min_size=30, max_size=30))
def test_touching_pairs_agree_with_a_walk_over_every_pixel(values):
    labels = np.array(values).reshape(5, 6)
    expected = set()
    for r in range(5):
        for c in range(6):
            for dr in (-1, 0, 1):
                for dc in (-1, 0, 1):
                    rr, cc = r + dr, c + dc
                    if 0 <= rr < 5 and 0 <= cc < 6:
                        a, b = labels[r, c], labels[rr, cc]
                        if a > 0 and b > 0 and a != b:
                            expected.add((min(a, b), max(a, b)))
    assert [tuple(p) for p in touching_pairs(labels).tolist()] == sorted(expected)


@settings(max_examples=30, deadline=None)
@given(
    st.lists(st.tuples(st.integers(0, 50), st.integers(0, 50), st.integers(3, 12)), min_size=1, max_size=6)
)
def test_rejoined_parts_cover_the_same_pixels_once(discs):
    yy, xx = np.mgrid[:64, :64]
    taken = np.zeros((64, 64), bool)
    parts = []
    for r, c, radius in discs:
        part = ((yy - r) ** 2 + (xx - c) ** 2 <= radius**2) & ~taken
        if part.any():
            parts.append(part)
            taken |= part
    out = rejoined(parts)
    assert 1 <= len(out) <= len(parts)
    assert np.array_equal(np.sum(out, axis=0), taken.astype(int))


def test_territories_give_every_pixel_to_the_nearest_region():
    a, b = np.zeros((5, 9), bool), np.zeros((5, 9), bool)
    a[2, 1], b[2, 7] = True, True
    owners = territories([a, b])
    assert (owners[:, :4] == 1).all() and (owners[:, 5:] == 2).all()


# ---------------------------------------------------------------- the segmentation score


def disc_level(shape=(120, 120), radius=30.0, noise=0.05, seed=0):
    rng = np.random.default_rng(seed)
    cover = coverage(shape, (60, 60), (radius, radius))
    return (cover + rng.normal(0.0, noise, shape)).astype(np.float32), cover > 0.5


def test_the_score_prefers_the_right_outline_to_a_shrunk_grown_or_half_one():
    level, truth = disc_level()
    yy, xx = np.mgrid[: truth.shape[0], : truth.shape[1]]
    shrunk = (yy - 60) ** 2 + (xx - 60) ** 2 <= 20**2
    grown = (yy - 60) ** 2 + (xx - 60) ** 2 <= 42**2
    half = truth & (xx < 60)
    sides = (False, False, False, False)
    right = outline_score(outline_evidence(level, truth, sides))
    assert right > 0.9
    for wrong in (shrunk, grown, half):
        assert outline_score(outline_evidence(level, wrong, sides)) < CONFIDENT_SCORE < right


def test_dark_beside_an_outline_is_measured_apart_from_its_score():
    level, truth = disc_level()
    yy, xx = np.mgrid[: truth.shape[0], : truth.shape[1]]
    distance = np.hypot(yy - 60, xx - 60)
    # A shaded rim darker than the ground, hugging the right half of the disc.
    shaded = level.copy()
    shaded[(distance > 30.5) & (distance <= 42) & (xx > 60)] -= 0.6
    sides = (False,) * 4
    plain, rimmed = outline_evidence(level, truth, sides), outline_evidence(shaded, truth, sides)
    assert plain.darker_outside < 0.01
    # The band beside the outline is half in the rim (both band edges are pixel-exact to a pixel or so).
    assert rimmed.darker_outside == pytest.approx(0.5, abs=0.08)
    # Not scored: the step across the outline and the level outside it, clipped at the
    # ground's, hardly move (the ground's spread does: the rim lies in its ring).
    assert len(rimmed.as_array()) == 6
    np.testing.assert_allclose(rimmed.as_array()[:3], plain.as_array()[:3], atol=0.01)


def test_a_noisy_inside_spreads_the_inside_apart_from_the_score():
    level, truth = disc_level(noise=0.05)
    yy, xx = np.mgrid[: truth.shape[0], : truth.shape[1]]
    # A rock seen in a channel that noise dominates on it (a dark rock's
    # chromaticity), away from its outline: its inside spreads 0.3 of the step.
    noisy = level.copy()
    deep = np.hypot(yy - 60, xx - 60) < 25.5
    noisy[deep] += np.random.default_rng(1).normal(0.0, 0.3, int(deep.sum())).astype(np.float32)
    sides = (False,) * 4
    even, spread = outline_evidence(level, truth, sides), outline_evidence(noisy, truth, sides)
    # Robust spreads of normal samples of sigma 0.05 and about 0.3, in units of the unit step.
    assert even.inner_spread == pytest.approx(0.05, abs=0.01)
    assert spread.inner_spread == pytest.approx(0.3, abs=0.06)
    # Not scored: the evidence along the outline is the same.
    np.testing.assert_allclose(spread.as_array()[:5], even.as_array()[:5], atol=1e-6)


def test_an_outline_along_the_frame_scores_lower_than_inside_it():
    level, truth = disc_level()
    inside = outline_score(outline_evidence(level, truth, (False,) * 4))
    cut = level[:, 45:]  # the disc cut by the frame on the left
    along = outline_score(outline_evidence(cut, truth[:, 45:], (False, False, True, False)))
    assert along < inside


def test_every_rock_gets_a_score_in_0_1_and_a_clear_one_scores_high():
    shape = (200, 300)
    pixels = photo_of([(coverage(shape, (100, 150), (40, 55)), 0.85)], shape=shape)
    seg = segment(pixels)
    assert 0.9 < seg.rocks[0].score <= 1.0
    assert len(seg.rocks[0].evidence) == 6


# ---------------------------------------------------------------- confident outlines only


def test_a_rock_below_the_confident_score_is_never_interesting(monkeypatch, default_lib):
    shape = (200, 300)
    pixels = photo_of([(coverage(shape, (100, 150), (45, 45)), 0.85)], shape=shape)
    rock = classify_image(pixels, default_lib)[0]
    assert rock.match.interesting and rock.match.match == "circle"
    assert rock.segmentation_score == segment(pixels).rocks[0].score
    # The same rock, judged against a bar its outline cannot reach.
    monkeypatch.setattr(rockscan.run.pipeline, "CONFIDENT_SCORE", 1.01)
    rock = classify_image(pixels, default_lib)[0]
    assert not rock.match.interesting and rock.match.match is None
    assert rock.match.nearest == "circle"


# ---------------------------------------------------------------- blobs of an outlined rock


def _blob_grid():
    return np.mgrid[:200, :260]


def test_an_outline_of_two_touching_disks_is_cut_into_the_two():
    from rockscan.core.segment.split import split_blobs

    rr, cc = _blob_grid()
    left = (rr - 100) ** 2 + (cc - 90) ** 2 <= 40**2
    right = (rr - 100) ** 2 + (cc - 165) ** 2 <= 38**2
    parts = split_blobs(left | right)
    assert len(parts) == 2
    # Each part is one disk, up to the pixels along the cut.
    for part, disk in zip(sorted(parts, key=lambda p: np.nonzero(p)[1].mean()), (left, right), strict=True):
        assert (part & disk).sum() / (part | disk).sum() > 0.95


def test_a_small_round_rock_beside_two_large_ones_is_a_rock_of_its_own():
    # Two disks of radius 45 and a disk of radius 13 pressed against them:
    # the small one is 4% of the outline, under the tenth a blob needs, but round.
    from rockscan.core.segment.split import BLOB_MIN_SHARE, split_blobs

    rr, cc = _blob_grid()
    large = [(rr - 100) ** 2 + (cc - c) ** 2 <= 45**2 for c in (75, 160)]
    small = (rr - 45) ** 2 + (cc - 117) ** 2 <= 13**2
    outline = large[0] | large[1] | small
    assert small.sum() < BLOB_MIN_SHARE * outline.sum()
    parts = split_blobs(outline)
    assert len(parts) == 3
    assert max((p & small).sum() / (p | small).sum() for p in parts) > 0.85
    # A thin lip of the same area is no rock: it stays with the disk it is on.
    lip = (np.abs(rr - 53) <= 2) & (np.abs(cc - 75) <= 35)
    assert len(split_blobs(large[0] | large[1] | lip)) == 2


@pytest.mark.parametrize(("arms", "amplitude"), [(5, 0.4), (6, 0.35), (3, 0.3), (4, 0.45), (8, 0.4)])
def test_a_star_and_a_disk_stay_whole(arms, amplitude):
    from rockscan.core.segment.split import split_blobs

    rr, cc = _blob_grid()
    angle = np.arctan2(rr - 100, cc - 130)
    star = np.hypot(rr - 100, cc - 130) <= 55 * (1 + amplitude * np.cos(arms * angle))
    assert len(split_blobs(star)) == 1
    assert len(split_blobs(np.hypot(rr - 100, cc - 130) <= 50)) == 1


def test_the_default_librarys_shapes_stay_whole():
    """No shape of the default library is cut into blobs, whatever its lobes."""
    from skimage.draw import polygon2mask

    from rockscan.core.segment.split import split_blobs
    from rockscan.core.superformula import shape_radii
    from rockscan.io import default_spec_path, read_spec

    theta = np.linspace(0, 2 * np.pi, 720, endpoint=False)
    for spec in read_spec(default_spec_path()):
        radii = shape_radii(spec.params, 720)
        radii = radii / radii.max() * 90
        outline = np.column_stack([100 + radii * np.sin(theta), 100 + radii * np.cos(theta)])
        assert len(split_blobs(polygon2mask((200, 200), outline))) == 1, spec.name


def test_a_deeply_lobed_star_is_cut_at_its_lobes_in_the_last_look():
    """The documented price of cutting at wider necks (BLOB_NECK_SHARE)."""
    from rockscan.core.segment.split import BLOB_NECK_SHARE, NECK_SHARE, split_blobs, split_necks

    rr, cc = _blob_grid()
    angle = np.arctan2(rr - 100, cc - 130)
    star = np.hypot(rr - 100, cc - 130) <= 55 * (1 + 0.6 * np.cos(4 * angle))
    assert BLOB_NECK_SHARE > NECK_SHARE
    assert len(split_necks(star, 0.1 * star.sum())) == 1
    assert len(split_blobs(star)) > 1


# ---------------------------------------------------------------- statistics


@settings(max_examples=60, deadline=None)
@given(
    count=st.integers(1, 9),
    shape=st.tuples(st.integers(0, 12), st.integers(1, 12)),
    seed=st.integers(0, 2**16),
)
def test_label_maxima_is_the_largest_value_under_each_label_and_at_least_zero(count, shape, seed):
    from rockscan.core.segment.stats import label_maxima

    rng = np.random.default_rng(seed)
    labels = rng.integers(0, count, shape)
    values = rng.normal(size=shape).astype(np.float32)
    got = label_maxima(values, labels, count)
    for k in range(count):
        under = values[labels == k]
        assert got[k] == max(0.0, float(under.max()) if under.size else 0.0)


@settings(max_examples=60, deadline=None)
@given(
    shape=st.tuples(st.integers(1, 15), st.integers(1, 15)),
    share=st.floats(0.0, 0.3),
    seed=st.integers(0, 2**16),
)
def test_bounding_box_holds_every_pixel_of_the_mask_and_no_more(shape, share, seed):
    from rockscan.core.segment.stats import bounding_box

    mask = np.random.default_rng(seed).random(shape) < share
    box = bounding_box(mask)
    if not mask.any():
        assert box is None
        return
    ys, xs = np.nonzero(mask)
    assert box == (ys.min(), ys.max() + 1, xs.min(), xs.max() + 1)


def test_solidity_of_a_square_an_l_a_disc_and_nothing():
    from skimage.draw import disk

    from rockscan.core.segment.stats import solidity

    square = np.zeros((40, 40), bool)
    square[5:25, 5:25] = True
    # The hull runs through the outer pixels' centres: 400 pixels over a 19 x 19 hull.
    assert solidity(square) == pytest.approx(400 / 361)
    # An L of three 10 x 10 blocks: 300 pixels; its hull cuts across the
    # missing block from the upright's top right pixel centre to the foot's
    # (a 19 x 19 hull less a triangle of legs 10).
    ell = np.zeros((40, 40), np.uint8)
    ell[5:25, 5:15] = 1
    ell[15:25, 15:25] = 1
    assert solidity(ell) == pytest.approx(300 / (361 - 50))
    disc = np.zeros((200, 200), bool)
    disc[disk((100, 100), 80)] = True
    assert 0.99 < solidity(disc) < 1.02
    assert solidity(np.zeros((10, 10), bool)) == 0.0


def test_notch_is_one_gap_of_the_hull_beyond_the_next():
    from skimage.draw import disk

    from rockscan.core.segment.stats import notch

    # A square with a 6 x 6 bite out of one side's middle: the bite is the
    # one gap of the hull (19 x 19 through the outer pixels' centres, the
    # filled hull 20 x 20 pixels).
    bitten = np.zeros((40, 40), bool)
    bitten[5:25, 5:25] = True
    bitten[5:11, 12:18] = False
    assert notch(bitten) == pytest.approx(36 / 400)
    # Two alike bites on opposite sides: neither dominates.
    twice = bitten.copy()
    twice[19:25, 12:18] = False
    assert notch(twice) == 0.0
    # A solid disc, a regular star and nothing: no notch to speak of.
    disc = np.zeros((200, 200), bool)
    disc[disk((100, 100), 80)] = True
    assert notch(disc) < 0.01
    turns = np.linspace(0.0, 2.0 * np.pi, 721)
    radius = 60.0 * (1.0 + 0.4 * np.cos(5.0 * turns))
    star = polygon2mask(
        (200, 200), np.column_stack([100 + radius * np.sin(turns), 100 + radius * np.cos(turns)])
    )
    assert notch(star) < 0.01
    assert notch(np.zeros((10, 10), bool)) == 0.0


@settings(max_examples=60, deadline=None)
@given(
    shape=st.tuples(st.integers(1, 30), st.integers(1, 30)),
    share=st.floats(0.0, 0.9),
    seed=st.integers(0, 2**16),
    pad=st.integers(1, 5),
)
def test_notch_and_solidity_are_shares_and_ignore_where_the_mask_lies(shape, share, seed, pad):
    from rockscan.core.segment.stats import notch, solidity

    mask = np.random.default_rng(seed).random(shape) < share
    assert 0.0 <= notch(mask) < 1.0
    assert solidity(mask) >= 0.0
    # Moved within a larger frame, the same pixels have the same hull and gaps.
    assert notch(np.pad(mask, pad)) == notch(mask)
    assert solidity(np.pad(mask, pad)) == solidity(mask)


def _disc_on_ramp(ground_left: float, ground_right: float, rock: float = 0.5):
    """A disc of one level on a ground ramping from left to right, its core and the ring round it."""
    from rockscan.core.segment.trace import _core_and_ring

    shape = (120, 120)
    cover = coverage(shape, (60, 60), (30, 30))
    ramp = np.linspace(ground_left, ground_right, shape[1], dtype=np.float32)[None, :].repeat(shape[0], 0)
    noise = np.random.default_rng(0).normal(0.0, 0.01, shape)
    flat = (ramp * (1 - cover) + rock * cover + noise).astype(np.float32)
    mask = cover > 0.5
    inside, ring = _core_and_ring(mask.astype(np.uint8), 30.0)
    return flat, mask, inside, ring


def test_a_ground_lighter_on_one_side_and_darker_on_the_other_keeps_the_step():
    from rockscan.core.segment.trace import _two_sided_ground, _two_sided_level

    flat, mask, inside, ring = _disc_on_ramp(0.1, 0.9)
    rock = float(np.median(flat[inside]))
    ground = _two_sided_ground(flat, ring, mask, rock)
    assert ground is not None
    level = _two_sided_level(flat, ground, rock)
    sides = (False,) * 4
    # One median of the ring lies at the rock's level: the step is lost.
    one = float(np.median(flat[ring]))
    single = outline_evidence(((flat - one) / (rock - one)).astype(np.float32), mask, sides)
    two = outline_evidence(level, mask, sides)
    assert np.median(level[inside]) == pytest.approx(1.0, abs=0.05)
    assert two.support > 0.7 > single.support
    assert outline_score(two) > CONFIDENT_SCORE > outline_score(single)


@pytest.mark.parametrize(("left", "right"), [(0.1, 0.3), (0.2, 0.2), (0.7, 0.95)])
def test_a_ground_on_one_side_of_the_rock_is_read_as_one_level(left, right):
    from rockscan.core.segment.trace import _two_sided_ground

    flat, mask, inside, ring = _disc_on_ramp(left, right)
    assert _two_sided_ground(flat, ring, mask, float(np.median(flat[inside]))) is None


def test_all_rocks_finds_a_rock_of_another_hue_beside_a_lighter_one():
    # A gray ground, a rock lighter than it, and a rock of the ground's own
    # luminance that differs from it in hue only: brightness sees one rock,
    # the chromaticity the other.
    shape = (200, 320)
    light = coverage(shape, (100, 90), (38, 44))
    hued = coverage(shape, (100, 230), (40, 36))
    ground = np.array([0.45, 0.45, 0.45])
    red = np.array([0.62, 0.38, 0.45])
    # The same luminance as the ground (BT.601 weights).
    red *= float(ground @ [0.299, 0.587, 0.114]) / float(red @ [0.299, 0.587, 0.114])
    rng = np.random.default_rng(5)
    image = np.broadcast_to(ground, (*shape, 3)).copy()
    image = image * (1 - light[..., None]) + 0.8 * light[..., None]
    image = image * (1 - hued[..., None]) + red * hued[..., None]
    image += rng.normal(0.0, 0.01, image.shape)
    pixels = np.clip(np.round(image * 255), 0, 255).astype(np.uint8)

    seg = segment(pixels, all_rocks=True)
    assert seg.n_rocks == 2
    for truth in (light > 0.5, hued > 0.5):
        assert _best_iou(seg, truth) > 0.85


def _best_iou(seg, truth):
    """IoU of a true rock with the found rock that holds most of it, the
    labels at working size read as photo pixels (nearest label)."""
    shape = truth.shape
    rows = np.minimum((np.arange(shape[0]) / seg.scale_rowcol[0]).astype(int), seg.labels.shape[0] - 1)
    cols = np.minimum((np.arange(shape[1]) / seg.scale_rowcol[1]).astype(int), seg.labels.shape[1] - 1)
    labels = seg.labels[rows[:, None], cols[None, :]]
    found = np.bincount(labels[truth], minlength=seg.n_rocks + 1)[1:].argmax() + 1
    return ((labels == found) & truth).sum() / ((labels == found) | truth).sum()


@pytest.mark.parametrize("polarity", ["auto", "dark", "light"])
def test_all_rocks_finds_rocks_of_hues_on_both_sides_of_the_grounds(polarity):
    # Rocks of the ground's own luminance, one redder and one bluer than a gray
    # ground, and a third greener: along the principal direction of the
    # chromaticity the first two lie on opposite sides of the ground, and one
    # polarity of that projection sees only one of them; the distance from
    # the ground's hue sees all three.
    shape = (200, 360)
    centres = ((70, 70), (70, 290), (140, 180))
    rocks = [coverage(shape, centre, (34, 30)) for centre in centres]
    ground = np.array([0.45, 0.45, 0.45])
    luma = np.array([0.299, 0.587, 0.114])
    rng = np.random.default_rng(7)
    image = np.broadcast_to(ground, (*shape, 3)).copy()
    for rock, hue in zip(rocks, ([0.62, 0.38, 0.45], [0.36, 0.44, 0.66], [0.40, 0.52, 0.40]), strict=True):
        colour = np.array(hue) * float(ground @ luma) / float(np.array(hue) @ luma)
        image = image * (1 - rock[..., None]) + colour * rock[..., None]
    image += rng.normal(0.0, 0.01, image.shape)
    pixels = np.clip(np.round(image * 255), 0, 255).astype(np.uint8)

    # The rocks are of the ground's brightness: a polarity set for brightness
    # does not keep them from standing out in hue.
    seg = segment(pixels, SegmentConfig(polarity=polarity), all_rocks=True)
    assert seg.n_rocks == 3
    for rock in rocks:
        assert _best_iou(seg, rock > 0.5) > 0.85


def test_with_all_a_light_rock_is_outlined_nearer_its_grounds_level(monkeypatch):
    # A light disc of radius 40 whose brightness rises linearly from the
    # ground's 0.4 at its left edge to the rock's 0.8 at its centre (the side
    # turned from the light). An outline at a share t of the way from the
    # ground's level to the rock's cuts the disc 40 t px in from that edge,
    # leaving out a circular segment: IoU 0.882 at LIGHT_EDGE (0.35), 0.804
    # half-way.
    shape = (160, 200)
    cols = np.arange(shape[1])[None, :]
    centre, radius = (80.0, 100.0), 40.0
    disc = coverage(shape, centre, (radius, radius))
    along = np.clip((cols - (centre[1] - radius)) / radius, 0.0, 1.0)
    image = 0.4 * (1 - disc) + (0.4 + 0.4 * along) * disc
    image = image + np.random.default_rng(2).normal(0.0, 0.005, shape)
    pixels = np.clip(np.round(image * 255), 0, 255).astype(np.uint8)
    truth = disc > 0.5

    def segment_iou(share):
        h = share * radius
        lost = radius**2 * np.arccos((radius - h) / radius) - (radius - h) * np.sqrt(2 * radius * h - h * h)
        return 1.0 - lost / (np.pi * radius**2)

    nearer = _best_iou(segment(pixels, all_rocks=True), truth)
    assert nearer == pytest.approx(segment_iou(rockscan.core.segment.scene.LIGHT_EDGE), abs=0.03)
    monkeypatch.setattr(rockscan.core.segment.scene, "LIGHT_EDGE", 0.5)
    half_way = _best_iou(segment(pixels, all_rocks=True), truth)
    assert half_way == pytest.approx(segment_iou(0.5), abs=0.03)
    assert half_way < nearer - 0.04


def _two_discs(shape, centers, radius):
    yy, xx = np.mgrid[: shape[0], : shape[1]]
    return [(yy - r) ** 2 + (xx - c) ** 2 <= radius**2 for r, c in centers]


def _painted(shape, masks, colours, ground=(0.45, 0.45, 0.45), texture=0.0, seed=0):
    """An RGB photo in [0, 1]: each mask in its colour, its brightness varied by ``texture``."""
    rng = np.random.default_rng(seed)
    rgb = np.broadcast_to(np.array(ground, np.float32), (*shape, 3)).copy()
    for mask, colour in zip(masks, colours, strict=True):
        rgb[mask] = colour
    shade = 1.0 + texture * rng.normal(0.0, 1.0, shape)
    return np.clip(rgb * shade[..., None].astype(np.float32) + rng.normal(0.0, 0.01, rgb.shape), 0, 1).astype(
        np.float32
    )


def test_split_colours_cuts_two_touching_rocks_of_different_hue_along_their_contact():
    shape = (120, 200)
    left, right = _two_discs(shape, [(60, 70), (60, 130)], 36)
    pixels = _painted(shape, [left, right], [(0.7, 0.45, 0.35), (0.4, 0.5, 0.7)], texture=0.1)
    parts = split_colours(left | right, pixels)
    assert len(parts) == 2
    for part in parts:
        truth = left if part[60, 50] else right
        assert (part & truth).sum() / (part | truth).sum() > 0.9


def test_split_colours_keeps_one_colour_a_convex_two_coloured_rock_and_a_gray_photo_whole():
    shape = (120, 200)
    left, right = _two_discs(shape, [(60, 70), (60, 130)], 36)
    both = left | right
    textured = _painted(shape, [both], [(0.7, 0.45, 0.35)], texture=0.25)
    assert len(split_colours(both, textured)) == 1
    # A disc half red, half blue: convex, so one rock whatever its colours.
    (disc,) = _two_discs(shape, [(60, 100)], 50)
    half = disc & (np.arange(shape[1])[None, :] < 100)
    two_toned = _painted(shape, [disc, half], [(0.4, 0.5, 0.7), (0.7, 0.45, 0.35)])
    assert len(split_colours(disc, two_toned)) == 1
    gray = _painted(shape, [left, right], [(0.7, 0.7, 0.7), (0.3, 0.3, 0.3)])
    assert len(split_colours(both, gray)) == 1


def test_all_rocks_parts_touching_rocks_of_different_hue():
    shape = (160, 240)
    left, right = _two_discs(shape, [(80, 85), (80, 150)], 40)
    pixels = _painted(shape, [left, right], [(0.75, 0.5, 0.4), (0.45, 0.6, 0.8)], ground=(0.3, 0.3, 0.3))
    seg = segment(np.round(pixels * 255).astype(np.uint8), all_rocks=True)
    assert seg.n_rocks == 2


@pytest.mark.parametrize("shade", [0.3, 0.45])
def test_all_rocks_keeps_a_coloured_rocks_shaded_side(shade):
    # A pink rock lit from the left on a gray ground: across it, its
    # brightness falls to ``shade`` of the lit side's, below the ground's,
    # while its hue stays. Halfway in brightness alone leaves the shaded side
    # out (IoU 0.87 and 0.74 with hue as colour differences, which shade
    # darkens with the brightness).
    shape, centre, radius = (200, 260), (100, 130), 55
    cover = coverage(shape, centre, (radius, radius))
    across = (np.arange(shape[1]) - (centre[1] - radius)) / (2 * radius)
    light = np.clip(1.0 - (1.0 - shade) * across, shade, 1.0)[None, :, None]
    image = 0.5 * (1 - cover[..., None]) + np.array([0.85, 0.5, 0.62]) * light * cover[..., None]
    image += np.random.default_rng(0).normal(0.0, 0.01, image.shape)
    pixels = np.clip(np.round(image * 255), 0, 255).astype(np.uint8)

    seg = segment(pixels, all_rocks=True)
    assert seg.n_rocks == 1
    rock = seg.rocks[0]
    outline = trace_outline(rock.coverage, scale=seg.scale_rowcol, origin_rowcol=rock.origin_rowcol)
    found = polygon2mask(shape, outline.contour_rowcol)
    truth = cover >= 0.5
    assert (found & truth).sum() / (found | truth).sum() > 0.88


# ---------------------------------------------------------------- seams between touching rocks


def _domes(shape, centers, radius):
    """Masks and heights of overlapping hemispheres, each laid over the ones before:
    where two meet, the upper one's rim, facing away from the camera, shows."""
    yy, xx = np.mgrid[: shape[0], : shape[1]]
    height = np.zeros(shape)
    owner = np.full(shape, -1)
    for i, (r, c) in enumerate(centers):
        inside = (yy - r) ** 2 + (xx - c) ** 2 < radius**2
        height[inside] = np.sqrt(1.0 - ((yy[inside] - r) ** 2 + (xx[inside] - c) ** 2) / radius**2)
        owner[inside] = i
    return [owner == i for i in range(len(centers))], height


def _dome_photo(shape, height, rock, ground, noise=0.01, seed=0):
    """Gray photo in [0, 1]: domed rocks of level ``rock`` darkening towards their rims, on ``ground``."""
    rng = np.random.default_rng(seed)
    inside = height > 0
    image = np.where(inside, rock * (0.55 + 0.45 * height), ground)
    return np.clip(image + rng.normal(0.0, noise, shape), 0.0, 1.0).astype(np.float32)


@pytest.mark.parametrize(("rock", "ground"), [(0.3, 0.6), (0.8, 0.3)])
def test_split_seams_cuts_touching_domes_along_the_line_they_meet(rock, ground):
    # Centres 1.75 radii apart, the second laid over the first: a notch at each
    # end of the contact (solidity 0.94), the contact a radius long.
    shape = (120, 200)
    masks, height = _domes(shape, [(60, 65), (60, 135)], 40)
    whole = height > 0
    parts = split_seams(whole, _dome_photo(shape, height, rock, ground))
    assert len(parts) == 2
    assert np.array_equal(np.logical_or.reduce(parts), whole)
    for part in parts:
        truth = masks[0] if part[60, 50] else masks[1]
        assert (part & truth).sum() / (part | truth).sum() > 0.95


def test_split_seams_keeps_a_rock_whole_when_a_dark_line_crosses_it_only_part_way():
    # A bean (a disc less a bite: solidity 0.91) with a dark crack half-way
    # across it: texture dents a rock's brightness, but not from one edge to
    # the other. The same crack from edge to edge is a seam.
    shape = (140, 140)
    yy, xx = np.mgrid[: shape[0], : shape[1]]
    (disc,), height = _domes(shape, [(70, 70)], 55)
    bean = disc & ~((yy - 70) ** 2 + (xx - 130) ** 2 <= 35**2)
    line = np.abs(yy - 70) <= 1
    for crack, parts in ((line & (xx < 75), 1), (line, 2)):
        image = _dome_photo(shape, np.where(bean, height, 0.0), 0.3, 0.6)
        image[crack & bean] = 0.12
        assert len(split_seams(bean, image)) == parts


@pytest.mark.parametrize("seed", range(5))
def test_split_seams_keeps_an_even_speckled_rock_and_a_convex_outline_whole(seed):
    # The outline of two touching rocks (solidity 0.94), but one rock of even
    # brightness with strong speckle: its darkest and brightest pixels are
    # noise apart, no seam (before SEAM_DEPTH, seeds 2 and 4 were cut).
    shape = (120, 200)
    _, height = _domes(shape, [(60, 65), (60, 135)], 40)
    whole = height > 0
    rng = np.random.default_rng(seed)
    speckled = np.where(whole, 0.6 + 0.08 * rng.normal(size=shape), 0.3).astype(np.float32)
    assert len(split_seams(whole, speckled)) == 1
    (disc,), dome = _domes(shape, [(60, 100)], 50)
    assert len(split_seams(disc, _dome_photo(shape, dome, 0.3, 0.6))) == 1


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**16), st.floats(1.2, 1.9))
def test_split_seams_parts_cover_the_outline_once(seed, apart):
    shape = (100, 160)
    _, height = _domes(shape, [(50, 60), (50, 60 + 30 * apart)], 30)
    whole = height > 0
    image = _dome_photo(shape, height, 0.35, 0.6, noise=0.04, seed=seed)
    parts = split_seams(whole, image)
    total = np.sum([p.astype(int) for p in parts], axis=0)
    assert np.array_equal(total, whole.astype(int))


def test_all_rocks_takes_the_polarity_of_the_rocks_that_together_stand_out_most(monkeypatch):
    # Twelve light rocks and one large dark blob (a hole, an eye in a cat's
    # fur: development crowded scene 194) on a mid-gray ground. The blob alone
    # outscores any one light rock, and --all found it alone, as "the" rock.
    shape = (240, 400)
    light = [coverage(shape, (50 + 70 * (k // 5), 40 + 70 * (k % 5)), (18, 18)) for k in range(12)]
    dark = coverage(shape, (190, 330), (38, 38))
    pixels = photo_of([(c, 0.8) for c in light] + [(dark, 0.1)], shape=shape, ground=0.5)
    seg = segment(pixels, all_rocks=True)
    assert seg.polarity == "light"
    # Every light rock is found, and the blob, closed all round by an edge
    # as steep as theirs, is found last by its rim (rockscan.core.segment.ringed).
    assert seg.n_rocks == 13
    assert (
        seg.labels[round(190 * seg.labels.shape[0] / shape[0]), round(330 * seg.labels.shape[1] / shape[1])]
        > 0
    )
    monkeypatch.setattr(rockscan.core.segment.scene, "_ringed", lambda *args: [])
    assert segment(pixels, all_rocks=True).n_rocks == 12
    # One rock alone still follows its own polarity.
    assert segment(photo_of([(dark, 0.1)], shape=shape, ground=0.5), all_rocks=True).polarity == "dark"


# ---------------------------------------------------------------- pockets of ground between rocks


def _ring_of_domes(radius=30):
    """Four domes, each overlapping the next (centres 1.9 radii apart), round a
    pocket of ground; their outline with the pocket filled; and the pocket."""
    shape = (200, 200)
    d = 0.95 * radius
    centers = [(100 + sy * d, 100 + sx * d) for sy, sx in ((-1, -1), (-1, 1), (1, 1), (1, -1))]
    masks, height = _domes(shape, centers, radius)
    ring = np.logical_or.reduce(masks)
    yy, xx = np.mgrid[: shape[0], : shape[1]]
    pocket = ~ring & ((yy - 100) ** 2 + (xx - 100) ** 2 < radius**2)
    return masks, height, ring | pocket, pocket


@pytest.mark.parametrize(("rock", "ground"), [(0.3, 0.6), (0.8, 0.3)])
def test_split_pockets_cuts_rocks_that_touch_round_a_pocket_of_ground(rock, ground):
    # Filled in, the outline of the four is one blob with no neck: only the
    # pocket, of the ground's level, tells them apart.
    masks, height, whole, pocket = _ring_of_domes()
    image = _dome_photo(whole.shape, height, rock, ground)
    found = pockets(whole, image)
    # Most of the pocket, and little else: the darkened rims where a light
    # rock meets the pocket may count.
    assert (found & pocket).sum() >= 0.75 * pocket.sum()
    assert (found & ~pocket).sum() <= 0.1 * found.sum()
    assert len(split_necks(whole, 50)) == 1
    parts = split_pockets(whole, image)
    assert len(parts) == 4
    assert np.array_equal(np.logical_or.reduce(parts), whole)
    for part in parts:
        assert max((part & m).sum() / (part | m).sum() for m in masks) > 0.9


def test_split_pockets_keeps_a_rock_with_a_spot_of_the_grounds_level_whole():
    # A spot of the ground's level inside one rock is a pocket when large
    # enough, but a ring has no neck: the rock stays whole. A speck is no
    # pocket at all.
    shape = (160, 160)
    yy, xx = np.mgrid[: shape[0], : shape[1]]
    (disc,), height = _domes(shape, [(80, 80)], 60)
    for radius, is_pocket in ((10, True), (2, False)):
        image = _dome_photo(shape, height, 0.3, 0.6)
        image[(yy - 80) ** 2 + (xx - 80) ** 2 <= radius**2] = 0.6
        assert pockets(disc, image).any() == is_pocket
        assert len(split_pockets(disc, image)) == 1
    assert not pockets(disc, _dome_photo(shape, height, 0.3, 0.6)).any()


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**16), st.floats(0.0, 0.05))
def test_split_pockets_parts_cover_the_outline_once(seed, noise):
    _, height, whole, _ = _ring_of_domes()
    parts = split_pockets(whole, _dome_photo(whole.shape, height, 0.35, 0.6, noise=noise, seed=seed))
    total = np.sum([p.astype(int) for p in parts], axis=0)
    assert np.array_equal(total, whole.astype(int))
