"""The HTML contact sheet of a triage report: one card per rock, best first.

The page is self-contained (styles, script and thumbnails inline, no network
access) and written as a stream (:func:`sheet_writer`), so a report of any
size is never held in memory. Each card links to its photo by a path relative
to the report, carries badges (interesting, novel, low segmentation score),
and the footer says how the report was made (its provenance).
"""

from __future__ import annotations

import html
import json
import math
import os
from collections.abc import Callable, Generator, Iterable
from functools import cache
from importlib import resources
from pathlib import Path
from typing import Any
from urllib.parse import quote

from rockscan.io.report import THUMBNAIL_KEY, photo_key, shown_text

__all__ = ["LOW_SEGMENTATION_SCORE", "OUTLINE_RGB", "SHAPE_RGB", "render_html", "sheet_writer"]

#: A rock whose ``segmentation_score`` is below this gets the "check outline" badge.
LOW_SEGMENTATION_SCORE = 0.5
#: Colours of the thumbnails' lines: the traced outline (yellow) and the matched
#: library shape (blue), far apart in lightness and hue (CIE76 distance ~ 170),
#: so they stay two lines at thumbnail size.
OUTLINE_RGB = (255, 221, 0)
SHAPE_RGB = (0, 102, 255)

_SORTS = (
    ("rank", "rank"),
    ("interest", "interest"),
    ("mscore", "MScore"),
    ("novelty", "novelty"),
    ("angle", "angle"),
    ("segmentation", "segmentation"),
    ("match", "match"),
    ("path", "photo"),
)


@cache
def _asset(name: str) -> str:
    return resources.files("rockscan.draw").joinpath("_sheet_assets", name).read_text(encoding="utf-8")


def _number(value: Any) -> str:
    # Six digits sort and filter the page; the report's files keep every digit.
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return ""
    return f"{value:.6g}"


def _esc(text: str) -> str:
    return html.escape(shown_text(text), quote=True)


def photo_href(path: str, report: Path | None) -> str:
    """A link from the report's folder to the photo (relative, percent-encoded bytes)."""
    target = photo_key(path)
    if report is not None:
        base = os.path.dirname(photo_key(os.fspath(report)))
        target = os.path.relpath(target, base)
    return quote(os.fsencode(target).replace(os.sep.encode(), b"/"), safe="/")


def _card(row: dict[str, Any], report: Path | None) -> str:
    path = row["path"]
    error = row.get("error")
    seg = row.get("segmentation_score")
    low_seg = seg is not None and seg < LOW_SEGMENTATION_SCORE
    attrs = {
        "rank": "" if row.get("rank") is None else str(row["rank"]),
        "interest": _number(row.get("interest")),
        "mscore": _number(row.get("mscore")),
        "angle": _number(row.get("angle_deg")),
        "novelty": _number(row.get("novelty")),
        "segmentation": _number(seg),
        "match": row.get("match") or row.get("nearest") or "",
        "path": path,
        "index": str(row.get("index") or 0),
        "error": "1" if error is not None else "0",
        "interesting": "1" if row.get("interesting") else "0",
        "novel": "1" if row.get("novel") else "0",
        "lowseg": "1" if low_seg else "0",
    }
    data = " ".join(f'data-{k}="{_esc(v)}"' for k, v in attrs.items())
    href = photo_href(path, report)
    thumb = row.get(THUMBNAIL_KEY)
    image = (
        f'<img src="{html.escape(thumb, quote=True)}" alt="{_esc(path)}" loading="eager">'
        if thumb
        else '<div class="noimage">no image</div>'
    )
    badges = []
    if row.get("interesting"):
        badges.append('<span class="badge interesting">interesting</span>')
    if row.get("novel"):
        badges.append('<span class="badge novel">novel</span>')
    if low_seg:
        badges.append(
            f'<span class="badge lowseg" title="segmentation score {seg:.2f}: the outline may be wrong">'
            "check outline</span>"
        )
    if error is not None:
        # The message names the photo already; the card shows the path below it.
        message = error[len(path) + 2 :] if error.startswith(f"{path}: ") else error
        text = f'<span class="error">error: {_esc(message)}</span>'
    else:
        shape = row.get("match")
        verdict = f"<b>{_esc(shape)}</b>" if shape else f"no match (nearest {_esc(row['nearest'])})"
        rock = f" rock {row['index']}" if row.get("index") else ""
        parts = [
            f'<span class="rank">#{row["rank"]}</span>{rock} {verdict}' if row.get("rank") else verdict,
            f"interest {row['interest']:.3f} &middot; MScore {row['mscore']:.3f}",
            f"angle {row['angle_deg']:.1f}&deg;"
            + (f" &middot; novelty {row['novelty']:.3f}" if row.get("novelty") is not None else ""),
        ]
        if row.get("equivalent_diameter_mm") is not None:
            parts.append(
                # Three significant digits: a grain under a microscope is 0.0 mm across to one decimal.
                f'<span class="sizes">{row["equivalent_diameter_mm"]:.3g} mm across, '
                f"{row['area_mm2']:.3g} mm&sup2;</span>"
            )
        text = "<br>".join(parts)
    return (
        f'<figure class="card" {data}><a class="photo" href="{href}">{image}</a>'
        f'<div class="badges">{"".join(badges)}</div><figcaption>{text}'
        f'<span class="path">{_esc(path)}</span></figcaption></figure>\n'
    )


