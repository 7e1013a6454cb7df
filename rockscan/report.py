"""Triage reports: CSV, JSON lines or HTML, written a row at a time and ranked at the end.

A report is first a *journal*: every photo's row is appended and flushed as
soon as it is known, so a run that is killed leaves every finished row behind,
complete, and a run started again with ``resume`` skips them. When the run
ends the journal is ranked (:func:`rank_key`) and rewritten in place
atomically (a temporary file renamed over it).

* ``.csv`` and ``.jsonl`` (or ``.ndjson``) reports are their own journal.
* An ``.html`` report keeps its journal beside it, ``REPORT.jsonl`` (the same
  rows as a JSON lines report, plus each photo's thumbnail as a data URI). The
  page is a contact sheet of the best ``limit`` rows and the errors, built from
  the journal when the run ends (and from time to time during it); the
  journal keeps every row.

This module knows rows and files only; :mod:`rockscan.triage` makes the rows.
"""

from __future__ import annotations

import csv
import html
import io
import json
import math
import os
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO

from rockscan.errors import ParameterError

__all__ = [
    "CSV_COLUMNS",
    "REPORT_FORMATS",
    "ROW_KEYS",
    "RankedReport",
    "ReportJournal",
    "finalize_report",
    "journal_path",
    "photo_key",
    "rank_key",
    "read_rows",
    "render_html",
    "report_format",
    "write_html",
]

#: Report file endings and their formats.
REPORT_FORMATS = {".csv": "csv", ".jsonl": "jsonl", ".ndjson": "jsonl", ".html": "html", ".htm": "html"}

#: Keys of a report row, in order. ``match`` ... ``area_px`` are exactly the
#: keys and values of ``rockscan classify --json`` for the photo's main rock.
ROW_KEYS = (
    "rank",
    "path",
    "interest",
    "match",
    "nearest",
    "mscore",
    "distance",
    "angle_deg",
    "interesting",
    "shape_interest",
    "novelty",
    "novel",
    "nearest_observed",
    "residual",
    "symmetry",
    "centroid",
    "index",
    "area_px",
    "error",
)

#: CSV columns: the row keys with ``centroid`` split into x and y.
CSV_COLUMNS = tuple(
    part for key in ROW_KEYS for part in (("centroid_x", "centroid_y") if key == "centroid" else (key,))
)
_FLOATS = {
    "interest",
    "mscore",
    "distance",
    "angle_deg",
    "shape_interest",
    "novelty",
    "residual",
    "area_px",
    "centroid_x",
    "centroid_y",
}
_INTS = {"rank", "symmetry", "index"}
_BOOLS = {"interesting", "novel"}
#: Journal-only key of HTML reports: the thumbnail as a data URI.
THUMBNAIL_KEY = "thumbnail"


def report_format(path: str | os.PathLike[str]) -> str:
    """The format of a report file from its ending: ``"csv"``, ``"jsonl"`` or ``"html"``.

    Parameters
    ----------
    path : path-like

    Raises
    ------
    ParameterError
        For any other ending.
    """
    suffix = Path(path).suffix.lower()
    if suffix not in REPORT_FORMATS:
        raise ParameterError(
            f"{path}: a report must end in .csv, .jsonl (JSON lines) or .html, not {suffix or 'nothing'!r}"
        )
    return REPORT_FORMATS[suffix]


def journal_path(path: str | os.PathLike[str]) -> Path:
    """Where a report's rows are appended while it runs: the report itself, or
    ``REPORT.jsonl`` beside an HTML report."""
    path = Path(path)
    return path.with_name(path.name + ".jsonl") if report_format(path) == "html" else path


def photo_key(path: str) -> str:
    """The identity of a photo across runs: its absolute, normalised path
    (symbolic links are not resolved: two links are two photos)."""
    return os.path.normcase(os.path.abspath(path))


