"""Fit the score of a rock chosen among the whole pool of candidate outlines
(``rockscan.core.segment.confidence``).

On development photos of the segmentation benchmark that the choice model
was never fitted on (by default photos 200-399 of each one-rock condition;
the choice model's are 0-199, ``scripts/fit_segment_choice.py``), each photo
is segmented as ``segment`` does it. Where the choice was made among the
whole pool, the features of that choice (``confidence_features``) and of
the offset step (``offset_evidence``) are kept beside whether the final
outline is right (IoU >= 0.9 against the truth).
A logistic model with an L2 penalty (``--penalty``, on standardised
features), each weight held to the direction ``confidence.SIGNS`` gives it,
learns it; ``--write`` puts its weights into
``rockscan/core/segment/confidence.py``.

Printed: under two-fold cross-validation (even and odd photos), the AUROC of
the segmentation score over all the photos (IoU >= 0.9 against < 0.8), over
those the whole pool decided, and at the 0.5 a rock needs to be
interesting, how many wrong outlines (IoU < 0.8) are trusted and right ones
refused; beside the same for the choice model's largest probability, the
score before.

::

    python scripts/fit_segment_confidence.py --jobs 2 --cache scene-cache --write
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_segment as bench
import fitting
import scenes
from fitting import measured, signed_logistic

from rockscan.core.errors import NoRockFoundError

CONDITIONS = [c for c, kind in scenes.CONDITION_KINDS.items() if kind != "all"]


def _measure(task: tuple[str, int]) -> tuple[str, int, float, float, np.ndarray | None]:
    """Condition, index, the final outline's IoU, its score before, and the
    choice's confidence features (None when the whole pool did not decide)."""
    from rockscan.core.segment import _chosen
    from rockscan.core.segment.finish import completed
    from rockscan.core.segment.types import SegmentConfig

    condition, index = task
    pixels, truth, _ = bench.photo("dev", condition, index)
    try:
        found, choice, easy = _chosen(pixels, SegmentConfig())
    except NoRockFoundError:
        return condition, index, 0.0, 0.0, None
    final, features = completed(found, choice, pixels, easy=easy)
    iou = bench.iou(bench.segmentation_labels(final, truth.shape) == 1, truth == 1)
    # Before: the choice model's largest probability, the first feature's log-odds.
    before = final.rocks[0].score if features is None else 1.0 / (1.0 + np.exp(-features[0]))
    return condition, index, iou, float(before), features


def _measured(args) -> list:
    tasks = [(c, i) for c in CONDITIONS for i in range(args.first, args.first + args.n)]
    return measured(_measure, tasks, jobs=args.jobs, cache=args.cache, keep=args.measured, chunksize=4)


def fit(x: np.ndarray, y: np.ndarray, penalty: float) -> tuple[np.ndarray, float]:
    """Raw-feature weights and intercept of the penalised logistic model, each
    weight held to its direction in ``confidence.SIGNS``."""
    from rockscan.core.segment.confidence import CONFIDENCE_FEATURES, SIGNS

    return signed_logistic(x, y, penalty, [SIGNS[name] for name in CONFIDENCE_FEATURES])


def predict(model: tuple[np.ndarray, float], x: np.ndarray) -> np.ndarray:
    weights, intercept = model
    return 1.0 / (1.0 + np.exp(-np.clip(x @ weights + intercept, -50.0, 50.0)))


def judged(ious: np.ndarray, scores: np.ndarray) -> tuple[float, int, int]:
    """AUROC (IoU >= 0.9 against < 0.8), wrong outlines trusted and right ones refused at 0.5."""
    from scipy.stats import rankdata

    right, wrong = ious >= 0.9, ious < 0.8
    ranks = rankdata(scores[right | wrong])
    n_right, n_wrong = int(right.sum()), int(wrong.sum())
    auroc = (ranks[right[right | wrong]].sum() - n_right * (n_right + 1) / 2) / max(n_right * n_wrong, 1)
    return float(auroc), int(((scores >= 0.5) & wrong).sum()), int(((scores < 0.5) & right).sum())


def write(model: tuple[np.ndarray, float], path: Path) -> None:
    """Put the fitted weights between the markers of ``confidence.py``."""
    from rockscan.core.segment.confidence import CONFIDENCE_FEATURES

    weights, intercept = model
    rows = "".join(
        f"        {w:.6g},  # {name}\n" for w, name in zip(weights, CONFIDENCE_FEATURES, strict=True)
    )
    block = (
        f"# BEGIN FITTED\nWEIGHTS = np.array(\n    [\n{rows}    ]\n)\n"
        f"INTERCEPT = {intercept:.6g}\n# END FITTED"
    )
    text = path.read_text()
    path.write_text(re.sub(r"# BEGIN FITTED\n.*?# END FITTED", lambda _: block, text, flags=re.S))


def main() -> None:
    parser = fitting.parser(__doc__, first=200)
    parser.add_argument("--penalty", type=float, default=1.0, help="L2 penalty (default 1.0)")
    parser.add_argument("--write", action="store_true", help="write the weights to confidence.py")
    args = parser.parse_args()
    results = _measured(args)
    ious = np.array([r[2] for r in results])
    before = np.array([r[3] for r in results])
    index = np.array([r[1] for r in results])
    pooled = np.array([r[4] is not None for r in results])
    x = np.array(
        [r[4] if r[4] is not None else np.zeros_like(results[np.argmax(pooled)][4]) for r in results]
    )
    after = before.copy()
    for fold in (0, 1):
        test = index % 2 == fold
        model = fit(x[pooled & ~test], ious[pooled & ~test] >= 0.9, args.penalty)
        at = pooled & test
        after[at] = predict(model, x[at])
    print(f"{len(results)} development photos, {int(pooled.sum())} decided by the whole pool")
    print("| score | AUROC, all | AUROC, whole pool | wrong trusted | right refused |")
    print("|---|---|---|---|---|")
    for name, scores in (("the choice's largest probability", before), ("fitted (2-fold)", after)):
        auroc, trusted, refused = judged(ious, scores)
        pool_auroc, _, _ = judged(ious[pooled], scores[pooled])
        print(f"| {name} | {auroc:.3f} | {pool_auroc:.3f} | {trusted} | {refused} |")
    if args.write:
        from rockscan.core.segment import confidence

        model = fit(x[pooled], ious[pooled] >= 0.9, args.penalty)
        write(model, Path(confidence.__file__))
        print(f"wrote the weights to {confidence.__file__}")


if __name__ == "__main__":
    main()
