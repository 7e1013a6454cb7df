"""Fit the offsets that move an outline to the rock's edge
(``rockscan.core.segment.offset``).

On the development part of the segmentation benchmark only (photos of one
rock and crops with neighbours, from :mod:`scenes`; by default photos 0-199
of each condition, those the choice model is fitted on), each photo is
segmented as ``segment`` does it, up to the last step, the offsets. Only
photos whose rock was chosen among the whole pool of candidates are kept:
the step runs on no other (not on the fast path, nor where the detection's
own outlines made the choice sure). Along every
other ray of ``offset.RAYS`` across the outline, the step's features
(``offset_features``) are kept beside where the truth's edge lies on that
ray, from the outline, in pixels of the working grid (the truth's mask read
between its pixels at the ray's points, its last crossing of 0.5).

Gradient-boosted regression trees (scikit-learn's
``HistGradientBoostingRegressor``, absolute loss, so that they give the
median and a ray that crosses a neighbour or a shadow, metres off, counts no
more than one a pixel off; targets clipped to ``--clip`` pixels) learn the
offset. Printed: under two-fold cross-validation (photos split at random),
the mean absolute offset of the rays before and after, the share within half
a pixel, and the same over the rays the step moves (a predicted offset of at
least ``offset.MIN_MOVE``). ``--write`` puts the trees into
``rockscan/core/segment/offset_model.py``, which evaluates them with numpy
alone (checked here against scikit-learn's own predictions).

Needs scikit-learn besides rockscan (``pip install scikit-learn``)::

    python scripts/fit_segment_offset.py --jobs 2 --cache scene-cache --write
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
from fitting import measured, tree_arrays

from rockscan.core.errors import NoRockFoundError

CONDITIONS = [c for c, kind in scenes.CONDITION_KINDS.items() if kind != "all"]


def truth_offsets(
    truth: np.ndarray,
    rays,
    window: tuple[int, int, int, int],
    scale_rowcol: tuple[float, float],
) -> tuple[np.ndarray, np.ndarray]:
    """Where the truth's edge lies on each ray, from the outline's crossing
    (pixels of the grid, outward positive), and whether the ray crosses it.

    The rays' points are taken from the window of the working grid to the
    photo (a working pixel ``i`` covers photo pixels ``[i*scale, (i+1)*scale)``)
    and the truth's mask is read there between its pixels."""
    import cv2

    from rockscan.core.segment.snap import SPACING, last_crossing

    across = rays.across
    r0, _, c0, _ = window
    photo_rows = ((across.map_y + r0 + 0.5) * scale_rowcol[0] - 0.5).astype(np.float32)
    photo_cols = ((across.map_x + c0 + 0.5) * scale_rowcol[1] - 0.5).astype(np.float32)
    cover = cv2.remap(
        truth.astype(np.float32), photo_cols, photo_rows, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT
    )
    at, seen = last_crossing(cover)
    return (at - across.at) * SPACING, seen


def _measure(task: tuple[str, int]) -> dict | None:
    """One development photo's rays: features, truth offsets and which rays count; None
    when no rock is found or the step would not run on it."""
    from rockscan.core.segment import _chosen
    from rockscan.core.segment.finish import finished, offset_inputs
    from rockscan.core.segment.offset import offset_features
    from rockscan.core.segment.types import SegmentConfig

    condition, index = task
    pixels, truth, _ = bench.photo("dev", condition, index)
    try:
        found, choice, easy = _chosen(pixels, SegmentConfig())
    except NoRockFoundError:
        return None
    if choice is None or found.channel == "alpha":
        return None
    found = finished(found, pixels, full=not easy)
    inputs = offset_inputs(found, pixels)
    if inputs is None:
        return None
    window, gray, coverage, levels = inputs
    rays = offset_features(gray, coverage, levels, 0.5 * (found.scale_rowcol[0] + found.scale_rowcol[1]))
    if rays is None:
        return None
    target, seen = truth_offsets(truth == 1, rays, window, found.scale_rowcol)
    # Every other ray: neighbours a degree apart say nearly the same.
    every = slice(None, None, 2)
    return {
        "condition": condition,
        "index": index,
        "features": rays.features[every].astype(np.float64),
        "target": target[every],
        "usable": (rays.usable & seen)[every],
    }


