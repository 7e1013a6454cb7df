"""Gradient-boosted regression trees kept as flat node arrays, and their sum.

The fitting scripts (``scripts/fit_segment_choice.py``,
``scripts/fit_segment_offset.py``, ``scripts/fit_segment_join.py``) write
scikit-learn's trees as modules of numpy arrays (``choice_model``,
``offset_model``, ``join_model``); rockscan reads them with numpy alone.
"""

from __future__ import annotations

from types import ModuleType
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

__all__ = ["Trees", "tree_sum", "trees_of"]


class Trees(NamedTuple):
    """Trees as flat node arrays: each tree's root in ``roots``; a node's
    ``feature`` (-1 at a leaf), ``threshold`` (a row goes ``left`` when its
    feature is at most that), children and, at a leaf, ``value``; ``bias`` is
    added to the sum of the leaves; no path is longer than ``depth``."""

    bias: float
    depth: int
    roots: NDArray[np.int64]
    feature: NDArray[np.int64]
    left: NDArray[np.int64]
    right: NDArray[np.int64]
    threshold: NDArray[np.float64]
    value: NDArray[np.float64]


def trees_of(module: ModuleType, prefix: str = "") -> Trees:
    """The trees a fitting script wrote into ``module`` under ``prefix``."""
    names = ("BIAS", "DEPTH", "ROOTS", "FEATURE", "LEFT", "RIGHT", "THRESHOLD", "VALUE")
    return Trees(*(getattr(module, prefix + name) for name in names))


def tree_sum(x: NDArray[np.floating], trees: Trees) -> NDArray[np.float64]:
    """The bias plus every tree's leaf for each row of ``x`` (rows, features).

    Every tree is walked at once, one level a step; a leaf stays where it is.
    """
    x = np.asarray(x, dtype=np.float64)
    rows = np.arange(x.shape[0])[:, None]
    node = np.broadcast_to(trees.roots, (x.shape[0], trees.roots.size)).copy()
    for _ in range(trees.depth):
        feature = trees.feature[node]
        left = x[rows, np.maximum(feature, 0)] <= trees.threshold[node]
        node = np.where(feature < 0, node, np.where(left, trees.left[node], trees.right[node]))
    return trees.bias + trees.value[node].sum(axis=1)
