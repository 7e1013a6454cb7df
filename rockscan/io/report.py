"""Triage reports: CSV, JSON lines, HTML or GeoJSON, written a row at a time and ranked at the end.

A report is first a *journal*: every photo's rows are appended and flushed as
soon as they are known, so a run that is killed leaves every finished row
behind, complete, and a run started again with ``resume`` skips them. When the
run ends the journal is ranked (:func:`rank_key`) and rewritten in place
atomically (a temporary file renamed over it).

* ``.csv`` and ``.jsonl`` (or ``.ndjson``) reports are their own journal.
* An ``.html`` or ``.geojson`` report keeps its journal beside it,
  ``REPORT.jsonl`` (the same rows as a JSON lines report, plus each rock's
  thumbnail for a sheet). The page (:mod:`rockscan.draw.sheet`) or the
  FeatureCollection (:mod:`rockscan.io.geojson`) is built from the journal when
  the run ends.

Every report records how it was made, its *provenance* (rockscan version,
library content hash, matcher settings and cutoffs, every option that changes
a row): the first line of a journal (``{"rockscan_report": {...}}`` in JSON
lines, ``# rockscan_report {...}`` above a CSV's column names), the footer of
a sheet, the ``rockscan_report`` member of a FeatureCollection. A journal
never mixes rows made with different settings: resuming with other settings
is refused (:class:`ReportSettingsError`) before the file is touched.

The final ranking streams: the journal is read in chunks of sort keys, each
chunk sorted and spilled to a temporary file, and the chunks merged
(:func:`heapq.merge`); besides a chunk, memory holds 9 bytes per row (a
64-bit hash of each rock's identity, to keep the first row of each, and
whether it is an error), about 50 for a moment while duplicates are looked for.

This module knows rows and files only; :mod:`rockscan.run.triage` makes the rows and
:mod:`rockscan.run.report` writes the ranked report (with the page of
:mod:`rockscan.draw.sheet` or the FeatureCollection of :mod:`rockscan.io.geojson`).
"""

from __future__ import annotations

import array
import contextlib
import csv
import errno
import hashlib
import heapq
import io
import json
import math
import os
import tempfile
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, BinaryIO

from rockscan.core.errors import ParameterError, WriteError

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

__all__ = [
    "CSV_COLUMNS",
    "REPORT_FORMATS",
    "ROW_KEYS",
    "RankedReport",
    "ReportBusyError",
    "ReportJournal",
    "ReportSettingsError",
    "journal_path",
    "lock_report",
    "photo_key",
    "rank_key",
    "read_provenance",
    "read_rows",
    "report_format",
    "report_target",
]

#: Report file endings and their formats.
REPORT_FORMATS = {
    ".csv": "csv",
    ".jsonl": "jsonl",
    ".ndjson": "jsonl",
    ".html": "html",
    ".htm": "html",
    ".geojson": "geojson",
}
#: Formats whose rows live in a journal beside the report.
SIDE_JOURNAL = {"html", "geojson"}

#: Keys of every report row, in order. ``match`` ... ``minor_axis_mm`` are the
#: keys and values of ``rockscan classify --json`` for the rock (None where
#: classify leaves a key out). A JSON row also keeps any other key of the
#: classify record (``outline``); a CSV has these columns only.
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
    "segmentation_score",
    "area_mm2",
    "equivalent_diameter_mm",
    "major_axis_mm",
    "minor_axis_mm",
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
    "segmentation_score",
    "area_mm2",
    "equivalent_diameter_mm",
    "major_axis_mm",
    "minor_axis_mm",
    "centroid_x",
    "centroid_y",
}
_INTS = {"rank", "symmetry", "index"}
_BOOLS = {"interesting", "novel"}
_STRINGS = {"match", "nearest", "nearest_observed", "error"}
#: Journal-only key of HTML reports: the thumbnail as a data URI.
THUMBNAIL_KEY = "thumbnail"
#: The key of a journal's first line that holds the provenance.
PROVENANCE_KEY = "rockscan_report"
_CSV_PROVENANCE = "# " + PROVENANCE_KEY + " "
#: Sort keys held in memory at once while ranking; more are spilled to disk.
CHUNK_ROWS = 100_000


class ReportSettingsError(ParameterError):
    """A report was made with other settings than the run that would continue it."""


class ReportBusyError(ParameterError):
    """Another run is writing the report."""


