"""Fit the choice among candidate outlines (``rockscan.core.segment.choose``).

On the development part of the segmentation benchmark only (photos of one
rock and crops with neighbours, from :mod:`scenes`), every candidate outline
``rockscan.core.segment`` considers is measured (``choice_features``) and
compared with the truth (intersection over union). A logistic model with an
L2 penalty on standardised features learns which candidates have IoU >= 0.9;
its weights, mapped back to raw features, are printed for
``rockscan/core/segment/choose.py``.

Printed besides: the share of photos whose chosen candidate has IoU >= 0.9
under two-fold cross-validation (photos split at random, averaged over five
splits), the same for the
rule it replaces (segmentation score times detection score to the 1/8) and for
an oracle that always takes the best candidate (what candidate generation
allows).

    python scripts/fit_segment_choice.py -n 20 --jobs 2 --cache scene-cache
"""

from __future__ import annotations

import argparse
import pickle
import sys
from pathlib import Path

import numpy as np
from scipy.optimize import minimize

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_segment as bench
import scenes

from rockscan.core.errors import NoRockFoundError
from rockscan.core.segment.choose import SOURCES

CONDITIONS = [c for c, kind in scenes.CONDITION_KINDS.items() if kind != "all"]


def _measure(task: tuple[str, int]) -> tuple[str, np.ndarray, np.ndarray, np.ndarray]:
    """Features, IoU and the old rule's key of every candidate of one development photo."""
    from rockscan.core.segment import _candidate_pool, _choice_key
    from rockscan.core.segment.choose import FEATURES, choice_features
    from rockscan.core.segment.types import Segmentation, SegmentConfig

    condition, index = task
    pixels, truth, _ = bench.photo("dev", condition, index)
    empty = np.zeros((0, len(FEATURES))), np.zeros(0), np.zeros(0)
    try:
        pool = _candidate_pool(pixels, SegmentConfig(), fast=False)
    except NoRockFoundError:
        return (condition, *empty)
    pool = [(pool, 1.0, "detected")] if isinstance(pool, Segmentation) else pool.candidates + pool.refined()
    found, scores, sources = zip(*pool, strict=True)
    features = choice_features(found, scores, sources)
    ious = np.array([bench.iou(bench.segmentation_labels(f, truth.shape) == 1, truth == 1) for f in found])
    keys = np.array([_choice_key(f, s) for f, s, _ in pool])
    return condition, features, ious, keys


#: The sign each weight is held to (+1: at least 0, -1: at most 0, 0: free), so
#: that more evidence for an outline never counts against it.
SIGNS = {
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
    # How far each cue is trusted is for the data to say.
    **{f"from_{source}": 0 for source in SOURCES[1:]},
}


#: Random two-fold splits the cross-validated share is averaged over.
REPEATS = 5


def fit(features: list[np.ndarray], ious: list[np.ndarray], penalty: float) -> tuple[np.ndarray, float]:
    """Raw-feature weights and intercept of the penalised, sign-constrained logistic model."""
    from rockscan.core.segment.choose import FEATURES

    x = np.vstack(features)
    y = (np.concatenate(ious) >= 0.9).astype(np.float64)
    mu, sd = x.mean(axis=0), x.std(axis=0) + 1e-9
    z = (x - mu) / sd

    def loss(w: np.ndarray) -> tuple[float, np.ndarray]:
        t = z @ w[1:] + w[0]
        p = 1.0 / (1.0 + np.exp(-t))
        value = float(np.sum(np.logaddexp(0.0, t) - y * t) + penalty * np.sum(w[1:] ** 2))
        grad = np.concatenate([[np.sum(p - y)], z.T @ (p - y) + 2.0 * penalty * w[1:]])
        return value, grad

    bounds = [(None, None)] + [
        {1: (0.0, None), -1: (None, 0.0), 0: (None, None)}[SIGNS[name]] for name in FEATURES
    ]
    w = minimize(loss, np.zeros(z.shape[1] + 1), jac=True, method="L-BFGS-B", bounds=bounds).x
    weights = w[1:] / sd
    return weights, float(w[0] - np.sum(w[1:] * mu / sd))


def hits(
    features: list[np.ndarray], ious: list[np.ndarray], weights: np.ndarray, intercept: float
) -> np.ndarray:
    """Whether each photo's most probable candidate has IoU >= 0.9."""
    return np.array(
        [
            iou.size > 0 and iou[np.argmax(f @ weights + intercept)] >= 0.9
            for f, iou in zip(features, ious, strict=True)
        ]
    )


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("-n", type=int, default=20, help="development photos per condition")
    parser.add_argument("--penalty", type=float, default=1.0, help="L2 penalty on standardised weights")
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--cache", type=Path, help="keep generated photos in this folder between runs")
    parser.add_argument("--measured", type=Path, help="keep the measured candidates in this .pkl file")
    args = parser.parse_args()
    bench._CACHE_DIR = args.cache
    tasks = [(c, i) for c in CONDITIONS for i in range(args.n)]
    if args.measured is not None and args.measured.exists():
        results = pickle.loads(args.measured.read_bytes())
    elif args.jobs > 1:
        import multiprocessing

        with multiprocessing.get_context("spawn").Pool(
            args.jobs, initializer=_set_cache, initargs=(args.cache,)
        ) as pool:
            results = pool.map(_measure, tasks, chunksize=1)
    else:
        results = [_measure(t) for t in tasks]
    if args.measured is not None:
        args.measured.write_bytes(pickle.dumps(results))
    conditions = np.array([r[0] for r in results])
    features = [r[1] for r in results]
    ious = [r[2] for r in results]
    keys = [r[3] for r in results]
    old = np.array([k.size > 0 and iou[np.argmax(k)] >= 0.9 for k, iou in zip(keys, ious, strict=True)])
    oracle = np.array([iou.size > 0 and iou.max() >= 0.9 for iou in ious])
    # Two-fold cross-validation, repeated over REPEATS random splits of the photos.
    cross = np.zeros(len(results))
    for repeat in range(REPEATS):
        half = np.random.default_rng(repeat).permutation(len(results)) < len(results) // 2
        for train in (half, ~half):
            w, b = fit(
                [f for f, t in zip(features, train, strict=True) if t],
                [i for i, t in zip(ious, train, strict=True) if t],
                args.penalty,
            )
            test = ~train
            cross[test] += hits(
                [f for f, t in zip(features, test, strict=True) if t],
                [i for i, t in zip(ious, test, strict=True) if t],
                w,
                b,
            )
    cross /= REPEATS
    weights, intercept = fit(features, ious, args.penalty)
    print("| condition | old rule | fitted choice (2-fold) | oracle |")
    print("|---|---|---|---|")
    for c in [*CONDITIONS, None]:
        sel = np.ones(len(results), bool) if c is None else conditions == c
        name = "all" if c is None else c
        print(f"| {name} | {old[sel].mean():.1%} | {cross[sel].mean():.1%} | {oracle[sel].mean():.1%} |")
    from rockscan.core.segment.choose import FEATURES

    print("\nWEIGHTS = np.array([" + ", ".join(f"{v:.4g}" for v in weights) + "])")
    print(f"INTERCEPT = {intercept:.4g}")
    print("# " + ", ".join(FEATURES))


def _set_cache(cache: Path | None) -> None:
    bench._CACHE_DIR = cache


if __name__ == "__main__":
    main()
