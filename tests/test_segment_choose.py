"""The choice among candidate outlines of the main rock (rockscan.core.segment.choose)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rockscan.core.segment import choice_model, segment
from rockscan.core.segment.choose import (
    FEATURES,
    MONOTONE,
    SAME_OBJECT,
    SOURCES,
    _mutual_ious,
    choice_features,
    choice_probabilities,
    choose,
    choose_ranked,
    pebble_share,
)
from rockscan.core.segment.stats import solidity
from rockscan.core.segment.types import RockMask, Segmentation

SHAPE = (120, 160)


def disk(row: float, col: float, radius: float) -> np.ndarray:
    rr, cc = np.mgrid[: SHAPE[0], : SHAPE[1]]
    return (rr - row) ** 2 + (cc - col) ** 2 <= radius**2


def candidate(mask: np.ndarray, score: float = 0.9, frame: float = 0.0) -> Segmentation:
    """A one-rock segmentation of ``mask`` with clean evidence, unless told otherwise."""
    rock = RockMask(
        mask=mask,
        coverage=mask.astype(np.float32),
        origin_rowcol=(0, 0),
        score=score,
        evidence=(0.95, 0.0, 0.03, 0.1, frame, solidity(mask)),
    )
    return Segmentation(
        labels=mask.astype(np.int32),
        rocks=(rock,),
        scale_rowcol=(1.0, 1.0),
        polarity="dark",
        channel="luminance",
    )


def test_features_measure_position_area_and_consensus():
    centred = candidate(disk(60, 80, 30))
    same = candidate(disk(61, 80, 30))
    corner = candidate(disk(15, 15, 10))
    features = choice_features([centred, same, corner], [1.0, 1.0, 1.0])
    col = {name: i for i, name in enumerate(FEATURES)}
    assert features.shape == (3, len(FEATURES))
    # Position: a centred disk covers the centre; the corner one lies far from it.
    assert features[0, col["covers_centre"]] == 1.0 and features[2, col["covers_centre"]] == 0.0
    assert features[0, col["centre_distance"]] < 0.01
    assert features[2, col["centre_distance"]] == pytest.approx(
        np.hypot(15.5 / 120 - 0.5, 15.5 / 160 - 0.5), abs=0.01
    )
    # Area: the log of the share of the frame.
    assert features[0, col["log_area"]] == pytest.approx(np.log(disk(60, 80, 30).mean()))
    # Consensus: the mean IoU with the (at most three) most overlapping others;
    # the near copies agree with each other, the corner disk with nobody.
    a, b = disk(60, 80, 30), disk(61, 80, 30)
    copies = (a & b).sum() / (a | b).sum()
    assert features[0, col["consensus"]] == pytest.approx(copies / 2, abs=0.02)
    assert features[1, col["consensus"]] == pytest.approx(copies / 2, abs=0.02)
    assert features[2, col["consensus"]] == 0.0
    assert features[0, col["logit_score"]] == pytest.approx(np.log(0.9 / 0.1))


def test_a_candidate_along_the_frame_loses_to_one_inside_it():
    inside = candidate(disk(60, 80, 25))
    along = candidate(disk(0, 0, 40), frame=0.6)
    assert choose([along, inside], [1.0, 1.0])[0] == 1


def test_of_outlines_of_the_same_rock_the_better_supported_wins():
    masks = [disk(60, 80, 30), disk(60, 80, 29.5), disk(60, 81, 30)]
    scores = [0.7, 0.95, 0.8]
    found = [candidate(m, s) for m, s in zip(masks, scores, strict=True)]
    ious = [(masks[0] & m).sum() / (masks[0] | m).sum() for m in masks]
    assert min(ious) >= SAME_OBJECT
    assert choose(found, [1.0, 1.0, 1.0])[0] == 1


def test_the_probability_is_in_zero_one_and_higher_for_a_clean_outline_inside_the_frame():
    inside = choose([candidate(disk(60, 80, 25)), candidate(disk(61, 80, 25))], [1.0, 1.0])
    along = choose([candidate(disk(0, 0, 40), frame=0.6), candidate(disk(1, 0, 40), frame=0.6)], [1.0, 1.0])
    assert 0.0 <= along[1] < inside[1] <= 1.0


@settings(max_examples=25, deadline=None)
@given(st.permutations(range(4)))
def test_the_choice_does_not_depend_on_the_order_of_candidates(order):
    masks = [disk(60, 80, 30), disk(20, 30, 12), disk(90, 130, 20), disk(60, 60, 18)]
    scores = [0.9, 0.6, 0.4, 0.75]
    found = [candidate(m, s) for m, s in zip(masks, scores, strict=True)]
    chosen = found[choose(found, [1.0] * 4)[0]]
    permuted = [found[k] for k in order]
    assert permuted[choose(permuted, [1.0] * 4)[0]] is chosen


def test_a_star_keeps_its_arms_beside_a_solid_pebble():
    """Solidity is no choice feature: a crisp star outline wins over a small solid blob."""
    rr, cc = np.mgrid[: SHAPE[0], : SHAPE[1]]
    angle = np.arctan2(rr - 60, cc - 80)
    star = np.hypot(rr - 60, cc - 80) <= 22 + 14 * np.cos(5 * angle)
    found = [candidate(star, 0.95), candidate(disk(20, 20, 6), 0.3)]
    assert found[0].rocks[0].evidence[5] < 0.75 < found[1].rocks[0].evidence[5]
    assert choose(found, [1.0, 0.5])[0] == 0


def star(row: float, col: float, radius: float, arms: int, depth: float) -> np.ndarray:
    rr, cc = np.mgrid[: SHAPE[0], : SHAPE[1]]
    angle = np.arctan2(rr - row, cc - col)
    return np.hypot(rr - row, cc - col) <= radius * (1 + depth * np.cos(arms * angle))


@pytest.mark.parametrize("pebble", [4.0, 5.0, 6.0])
def test_the_pebble_share_is_the_area_of_a_small_round_pebble_on_the_rock(pebble):
    rock = disk(60, 80, 30)
    pebble_disk = disk(60, 80 + 30 + pebble - 1.5, pebble)
    share = pebble_share(rock | pebble_disk)
    # The opening leaves the pebble's rim by the contact on the rock's side.
    assert share == pytest.approx((pebble_disk & ~rock).sum() / (rock | pebble_disk).sum(), rel=0.35)
    assert share > 0


@pytest.mark.parametrize(
    "mask",
    [
        disk(60, 80, 30),
        disk(60, 80, 3),
        np.zeros(SHAPE, bool),
        star(60, 80, 30, 5, 0.4),
        star(60, 80, 30, 6, 0.3),
    ],
    ids=["disk", "speck", "empty", "star-5", "star-6"],
)
def test_a_rock_alone_has_no_pebbles_and_a_star_keeps_its_arms(mask):
    assert pebble_share(mask) < 0.02


def test_alike_lobes_all_round_are_the_rocks_own_shape():
    """Eight round lobes (a Superformula of symmetry 8) are no pebbles; one of them alone is."""
    lobes = disk(60, 80, 26)
    for k in range(8):
        a = 2 * np.pi * k / 8
        lobes |= disk(60 + 31 * np.sin(a), 80 + 31 * np.cos(a), 5)
    assert pebble_share(lobes) == 0.0
    assert pebble_share(disk(60, 80, 26) | disk(60, 80 + 31, 5)) > 0.005


def test_the_pebble_share_does_not_depend_on_resolution():
    """Regions larger than the measuring radius are scaled down to it."""
    rr, cc = np.mgrid[:600, :800]
    big = np.hypot(rr - 300, cc - 400) <= 150
    big |= np.hypot(rr - 300, cc - 400 - 150 - 22) <= 25
    small = big[::4, ::4]
    assert pebble_share(big) == pytest.approx(pebble_share(small), abs=0.01)
    assert pebble_share(big) > 0.01


def test_a_candidate_with_a_pebble_joined_on_loses_to_the_rock_alone():
    rock = disk(60, 80, 30)
    joined = rock | disk(60, 80 + 34.5, 6) | disk(60, 80 - 33.5, 5) | disk(60 + 32.5, 80, 4)
    assert (rock & joined).sum() / joined.sum() < SAME_OBJECT
    found = [candidate(joined, 0.9), candidate(rock, 0.9)]
    col = FEATURES.index("pebbles")
    features = choice_features(found, [1.0, 1.0])
    assert features[0, col] > 0.005 and features[1, col] == 0.0
    assert choose(found, [1.0, 1.0])[0] == 1


def test_segment_takes_the_chosen_candidate_on_a_photo_with_a_neighbour_at_the_edge():
    """A dark rock in the middle of a light frame, a darker neighbour cut by the frame."""
    rng = np.random.default_rng(3)
    photo = np.full(SHAPE, 200.0) + rng.normal(0, 4, SHAPE)
    photo[disk(60, 80, 28)] = 90
    photo[disk(60, -10, 35)] = 40
    found = segment(photo.clip(0, 255).astype(np.uint8))
    main = found.labels == 1
    truth = disk(60, 80, 28)
    scale = found.scale_rowcol
    assert scale == (1.0, 1.0)
    assert (main & truth).sum() / (main | truth).sum() > 0.9


def test_each_source_has_its_own_column_and_unknown_sources_are_refused():
    found = [candidate(disk(60, 80, 20)), candidate(disk(60, 80, 20))]
    features = choice_features(found, [1.0, 1.0], ["detected", "centre-basin"])
    columns = features[:, -(len(SOURCES) - 1) :]
    np.testing.assert_array_equal(columns[0], 0.0)
    assert columns[1].sum() == 1.0 and columns[1][SOURCES.index("centre-basin") - 1] == 1.0
    with pytest.raises(ValueError, match="one source per candidate"):
        choose(found, [1.0, 1.0], ["detected", "watershed"])
    with pytest.raises(ValueError, match="one source per candidate"):
        choose(found, [1.0, 1.0], ["detected"])


def test_the_channel_column_marks_outlines_found_in_chromaticity():
    grey = candidate(disk(60, 80, 20))
    hue = dataclasses.replace(grey, channel="chromaticity")
    features = choice_features([grey, hue], [1.0, 1.0])
    column = features[:, FEATURES.index("chromaticity")]
    np.testing.assert_array_equal(column, [0.0, 1.0])
    # Everything else about the two outlines is the same.
    others = np.delete(features, FEATURES.index("chromaticity"), axis=1)
    np.testing.assert_array_equal(others[0], others[1])


def _in_channel(found: Segmentation, channel: str, inner_spread: float) -> Segmentation:
    rock = dataclasses.replace(found.rocks[0], inner_spread=inner_spread)
    return dataclasses.replace(found, channel=channel, rocks=(rock,))


def test_a_colour_outline_uneven_inside_yields_to_the_brightness_outline_of_the_same_rock():
    # The colour outline is the better supported one (the choice model takes it)...
    hue = candidate(disk(60, 80, 20), score=0.99)
    grey = candidate(disk(60, 80, 21.2), score=0.9)
    elsewhere = candidate(disk(30, 40, 12), score=0.9)
    assert 0.85 <= _mutual_ious([hue, grey])[0, 1] < SAME_OBJECT
    even = [_in_channel(hue, "chromaticity", 0.1), _in_channel(grey, "luminance", 0.1)]
    assert choose(even, [1.0, 1.0])[0] == 0
    # ...unless its inside spreads more than UNEVEN_INSIDE times as much as the
    # brightness outline's: brightness then shows the rock better.
    uneven = [_in_channel(hue, "chromaticity", 0.25), _in_channel(grey, "luminance", 0.1)]
    index, probabilities = choose(uneven, [1.0, 1.0]), choose_ranked(uneven, [1.0, 1.0])[1]
    assert index[0] == 1 and index[1] == probabilities.max()
    # Another object, or another colour outline, is no brightness outline of the same rock.
    apart = [_in_channel(hue, "chromaticity", 0.25), _in_channel(elsewhere, "luminance", 0.1)]
    assert choose(apart, [1.0, 1.0])[0] == 0
    both_colour = [_in_channel(hue, "chromaticity", 0.25), _in_channel(grey, "chromaticity", 0.1)]
    assert choose(both_colour, [1.0, 1.0])[0] == 0


def test_of_outlines_of_one_object_the_detected_is_kept():
    found = [candidate(disk(60, 80, 20.3), score=0.95), candidate(disk(60, 80, 20), score=0.9)]
    assert choose(found, [1.0, 1.0], ["box-frame", "detected"])[0] == 1


#: Both tree sets of the choice model: the whole pool's, and the detected candidates' alone.
TREES = [False, True]


def _arrays(detected_only: bool) -> dict[str, np.ndarray]:
    prefix = "DETECTED_" if detected_only else ""
    names = ("BIAS", "DEPTH", "ROOTS", "FEATURE", "LEFT", "RIGHT", "THRESHOLD", "VALUE")
    return {name: getattr(choice_model, prefix + name) for name in names}


def _walk(x: np.ndarray, m: dict[str, np.ndarray]) -> float:
    """The log-odds of one feature row, tree by tree, node by node."""
    total = m["BIAS"]
    for root in m["ROOTS"]:
        node = int(root)
        while m["FEATURE"][node] >= 0:
            k = m["FEATURE"][node]
            node = int(m["LEFT"][node] if x[k] <= m["THRESHOLD"][node] else m["RIGHT"][node])
        total += m["VALUE"][node]
    return total


def _feature_rows(rng: np.random.Generator, n: int, m: dict[str, np.ndarray]) -> np.ndarray:
    """Feature rows spread over the trees' own thresholds, each source flag 0 or 1."""
    rows = np.empty((n, len(FEATURES)))
    for k in range(len(FEATURES)):
        cuts = m["THRESHOLD"][m["FEATURE"] == k]
        low, high = (cuts.min() - 1.0, cuts.max() + 1.0) if cuts.size else (-1.0, 1.0)
        rows[:, k] = rng.uniform(low, high, n)
    sources = [FEATURES.index(f"from_{s}") for s in SOURCES[1:]]
    rows[:, sources] = rng.integers(0, 2, (n, len(sources)))
    return rows