def rank_key(row: dict[str, Any]) -> tuple[int, float, float, str]:
    """Sort key of a row: photos by decreasing interest, then decreasing MScore,
    then path; error rows last, by path."""
    if row.get("error") is not None:
        return (1, 0.0, 0.0, row["path"])
    return (0, -float(row["interest"]), -float(row["mscore"]), row["path"])


# ---------------------------------------------------------------- encoding


def _encode(row: dict[str, Any], fmt: str) -> bytes:
    if fmt == "csv":
        buf = io.StringIO()
        csv.writer(buf, lineterminator="\n").writerow([_csv_cell(v) for v in _csv_values(row)])
        return buf.getvalue().encode("utf-8")
    return (json.dumps(row, ensure_ascii=False) + "\n").encode("utf-8")


def _csv_values(row: dict[str, Any]) -> list[Any]:
    out = []
    for key in ROW_KEYS:
        value = row.get(key)
        if key == "centroid":
            out.extend(value if value is not None else (None, None))
        else:
            out.append(value)
    return out


def _csv_cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        # repr round-trips every float exactly.
        return repr(value)
    return str(value)


def _decode(record: bytes, fmt: str, source: Path) -> dict[str, Any]:
    text = record.decode("utf-8", errors="replace")
    if fmt != "csv":
        try:
            row = json.loads(text)
        except json.JSONDecodeError:
            raise ParameterError(f"{source}: a line is not JSON; is this a rockscan triage report?") from None
        if not isinstance(row, dict) or not isinstance(row.get("path"), str):
            raise ParameterError(f"{source}: a line has no photo path; is this a rockscan triage report?")
        return row
    (cells,) = list(csv.reader([text]))
    if len(cells) != len(CSV_COLUMNS):
        raise ParameterError(f"{source}: a row has {len(cells)} columns, not {len(CSV_COLUMNS)}")
    flat = {key: _parse_cell(key, cell, source) for key, cell in zip(CSV_COLUMNS, cells, strict=True)}
    cx, cy = flat.pop("centroid_x"), flat.pop("centroid_y")
    flat["centroid"] = None if cx is None else [cx, cy]
    return {key: flat[key] for key in ROW_KEYS}


def _parse_cell(key: str, cell: str, source: Path) -> Any:
    if cell == "":
        return None
    try:
        if key in _FLOATS:
            return float(cell)
        if key in _INTS:
            return int(cell)
    except ValueError:
        raise ParameterError(f"{source}: column {key} holds {cell!r}, not a number") from None
    if key in _BOOLS:
        return cell == "true"
    return cell


def _records(fh: BinaryIO, fmt: str) -> Iterator[tuple[int, bytes]]:
    """Complete records of a journal as (offset, bytes); a trailing record cut
    short by a crash (no final newline) is left out."""
    offset = fh.tell()
    pending, start, quotes = b"", offset, 0
    for line in fh:
        if not pending:
            start = offset
        offset += len(line)
        pending += line
        if not line.endswith(b"\n"):
            return
        if fmt == "csv":
            # A quoted CSV field may hold a newline: the record ends where the
            # count of quote characters is even ("" escapes one quote).
            quotes += line.count(b'"')
            if quotes % 2:
                continue
            quotes = 0
        if pending.strip():
            yield start, pending
        pending = b""


# ---------------------------------------------------------------- reading


def read_rows(path: str | os.PathLike[str]) -> Iterator[dict[str, Any]]:
    """The rows of a triage report, in file order (ranked once the run ended).

    Parameters
    ----------
    path : path-like
        A ``.csv``, ``.jsonl`` or ``.html`` report (an HTML report's rows are
        read from its journal ``REPORT.jsonl``).

    Yields
    ------
    row : dict
        Keys :data:`ROW_KEYS` (and ``thumbnail`` from an HTML report's journal).

    Raises
    ------
    ParameterError
        If the file is missing or not a triage report.
    """
    path = Path(path)
    fmt = "csv" if report_format(path) == "csv" else "jsonl"
    source = journal_path(path)
    try:
        fh = open(source, "rb")
    except FileNotFoundError:
        raise ParameterError(f"{source}: report not found") from None
    except OSError as exc:
        raise ParameterError(f"{source}: cannot read report ({exc.strerror or exc})") from None
    with fh:
        if fmt == "csv":
            _check_header(fh, source)
        for _, record in _records(fh, fmt):
            yield _decode(record, fmt, source)


