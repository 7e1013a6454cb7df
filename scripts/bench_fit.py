"""Benchmark of Superformula fitting (``rockscan library fit``): speed and accuracy.

Measures, in one run:

(a) **Cold fit**: the first fit in a fresh Python process, which also imports
    SciPy's optimiser and builds the global search's bank of shapes, timed in
    a child process around the fit alone.
(b) **Warm fits**: fitting the outline of each of ``n_speed`` rendered photos,
    median and worst time, and as a ratio to measuring the same photo's
    outline (segmentation, tracing and radii: ``measure_rocks``). The two calls
    take turns photo by photo, so a busy machine slows both alike. Then the
    same for smooth random outlines that no Superformula draws well, where
    every fallback of the fit (restarts, m1 != m2) runs: the slowest case.
(c) **Accuracy**: for ``n_shapes`` random shapes (:func:`rockscan.core.render.random_superformula`)
    per seed, rendered with the renderer's defaults, measured and fitted: the
    RMS difference between the fitted curve (at the fitted angle) and the true
    curve (at the true angle), about the rock's centroid, in percent of the
    mean radius. The photo's own outline is judged against the truth the same
    way, for comparison.
(d) **Library from examples**: one photo per class of the default library is
    fitted, and fresh photos of every class are classified against the fitted
    library and against the true one.

Usage::

    python scripts/bench_fit.py [--seeds 0 1 2 3 4] [--parts speed accuracy examples] [--quick]
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import subprocess
import sys
import time
from dataclasses import dataclass, replace

import numpy as np

from rockscan.core.fit import fit_superformula
from rockscan.core.library import Library, ShapeSpec
from rockscan.core.polar import polar_angles, recenter_radii
from rockscan.core.render import random_superformula, render_photo
from rockscan.core.superformula import SuperformulaParams
from rockscan.io import default_library, default_spec_path, read_spec
from rockscan.run.pipeline import classify_image, measure_rocks


@dataclass(frozen=True)
class Settings:
    """Sizes of the benchmark."""

    seeds: tuple[int, ...] = (0, 1, 2, 3, 4)
    n_shapes: int = 50
    n_speed: int = 30
    per_class: int = 5
    n_angles: int = 360


QUICK = Settings(seeds=(0,), n_shapes=4, n_speed=3, per_class=1)

_COLD = """
import sys, time
import numpy as np
from rockscan.core.superformula import shape_radii
from rockscan.core.superformula import SuperformulaParams
radii = shape_radii(SuperformulaParams(5, 5, 2.0, 7.0, 7.0), 360)
import rockscan.core.fit
start = time.perf_counter()
rockscan.core.fit.fit_superformula(radii, rng=0)
print(time.perf_counter() - start)
"""


def true_curve(params: SuperformulaParams, angle_deg: float, n_angles: int) -> np.ndarray:
    """The shape turned by angle_deg, radii about its centroid, mean 1 (the renderer's drawing)."""
    theta = polar_angles(n_angles)
    radii, _ = recenter_radii(params.radii(np.mod(theta - math.radians(angle_deg), 2 * np.pi)))
    return radii / radii.mean()


def rms_percent(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean((a / a.mean() - b / b.mean()) ** 2)) * 100)


def cold_fit_seconds() -> float:
    """Seconds of the first fit in a fresh process."""
    out = subprocess.run([sys.executable, "-c", _COLD], capture_output=True, text=True, check=True)
    return float(out.stdout.strip().splitlines()[-1])


def warm_fits(settings: Settings) -> dict[str, float]:
    rng = np.random.default_rng(1234)
    fit_times, measure_times = [], []
    fit_superformula(np.ones(settings.n_angles), rng=0)  # warm-up: imports and the bank
    for i in range(settings.n_speed):
        photo = render_photo(random_superformula(rng), rng=rng)
        start = time.perf_counter()
        radii = measure_rocks(photo.pixels, settings.n_angles)[1][0].radii
        measure_times.append(time.perf_counter() - start)
        start = time.perf_counter()
        fit_superformula(radii, rng=i)
        fit_times.append(time.perf_counter() - start)
    fits, measures = np.array(fit_times), np.array(measure_times)
    return {
        "median_s": float(np.median(fits)),
        "p90_s": float(np.percentile(fits, 90)),
        "max_s": float(fits.max()),
        "ratio_to_measure": float(np.median(fits / measures)),
        "measure_median_s": float(np.median(measures)),
    }


def rough_outline(rng: np.random.Generator, n_angles: int) -> np.ndarray:
    """A smooth random outline that is no Superformula: 8 Fourier harmonics, amplitude 0.12/k."""
    theta = polar_angles(n_angles)
    k = np.arange(1, 9)[:, None]
    amplitude = rng.normal(0.0, 0.12, (8, 1)) / k
    phase = rng.uniform(0.0, 2 * np.pi, (8, 1))
    return np.maximum(1.0 + (amplitude * np.cos(k * theta + phase)).sum(axis=0), 0.3)


