"""Folder -> ranked report: classify every photo under a folder and rank by interest.

``triage_folder`` walks a folder for photos (:func:`find_photos`), classifies
each exactly as ``rockscan classify`` does (:func:`rockscan.run.pipeline.classify_path`),
scores its interest (:func:`interest_score`), optionally its novelty against
the shapes seen so far (:mod:`rockscan.core.novelty`), and writes a row per photo to
a report (:mod:`rockscan.run.report`) as soon as it is known. When the run ends the
report is ranked. Nothing is printed: progress goes to a callback.

Photos are classified in this process (``workers=1``), in a pool of worker
processes on this machine, or on a Dask distributed cluster (``scheduler``).
The report does not depend on which: each photo's row is computed the same
way, novelty is assessed in the parent in a fixed order, and the ranking is a
total order (:func:`rockscan.io.report.rank_key`).

Interest (the ranking rule)
---------------------------
``interest = MScore * interest_k`` where ``k`` is the matched library shape
and ``interest_k`` its weight (``interest = <number>`` in the spec, default 1).
A rock that fails the cutoffs (no match) has interest 0. With an observed
library, novelty is rewarded too::

    interest = max(MScore * interest_k, w * min(novelty / threshold, 1))

so a rock unlike everything seen (novel: ``novelty > threshold``) scores ``w``
(default: the library's largest ``interest_k``, as much as a perfect match of
its most wanted shape) instead of sinking to the bottom. Ties go to the higher
MScore, then to the path; photos that could not be classified come last.
"""

from __future__ import annotations

import contextlib
import math
import numbers
import os
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rockscan.core.errors import ParameterError, RockscanError
from rockscan.core.novelty import NoveltyConfig, ObservedShapes, observed_name
from rockscan.io.atomic import remove_leftovers
from rockscan.io.folders import PhotoListing, find_photos
from rockscan.io.library import append_pending, read_pending
from rockscan.io.report import (
    ROW_KEYS,
    THUMBNAIL_KEY,
    RankedReport,
    ReportJournal,
    journal_path,
    lock_report,
    photo_key,
    report_format,
    report_target,
)
from rockscan.run.backends import (
    _DaskBackend,
    _init_worker,
    _pool_work,
    _ProcessBackend,
    _run_backend,
    held_interrupts,
)
from rockscan.run.photo import PhotoOutcome, photo_outcome
from rockscan.run.pipeline import ClassifyConfig
from rockscan.run.provenance import novelty_weight, report_provenance
from rockscan.run.report import finalize_report, refresh_html

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

    from rockscan.core.library import Library

__all__ = ["TriageConfig", "TriageSummary", "interest_score", "triage_folder", "triage_row"]

#: ``progress(done, total)``: called once before the first photo and after each row.
Progress = Callable[[int, int], None]