def report_format(path: str | os.PathLike[str]) -> str:
    """The format of a report file from its ending: ``"csv"``, ``"jsonl"``, ``"html"`` or ``"geojson"``.

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
            f"{path}: a report must end in .csv, .jsonl (JSON lines), .html or .geojson, "
            f"not {suffix or 'nothing'!r}"
        )
    return REPORT_FORMATS[suffix]


def report_target(path: str | os.PathLike[str]) -> Path:
    """The file a report named ``path`` is written to: ``path``, or for a symbolic
    link the file it points to, so that the link stays a link (a run through
    ``latest.csv`` appended to its target, then put a file of its own in the
    link's place) and a run through the link and one on its target lock each
    other out.

    Raises
    ------
    ParameterError
        For an ending no report has (:func:`report_format`), the journal of an
        HTML or GeoJSON report named as a report of its own (its rows lack what
        the report's own run gives them, and a run on it ran beside the
        report's), and a link to a file of another ending.
    """
    path = Path(path)
    fmt = report_format(path)
    if fmt == "jsonl" and REPORT_FORMATS.get(Path(path.stem).suffix.lower()) in SIDE_JOURNAL:
        report = path.with_name(path.stem)
        raise ParameterError(
            f"{path}: the journal the report {report} keeps while it runs, not a report of its own; "
            f"give -o {report}"
        )
    if not path.is_symlink():
        return path
    target = Path(os.path.realpath(path))
    if REPORT_FORMATS.get(target.suffix.lower()) != fmt:
        raise ParameterError(f"{path}: a link to {target}, which is not a {path.suffix} report")
    return report_target(target)


def journal_path(path: str | os.PathLike[str]) -> Path:
    """Where a report's rows are appended while it runs: the report itself, or
    ``REPORT.jsonl`` beside an HTML or GeoJSON report."""
    path = Path(path)
    return path.with_name(path.name + ".jsonl") if report_format(path) in SIDE_JOURNAL else path


def photo_key(path: str) -> str:
    """The identity of a photo across runs: its absolute, normalised path
    (symbolic links are not resolved: two links are two photos)."""
    return os.path.normcase(os.path.abspath(path))


def rank_key(row: dict[str, Any]) -> tuple[int, float, float, str, int]:
    """Sort key of a row: rocks by decreasing interest, then decreasing MScore,
    then path, then rock index; error rows last, by path."""
    index = row.get("index") or 0
    if row.get("error") is not None:
        return (1, 0.0, 0.0, row["path"], index)
    return (0, -float(row["interest"]), -float(row["mscore"]), row["path"], index)


def _hash(key: str) -> int:
    return int.from_bytes(
        hashlib.blake2b(key.encode("utf-8", "surrogateescape"), digest_size=8).digest(), "little", signed=True
    )


def _rock_hash(row: dict[str, Any]) -> int:
    return _hash(f"{photo_key(row['path'])}\0{row.get('index') or 0}")


def _photo_hash(row: dict[str, Any]) -> int:
    return _hash(photo_key(row["path"]))


def shown_text(text: str) -> str:
    """A path or message made safe to print or to put in a page: bytes that
    are not UTF-8 become U+FFFD, control characters their escapes."""
    text = text.encode("utf-8", "surrogateescape").decode("utf-8", "replace")
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


# ---------------------------------------------------------------- encoding


def encode_row(row: dict[str, Any], fmt: str) -> bytes:
    if fmt == "csv":
        buf = io.StringIO()
        # CRLF endings make the writer quote a carriage return inside a name.
        csv.writer(buf, lineterminator="\r\n").writerow([_csv_cell(v) for v in _csv_values(row)])
        # A name that is not UTF-8 keeps its own bytes.
        return buf.getvalue().encode("utf-8", "surrogateescape")
    text = json.dumps(row, ensure_ascii=False, allow_nan=False)
    try:
        return (text + "\n").encode("utf-8")
    except UnicodeEncodeError:
        # A name that is not UTF-8: \udcXX escapes, read back as the same name.
        return (json.dumps(row, allow_nan=False) + "\n").encode("ascii")


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


def _decode(record: bytes, fmt: str, source: Path, number: int = 0) -> dict[str, Any]:
    text = record.decode("utf-8", "surrogateescape")
    where = f"{source}: row {number}" if number else f"{source}"
    if fmt != "csv":
        try:
            row = json.loads(text)
        except json.JSONDecodeError:
            raise ParameterError(f"{where} is not JSON; is this a rockscan triage report?") from None
        if not isinstance(row, dict) or not isinstance(row.get("path"), str):
            raise ParameterError(f"{where} has no photo path; is this a rockscan triage report?")
        _check_row(row, where)
        return row
    cells = next(csv.reader(io.StringIO(text, newline="")), [])
    if len(cells) != len(CSV_COLUMNS):
        raise ParameterError(f"{where} has {len(cells)} columns, not {len(CSV_COLUMNS)}")
    flat = {key: _parse_cell(key, cell, where) for key, cell in zip(CSV_COLUMNS, cells, strict=True)}
    cx, cy = flat.pop("centroid_x"), flat.pop("centroid_y")
    flat["centroid"] = None if cx is None else [cx, cy]
    row = {key: flat[key] for key in ROW_KEYS}
    _check_row(row, where)
    return row


def _parse_cell(key: str, cell: str, where: str) -> Any:
    if cell == "":
        return None
    try:
        if key in _FLOATS:
            return float(cell)
        if key in _INTS:
            return int(cell)
    except ValueError:
        raise ParameterError(f"{where}: {key} holds {cell!r}, not a number; was it edited?") from None
    if key in _BOOLS:
        if cell not in ("true", "false"):
            raise ParameterError(f"{where}: {key} holds {cell!r}, not true or false; was it edited?")
        return cell == "true"
    return cell


def _check_row(row: dict[str, Any], where: str) -> None:
    """Every known key holds its type (a hand-edited journal fails here, clearly)."""

    def bad(key: str, kind: str) -> ParameterError:
        return ParameterError(f"{where}: {key} holds {row[key]!r}, not {kind}; was it edited?")

    for key, value in row.items():
        if value is None:
            continue
        if key in _FLOATS:
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise bad(key, "a number")
        elif key in _INTS:
            if isinstance(value, bool) or not isinstance(value, int):
                raise bad(key, "a whole number")
        elif key in _BOOLS:
            if not isinstance(value, bool):
                raise bad(key, "true or false")
        elif key in _STRINGS:
            if not isinstance(value, str):
                raise bad(key, "text")
        elif key == "centroid":
            if not (
                isinstance(value, list)
                and len(value) == 2
                and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
            ):
                raise bad(key, "[x, y]")
    if row.get("error") is None and (row.get("interest") is None or row.get("mscore") is None):
        raise ParameterError(f"{where}: a rock without interest or MScore; was it edited?")


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


# ---------------------------------------------------------------- provenance header


def journal_header(provenance: dict[str, Any] | None, fmt: str) -> bytes:
    text = json.dumps(provenance, sort_keys=True, separators=(",", ":"), allow_nan=False)
    if fmt == "csv":
        head = (_CSV_PROVENANCE + text + "\r\n") if provenance is not None else ""
        return (head + ",".join(CSV_COLUMNS) + "\r\n").encode("utf-8")
    if provenance is None:
        return b""
    return (json.dumps({PROVENANCE_KEY: provenance}, sort_keys=True, allow_nan=False) + "\n").encode("utf-8")


def read_header(fh: BinaryIO, fmt: str, source: Path) -> dict[str, Any] | None:
    """Read a journal's provenance and column lines; the file is left at its first row.

    Returns None for a journal that records no provenance (made by an older
    rockscan, or still empty)."""
    start = fh.tell()
    first = fh.readline()
    provenance = None
    if fmt == "csv":
        if first.startswith(_CSV_PROVENANCE.encode()):
            provenance = _parse_provenance(first[len(_CSV_PROVENANCE) :], source)
            first = fh.readline()
        if first.decode("utf-8", "replace").strip() != ",".join(CSV_COLUMNS):
            raise ParameterError(
                f"{source}: not a rockscan triage report (its first lines are not the report's header)"
            )
        return provenance
    if first.startswith(b'{"' + PROVENANCE_KEY.encode() + b'"') and first.endswith(b"\n"):
        return _parse_provenance(first, source, wrapped=True)
    fh.seek(start)
    return None


def _parse_provenance(data: bytes, source: Path, *, wrapped: bool = False) -> dict[str, Any]:
    try:
        value = json.loads(data.decode("utf-8"))
        if wrapped:
            value = value[PROVENANCE_KEY]
    except (ValueError, KeyError, TypeError):
        value = None
    if not isinstance(value, dict):
        raise ParameterError(f"{source}: the report's header line is damaged; start again with --overwrite")
    return value


def read_provenance(path: str | os.PathLike[str]) -> dict[str, Any] | None:
    """How a report was made (see the module docstring), or None if it does not say.

    Raises
    ------
    ParameterError
        If the report is missing or not a triage report.
    """
    fmt, source = _journal_format(path)
    with open_journal(source) as fh:
        return read_header(fh, fmt, source)


def _differences(old: Any, new: Any, prefix: str = "") -> list[str]:
    if prefix == "" and isinstance(old, dict) and isinstance(new, dict):
        said = _photos_difference(old.get("photos"), new.get("photos"))
        if said is not None:
            rest = _differences({**old, "photos": None}, {**new, "photos": None})
            return [said, *rest]
    if (isinstance(old, dict) or old is None) and (isinstance(new, dict) or new is None) and old != new:
        # A setting given on one side only (an observed library) is named key by
        # key, so that its paths show whole.
        old, new = old or {}, new or {}
        out = []
        for key in sorted(set(old) | set(new)):
            out += _differences(old.get(key), new.get(key), f"{prefix}{key}.")
        return out
    if old != new:
        return [f"{prefix.rstrip('.')} {_short(old)} (report) vs {_short(new)} (now)"]
    return []


def _photos_difference(old: Any, new: Any) -> str | None:
    """What a user must do when a report's photos were named otherwise than now, in
    words (the report's paths are the folder's as given then), or None if they agree."""
    if not (isinstance(old, dict) and isinstance(new, dict)) or old == new:
        return None
    folder, base = old.get("folder"), old.get("relative_to")
    if folder != new.get("folder"):
        return f"the report is of the photos in {folder}, not {new.get('folder')}"
    if base is None:
        return f"the report names its photos by absolute paths: give the folder as {folder}"
    given = os.path.relpath(str(folder), str(base))
    return f"the report names its photos from {base}: give the folder as {given} from there"


def _short(value: Any) -> str:
    text = json.dumps(value)
    # A path is shown whole: its differing part may lie anywhere in it.
    if isinstance(value, str):
        return text
    return text if len(text) <= 24 else text[:12] + "..." + text[-6:]


# ---------------------------------------------------------------- reading


def _journal_format(path: str | os.PathLike[str]) -> tuple[str, Path]:
    fmt = "csv" if report_format(path) == "csv" else "jsonl"
    return fmt, journal_path(path)


def open_journal(source: Path) -> BinaryIO:
    try:
        return open(source, "rb")
    except FileNotFoundError:
        raise ParameterError(f"{source}: report not found") from None
    except OSError as exc:
        raise ParameterError(f"{source}: cannot read report ({exc.strerror or exc})") from None


def read_rows(path: str | os.PathLike[str]) -> Iterator[dict[str, Any]]:
    """The rows of a triage report, in file order (ranked once the run ended).

    Parameters
    ----------
    path : path-like
        A ``.csv``, ``.jsonl``, ``.html`` or ``.geojson`` report (the last two
        are read from their journal ``REPORT.jsonl``).

    Yields
    ------
    row : dict
        Keys :data:`ROW_KEYS` (and ``thumbnail`` from an HTML report's journal).

    Raises
    ------
    ParameterError
        If the file is missing or not a triage report, or a row was damaged.
    """
    fmt, source = _journal_format(path)
    with open_journal(source) as fh:
        read_header(fh, fmt, source)
        for number, (_, record) in enumerate(_records(fh, fmt), 1):
            yield _decode(record, fmt, source, number)


# ---------------------------------------------------------------- the lock


@contextlib.contextmanager
def lock_report(path: str | os.PathLike[str]) -> Iterator[None]:
    """Hold a report for one run: a second run on it is refused at once.

    The lock is an advisory ``flock`` on ``.REPORT.lock`` beside the report,
    released by the operating system when the process ends however it ends,
    so a crash never leaves a stale lock. Where ``fcntl`` is missing (not
    POSIX) nothing is locked.

    Raises
    ------
    ReportBusyError
        If another process holds the report.
    """
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX
        yield
        return
    report = Path(path)
    lock = report.with_name(f".{report.name}.lock")
    while True:
        try:
            fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as exc:
            raise ParameterError(f"{report}: cannot lock the report ({exc.strerror or exc})") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            os.close(fd)
            if exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise ReportBusyError(
                    f"{report}: another rockscan run is writing this report; wait for it to end"
                ) from None
            raise ParameterError(f"{report}: cannot lock the report ({exc.strerror or exc})") from None
        # The holder before us may have removed the file it locked: lock the one on disk.
        try:
            same = os.path.samestat(os.fstat(fd), os.stat(lock))
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    try:
        yield
    finally:
        with contextlib.suppress(OSError):
            os.unlink(lock)
        os.close(fd)


# ---------------------------------------------------------------- the journal


class ReportJournal:
    """Append-only rows of a report while it runs.

    Parameters
    ----------
    path : path-like
        The report (``.csv``, ``.jsonl``, ``.html`` or ``.geojson``).
    resume : bool
        Keep the rows of an earlier run and continue after them.
    overwrite : bool
        Start again even if the report exists.
    provenance : dict, optional
        How the rows are made (JSON-able). Recorded in a new report; a resumed
        report must record the same.

    Attributes
    ----------
    done : set of str
        :func:`photo_key` of every photo already in the report (kept from earlier
        runs when resuming).
    failed : set of str
        Those of ``done`` whose latest row is an error row: a resume tries them
        again, and the ranking keeps their rows after the error row
        (:func:`latest_rows`).

    Raises
    ------
    ReportSettingsError
        If ``resume`` meets a report made with other settings (the report is
        left as it was).
    ParameterError
        If the report exists and neither ``resume`` nor ``overwrite`` is set,
        or it cannot be read or written.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        resume: bool = False,
        overwrite: bool = False,
        provenance: dict[str, Any] | None = None,
    ) -> None:
        self.report = Path(path)
        self.format = report_format(self.report)
        self.path = journal_path(self.report)
        self._fmt = "csv" if self.format == "csv" else "jsonl"
        # The provenance as a JSON round trip gives it (tuples become lists).
        self.provenance = None if provenance is None else json.loads(json.dumps(provenance))
        self.done: set[str] = set()
        self.failed: set[str] = set()
        exists = self.path.exists() or (self.format in SIDE_JOURNAL and self.report.exists())
        if exists and not (resume or overwrite):
            raise ParameterError(
                f"{self.report} exists: add --resume to continue it, or --overwrite to start again"
            )
        if resume and self.format in SIDE_JOURNAL and self.report.exists() and not self.path.exists():
            raise ParameterError(
                f"{self.report}: cannot resume, its rows ({self.path.name}) are missing; use --overwrite"
            )
        if self.report.is_dir() or self.path.is_dir():
            raise ParameterError(f"{self.report}: is a folder; give a report file name")
        try:
            if resume and self.path.exists() and self.path.stat().st_size > 0:
                end = self._scan()
                if end < self.path.stat().st_size:
                    # Drop a row cut short by a crash; its photo is done again.
                    os.truncate(self.path, end)
            else:
                with open(self.path, "wb") as fh:
                    fh.write(journal_header(self.provenance, self._fmt))
            # Unbuffered appends: each row reaches the file in one write, or not at all
            # but a torn tail that the next resume drops.
            self._fh = open(self.path, "ab", buffering=0)
        except OSError as exc:
            raise WriteError(f"{self.path}: cannot write report ({exc.strerror or exc})") from None

    def _scan(self) -> int:
        """Check an earlier run's header and rows; the end of its last complete row."""
        with open(self.path, "rb") as fh:
            recorded = read_header(fh, self._fmt, self.path)
            if self.provenance is not None and recorded != self.provenance:
                if recorded is None:
                    why = "it does not record how it was made (an older rockscan wrote it)"
                else:
                    why = "; ".join(_differences(recorded, self.provenance))
                raise ReportSettingsError(
                    f"{self.report} was made with other settings ({why}); resume it with the same "
                    "library and options, or write another report (-o) or start again (--overwrite)"
                )
            end = fh.tell()
            for number, (offset, record) in enumerate(_records(fh, self._fmt), 1):
                self._note(_decode(record, self._fmt, self.path, number))
                end = offset + len(record)
        return end

    def _note(self, row: dict[str, Any]) -> None:
        key = photo_key(row["path"])
        self.done.add(key)
        if row.get("error") is not None:
            self.failed.add(key)
        else:
            self.failed.discard(key)

    def append(self, row: dict[str, Any] | Iterable[dict[str, Any]]) -> None:
        """Write one photo's row (or rows, one per rock) in a single write.

        Parameters
        ----------
        row : dict or iterable of dict
            Keys :data:`ROW_KEYS` (and ``thumbnail`` for an HTML report).

        Raises
        ------
        ParameterError
            If the file cannot take it (disk full, file size limit): the rows
            written before stay readable, none of these rows is left (the file
            is cut back to where they began), and ``resume`` continues after them.
        """
        rows = [row] if isinstance(row, dict) else list(row)
        data = b"".join(encode_row(r, self._fmt) for r in rows)
        start = None
        try:
            start = self._fh.tell()
            written = self._fh.write(data)
            while written < len(data):
                written += self._fh.write(data[written:])
        except OSError as exc:
            if start is not None:
                # A full disk takes part of the write: a photo's first rocks whole
                # and the next cut short. The resume would drop the cut row and
                # count the photo done with rocks missing: all its rows go.
                with contextlib.suppress(OSError):
                    os.ftruncate(self._fh.fileno(), start)
            raise WriteError(
                f"{self.path}: cannot write report ({exc.strerror or exc}); the rows before are kept: "
                "make room and run again with --resume"
            ) from None
        for r in rows:
            self._note(r)

    def close(self) -> None:
        """Close the journal file."""
        with contextlib.suppress(OSError):
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
        Rows in it (each rock once).
    n_errors : int
        Error rows among them.
    top : tuple of dict
        The best ranked rows (without thumbnails), best first.
    errors : tuple of dict
        The first error rows, by path.
    provenance : dict or None
        How the report was made.
    """

    path: Path
    n_rows: int
    n_errors: int
    top: tuple[dict[str, Any], ...] = field(repr=False)
    errors: tuple[dict[str, Any], ...] = field(repr=False)
    provenance: dict[str, Any] | None = field(default=None, repr=False)


#: (rank key, ordinal, offset, length) of one row in a journal.
JournalEntry = tuple[tuple[int, float, float, str, int], int, int, int]


@dataclass
class JournalScan:
    provenance: dict[str, Any] | None
    n_rows: int
    n_errors: int
    drop: frozenset[int]
    chunks: list[Iterable[JournalEntry]]


def journal_entries(fh: BinaryIO, fmt: str, source: Path) -> Iterator[tuple[JournalEntry, int, int, bool]]:
    """Each row's sort entry, its rock's and its photo's identity hashes, and
    whether it begins an attempt at its photo (rock index 0)."""
    for ordinal, (offset, record) in enumerate(_records(fh, fmt)):
        row = _decode(record, fmt, source, ordinal + 1)
        entry = (rank_key(row), ordinal, offset, len(record))
        yield entry, _rock_hash(row), _photo_hash(row), not row.get("index")


def scan_journal(
    journal: Path,
    fmt: str,
    spill: contextlib.ExitStack,
    chunk_rows: int,
    *,
    resolved: frozenset[str] = frozenset(),
) -> JournalScan:
    """Sort keys of a journal in sorted chunks (spilled to temporary files), and
    the rows to drop (:func:`latest_rows`, and the error rows of the photo keys
    ``resolved``)."""
    kept = KeptRows()
    chunk: list[JournalEntry] = []
    chunks: list[Iterable[JournalEntry]] = []
    with open_journal(journal) as fh:
        provenance = read_header(fh, fmt, journal)
        for entry, rock, photo, first in journal_entries(fh, fmt, journal):
            kept.add(entry, rock, photo, first)
            chunk.append(entry)
            if len(chunk) >= chunk_rows:
                chunks.append(_spill(sorted(chunk), journal, spill))
                chunk = []
    chunk.sort()
    chunks.append(chunk)
    return kept.scan(provenance, chunks, resolved)


class KeptRows:
    """What the ranking needs of each row to know which rows a report keeps
    (:func:`latest_rows`), gathered as a journal is read: 18 bytes a row, the
    rock's and the photo's identity hashes, whether the row is an error, and
    whether it begins an attempt at its photo."""

    def __init__(self) -> None:
        self.rocks, self.photos = array.array("q"), array.array("q")
        self.errors, self.starts = bytearray(), bytearray()

    def add(self, entry: JournalEntry, rock: int, photo: int, first: bool) -> None:
        """One row, as :func:`journal_entries` gives it."""
        self.rocks.append(rock)
        self.photos.append(photo)
        self.errors.append(entry[0][0])
        self.starts.append(first)

    def scan(
        self,
        provenance: dict[str, Any] | None,
        chunks: list[Iterable[JournalEntry]],
        resolved: frozenset[str] = frozenset(),
    ) -> JournalScan:
        """The journal's scan: rows kept and errors among them, the rows to drop
        (also the error rows of the photo keys ``resolved``), and ``chunks``."""
        import numpy as np

        def column(values: array.array | bytearray, dtype: type) -> NDArray[Any]:
            return np.frombuffer(values, dtype=dtype) if values else np.zeros(0, dtype)

        photos, errors = column(self.photos, np.int64), column(self.errors, np.bool_)
        keep = latest_rows(photos, column(self.starts, np.bool_), column(self.rocks, np.int64))
        if resolved:
            keep &= ~(errors & np.isin(photos, [_hash(key) for key in resolved]))
        drop = frozenset(np.flatnonzero(~keep).tolist())
        return JournalScan(provenance, int(keep.sum()), int(errors[keep].sum()), drop, chunks)


def latest_rows(
    photos: NDArray[np.int64], starts: NDArray[np.bool_], rocks: NDArray[np.int64]
) -> NDArray[np.bool_]:
    """Which rows of a journal a report keeps: each photo's latest attempt, and
    each rock once (its first row).

    A photo's rows are written together, its rocks by increasing index, so each
    attempt at a photo begins with a row of index 0 (an error row too). A
    resume tries a photo again when its row is an error
    (``ReportJournal.failed``) or the photo changed since: its new rows, an error
    or its rocks however many, come after the old ones, wherever the ranking of
    an earlier run put those, and replace them. A photo with one attempt keeps
    all its rows, in whatever order the ranking left them.

    Parameters
    ----------
    photos, starts, rocks : (n,) ndarray
        Each row's photo identity hash, whether it has index 0, and its rock's
        identity hash, in journal order.

    Returns
    -------
    (n,) ndarray of bool
    """
    import numpy as np

    n = photos.size
    keep = np.zeros(n, dtype=bool)
    if n == 0:
        return keep
    # Few photos are tried again: the rows of those that were are found by a
    # search in their sorted hashes, and only they are grouped.
    begun, attempts = np.unique(photos[starts], return_counts=True)
    again = begun[attempts > 1]
    del begun, attempts
    replaced = None
    if again.size:
        at = np.minimum(np.searchsorted(again, photos), again.size - 1)
        rows = np.flatnonzero(again[at] == photos)
        del at
        _, inverse = np.unique(photos[rows], return_inverse=True)
        inverse = inverse.ravel()
        first = starts[rows]
        last = np.full(again.size, -1, dtype=np.int64)
        np.maximum.at(last, inverse[first], rows[first])
        replaced = rows[rows < last[inverse]]
    if replaced is None or replaced.size == 0:
        keep[np.unique(rocks, return_index=True)[1]] = True
        return keep
    kept = np.ones(n, dtype=bool)
    kept[replaced] = False
    kept_rows = np.flatnonzero(kept)
    keep[kept_rows[np.unique(rocks[kept_rows], return_index=True)[1]]] = True
    return keep


def _spill(entries: list[JournalEntry], journal: Path, stack: contextlib.ExitStack) -> Iterator[JournalEntry]:
    try:
        fh = stack.enter_context(tempfile.TemporaryFile("w+", dir=journal.parent, encoding="utf-8"))
        for key, ordinal, offset, length in entries:
            fh.write(json.dumps([*key, ordinal, offset, length]) + "\n")
        fh.seek(0)
    except OSError as exc:
        raise ParameterError(f"{journal}: cannot sort the report ({exc.strerror or exc})") from None

    def read() -> Iterator[JournalEntry]:
        for line in fh:
            a, b, c, d, e, ordinal, offset, length = json.loads(line)
            yield (a, b, c, d, e), ordinal, offset, length

    return read()


def ranked_rows(journal: Path, fmt: str, scan: JournalScan) -> Iterator[dict[str, Any]]:
    rank = 0
    with open_journal(journal) as fh:
        for key, ordinal, offset, length in heapq.merge(*scan.chunks):
            if ordinal in scan.drop:
                continue
            fh.seek(offset)
            row = _decode(fh.read(length), fmt, journal, ordinal + 1)
            if key[0] == 0:
                rank += 1
                row["rank"] = rank
            else:
                row["rank"] = None
            yield row