def _check_header(fh: BinaryIO, source: Path) -> None:
    header = fh.readline().decode("utf-8", errors="replace").strip()
    if header != ",".join(CSV_COLUMNS):
        raise ParameterError(
            f"{source}: not a rockscan triage report (its first line is not the report's columns)"
        )


# ---------------------------------------------------------------- the journal


class ReportJournal:
    """Append-only rows of a report while it runs.

    Parameters
    ----------
    path : path-like
        The report (``.csv``, ``.jsonl`` or ``.html``).
    resume : bool
        Keep the rows of an earlier run and continue after them.
    overwrite : bool
        Start again even if the report exists.

    Attributes
    ----------
    done : set of str
        :func:`photo_key` of every photo already in the report.
    n_resumed : int
        Rows kept from earlier runs.

    Raises
    ------
    ParameterError
        If the report exists and neither ``resume`` nor ``overwrite`` is set,
        or it cannot be read or written.
    """

    def __init__(
        self, path: str | os.PathLike[str], *, resume: bool = False, overwrite: bool = False
    ) -> None:
        self.report = Path(path)
        self.format = report_format(self.report)
        self.path = journal_path(self.report)
        self._fmt = "csv" if self.format == "csv" else "jsonl"
        self.done: set[str] = set()
        exists = self.path.exists() or (self.format == "html" and self.report.exists())
        if exists and not (resume or overwrite):
            raise ParameterError(
                f"{self.report} exists: add --resume to continue it, or --overwrite to start again"
            )
        if resume and self.format == "html" and self.report.exists() and not self.path.exists():
            raise ParameterError(
                f"{self.report}: cannot resume, its rows ({self.path.name}) are missing; use --overwrite"
            )
        if self.report.is_dir() or self.path.is_dir():
            raise ParameterError(f"{self.report}: is a folder; give a report file name")
        try:
            if resume and self.path.exists():
                self._reopen()
            else:
                self._fh = open(self.path, "wb")
                if self._fmt == "csv":
                    self._fh.write((",".join(CSV_COLUMNS) + "\n").encode("utf-8"))
                    self._fh.flush()
        except OSError as exc:
            raise ParameterError(f"{self.path}: cannot write report ({exc.strerror or exc})") from None
        self.n_resumed = len(self.done)

    def _reopen(self) -> None:
        fh = open(self.path, "r+b")
        end = 0
        try:
            if self._fmt == "csv":
                if fh.read(1) == b"":
                    fh.write((",".join(CSV_COLUMNS) + "\n").encode("utf-8"))
                fh.seek(0)
                _check_header(fh, self.path)
                end = fh.tell()
            for offset, record in _records(fh, self._fmt):
                self.done.add(photo_key(_decode(record, self._fmt, self.path)["path"]))
                end = offset + len(record)
            # Drop a row cut short by a crash; it is done again.
            fh.truncate(end)
            fh.seek(end)
        except BaseException:
            fh.close()
            raise
        self._fh = fh

    def append(self, row: dict[str, Any]) -> None:
        """Write one row and hand it to the operating system at once.

        Parameters
        ----------
        row : dict
            Keys :data:`ROW_KEYS` (and ``thumbnail`` for an HTML report).
        """
        data = _encode(row, self._fmt)
        try:
            self._fh.write(data)
            self._fh.flush()
        except OSError as exc:
            raise ParameterError(f"{self.path}: cannot write report ({exc.strerror or exc})") from None
        self.done.add(photo_key(row["path"]))

    def close(self) -> None:
        """Close the journal file."""
        self._fh.close()

    def __enter__(self) -> ReportJournal:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


