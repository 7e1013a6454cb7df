"""Fit the trees that join pieces of one rock (``rockscan.core.segment.join``).

On development crowded scenes of the segmentation benchmark only (from
:mod:`scenes`; by default scenes 200-599, apart from scenes 0-199 on which
the rest of ``--all`` was tuned and on which this script checks the
result), each scene is segmented as ``segment(..., all_rocks=True)`` does
it, up to the join. Every pair of touching regions is measured
(``join.pair_features``) and labelled against the truth: one rock when
most of each region (``SHARE``) lies on one and the same true rock, two
rocks when most of each lies on two different ones; a pair with a region
mostly on the ground is left out.

Gradient-boosted trees (scikit-learn's ``HistGradientBoostingClassifier``;
a pair is less likely one rock the larger it is and the sharper the line
between them, and more likely the longer its contact: ``MONOTONE``) learn
the probability of one rock. Printed: the AUROC under two-fold
cross-validation (scenes split in halves), and on the check scenes, with
the trees fitted on all the fitting scenes, the counts of the benchmark
(exact counts, rocks one to one, merges, splits) of the regions the join
sees (before regions much smaller than the median are dropped), without
joining and at several least probabilities. ``--write`` puts the trees
into ``rockscan/core/segment/join_model.py``, which evaluates them with
numpy alone (checked here against scikit-learn's own predictions).

Needs scikit-learn besides rockscan (``pip install scikit-learn``)::

    python scripts/fit_segment_join.py --jobs 2 --cache scene-cache --write
"""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_segment as bench
import fitting
from fitting import measured, tree_arrays

from rockscan.core.errors import NoRockFoundError

#: A region is on a true rock (or the ground) when this share of it lies there.
SHARE = 0.6
#: Signs the trees keep for each feature (``join.FEATURES``): -1 decreasing, +1 increasing.
MONOTONE = {"union": -1, "smaller": -1, "contact": 1, "seam_sharpness": -1}
#: Least probabilities tried on the check scenes.
PROBABILITIES = (0.4, 0.5, 0.6, 0.7, 0.8)


