"""What the fitting scripts share: measuring development photos in parallel,
kept between runs, a logistic model whose weights keep given signs, and
gradient-boosted trees written as modules of numpy arrays."""

from __future__ import annotations

import argparse
import pickle
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import TextIO

import bench_segment as bench
import numpy as np
from scipy.optimize import minimize


def parser(doc: str, first: int) -> argparse.ArgumentParser:
    """The options every fitting script takes: which development photos, and
    how to measure them (the script adds its own)."""
    parser = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("-n", type=int, default=200, help="development photos per condition (default 200)")
    parser.add_argument(
        "--first",
        type=int,
        default=first,
        help=f"first photo of each condition (default {first})",
    )
    parser.add_argument("--jobs", type=int, default=1, help="processes (default 1)")
    parser.add_argument("--cache", type=Path, help="keep generated photos in this folder between runs")
    parser.add_argument("--measured", type=Path, help="keep the measurements in this .pkl file")
    return parser


def set_cache(cache: Path | None) -> None:
    """Keep the benchmark's generated photos in ``cache`` (in this process)."""
    bench._CACHE_DIR = cache


def measured(
    measure: Callable,
    tasks: Sequence,
    *,
    jobs: int,
    cache: Path | None,
    keep: Path | None,
    chunksize: int = 1,
) -> list:
    """``measure`` of every task, on ``jobs`` processes; read back from ``keep``
    when it exists, written there otherwise (when given).

    Measuring thousands of photos takes half an hour: how far it has got, how
    fast and how long is left go to standard error every ``PROGRESS_EVERY``
    tasks, one plain line each (readable in a terminal and in a log).
    """
    if keep is not None and keep.exists():
        return pickle.loads(keep.read_bytes())
    if jobs > 1:
        import multiprocessing

        with multiprocessing.get_context("spawn").Pool(
            jobs, initializer=set_cache, initargs=(cache,)
        ) as pool:
            results = list(_reported(pool.imap(measure, tasks, chunksize=chunksize), len(tasks)))
    else:
        set_cache(cache)
        results = list(_reported(map(measure, tasks), len(tasks)))
    if keep is not None:
        keep.write_bytes(pickle.dumps(results))
    return results


#: Tasks between two progress lines of :func:`measured`.
PROGRESS_EVERY = 50


def _reported(results: Iterator, total: int, stream: TextIO | None = None) -> Iterator:
    """``results`` passed on as they come, with a progress line every
    ``PROGRESS_EVERY`` of them and at the last (to ``stream``, standard error by default)."""
    if stream is None:
        stream = sys.stderr
    start = time.perf_counter()
    for done, result in enumerate(results, start=1):
        yield result
        if done % PROGRESS_EVERY == 0 or done == total:
            rate = done / max(time.perf_counter() - start, 1e-9)
            left = (total - done) / rate
            line = f"  measured {done}/{total} ({rate:.2f}/s, {left / 60:.0f} min left)"
            print(line, file=stream, flush=True)


def signed_logistic(
    x: np.ndarray, y: np.ndarray, penalty: float, signs: Sequence[int]
) -> tuple[np.ndarray, float]:
    """Raw-feature weights and intercept of a logistic model with an L2 penalty
    on standardised features, each weight's sign held (+1: >= 0, -1: <= 0, 0: free)."""
    y = np.asarray(y, dtype=np.float64)
    mu, sd = x.mean(axis=0), x.std(axis=0) + 1e-9
    z = (x - mu) / sd

    def loss(w: np.ndarray) -> tuple[float, np.ndarray]:
        t = z @ w[1:] + w[0]
        p = 1.0 / (1.0 + np.exp(-t))
        value = float(np.sum(np.logaddexp(0.0, t) - y * t) + penalty * np.sum(w[1:] ** 2))
        grad = np.concatenate([[np.sum(p - y)], z.T @ (p - y) + 2.0 * penalty * w[1:]])
        return value, grad

    bounds = [(None, None)] + [{1: (0.0, None), -1: (None, 0.0), 0: (None, None)}[s] for s in signs]
    w = minimize(loss, np.zeros(z.shape[1] + 1), jac=True, method="L-BFGS-B", bounds=bounds).x
    return w[1:] / sd, float(w[0] - np.sum(w[1:] * mu / sd))


