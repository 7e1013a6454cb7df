"""Figures of fits: example outlines with their fitted Superformulas overlaid."""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from rockscan.core.fit import FitResult
from rockscan.core.polar import radii_to_xy
from rockscan.draw.plot import save_figure

__all__ = ["plot_fits"]


def plot_fits(
    items: Sequence[tuple[str, ArrayLike, FitResult]],
    path: str | os.PathLike[str],
    *,
    columns: int = 4,
) -> None:
    """Draw outlines with their fitted Superformulas overlaid (PNG via matplotlib).

    Parameters
    ----------
    items : sequence of (name, radii, FitResult)
        Each outline's name, its radii (as given to :func:`fit_superformula`)
        and its fit.
    path : path-like
        PNG file to write.
    columns : int
        Panels per row.

    Raises
    ------
    WriteError
        If the file cannot be written.
    """
    from matplotlib.figure import Figure

    n = max(len(items), 1)
    cols = min(columns, n)
    rows = -(-n // cols)
    # A Figure of its own: no pyplot state, no backend switched (see rockscan.draw.plot).
    fig = Figure(figsize=(3.2 * cols, 3.4 * rows))
    axes = fig.subplots(rows, cols, squeeze=False)
    for ax, (name, radii, fit) in zip(axes.flat, items, strict=False):
        radii = np.asarray(radii, dtype=np.float64) / fit.mean_radius
        outline = radii_to_xy(radii)
        curve = radii_to_xy(fit.curve(max(radii.size, 360)) / fit.mean_radius)
        ax.plot(*np.vstack([outline, outline[:1]]).T, "-", color="#1c1c1e", lw=1.6, label="outline")
        ax.plot(*np.vstack([curve, curve[:1]]).T, "--", color="#ff3b30", lw=1.2, label="fit")
        ax.plot([0], [0], "+", color="#007aff", ms=8)
        p = fit.params
        ax.set_title(
            f"{name}\nm {p.m1:g}/{p.m2:g}  n {p.n1:.3g}, {p.n2:.3g}, {p.n3:.3g}  b/a {p.b / p.a:.3g}\n"
            f"rms {fit.rms_percent:.2f}%  angle {fit.angle_deg:.1f}°",
            fontsize=7,
        )
        ax.set_aspect("equal")
        ax.axis("off")
    for ax in list(axes.flat)[len(items) :]:
        ax.axis("off")
    if items:
        axes.flat[0].legend(loc="lower left", fontsize=6, framealpha=0.7)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