# ---------------------------------------------------------------- ranking


@dataclass(frozen=True)
class RankedReport:
    """What a finished report holds.

    Attributes
    ----------
    path : Path
        The report.
    n_rows : int
        Photos in it (each once).
    n_errors : int
        Error rows among them.
    top : tuple of dict
        The best ranked rows (without thumbnails), best first.
    errors : tuple of dict
        The first error rows, by path.
    """

    path: Path
    n_rows: int
    n_errors: int
    top: tuple[dict[str, Any], ...] = field(repr=False)
    errors: tuple[dict[str, Any], ...] = field(repr=False)


def _ranked(journal: Path, fmt: str) -> list[tuple[tuple[int, float, float, str], int, int]]:
    """(rank key, offset, length) of every photo's first row in a journal, ranked."""
    entries = []
    seen: set[str] = set()
    with open(journal, "rb") as fh:
        if fmt == "csv":
            _check_header(fh, journal)
        for offset, record in _records(fh, fmt):
            row = _decode(record, fmt, journal)
            key = photo_key(row["path"])
            if key in seen:
                continue
            seen.add(key)
            entries.append((rank_key(row), offset, len(record)))
    entries.sort()
    return entries


def _iter_ranked(
    journal: Path, fmt: str, entries: list[tuple[tuple[int, float, float, str], int, int]]
) -> Iterator[dict[str, Any]]:
    rank = 0
    with open(journal, "rb") as fh:
        for key, offset, length in entries:
            fh.seek(offset)
            row = _decode(fh.read(length), fmt, journal)
            if key[0] == 0:
                rank += 1
                row["rank"] = rank
            else:
                row["rank"] = None
            yield row


def finalize_report(
    path: str | os.PathLike[str],
    *,
    title: str = "rockscan triage",
    limit: int = 2000,
    n_top: int = 10,
    n_errors: int = 20,
) -> RankedReport:
    """Rank a report's journal and rewrite the report atomically.

    Every photo appears once (the first row of a photo wins), ranked photos
    first (rank 1, 2, ...), then error rows with no rank.

    Parameters
    ----------
    path : path-like
        The report.
    title : str
        Heading of an HTML report.
    limit : int
        An HTML report shows the best ``limit`` photos and at most ``limit``
        error rows; its journal keeps all.
    n_top, n_errors : int
        How many best rows and error rows to return.

    Returns
    -------
    RankedReport
    """
    report = Path(path)
    fmt = report_format(report)
    journal = journal_path(report)
    line_fmt = "csv" if fmt == "csv" else "jsonl"
    entries = _ranked(journal, line_fmt)
    top: list[dict[str, Any]] = []
    errors: list[dict[str, Any]] = []
    shown: list[dict[str, Any]] = []
    n_err = n_shown_ok = n_shown_err = 0
    tmp = journal.with_name(f".{journal.name}.tmp{os.getpid()}")
    try:
        with open(tmp, "wb") as out:
            if line_fmt == "csv":
                out.write((",".join(CSV_COLUMNS) + "\n").encode("utf-8"))
            for row in _iter_ranked(journal, line_fmt, entries):
                out.write(_encode(row, line_fmt))
                is_error = row.get("error") is not None
                n_err += is_error
                if not is_error and len(top) < n_top:
                    top.append({k: v for k, v in row.items() if k != THUMBNAIL_KEY})
                if is_error and len(errors) < n_errors:
                    errors.append({k: v for k, v in row.items() if k != THUMBNAIL_KEY})
                if fmt == "html" and (n_shown_err if is_error else n_shown_ok) < limit:
                    shown.append(row)
                    n_shown_err += is_error
                    n_shown_ok += not is_error
        os.replace(tmp, journal)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise ParameterError(f"{report}: cannot write report ({exc.strerror or exc})") from None
    if fmt == "html":
        write_html(report, shown, n_rows=len(entries), n_errors=n_err, title=title, limit=limit)
    return RankedReport(
        path=report, n_rows=len(entries), n_errors=n_err, top=tuple(top), errors=tuple(errors)
    )


