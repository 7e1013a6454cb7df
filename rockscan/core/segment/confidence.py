"""How sure a choice among candidate outlines is: the chosen rock's segmentation score.

The choice model (``rockscan.core.segment.choose``) judges each candidate
alone, and its largest probability ranks the candidates of one photo well;
as a score across photos it is too sure of a photo where another object
was about as probable, and too unsure of one where many candidates agree
on a modestly supported outline. So when the choice was made among the whole
pool (not at the fast path, nor among the detected candidates alone, whose
scores stand), the chosen rock's score is a logistic function of what the
choice saw, over the whole photo:

* the largest probability (its log-odds);
* the largest probability of a candidate of another object (IoU < 0.5 with
  the chosen one): a rival;
* the mean probability of the candidates that agree with the chosen one
  (IoU >= 0.8, itself included), and how many they are, of how many in all;
* the largest probability among the detection's own outlines alone, before
  the refinements;
* the chosen candidate's own features (``choose.FEATURES``, up to its
  channel);
* how far one notch dominates the outline taken (``stats.notch``): the
  share of its convex hull that its largest gap covers, less the second
  largest's. Of two outlines the photo supports alike, one that took
  something in or left a bite out has one deep notch and is more often
  wrong; a star's arms leave alike gaps all round and a solid rock none,
  so neither shape counts against its outline;
* what the offset step's trees (``rockscan.core.segment.offset``) read
  across the outline before it moved and after: the mean distance they
  still put between the final outline and the rock's edge, how much less
  that is than before the move, and how far out the move took the outline
  in their eyes (the mean signed offset before, less after). Trees that
  agree with the outline they moved are evidence for it; an outline they
  would still move is more often wrong.

The weights are fitted (``scripts/fit_segment_confidence.py``) on
development photos the choice model never saw, so that the score is the
probability that the outline is right (IoU >= 0.9), each held to the
direction :data:`SIGNS` gives it: the photos are of one generator, and on a
real photo more evidence for an outline must never count against it.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from rockscan.core.segment.choose import FEATURES, MONOTONE, Ranking
from rockscan.core.segment.stats import logistic, logit

__all__ = [
    "CHOICE_COUNT",
    "CONFIDENCE_FEATURES",
    "SIGNS",
    "confidence_features",
    "offset_evidence",
    "outline_confidence",
]

#: The chosen candidate's features the score reads: ``choose.FEATURES`` up to its channel.
_OWN = FEATURES[: FEATURES.index("chromaticity") + 1]

#: Names of the columns of :func:`confidence_features`.
CONFIDENCE_FEATURES = (
    "logit_best",
    "logit_rival",
    "logit_agreeing",
    "agreeing",
    "candidates",
    "logit_detected_best",
    *(f"own_{name}" for name in _OWN),
    "notch",
    "offset_left",
    "offset_settled",
    "offset_out",
)

#: How many of :data:`CONFIDENCE_FEATURES` the choice gives (:func:`confidence_features`);
#: the rest are the offset step's (:func:`offset_evidence`).
CHOICE_COUNT = len(CONFIDENCE_FEATURES) - 3

#: The direction in which the score may move with each feature (+1: never
#: down as it grows, -1: never up, 0: free): a surer choice, a less probable
#: rival object and more agreement never count against an outline, nor does
#: more evidence for it (``choose.MONOTONE``). The fit is held to them.
SIGNS = {
    "logit_best": 1,
    "logit_rival": -1,
    "logit_agreeing": 1,
    "agreeing": 1,
    "candidates": 0,
    "logit_detected_best": 0,
    **{f"own_{name}": MONOTONE[name] for name in _OWN},
    "notch": -1,
    "offset_left": -1,
    "offset_settled": 1,
    "offset_out": 0,
}

#: Overlap below which a candidate outlines another object than the chosen one,
#: and from which it agrees with it.
RIVAL_IOU = 0.5
AGREE_IOU = 0.8

#: Logistic weights of :data:`CONFIDENCE_FEATURES` and the intercept, fitted by
#: ``scripts/fit_segment_confidence.py --write`` (between the markers).
# BEGIN FITTED
WEIGHTS = np.array(
    [
        0.740569,  # logit_best
        -0.0660953,  # logit_rival
        0.0571903,  # logit_agreeing
        0.0556589,  # agreeing
        -0.0604743,  # candidates
        -0.157649,  # logit_detected_best
        0,  # own_logit_score
        1.82495,  # own_support
        1.11746,  # own_weak
        0,  # own_outside
        0,  # own_noise
        0,  # own_frame
        0,  # own_log_detection
        -1.2824,  # own_centre_distance
        0,  # own_covers_centre
        0.111291,  # own_log_area
        0,  # own_consensus
        0,  # own_pebbles
        1.5151,  # own_chromaticity
        -36.2036,  # notch
        -1.55341,  # offset_left
        2.25162,  # offset_settled
        1.58582,  # offset_out
    ]
)
INTERCEPT = 0.499276
# END FITTED


def confidence_features(ranking: Ranking, detected_best: float, notch: float) -> NDArray[np.float64]:
    """The score's features of a choice among the whole pool (module
    docstring), up to the offset step's (:func:`offset_evidence`).

    Parameters
    ----------
    ranking : Ranking
        The choice among the whole pool (``choose.rank``).
    detected_best : float
        The largest probability among the detection's own outlines, judged alone.
    notch : float
        How far one notch dominates the outline taken (``stats.notch``).

    Returns
    -------
    features : (CHOICE_COUNT,) ndarray of float64
    """
    p = np.asarray(ranking.probabilities, dtype=np.float64)
    overlap = np.asarray(ranking.ious[ranking.index], dtype=np.float64)
    rivals = overlap < RIVAL_IOU
    agreeing = overlap >= AGREE_IOU
    agreeing[ranking.index] = True
    own = ranking.features[ranking.index, : len(_OWN)]
    return np.array(
        [
            logit(p.max()),
            logit(p[rivals].max() if rivals.any() else 0.0),
            logit(p[agreeing].mean()),
            float(agreeing.sum()),
            float(p.size),
            logit(detected_best),
            *own,
            float(notch),
        ]
    )


def offset_evidence(
    before: NDArray[np.floating] | None, after: NDArray[np.floating] | None
) -> NDArray[np.float64]:
    """The score's features of the offset step (module docstring).

    Parameters
    ----------
    before, after : 1-D ndarray of float or None
        The offsets the trees read on the rays across the outline before the
        step moved it and after (``offset.OffsetsRead.on_usable``, pixels of
        the grid); None where they could not be read. An outline that did
        not move is read once, and given as both.

    Returns
    -------
    evidence : (len(CONFIDENCE_FEATURES) - CHOICE_COUNT,) ndarray of float64
        ``offset_left``, ``offset_settled``, ``offset_out``; all 0 where
        nothing was read, and when only ``before`` was, it stands for ``after``.
    """
    if before is None or np.size(before) == 0:
        return np.zeros(len(CONFIDENCE_FEATURES) - CHOICE_COUNT)
    before = np.asarray(before, dtype=np.float64)
    after = before if after is None or np.size(after) == 0 else np.asarray(after, dtype=np.float64)
    left = float(np.mean(np.abs(after)))
    return np.array([left, float(np.mean(np.abs(before))) - left, float(np.mean(before) - np.mean(after))])


def outline_confidence(features: NDArray[np.float64]) -> float:
    """The probability, in [0, 1], that the chosen outline is right (IoU >= 0.9 with the rock).

    Parameters
    ----------
    features : (len(CONFIDENCE_FEATURES),) ndarray
        :func:`confidence_features` of the choice followed by
        :func:`offset_evidence` of the outline.
    """
    return logistic(float(INTERCEPT + WEIGHTS @ np.asarray(features, dtype=np.float64)))