@pytest.mark.parametrize("detected_only", TREES)
def test_the_trees_are_walked_all_at_once_as_one_by_one(detected_only):
    m = _arrays(detected_only)
    assert m["ROOTS"].size >= 10 and m["DEPTH"] >= 1
    # Every node is a leaf or points at two nodes of its own tree, deeper down.
    inner = np.flatnonzero(m["FEATURE"] >= 0)
    assert np.all(m["LEFT"][inner] > inner) and np.all(m["RIGHT"][inner] > inner)
    assert m["FEATURE"].max() < len(FEATURES)
    x = _feature_rows(np.random.default_rng(0), 200, m)
    expected = 1.0 / (1.0 + np.exp(-np.array([_walk(row, m) for row in x])))
    got = choice_probabilities(x, detected_only=detected_only)
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-15)


def test_the_two_tree_sets_differ():
    x = _feature_rows(np.random.default_rng(1), 200, _arrays(True))
    assert np.abs(choice_probabilities(x) - choice_probabilities(x, detected_only=True)).max() > 0.05


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    feature=st.sampled_from([f for f, sign in MONOTONE.items() if sign]),
    detected_only=st.sampled_from(TREES),
)
def test_more_evidence_for_an_outline_never_lowers_its_probability(seed, feature, detected_only):
    k = FEATURES.index(feature)
    x = _feature_rows(np.random.default_rng(seed), 20, _arrays(detected_only))
    more = x.copy()
    more[:, k] += MONOTONE[feature] * np.random.default_rng(seed + 1).uniform(0.0, 3.0, 20)
    before = choice_probabilities(x, detected_only=detected_only)
    assert np.all(choice_probabilities(more, detected_only=detected_only) >= before - 1e-12)
    assert set(MONOTONE) == set(FEATURES)