def refresh_html(path: str | os.PathLike[str], *, title: str = "rockscan triage", limit: int = 2000) -> None:
    """Rebuild an HTML report's page from its journal while the run goes on
    (the journal itself is left as it is).

    Parameters
    ----------
    path : path-like
        The ``.html`` report.
    title : str
    limit : int
        See :func:`finalize_report`.
    """
    report = Path(path)
    journal = journal_path(report)
    entries = _ranked(journal, "jsonl")
    n_err = sum(key[0] for key, _, _ in entries)
    ok = [e for e in entries if e[0][0] == 0][:limit]
    bad = [e for e in entries if e[0][0] == 1][:limit]
    rows = list(_iter_ranked(journal, "jsonl", ok + bad))
    write_html(report, rows, n_rows=len(entries), n_errors=n_err, title=title, limit=limit, in_progress=True)


# ---------------------------------------------------------------- HTML


def write_html(
    path: str | os.PathLike[str],
    rows: Iterable[dict[str, Any]],
    *,
    n_rows: int,
    n_errors: int,
    title: str = "rockscan triage",
    limit: int = 2000,
    in_progress: bool = False,
) -> None:
    """Write the contact sheet atomically (see :func:`render_html`)."""
    path = Path(path)
    text = render_html(
        rows,
        n_rows=n_rows,
        n_errors=n_errors,
        title=title,
        journal_name=journal_path(path).name,
        limit=limit,
        in_progress=in_progress,
    )
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise ParameterError(f"{path}: cannot write report ({exc.strerror or exc})") from None


def render_html(
    rows: Iterable[dict[str, Any]],
    *,
    n_rows: int,
    n_errors: int,
    title: str = "rockscan triage",
    journal_name: str = "",
    limit: int = 2000,
    in_progress: bool = False,
) -> str:
    """The contact sheet: one card per photo, best first, sortable and filterable.

    Parameters
    ----------
    rows : iterable of dict
        Ranked rows (with ``thumbnail`` data URIs where there is one).
    n_rows, n_errors : int
        Photos and error rows in the whole report.
    title : str
    journal_name : str
        File name of the journal that holds every row (linked from the page).
    limit : int
        How many photos the page shows at most (stated on the page).
    in_progress : bool
        The run is still going (stated on the page).

    Returns
    -------
    str
        A self-contained HTML page: styles, script and thumbnails inline, no
        network access.
    """
    cards = []
    shapes: set[str] = set()
    n_shown = 0
    for row in rows:
        n_shown += 1
        cards.append(_card(row))
        if row.get("match"):
            shapes.add(row["match"])
    n_ranked = n_rows - n_errors
    notes = [f"{n_rows} photos: {n_ranked} ranked, {n_errors} errors."]
    if n_ranked > limit or n_errors > limit:
        notes.append(f"This page shows the best {limit} photos and at most {limit} errors.")
    if journal_name:
        link = html.escape(journal_name, quote=True)
        notes.append(f'Every row is in <a href="{link}">{html.escape(journal_name)}</a>.')
    if in_progress:
        notes.append("The run is still going: this page is a snapshot.")
    options = "".join(
        f'<option value="{html.escape(s, quote=True)}">{html.escape(s)}</option>' for s in sorted(shapes)
    )
    sort_buttons = "".join(
        f'<button type="button" class="sort" data-key="{key}">{label}</button>' for key, label in _SORTS
    )
    return _PAGE.format(
        title=html.escape(title),
        notes=" ".join(notes),
        options=options,
        sort_buttons=sort_buttons,
        cards="\n".join(cards),
        n_shown=n_shown,
        style=_STYLE,
        script=_SCRIPT,
    )


