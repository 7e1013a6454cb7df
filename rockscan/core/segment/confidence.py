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
  so neither shape counts against its outline.

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

__all__ = ["CONFIDENCE_FEATURES", "SIGNS", "confidence_features", "outline_confidence"]

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
)

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
        0.498942,  # logit_best
        -0.0735086,  # logit_rival
        0.160471,  # logit_agreeing
        0.0557198,  # agreeing
        -0.0824567,  # candidates
        -0.0935413,  # logit_detected_best
        0,  # own_logit_score
        0,  # own_support
        -0.976188,  # own_weak
        0,  # own_outside
        0,  # own_noise
        0,  # own_frame
        0,  # own_log_detection
        0,  # own_centre_distance
        0,  # own_covers_centre
        0.373956,  # own_log_area
        0,  # own_consensus
        0,  # own_pebbles
        1.259,  # own_chromaticity
        -30.4092,  # notch
    ]
)
INTERCEPT = 1.75193
# END FITTED


def confidence_features(ranking: Ranking, detected_best: float, notch: float) -> NDArray[np.float64]:
    """The score's features of a choice among the whole pool (module docstring).

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
    features : (len(CONFIDENCE_FEATURES),) ndarray of float64
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


def outline_confidence(features: NDArray[np.float64]) -> float:
    """The probability, in [0, 1], that the chosen outline is right (IoU >= 0.9 with the rock).

    Parameters
    ----------
    features : (len(CONFIDENCE_FEATURES),) ndarray
        :func:`confidence_features` of the choice.
    """
    return logistic(float(INTERCEPT + WEIGHTS @ np.asarray(features, dtype=np.float64)))
