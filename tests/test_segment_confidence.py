"""The score of a rock chosen among the whole pool of candidates (rockscan.core.segment.confidence)."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from rockscan.core.segment import _chosen, confidence, segment
from rockscan.core.segment.choose import FEATURES, Ranking
from rockscan.core.segment.confidence import (
    CHOICE_COUNT,
    CONFIDENCE_FEATURES,
    INTERCEPT,
    SIGNS,
    WEIGHTS,
    confidence_features,
    offset_evidence,
    outline_confidence,
)
from rockscan.core.segment.finish import completed
from rockscan.core.segment.types import SegmentConfig

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
import bench_segment
import fit_segment_confidence as fitting


def logit(p: float) -> float:
    return math.log(p / (1.0 - p))


def ranking() -> Ranking:
    """Four candidates: the chosen one (1), one agreeing with it, one of another
    object, one in between."""
    probabilities = np.array([0.3, 0.6, 0.5, 0.2])
    ious = np.array(
        [
            [1.0, 0.9, 0.1, 0.6],
            [0.9, 1.0, 0.2, 0.7],
            [0.1, 0.2, 1.0, 0.3],
            [0.6, 0.7, 0.3, 1.0],
        ]
    )
    # Values in [0, 1), as most of the features are shares.
    features = np.arange(4 * len(FEATURES), dtype=np.float64).reshape(4, len(FEATURES)) / (4 * len(FEATURES))
    return Ranking(1, probabilities, features, ious)


def scored(ranking: Ranking, detected_best: float, notch: float, before=None, after=None) -> np.ndarray:
    """All of the score's features: the choice's, then the offset step's."""
    return np.concatenate(
        [confidence_features(ranking, detected_best, notch), offset_evidence(before, after)]
    )


def test_the_features_read_the_best_the_rival_and_the_agreeing_candidates():
    x = confidence_features(ranking(), detected_best=0.4, notch=0.05)
    assert x.shape == (CHOICE_COUNT,)
    col = {name: k for k, name in enumerate(CONFIDENCE_FEATURES)}
    assert x[col["logit_best"]] == pytest.approx(logit(0.6))
    # The rival: candidate 2, IoU 0.2 < 0.5 with the chosen one (3 lies in between).
    assert x[col["logit_rival"]] == pytest.approx(logit(0.5))
    # Agreeing: the chosen one and candidate 0 (IoU 0.9).
    assert x[col["logit_agreeing"]] == pytest.approx(logit(0.45))
    assert x[col["agreeing"]] == 2.0 and x[col["candidates"]] == 4.0
    assert x[col["logit_detected_best"]] == pytest.approx(logit(0.4))
    # The chosen candidate's own features, up to its channel.
    own = [k for k, name in enumerate(CONFIDENCE_FEATURES) if name.startswith("own_")]
    np.testing.assert_array_equal(x[own], ranking().features[1, : len(own)])
    assert CONFIDENCE_FEATURES[own[-1]] == "own_chromaticity"
    assert x[col["notch"]] == 0.05


def test_an_outline_with_one_deeper_notch_is_never_surer():
    x = scored(ranking(), detected_best=0.4, notch=0.0)
    notched = scored(ranking(), detected_best=0.4, notch=0.2)
    assert WEIGHTS[CONFIDENCE_FEATURES.index("notch")] <= 0
    assert outline_confidence(notched) <= outline_confidence(x)


def test_no_rival_counts_as_a_probability_near_zero():
    r = ranking()
    alone = Ranking(r.index, r.probabilities, r.features, np.ones_like(r.ious))
    x = confidence_features(alone, detected_best=0.4, notch=0.05)
    assert x[CONFIDENCE_FEATURES.index("logit_rival")] == pytest.approx(logit(1e-4))
    assert x[CONFIDENCE_FEATURES.index("agreeing")] == 4.0


def test_the_offset_evidence_reads_what_the_trees_left_and_what_the_move_settled():
    before, after = np.array([1.0, -2.0, 3.0]), np.array([0.5, -0.5, 1.0])
    left, settled, out = offset_evidence(before, after)
    # Still read on the final outline: (0.5 + 0.5 + 1) / 3; before, (1 + 2 + 3) / 3.
    assert left == pytest.approx(2.0 / 3.0)
    assert settled == pytest.approx(2.0 - 2.0 / 3.0)
    # The mean signed offset went from 2/3 to 1/3: the outline moved out by 1/3.
    assert out == pytest.approx(1.0 / 3.0)
    assert [CONFIDENCE_FEATURES[k] for k in range(CHOICE_COUNT, len(CONFIDENCE_FEATURES))] == [
        "offset_left",
        "offset_settled",
        "offset_out",
    ]


def test_an_outline_that_did_not_move_is_read_once_and_nothing_read_counts_as_nothing():
    before = np.array([1.0, -2.0, 3.0])
    np.testing.assert_allclose(offset_evidence(before, None), [2.0, 0.0, 0.0])
    np.testing.assert_allclose(offset_evidence(before, before), [2.0, 0.0, 0.0])
    np.testing.assert_array_equal(offset_evidence(None, None), [0.0, 0.0, 0.0])
    np.testing.assert_array_equal(offset_evidence(np.array([]), np.array([])), [0.0, 0.0, 0.0])


