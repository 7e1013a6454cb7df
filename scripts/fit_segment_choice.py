"""Fit the choice among candidate outlines (``rockscan.core.segment.choose``).

On the development part of the segmentation benchmark only (photos of one
rock and crops with neighbours, from :mod:`scenes`), every candidate outline
``rockscan.core.segment`` considers is measured (``choice_features``) and
compared with the truth (intersection over union). Two models learn which
candidates have IoU >= 0.9:

* **trees** (what rockscan uses): gradient-boosted regression trees
  (scikit-learn's ``HistGradientBoostingClassifier``, depth ``--depth``,
  ``--trees`` rounds), each evidence feature held monotone in the direction
  :data:`SIGNS` gives unless ``--free``; with ``--write`` its trees are
  written to ``rockscan/core/segment/choice_model.py``, which evaluates them
  with numpy alone (checked here against scikit-learn's own predictions);
* **linear**, the baseline it replaced: a logistic model with an L2 penalty on
  standardised features and the same signs.

The trees are fitted twice: on the whole pool of each photo, and on its
detected candidates alone (their features measured among themselves), which
is all the choice sees before the refinements; both are written, the second
as ``DETECTED_`` arrays.

Printed: the share of photos whose chosen candidate has IoU >= 0.9 under
two-fold cross-validation (photos split at random, averaged over five
splits) for both, beside the rule before any model (segmentation score times
detection score to the 1/8) and an oracle that always takes the best
candidate (what candidate generation allows); and for the choice as
``segment`` makes it (the detected candidates' trees first, the whole pool's
when they are not sure), its share right and the share of photos on which
it stops before the refinements.

Needs scikit-learn besides rockscan (``pip install scikit-learn``)::

    python scripts/fit_segment_choice.py --jobs 2 --cache scene-cache --write
"""

from __future__ import annotations

import importlib
import sys
import textwrap
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_segment as bench
import fitting
import scenes
from fitting import measured, set_cache, signed_logistic, tree_arrays

from rockscan.core.errors import NoRockFoundError
from rockscan.core.segment import FAST_PROBABILITY
from rockscan.core.segment.choose import MONOTONE

CONDITIONS = [c for c, kind in scenes.CONDITION_KINDS.items() if kind != "all"]