_SORTS = (
    ("rank", "rank"),
    ("interest", "interest"),
    ("mscore", "MScore"),
    ("angle", "angle"),
    ("novelty", "novelty"),
    ("match", "match"),
    ("path", "photo"),
)


def _number(value: Any) -> str:
    return "" if value is None or (isinstance(value, float) and not math.isfinite(value)) else repr(value)


def _card(row: dict[str, Any]) -> str:
    esc = html.escape
    path = row["path"]
    error = row.get("error")
    attrs = {
        "rank": "" if row.get("rank") is None else str(row["rank"]),
        "interest": _number(row.get("interest")),
        "mscore": _number(row.get("mscore")),
        "angle": _number(row.get("angle_deg")),
        "novelty": _number(row.get("novelty")),
        "match": row.get("match") or row.get("nearest") or "",
        "path": path,
        "error": "1" if error is not None else "0",
        "interesting": "1" if row.get("interesting") else "0",
        "novel": "1" if row.get("novel") else "0",
    }
    data = " ".join(f'data-{k}="{esc(v, quote=True)}"' for k, v in attrs.items())
    thumb = row.get(THUMBNAIL_KEY)
    image = (
        f'<img src="{esc(thumb, quote=True)}" alt="{esc(path, quote=True)}" loading="eager">'
        if thumb
        else '<div class="noimage">no image</div>'
    )
    if error is not None:
        # The message names the photo already; the card shows the path below it.
        message = error[len(path) + 2 :] if error.startswith(f"{path}: ") else error
        text = f'<span class="error">error: {esc(message)}</span>'
    else:
        shape = row.get("match")
        verdict = f"<b>{esc(shape)}</b>" if shape else f"no match (nearest {esc(row['nearest'])})"
        parts = [
            f'<span class="rank">#{row["rank"]}</span> {verdict}' if row.get("rank") else verdict,
            f"interest {row['interest']:.3f}",
            f"MScore {row['mscore']:.3f}",
            f"angle {row['angle_deg']:.1f}&deg;",
        ]
        if row.get("novelty") is not None:
            flag = ' <span class="novel">novel</span>' if row.get("novel") else ""
            parts.append(f"novelty {row['novelty']:.3f}{flag}")
        text = "<br>".join(parts)
    return (
        f'<figure class="card" {data}>{image}<figcaption>{text}'
        f'<span class="path" title="{esc(path, quote=True)}">{esc(path)}</span></figcaption></figure>'
    )


_STYLE = """
body { font: 14px/1.35 system-ui, sans-serif; margin: 0; color: #222; background: #f4f4f2; }
header { padding: 12px 16px 4px; }
h1 { font-size: 20px; margin: 0 0 4px; }
#controls { position: sticky; top: 0; background: #f4f4f2ee; padding: 8px 16px;
  display: flex; flex-wrap: wrap; gap: 8px; align-items: center; border-bottom: 1px solid #ccc; }
button.sort { border: 1px solid #999; background: #fff; border-radius: 4px; padding: 2px 8px;
  cursor: pointer; }
button.sort.active { background: #234; color: #fff; }
#sheet { display: grid; grid-template-columns: repeat(auto-fill, minmax(210px, 1fr)); gap: 10px;
  padding: 12px 16px; }
figure.card { margin: 0; background: #fff; border: 1px solid #ccc; border-radius: 6px; padding: 6px; }
figure.card[data-error="1"] { border-color: #c33; }
figure.card img, .noimage { display: block; max-width: 100%; max-height: 200px; margin: 0 auto 4px; }
.noimage { height: 120px; line-height: 120px; text-align: center; color: #999; background: #eee; }
.path { display: block; color: #666; font-size: 12px; overflow-wrap: anywhere; }
.error { color: #b00; }
.novel { background: #fd4; padding: 0 4px; border-radius: 3px; }
.legend { color: #555; font-size: 12px; }
.legend i { font-style: normal; font-weight: bold; }
"""

