"""Speed of classifying a photo, as ratios to a floor measured in the same run.

The floor is the least any shape tool must do with the same file: OpenCV reads
it, turns it gray, blurs it, thresholds it by Otsu's method and finds its
contours. rockscan's times are measured interleaved with the floor's, many
times over, so that a busy machine slows both alike; the table gives the
fastest and the median of the repetitions, and the ratios of each.

Rows:
* ``floor``: cv2.imread, cvtColor, GaussianBlur 5x5, Otsu threshold, findContours;
* ``classify_path``: rockscan reads the file and classifies it (in process);
* ``classify_image``: the same on pixels already decoded;
* ``read_image``: rockscan's reader alone;
* the stages of ``classify_image``: segmentation, outline and radii, matching.

Then ``rockscan --help`` is timed in a fresh interpreter, against a bare
``python -c pass``.

Run ``python scripts/bench_classify.py --help`` for options.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

from rockscan.core.match import match_radii
from rockscan.core.outline import trace_outline
from rockscan.core.polar import contour_radii
from rockscan.core.render import RenderConfig, render_photo
from rockscan.core.segment import segment
from rockscan.io import default_library, default_spec_path, read_image, read_spec
from rockscan.io.photos import write_photo
from rockscan.run.pipeline import classify_image, classify_path


def floor(path: str) -> None:
    """The least a shape tool does: read, gray, blur, Otsu, contours."""
    image = cv2.imread(path)
    gray = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    gray = cv2.GaussianBlur(gray, (5, 5), 0)
    _, binary = cv2.threshold(gray, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    cv2.findContours(binary, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)


def interleaved(tasks: dict[str, Callable[[], object]], repeats: int) -> dict[str, list[float]]:
    """Seconds per call of each task, the tasks taking turns ``repeats`` times."""
    for task in tasks.values():
        task()  # warm caches, lazy imports and the library's templates
    times: dict[str, list[float]] = {name: [] for name in tasks}
    for _ in range(repeats):
        for name, task in tasks.items():
            start = time.perf_counter()
            task()
            times[name].append(time.perf_counter() - start)
    return times


def stage_tasks(pixels: np.ndarray, library) -> dict[str, Callable[[], object]]:
    """The stages of classify_image, each on the previous stage's result."""
    seg = segment(pixels)
    rock = seg.rocks[0]
    outline = trace_outline(rock.coverage, scale=seg.scale_rowcol, origin_rowcol=rock.origin_rowcol)
    radii = contour_radii(outline.contour_rowcol, outline.centroid_rowcol, library.face_config.n_angles)

    def outline_and_radii() -> object:
        o = trace_outline(rock.coverage, scale=seg.scale_rowcol, origin_rowcol=rock.origin_rowcol)
        return contour_radii(o.contour_rowcol, o.centroid_rowcol, library.face_config.n_angles)

    return {
        "  segment": lambda: segment(pixels),
        "  outline and radii": outline_and_radii,
        "  match": lambda: match_radii(radii, library),
    }


def table(times: dict[str, list[float]], reference: str) -> str:
    lines = [
        "| step | fastest (ms) | median (ms) | fastest / floor | median / floor |",
        "|---|---|---|---|---|",
    ]
    best_ref, median_ref = min(times[reference]), statistics.median(times[reference])
    for name, values in times.items():
        best, median = min(values), statistics.median(values)
        lines.append(
            f"| {name.strip()} | {1e3 * best:.1f} | {1e3 * median:.1f} | "
            f"{best / best_ref:.2f} | {median / median_ref:.2f} |"
        )
    return "\n".join(lines)


def help_time(repeats: int) -> tuple[float, float]:
    """Median wall time of ``rockscan --help`` and of a bare interpreter, in a fresh process each."""
    cli = [
        sys.executable,
        "-c",
        "import sys; from rockscan.cli import main; sys.argv[0] = 'rockscan'; main()",
        "--help",
    ]
    bare = [sys.executable, "-c", "pass"]
    out = {}
    for name, command in (("help", cli), ("bare", bare)):
        values = []
        for _ in range(repeats):
            start = time.perf_counter()
            subprocess.run(command, check=True, capture_output=True)
            values.append(time.perf_counter() - start)
        out[name] = statistics.median(values)
    return out["help"], out["bare"]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--repeats", type=int, default=40, help="interleaved repetitions (default 40)")
    parser.add_argument("--size", default="768x1024", help="photo size ROWSxCOLS (default 768x1024)")
    parser.add_argument("--format", default="png", choices=["png", "jpg"], help="file format (default png)")
    parser.add_argument("--seed", type=int, default=7, help="render seed (default 7)")
    parser.add_argument(
        "--shape", default=None, help="default library shape to draw (default: the first, rounded-triangle)"
    )
    args = parser.parse_args(argv)
    rows, cols = (int(v) for v in args.size.lower().split("x"))
    library = default_library()
    specs = {spec.name: spec for spec in read_spec(default_spec_path())}
    if args.shape is not None and args.shape not in specs:
        parser.error(f"--shape must be one of {', '.join(specs)}")
    spec = specs[args.shape] if args.shape else next(iter(specs.values()))
    photo = render_photo(spec.params, RenderConfig(rows=rows, cols=cols), rng=args.seed, name=spec.name)
    with tempfile.TemporaryDirectory() as folder:
        path = str(Path(folder) / f"rock.{args.format}")
        write_photo(photo, path)
        pixels = read_image(path).pixels
        tasks: dict[str, Callable[[], object]] = {
            "floor": lambda: floor(path),
            "classify_path": lambda: classify_path(path, library),
            "classify_image": lambda: classify_image(pixels, library),
            "read_image": lambda: read_image(path),
            **stage_tasks(pixels, library),
        }
        times = interleaved(tasks, args.repeats)
    print(
        f"{rows}x{cols} {args.format.upper()} photo of a {spec.name}, "
        f"{args.repeats} interleaved repetitions\n"
    )
    print(table(times, "floor"))
    help_s, bare_s = help_time(max(5, args.repeats // 4))
    print(f"\n`rockscan --help`: {help_s:.3f} s (median; a bare `python -c pass`: {bare_s:.3f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