def _footer(provenance: dict[str, Any] | None) -> str:
    if provenance is None:
        return "<footer><p>This report does not record how it was made.</p></footer>"
    items = []
    for key, value in provenance.items():
        if isinstance(value, dict):
            shown = ", ".join(f"{k} {_plain(v)}" for k, v in value.items() if v is not None)
        else:
            shown = _plain(value)
        items.append(f"<dt>{_esc(str(key))}</dt><dd>{_esc(shown) or '-'}</dd>")
    # No "<", ">" or "&" inside the script element: "<!--<script>" in a folder's name put
    # the HTML parser in a state where the element swallowed the page's own script.
    full = (
        json.dumps(provenance, sort_keys=True)
        .replace("<", "\\u003c")
        .replace(">", "\\u003e")
        .replace("&", "\\u0026")
    )
    return (
        "<footer><p><b>How this report was made</b> (a report is resumed only with the same settings):</p>"
        f'<dl id="provenance">{"".join(items)}</dl>'
        f'<script type="application/json" id="provenance-json">{full}</script></footer>'
    )


def _plain(value: Any) -> str:
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} {_plain(v)}" for k, v in value.items() if v is not None) + "}"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return f"{value:.6g}"
    return str(value)


def sheet_writer(
    write: Callable[[bytes], object],
    *,
    n_rows: int,
    n_errors: int,
    title: str = "rockscan triage",
    report: Path | None = None,
    journal_name: str = "",
    limit: int = 2000,
    provenance: dict[str, Any] | None = None,
    in_progress: bool = False,
) -> Generator[None, dict[str, Any], None]:
    """Write the contact sheet as rows are sent to it, best first.

    Parameters
    ----------
    write : callable
        Takes the page's bytes (UTF-8), piece by piece.
    n_rows, n_errors : int
        Rows and error rows in the whole report.
    title : str
    report : Path, optional
        Where the page is written (photo links are relative to its folder).
    journal_name : str
        File name of the journal that holds every row (linked from the page).
    limit : int
        The page shows the best ``limit`` rocks and the first ``limit`` error
        rows; later rows sent are skipped.
    provenance : dict, optional
        Shown in the footer.
    in_progress : bool
        The run is still going (stated on the page).

    Yields
    ------
    None
        Send ranked rows (with ``thumbnail`` data URIs where there is one);
        ``close()`` ends the page.
    """
    n_ranked = n_rows - n_errors
    notes = [f"{n_rows} rocks: {n_ranked} ranked, {n_errors} error{'' if n_errors == 1 else 's'}."]
    if n_ranked > limit or n_errors > limit:
        notes.append(f"This page shows the best {limit} and at most {limit} errors.")
    if journal_name:
        link = html.escape(quote(os.fsencode(journal_name)), quote=True)
        notes.append(f'Every row is in <a href="{link}">{_esc(journal_name)}</a>.')
    if in_progress:
        notes.append("The run is still going: this page is a snapshot.")
    weighted = bool(provenance and (provenance.get("interest") or {}).get("novelty_weight"))
    rule = "MScore times the matched shape's interest" + (
        ", or the novelty reward where that is more (see the footer)" if weighted else ""
    )
    sort_buttons = "".join(
        f'<button type="button" class="sort" data-key="{key}">{label}</button>' for key, label in _SORTS
    )
    outline, shape = ("#{:02x}{:02x}{:02x}".format(*rgb) for rgb in (OUTLINE_RGB, SHAPE_RGB))
    write(
        _HEAD.format(
            title=_esc(title),
            notes=" ".join(notes),
            rule=rule,
            style=_asset("sheet.css"),
            outline=outline,
            shape=shape,
            sort_buttons=sort_buttons,
            n_rows=n_rows,
        ).encode("utf-8")
    )
    n_ok = n_bad = 0
    try:
        while True:
            row = yield
            is_error = row.get("error") is not None
            if (n_bad if is_error else n_ok) < limit:
                write(_card(row, report).encode("utf-8", "replace"))
                n_bad += is_error
                n_ok += not is_error
    except GeneratorExit:
        write(_TAIL.format(footer=_footer(provenance), script=_asset("sheet.js")).encode("utf-8"))


def render_html(rows: Iterable[dict[str, Any]], **options: Any) -> str:
    """The whole contact sheet as a string (see :func:`sheet_writer` for ``options``)."""
    parts: list[bytes] = []
    gen = sheet_writer(parts.append, **options)
    next(gen)
    for row in rows:
        gen.send(row)
    gen.close()
    return b"".join(parts).decode("utf-8")


_HEAD = """<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{title}</title>
<style>{style}</style>
</head>
<body>
<header>
<h1>{title}</h1>
<p>{notes} Ranked by interest: {rule}.</p>
<p class="legend">On each photo: <i style="background:#333;color:{outline}">yellow</i> the rock's outline,
<i style="background:#fff;color:{shape}">blue</i> the matched library shape turned by the found angle.
Click a photo to open it.</p>
</header>
<div id="controls">
<span>Sort:</span> {sort_buttons}
<input id="filter" type="search" placeholder="filter: photo or shape" aria-label="filter by photo or shape">
<select id="shape" aria-label="matched shape"><option value="">all shapes</option></select>
<label>interest &ge;
<input id="min-interest" type="number" step="0.1" min="0" aria-label="least interest"></label>
<label><input type="checkbox" id="only-interesting"> interesting only</label>
<label><input type="checkbox" id="only-novel"> novel only</label>
<label><input type="checkbox" id="show-errors" checked> errors</label>
<span id="count">{n_rows} rocks</span>
</div>
<main id="sheet">
"""

_TAIL = """</main>
{footer}
<script>{script}</script>
</body>
</html>
"""
