"""The calibration of a library's cutoffs: its figure and its cost.

Every library calibrates its own per-shape cutoffs when it is built
(:func:`rockscan.core.calibrate.calibrate`; docs/decision.md). This script

* draws, for the default library, each shape's simulated in-library
  distances and its out-of-library ones (shapes at the library's spacing
  around it), clean and at the tolerance's outline noise, and the cutoff
  chosen at each end: ``--figure PNG``
  (docs/figures/decision-calibration.png);
* times a library build with and without the calibration at 14, 1,000 and
  10,000 shapes (``--timing``), as ratios within one run. The build without
  calibration is the eigen decomposition, whose cost another part of rockscan
  bounds; at 10,000 shapes only the calibration is timed unless ``--full``.

Run ``python scripts/calibrate_cutoffs.py --help`` for options.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from rockscan.core.calibrate import Calibration, calibrate
from rockscan.core.library import Library
from rockscan.core.render import random_superformula
from rockscan.core.superformula import shape_radii
from rockscan.io import default_library


def figure(path: str, *, tolerance: float = 0.2) -> None:
    """Per shape of the default library, at both ends of its cutoff: in- and out-of-library distances."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    library = default_library()
    cal = calibrate(library.radii, tolerance=tolerance, keep_samples=True)
    assert cal.samples is not None and cal.clean_cutoffs is not None
    s = cal.samples
    n = len(library)
    fig, axes = plt.subplots(1, 2, figsize=(11, 0.42 * n + 1.9), sharey=True)
    ends = (
        ("clean samples (blur and jitter only)", s.inside_clean, s.outside[:, 0::2], cal.clean_cutoffs),
        (f"outline noise {100 * tolerance:g}% (the tolerance)", s.inside, s.outside[:, 1::2], cal.cutoffs),
    )
    rng = np.random.default_rng(0)
    for ax, (title, inside, outside, cutoffs) in zip(axes, ends, strict=True):
        for i, k in enumerate(s.shapes):
            y = n - 1 - i
            ax.scatter(
                inside[i],
                y + 0.12 + 0.08 * rng.uniform(-1, 1, inside.shape[1]),
                s=9,
                color="#1f77b4",
                alpha=0.7,
            )
            ax.scatter(
                outside[i],
                y - 0.12 + 0.08 * rng.uniform(-1, 1, outside.shape[1]),
                s=9,
                color="#d62728",
                alpha=0.7,
            )
            ax.plot([cutoffs[k]] * 2, [y - 0.35, y + 0.35], color="black", lw=2)
        ax.set_title(title, fontsize=9)
        ax.set_xscale("symlog", linthresh=0.1)
        ax.set_xlim(left=0)
        ax.set_xlabel("sensor distance to the shape, the sample's own noise taken out", fontsize=8)
    axes[0].set_yticks(np.arange(n)[::-1], [library.names[k] for k in s.shapes], fontsize=8)
    for k in np.flatnonzero(cal.crowded[s.shapes]):
        axes[1].text(cal.cutoffs[s.shapes[k]], n - 1 - k + 0.38, "crowded", fontsize=6, ha="center")
    axes[0].scatter([], [], s=9, color="#1f77b4", label="in library")
    axes[0].scatter([], [], s=9, color="#d62728", label="out of library: shapes at the library's spacing")
    axes[0].plot([], [], color="black", lw=2, label="calibrated cutoff (a sample between: interpolated)")
    fig.legend(fontsize=8, loc="lower center", ncol=3, frameon=False)
    fig.suptitle("Default library: simulated samples and each shape's calibrated cutoffs", fontsize=10)
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    fig.savefig(path, dpi=110)
    print(f"drew {path}")


def random_radii(n_shapes: int, seed: int) -> np.ndarray:
    """Radii of random rock-like shapes (some repeat when drawn many times; that is fine for timing)."""
    rng = np.random.default_rng(seed)
    pool = np.array([shape_radii(random_superformula(rng), 360) for _ in range(min(n_shapes, 400))])
    picks = rng.integers(0, pool.shape[0], n_shapes)
    # Small distinct changes so that no two shapes are equal.
    return pool[picks] * (1.0 + 0.01 * rng.standard_normal((n_shapes, 1)) * np.cos(np.arange(360) / 57.3))


def timing(sizes: list[int], *, full: bool) -> None:
    print("| shapes | build without calibration (s) | calibration (s) | build with calibration (s) | ratio |")
    print("|---|---|---|---|---|")
    for n in sizes:
        radii = default_library().radii if n == 14 else random_radii(n, n)
        names = [f"s{i}" for i in range(n)]
        start = time.perf_counter()
        cal = calibrate(radii)
        t_cal = time.perf_counter() - start
        if n <= 1000 or full:
            given = Calibration(
                cal.cutoffs, cal.spacing, cal.crowded, cal.calibrated, clean_cutoffs=cal.clean_cutoffs
            )
            start = time.perf_counter()
            Library.from_radii(names, radii, calibration=given)
            t_plain = time.perf_counter() - start
            start = time.perf_counter()
            Library.from_radii(names, radii)
            t_with = time.perf_counter() - start
            print(f"| {n:,} | {t_plain:.2f} | {t_cal:.2f} | {t_with:.2f} | {t_with / t_plain:.2f} |")
        else:
            print(f"| {n:,} | (not run) | {t_cal:.2f} | | |")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--figure", metavar="PNG", help="draw the default library's calibration")
    parser.add_argument("--timing", action="store_true", help="time builds at 14, 1,000 and 10,000 shapes")
    parser.add_argument("--full", action="store_true", help="also build the 10,000-shape library in full")
    args = parser.parse_args(argv)
    if args.figure:
        figure(args.figure)
    if args.timing:
        timing([14, 1000, 10_000], full=args.full)
    if not (args.figure or args.timing):
        parser.print_help()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