def pair_labels(labels: np.ndarray, truth_work: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """1 for a pair on one true rock, 0 for two, -1 for a pair left out."""
    table = bench.overlap_table(labels, bench._dense(truth_work)).astype(np.float64)
    area = np.maximum(table.sum(axis=1), 1.0)
    rock = np.argmax(table[:, 1:], axis=1) + 1 if table.shape[1] > 1 else np.zeros(len(table), int)
    share = table[np.arange(len(table)), rock] / area
    out = np.full(len(pairs), -1, np.int64)
    for k, (a, b) in enumerate(pairs):
        if share[a] >= SHARE and share[b] >= SHARE:
            out[k] = int(rock[a] == rock[b])
    return out


def _measure(scene: int) -> dict | None:
    """One scene's touching pairs (features and labels), and what the
    join sees, so that the check can join at any probability."""
    from rockscan.core.segment import join, segment

    pixels, truth, _ = bench.photo("dev", "crowded", scene)
    seen = {}
    original = join.joined

    def recorded(labels, gray, probability=join.JOIN_PROBABILITY):
        seen["labels"], seen["gray"] = labels.copy(), gray.copy()
        return np.arange(int(labels.max()) + 1)

    join.joined = recorded
    try:
        seg = segment(pixels, all_rocks=True)
    except NoRockFoundError:
        return None
    finally:
        join.joined = original
    if "labels" not in seen:
        return None
    labels, gray = seen["labels"], seen["gray"]
    pairs, features = join.pair_features(labels, gray)
    truth_work = fitting.truth_on_grid(labels.shape, truth, seg.scale_rowcol)
    return {
        "scene": scene,
        "pairs": pairs,
        "features": features,
        "labels": pair_labels(labels, truth_work, pairs),
        "regions": labels,
        "gray": gray.astype(np.float32),
        "truth": truth_work,
    }


def fit(x: np.ndarray, y: np.ndarray, args):
    """The join's trees, fitted with scikit-learn."""
    from rockscan.core.segment.join import FEATURES

    return fitting.boosted_classifier(args, [MONOTONE.get(name, 0) for name in FEATURES]).fit(x, y)


def _stack(records: list[dict]) -> tuple[np.ndarray, np.ndarray]:
    x = np.vstack([r["features"] for r in records if len(r["pairs"])])
    y = np.concatenate([r["labels"] for r in records if len(r["pairs"])])
    keep = y >= 0
    return x[keep], y[keep]


def counted(records: list[dict], probability: float | None) -> str:
    """The benchmark's counts of the check scenes, joined at ``probability`` (None: not joined).

    Counted on the working grid against the truth sampled there, before
    specks are dropped; the benchmark counts the final regions at photo
    resolution."""
    from rockscan.core.segment import join

    scores = []
    for r in records:
        labels = r["regions"]
        if probability is not None:
            labels = join.joined(labels, r["gray"], probability)[labels]
        scores.append(bench.score_crowd(labels, r["truth"]))
    true = sum(s.n_true for s in scores)
    exact = sum(s.n_true == s.n_found for s in scores)
    one = sum(s.matched for s in scores) / max(true, 1)
    merges, splits = sum(s.merges for s in scores), sum(s.splits for s in scores)
    name = "not joined" if probability is None else f"joined from {probability:.2f}"
    return f"| {name} | {exact}/{len(scores)} | {one:.2%} | {merges} | {splits} |"


def write_model(arrays: dict, path: Path, summary: str) -> None:
    """Write the trees as a module of numpy arrays (``join_model``)."""
    fitting.write_trees(
        path,
        "The join model's trees (``join.join_probabilities``)",
        "scripts/fit_segment_join.py",
        summary,
        {"": arrays},
    )


def main() -> None:
    from sklearn.metrics import roc_auc_score

    parser = fitting.parser(__doc__, first=200)
    parser.set_defaults(n=400)
    parser.add_argument("--check", type=int, default=200, help="check scenes 0..CHECK-1 (default 200)")
    parser.add_argument("--trees", type=int, default=100, help="boosting rounds (default 100)")
    parser.add_argument("--depth", type=int, default=3, help="depth of each tree (default 3)")
    parser.add_argument("--rate", type=float, default=0.1, help="learning rate (default 0.1)")
    parser.add_argument("--write", action="store_true", help="write rockscan/core/segment/join_model.py")
    args = parser.parse_args()
    if args.first < args.check:
        parser.error("the fitting scenes must come after the check scenes")

    tasks = list(range(args.first, args.first + args.n)) + list(range(args.check))
    every = [r for r in measured(_measure, tasks, jobs=args.jobs, cache=args.cache, keep=args.measured) if r]
    fitting_part = [r for r in every if r["scene"] >= args.first]
    check = [r for r in every if r["scene"] < args.check]

    halves = [fitting_part[: len(fitting_part) // 2], fitting_part[len(fitting_part) // 2 :]]
    truths, predicted = [], []
    for train, test in (halves, halves[::-1]):
        model = fit(*_stack(train), args)
        x, y = _stack(test)
        truths.append(y)
        predicted.append(model.predict_proba(x)[:, 1])
    y, p = np.concatenate(truths), np.concatenate(predicted)
    x_all, y_all = _stack(fitting_part)
    lines = [
        f"Fitted on development crowded scenes {args.first}-{args.first + args.n - 1}: "
        f"{len(y_all)} touching pairs, {int(y_all.sum())} of one rock.",
        f"Two-fold cross-validated AUROC {roc_auc_score(y, p):.3f}.",
        "",
        f"Check scenes 0-{args.check - 1} (the regions the join sees, before specks are dropped;",
        "counted on the working grid):",
        "",
        "| join | exact counts | one to one | merges | splits |",
        "|---|---|---|---|---|",
    ]
    print("\n".join(lines), flush=True)

    model = fit(x_all, y_all, args)
    arrays = tree_arrays(model)
    path = Path(__file__).resolve().parents[1] / "rockscan" / "core" / "segment" / "join_model.py"
    previous = path.read_text()
    write_model(arrays, path, "\n".join(lines))
    from rockscan.core.segment import join, join_model

    importlib.reload(join_model)
    ours = join.join_probabilities(x_all)
    theirs = model.predict_proba(x_all)[:, 1]
    if not np.allclose(ours, theirs, atol=1e-9):
        path.write_text(previous)
        raise SystemExit(f"trees differ from scikit-learn's by {np.abs(ours - theirs).max():.2e}")
    rows = [counted(check, None)] + [counted(check, q) for q in PROBABILITIES]
    print("\n".join(rows))
    if args.write:
        write_model(arrays, path, "\n".join(lines + rows))
        print(f"wrote {path}")
    else:
        path.write_text(previous)
        importlib.reload(join_model)


if __name__ == "__main__":
    main()
