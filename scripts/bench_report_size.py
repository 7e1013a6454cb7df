"""How big a 2,000-rock contact sheet is, and how much memory ranking a report takes per row.

    python scripts/bench_report_size.py [--photos 40] [--rows 2000]

1. Sheet size: ``--photos`` distinct textured 640 x 480 photos are triaged to an
   HTML report; its journal is then grown to ``--rows`` rows (each photo's row
   and thumbnail repeated under new 40-character paths, so every card is a
   realistic one) and ranked again. Prints the page's size and bytes per card.
2. Ranking memory: journals of N and 3N synthetic rows are ranked with the same
   chunk size; the difference in peak traced memory over 2N is what each row
   costs beyond a chunk (the ranking streams; see rockscan.run.report).
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

from rockscan.core.render import RenderConfig, render_photo
from rockscan.io import default_library, default_spec_path, read_spec
from rockscan.io.report import ROW_KEYS, ReportJournal, journal_path
from rockscan.run.report import finalize_report
from rockscan.run.triage import TriageConfig, triage_folder

REALISTIC = RenderConfig(rows=480, cols=640, rock_texture=0.08, ground_texture=0.08, pebbles=30)


def sheet_size(n_photos: int, n_rows: int, root: Path) -> None:
    specs = [(s.name, s.params) for s in read_spec(default_spec_path())]
    rng = np.random.default_rng(2000)
    for i in range(n_photos):
        name, params = specs[i % len(specs)]
        photo = render_photo(params, REALISTIC, rng=rng, name=name)
        (root / "photos").mkdir(exist_ok=True)
        (root / "photos" / f"{i:04d}-{name}.jpg").write_bytes(photo.encode(".jpg"))
    report = root / "sheet.html"
    triage_folder(root / "photos", report, default_library(), TriageConfig(workers=1))
    journal = journal_path(report)
    header, *rows = journal.read_text().splitlines()
    small = report.stat().st_size
    with open(journal, "w") as fh:
        fh.write(header + "\n")
        for i in range(n_rows):
            row = json.loads(rows[i % len(rows)])
            row["path"] = f"mission/sol-{i // 100:04d}/photo-{i:06d}.jpg"
            fh.write(json.dumps(row) + "\n")
    finalize_report(report, limit=n_rows)
    size = report.stat().st_size
    cards = report.read_text().count('<figure class="card"')
    print(f"sheet of {len(rows)} photos: {small / 1e6:.2f} MB")
    print(f"sheet of {cards} rocks: {size / 1e6:.2f} MB ({size / cards:.0f} bytes per card)")


def ranking_memory(n: int, chunk: int, root: Path) -> float:
    peaks = []
    for rows in (n, 3 * n):
        report = root / f"rank{rows}.csv"
        rng = np.random.default_rng(0)
        with ReportJournal(report, provenance={"bench": 1}) as journal:
            for i in range(rows):
                interest = float(rng.random())
                path = f"mission/sol-{i // 100:04d}/photo-{i:06d}.jpg"
                journal.append(
                    {**dict.fromkeys(ROW_KEYS), "path": path, "interest": interest, "mscore": interest}
                )
        tracemalloc.start()
        started = time.perf_counter()
        finalize_report(report, chunk_rows=chunk)
        elapsed = time.perf_counter() - started
        peaks.append(tracemalloc.get_traced_memory()[1])
        tracemalloc.stop()
        print(f"ranking {rows} rows (chunks of {chunk}): peak {peaks[-1] / 1e6:.1f} MB, {elapsed:.1f} s")
    per_row = (peaks[1] - peaks[0]) / (2 * n)
    print(f"memory per row beyond a chunk: {per_row:.1f} bytes")
    return per_row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--photos", type=int, default=40)
    parser.add_argument("--rows", type=int, default=2000)
    parser.add_argument("--rank-rows", type=int, default=20000)
    parser.add_argument("--chunk", type=int, default=5000)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        sheet_size(args.photos, args.rows, Path(tmp))
        ranking_memory(args.rank_rows, args.chunk, Path(tmp))


if __name__ == "__main__":
    main()
