"""Rocks outlined on one working grid, placed on a window of another (``rockscan.core.segment.finish.placed``).

The choice's candidates come from detections outlined at different scales;
comparing them needs each on the chosen rock's grid.
"""

from __future__ import annotations

import numpy as np
import pytest

from rockscan.core.segment.finish import placed as place
from rockscan.core.segment.types import RockMask


def rock(mask: np.ndarray, origin: tuple[int, int]) -> RockMask:
    return RockMask(mask=mask, coverage=mask.astype(np.float32), origin_rowcol=origin)


def disk(shape: tuple[int, int], centre: tuple[float, float], radius: float) -> np.ndarray:
    rr, cc = np.mgrid[: shape[0], : shape[1]]
    return np.hypot(rr + 0.5 - centre[0], cc + 0.5 - centre[1]) <= radius


def test_on_its_own_grid_a_rock_lands_where_it_was():
    mask = disk((20, 30), (10, 15), 8)
    placed = place(rock(mask, (12, 7)), (10, 40, 5, 45), (2.0, 2.0))
    assert placed.shape == (30, 40)
    np.testing.assert_array_equal(placed[2:22, 2:32], mask)
    assert placed.sum() == mask.sum()


@pytest.mark.parametrize("factor", [2.0, 0.5, 1.5])
def test_from_another_grid_a_rock_keeps_its_place_and_size(factor):
    # The same disk of radius 12 photo pixels centred at (40, 50), outlined on
    # a grid of 1 photo pixel a pixel and on another of ``factor``.
    coarse = disk((int(80 / factor), int(100 / factor)), (40 / factor, 50 / factor), 12 / factor)
    ys, xs = np.nonzero(coarse)
    window = coarse[ys.min() : ys.max() + 1, xs.min() : xs.max() + 1]
    placed = place(rock(window, (ys.min(), xs.min())), (20, 60, 30, 70), (1.0, 1.0), (factor, factor))
    truth = disk((80, 100), (40, 50), 12)[20:60, 30:70]
    assert placed.shape == truth.shape
    assert (placed & truth).sum() / (placed | truth).sum() > 0.85
    ys, xs = np.nonzero(placed)
    np.testing.assert_allclose((ys.mean() + 20, xs.mean() + 30), (39.5, 49.5), atol=0.6)


def test_a_rock_that_does_not_fit_the_window_is_not_placed():
    mask = disk((20, 20), (10, 10), 8)
    assert place(rock(mask, (0, 0)), (5, 40, 0, 40), (1.0, 1.0)) is None
    assert place(rock(mask, (25, 25)), (0, 40, 0, 40), (1.0, 1.0)) is None
    # On a grid twice as coarse, the same window holds only half as many of its pixels.
    assert place(rock(mask, (12, 12)), (0, 40, 0, 40), (1.0, 1.0), (2.0, 2.0)) is None
    assert place(rock(mask, (5, 5)), (0, 60, 0, 60), (1.0, 1.0), (2.0, 2.0)) is not None
