"""Benchmark ``rockscan triage`` on a rendered folder.

Measures, on one machine and in one run (ratios, so that a busy machine
shifts both sides alike):

* speed-up of 2 worker processes over 1 (target: at least 1.7x);
* overhead of triage on 1 worker over the sum of per-photo classify times
  (target: at most 1.3x): walking, writing rows, ranking, the report;
* peak memory of the whole ``rockscan triage`` process for N photos and for
  4N photos (target: flat).

Usage::

    python scripts/bench_triage.py                 # 500 and 2,000 photos, 480 x 640 JPEG
    python scripts/bench_triage.py --photos 100 --memory-photos 400 --keep bench-photos

The figures go to standard output as a Markdown table (docs/triage.md
records them) and, with ``--json FILE``, as JSON.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from rockscan.core.render import RenderConfig, render_photo
from rockscan.io import default_library, default_spec_path, read_spec
from rockscan.io.folders import find_photos
from rockscan.run.pipeline import classify_path
from rockscan.run.triage import TriageConfig, triage_folder


def _render_one(args: tuple[Path, int, int, int, int]) -> None:
    folder, index, seed, rows, cols = args
    shapes = [s for s in read_spec(default_spec_path()) if s.params is not None]
    shape = shapes[index % len(shapes)]
    rng = np.random.default_rng([seed, index])
    photo = render_photo(shape.params, RenderConfig(rows=rows, cols=cols), rng=rng, name=shape.name)
    # A folder per 100 photos, as a camera's card would hold them.
    path = folder / f"{index // 100:03d}" / f"{index:05d}-{shape.name}.jpg"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(photo.encode(".jpg"))


def render_folder(folder: Path, count: int, *, rows: int, cols: int, seed: int = 0) -> None:
    """Render ``count`` photos of the default library's shapes into ``folder`` (in parallel)."""
    with ProcessPoolExecutor() as pool:
        list(pool.map(_render_one, [(folder, i, seed, rows, cols) for i in range(count)], chunksize=16))


def link_subset(source: Path, target: Path, count: int) -> None:
    """The first ``count`` photos of ``source`` as hard links under ``target`` (no copies)."""
    for path in find_photos(source).photos[:count]:
        dest = target / Path(path).relative_to(source)
        dest.parent.mkdir(parents=True, exist_ok=True)
        os.link(path, dest)


def classify_times(folder: Path) -> tuple[list[float], float]:
    """Seconds to classify each photo, one after another in this process, and
    the CPU time of them all."""
    library = default_library()
    photos = find_photos(folder).photos
    classify_path(photos[0], library)  # warm up: imports, scan templates
    times = []
    cpu = _cpu(resource.RUSAGE_SELF)
    for photo in photos:
        start = time.perf_counter()
        classify_path(photo, library)
        times.append(time.perf_counter() - start)
    return times, _cpu(resource.RUSAGE_SELF) - cpu


def _cpu(who: int) -> float:
    usage = resource.getrusage(who)
    return usage.ru_utime + usage.ru_stime