def _measure(task: tuple[str, int]) -> tuple[str, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Features, IoU and the old rule's key of every candidate of one development photo, and the
    features of its detected candidates (the first) measured among themselves."""
    from rockscan.core.segment import _candidate_pool, _choice_key
    from rockscan.core.segment.choose import FEATURES, choice_features
    from rockscan.core.segment.types import Segmentation, SegmentConfig

    condition, index = task
    pixels, truth, _ = bench.photo("dev", condition, index)
    empty = np.zeros((0, len(FEATURES)))
    try:
        pool = _candidate_pool(pixels, SegmentConfig(), fast=False)
    except NoRockFoundError:
        return condition, empty, np.zeros(0), np.zeros(0), empty
    if isinstance(pool, Segmentation):
        pool, detected = [(pool, 1.0, "detected")], 1
    else:
        detected = len(pool.candidates)
        pool = pool.candidates + pool.refined()
    found, scores, sources = zip(*pool, strict=True)
    features = choice_features(found, scores, sources)
    ious = np.array([bench.iou(bench.segmentation_labels(f, truth.shape) == 1, truth == 1) for f in found])
    keys = np.array([_choice_key(f, s) for f, s, _ in pool])
    # The detected candidates come first; alone, they are what the early choice sees.
    early = choice_features(found[:detected], scores[:detected], sources[:detected])
    return condition, features, ious, keys, early


#: The direction each feature is held to (``choose.MONOTONE``).
SIGNS = MONOTONE


#: Random two-fold splits the cross-validated share is averaged over.
REPEATS = 5


def fit(features: list[np.ndarray], ious: list[np.ndarray], penalty: float) -> tuple[np.ndarray, float]:
    """Raw-feature weights and intercept of the penalised, sign-constrained logistic model."""
    from rockscan.core.segment.choose import FEATURES

    y = np.concatenate(ious) >= 0.9
    return signed_logistic(np.vstack(features), y, penalty, [SIGNS[name] for name in FEATURES])


def hits(features: list[np.ndarray], ious: list[np.ndarray], rank) -> np.ndarray:
    """Whether each photo's highest-ranked candidate (``rank(features)``) has IoU >= 0.9."""
    return np.array(
        [iou.size > 0 and iou[np.argmax(rank(f))] >= 0.9 for f, iou in zip(features, ious, strict=True)]
    )


def fit_trees(features: list[np.ndarray], ious: list[np.ndarray], args, seed: int = 0):
    """The gradient-boosted trees of the choice, fitted with scikit-learn."""
    from rockscan.core.segment.choose import FEATURES

    x = np.vstack(features)
    y = np.concatenate(ious) >= 0.9
    monotone = [0 if args.free else SIGNS[name] for name in FEATURES]
    return fitting.boosted_classifier(args, monotone, seed).fit(x, y)


def write_model(arrays: dict, detected_arrays: dict, path: Path, summary: str) -> None:
    """Write both models' trees as a module of numpy arrays (``choice_model``): the whole
    pool's, and those of the detected candidates alone under the prefix ``DETECTED_``."""
    fitting.write_trees(
        path,
        "The choice model's trees (``choose.choice_probabilities``)",
        "scripts/fit_segment_choice.py",
        summary,
        {"": arrays, "DETECTED_": detected_arrays},
    )


def _measured(args) -> list:
    """Every development photo's candidates, measured (or read back from ``--measured``)."""
    tasks = [(c, i) for c in CONDITIONS for i in range(args.first, args.first + args.n)]
    return measured(_measure, tasks, jobs=args.jobs, cache=args.cache, keep=args.measured)


def cross_validated(features: list[np.ndarray], ious: list[np.ndarray], fit_rank) -> np.ndarray:
    """Each photo's share of splits in which the model fitted on the other half chose right.

    Two-fold, over REPEATS random splits of the photos; ``fit_rank(features,
    ious, seed)`` fits a model and returns its ranking function.
    """
    n = len(features)
    cross = np.zeros(n)
    for repeat in range(REPEATS):
        half = np.random.default_rng(repeat).permutation(n) < n // 2
        for train in (half, ~half):
            rank = fit_rank(
                [f for f, t in zip(features, train, strict=True) if t],
                [i for i, t in zip(ious, train, strict=True) if t],
                repeat,
            )
            test = ~train
            cross[test] += hits(
                [f for f, t in zip(features, test, strict=True) if t],
                [i for i, t in zip(ious, test, strict=True) if t],
                rank,
            )
    return cross / REPEATS


def staged_cross_validated(
    features: list[np.ndarray],
    ious: list[np.ndarray],
    early: list[np.ndarray],
    early_ious: list[np.ndarray],
    args,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each photo's share of splits in which the choice as ``segment`` makes it was right,
    in which it stopped before the refinements, and in which it stopped and was right.

    Both models are fitted on one half of the photos: the trees of the detected
    candidates alone, and those of the whole pool. On the other half, a photo
    whose most probable detected candidate reaches ``FAST_PROBABILITY`` keeps
    it; any other photo takes the whole pool's most probable candidate.
    """
    n = len(features)
    right, stopped, stopped_right = np.zeros(n), np.zeros(n), np.zeros(n)
    for repeat in range(REPEATS):
        half = np.random.default_rng(repeat).permutation(n) < n // 2
        for train in (half, ~half):
            rows = np.flatnonzero(train)
            whole = fit_trees([features[k] for k in rows], [ious[k] for k in rows], args, repeat)
            first = fit_trees([early[k] for k in rows], [early_ious[k] for k in rows], args, repeat)
            for k in np.flatnonzero(~train):
                if ious[k].size == 0:
                    continue
                p = first.predict_proba(early[k])[:, 1]
                if p.max() >= FAST_PROBABILITY:
                    stopped[k] += 1
                    stopped_right[k] += early_ious[k][np.argmax(p)] >= 0.9
                    right[k] += early_ious[k][np.argmax(p)] >= 0.9
                else:
                    right[k] += ious[k][np.argmax(whole.predict_proba(features[k])[:, 1])] >= 0.9
    return right / REPEATS, stopped / REPEATS, stopped_right / REPEATS


def main() -> None:
    parser = fitting.parser(__doc__, first=0)
    parser.add_argument("--trees", type=int, default=200, help="boosting rounds (default 200)")
    parser.add_argument("--depth", type=int, default=4, help="depth of each tree (default 4)")
    parser.add_argument("--rate", type=float, default=0.1, help="learning rate (default 0.1)")
    parser.add_argument("--free", action="store_true", help="no monotone constraints on the trees")
    parser.add_argument("--penalty", type=float, default=1.0, help="the linear baseline's L2 penalty")
    parser.add_argument("--write", action="store_true", help="write the trees to choice_model.py")
    args = parser.parse_args()
    set_cache(args.cache)
    results = _measured(args)
    conditions = np.array([r[0] for r in results])
    features = [r[1] for r in results]
    ious = [r[2] for r in results]
    keys = [r[3] for r in results]
    # The detected candidates of each photo (the first of its pool) and their features among themselves.
    early = [r[4] for r in results]
    early_ious = [i[: len(e)] for i, e in zip(ious, early, strict=True)]
    old = np.array([k.size > 0 and iou[np.argmax(k)] >= 0.9 for k, iou in zip(keys, ious, strict=True)])
    oracle = np.array([iou.size > 0 and iou.max() >= 0.9 for iou in ious])

    def linear(f, i, seed):
        w, b = fit(f, i, args.penalty)
        return lambda x: x @ w + b

    def trees(f, i, seed):
        return fit_trees(f, i, args, seed).decision_function

    columns = {"old rule": old, "linear (2-fold)": cross_validated(features, ious, linear)}
    columns["trees (2-fold)"] = cross_validated(features, ious, trees)
    staged, stopped, stopped_right = staged_cross_validated(features, ious, early, early_ious, args)
    columns["trees, early stop (2-fold)"] = staged
    columns["early stops (2-fold)"] = stopped
    columns["oracle"] = oracle
    print("| condition | photos | " + " | ".join(columns) + " |")
    print("|---|---|" + "---|" * len(columns))
    for c in [*CONDITIONS, None]:
        sel = np.ones(len(results), bool) if c is None else conditions == c
        cells = " | ".join(f"{v[sel].mean():.1%}" for v in columns.values())
        print(f"| {'all' if c is None else c} | {int(sel.sum())} | {cells} |")
    print(
        f"\nearly stops: {stopped.mean():.1%} of photos (probability >= {FAST_PROBABILITY}), "
        f"right on {stopped_right.sum() / max(stopped.sum(), 1e-9):.1%} of them"
    )
    if args.write:
        model = fit_trees(features, ious, args)
        arrays = tree_arrays(model)
        early_model = fit_trees(early, early_ious, args)
        early_arrays = tree_arrays(early_model)
        from rockscan.core.segment import choice_model

        choose = importlib.import_module("rockscan.core.segment.choose")

        summary = (
            f"{len(arrays['ROOTS'])} trees of depth {arrays['DEPTH']} (learning rate {args.rate}"
            f"{', no monotone constraints' if args.free else ', evidence monotone'}), fitted on "
            f"{len(results)} development photos, {sum(len(i) for i in ious)} candidates; "
            f"cross-validated choice {columns['trees (2-fold)'].mean():.1%} (linear "
            f"{columns['linear (2-fold)'].mean():.1%}, oracle {oracle.mean():.1%}). "
            f"The DETECTED_ trees, as many and as deep, are fitted on the same photos' "
            f"{sum(len(i) for i in early_ious)} detected candidates alone: with them the choice "
            f"stops before the refinements on {stopped.mean():.1%} of the photos "
            f"(cross-validated), right on {stopped_right.sum() / max(stopped.sum(), 1e-9):.1%} "
            f"of them, and chooses right on {staged.mean():.1%} in all."
        )
        path = Path(choice_model.__file__)
        write_model(arrays, early_arrays, path, textwrap.fill(summary, 76))
        importlib.reload(choice_model)
        importlib.reload(choose)
        for name, x, fitted, detected_only in (
            ("trees", np.vstack(features), model, False),
            ("DETECTED_ trees", np.vstack(early), early_model, True),
        ):
            ours = choose.choice_probabilities(x, detected_only=detected_only)
            theirs = fitted.predict_proba(x)[:, 1]
            gap = np.abs(ours - theirs).max()
            print(f"wrote {name} to {path}; largest difference from scikit-learn: {gap:.2e}")


if __name__ == "__main__":
    main()
