"""Reproduce the experiments of the paper (Fleetwood & Thangavelautham, Section IV).

Everything goes through rockscan's public API with the paper's three shapes as
the library, and every experiment is run with two matchers:

default
    ``MatchConfig()``: rank by the eigenspace distance, take the angle from the
    whole-face distance.
paper
    ``paper.experiments.PAPER``: the paper's exact method, the eigenspace
    distance for both.

Experiments
-----------
Table I    the three library shapes matched to themselves
Table V    the near shapes of Tables II-IV
Fig. 12    MScore against radial noise (Fig. 11's model: every radius times
           1 + e, e normal), 0-20 % standard error, averaged over seeds
Fig. 13    MScore against rotation, without the rotation scan (the paper's
           figure) and with it
Fig. 14-16 MScore as m, n1 and n2 = n3 move away from each base shape

The paper's Cartesian grid map (``FaceConfig(grid="cartesian")``) is run beside
rockscan's polar grid on the tables and on a subset of every sweep, to show
that both choose the same shapes with close MScores.

Writes ``paper-*.png`` into ``--out`` and the README section ``--doc`` with the
tables, the figures and the differences from the paper; ``--json`` also saves
the numbers. ``--quick`` runs a tiny version (seconds) for smoke tests.

The experiments, findings, figures and document live in the ``paper`` package
beside this script; this file is its command line.

Usage::

    python scripts/reproduce_paper.py [--out docs/figures] [--doc docs/paper.md]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np

# The ``paper`` package sits beside this script, which is run by path or loaded by path in the tests.
sys.path.insert(0, str(Path(__file__).resolve().parent))
from paper.document import fmt, markdown_table, write_doc
from paper.experiments import (
    QUICK,
    Settings,
    angle_error_deg,
    noisy_radii,
    run_all,
    sweep_params,
    turned_radii,
)
from paper.figures import figure_paths, write_figures
from paper.findings import findings, paper_pairwise_distances, table_rows

__all__ = [
    "angle_error_deg",
    "fmt",
    "main",
    "noisy_radii",
    "paper_pairwise_distances",
    "sweep_params",
    "turned_radii",
]

ROOT = Path(__file__).resolve().parents[1]


def _jsonable(value: object) -> object:
    """NaN and infinity as null, so the file is strict JSON."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.generic):
        return _jsonable(value.item())
    return value


def _arguments(argv: Sequence[str] | None) -> tuple[argparse.Namespace, Settings]:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "figures", help="directory for the PNGs")
    parser.add_argument(
        "--doc", type=Path, default=ROOT / "docs" / "paper.md", help="README section to write"
    )
    parser.add_argument("--json", type=Path, default=None, help="also save the numbers as JSON")
    parser.add_argument("--seed", type=int, default=Settings.seed, help="base seed of the noise draws")
    parser.add_argument("--seeds", type=int, default=None, help="noise draws per shape")
    parser.add_argument("--quick", action="store_true", help="a tiny run for smoke tests (seconds)")
    args = parser.parse_args(argv)
    settings = replace(QUICK if args.quick else Settings(), seed=args.seed)
    if args.seeds is not None:
        if args.seeds < 1:
            parser.error("--seeds must be at least 1")
        settings = replace(
            settings, n_seeds=args.seeds, cartesian_seeds=min(settings.cartesian_seeds, args.seeds)
        )
    return args, settings


def _print_summary(tables: dict[str, list[dict[str, object]]], facts: dict[str, object]) -> None:
    for table, rows in tables.items():
        print(f"Table {table}")
        print(markdown_table(rows))
        print()
    grids, methods = facts["grids"], facts["methods"]
    assert isinstance(grids, dict) and isinstance(methods, dict)
    print(
        f"polar vs Cartesian grid: same winner {grids['same_winner']}/{grids['pairs']}, largest MScore "
        f"difference {grids['max_mscore_diff']:.4f}, "
        f"{grids['max_mscore_diff_without_noise']:.4f} without noise"
    )
    print(
        f"default vs paper matcher: largest MScore difference {methods['max_mscore_diff']:.1e}, "
        f"winner differs {methods['winner_differs']}/{methods['pairs']}"
    )


def main(argv: Sequence[str] | None = None) -> int:
    args, settings = _arguments(argv)
    start = time.perf_counter()
    results = run_all(settings)
    figures = figure_paths(args.out)
    write_figures(results.matcher, figures, settings.dpi)
    facts = findings(results.matcher)
    seconds = time.perf_counter() - start
    command = "python scripts/reproduce_paper.py" + (" --quick" if args.quick else "")
    write_doc(
        args.doc, results.matcher, settings, facts, results.check, figures, results.skipped, seconds, command
    )

    tables = {table: table_rows(results.matcher, table) for table in ("I", "V")}
    _print_summary(tables, facts)
    print(f"wrote {args.doc} and {len(figures)} figures in {args.out} ({seconds:.1f} s)")
    if args.json is not None:
        payload = {
            "settings": settings.__dict__,
            "table_I": tables["I"],
            "table_V": tables["V"],
            "findings": facts,
            "noise_check": results.check,
            "skipped": results.skipped,
            "figures": {key: str(value) for key, value in figures.items()},
        }
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(_jsonable(payload), indent=1, allow_nan=False), encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
