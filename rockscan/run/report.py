"""The final triage report: the journal ranked and rewritten, and its page or FeatureCollection.

The journal and its rows are :mod:`rockscan.io.report`'s; this module composes
them with the contact sheet of :mod:`rockscan.draw.sheet` and the GeoJSON of
:mod:`rockscan.io.geojson` when a run ends (:func:`finalize_report`) or while it
goes on (:func:`refresh_html`).
"""

from __future__ import annotations

import contextlib
import heapq
import os
from collections.abc import Generator
from pathlib import Path
from typing import Any, BinaryIO

from rockscan.core.errors import WriteError
from rockscan.io.atomic import temporary_name
from rockscan.io.report import (
    CHUNK_ROWS,
    SIDE_JOURNAL,
    THUMBNAIL_KEY,
    JournalEntry,
    JournalScan,
    KeptRows,
    RankedReport,
    encode_row,
    journal_entries,
    journal_header,
    journal_path,
    open_journal,
    ranked_rows,
    read_header,
    report_format,
    scan_journal,
)

__all__ = ["finalize_report", "refresh_html"]


class _Output:
    """A file written under a temporary name and renamed over the target at the end."""

    def __init__(self, target: Path, stack: contextlib.ExitStack) -> None:
        self.target = target
        self.tmp = temporary_name(target)
        stack.callback(self.tmp.unlink, missing_ok=True)
        self.fh: BinaryIO = stack.enter_context(open(self.tmp, "wb"))

    def write(self, data: bytes) -> None:
        self.fh.write(data)

    def commit(self) -> None:
        self.fh.close()
        os.replace(self.tmp, self.target)


def finalize_report(
    path: str | os.PathLike[str],
    *,
    title: str = "rockscan triage",
    limit: int = 2000,
    n_top: int = 10,
    n_errors: int = 20,
    chunk_rows: int | None = None,
    resolved: frozenset[str] = frozenset(),
) -> RankedReport:
    """Rank a report's journal and rewrite the report atomically.

    Every rock appears once (the first row of a photo's rock wins; an error row
    gives way to a later row of its photo), ranked rocks first (rank 1, 2, ...),
    then error rows with no rank.

    Parameters
    ----------
    path : path-like
        The report.
    title : str
        Heading of an HTML report.
    limit : int
        An HTML report shows the best ``limit`` rocks and at most ``limit``
        error rows; its journal keeps all.
    n_top, n_errors : int
        How many best rows and error rows to return.
    chunk_rows : int, optional
        Sort keys held in memory at once (default :data:`CHUNK_ROWS`).
    resolved : frozenset of str
        :func:`rockscan.io.report.photo_key` of error rows to leave out: a
        folder that could not be listed then and can now (its photos have
        rows of their own).

    Returns
    -------
    RankedReport

    Raises
    ------
    WriteError
        If the report cannot be written (it is then left as it was).
    """
    report = Path(path)
    fmt = report_format(report)
    journal = journal_path(report)
    line_fmt = "csv" if fmt == "csv" else "jsonl"
    top: list[dict[str, Any]] = []
    errors: list[dict[str, Any]] = []
    n_err = 0
    try:
        with contextlib.ExitStack() as stack:
            scan = scan_journal(journal, line_fmt, stack, chunk_rows or CHUNK_ROWS, resolved=resolved)
            out = _Output(journal, stack)
            out.write(journal_header(scan.provenance, line_fmt))
            page = _open_page(fmt, report, scan, stack, title=title, limit=limit)
            for row in ranked_rows(journal, line_fmt, scan):
                out.write(encode_row(row, line_fmt))
                is_error = row.get("error") is not None
                n_err += is_error
                kept, most = (errors, n_errors) if is_error else (top, n_top)
                if len(kept) < most:
                    kept.append({k: v for k, v in row.items() if k != THUMBNAIL_KEY})
                if page is not None:
                    page[0].send(row)
            out.commit()
            if page is not None:
                page[0].close()
                page[1].commit()
    except OSError as exc:
        raise WriteError(f"{report}: cannot write report ({exc.strerror or exc})") from None
    return RankedReport(
        path=report,
        n_rows=scan.n_rows,
        n_errors=n_err,
        top=tuple(top),
        errors=tuple(errors),
        provenance=scan.provenance,
    )


def _open_page(
    fmt: str,
    report: Path,
    scan: JournalScan,
    stack: contextlib.ExitStack,
    *,
    title: str,
    limit: int,
    in_progress: bool = False,
) -> tuple[Generator[None, dict[str, Any], None], _Output] | None:
    """A generator that takes ranked rows and writes the page or FeatureCollection."""
    if fmt not in SIDE_JOURNAL:
        return None
    out = _Output(report, stack)
    if fmt == "html":
        from rockscan.draw.sheet import sheet_writer

        gen = sheet_writer(
            out.write,
            n_rows=scan.n_rows,
            n_errors=scan.n_errors,
            title=title,
            report=report,
            journal_name=journal_path(report).name,
            limit=limit,
            provenance=scan.provenance,
            in_progress=in_progress,
        )
    else:
        from rockscan.io.geojson import feature_collection_writer

        gen = feature_collection_writer(out.write, provenance=scan.provenance)
    next(gen)
    return gen, out


def refresh_html(path: str | os.PathLike[str], *, title: str = "rockscan triage", limit: int = 2000) -> None:
    """Rebuild an HTML report's page from its journal while the run goes on
    (the journal itself is left as it is).

    Only the ``limit`` best rocks and first ``limit`` errors are held (a heap).

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
    best: list[_Negated] = []
    bad: list[_Negated] = []
    # What the ranking keeps (rockscan.io.report.latest_rows): a photo tried again
    # shows its latest attempt only, while the run goes on too.
    kept = KeptRows()
    with open_journal(journal) as fh:
        provenance = read_header(fh, "jsonl", journal)
        for entry, rock, photo, first in journal_entries(fh, "jsonl", journal):
            kept.add(entry, rock, photo, first)
            heap = bad if entry[0][0] else best
            # A max-heap of the best `limit` keeps memory to the page's rows.
            item = _Negated(entry)
            if len(heap) < limit:
                heapq.heappush(heap, item)
            elif heap[0] < item:
                heapq.heapreplace(heap, item)
    entries = sorted(e.entry for e in best) + sorted(e.entry for e in bad)
    scan = kept.scan(provenance, [entries])
    try:
        with contextlib.ExitStack() as stack:
            page = _open_page("html", report, scan, stack, title=title, limit=limit, in_progress=True)
            assert page is not None
            for row in ranked_rows(journal, "jsonl", scan):
                page[0].send(row)
            page[0].close()
            page[1].commit()
    except OSError as exc:
        raise WriteError(f"{report}: cannot write report ({exc.strerror or exc})") from None


class _Negated:
    """Orders entries in reverse, so that heapq's min-heap keeps the smallest keys."""

    __slots__ = ("entry",)

    def __init__(self, entry: JournalEntry) -> None:
        self.entry = entry

    def __lt__(self, other: _Negated) -> bool:
        return self.entry > other.entry
