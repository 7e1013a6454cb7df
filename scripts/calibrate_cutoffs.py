"""Choose the matcher's cutoffs from measured data: in-library rocks against distractors.

The paper counts a sample when its best distance w does not exceed a cutoff
theta and its MScore exceeds gamma, but gives no values. Here they are
measured. A calibration set is rendered exactly as the accuracy benchmark's
sets (scripts/bench_accuracy.py) but from another seed, so that no photo is
shared: in-library rocks (clean, outline noise up to 10%, near shapes, hard
photos) that should be accepted, and out-of-library distractors that should
be rejected. Each photo is segmented once; every configuration matches the
same radii with the cutoffs off and records (w, MScore, DFFS).

The rule: among all pairs (theta, gamma) placed half-way between measured
values, take those that maximise the smaller of the two rates (acceptance of
in-library rocks, rejection of distractors); among them, those with the
larger sum; among those, the median gamma and then the median theta, which
keeps the cutoffs away from the measured values on both sides.

It also reports what adding Turk and Pentland's distance from face space
(DFFS, ``Match.residual``) as a third cutoff would gain, and checks that the
coins of scikit-image's ``coins()`` photo stay interesting circles.

Run ``python scripts/calibrate_cutoffs.py --help`` for options.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import dataclass

import numpy as np
from bench_accuracy import ACCEPT_SETS, CALIBRATION_SEED, render_set

from rockscan.errors import RockscanError
from rockscan.information import FaceConfig
from rockscan.io import default_library
from rockscan.library import Library
from rockscan.match import DEFAULT_CUTOFFS, MatchConfig, match_radii
from rockscan.pipeline import measure_rocks
from rockscan.superformula import SuperformulaParams

#: The paper's rounded triangle (Fig. 5), the reference of the variant-2 faces.
ROUNDED_TRIANGLE = SuperformulaParams(3, 3, 1500, 1500, 1500)
#: Configurations calibrated: the three face kinds under the default matcher
#: (these give DEFAULT_CUTOFFS), and the benchmark's rows whose distance is
#: another one (their own cutoffs, for a fair comparison).
CONFIGS: dict[str, tuple[FaceConfig, MatchConfig]] = {
    "information": (FaceConfig(), MatchConfig()),
    "information-shape": (FaceConfig(kind="information-shape", reference=ROUNDED_TRIANGLE), MatchConfig()),
    "radii": (FaceConfig(kind="radii"), MatchConfig()),
    "information, face metric": (FaceConfig(), MatchConfig(metric="face", angle_metric="face")),
    "radii, face metric": (FaceConfig(kind="radii"), MatchConfig(metric="face", angle_metric="face")),
}
#: No cutoff at all: every match is interesting, so w and MScore can be read.
OPEN = {"distance_cutoff": float("inf"), "mscore_cutoff": float("-inf")}


@dataclass(frozen=True)
class Measured:
    """w, MScore and DFFS of every calibration photo under one configuration."""

    inside: np.ndarray  # (n_in, 3): in-library rocks
    outside: np.ndarray  # (n_out, 3): distractors


def measure(n_in: int, n_out: int, seed: int) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Radii of the calibration photos' rocks: in-library, then distractors."""
    inside, outside = [], []
    for set_name in (*ACCEPT_SETS, "distractor"):
        n = n_out if set_name == "distractor" else n_in
        for sample in render_set(set_name, n, seed):
            try:
                radii = measure_rocks(sample.pixels, 360)[1][0][1]
            except RockscanError:
                continue
            (outside if set_name == "distractor" else inside).append(radii)
        print(f"  {set_name}: rendered and segmented", file=sys.stderr, flush=True)
    return inside, outside


def scores(library: Library, config: MatchConfig, radii: list[np.ndarray]) -> np.ndarray:
    """(w of the nearest shape, MScore, DFFS) per sample, cutoffs off."""
    open_config = MatchConfig(
        metric=config.metric, angle_metric=config.angle_metric, scan=config.scan, refine=config.refine, **OPEN
    )
    out = []
    for r in radii:
        m = match_radii(r, library, open_config)
        out.append((float(m.distances.min()), m.mscore, m.residual))
    return np.array(out)


