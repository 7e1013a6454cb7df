"""Draw docs/figures/triage-report.png: the HTML contact sheet as headless Chromium shows it.

    python scripts/figure_triage_report.py [-o docs/figures/triage-report.png]

A small mission is rendered (textured 480 x 640 photos of the built-in
library's shapes, two rocks unlike any of them, one broken file), triaged with
an observed library and a scale (``--observed``, ``--px-per-mm 8``) to an HTML
report, and the page is photographed by ``chromium --headless --screenshot``.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from rockscan.core.novelty import NoveltyConfig
from rockscan.core.render import RenderConfig, render_photo
from rockscan.core.superformula import SuperformulaParams
from rockscan.io import default_library, default_spec_path, read_spec
from rockscan.run.pipeline import ClassifyConfig
from rockscan.run.triage import TriageConfig, triage_folder

PHOTO = RenderConfig(rows=480, cols=640, rock_texture=0.06, ground_texture=0.06, pebbles=20)


def mission(root: Path) -> Path:
    specs = [(s.name, s.params) for s in read_spec(default_spec_path())]
    odd = [
        ("four-lobed", SuperformulaParams(4, 4, 0.6, 1, 1)),
        ("seven-lobed", SuperformulaParams(7, 7, 2, 4, 4)),
    ]
    rng = np.random.default_rng(412)
    folder = Path("sol-0412")
    for i, (name, params) in enumerate(specs[:10] + odd):
        sub = folder / ("", "north")[i % 2]
        sub.mkdir(parents=True, exist_ok=True)
        config = dataclasses.replace(PHOTO, area_fraction=float(rng.uniform(0.04, 0.2)))
        photo = render_photo(params, config, rng=rng, name=name)
        (sub / f"{i:03d}-rock.jpg").write_bytes(photo.encode(".jpg"))
    (folder / "north" / "099-cut.jpg").write_bytes(b"\xff\xd8\xff\xe0 cut short")
    return folder


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", default="docs/figures/triage-report.png")
    parser.add_argument("--size", default="1200,1000", help="window width,height in pixels")
    args = parser.parse_args()
    chromium = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")
    if chromium is None:
        sys.exit("figure_triage_report.py: needs Chromium (apt-get install chromium)")
    output = Path(args.output).resolve()
    here = os.getcwd()
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        # Paths as a user gives them: relative to the working folder.
        os.chdir(root)
        folder = mission(root)
        report = root / "sol-0412.html"
        config = TriageConfig(
            workers=1, classify=ClassifyConfig(px_per_mm=8.0), novelty=NoveltyConfig(), thumbnail_size=144
        )
        triage_folder(folder, report, default_library(), config, observed=root / "observed.npz")
        out = output
        out.parent.mkdir(parents=True, exist_ok=True)
        subprocess.run(
            [
                chromium,
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--hide-scrollbars",
                f"--window-size={args.size}",
                f"--screenshot={out}",
                report.as_uri(),
            ],
            check=True,
            capture_output=True,
        )
        os.chdir(here)
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
