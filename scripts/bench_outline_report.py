"""How close the reported ``outline`` stays to the traced one (docs/cli.md's table).

For rendered photos of the default library's shapes at three sizes, and
rocks of 1% of a 64 x 64 photo (about 40 px, the smallest the interface
names), clean and with 3% outline noise, over several seeds, prints per size: the traced and the
reported vertex counts, the largest difference between the reported polygon's
area and ``area_px`` and between its centroid and ``centroid``, and the size of
``outline`` in JSON. The interface allows 2% and 1 px.

    python scripts/bench_outline_report.py [--seeds 10]
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from rockscan.core.render import RenderConfig, render_photo
from rockscan.io import default_library, default_spec_path, read_spec
from rockscan.run.pipeline import classify_image

#: (rows, cols, share of the frame the rock covers; None: the renderer's default).
SIZES = ((64, 64, 0.01), (240, 320, None), (480, 640, None), (1200, 1600, None))
NOISES = (0.0, 0.03)


def _area_centroid(xy: np.ndarray) -> tuple[float, np.ndarray]:
    x, y = xy.T
    cross = x * np.roll(y, -1) - np.roll(x, -1) * y
    area = 0.5 * cross.sum()
    centroid = np.array([((x + np.roll(x, -1)) * cross).sum(), ((y + np.roll(y, -1)) * cross).sum()]) / (
        6 * area
    )
    return abs(area), centroid


def measure(rows: int, cols: int, share: float | None, seeds: int) -> dict[str, float]:
    library = default_library()
    shapes = [s for s in read_spec(default_spec_path()) if s.params is not None]
    traced, reported, area_error, centroid_error, size = [], [], [], [], []
    for seed in range(seeds):
        for noise in NOISES:
            for k, shape in enumerate(shapes):
                sized = {} if share is None else {"area_fraction": share}
                config = RenderConfig(rows=rows, cols=cols, outline_noise=noise, **sized)
                photo = render_photo(shape.params, config, rng=1000 * seed + k)
                rock = classify_image(photo.pixels, library)[0]
                record = rock.to_dict()
                xy = np.asarray(record["outline"], dtype=np.float64)
                area, centroid = _area_centroid(xy)
                traced.append(len(rock.outline.contour_rowcol))
                reported.append(len(xy))
                area_error.append(abs(area / record["area_px"] - 1.0))
                centroid_error.append(float(np.hypot(*(centroid - np.asarray(record["centroid"])))))
                size.append(len(json.dumps(record["outline"])) / 1000)
    return {
        "photos": len(reported),
        "traced": (min(traced), max(traced)),
        "reported": (min(reported), int(np.median(reported)), max(reported)),
        "area": 100 * max(area_error),
        "centroid": max(centroid_error),
        "json": (float(np.median(size)), max(size)),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10)
    args = parser.parse_args()
    print(
        "| photo | photos | traced vertices | reported vertices (min / median / max) "
        "| area vs `area_px` (max) | centroid vs `centroid` (max) | `outline` in JSON (median / max) |"
    )
    print("|---|---|---|---|---|---|---|")
    for rows, cols, share in SIZES:
        m = measure(rows, cols, share, args.seeds)
        rock = "" if share is None else f", rock {100 * share:g}%"
        print(
            f"| {rows} x {cols}{rock} | {m['photos']} | {m['traced'][0]}-{m['traced'][1]} | "
            f"{' / '.join(map(str, m['reported']))} | {m['area']:.2f}% | {m['centroid']:.2f} px | "
            f"{m['json'][0]:.1f} / {m['json'][1]:.1f} kB |",
            flush=True,
        )


if __name__ == "__main__":
    main()
