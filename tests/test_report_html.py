"""The contact sheet's content: photo links, badges, line colours that stay apart, size per card."""

from __future__ import annotations

import base64
import io
import re
from pathlib import Path

import cv2
import numpy as np
import pytest
from PIL import Image
from skimage.color import rgb2lab

from rockscan.core.render import RenderConfig, render_photo
from rockscan.core.superformula import SuperformulaParams
from rockscan.draw.plot import library_outline_rowcol
from rockscan.draw.sheet import LOW_SEGMENTATION_SCORE, OUTLINE_RGB, SHAPE_RGB, photo_href, render_html
from rockscan.io import default_spec_path, read_spec
from rockscan.io.report import read_rows
from rockscan.run.pipeline import classify_path
from rockscan.run.triage import TriageConfig, triage_folder

#: A textured 640 x 480 photo is a realistic thumbnail to measure.
REALISTIC = RenderConfig(rows=480, cols=640, rock_texture=0.08, ground_texture=0.08, pebbles=30)


@pytest.fixture(scope="module")
def sheet(tmp_path_factory, default_lib):
    root = tmp_path_factory.mktemp("html")
    specs = {s.name: s.params for s in read_spec(default_spec_path())}
    rng = np.random.default_rng(21)
    # The last, a four-lobed rock, is unlike its nearest shape: the two lines part.
    specs["four-lobe"] = SuperformulaParams(4, 4, 0.6, 1, 1)
    for i, name in enumerate(["five-armed-star", "egg", "six-pointed-star", "rounded-triangle", "four-lobe"]):
        photo = render_photo(specs[name], REALISTIC, rng=rng, name=name)
        path = root / "mission" / ("", "sol 12")[i % 2] / f"{i}-{name}.jpg"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(photo.encode(".jpg"))
    report = root / "reports" / "sheet.html"
    report.parent.mkdir()
    triage_folder(root / "mission", report, default_lib, TriageConfig(workers=1))
    return report, list(read_rows(report))


def _lab(rgb) -> np.ndarray:
    return rgb2lab(np.asarray(rgb, dtype=np.float64).reshape(-1, 1, 3) / 255.0).reshape(-1, 3)


def test_outline_and_library_shape_stay_apart_in_colour_at_thumbnail_size(sheet, default_lib):
    _, rows = sheet
    # The chosen colours themselves, and as each line comes out of a thumbnail.
    assert np.linalg.norm(_lab(OUTLINE_RGB) - _lab(SHAPE_RGB)) > 100
    measured = []
    for row in rows:
        thumb = _picture(row["thumbnail"])
        (rock,) = classify_path(row["path"], default_lib).rocks
        scale = np.array(thumb.shape[:2]) / np.array([REALISTIC.rows, REALISTIC.cols])
        outline = _line_mask(rock.outline.contour_rowcol, scale, thumb.shape[:2])
        # The library shape where the outline (drawn over it) does not hide it.
        near_outline = cv2.dilate(outline.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
        shape = _line_mask(library_outline_rowcol(default_lib, rock), scale, thumb.shape[:2]) & ~near_outline
        assert outline.sum() > 100
        if shape.sum() < 20:  # the lines agree all round
            continue
        seen_outline = np.median(_lab(thumb[outline]), axis=0)
        seen_shape = np.median(_lab(thumb[shape]), axis=0)
        measured.append(np.linalg.norm(seen_outline - seen_shape))
    # CIE76: 2.3 is a just-noticeable difference; 40 is two colours nobody confuses.
    assert measured and min(measured) > 40, measured


def _picture(uri: str) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(base64.b64decode(uri.split(",")[1]))).convert("RGB"))


