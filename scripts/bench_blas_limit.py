"""What holding BLAS to one thread costs a photo, as a ratio in one run.

rockscan limits every BLAS library to one thread inside its numeric entry points
(rockscan/core/_threads.py) so that results do not depend on the thread count. This
times ``classify_path`` on rendered photos, and, interleaved with it, the limit
alone (entering and leaving once, as an outermost call does), and prints the
limit's share of a photo. Run ``python scripts/bench_blas_limit.py --help``.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from rockscan.core import _threads
from rockscan.core.render import RenderConfig, render_photo
from rockscan.io import default_library, default_spec_path, read_spec
from rockscan.run.pipeline import classify_path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--photos", type=int, default=6, help="rendered photos (default 6)")
    parser.add_argument("--repeats", type=int, default=5, help="passes over the photos (default 5)")
    args = parser.parse_args()

    library = default_library()
    shapes = read_spec(default_spec_path())
    limit = _threads.one_blas_thread(lambda: None)
    with tempfile.TemporaryDirectory() as tmp:
        paths = []
        for i in range(args.photos):
            photo = render_photo(shapes[i % len(shapes)].params, RenderConfig(), rng=[7, i])
            path = Path(tmp) / f"{i:04d}.png"
            path.write_bytes(photo.encode(".png"))
            paths.append(str(path))
        classify_path(paths[0], library)  # warm the library's templates
        photo_s, limit_s = [], []
        for _ in range(args.repeats):
            for path in paths:
                start = time.perf_counter()
                classify_path(path, library)
                photo_s.append(time.perf_counter() - start)
                start = time.perf_counter()
                for _ in range(100):
                    limit()
                limit_s.append((time.perf_counter() - start) / 100)
    photo, overhead = statistics.median(photo_s), statistics.median(limit_s)
    print(f"classify_path, median of {len(photo_s)}: {photo * 1e3:.1f} ms per photo")
    print(f"one-thread limit, enter and leave:  {overhead * 1e6:.1f} us")
    print(f"share of a photo:                   {overhead / photo:.2e}")


if __name__ == "__main__":
    main()
