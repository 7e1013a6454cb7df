"""Benchmark of the core matcher: the rotation scan, library building, library size.

Measures, in one run, with ``time.perf_counter`` and the median of repeats:

(a) scoring all rotations of a sample against a 100-shape library, as a ratio
    to scoring one rotation. *Matcher alone* starts from the sample term ``q``
    of the face: all rotations are ``library.scan_templates.squared_distances``
    (then the square root), one rotation is the direct projection
    ``library.basis.distances(weights * q)``. *End to end* starts from the radii:
    ``match_radii(radii, library)`` (scan) against
    ``match_radii(radii, library, MatchConfig(scan=False))``. The timed calls
    take turns within every repeat, so a busy machine slows both sides alike.
(b) building a library of 1,000 random shapes: wall time and peak memory
    (``tracemalloc``, in a separate build so that its bookkeeping does not slow
    the timed ones), then the scan templates that the first match builds.
(c) matching cost for libraries of 10, 100 and 1,000 shapes, and per shape.

(a) and (c) run twice: with the BLAS threads numpy starts with, and in a child
process limited to one BLAS thread (the direct projection is one BLAS call that
can use every core, while the scan's per-frequency products each run on one).

Random libraries come from :func:`rockscan.core.render.random_superformula`.
Writes the figures into ``--doc`` (a README section). ``--quick`` runs a tiny
version for smoke tests.

Usage::

    python scripts/bench_core.py [--doc docs/core-benchmark.md]
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
import tracemalloc
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from rockscan.core.information import sample_term
from rockscan.core.library import Library, ShapeSpec
from rockscan.core.match import MatchConfig, match_radii
from rockscan.core.render import random_superformula
from rockscan.core.superformula import shape_radii

ROOT = Path(__file__).resolve().parents[1]
PAPER = MatchConfig.paper()
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
ONE_ROTATION = "one rotation, direct projection"
ONE_MATCH = "match_radii, scan=False"
SCAN_ROWS = (
    ONE_ROTATION,
    "all rotations, eigenspace distance",
    "all rotations, eigenspace and face distances",
    ONE_MATCH,
    "match_radii, default (scan)",
    "match_radii, paper's method (scan)",
)


@dataclass(frozen=True)
class Settings:
    """Sizes and repeats of the benchmark."""

    seed: int = 7
    scan_size: int = 100
    build_size: int = 1000
    build_repeats: int = 3
    sizes: tuple[int, ...] = (10, 100, 1000)
    repeats: int = 50
    n_samples: int = 5


QUICK = Settings(scan_size=12, build_size=30, build_repeats=1, sizes=(4, 8, 16), repeats=3, n_samples=2)


@dataclass(frozen=True)
class Workload:
    """The random shapes every measurement draws from (the same in every process)."""

    specs: list[ShapeSpec]
    radii: list[np.ndarray]

    @classmethod
    def draw(cls, settings: Settings) -> Workload:
        rng = np.random.default_rng(settings.seed)
        n = max(settings.build_size, settings.scan_size, *settings.sizes)
        specs = [ShapeSpec(f"shape-{i}", random_superformula(rng)) for i in range(n)]
        radii = []
        for _ in range(settings.n_samples):
            # Shapes in no library, turned, with 3 % radial noise.
            r = np.roll(shape_radii(random_superformula(rng), 360), int(rng.integers(360)))
            radii.append(r * (1.0 + 0.03 * rng.standard_normal(360)))
        return cls(specs=specs, radii=radii)


def median_times(functions: dict[str, Callable[[], object]], repeats: int) -> dict[str, float]:
    """Median seconds per call; every repeat calls each function once, in turn."""
    for function in functions.values():
        function()  # warm-up: caches, lazily built templates
    times: dict[str, list[float]] = {name: [] for name in functions}
    for _ in range(repeats):
        for name, function in functions.items():
            start = time.perf_counter()
            function()
            times[name].append(time.perf_counter() - start)
    return {name: float(np.median(t)) for name, t in times.items()}


def cycle(functions: Sequence[Callable[[], object]]) -> Callable[[], object]:
    """A call that runs the next of ``functions``: spreads the repeats over the samples."""
    state = {"i": 0}

    def call() -> object:
        state["i"] = (state["i"] + 1) % len(functions)
        return functions[state["i"]]()

    return call


def _one_rotation(library: Library, radii: np.ndarray) -> Callable[[], object]:
    q = sample_term(radii, library.face_config)
    weights = library.reference_map
    return lambda: library.basis.distances(weights * q)


def _all_rotations(library: Library, radii: np.ndarray, metrics: tuple[str, ...]) -> Callable[[], object]:
    q = sample_term(radii, library.face_config)
    return lambda: {k: np.sqrt(v) for k, v in library.scan_templates.squared_distances(q, metrics).items()}


def _match(library: Library, radii: np.ndarray, config: MatchConfig) -> Callable[[], object]:
    return lambda: match_radii(radii, library, config)


def bench_scan(library: Library, radii: list[np.ndarray], repeats: int) -> dict[str, float]:
    """(a): all rotations against one, matcher alone and end to end; seconds per sample."""
    makers: dict[str, Callable[[np.ndarray], Callable[[], object]]] = {
        ONE_ROTATION: lambda r: _one_rotation(library, r),
        SCAN_ROWS[1]: lambda r: _all_rotations(library, r, ("eigenspace",)),
        SCAN_ROWS[2]: lambda r: _all_rotations(library, r, ("eigenspace", "face")),
        ONE_MATCH: lambda r: _match(library, r, MatchConfig(scan=False)),
        SCAN_ROWS[4]: lambda r: _match(library, r, MatchConfig()),
        SCAN_ROWS[5]: lambda r: _match(library, r, PAPER),
    }
    return median_times({name: cycle([make(r) for r in radii]) for name, make in makers.items()}, repeats)


def bench_sizes(workload: Workload, sizes: Sequence[int], repeats: int) -> dict[str, dict[str, float]]:
    """(c): seconds per match for each library size, end to end and the scan alone."""
    out = {}
    for size in sizes:
        library = Library.from_shapes(workload.specs[:size])
        times = median_times(
            {
                "match": cycle([_match(library, r, MatchConfig()) for r in workload.radii]),
                "scan": cycle([_all_rotations(library, r, ("eigenspace", "face")) for r in workload.radii]),
            },
            repeats,
        )
        out[str(size)] = {**times, "n_components": float(library.basis.n_components)}
    return out


def bench_build(specs: list[ShapeSpec], repeats: int) -> dict[str, object]:
    """(b): seconds and peak bytes to build a library, then its scan templates."""
    seconds, template_seconds = [], []
    for _ in range(repeats):
        start = time.perf_counter()
        library = Library.from_shapes(specs)
        seconds.append(time.perf_counter() - start)
        start = time.perf_counter()
        _ = library.scan_templates
        template_seconds.append(time.perf_counter() - start)
        del library
    tracemalloc.start()
    library = Library.from_shapes(specs)
    kept, build_peak = tracemalloc.get_traced_memory()
    tracemalloc.reset_peak()
    _ = library.scan_templates
    with_templates, templates_peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return {
        "seconds": float(np.median(seconds)),
        "seconds_all": seconds,
        "template_seconds": float(np.median(template_seconds)),
        "peak_bytes": float(build_peak),
        "kept_bytes": float(kept),
        "template_peak_bytes": float(templates_peak),
        "template_bytes": float(with_templates - kept),
        "n_components": library.basis.n_components,
    }


def timings(settings: Settings, workload: Workload) -> dict[str, object]:
    """(a) and (c) in this process."""
    library = Library.from_shapes(workload.specs[: settings.scan_size])
    scan = bench_scan(library, workload.radii, settings.repeats)
    del library
    return {"scan": scan, "sizes": bench_sizes(workload, settings.sizes, settings.repeats)}


def single_thread_timings(argv: Sequence[str]) -> dict[str, object]:
    """(a) and (c) again in a child process limited to one BLAS thread."""
    env = {**os.environ, **dict.fromkeys(THREAD_VARIABLES, "1")}
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "timings.json"
        command = [sys.executable, str(Path(__file__).resolve()), *argv, "--timings-only", str(out)]
        subprocess.run(command, env=env, check=True)
        return json.loads(out.read_text(encoding="utf-8"))


# ---------------------------------------------------------------- the README section


def _mib(n_bytes: object) -> str:
    return f"{float(n_bytes) / 2**20:.0f} MiB"


def _verdict(ok: bool) -> str:
    return "met" if ok else "not met"


def scan_table(runs: dict[str, dict[str, object]]) -> list[str]:
    head = "| Path |" + "".join(f" {name}: time | ratio |" for name in runs)
    lines = [head, "|---|" + "---|---|" * len(runs)]
    for row in SCAN_ROWS:
        cells = []
        for run in runs.values():
            scan = run["scan"]
            assert isinstance(scan, dict)
            base = scan[ONE_MATCH if row.startswith("match_radii") else ONE_ROTATION]
            cells.append(f" {scan[row] * 1e3:.2f} ms | {scan[row] / base:.2f} |")
        lines.append(f"| {row} |" + "".join(cells))
    return lines


def size_table(runs: dict[str, dict[str, object]]) -> tuple[list[str], list[str]]:
    lines = [
        "| Shapes | Eigenfaces |"
        + "".join(f" {name}: `match_radii` | per shape | scan alone | per shape |" for name in runs),
        "|---|---|" + "---|---|---|---|" * len(runs),
    ]
    first = next(iter(runs.values()))["sizes"]
    assert isinstance(first, dict)
    keys = list(first)
    for key in keys:
        size = int(key)
        cells = []
        for run in runs.values():
            t = run["sizes"][key]
            cells.append(
                f" {t['match'] * 1e3:.2f} ms | {t['match'] / size * 1e6:.1f} us | {t['scan'] * 1e3:.2f} ms "
                f"| {t['scan'] / size * 1e6:.1f} us |"
            )
        lines.append(f"| {size} | {first[key]['n_components']:.0f} |" + "".join(cells))
    growth = []
    for name, run in runs.items():
        sizes = run["sizes"]
        assert isinstance(sizes, dict)
        steps = []
        linear = True
        for lo, hi in itertools.pairwise(keys):
            factor = int(hi) / int(lo)
            match = sizes[hi]["match"] / sizes[lo]["match"]
            scan = sizes[hi]["scan"] / sizes[lo]["scan"]
            linear &= match <= factor and scan <= factor
            steps.append(f"{lo} -> {hi} shapes (x{factor:g}): match x{match:.2f}, scan x{scan:.2f}")
        growth.append(f"- {name}: " + "; ".join(steps) + f"; no worse than linear: {_verdict(linear)}.")
    return lines, growth


def report(
    settings: Settings,
    runs: dict[str, dict[str, object]],
    build: dict[str, object],
    load: tuple[float, float],
) -> str:
    """The README section, in markdown."""
    threads = ", ".join(f"{k}={os.environ[k]}" for k in THREAD_VARIABLES if k in os.environ)
    summary = []
    missed = []
    for name, run in runs.items():
        scan = run["scan"]
        assert isinstance(scan, dict)
        alone = scan[SCAN_ROWS[1]] / scan[ONE_ROTATION]
        both = scan[SCAN_ROWS[2]] / scan[ONE_ROTATION]
        end = scan[SCAN_ROWS[4]] / scan[ONE_MATCH]
        missed += [
            f"{what} with {name}"
            for what, r in (("matcher alone", max(alone, both)), ("end to end", end))
            if r > 3
        ]
        summary.append(
            f"- {name}: matcher alone {alone:.2f}x (paper's distance) and {both:.2f}x (both distances, as "
            f"the default matcher needs); end to end {end:.2f}x."
        )
    size_lines, growth = size_table(runs)
    seconds_all = build["seconds_all"]
    assert isinstance(seconds_all, list)
    lines = [
        "## Core benchmark",
        "",
        "`python scripts/bench_core.py` measures the matcher on random Superformula libraries "
        "(`rockscan.core.render.random_superformula`) and rewrites this section. Times are medians of "
        f"{settings.repeats} repeats with `time.perf_counter`, the timed calls taking turns within every "
        f"repeat. Measured on a machine with {os.cpu_count()} cores ({platform.machine()}, Python "
        f"{platform.python_version()}, numpy {np.__version__}), shared with other work (load average "
        f"{load[0]:.1f} at the start, {load[1]:.1f} at the end), so read ratios rather than absolute "
        "times. Faces: the defaults (360 rays of 50 sections). Each timing runs twice: with the BLAS "
        f"threads numpy starts with ({threads or 'its default'}) and in a child process with one BLAS "
        "thread.",
        "",
        f"### All 360 rotations against one ({settings.scan_size}-shape library)",
        "",
        "*Matcher alone* starts from the sample's term of the face: all rotations are "
        "`library.scan_templates.squared_distances(q)` (then a square root), one rotation the direct "
        "projection `library.basis.distances(weights * q)`. *End to end* starts from the radii: "
        "`match_radii` with the scan against `MatchConfig(scan=False)`. Ratios are to the one-rotation path "
        "of the same kind. Target: all rotations cost at most 3 times one.",
        "",
        *scan_table(runs),
        "",
        *summary,
        "",
        ("Target of 3x: met everywhere." if not missed else f"Target of 3x: not met for {', '.join(missed)}.")
        + " The scan correlates the sample term with one template per eigenface by FFT along theta, then "
        "takes the products with each library shape from the eigenface coordinates: it reads as many numbers "
        "as the direct projection, in one small product per frequency instead of one large one. On a busy "
        "machine BLAS threads fight the other work for the cores, so there one BLAS thread "
        "(`OPENBLAS_NUM_THREADS=1`) is faster and steadier.",
        "",
        f"### Building a {settings.build_size}-shape library",
        "",
        "| Step | Time | Peak memory (tracemalloc) | Kept |",
        "|---|---|---|---|",
        f"| `Library.from_shapes` | {build['seconds']:.2f} s | {_mib(build['peak_bytes'])} "
        f"| {_mib(build['kept_bytes'])} |",
        f"| scan templates (first match) | {build['template_seconds']:.2f} s "
        f"| {_mib(build['template_peak_bytes'])} | {_mib(build['template_bytes'])} |",
        "",
        f"Median of {settings.build_repeats} builds ("
        + ", ".join(f"{s:.2f} s" for s in seconds_all)
        + f"); target under 10 s: {_verdict(float(build['seconds']) < 10)}. The basis keeps "
        f"{build['n_components']} eigenfaces, those with a non-zero eigenvalue.",
        "",
        "### Matching cost against library size",
        "",
        *size_lines,
        "",
        "Growth with the library (target: no worse than linear):",
        "",
        *growth,
        "",
    ]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--doc", type=Path, default=ROOT / "docs" / "core-benchmark.md", help="README section to write"
    )
    parser.add_argument("--repeats", type=int, default=None, help="timed repeats per measurement")
    parser.add_argument("--quick", action="store_true", help="a tiny run for smoke tests (seconds)")
    parser.add_argument("--timings-only", type=Path, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    settings = QUICK if args.quick else Settings()
    if args.repeats is not None:
        if args.repeats < 1:
            parser.error("--repeats must be at least 1")
        settings = replace(settings, repeats=args.repeats)
    workload = Workload.draw(settings)
    if args.timings_only is not None:
        args.timings_only.write_text(json.dumps(timings(settings, workload)), encoding="utf-8")
        return 0

    load_start = os.getloadavg()[0]
    runs = {"BLAS default": timings(settings, workload)}
    build = bench_build(workload.specs[: settings.build_size], settings.build_repeats)
    child = ["--quick"] if args.quick else []
    child += ["--repeats", str(settings.repeats)]
    runs["1 BLAS thread"] = single_thread_timings(child)

    text = report(settings, runs, build, (load_start, os.getloadavg()[0]))
    args.doc.parent.mkdir(parents=True, exist_ok=True)
    args.doc.write_text(text, encoding="utf-8")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