def boosted_classifier(args: argparse.Namespace, monotone: Sequence[int], seed: int = 0):
    """Gradient-boosted trees of a yes-or-no answer (scikit-learn's
    ``HistGradientBoostingClassifier``), unfitted: ``args.trees`` rounds of depth
    ``args.depth`` at rate ``args.rate``, each feature held to its sign in
    ``monotone`` (+1 rising, -1 falling, 0 free)."""
    from sklearn.ensemble import HistGradientBoostingClassifier

    return HistGradientBoostingClassifier(
        max_iter=args.trees,
        max_depth=args.depth,
        learning_rate=args.rate,
        l2_regularization=1.0,
        min_samples_leaf=20,
        monotonic_cst=list(monotone),
        early_stopping=False,
        random_state=seed,
    )


def truth_on_grid(shape: tuple[int, int], truth: np.ndarray, scale_rowcol: tuple[float, float]) -> np.ndarray:
    """The true label under the centre of each pixel of a grid of ``shape``
    whose pixels span ``scale_rowcol`` photo pixels (a segmentation's working grid)."""
    rows = np.minimum(((np.arange(shape[0]) + 0.5) * scale_rowcol[0]).astype(int), truth.shape[0] - 1)
    cols = np.minimum(((np.arange(shape[1]) + 0.5) * scale_rowcol[1]).astype(int), truth.shape[1] - 1)
    return truth[np.ix_(rows, cols)]


def tree_arrays(model) -> dict[str, np.ndarray | float | int]:
    """The fitted trees as flat node arrays (``choice_model``, ``offset_model``,
    ``join_model``): a leaf's feature is -1."""
    nodes = [predictor.nodes for (predictor,) in model._predictors]
    sizes = np.array([len(n) for n in nodes])
    roots = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    flat = np.concatenate(nodes)
    offset = np.repeat(roots, sizes)
    leaf = flat["is_leaf"].astype(bool)
    return {
        "ROOTS": roots.astype(np.int64),
        "FEATURE": np.where(leaf, -1, flat["feature_idx"]).astype(np.int64),
        "THRESHOLD": np.where(leaf, 0.0, flat["num_threshold"]).astype(np.float64),
        "LEFT": np.where(leaf, 0, flat["left"] + offset).astype(np.int64),
        "RIGHT": np.where(leaf, 0, flat["right"] + offset).astype(np.int64),
        "VALUE": np.where(leaf, flat["value"], 0.0).astype(np.float64),
        "BIAS": float(np.ravel(model._baseline_prediction)[0]),
        "DEPTH": int(flat["depth"].max()),
    }


def write_trees(path: Path, title: str, script: str, summary: str, trees: dict[str, dict]) -> None:
    """Write fitted trees (:func:`tree_arrays`) as a module of numpy arrays.

    ``trees`` maps a prefix of the module's names (``""`` for the first
    model) to that model's arrays; ``title`` names the model and what reads
    it, ``script`` the script that writes it, and ``summary`` (how it was
    fitted and what it measured) goes into the module's docstring.
    """
    header = (
        f'"""{title}, written by\n'
        f"``{script} --write``: not to be edited by hand.\n\n"
        f"{summary}\n"
        '"""\n\nimport numpy as np\n'
    )
    parts = [header]
    for prefix, arrays in trees.items():
        parts += [f"{prefix}BIAS = {arrays['BIAS']!r}\n", f"{prefix}DEPTH = {arrays['DEPTH']}\n"]
        parts += [
            array_source(prefix + name, arrays[name], "int64")
            for name in ("ROOTS", "FEATURE", "LEFT", "RIGHT")
        ]
        parts += [array_source(prefix + name, arrays[name], "float64") for name in ("THRESHOLD", "VALUE")]
    path.write_text("\n".join(parts))


def array_source(name: str, values: np.ndarray, kind: str) -> str:
    """``NAME = np.array([...], dtype=...)`` with the values wrapped to the line length."""
    items = [repr(float(v)) if kind == "float64" else str(int(v)) for v in values]
    lines, line = [], ""
    for item in items:
        if line and len(line) + len(item) > 96:
            lines.append(line.rstrip())
            line = ""
        line += item + ", "
    lines.append(line.rstrip())
    body = "".join(f"        {text}\n" for text in lines)
    return f"{name} = np.array(\n    [\n{body}    ],\n    dtype=np.{kind},\n)\n"
