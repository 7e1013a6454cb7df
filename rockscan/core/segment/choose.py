"""Which of several candidate outlines of the main rock is the rock.

Candidates come from different cues (:data:`SOURCES`: the hysteresis region
in either polarity and channel, its runners-up, GrabCut from the outline and
from boxes, the Otsu class under the frame's centre, watershed basins from
the centre and from the outline's core, outlines with touching pebbles
opened off). Each is measured by what a person would look at:

* how well the photo supports its outline (its segmentation score and the
  evidence behind it, ``rockscan.core.segment.score``);
* how clearly its region stood out when it was detected;
* where it lies: distance of its centroid from the frame's centre, whether
  it covers the centre (a photo of one rock is framed on it, a crop is
  centred on it), and its share of the frame;
* **consensus**: how much it agrees with the other candidates (mean
  intersection over union with the three that overlap it most). Cues fail
  in different ways, a shaded side here, a highlight there, and mostly
  agree where they are right.
* **pebbles**: the share of its area in round pieces hanging off its body
  (:func:`pebble_share`). A rock with a touching pebble joined on is the
  commonest wrong outline that the photo supports all round.
* its **channel**: whether its region was found in the chromaticity channel
  rather than in luminance. Its evidence is read in its own channel, so
  the model learns how that compares with luminance's.
* its **source**: one column per cue, so that the model learns how far each
  cue is to be trusted.

A model of these features gives each candidate the probability that it
outlines the rock (intersection over union >= 0.9), and the most probable
wins: gradient-boosted regression trees (:func:`choice_probabilities`),
fitted on the development part of the segmentation benchmark
(``scripts/fit_segment_choice.py``, which also fits the one-weight-per-feature
logistic model they replaced, as a baseline). One rule stands beside the
model: a chromaticity outline whose inside is much less even than a
luminance outline's of the same object yields to it (:func:`_luminance_if_even`;
the model judges each candidate alone and cannot compare the two). The
winner's probability,
read with the rest of the choice (``rockscan.core.segment.confidence``),
becomes the rock's segmentation score: it ranks right outlines above wrong
ones better than the outline's own evidence.

The refinements (GrabCut above all) cost most, so the detection's own
outlines are judged first, alone, by trees of their own fitted on such
pools (``detected_only``); only when none of them is sure are the other
cues' outlines made and the whole pool judged.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from rockscan.core.segment import choice_model
from rockscan.core.segment.pebbles import pebble_share
from rockscan.core.segment.stats import logit
from rockscan.core.segment.trees import tree_sum, trees_of
from rockscan.core.segment.types import Segmentation

__all__ = [
    "FEATURES",
    "MONOTONE",
    "Ranking",
    "choice_features",
    "choice_probabilities",
    "choose",
    "choose_ranked",
    "pebble_share",
    "rank",
]

#: Where a candidate comes from: the detection's own threshold outlines
#: ("detected", placed between pixels), then the other cues of
#: ``rockscan.core.segment`` (GrabCut from the outline and from most of the frame,
#: the Otsu class and the watershed basin under the frame's centre, the basin
#: of the outline's core, and two outlines with touching pebbles opened off).
#: Each cue has a column of its own: the model learns how far each is to be trusted.
SOURCES = (
    "detected",
    "grabcut",
    "centre-otsu",
    "centre-basin",
    "core-basin",
    "opened",
    "opened-core",
    "box-frame",
)

#: Names of the columns of :func:`choice_features`.
FEATURES = (
    "logit_score",
    "support",
    "weak",
    "outside",
    "noise",
    "frame",
    "log_detection",
    "centre_distance",
    "covers_centre",
    "log_area",
    "consensus",
    "pebbles",
    "chromaticity",
    *(f"from_{source}" for source in SOURCES[1:]),
)

#: The direction in which the choice model's probability may move with each
#: feature (+1: never down as it grows, -1: never up, 0: free), so that more
#: evidence for an outline never counts against it; the trees are fitted
#: under these constraints.
MONOTONE = {
    "logit_score": 1,
    "support": 1,
    # Free: the outline of a rock that touches others crosses the contacts,
    # where the photo steps little, while the joined region of the rocks is
    # supported all round; how much of an outline is weak is no evidence against it.
    "weak": 0,
    "outside": -1,
    "noise": -1,
    "frame": -1,
    "log_detection": 1,
    "centre_distance": -1,
    "covers_centre": 1,
    "log_area": 0,
    "consensus": 1,
    # A round piece hanging off the body is a touching pebble, never the rock.
    "pebbles": -1,
    # Free: its evidence is read in its own channel, so how far it compares with
    # luminance's is for the data to say.
    "chromaticity": 0,
    # How far each cue is trusted is for the data to say.
    **{f"from_{source}": 0 for source in SOURCES[1:]},
}

#: Side of the common grid candidates are compared on (they may come from
#: working images of different sizes).
_GRID = 96
#: How many of the most overlapping other candidates the consensus averages.
_CONSENSUS_OF = 3


def _grid_mask(found: Segmentation) -> NDArray[np.bool_]:
    import cv2

    main = (found.labels == 1).astype(np.float32)
    return cv2.resize(main, (_GRID, _GRID), interpolation=cv2.INTER_AREA) >= 0.5


def _mutual_ious(candidates: Sequence[Segmentation]) -> NDArray[np.float64]:
    """Intersection over union of every pair of main rocks, on the common grid."""
    flat = np.array([_grid_mask(found).ravel() for found in candidates], dtype=np.float64)
    inter = flat @ flat.T
    area = flat.sum(axis=1)
    union = area[:, None] + area[None, :] - inter
    return np.divide(inter, union, out=np.zeros_like(inter), where=union > 0)


def choice_features(
    candidates: Sequence[Segmentation],
    detection_scores: Sequence[float],
    sources: Sequence[str] | None = None,
) -> NDArray:
    """The choice features of each candidate's main rock (module docstring).

    Parameters
    ----------
    candidates : sequence of Segmentation
        Candidate segmentations of one photo; rock 1 of each is its main rock.
    detection_scores : sequence of float
        How clearly each candidate's region stood out when detected.
    sources : sequence of str, optional
        Where each candidate comes from (:data:`SOURCES`); "detected" for all
        when not given.

    Returns
    -------
    features : (n, len(FEATURES)) ndarray of float64
    """
    sources = _sources(sources, len(candidates))
    return _features(candidates, detection_scores, sources, _mutual_ious(candidates))


def _sources(sources: Sequence[str] | None, n: int) -> list[str]:
    if sources is None:
        return ["detected"] * n
    unknown = set(sources) - set(SOURCES)
    if unknown or len(sources) != n:
        raise ValueError(f"one source per candidate, each one of {SOURCES}")
    return list(sources)


def _features(
    candidates: Sequence[Segmentation],
    detection_scores: Sequence[float],
    sources: list[str],
    ious: NDArray[np.float64],
) -> NDArray:
    """:func:`choice_features`, given the candidates' sources and mutual IoUs."""
    rows = []
    for k, (found, detected) in enumerate(zip(candidates, detection_scores, strict=True)):
        rock = found.rocks[0]
        others = np.delete(ious[k], k)
        consensus = float(np.sort(others)[-_CONSENSUS_OF:].mean()) if others.size else 0.0
        mask = found.labels == 1
        h, w = mask.shape
        ys, xs = np.nonzero(mask)
        if ys.size:
            centre = math.hypot((ys.mean() + 0.5) / h - 0.5, (xs.mean() + 0.5) / w - 0.5)
            share = ys.size / mask.size
        else:
            centre, share = 0.75, 0.0
        # Solidity stays out: the rocks it was fitted on are blobs, and a
        # star's arms must not count against it (the outline score weighs it).
        evidence = list(rock.evidence[:5]) if len(rock.evidence) == 6 else [0.0, 1.0, 1.0, 1.0, 0.0]
        rows.append(
            [
                logit(rock.score),
                *evidence,
                math.log(max(detected, 1e-6)),
                centre,
                float(mask[h // 2, w // 2]),
                math.log(max(share, 1e-6)),
                consensus,
                pebble_share(mask),
                float(found.channel == "chromaticity"),
                *(float(sources[k] == source) for source in SOURCES[1:]),
            ]
        )
    return np.array(rows, dtype=np.float64).reshape(len(candidates), len(FEATURES))


def choice_probabilities(features: NDArray, *, detected_only: bool = False) -> NDArray[np.float64]:
    """The choice model's probability that each candidate outlines the rock.

    The model (``choice_model``) is an ensemble of small regression trees
    whose leaf values add up to the log-odds, gradient-boosted on the
    development part by ``scripts/fit_segment_choice.py``. Trees, unlike one
    weight per feature, let how much a cue counts depend on the others (and
    saturate where more of it says nothing new), each within the direction
    :data:`MONOTONE` allows it.

    Parameters
    ----------
    features : (n, len(FEATURES)) ndarray
        ``choice_features`` of the candidates.
    detected_only : bool
        The candidates are a detection's outlines alone, before the other
        cues' refinements: trees fitted on such pools judge them. Their
        consensus is among fewer and like-made candidates, and the trees of
        the whole pool, which never saw it so, are unsure of them.

    Returns
    -------
    probabilities : (n,) ndarray of float64
    """
    x = np.asarray(features, dtype=np.float64).reshape(-1, len(FEATURES))
    t = np.clip(tree_sum(x, trees_of(choice_model, "DETECTED_" if detected_only else "")), -50.0, 50.0)
    return 1.0 / (1.0 + np.exp(-t))


def choose(
    candidates: Sequence[Segmentation],
    detection_scores: Sequence[float],
    sources: Sequence[str] | None = None,
) -> tuple[int, float]:
    """Index of the candidate that outlines the rock, and the probability that it does
    (:func:`choose_ranked`, which also gives every candidate's probability)."""
    index, probabilities = choose_ranked(candidates, detection_scores, sources)
    return index, float(probabilities.max())


def choose_ranked(
    candidates: Sequence[Segmentation],
    detection_scores: Sequence[float],
    sources: Sequence[str] | None = None,
    *,
    detected_only: bool = False,
) -> tuple[int, NDArray[np.float64]]:
    """Index of the candidate that outlines the rock, and the probability that it does.

    The most probable candidate says which object the rock is. Of the
    candidates that outline the same object (IoU >= ``SAME_OBJECT`` with it),
    the detection's own outlines are preferred (placed between pixels, where
    the other cues cut on a reduced copy), and of those the one whose outline
    the photo supports best (segmentation score, a little for how clearly it
    was detected), so that a finer outline of the same rock is not lost to a
    coarser one.

    Parameters
    ----------
    candidates : sequence of Segmentation
    detection_scores : sequence of float
    sources : sequence of str, optional
        Where each candidate comes from (:data:`SOURCES`); "detected" for all
        when not given.
    detected_only : bool
        The candidates are a detection's outlines alone, judged by the trees
        fitted on such pools (:func:`choice_probabilities`).

    Returns
    -------
    index : int
    probabilities : (n,) ndarray of float64
        The choice model's probability that each candidate outlines the rock;
        the largest is the probability that the chosen candidate's object is
        the rock.
    """
    ranking = rank(candidates, detection_scores, sources, detected_only=detected_only)
    return ranking.index, ranking.probabilities


class Ranking(NamedTuple):
    """The choice among candidates (:func:`rank`).

    Attributes
    ----------
    index : int
        The candidate taken.
    probabilities : (n,) ndarray of float64
        The choice model's probability that each candidate outlines the rock.
    features : (n, len(FEATURES)) ndarray of float64
        Every candidate's choice features.
    ious : (n, n) ndarray of float64
        Intersection over union of every pair of candidates, on a common grid.
    """

    index: int
    probabilities: NDArray[np.float64]
    features: NDArray[np.float64]
    ious: NDArray[np.float64]


def rank(
    candidates: Sequence[Segmentation],
    detection_scores: Sequence[float],
    sources: Sequence[str] | None = None,
    *,
    detected_only: bool = False,
) -> Ranking:
    """:func:`choose_ranked`, with the features and mutual overlaps it was made from."""
    sources = _sources(sources, len(candidates))
    ious = _mutual_ious(candidates)
    features = _features(candidates, detection_scores, sources, ious)
    probabilities = choice_probabilities(features, detected_only=detected_only)
    best = _luminance_if_even(candidates, ious, probabilities, int(np.argmax(probabilities)))
    # The best is always among its own (a rock below the grid's cell has no IoU with itself).
    same = np.union1d(np.flatnonzero(ious[best] >= SAME_OBJECT), [best])
    if any(sources[k] == "detected" for k in same):
        same = np.array([k for k in same if sources[k] == "detected"])
    column = FEATURES.index("log_detection")
    support = [
        math.log(max(candidates[k].rocks[0].score, 1e-12)) + _DETECTION_WEIGHT * features[k, column]
        for k in same
    ]
    return Ranking(int(same[int(np.argmax(support))]), probabilities, features, ious)


#: Intersection over union from which two candidates outline the same object.
SAME_OBJECT = 0.95
#: Intersection over union from which a luminance outline and a chromaticity
#: outline are of the same object (the chromaticity outline may be ragged).
SAME_OBJECT_ACROSS_CHANNELS = 0.85
#: How many times a chromaticity outline's inside must spread more than a
#: luminance outline's of the same object for the luminance outline to be taken.
UNEVEN_INSIDE = 2.0


def _luminance_if_even(
    candidates: Sequence[Segmentation],
    ious: NDArray[np.float64],
    probabilities: NDArray[np.float64],
    best: int,
) -> int:
    """The best candidate, or for a chromaticity outline whose inside is uneven,
    the most probable luminance outline of the same object whose inside is even.

    Chromaticity divides colour by brightness: on a dark rock it is mostly
    noise (JPEG keeps colour at half resolution and coarse, too), so the rock
    is patchy in it and its outline ragged, while brightness may show the same
    rock evenly and crisply. Each outline's evidence is read in its own
    channel, and on the development photos a chromaticity outline is mostly
    the finer one (where the rock's shaded side blurs its brightness step), so
    the choice model prefers it; an inside that spreads ``UNEVEN_INSIDE`` times
    more than brightness's is the sign that it is the coarser one here. On
    the development photos 0-199 of each condition, 4 of 648 pairs of a
    chromaticity and a brightness outline of the rock are that uneven; the
    rule moves no held-out photo and one development photo of 960 the other
    way, and puts right the bundled three-faced render (a dark gray rock on
    greenish ground, a JPEG).
    """
    chosen = candidates[best]
    if chosen.channel != "chromaticity":
        return best
    spread = chosen.rocks[0].inner_spread
    even = [
        k
        for k, other in enumerate(candidates)
        if other.channel == "luminance"
        and ious[best, k] >= SAME_OBJECT_ACROSS_CHANNELS
        and spread > UNEVEN_INSIDE * other.rocks[0].inner_spread
    ]
    return max(even, key=lambda k: probabilities[k]) if even else best


#: Weight of the log detection score beside the log segmentation score among
#: outlines of the same object (a tenth of the detection score costs a quarter).
_DETECTION_WEIGHT = 0.125