def test_an_outline_the_trees_would_still_move_is_never_surer():
    x = scored(ranking(), 0.4, 0.05, before=np.full(8, 2.5), after=np.full(8, 0.2))
    unsettled = scored(ranking(), 0.4, 0.05, before=np.full(8, 2.5), after=np.full(8, 1.5))
    assert outline_confidence(unsettled) <= outline_confidence(x)


def test_the_shipped_weights_keep_the_directions_the_fit_is_held_to():
    for name, weight in zip(CONFIDENCE_FEATURES, WEIGHTS, strict=True):
        assert weight * SIGNS[name] >= 0.0, name


def test_the_score_is_a_probability_and_the_fit_reads_the_choice_as_expected():
    x = scored(ranking(), detected_best=0.4, notch=0.05)
    assert 0.0 < outline_confidence(x) < 1.0
    assert outline_confidence(x) == pytest.approx(1.0 / (1.0 + math.exp(-(INTERCEPT + WEIGHTS @ x))))
    # A more probable choice is surer; a more probable rival object, less sure.
    col = {name: k for k, name in enumerate(CONFIDENCE_FEATURES)}
    assert WEIGHTS[col["logit_best"]] > 0 and WEIGHTS[col["logit_rival"]] < 0
    # Far out, the log-odds are clipped rather than overflowing.
    assert outline_confidence(np.sign(WEIGHTS) * 1e6) == pytest.approx(1.0)
    assert outline_confidence(-np.sign(WEIGHTS) * 1e6) == pytest.approx(0.0)


def test_a_rock_chosen_among_the_whole_pool_is_scored_by_the_fitted_model():
    # Development photo "shaded" 0 is decided by the whole pool.
    pixels, _, _ = bench_segment.photo("dev", "shaded", 0)
    found, choice, easy = _chosen(pixels, SegmentConfig())
    assert choice is not None
    final, features = completed(found, choice, pixels, easy=easy)
    np.testing.assert_array_equal(features[:CHOICE_COUNT], choice)
    rock = segment(pixels).rocks[0]
    np.testing.assert_array_equal(rock.mask, final.rocks[0].mask)
    assert rock.score == pytest.approx(outline_confidence(features))


# ---------------------------------------------------------------- the fit (scripts/fit_segment_confidence.py)


def test_the_auroc_counts_right_outlines_ranked_above_wrong_ones():
    ious = np.array([0.95, 0.92, 0.5, 0.7, 0.85])
    scores = np.array([0.9, 0.4, 0.6, 0.1, 0.99])
    # Right (0.95, 0.92) against wrong (0.5, 0.7); 0.85 counts as neither. Of
    # the four pairs, three rank right: 0.4 < 0.6 is the one that does not.
    auroc, trusted, refused = fitting.judged(ious, scores)
    assert auroc == pytest.approx(0.75)
    assert (trusted, refused) == (1, 1)


def test_the_fit_holds_every_weight_to_its_direction():
    rng = np.random.default_rng(0)
    x = rng.normal(size=(400, len(CONFIDENCE_FEATURES)))
    # An outcome that every feature pushes the wrong way.
    signs = np.array([SIGNS[name] for name in CONFIDENCE_FEATURES], dtype=np.float64)
    y = (x @ -np.where(signs == 0, 1.0, signs) + rng.normal(size=400)) > 0
    weights, _ = fitting.fit(x, y, penalty=1.0)
    assert np.all(weights[signs > 0] >= 0.0) and np.all(weights[signs < 0] <= 0.0)
    # Free features follow the data.
    assert np.all(weights[signs == 0] < 0.0)


def test_written_weights_are_read_back(tmp_path):
    path = tmp_path / "confidence.py"
    path.write_text(Path(confidence.__file__).read_text())
    weights = np.linspace(-1.0, 1.0, len(CONFIDENCE_FEATURES))
    fitting.write((weights, 0.25), path)
    namespace: dict = {}
    exec(compile(path.read_text(), str(path), "exec"), namespace)
    np.testing.assert_allclose(namespace["WEIGHTS"], weights, rtol=1e-5)
    assert namespace["INTERCEPT"] == pytest.approx(0.25)


def test_a_stars_arms_do_not_count_against_its_outline_in_hard_photos():
    # Low contrast, textures, pebbles, a cast shadow, a lighting gradient, noise
    # and blur: the whole pool decides. The arms leave alike gaps all round the
    # hull, so the notch reads near 0 and the star keeps the trust a solid
    # rock's outline gets (a score on the outline's solidity trusted none).
    from rockscan.core.render import RenderConfig, render_photo
    from rockscan.core.segment.stats import notch
    from rockscan.io import default_spec_path, read_spec

    star = next(s for s in read_spec(default_spec_path()) if s.name == "five-armed-star")
    config = RenderConfig(
        rows=240, cols=320, contrast=0.12, rock_texture=0.08, ground_texture=0.08,
        pebbles=6, gradient=0.3, shadow=0.4, noise=0.03, blur=1.5,
    )  # fmt: skip
    trusted = 0
    for seed in range(1, 5):
        pixels = render_photo(star.params, config, rng=seed, name=star.name).pixels
        found, features, _ = _chosen(pixels, SegmentConfig())
        assert features is not None
        assert notch(found.rocks[0].mask) < 0.02
        trusted += segment(pixels).rocks[0].score >= 0.5
    assert trusted >= 3