def fit(x: np.ndarray, y: np.ndarray, args):
    from sklearn.ensemble import HistGradientBoostingRegressor

    model = HistGradientBoostingRegressor(
        loss="absolute_error",
        max_depth=args.depth,
        max_iter=args.trees,
        learning_rate=args.rate,
        early_stopping=False,
        random_state=0,
    )
    return model.fit(x, y)


def summary_row(name: str, target: np.ndarray, predicted: np.ndarray, least: float) -> str:
    moved = np.abs(predicted) >= least
    cells = [
        f"{np.abs(target).mean():.3f} -> {np.abs(target - predicted).mean():.3f}",
        f"{(np.abs(target) < 0.5).mean():.1%} -> {(np.abs(target - predicted) < 0.5).mean():.1%}",
        f"{moved.mean():.1%}",
        f"{np.abs(target[moved]).mean():.3f} -> {np.abs(target[moved] - predicted[moved]).mean():.3f}"
        if moved.any()
        else "-",
    ]
    return f"| {name} | " + " | ".join(cells) + " |"


def write_model(arrays: dict, path: Path, summary: str) -> None:
    """Write the trees as a module of numpy arrays (``offset_model``)."""
    fitting.write_trees(
        path,
        "The offset model's trees (``offset.predicted_offsets``)",
        "scripts/fit_segment_offset.py",
        summary,
        {"": arrays},
    )


def main() -> None:
    parser = fitting.parser(__doc__, first=0)
    parser.add_argument("--trees", type=int, default=200, help="boosting rounds (default 200)")
    parser.add_argument("--depth", type=int, default=5, help="depth of each tree (default 5)")
    parser.add_argument("--rate", type=float, default=0.1, help="learning rate (default 0.1)")
    parser.add_argument("--clip", type=float, default=4.0, help="largest target, pixels (default 4)")
    parser.add_argument("--write", action="store_true", help="write the trees to offset_model.py")
    args = parser.parse_args()
    from rockscan.core.segment.offset import MIN_MOVE

    tasks = [(c, i) for c in CONDITIONS for i in range(args.first, args.first + args.n)]
    results = [
        r
        for r in measured(_measure, tasks, jobs=args.jobs, cache=args.cache, keep=args.measured, chunksize=4)
        if r is not None
    ]
    x = [r["features"][r["usable"]] for r in results]
    y = [np.clip(r["target"][r["usable"]], -args.clip, args.clip) for r in results]
    print(f"{len(results)} photos chosen among the whole pool, {sum(len(v) for v in y)} rays")
    print("| rays | mean absolute offset | within 0.5 px | moved | mean absolute offset where moved |")
    print("|---|---|---|---|---|")
    half = np.random.default_rng(0).permutation(len(results)) < len(results) // 2
    target, predicted = [], []
    for train in (half, ~half):
        rows, others = np.flatnonzero(train), np.flatnonzero(~train)
        model = fit(np.vstack([x[k] for k in rows]), np.concatenate([y[k] for k in rows]), args)
        target.append(np.concatenate([y[k] for k in others]))
        predicted.append(model.predict(np.vstack([x[k] for k in others])))
    print(summary_row("all, two-fold", np.concatenate(target), np.concatenate(predicted), MIN_MOVE))
    if args.write:
        model = fit(np.vstack(x), np.concatenate(y), args)
        arrays = tree_arrays(model)
        from rockscan.core.segment import offset_model

        offset = importlib.import_module("rockscan.core.segment.offset")
        summary = (
            f"{len(arrays['ROOTS'])} trees of depth {arrays['DEPTH']} (learning rate {args.rate}, "
            f"absolute loss, targets clipped to {args.clip} px), fitted on {sum(len(v) for v in y)} "
            f"rays of {len(results)} development photos chosen among the whole pool (photos "
            f"{args.first}-{args.first + args.n - 1} of each one-rock condition and crops)."
        )
        path = Path(offset_model.__file__)
        write_model(arrays, path, textwrap.fill(summary, 76))
        importlib.reload(offset_model)
        importlib.reload(offset)
        xs = np.vstack(x)
        gap = np.abs(offset.predicted_offsets(xs) - model.predict(xs)).max()
        print(f"wrote the trees to {path}; largest difference from scikit-learn: {gap:.2e}")


if __name__ == "__main__":
    main()
