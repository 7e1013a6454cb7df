"""Benchmark of large libraries and large missions, in one run.

Measures (medians of repeats, ``time.perf_counter``; ratios within the run, as
the machine may be shared):

(a) building libraries of 1,000, 10,000 and 100,000 random Superformula shapes
    (``Library.from_shapes``), each in a fresh child process: wall time and the
    child's peak resident memory (``getrusage``), less what the process held
    before the build;
(b) one match (``match_radii``, default settings) against the 10,000- and
    100,000-shape libraries, against the exhaustive scan of the same library;
(c) agreement: the nearest shape of the pruned scan against the exhaustive
    scan's, for ``--queries`` samples (library shapes turned at random, with
    radial noise of 0-20%) against the 10,000-shape library; and MScore;
(d) what the truncated basis changes: the nearest shape of a 1,000-shape
    library with its exact basis (every non-zero eigenface) against the same
    library built the large way (128 eigenfaces of a random sample), both
    scanned exhaustively;
(e) adding one shape to an observed library (``ObservedShapes.with_shape``) of
    1,000 and of 100,000 shapes;
(f) the command line: ``rockscan library build`` of a 10,000-shape spec, and
    ``rockscan classify --library`` of that file;
(g) triage on a Dask ``LocalCluster`` of 1, 2 and 4 worker processes
    (``rockscan triage --scheduler``): photos per second and peak memory of
    every process.

Random shapes are drawn as :func:`rockscan.core.render.random_superformula` draws
them (m from 1 to 8, n1 and n2 log-uniform in [0.3, 20], n3 = n2 in 60% of
draws, longest radius under 3.5 times the shortest), vectorised.

Usage::

    python scripts/bench_scale.py [--sizes 1000 10000 100000] [--queries 2000] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from rockscan.core.library import Library, ShapeSpec, closed_shapes_radii
from rockscan.core.match import match_radii
from rockscan.core.novelty import NoveltyConfig, ObservedShapes
from rockscan.core.superformula import SuperformulaParams
from rockscan.io import save_library, write_spec

ROOT = Path(__file__).resolve().parents[1]


def draw_shapes(n: int, seed: int) -> list[SuperformulaParams]:
    """``n`` random rock-like Superformula shapes, as random_superformula draws them."""
    rng = np.random.default_rng(seed)
    out: list[SuperformulaParams] = []
    while len(out) < n:
        k = 2 * (n - len(out)) + 64
        m = rng.integers(1, 9, size=k).astype(float)
        n1, n2, n3 = (np.exp(rng.uniform(np.log(0.3), np.log(20), size=k)) for _ in range(3))
        n3 = np.where(rng.random(k) < 0.6, n2, n3)
        params = [SuperformulaParams(*v) for v in zip(m, m, n1, n2, n3, strict=True)]
        for start in range(0, k, 4096):
            chunk = params[start : start + 4096]
            radii, closed = closed_shapes_radii(chunk, 360)
            closed &= radii.max(axis=1) / radii.min(axis=1) < 3.5
            out += [p for p, ok in zip(chunk, closed, strict=True) if ok]
    return out[:n]


def specs(params: list[SuperformulaParams]) -> list[ShapeSpec]:
    return [ShapeSpec(f"shape-{i}", p) for i, p in enumerate(params)]


def noisy_queries(library: Library, n: int, seed: int) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """Library shapes turned by a random whole number of rays, with 0-20% radial noise.

    Returns the radii, each one's source shape and its noise level.
    """
    rng = np.random.default_rng(seed)
    sources = rng.integers(len(library), size=n)
    noise = rng.uniform(0.0, 0.2, size=n)
    out = []
    for source, level in zip(sources, noise, strict=True):
        radii = np.roll(library.radii[source], int(rng.integers(360)))
        out.append(np.maximum(radii * (1.0 + level * rng.standard_normal(radii.size)), 1e-3))
    return out, sources, noise


def peak_rss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def child_build(n: int, seed: int, out: str | None) -> None:
    """In a fresh process: build an n-shape library, print time and memory as JSON."""
    shapes = specs(draw_shapes(n, seed))
    before = peak_rss_mib()
    start, cpu = time.perf_counter(), time.process_time()
    library = Library.from_shapes(shapes)
    seconds, cpu = time.perf_counter() - start, time.process_time() - cpu
    peak = peak_rss_mib()
    if out:
        save_library(library, out)
    print(
        json.dumps(
            {
                "n": n,
                "seconds": seconds,
                "cpu_seconds": cpu,
                "peak_mib": peak,
                "before_mib": before,
                "components": library.basis.n_components,
            }
        )
    )


def run_child(*args: str) -> dict:
    text = (
        subprocess.run([sys.executable, __file__, *args], check=True, capture_output=True, text=True)
        .stdout.strip()
        .splitlines()[-1]
    )
    return json.loads(text)


def median_ms(function, items) -> tuple[float, float]:  # type: ignore[no-untyped-def]
    """Median wall and CPU milliseconds of one call (CPU time is what a shared machine
    does not inflate, as long as the process runs on one core)."""
    times, cpus = [], []
    for item in items:
        start, cpu = time.perf_counter(), time.process_time()
        function(item)
        times.append(time.perf_counter() - start)
        cpus.append(time.process_time() - cpu)
    return 1e3 * float(np.median(times)), 1e3 * float(np.median(cpus))


def exhaustive(library: Library) -> Library:
    """The same library, scanned whole."""
    return library.scanned_whole()


def load() -> str:
    one, five, _ = os.getloadavg()
    return f"{one:.1f} (1 min), {five:.1f} (5 min)"


def measure_agreement(library: Library, n_queries: int, seed: int) -> dict:
    """Pruned against exhaustive, default settings (``metric="auto"``): each query is
    ranked by the same metric in both (the choice depends on the sample alone)."""
    from rockscan.core.match import _clean_enough

    queries = noisy_queries(library, n_queries, seed)[0]
    whole = exhaustive(library)
    pruned, full = [], []
    c_pruned, c_full, t_pruned, t_full = [], [], [], []
    for q in queries:
        start, cpu = time.perf_counter(), time.process_time()
        pruned.append(match_radii(q, library))
        t_pruned.append(time.perf_counter() - start)
        c_pruned.append(time.process_time() - cpu)
        start, cpu = time.perf_counter(), time.process_time()
        full.append(match_radii(q, whole))
        t_full.append(time.perf_counter() - start)
        c_full.append(time.process_time() - cpu)
    clean = np.array([_clean_enough(q, library) for q in queries])
    same = np.array([a.nearest == b.nearest for a, b in zip(pruned, full, strict=True)])
    angle = np.array([a.angle_deg == b.angle_deg for a, b in zip(pruned, full, strict=True)])
    sensor = np.abs([a.sensor_distance - b.sensor_distance for a, b in zip(pruned, full, strict=True)])
    mscore = np.abs([a.mscore - b.mscore for a, b in zip(pruned, full, strict=True)])
    flags = np.mean([a.interesting == b.interesting for a, b in zip(pruned, full, strict=True)])
    return {
        "queries": n_queries,
        "ranked_by_sensor": int((~clean).sum()),
        "ranked_by_eigenspace": int(clean.sum()),
        "agreement": float(same.mean()),
        "disagreements": int((~same).sum()),
        "agreement_sensor_ranked": float(same[~clean].mean()) if (~clean).any() else None,
        "agreement_eigenspace_ranked": float(same[clean].mean()) if clean.any() else None,
        "same_angle": float(angle.mean()),
        "sensor_distance_error_max": float(sensor.max()),
        "mscore_error_median": float(np.median(mscore)),
        "mscore_error_p99": float(np.quantile(mscore, 0.99)),
        "interesting_agreement": float(flags),
        "pruned_ms": 1e3 * float(np.median(t_pruned)),
        "pruned_cpu_ms": 1e3 * float(np.median(c_pruned)),
        "pruned_cpu_ms_p90": 1e3 * float(np.quantile(c_pruned, 0.9)),
        "pruned_cpu_ms_sensor_ranked": 1e3 * float(np.median(np.asarray(c_pruned)[~clean])),
        "pruned_cpu_ms_eigenspace_ranked": 1e3 * float(np.median(np.asarray(c_pruned)[clean]))
        if clean.any()
        else None,
        "exhaustive_ms": 1e3 * float(np.median(t_full)),
        "exhaustive_cpu_ms": 1e3 * float(np.median(c_full)),
        "load": load(),
    }


def measure_load(path: Path, n_queries: int, seed: int) -> dict:
    """Reading a library file, then what its first match sets up (CPU and wall)."""
    from rockscan.io import load_library

    out = {}
    start, cpu = time.perf_counter(), time.process_time()
    library = load_library(path)
    out["load_s"], out["load_cpu_s"] = time.perf_counter() - start, time.process_time() - cpu
    query = noisy_queries(library, 1, seed)[0][0]
    start, cpu = time.perf_counter(), time.process_time()
    match_radii(query, library)
    out["first_match_s"], out["first_match_cpu_s"] = time.perf_counter() - start, time.process_time() - cpu
    return out


def measure_truncation(n: int, n_queries: int, seed: int) -> dict:
    shapes = specs(draw_shapes(n, seed))
    exact = Library.from_shapes(shapes)
    truncated = Library.from_shapes(shapes, exact_limit=0)
    queries, sources, noise = noisy_queries(exact, n_queries, seed + 1)
    a = np.array([exact.index(match_radii(q, exhaustive(exact)).nearest) for q in queries])
    b = np.array([exact.index(match_radii(q, exhaustive(truncated)).nearest) for q in queries])
    low = noise <= 0.05
    return {
        "shapes": n,
        "exact_components": exact.basis.n_components,
        "truncated_components": truncated.basis.n_components,
        "agreement": float(np.mean(a == b)),
        "agreement_low_noise": float(np.mean((a == b)[low])),
        "exact_finds_source": float(np.mean(a == sources)),
        "truncated_finds_source": float(np.mean(b == sources)),
        "exact_finds_source_low_noise": float(np.mean((a == sources)[low])),
        "truncated_finds_source_low_noise": float(np.mean((b == sources)[low])),
        "queries": n_queries,
    }


def measure_observed(library: Library, adds: int, seed: int) -> tuple[float, float]:
    """Median CPU ms of one ``with_shape`` after the first (which sets up the growing
    arrays), and of one ``assess`` of the grown library."""
    rng = np.random.default_rng(seed)
    observed = ObservedShapes.from_library(library, NoveltyConfig(threshold=0.1))
    observed = observed.with_shape("seen-first", library.radii[0] * (1 + 0.05 * rng.standard_normal(360)))
    observed.assess(library.radii[1])
    times, assess = [], []
    for i in range(adds):
        radii = library.radii[rng.integers(len(library))] * (1 + 0.05 * rng.standard_normal(360))
        start = time.process_time()
        observed = observed.with_shape(f"seen-{i}", radii)
        times.append(time.process_time() - start)
        start = time.process_time()
        observed.assess(radii)
        assess.append(time.process_time() - start)
    return 1e3 * float(np.median(times)), 1e3 * float(np.median(assess))


def measure_cli(n: int, seed: int, folder: Path) -> dict:
    spec = folder / "spec.toml"
    write_spec(specs(draw_shapes(n, seed)), spec)
    lib_path = folder / "lib.npz"
    env = dict(os.environ)
    start, children = time.perf_counter(), _children_cpu()
    subprocess.run(
        ["rockscan", "library", "build", str(spec), "-o", str(lib_path)],
        check=True,
        capture_output=True,
        env=env,
    )
    build_s, build_cpu = time.perf_counter() - start, _children_cpu() - children
    photo = ROOT / "data" / "examples" / "0001-six-pointed-star.jpg"
    start, children = time.perf_counter(), _children_cpu()
    subprocess.run(
        ["rockscan", "classify", "--json", "--library", str(lib_path), str(photo)],
        check=True,
        capture_output=True,
        env=env,
    )
    classify_s, classify_cpu = time.perf_counter() - start, _children_cpu() - children
    start, children = time.perf_counter(), _children_cpu()
    subprocess.run(["rockscan", "classify", "--json", str(photo)], check=True, capture_output=True, env=env)
    default_s, default_cpu = time.perf_counter() - start, _children_cpu() - children
    return {
        "shapes": n,
        "build_s": build_s,
        "build_cpu_s": build_cpu,
        "classify_s": classify_s,
        "classify_cpu_s": classify_cpu,
        "classify_default_library_s": default_s,
        "classify_default_library_cpu_s": default_cpu,
        "file_mib": lib_path.stat().st_size / 2**20,
        **measure_load(lib_path, 1, 5),
        "load": load(),
    }


def _children_cpu() -> float:
    """CPU seconds of every finished child process so far (user + system)."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def measure_cluster(photos: int, workers: tuple[int, ...], folder: Path) -> list[dict]:
    """``rockscan triage --scheduler`` on LocalClusters of each size: photos/s and memory."""
    import psutil
    from dask.distributed import LocalCluster

    sys.path.insert(0, str(ROOT / "scripts"))
    from bench_triage import render_folder

    photo_dir = folder / "photos"
    render_folder(photo_dir, photos, rows=480, cols=640)
    rows = []
    for count in workers:
        with LocalCluster(
            n_workers=count, threads_per_worker=1, processes=True, dashboard_address=None
        ) as cluster:
            report = folder / f"report-{count}.csv"
            start = time.perf_counter()
            proc = subprocess.Popen(
                [
                    "rockscan",
                    "triage",
                    str(photo_dir),
                    "-o",
                    str(report),
                    "--scheduler",
                    cluster.scheduler_address,
                ],
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
            peak_client, peak_workers = 0.0, 0.0
            pids = [w.pid for w in cluster.workers.values() if hasattr(w, "pid")]
            while proc.poll() is None:
                try:
                    peak_client = max(peak_client, psutil.Process(proc.pid).memory_info().rss / 2**20)
                    peak_workers = max(
                        peak_workers,
                        max((psutil.Process(p).memory_info().rss / 2**20 for p in pids), default=0.0),
                    )
                except psutil.Error:
                    pass
                time.sleep(0.2)
            seconds = time.perf_counter() - start
            rows.append(
                {
                    "workers": count,
                    "seconds": seconds,
                    "photos_per_s": photos / seconds,
                    "peak_client_mib": peak_client,
                    "peak_worker_mib": peak_workers,
                    "returncode": proc.returncode,
                }
            )
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[1000, 10000, 100000])
    parser.add_argument("--queries", type=int, default=2000)
    parser.add_argument("--match-queries", type=int, default=200)
    parser.add_argument("--photos", type=int, default=120)
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2, 4])
    parser.add_argument("--seed", type=int, default=11)
    parser.add_argument(
        "--skip",
        nargs="*",
        default=[],
        help="parts to leave out: build agreement truncation observed cli cluster",
    )
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--child", nargs=2, metavar=("N", "OUT"), default=None, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        child_build(int(args.child[0]), args.seed, args.child[1] if args.child[1] != "-" else None)
        return 0
    results: dict = {
        "machine": f"{os.cpu_count()} cores, {platform.machine()}, Python {platform.python_version()}",
        "load_start": load(),
    }
    print(f"# load average at the start: {results['load_start']}", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        libraries = {}
        if "build" not in args.skip:
            results["build"] = []
            for n in args.sizes:
                out = folder / f"lib-{n}.npz"
                row = run_child("--child", str(n), str(out), "--seed", str(args.seed))
                row["load"] = load()
                results["build"].append(row)
                libraries[n] = out
                print(
                    f"build {n:>7} shapes: {row['seconds']:7.1f} s (CPU {row['cpu_seconds']:.1f} s), "
                    f"peak {row['peak_mib']:7.0f} MiB "
                    f"({row['peak_mib'] - row['before_mib']:.0f} MiB above the {row['before_mib']:.0f} MiB "
                    f"before), {row['components']} eigenfaces; load {row['load']}",
                    flush=True,
                )
        from rockscan.io import load_library

        big = [n for n in libraries if n >= 10000]
        results["match"] = []
        for n in big:
            library = load_library(libraries[n])
            queries = noisy_queries(library, args.match_queries, args.seed + n)[0]
            match_radii(queries[0], library)
            pruned, pruned_cpu = median_ms(lambda q, lib=library: match_radii(q, lib), queries)
            whole = exhaustive(library)
            match_radii(queries[0], whole)
            some = queries[: max(20, args.match_queries // 10)]
            full, full_cpu = median_ms(lambda q, lib=whole: match_radii(q, lib), some)
            results["match"].append(
                {"shapes": n, "pruned_ms": pruned, "pruned_cpu_ms": pruned_cpu, "exhaustive_ms": full,
                 "exhaustive_cpu_ms": full_cpu, "load": load()}
            )  # fmt: skip
            print(
                f"match {n:>7} shapes: {pruned:.2f} ms pruned (CPU {pruned_cpu:.2f} ms), {full:.2f} ms "
                f"exhaustive (CPU {full_cpu:.2f} ms), x{full_cpu / pruned_cpu:.1f} in CPU; load {load()}",
                flush=True,
            )
        if "agreement" not in args.skip and 10000 in libraries:
            row = measure_agreement(load_library(libraries[10000]), args.queries, args.seed + 1)
            results["agreement"] = row
            print(
                f"agreement, 10,000 shapes, {row['queries']} queries ({row['ranked_by_sensor']} ranked "
                f"by the sensor distance, {row['ranked_by_eigenspace']} by the eigenspace one): "
                f"{100 * row['agreement']:.2f}% ({row['disagreements']} differ), same angle "
                f"{100 * row['same_angle']:.2f}%, sensor distance error max "
                f"{row['sensor_distance_error_max']:.2g}; "
                f"MScore error median {row['mscore_error_median']:.4f}, p99 {row['mscore_error_p99']:.4f}; "
                f"interesting flag {100 * row['interesting_agreement']:.2f}%; match CPU median "
                f"{row['pruned_cpu_ms']:.1f} ms (p90 {row['pruned_cpu_ms_p90']:.1f}; sensor-ranked "
                f"{row['pruned_cpu_ms_sensor_ranked']:.1f}, eigenspace-ranked "
                f"{row['pruned_cpu_ms_eigenspace_ranked'] or 0:.1f}), wall {row['pruned_ms']:.1f} ms; "
                f"exhaustive CPU {row['exhaustive_cpu_ms']:.1f} ms, wall {row['exhaustive_ms']:.1f} ms; "
                f"load {row['load']}",
                flush=True,
            )
        if "truncation" not in args.skip:
            row = measure_truncation(1000, min(args.queries, 500), args.seed + 2)
            results["truncation"] = row
            print(
                f"truncation, 1,000 shapes: {row['exact_components']} eigenfaces vs "
                f"{row['truncated_components']}: the same nearest shape for {100 * row['agreement']:.1f}% of "
                f"{row['queries']} ({100 * row['agreement_low_noise']:.1f}% at noise <= 5%); the source"
                f" shape found {100 * row['exact_finds_source']:.1f}% vs "
                f"{100 * row['truncated_finds_source']:.1f}% "
                f"(noise <= 5%: {100 * row['exact_finds_source_low_noise']:.1f}% vs "
                f"{100 * row['truncated_finds_source_low_noise']:.1f}%)",
                flush=True,
            )
        if "observed" not in args.skip and libraries:
            sizes = sorted(libraries)
            small, large = load_library(libraries[sizes[0]]), load_library(libraries[sizes[-1]])
            # The same small library built the large way (a streamed basis of 128 eigenfaces
            # that grows by Gram-Schmidt, as the large one's does).
            streamed = Library.from_shapes(specs(draw_shapes(sizes[0], args.seed)), exact_limit=0)
            rows = {
                f"{sizes[0]} exact basis": (small, measure_observed(small, 30, 1)),
                f"{sizes[0]} streamed basis": (streamed, measure_observed(streamed, 30, 1)),
                f"{sizes[-1]} streamed basis": (large, measure_observed(large, 30, 2)),
            }
            results["observed"] = {
                name: {"shapes": len(lib), "components": lib.basis.n_components, "add_ms": a, "assess_ms": b}
                for name, (lib, (a, b)) in rows.items()
            }
            for name, row in results["observed"].items():
                print(
                    f"observed, {name} ({row['components']} eigenfaces): add {row['add_ms']:.2f} ms, "
                    f"assess {row['assess_ms']:.2f} ms (CPU)",
                    flush=True,
                )
            keys = list(results["observed"])
            print(
                f"observed add ratio {sizes[-1]} / {sizes[0]}: "
                f"{results['observed'][keys[2]]['add_ms'] / results['observed'][keys[0]]['add_ms']:.2f} "
                f"against the exact basis, "
                f"{results['observed'][keys[2]]['add_ms'] / results['observed'][keys[1]]['add_ms']:.2f} "
                f"against the streamed one; load {load()}",
                flush=True,
            )
        if "cli" not in args.skip:
            row = measure_cli(10000, args.seed + 3, folder)
            results["cli"] = row
            print(
                f"CLI, 10,000 shapes: library build {row['build_s']:.1f} s (CPU {row['build_cpu_s']:.1f} s); "
                f"classify --library {row['classify_s']:.2f} s (CPU {row['classify_cpu_s']:.2f} s), default "
                f"library {row['classify_default_library_s']:.2f} s (CPU "
                f"{row['classify_default_library_cpu_s']:.2f} s); file {row['file_mib']:.0f} MiB, load "
                f"{row['load_s']:.2f} s (CPU {row['load_cpu_s']:.2f} s), first match "
                f"{row['first_match_s']:.2f} s (CPU {row['first_match_cpu_s']:.2f} s); "
                f"load average {row['load']}",
                flush=True,
            )
        if "cluster" not in args.skip:
            rows = measure_cluster(args.photos, tuple(args.workers), folder)
            results["cluster"] = rows
            base = rows[0]["photos_per_s"]
            for row in rows:
                print(
                    f"LocalCluster {row['workers']} workers: {row['photos_per_s']:.1f} photos/s "
                    f"(x{row['photos_per_s'] / base:.2f}), peak client {row['peak_client_mib']:.0f} MiB, "
                    f"worker {row['peak_worker_mib']:.0f} MiB",
                    flush=True,
                )
    results["load_end"] = load()
    print(f"# load average at the end: {results['load_end']}")
    if args.json:
        args.json.write_text(json.dumps(results, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