def rates(measured: Measured, theta: float, gamma: float, rho: float = np.inf) -> tuple[float, float]:
    """(acceptance of in-library rocks, rejection of distractors) at the given cutoffs."""

    def passes(values: np.ndarray) -> np.ndarray:
        return (values[:, 0] <= theta) & (values[:, 1] > gamma) & (values[:, 2] <= rho)

    return float(passes(measured.inside).mean()), float(1.0 - passes(measured.outside).mean())


def midpoints(values: np.ndarray, limit: int = 160) -> np.ndarray:
    """Candidate cutoffs half-way between measured values (thinned to ``limit``), and both ends."""
    v = np.unique(values)
    mids = 0.5 * (v[1:] + v[:-1])
    if mids.size > limit:
        mids = mids[np.linspace(0, mids.size - 1, limit).round().astype(int)]
    return np.concatenate([[v[0] - 1.0], mids, [v[-1] + 1.0]])


def choose(measured: Measured, *, with_residual: bool = False) -> tuple[float, float, float, float, float]:
    """The rule of the module docstring: (theta, gamma, rho, acceptance, rejection)."""
    both = np.concatenate([measured.inside, measured.outside])
    thetas, gammas = midpoints(both[:, 0]), midpoints(both[:, 1])
    rhos = midpoints(both[:, 2], limit=40) if with_residual else np.array([np.inf])
    table = []
    for rho in rhos:
        for gamma in gammas:
            # Every theta at once: (n_thetas, n_samples) of "passes".
            ok_in = (measured.inside[:, 1] > gamma) & (measured.inside[:, 2] <= rho)
            ok_out = (measured.outside[:, 1] > gamma) & (measured.outside[:, 2] <= rho)
            acc = ((measured.inside[None, :, 0] <= thetas[:, None]) & ok_in).mean(axis=1)
            rej = 1.0 - ((measured.outside[None, :, 0] <= thetas[:, None]) & ok_out).mean(axis=1)
            table.extend(
                zip(
                    np.minimum(acc, rej),
                    acc + rej,
                    thetas,
                    np.full_like(thetas, gamma),
                    np.full_like(thetas, rho),
                    acc,
                    rej,
                    strict=True,
                )
            )
    table_arr = np.array(table)
    best = table_arr[table_arr[:, 0] == table_arr[:, 0].max()]
    best = best[best[:, 1] == best[:, 1].max()]
    if with_residual:
        rho = float(np.median(np.unique(best[:, 4])))
        best = best[best[:, 4] == best[np.argmin(np.abs(best[:, 4] - rho)), 4]]
    gamma = float(np.median(np.unique(best[:, 3])))
    best = best[best[:, 3] == best[np.argmin(np.abs(best[:, 3] - gamma)), 3]]
    theta = float(np.median(np.unique(best[:, 2])))
    row = best[np.argmin(np.abs(best[:, 2] - theta))]
    return float(row[2]), float(row[3]), float(row[4]), float(row[5]), float(row[6])


def trade_off(measured: Measured, theta: float, gamma: float) -> str:
    """Markdown: acceptance and rejection as each cutoff moves with the other fixed."""
    lines = ["| theta (gamma fixed) | accepted | rejected |", "|---|---|---|"]
    both = np.concatenate([measured.inside, measured.outside])
    for q in (0.05, 0.2, 0.4, 0.6, 0.7, 0.8, 0.9, 0.95):
        t = float(np.quantile(both[:, 0], q))
        acc, rej = rates(measured, t, gamma)
        lines.append(f"| {t:.4g} | {100 * acc:.1f}% | {100 * rej:.1f}% |")
    acc, rej = rates(measured, theta, gamma)
    lines.append(f"| **{theta:.4g} (chosen)** | {100 * acc:.1f}% | {100 * rej:.1f}% |")
    lines += ["", "| gamma (theta fixed) | accepted | rejected |", "|---|---|---|"]
    for q in (0.05, 0.2, 0.4, 0.6, 0.8, 0.95):
        g = float(np.quantile(both[:, 1], q))
        acc, rej = rates(measured, theta, g)
        lines.append(f"| {g:.4g} | {100 * acc:.1f}% | {100 * rej:.1f}% |")
    acc, rej = rates(measured, theta, gamma)
    lines.append(f"| **{gamma:.4g} (chosen)** | {100 * acc:.1f}% | {100 * rej:.1f}% |")
    return "\n".join(lines)