_SCRIPT = """
(function () {
  const sheet = document.getElementById('sheet');
  const cards = Array.from(sheet.querySelectorAll('figure.card'));
  const numeric = new Set(['rank', 'interest', 'mscore', 'angle', 'novelty']);
  const descending = new Set(['interest', 'mscore', 'novelty']);
  const state = { key: 'rank', ascending: true };
  const $ = (id) => document.getElementById(id);

  function value(card, key) {
    const raw = card.dataset[key];
    if (!numeric.has(key)) return raw.toLowerCase();
    return raw === '' ? null : parseFloat(raw);
  }
  function compare(a, b) {
    const va = value(a, state.key), vb = value(b, state.key);
    // Rows without the value (errors) stay last whichever way the sort goes.
    if (va === null || vb === null) {
      if (va === vb) return value(a, 'path') < value(b, 'path') ? -1 : 1;
      return va === null ? 1 : -1;
    }
    let order = va < vb ? -1 : va > vb ? 1 : 0;
    if (!state.ascending) order = -order;
    if (order === 0) order = value(a, 'path') < value(b, 'path') ? -1 : 1;
    return order;
  }
  function visible(card) {
    const text = $('filter').value.trim().toLowerCase();
    const shape = $('shape').value;
    const d = card.dataset;
    if (text && !(d.path.toLowerCase().includes(text) || d.match.toLowerCase().includes(text))) return false;
    if (shape && d.match !== shape) return false;
    if ($('only-interesting').checked && d.interesting !== '1') return false;
    if ($('only-novel').checked && d.novel !== '1') return false;
    if (!$('show-errors').checked && d.error === '1') return false;
    return true;
  }
  function apply() {
    cards.sort(compare);
    let shown = 0;
    for (const card of cards) {
      const show = visible(card);
      card.hidden = !show;
      shown += show;
      sheet.appendChild(card);
    }
    $('count').textContent = shown + ' of ' + cards.length + ' shown';
    for (const button of document.querySelectorAll('button.sort')) {
      const active = button.dataset.key === state.key;
      button.classList.toggle('active', active);
      button.setAttribute('aria-pressed', active ? 'true' : 'false');
      button.textContent = button.dataset.label + (active ? (state.ascending ? ' \\u2191' : ' \\u2193') : '');
    }
  }
  for (const button of document.querySelectorAll('button.sort')) {
    button.dataset.label = button.textContent;
    button.addEventListener('click', () => {
      const key = button.dataset.key;
      if (state.key === key) state.ascending = !state.ascending;
      else { state.key = key; state.ascending = !descending.has(key); }
      apply();
    });
  }
  for (const id of ['filter', 'shape', 'only-interesting', 'only-novel', 'show-errors']) {
    $(id).addEventListener('input', apply);
    $(id).addEventListener('change', apply);
  }
  apply();
})();
"""

_PAGE = """<!DOCTYPE html>
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
<p>{notes} Ranked by interest: MScore times the matched shape's interest.</p>
<p class="legend">On each photo: <i style="color:#0bb">cyan</i> the rock's outline,
<i style="color:#c0c">magenta</i> the matched library shape turned by the found angle.</p>
</header>
<div id="controls">
<span>Sort:</span> {sort_buttons}
<input id="filter" type="search" placeholder="filter: photo or shape" aria-label="filter by photo or shape">
<select id="shape" aria-label="matched shape"><option value="">all shapes</option>{options}</select>
<label><input type="checkbox" id="only-interesting"> interesting only</label>
<label><input type="checkbox" id="only-novel"> novel only</label>
<label><input type="checkbox" id="show-errors" checked> errors</label>
<span id="count">{n_shown} shown</span>
</div>
<main id="sheet">
{cards}
</main>
<script>{script}</script>
</body>
</html>
"""