def _line_mask(rowcol: np.ndarray, scale: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """The pixels of a closed line through photo (row, col) points, drawn on the thumbnail."""
    xy = ((rowcol + 0.5) * scale - 0.5)[:, ::-1]
    out = np.zeros(shape, np.uint8)
    cv2.polylines(out, [np.round(xy).astype(np.int32)], True, 1, 1)
    return out.astype(bool)


def test_each_card_links_its_photo_relative_to_the_report_and_carries_badges(sheet):
    report, rows = sheet
    page = report.read_text()
    for row in rows:
        href = photo_href(row["path"], report)
        assert not href.startswith("/") and f'href="{href}"' in page
        assert (report.parent / href.replace("%20", " ")).resolve() == Path(row["path"]).resolve()
    n_interesting = sum(bool(r["interesting"]) for r in rows)
    assert page.count('class="badge interesting"') == n_interesting > 0
    low = [r for r in rows if r["segmentation_score"] < LOW_SEGMENTATION_SCORE]
    assert page.count('class="badge lowseg"') == len(low)


def test_badges_for_novel_and_doubtful_rocks():
    row = {
        "rank": 1,
        "path": "a.png",
        "interest": 2.0,
        "match": None,
        "nearest": "egg",
        "mscore": 0.4,
        "angle_deg": 10.0,
        "novelty": 0.5,
        "novel": True,
        "interesting": False,
        "segmentation_score": 0.2,
        "error": None,
    }
    page = render_html([row], n_rows=1, n_errors=0)
    assert 'class="badge novel"' in page and 'class="badge lowseg"' in page
    assert 'class="badge interesting"' not in page
    assert 'data-novel="1"' in page and 'data-lowseg="1"' in page


def test_a_2000_rock_sheet_stays_under_10_mb(sheet):
    _, rows = sheet
    options = {"n_rows": 2000, "n_errors": 0, "report": Path("reports/sheet.html")}
    empty = len(render_html([], **options).encode())
    # Every card with a path of 120 characters (a path shows in a card four times).
    long = [{**row, "path": "m/" + "x" * 114 + ".jpg"} for row in rows]
    per_card = max(len(render_html([row], **options).encode()) - empty for row in long)
    assert empty + 2000 * per_card < 10_000_000


def test_the_embedded_provenance_holds_no_markup_and_reads_back():
    import json
    import re

    # "<!--<script>" in a folder's name put the HTML parser in the script element's
    # double-escaped state: the element swallowed the page's own script, and the
    # sheet's sorting, filter and shape list stopped working.
    provenance = {"photos": {"folder": "/data/<!--<script>/a&b", "relative_to": None}, "rockscan": "x"}
    page = render_html([], n_rows=0, n_errors=0, provenance=provenance)
    body = re.search(r'<script type="application/json" id="provenance-json">(.*?)</script>', page, re.S)
    assert body is not None and not set("<>&") & set(body.group(1))
    assert json.loads(body.group(1)) == provenance
    assert page.count("<script") == 2  # the provenance, and the page's own script


def test_the_page_of_a_running_resume_shows_a_photo_tried_again_once(tmp_path):
    from rockscan.io.report import ROW_KEYS, ReportJournal
    from rockscan.run.report import refresh_html

    report = tmp_path / "r.html"
    row = {
        **dict.fromkeys(ROW_KEYS),
        **{"interest": 0.5, "mscore": 0.5, "match": "egg", "nearest": "egg", "angle_deg": 10.0},
        **{"interesting": False, "segmentation_score": 0.9},
    }
    with ReportJournal(report) as journal:
        journal.append({**row, "path": "a.png"})
        journal.append({**dict.fromkeys(ROW_KEYS), "path": "late.png", "error": "late.png: file is empty"})
        # The resume's row for it, while the run goes on.
        journal.append({**row, "path": "late.png", "interest": 0.9})
    refresh_html(report)
    page = report.read_text()
    assert "file is empty" not in page
    # Paths are relative to the working folder: each card shows its path the same number of times.
    assert page.count("late.png") == page.count("a.png") > 0


def test_a_grains_sizes_show_their_digits_on_its_card():
    row = {
        "rank": 1,
        "path": "grain.png",
        "interest": 0.5,
        "match": "egg",
        "nearest": "egg",
        "mscore": 0.5,
        "angle_deg": 10.0,
        "interesting": False,
        "segmentation_score": 0.9,
        "error": None,
        "equivalent_diameter_mm": 0.0432,
        "area_mm2": 0.00147,
    }
    page = render_html([row], n_rows=1, n_errors=0)
    assert "0.0432 mm across, 0.00147 mm&sup2;" in page


def test_the_page_of_a_running_resume_shows_a_replaced_photos_new_rocks_only(tmp_path):
    from rockscan.io.report import ROW_KEYS, ReportJournal
    from rockscan.run.report import refresh_html

    report = tmp_path / "r.html"
    row = {
        **dict.fromkeys(ROW_KEYS),
        **{"mscore": 0.5, "match": "egg", "nearest": "egg", "angle_deg": 10.0},
        **{"interesting": False, "segmentation_score": 0.9},
    }
    with ReportJournal(report) as journal:
        journal.append([{**row, "path": "a.png", "index": i, "interest": 0.1 * i} for i in range(3)])
        journal.append({**row, "path": "b.png", "index": 0, "interest": 0.5})
        # a.png replaced under its name, classified again while the run goes on: one rock now.
        journal.append({**row, "path": "a.png", "index": 0, "interest": 0.9, "nearest": "lens"})
    refresh_html(report)
    page = report.read_text()
    cards = re.findall(r'<figure class="card" [^>]*data-interest="([^"]*)"[^>]*data-path="([^"]*)"', page)
    assert cards == [("0.9", "a.png"), ("0.5", "b.png")]
    assert "2 ranked, 0 errors" in page