def coins_check(library: Library, config: MatchConfig, theta: float, gamma: float) -> str:
    """How scikit-image's 24 coins fare at the chosen cutoffs."""
    from skimage import data

    from rockscan.pipeline import ClassifyConfig, classify_image

    match = MatchConfig(metric=config.metric, angle_metric=config.angle_metric, **OPEN)
    rocks = classify_image(data.coins(), library, ClassifyConfig(match=match), all_rocks=True)
    w = np.array([r.match.distances.min() for r in rocks])
    mscore = np.array([r.match.mscore for r in rocks])
    circles = sum(r.match.nearest == "circle" for r in rocks)
    kept = int(
        np.sum((w <= theta) & (mscore > gamma) & np.array([r.match.nearest == "circle" for r in rocks]))
    )
    return (
        f"coins: {len(rocks)} found, {circles} nearest circle, {kept} interesting circles "
        f"(largest w {w.max():.4g}, smallest MScore {mscore.min():.3f})"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--photos", type=int, default=56, help="photos per in-library set (default 56)")
    parser.add_argument("--distractors", type=int, default=112, help="distractor photos (default 112)")
    parser.add_argument("--seed", type=int, default=CALIBRATION_SEED, help="base seed of the calibration set")
    parser.add_argument("--write", metavar="JSON", help="write the chosen cutoffs per configuration here")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    inside, outside = measure(args.photos, args.distractors, args.seed)
    print(
        f"calibration set (seed {args.seed}): {len(inside)} in-library rocks "
        f"({', '.join(ACCEPT_SETS)}), {len(outside)} distractors\n"
    )
    chosen: dict[str, dict[str, float]] = {}
    for name, (face_config, config) in CONFIGS.items():
        library = default_library(face_config)
        measured = Measured(scores(library, config, inside), scores(library, config, outside))
        theta, gamma, _, acc, rej = choose(measured)
        theta3, gamma3, rho, acc3, rej3 = choose(measured, with_residual=True)
        chosen[name] = {"distance_cutoff": theta, "mscore_cutoff": gamma}
        print(f"### {name}\n")
        print(f"chosen: theta = {theta:.4g}, gamma = {gamma:.4g}", end=" ")
        print(f"-> accepted {100 * acc:.1f}%, rejected {100 * rej:.1f}%")
        print(
            f"with a DFFS cutoff as well (theta = {theta3:.4g}, gamma = {gamma3:.4g}, rho = {rho:.4g}):",
            end=" ",
        )
        print(f"accepted {100 * acc3:.1f}%, rejected {100 * rej3:.1f}%")
        default = DEFAULT_CUTOFFS.get(face_config.kind) if config == MatchConfig() else None
        if default is not None:
            acc_d, rej_d = rates(measured, *default)
            print(f"DEFAULT_CUTOFFS now {default}: accepted {100 * acc_d:.1f}%, rejected {100 * rej_d:.1f}%")
        print(coins_check(library, config, theta, gamma))
        print()
        print(trade_off(measured, theta, gamma))
        print()
    if args.write:
        with open(args.write, "w", encoding="utf-8") as handle:
            json.dump(chosen, handle, indent=2)
        print(f"cutoffs written to {args.write}")
    print(f"{time.perf_counter() - start:.0f} s in all")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