def _whole(value: object, low: int, high: int | None) -> bool:
    """``value`` is an integer (not a bool) from ``low`` to ``high`` (None: no top)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        return False
    return low <= value and (high is None or value <= high)


@dataclass(frozen=True)
class TriageConfig:
    """Settings of a triage run.

    Parameters
    ----------
    classify : ClassifyConfig
        Segmentation and matching, as for ``rockscan classify``.
    workers : int or None
        Worker processes on this machine; None uses every core, 1 classifies
        in this process.
    scheduler : str or None
        Address of a Dask distributed scheduler (``tcp://host:8786``); the
        photos are then classified on its workers, which must see the folder
        at the same path. Overrides ``workers``.
    resume : bool
        Continue an existing report: photos already in it are skipped.
    overwrite : bool
        Replace an existing report.
    novelty : NoveltyConfig or None
        Novelty settings, used when an observed library is given.
    html_limit : int
        An HTML report shows the best ``html_limit`` photos (and at most as
        many error rows); its journal keeps every row.
    thumbnail_size : int
        Longer side of an HTML report's thumbnails, pixels.
    refresh_s : float
        Rebuild an HTML report's page at most this often during a run, seconds.
    window : int or None
        Photos in flight per worker (bounds memory); default 4.
    connect_timeout_s : float
        How long to try to reach the scheduler, seconds.
    all_rocks : bool
        Rank every rock of every photo (``--all``), each row with its ``index``.
    novelty_weight : float or None
        ``w`` of the interest rule with an observed library; None takes the
        library's largest shape interest, 0 leaves novelty out of interest.
    """

    classify: ClassifyConfig = field(default_factory=ClassifyConfig)
    workers: int | None = None
    scheduler: str | None = None
    resume: bool = False
    overwrite: bool = False
    novelty: NoveltyConfig = field(default_factory=NoveltyConfig)
    html_limit: int = 2000
    thumbnail_size: int = 144
    refresh_s: float = 30.0
    window: int | None = None
    connect_timeout_s: float = 30.0
    all_rocks: bool = False
    novelty_weight: float | None = None

    def __post_init__(self) -> None:
        # Whole numbers: int() of nan or inf raised ValueError or OverflowError, and of 2.5 gave 2.
        for name, low, high in (("workers", 1, None), ("html_limit", 1, None), ("window", 1, None)):
            value = getattr(self, name)
            if value is not None and not _whole(value, low, high):
                raise ParameterError(f"{name} must be a whole number of at least {low}, got {value!r}")
        if not _whole(self.thumbnail_size, 16, 1024):
            raise ParameterError(
                f"thumbnail_size must be a whole number of 16 to 1024 pixels, got {self.thumbnail_size!r}"
            )
        if self.resume and self.overwrite:
            raise ParameterError("resume and overwrite exclude each other; choose one")
        if not (math.isfinite(self.refresh_s) and self.refresh_s >= 0):
            raise ParameterError("refresh_s must be a non-negative number of seconds")
        if not (math.isfinite(self.connect_timeout_s) and self.connect_timeout_s > 0):
            raise ParameterError("connect_timeout_s must be a positive number of seconds")
        if self.scheduler is not None and not str(self.scheduler).strip():
            raise ParameterError("scheduler must be an address such as tcp://host:8786")
        if self.novelty_weight is not None and not (
            math.isfinite(self.novelty_weight) and self.novelty_weight >= 0
        ):
            raise ParameterError("novelty_weight must be a non-negative number")

    @property
    def n_workers(self) -> int:
        """Worker processes used on this machine."""
        if self.workers is not None:
            return int(self.workers)
        try:
            return max(1, len(os.sched_getaffinity(0)))
        except AttributeError:  # not on Linux
            return max(1, os.cpu_count() or 1)


@dataclass(frozen=True)
class TriageSummary:
    """What a triage run did and what its report holds.

    Attributes
    ----------
    report : Path
    n_found : int
        Photos found under the folder (and folders that could not be listed).
    n_resumed : int
        Of them, already in the report from an earlier run and skipped.
    n_processed : int
        Photos classified in this run.
    n_rows : int
        Photos in the report, each once.
    n_errors : int
        Error rows in the report (this and earlier runs).
    n_interesting : int
        Photos of this run that passed the cutoffs.
    n_novel : int
        Photos of this run flagged novel (0 without an observed library).
    n_observed : int or None
        Shapes in the observed library at the end (None without one).
    top : tuple of dict
        The best 10 rows of the report.
    errors : tuple of dict
        The first 20 error rows of the report.
    elapsed_s : float
    n_skipped : int
        Files under the folder that are not photos (no photo ending), skipped.
    skipped_endings : tuple of str
        Their endings (see :class:`rockscan.io.folders.PhotoListing`).
    n_gone : int
        Photos a resumed report holds that are no longer under the folder (their rows are kept).
    n_changed : int
        Photos a resumed report holds that were changed after the report was last
        written: their rows are of the photos as they were.
    n_retried : int
        Of them, in the report with an error row from an earlier run, and
        tried again in this one (their new rows replace the error rows).
    """

    report: Path
    n_found: int
    n_resumed: int
    n_processed: int
    n_rows: int
    n_errors: int
    n_interesting: int
    n_novel: int
    n_observed: int | None
    top: tuple[dict[str, Any], ...] = field(repr=False)
    errors: tuple[dict[str, Any], ...] = field(repr=False)
    elapsed_s: float = 0.0
    n_skipped: int = 0
    skipped_endings: tuple[str, ...] = ()
    n_gone: int = 0
    n_changed: int = 0
    n_retried: int = 0

    @property
    def failed(self) -> bool:
        """Whether any photo in the report could not be classified."""
        return self.n_errors > 0


def interest_score(
    match: str | None,
    mscore: float,
    shape_interest: float,
    *,
    novelty: float | None = None,
    threshold: float = 1.0,
    novelty_weight: float = 0.0,
) -> float:
    """The ranking rule: MScore weighted by the matched shape's interest, and
    novelty rewarded when it is measured.

    Parameters
    ----------
    match : str or None
        The matched shape; None when the rock failed the cutoffs.
    mscore : float
        ``1 - min(w)/mean(w)``, in [0, 1].
    shape_interest : float
        The matched shape's ``interest`` (default 1).
    novelty : float, optional
        The rock's distance from every shape seen so far (:mod:`rockscan.core.novelty`).
    threshold : float
        Novelty above which a rock is novel.
    novelty_weight : float
        What a novel rock scores (``w``).

    Returns
    -------
    float
        ``max(mscore * shape_interest, w * min(novelty / threshold, 1))``, the
        first term 0 without a match, the second 0 without novelty.

    Examples
    --------
    >>> interest_score("five-armed-star", 0.9, 2.0)
    1.8
    >>> interest_score(None, 0.9, 2.0)
    0.0
    >>> interest_score(None, 0.9, 2.0, novelty=0.3, threshold=0.2, novelty_weight=2.0)
    2.0
    """
    score = float(mscore) * float(shape_interest) if match is not None else 0.0
    if novelty is None or novelty_weight <= 0:
        return score
    if threshold > 0:
        ratio = min(float(novelty) / threshold, 1.0)
    else:
        ratio = 1.0 if novelty > 0 else 0.0
    return max(score, float(novelty_weight) * ratio)


def triage_row(record: dict[str, Any], library: Library) -> dict[str, Any]:
    """A report row from a photo's ``classify`` record.

    Parameters
    ----------
    record : dict
        As :class:`PhotoOutcome` holds it.
    library : Library
        Gives the shapes' interest.

    Returns
    -------
    row : dict
        Keys :data:`rockscan.io.report.ROW_KEYS` then any other key of the
        record (``outline``); the record's own keys keep their values,
        ``rank`` and the novelty keys are None.
    """
    row: dict[str, Any] = dict.fromkeys(ROW_KEYS)
    row.update(record)
    if record.get("error") is None:
        shape_interest = float(library.interest[library.index(record["nearest"])])
        row["shape_interest"] = shape_interest
        row["interest"] = interest_score(record["match"], record["mscore"], shape_interest)
    return row


def triage_folder(
    folder: str | os.PathLike[str],
    report: str | os.PathLike[str],
    library: Library,
    config: TriageConfig | None = None,
    *,
    observed: str | os.PathLike[str] | None = None,
    progress: Progress | None = None,
    on_error: Callable[[dict[str, Any]], None] | None = None,
) -> TriageSummary:
    """Classify every photo under a folder and write a ranked report.

    Parameters
    ----------
    folder : path-like
        Walked recursively (:func:`find_photos`).
    report : path-like
        ``.csv``, ``.jsonl``, ``.html`` or ``.geojson`` (see
        :mod:`rockscan.run.report`). Rows are written as photos finish; the report
        is ranked when the run ends, or is interrupted. The report is locked
        for the run: a second run on it is refused at once.
    library : Library
        The library of interest.
    config : TriageConfig, optional
    observed : path-like, optional
        The observed library file (:mod:`rockscan.core.novelty`): read if it
        exists, else started from ``library``'s shapes; written back when the
        run ends (and every few seconds while it grows).
    progress : callable, optional
        ``progress(done, total)``.
    on_error : callable, optional
        Called with each error row as it is written.

    Returns
    -------
    TriageSummary

    Raises
    ------
    ReportSettingsError
        If ``resume`` meets a report made with other settings (it is left as it was).
    ReportBusyError
        If another run is writing the report.
    ParameterError
        For a missing folder, an unknown report ending, an existing report
        without ``resume`` or ``overwrite``, an unreachable or lost
        scheduler, or a report that cannot be written (disk full): the rows
        written so far are then kept, ranked where possible.
    LibraryError
        If the observed library cannot be read or does not fit ``library``.
    KeyboardInterrupt
        After the report has been ranked with the rows finished so far.
    TypeError
        If ``library`` is not a :class:`Library`.
    """
    from rockscan.core.match import require_library

    require_library(library)
    config = config or TriageConfig()
    report = report_target(report)
    listing = find_photos(folder)
    with lock_report(report):
        # Held by this run alone: a temporary report beside it is a killed run's.
        remove_leftovers(report)
        return _triage_locked(listing, folder, report, library, config, observed, progress, on_error)


def _triage_locked(
    listing: PhotoListing,
    folder: str | os.PathLike[str],
    report: Path,
    library: Library,
    config: TriageConfig,
    observed: str | os.PathLike[str] | None,
    progress: Progress | None,
    on_error: Callable[[dict[str, Any]], None] | None,
) -> TriageSummary:
    started = time.perf_counter()
    # Before the journal is opened: a resume drops a row cut short, and so writes to it.
    written = _modified(journal_path(report))
    run = _TriageRun(report, folder, library, config, observed, progress, on_error)
    # A folder that could not be listed then and can now: its photos are listed,
    # and its error row goes from the report.
    unlisted = {photo_key(p) for p, _ in listing.problems}
    resolved = frozenset(k for k in run.journal.failed if k not in unlisted and os.path.isdir(k))
    run.resolved = resolved
    stale = _stale_rows(listing, run.journal.done - resolved, run.journal.failed, written)
    # A photo that failed before is tried again: it may have been half copied,
    # unreadable to this user, or met a fault since mended; its latest rows count.
    settled = run.journal.done - run.journal.failed
    todo = [p for p in listing.photos if photo_key(p) not in settled]
    problems = [(p, msg) for p, msg in listing.problems if photo_key(p) not in settled]
    n_retried = sum(photo_key(p) in run.journal.failed for p in (*todo, *(p for p, _ in problems)))
    run.total = len(todo) + len(problems)
    interrupted = False
    failure: RockscanError | None = None
    try:
        run.start()
        for path, message in problems:
            run.commit(PhotoOutcome({"path": path, "error": message}))
        outcomes = _outcomes(todo, library, config, run.thumbnail_size, ordered=run.novelty is not None)
        # Closing the generator closes its backend, also when a row cannot be written.
        with contextlib.closing(outcomes):
            for outcome in outcomes:
                run.commit(outcome)
    except KeyboardInterrupt:
        interrupted = True
    except RockscanError as exc:
        # A lost scheduler, a full disk: rank what is done, then say why the run stopped.
        failure = exc
    except BaseException:
        run.journal.close()
        # The rows written so far assume the shapes they added are kept.
        with contextlib.suppress(RockscanError, OSError):
            run.save_observed()
        raise
    ranked = run.finish(failure)
    if interrupted:
        raise KeyboardInterrupt
    n_found = len(listing.photos) + len(listing.problems)
    return TriageSummary(
        report=report,
        n_found=n_found,
        n_resumed=n_found - run.total,
        n_retried=n_retried,
        n_processed=run.done,
        n_rows=ranked.n_rows,
        n_errors=ranked.n_errors,
        n_interesting=run.n_interesting,
        n_novel=run.n_novel,
        n_observed=None if run.novelty is None else len(run.novelty.library),
        top=ranked.top,
        errors=ranked.errors,
        elapsed_s=time.perf_counter() - started,
        n_skipped=listing.n_skipped,
        skipped_endings=listing.skipped_endings,
        n_gone=stale[0],
        n_changed=stale[1],
    )


def _modified(path: Path) -> float | None:
    """When a file was last written, or None if it is not there."""
    try:
        return path.stat().st_mtime
    except OSError:
        return None


def _stale_rows(
    listing: PhotoListing, done: set[str], failed: set[str], written: float | None
) -> tuple[int, int]:
    """Of the photos a resumed report holds, how many are no longer under the
    folder, and how many were changed after the report was last written (at
    ``written``: a photo replaced under its name keeps its old row; one that
    ``failed`` is tried again); both 0 for a new report."""
    if not done or written is None:
        return 0, 0
    found = {photo_key(p) for p in listing.photos} | {photo_key(p) for p, _ in listing.problems}
    changed = 0
    for path in listing.photos:
        key = photo_key(path)
        if key in done and key not in failed:
            with contextlib.suppress(OSError):
                changed += os.stat(path).st_mtime > written
    return len(done - found), changed


def _outcomes(
    todo: list[str], library: Library, config: TriageConfig, thumbnail_size: int, *, ordered: bool
) -> Iterator[PhotoOutcome]:
    """Each photo's outcome, from this process, a local pool or a Dask cluster."""
    if config.scheduler is None and (config.n_workers == 1 or len(todo) <= 1):
        for path in todo:
            yield photo_outcome(path, library, config.classify, thumbnail_size, config.all_rocks)
        return
    if not todo:
        return
    backend: _ProcessBackend | _DaskBackend
    if config.scheduler is not None:
        backend = _DaskBackend(
            config.scheduler,
            library,
            config.classify,
            thumbnail_size,
            config.connect_timeout_s,
            config.all_rocks,
        )
    else:
        if library.face_config.grid == "polar":
            # Computed once here, inherited by forked workers.
            _ = library.scan_templates
        backend = _ProcessBackend(
            min(config.n_workers, len(todo)),
            _pool_work,
            _init_worker,
            (library, config.classify, thumbnail_size, config.all_rocks, os.getpid()),
        )
    try:
        window = backend.slots * int(config.window or 4)
        with held_interrupts() as stop:
            for _, outcome in _run_backend(todo, backend, window, ordered=ordered, stop=stop):
                yield outcome
    finally:
        backend.close()


class _TriageRun:
    """The state of one triage while photos come in: the journal, the observed
    library as it grows, the counts, and when the page and the observed library
    were last written."""

    #: Seconds between writes of a growing observed library.
    SAVE_OBSERVED_S = 5.0

    def __init__(
        self,
        report: Path,
        folder: str | os.PathLike[str],
        library: Library,
        config: TriageConfig,
        observed: str | os.PathLike[str] | None,
        progress: Progress | None,
        on_error: Callable[[dict[str, Any]], None] | None,
    ) -> None:
        self.report, self.title, self.library, self.config = report, _title(folder), library, config
        self.progress, self.on_error = progress, on_error
        self.observed_path = Path(observed) if observed is not None else None
        self.observed_dirty = False
        self.novelty = self._observed_shapes()
        self.novelty_weight = novelty_weight(library, config)
        provenance = report_provenance(library, config, self.novelty, folder=folder, observed=observed)
        self.journal = ReportJournal(
            report, resume=config.resume, overwrite=config.overwrite, provenance=provenance
        )
        self.html = report_format(report) == "html"
        self.thumbnail_size = int(config.thumbnail_size) if self.html else 0
        self.total = self.done = self.n_interesting = self.n_novel = 0
        self.last_refresh = self.last_save = time.monotonic()
        self.refresh_every = float(config.refresh_s)
        # A new observed library is written even if no rock turns out novel.
        self.observed_dirty |= self.observed_path is not None and not self.observed_path.exists()
        self.names = set(self.novelty.library.names) if self.novelty is not None else set()
        # Error rows of folders that can be listed now (_triage_locked).
        self.resolved: frozenset[str] = frozenset()
        # Novel shapes of the photo being committed, kept once its rows are written.
        self._unwritten: list[tuple[str, NDArray[np.float64]]] = []

    @property
    def pending_path(self) -> Path | None:
        """Where each novel shape is appended as it is found, until the observed
        library is next written: a run killed in between loses none of them."""
        return (
            None
            if self.observed_path is None
            else self.observed_path.with_name(self.observed_path.name + ".pending")
        )

    def _observed_shapes(self) -> ObservedShapes | None:
        from rockscan.io import load_library

        if self.observed_path is None:
            return None
        if self.observed_path.exists():
            novelty = ObservedShapes.from_file(
                load_library(self.observed_path), self.library, self.config.novelty
            )
        else:
            novelty = ObservedShapes.from_library(self.library, self.config.novelty)
        # The shapes a killed run found after its last write of the library.
        known = set(novelty.library.names)
        for name, radii in read_pending(self.pending_path):
            if name not in known:
                novelty = novelty.with_shape(name, radii)
                known.add(name)
                self.observed_dirty = True
        return novelty

    def start(self) -> None:
        if self.html:
            refresh_html(self.report, title=self.title, limit=self.config.html_limit)
        if self.progress is not None:
            self.progress(0, self.total)

    def save_observed(self) -> None:
        from rockscan.io import save_library

        if self.novelty is not None and self.observed_path is not None and self.observed_dirty:
            save_library(self.novelty.library, self.observed_path)
            self.observed_dirty = False
            # Written whole (atomically), the library holds every pending shape.
            self.pending_path.unlink(missing_ok=True)
            self.last_save = time.monotonic()

    def row_of(self, outcome: PhotoOutcome) -> dict[str, Any]:
        """The report row of one rock, its novelty assessed (and the observed
        library grown) in the order the rows are committed."""
        row = triage_row(outcome.record, self.library)
        if self.novelty is not None and outcome.radii is not None:
            found = self.novelty.assess(outcome.radii)
            row.update(novelty=found.score, novel=found.novel, nearest_observed=found.nearest)
            row["interest"] = interest_score(
                row["match"],
                row["mscore"],
                row["shape_interest"],
                novelty=found.score,
                threshold=self.novelty.threshold,
                novelty_weight=self.novelty_weight,
            )
            if found.novel:
                stem = Path(row["path"]).stem + (f"-{row['index']}" if row.get("index") else "")
                name = observed_name(stem, self.names)
                self.names.add(name)
                # The next rock of the photo is assessed against this one; the shape
                # is kept (in the pending file) once the photo's rows are written.
                self.novelty = self.novelty.with_shape(name, outcome.radii)
                self._unwritten.append((name, outcome.radii))
                self.n_novel += 1
        if self.html:
            row[THUMBNAIL_KEY] = outcome.thumbnail
        return row

    def commit(self, outcome: PhotoOutcome) -> None:
        before = (self.novelty, set(self.names), self.n_novel)
        self._unwritten = []
        rows = [self.row_of(rock) for rock in outcome.rocks()]
        try:
            # All rows of a photo in one write: a crash leaves all of them or none.
            self.journal.append(rows)
        except RockscanError:
            # Its rows lost (a full disk), the photo is done again on resume: its
            # novel shapes must not be in the observed library by then, or it
            # would be compared with itself and found not novel.
            self.novelty, self.names, self.n_novel = before
            raise
        for name, radii in self._unwritten:
            append_pending(self.pending_path, name, radii)
            self.observed_dirty = True
        self.done += 1
        self.n_interesting += sum(bool(row.get("interesting")) for row in rows)
        if self.on_error is not None and rows[0].get("error") is not None:
            self.on_error(rows[0])
        now = time.monotonic()
        if self.observed_dirty and now - self.last_save >= self.SAVE_OBSERVED_S:
            self.save_observed()
        if self.html and now - self.last_refresh >= self.refresh_every:
            refresh_html(self.report, title=self.title, limit=self.config.html_limit)
            self.last_refresh = time.monotonic()
            # A refresh reads the whole journal: keep refreshes under 5% of the run.
            self.refresh_every = max(float(self.config.refresh_s), 20.0 * (self.last_refresh - now))
        if self.progress is not None:
            self.progress(self.done, self.total)

    def finish(self, failure: RockscanError | None) -> RankedReport:
        """Close the journal, write the observed library and rank the report;
        then raise the error that stopped the run, if one did."""
        self.journal.close()
        try:
            self.save_observed()
            ranked = finalize_report(
                self.report, title=self.title, limit=self.config.html_limit, resolved=self.resolved
            )
        except RockscanError:
            if failure is None:
                raise
            raise failure from None
        if failure is not None:
            raise failure
        return ranked


def _title(folder: str | os.PathLike[str]) -> str:
    return f"rockscan triage: {os.fspath(folder)}"
