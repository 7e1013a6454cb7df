"""Segmentation on photos of the independent generator (``scripts/scenes.py``).

A small fast subset of every condition of the benchmark's development part,
rendered here (not pasted), judged against the generator's exact truth as
``scripts/bench_segment.py`` judges it. The tolerances sit below what the
segmenter measures on these photos; the benchmark reports the full table on
the held-out part.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
import bench_segment
import scenes

import rockscan.core.segment.scene
from rockscan.core.segment import segment

#: Photos per condition: the first seeds of the development part.
N_PHOTOS = 1


def judged(condition: str, index: int):
    pixels, truth, kind = bench_segment.photo("dev", condition, index)
    found, _ = bench_segment.as_method(segment)(pixels, kind)
    if kind == "all":
        return bench_segment.score_crowd(found, truth)
    return bench_segment.score_rock(found == 1, truth == 1)


@pytest.fixture(scope="module")
def one_rock_scores() -> dict[str, list]:
    return {c: [judged(c, i) for i in range(N_PHOTOS)] for c in scenes.SINGLE_CONDITIONS}


def test_every_one_rock_condition_finds_a_rock(one_rock_scores):
    for condition, scores in one_rock_scores.items():
        assert not any(s.no_rock for s in scores), condition


def test_most_one_rock_photos_are_outlined_at_iou_09(one_rock_scores):
    ious = np.array([s.iou for scores in one_rock_scores.values() for s in scores])
    assert np.mean(ious >= 0.9) >= 0.45, np.round(ious, 2)
    assert np.mean(ious >= 0.5) >= 0.7, np.round(ious, 2)


def test_a_crop_is_outlined_around_the_rock_it_is_centred_on():
    scores = [judged("crop-neighbours", i) for i in range(8)]
    # All eight reach IoU 0.9 on the development part; crops 4 and 7 (rocks
    # walled in by neighbours of their own level, which widen the ground's
    # spread) found no rock until the last detection round could also fall
    # back on the spread of most stretches of the ground. A photo to spare.
    assert sum(s.iou >= 0.85 for s in scores) >= 7, [round(s.iou, 2) for s in scores]
    assert not any(s.no_rock for s in scores)


@pytest.mark.parametrize("index", [243, 349])
def test_a_crops_outline_moves_to_the_rocks_edge(index):
    # Development crops whose rock darkens towards its rim: the half-way
    # level runs a pixel or so inside the edge (IoU 0.883 and 0.873) until
    # the outline moves to the steepest change beside it (0.911 and 0.909).
    score = judged("crop-neighbours", index)
    assert score.iou >= 0.9, round(score.iou, 3)


def test_a_ground_whose_texture_varies_across_the_frame_does_not_hide_a_clear_rock():
    # Development plain photo 39: a rock of contrast 0.28 covering a quarter of
    # the frame on tinted grass. Against the whole ground's spread nothing
    # stood out in the last round, and "no rock" came back.
    score = judged("plain", 39)
    assert not score.no_rock
    assert score.iou >= 0.85, round(score.iou, 3)


def test_crowded_touching_rocks_are_found_one_to_one():
    crowds = [judged("crowded", i) for i in range(N_PHOTOS)]
    true = sum(c.n_true for c in crowds)
    assert sum(c.matched for c in crowds) >= 0.6 * true
    # Neither everything merged into one region nor shattered.
    for c in crowds:
        assert 0.5 * c.n_true <= c.n_found <= 1.5 * c.n_true


def test_a_band_of_ground_that_outscores_every_rock_does_not_hide_them():
    # Development scene 35: 31 light rocks on a ground crossed by a broad
    # shadowed band. The band is the best-scoring region; when every rock
    # had to score a tenth of it and cover 15% of its area, 8 regions were
    # found and 6 rocks matched. A rock is now judged per pixel against the
    # best regions, whatever its size.
    crowd = judged("crowded", 35)
    assert crowd.matched >= 0.85 * crowd.n_true, crowd
    assert abs(crowd.n_found - crowd.n_true) <= 3, crowd


def test_dark_rocks_touching_along_dark_seams_are_parted():
    # Development scene 5: 14 dark rocks of several colours in a cluster, on
    # a lighter ground. Where two touch, the line between them is darker than
    # either; at detection size it blurs away, and 7 rocks were matched one
    # to one (two regions of three and more rocks) until the outlines were
    # cut along their seams at working size (11).
    crowd = judged("crowded", 5)
    assert crowd.matched >= 10, crowd


@pytest.mark.parametrize("index", [8, 76])
def test_rocks_that_touch_round_a_pocket_of_ground_are_parted(index):
    # Development scenes 8 and 76: dark rocks on a lighter ground, in groups
    # of three round a pocket of ground. Outlined together, the pocket filled
    # in, 23 of 29 and 31 of 36 rocks were matched one to one until outlines
    # much larger than the median were cut round their pockets: every rock.
    crowd = judged("crowded", index)
    assert crowd.matched == crowd.n_true == crowd.n_found, crowd
    assert crowd.merges == 0, crowd


def test_specks_are_judged_against_the_largest_rock_not_the_largest_cluster():
    # Development scene 23: 14 light rocks on a brick wall, two clusters of
    # them touching. Specks were dropped against the largest detected region,
    # a cluster parted only later: 28 regions were found for 14 rocks. Judged
    # against the largest rock once every outline is parted, 22.
    crowd = judged("crowded", 23)
    assert crowd.matched == crowd.n_true, crowd
    assert crowd.n_found <= 24, crowd


@pytest.mark.parametrize("index", [0, 20, 66])
def test_pieces_of_one_textured_rock_are_joined_again(index):
    # Development crowded scenes 0, 20 and 66 (10, 17 and 29 rocks): 2, 2 and 4
    # rocks were broken into pieces along veins of their skins (12, 19 and 33
    # regions found) until touching pieces that are likely one rock were
    # joined (rockscan.core.segment.join): every count is exact.
    crowd = judged("crowded", index)
    assert crowd.n_found == crowd.n_true, crowd
    assert crowd.splits == 0, crowd


@pytest.mark.parametrize(("index", "matched"), [(85, 34), (88, 36)])
def test_two_rocks_outlined_as_one_are_cut_where_the_join_sees_two(index, matched):
    # Development crowded scenes 85 and 88 (35 and 36 rocks): a region held two
    # rocks touching along a contact with neither a neck nor a dark seam (34
    # and 35 regions found, 33 and 34 rocks one to one) until large regions
    # that are not convex were cut between the peaks of their distance to the
    # ground where the join's trees see two rocks
    # (rockscan.core.segment.join.parted; the halves' probability of one rock
    # is 0.02 and 0.05, against 0.2): every count exact, no merge.
    crowd = judged("crowded", index)
    assert crowd.n_found == crowd.n_true, crowd
    assert crowd.merges == 0, crowd
    assert crowd.matched >= matched, crowd


@pytest.mark.parametrize(("index", "matched"), [(22, 29), (740, 24)])
def test_rocks_of_the_grounds_brightness_are_found_by_their_distance_from_its_hue(index, matched):
    # Development crowded scenes 22 and 740 (32 and 30 rocks): rocks of the
    # ground's own brightness, in hues on several sides of the ground's, were
    # missed by brightness and by the principal direction of the chromaticity
    # (27 and 21 rocks one to one) until the distance from the ground's hue
    # looked for rocks where none was found: 30 and 26.
    crowd = judged("crowded", index)
    assert crowd.matched >= matched, crowd
    assert crowd.merges == 0, crowd


@pytest.mark.parametrize(("index", "matched"), [(29, 35), (110, 17)])
def test_light_rocks_keep_their_shaded_sides_with_all(index, matched):
    # Development crowded scenes 29 and 110 (37 and 18 light rocks lit from
    # one side): outlined half-way between the ground's level and theirs, the
    # shaded sides were left out, and rocks were found too small or in pieces
    # (33 and 16 one to one, 2 splits and 1 merge); outlined at LIGHT_EDGE
    # (0.35) of the way, 36 and 18, every count exact, no split.
    crowd = judged("crowded", index)
    assert crowd.matched >= matched, crowd
    assert crowd.splits == 0, crowd


@pytest.mark.parametrize(("index", "matched"), [(29, 37), (190, 23)])
def test_a_rock_in_its_neighbours_region_under_their_outlines_level_is_outlined_at_its_own(
    index, matched, monkeypatch
):
    # Development crowded scenes 29 and 190 (37 and 25 rocks): a rock lay in a
    # detected region under the level that region's outline was drawn at
    # (scene 29: a light rock of which the outline took a thin piece; scene
    # 190: a rock between two larger, brighter ones, which took none of it).
    # What of a region no rock took, where it is a round, solid part of a
    # rock's size, is outlined at its own level (_left_over): 36 -> 37 and
    # 22 -> 23 one to one. The rock of scene 190 is closed by its rim as well,
    # and the ring step (rockscan.core.segment.ringed) finds it without this
    # one: that step is held off to see this one alone.
    monkeypatch.setattr(rockscan.core.segment.scene, "_ringed", lambda *args: [])
    crowd = judged("crowded", index)
    assert crowd.matched >= matched, crowd
    monkeypatch.setattr(rockscan.core.segment.scene, "_left_over", lambda *args: None)
    assert judged("crowded", index).matched < crowd.matched


def test_a_piece_far_smaller_than_the_typical_rock_is_no_rock_of_its_own():
    # Development scene 32: 32 rocks, and a 33rd region, a piece under a
    # fifth of the median rock's area, until such regions were dropped
    # (min_median_area): the count is exact, and every rock matched before
    # still is.
    crowd = judged("crowded", 32)
    assert crowd.n_found == crowd.n_true == 32, crowd
    assert crowd.matched >= 30, crowd


@pytest.mark.parametrize(
    ("condition", "index"), [("plain", 9), ("touching-pebbles", 2), ("touching-pebbles", 3)]
)
def test_a_crisp_pebble_beside_an_unrivalled_rock_is_not_taken_for_it(condition, index):
    # On these development photos the rock stands out far above every other
    # region, and a small pebble beside it is outlined as crisply (score
    # >= FAST_SCORE): the fast path is for the unrivalled region itself, so
    # the pebble must not end the search (it did, at IoU 0 with the rock).
    # The bound asks for the rock, not for the finest of its outlines.
    score = judged(condition, index)
    assert score.iou >= 0.85, round(score.iou, 3)


@pytest.mark.parametrize("index", [3, 19])
def test_pebbles_pressed_against_the_rock_are_cut_off_its_outline(index):
    # Development photos of touching pebbles as dark as the rock: the chosen
    # outline holds the rock with its pebbles (IoU 0.90 and 0.91) until the
    # pebbles are cut off the main rock along their contacts (0.96 and 0.95).
    score = judged("touching-pebbles", index)
    assert score.iou >= 0.94, round(score.iou, 3)


def test_a_pebble_pressed_broadly_against_the_rock_is_cut_off_at_its_notches():
    # Development photo 626 of touching pebbles: a pebble meets the rock along
    # a contact too broad for the neck rule (NECK), and the outline holds it
    # (IoU 0.887) unless a round piece with a notch of the outline beside it
    # is cut as well (0.947).
    score = judged("touching-pebbles", 626)
    assert score.iou >= 0.92, round(score.iou, 3)


@pytest.mark.parametrize(("condition", "index"), [("plain", 17), ("shaded", 6)])
def test_a_cast_shadow_that_joined_a_dark_rock_is_cut_off_its_outline(condition, index):
    # Development photos of a dark rock beside its cast shadow, darker than
    # half-way to the ground: every cue outlined rock and shadow together
    # (IoU 0.90 and 0.76) until the shadow was cut off along the rock's
    # edge (0.98 and 0.97).
    score = judged(condition, index)
    assert score.iou >= 0.95, round(score.iou, 3)


def test_a_light_rock_with_dark_beside_its_first_outline_takes_no_fast_path():
    # Development photo "large" 2: a light rock lit from one side. Its lit
    # part steps against the ground and against its own shaded rim alike,
    # and the first outline (score >= FAST_SCORE) left the rim out (IoU
    # 0.92). The rim, darker than the ground, lies beside that outline: the
    # other candidates are judged, and the choice takes the whole rock.
    from rockscan.core.segment import SHADE_BESIDE, _candidate_pool
    from rockscan.core.segment.types import Segmentation, SegmentConfig

    pixels, _, _ = bench_segment.photo("dev", "large", 2)
    first = _candidate_pool(pixels, SegmentConfig(), fast=False).candidates[0][0]
    assert first.polarity == "light" and first.rocks[0].darker_outside >= SHADE_BESIDE
    assert not isinstance(_candidate_pool(pixels, SegmentConfig()), Segmentation)
    score = judged("large", 2)
    assert score.iou >= 0.95, round(score.iou, 3)


def test_a_dark_rock_taken_with_its_cast_shadow_takes_no_fast_path():
    # Development photo "shaded" 556: a dark rock under a low light. Its
    # shaded side joined to its cast shadow is one dark region whose far edge
    # steps against the lit ground as crisply as a rock's, and its first
    # outline scores above FAST_SCORE at IoU 0.49. The rock's lit face,
    # lighter than the ground, lies beside that outline: the other candidates
    # are judged, and the choice takes the rock without its shadow.
    from rockscan.core.segment import FAST_SCORE, LIT_BESIDE, _candidate_pool
    from rockscan.core.segment.types import Segmentation, SegmentConfig

    pixels, _, _ = bench_segment.photo("dev", "shaded", 556)
    first = _candidate_pool(pixels, SegmentConfig(), fast=False).candidates[0][0]
    rock = first.rocks[0]
    assert first.polarity == "dark" and first.channel == "luminance"
    assert rock.score >= FAST_SCORE and rock.darker_outside >= LIT_BESIDE
    assert not isinstance(_candidate_pool(pixels, SegmentConfig()), Segmentation)
    score = judged("shaded", 556)
    assert score.iou >= 0.95, round(score.iou, 3)


def test_a_real_coin_with_nothing_dark_beside_it_keeps_the_fast_path():
    # Flat, lit from above, a coin of coins() has no shaded rim: its first
    # outline is final, as for the light rocks rendered from the default library.
    from rockscan.core.segment import _candidate_pool
    from rockscan.core.segment.types import Segmentation, SegmentConfig

    crop, _ = bench_segment.coin_crops()[0]
    found = _candidate_pool(crop, SegmentConfig())
    assert isinstance(found, Segmentation)
    assert found.polarity == "light" and found.rocks[0].darker_outside < 0.05


def test_a_light_rocks_dark_rim_is_in_its_outline(monkeypatch):
    # Development photo "vignette-blur-jpeg" 30: a light rock whose rim,
    # darker than the ground, the half-way outline left out (IoU 0.885);
    # moved out to the rim's darkest line, it is outlined at 0.92. (The
    # learnt offsets, after the rim, would take the outline there too: they
    # are left out to judge the rim alone.)
    import rockscan.core.segment.finish as finish

    assert judged("vignette-blur-jpeg", 30).iou >= 0.91
    monkeypatch.setattr(finish, "moved_by", lambda read: None)
    assert judged("vignette-blur-jpeg", 30).iou >= 0.91
    monkeypatch.setattr(finish, "rim_on", lambda gray, mask, region=None: mask)
    assert judged("vignette-blur-jpeg", 30).iou < 0.9


@pytest.mark.parametrize(("condition", "index"), [("small", 277), ("crop-neighbours", 270)])
def test_an_outline_short_of_a_small_rocks_edge_moves_out_by_the_learnt_offsets(
    monkeypatch, condition, index
):
    # Development photos the offset model was not fitted on (it was on
    # 0-199): small light rocks whose limb darkens into a blurred rim, their
    # outlines a pixel or two short all round (IoU 0.872 and 0.877) until
    # the learnt offsets move them out (0.955 and 0.924).
    import rockscan.core.segment.finish as finish

    assert judged(condition, index).iou >= 0.92
    monkeypatch.setattr(finish, "moved_by", lambda read: None)
    assert judged(condition, index).iou < 0.9