def triage_seconds(folder: Path, report: Path, workers: int) -> tuple[float, float, float]:
    """Wall time, CPU time of this process and CPU time of its (worker) children
    for one triage run in this process (library already built)."""
    library = default_library()
    cpu_self, cpu_children = _cpu(resource.RUSAGE_SELF), _cpu(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    summary = triage_folder(folder, report, library, TriageConfig(workers=workers, overwrite=True))
    elapsed = time.perf_counter() - start
    if summary.n_errors:
        raise SystemExit(f"benchmark photos failed: {summary.errors[:3]}")
    return (
        elapsed,
        _cpu(resource.RUSAGE_SELF) - cpu_self,
        _cpu(resource.RUSAGE_CHILDREN) - cpu_children,
    )


def peak_memory_mib(folder: Path, report: Path) -> tuple[float, float]:
    """Peak resident memory (MiB) and wall time of ``rockscan triage -j 1`` in its own process."""
    code = "import sys; from rockscan.cli import main; sys.argv[0] = 'rockscan'; main()"
    args = ["triage", str(folder), "-o", str(report), "-j", "1", "--overwrite", "--quiet"]
    start = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-c", code, *args])
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise SystemExit(f"rockscan triage exited with {proc.returncode}")
    return usage.ru_maxrss / 1024.0, time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--photos", type=int, default=500, help="photos for the speed figures")
    parser.add_argument("--memory-photos", type=int, default=2000, help="photos for the larger memory run")
    parser.add_argument("--size", default="480x640", help="photo size ROWSxCOLS")
    parser.add_argument("--repeat", type=int, default=2, help="runs of each timing (the best counts)")
    parser.add_argument("--keep", type=Path, default=None, help="render into this folder and keep it")
    parser.add_argument("--json", type=Path, default=None, help="also write the figures here")
    args = parser.parse_args()
    rows, cols = (int(v) for v in args.size.lower().split("x"))
    work = args.keep or Path(tempfile.mkdtemp(prefix="rockscan-bench-"))
    big, small = work / "photos-big", work / "photos-small"
    if not big.exists():
        print(f"rendering {args.memory_photos} photos of {rows} x {cols} ...", file=sys.stderr)
        render_folder(big, args.memory_photos, rows=rows, cols=cols)
    if not small.exists():
        link_subset(big, small, args.photos)
    n = len(find_photos(small).photos)

    print(f"classifying {n} photos one by one ...", file=sys.stderr)
    per_photo, classify_cpu = classify_times(small)
    total_classify = sum(per_photo)
    one, two = [], []
    for _ in range(args.repeat):
        # Alternate, so that a change in the machine's load touches both.
        print("triage -j 1 ...", file=sys.stderr)
        one.append(triage_seconds(small, work / "report-1.csv", 1))
        print("triage -j 2 ...", file=sys.stderr)
        two.append(triage_seconds(small, work / "report-2.csv", 2))
    same = (work / "report-1.csv").read_bytes() == (work / "report-2.csv").read_bytes()
    best_one, best_two = min(one), min(two)
    # Load-independent bound: with 2 workers the wall time is at least the
    # parent's CPU time and half the workers' CPU time.
    bound = best_one[1] / max(best_two[1], best_two[2] / 2)
    print("peak memory ...", file=sys.stderr)
    mem_small, wall_small = peak_memory_mib(small, work / "mem-small.csv")
    mem_big, wall_big = peak_memory_mib(big, work / "mem-big.csv")

    figures = {
        "photos": n,
        "size": f"{rows}x{cols}",
        "cores": os.cpu_count(),
        "classify_sum_s": round(total_classify, 2),
        "classify_median_ms": round(1000 * float(np.median(per_photo)), 1),
        "triage_j1_s": round(best_one[0], 2),
        "triage_j2_s": round(best_two[0], 2),
        "speedup_j2": round(best_one[0] / best_two[0], 2),
        "overhead_j1": round(best_one[0] / total_classify, 3),
        "overhead_ms_per_photo": round(1000 * (best_one[0] - total_classify) / n, 2),
        "classify_cpu_s": round(classify_cpu, 2),
        "overhead_j1_cpu": round(best_one[1] / classify_cpu, 3),
        "cpu_j1_s": round(best_one[1], 2),
        "cpu_j2_parent_s": round(best_two[1], 2),
        "cpu_j2_workers_s": round(best_two[2], 2),
        "speedup_j2_cpu_bound": round(bound, 2),
        "load_average_1min": round(os.getloadavg()[0], 2),
        "same_report_j1_j2": same,
        "memory_photos_small": n,
        "memory_photos_big": args.memory_photos,
        "peak_mib_small": round(mem_small, 1),
        "peak_mib_big": round(mem_big, 1),
        "peak_ratio": round(mem_big / mem_small, 3),
        "cli_wall_small_s": round(wall_small, 1),
        "cli_wall_big_s": round(wall_big, 1),
    }
    print("| figure | value | target |\n|---|---|---|")
    print(f"| photos ({rows} x {cols} JPEG) | {n} | |")
    print(f"| sum of per-photo classify times | {figures['classify_sum_s']} s | |")
    print(f"| triage -j 1, best of {args.repeat} | {figures['triage_j1_s']} s | |")
    print(f"| triage -j 2, best of {args.repeat} | {figures['triage_j2_s']} s | |")
    print(f"| speed-up, 2 workers over 1 (wall) | {figures['speedup_j2']}x | >= 1.7x |")
    print(
        f"| speed-up bound from CPU times (parent {figures['cpu_j2_parent_s']} s, "
        f"workers {figures['cpu_j2_workers_s']} s) | {figures['speedup_j2_cpu_bound']}x | |"
    )
    print(f"| triage -j 1 over sum of classify (wall) | {figures['overhead_j1']}x | <= 1.3x |")
    print(
        f"| triage -j 1 over classify, CPU time ({figures['cpu_j1_s']} s / {figures['classify_cpu_s']} s) "
        f"| {figures['overhead_j1_cpu']}x | |"
    )
    print(f"| reports of -j 1 and -j 2 identical | {same} | True |")
    print(
        f"| peak memory, {n} / {args.memory_photos} photos | {figures['peak_mib_small']} / "
        f"{figures['peak_mib_big']} MiB ({figures['peak_ratio']}x) | flat |"
    )
    print(f"| load average at the end (1 min, {os.cpu_count()} cores) | {figures['load_average_1min']} | |")
    if args.json:
        args.json.write_text(json.dumps(figures, indent=1) + "\n")


if __name__ == "__main__":
    main()