def rough_fits(settings: Settings) -> dict[str, float]:
    """Fit time and residual for outlines no Superformula draws well (every fallback runs)."""
    rng = np.random.default_rng(99)
    times, residuals = [], []
    for i in range(settings.n_speed):
        radii = rough_outline(rng, settings.n_angles) * 100.0
        start = time.perf_counter()
        fit = fit_superformula(radii, rng=i)
        times.append(time.perf_counter() - start)
        residuals.append(fit.rms_percent)
    return {
        "median_s": float(np.median(times)),
        "max_s": float(np.max(times)),
        "residual_median": float(np.median(residuals)),
    }


def accuracy(settings: Settings) -> list[dict[str, object]]:
    rows = []
    for seed in settings.seeds:
        rng = np.random.default_rng(seed)
        fit_err, photo_err, residual = [], [], []
        for i in range(settings.n_shapes):
            params = random_superformula(rng)
            photo = render_photo(params, rng=rng)
            radii = measure_rocks(photo.pixels, settings.n_angles)[1][0].radii
            fit = fit_superformula(radii, rng=i)
            truth = true_curve(params, photo.truth["angle_deg"], settings.n_angles)
            fit_err.append(rms_percent(fit.curve(settings.n_angles), truth))
            photo_err.append(rms_percent(radii, truth))
            residual.append(fit.rms_percent)
        fit_arr = np.array(fit_err)
        rows.append(
            {
                "seed": seed,
                "fit_median": float(np.median(fit_arr)),
                "fit_max": float(fit_arr.max()),
                "fit_worst": int(fit_arr.argmax()),
                "fit_over_3": int((fit_arr > 3.0).sum()),
                "photo_median": float(np.median(photo_err)),
                "photo_max": float(np.max(photo_err)),
                "residual_median": float(np.median(residual)),
            }
        )
    return rows


def library_from_examples(settings: Settings) -> dict[str, object]:
    specs = read_spec(default_spec_path())
    rng = np.random.default_rng(2718)
    fitted = []
    for spec in specs:
        radii = measure_rocks(render_photo(spec.params, rng=rng).pixels, settings.n_angles)[1][0].radii
        fitted.append(ShapeSpec(spec.name, fit_superformula(radii, rng=0).params))
    libraries = {"fitted": Library.from_shapes(fitted), "true": default_library()}
    right = dict.fromkeys(libraries, 0)
    total = 0
    for _ in range(settings.per_class):
        for spec in specs:
            pixels = render_photo(spec.params, rng=rng).pixels
            for key, library in libraries.items():
                right[key] += classify_image(pixels, library)[0].match.nearest == spec.name
            total += 1
    return {"classes": len(specs), "photos": total, **{f"{k}_right": v for k, v in right.items()}}


def main(argv: list[str] | None = None) -> dict[str, object]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=None, help="Seeds of the accuracy runs.")
    parser.add_argument("--quick", action="store_true", help="A tiny run for smoke tests.")
    parser.add_argument(
        "--parts",
        nargs="+",
        choices=("speed", "accuracy", "examples"),
        default=("speed", "accuracy", "examples"),
        help="Parts to run: speed (a, b), accuracy (c), examples (d).",
    )
    args = parser.parse_args(argv)
    settings = QUICK if args.quick else Settings()
    if args.seeds:
        settings = replace(settings, seeds=tuple(args.seeds))
    print(f"# rockscan fit benchmark ({platform.processor() or platform.machine()}, {os.cpu_count()} cores)")
    results: dict[str, object] = {}
    if "speed" in args.parts:
        results["cold_s"] = cold = cold_fit_seconds()
        print(f"(a) cold fit (fresh process, bank built): {cold:.2f} s")
        results["warm"] = warm = warm_fits(settings)
        print(
            f"(b) warm fit of one outline over {settings.n_speed} photos: median {warm['median_s']:.3f} s, "
            f"90th percentile {warm['p90_s']:.3f} s, worst {warm['max_s']:.3f} s; "
            f"{warm['ratio_to_measure']:.2f} x the photo's measurement "
            f"(median {warm['measure_median_s']:.3f} s)"
        )
        results["rough"] = rough = rough_fits(settings)
        print(
            f"(b) warm fit of {settings.n_speed} outlines that are no Superformula (residual median "
            f"{rough['residual_median']:.1f}%): median {rough['median_s']:.3f} s, "
            f"worst {rough['max_s']:.3f} s"
        )
    if "accuracy" in args.parts:
        results["accuracy"] = rows = accuracy(settings)
        print(f"(c) fitted vs true curve, {settings.n_shapes} random shapes per seed (RMS % of mean radius)")
        print(
            "| seed | fit median | fit worst | fits > 3% | photo outline median | photo worst "
            "| residual median |"
        )
        print("|---:|---:|---:|---:|---:|---:|---:|")
        for row in rows:
            print(
                f"| {row['seed']} | {row['fit_median']:.2f} | {row['fit_max']:.2f} (#{row['fit_worst']}) | "
                f"{row['fit_over_3']} | {row['photo_median']:.2f} | {row['photo_max']:.2f} | "
                f"{row['residual_median']:.2f} |"
            )
    if "examples" in args.parts:
        results["examples"] = examples = library_from_examples(settings)
        print(
            f"(d) library fitted from one photo per class ({examples['classes']} classes): "
            f"{examples['fitted_right']}/{examples['photos']} fresh photos top-1 correct; "
            f"the true library: {examples['true_right']}/{examples['photos']}"
        )
    return results


if __name__ == "__main__":
    main()
