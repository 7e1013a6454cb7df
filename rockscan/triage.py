"""Folder -> ranked report: classify every photo under a folder and rank by interest.

``triage_folder`` walks a folder for photos (:func:`find_photos`), classifies
each exactly as ``rockscan classify`` does (:func:`rockscan.pipeline.classify_path`),
scores its interest (:func:`interest_score`), optionally its novelty against
the shapes seen so far (:mod:`rockscan.novelty`), and writes a row per photo to
a report (:mod:`rockscan.report`) as soon as it is known. When the run ends the
report is ranked. Nothing is printed: progress goes to a callback.

Photos are classified in this process (``workers=1``), in a pool of worker
processes on this machine, or on a Dask distributed cluster (``scheduler``).
The report does not depend on which: each photo's row is computed the same
way, novelty is assessed in the parent in a fixed order, and the ranking is a
total order (:func:`rockscan.report.rank_key`).

Interest (the ranking rule)
---------------------------
``interest = MScore * interest_k`` where ``k`` is the matched library shape
and ``interest_k`` its weight (``interest = <number>`` in the spec, default 1).
A rock that fails the cutoffs (no match) has interest 0. Ties go to the higher
MScore, then to the path; photos that could not be classified come last.
"""

from __future__ import annotations

import base64
import concurrent.futures as cf
import contextlib
import io
import math
import os
import signal
import sys
import time
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from rockscan.errors import ParameterError, RockscanError
from rockscan.io import IMAGE_SUFFIXES
from rockscan.novelty import NoveltyConfig, ObservedShapes, observed_name
from rockscan.pipeline import ClassifyConfig, RockResult, classify_path
from rockscan.report import (
    ROW_KEYS,
    THUMBNAIL_KEY,
    RankedReport,
    ReportJournal,
    finalize_report,
    photo_key,
    refresh_html,
    report_format,
)

if TYPE_CHECKING:
    from rockscan.library import Library

__all__ = [
    "PhotoListing",
    "PhotoOutcome",
    "TriageConfig",
    "TriageSummary",
    "find_photos",
    "interest_score",
    "photo_outcome",
    "thumbnail_data_uri",
    "triage_folder",
    "triage_row",
]

#: ``progress(done, total)``: called once before the first photo and after each row.
Progress = Callable[[int, int], None]


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
    """

    classify: ClassifyConfig = field(default_factory=ClassifyConfig)
    workers: int | None = None
    scheduler: str | None = None
    resume: bool = False
    overwrite: bool = False
    novelty: NoveltyConfig = field(default_factory=NoveltyConfig)
    html_limit: int = 2000
    thumbnail_size: int = 192
    refresh_s: float = 30.0
    window: int | None = None
    connect_timeout_s: float = 30.0

    def __post_init__(self) -> None:
        if self.workers is not None and (isinstance(self.workers, bool) or int(self.workers) < 1):
            raise ParameterError(f"workers must be at least 1, got {self.workers!r}")
        if self.resume and self.overwrite:
            raise ParameterError("resume and overwrite exclude each other; choose one")
        if int(self.html_limit) < 1:
            raise ParameterError("html_limit must be at least 1")
        if not 16 <= int(self.thumbnail_size) <= 1024:
            raise ParameterError("thumbnail_size must be between 16 and 1024 pixels")
        if not (math.isfinite(self.refresh_s) and self.refresh_s >= 0):
            raise ParameterError("refresh_s must be a non-negative number of seconds")
        if self.window is not None and int(self.window) < 1:
            raise ParameterError("window must be at least 1")
        if not (math.isfinite(self.connect_timeout_s) and self.connect_timeout_s > 0):
            raise ParameterError("connect_timeout_s must be a positive number of seconds")
        if self.scheduler is not None and not str(self.scheduler).strip():
            raise ParameterError("scheduler must be an address such as tcp://host:8786")

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

    @property
    def failed(self) -> bool:
        """Whether any photo in the report could not be classified."""
        return self.n_errors > 0


# ---------------------------------------------------------------- finding photos


@dataclass(frozen=True)
class PhotoListing:
    """The photos under a folder.

    Attributes
    ----------
    photos : tuple of str
        Paths of files with a photo ending (:data:`rockscan.io.IMAGE_SUFFIXES`,
        any case), each joined to the folder as given, in a fixed order: each
        folder's files by name, then its subfolders by name.
    problems : tuple of (str, str)
        Folders that could not be listed, and why.
    """

    photos: tuple[str, ...]
    problems: tuple[tuple[str, str], ...] = ()


def find_photos(folder: str | os.PathLike[str]) -> PhotoListing:
    """Walk a folder recursively for photos.

    Symbolic links are followed, and each real folder is visited once, so a
    link loop ends the walk of that branch instead of running forever. Files
    of other kinds are skipped.

    Parameters
    ----------
    folder : path-like

    Returns
    -------
    PhotoListing

    Raises
    ------
    ParameterError
        If ``folder`` is missing or not a folder.
    """
    root = os.path.normpath(os.fspath(folder))
    if not os.path.exists(root):
        raise ParameterError(f"{folder}: folder not found")
    if not os.path.isdir(root):
        raise ParameterError(f"{folder}: is a file, not a folder; use 'rockscan classify' for single photos")
    photos: list[str] = []
    problems: list[tuple[str, str]] = []
    visited: set[tuple[int, int]] = set()
    stack = [root]
    while stack:
        current = stack.pop()
        try:
            st = os.stat(current)
            identity = (st.st_dev, st.st_ino)
            if identity in visited:
                continue
            visited.add(identity)
            with os.scandir(current) as it:
                entries = sorted(it, key=lambda e: e.name)
        except OSError as exc:
            problems.append((current, f"cannot list folder ({exc.strerror or exc})"))
            continue
        subfolders = []
        for entry in entries:
            try:
                is_dir = entry.is_dir()
            except OSError:  # e.g. a link that points at itself
                is_dir = False
            if is_dir:
                subfolders.append(entry.path)
            elif entry.name.lower().endswith(IMAGE_SUFFIXES):
                photos.append(entry.path)
        stack.extend(reversed(subfolders))
    return PhotoListing(photos=tuple(photos), problems=tuple(problems))


# ---------------------------------------------------------------- one photo


@dataclass(frozen=True, eq=False)
class PhotoOutcome:
    """One photo classified, as a worker returns it.

    Attributes
    ----------
    record : dict
        The interface's JSON object for the main rock (``rockscan classify --json``),
        or ``{"path": ..., "error": ...}``.
    radii : (n_angles,) ndarray of float or None
        The rock's radii (for novelty); None for an error.
    thumbnail : str or None
        A JPEG data URI of the photo with outline and matched shape drawn, when asked for.
    """

    record: dict[str, Any]
    radii: NDArray[np.float64] | None = None
    thumbnail: str | None = None


def photo_outcome(
    path: str, library: Library, config: ClassifyConfig | None = None, thumbnail_size: int = 0
) -> PhotoOutcome:
    """Classify one photo for triage; never raises for a bad photo.

    Parameters
    ----------
    path : str
    library : Library
    config : ClassifyConfig, optional
    thumbnail_size : int
        Make a thumbnail with this longer side (0: none).

    Returns
    -------
    PhotoOutcome
        A photo rockscan cannot use gives the error record ``classify`` gives.
        An unexpected failure (a bug) gives an error record that says so,
        so that one photo never stops a batch.
    """
    try:
        result = classify_path(path, library, config)
        rock = result.rocks[0] if result.ok else None
        thumbnail = _thumbnail_or_none(path, rock, library, thumbnail_size) if thumbnail_size else None
        return PhotoOutcome(
            record=result.records()[0], radii=None if rock is None else rock.radii, thumbnail=thumbnail
        )
    except Exception as exc:  # one photo must never stop a batch of millions
        first = str(exc).splitlines()[0] if str(exc) else ""
        return PhotoOutcome(
            record={
                "path": path,
                "error": f"internal error, please report it: {type(exc).__name__}: {first}".rstrip(": "),
            }
        )


def _thumbnail_or_none(path: str, rock: RockResult | None, library: Library, size: int) -> str | None:
    try:
        return thumbnail_data_uri(path, rock, library, size)
    except RockscanError:
        return None


def thumbnail_data_uri(path: str, rock: RockResult | None, library: Library, size: int = 192) -> str:
    """A small JPEG of a photo with the rock's outline (cyan) and the matched
    library shape (magenta, turned by the found angle) drawn on it.

    Parameters
    ----------
    path : str
        The photo.
    rock : RockResult or None
        Its main rock; None draws the photo alone.
    library : Library
    size : int
        Longer side of the thumbnail, pixels (a smaller photo is not enlarged).

    Returns
    -------
    str
        ``data:image/jpeg;base64,...``

    Raises
    ------
    ImageReadError
        If the photo cannot be read.
    """
    import cv2
    from PIL import Image

    from rockscan.io import read_image
    from rockscan.plot import library_outline_rowcol

    image = read_image(path, max_side=2 * size)
    pixels = _rgb8(image.pixels)
    rows, cols = pixels.shape[:2]
    factor = min(1.0, size / max(rows, cols))
    out_size = (max(1, round(cols * factor)), max(1, round(rows * factor)))
    thumb = cv2.resize(pixels, out_size, interpolation=cv2.INTER_AREA) if factor < 1 else pixels.copy()
    if rock is not None:
        full_rows, full_cols = image.full_shape
        per_row, per_col = full_rows / thumb.shape[0], full_cols / thumb.shape[1]

        def points(rowcol: NDArray[np.float64]) -> NDArray[np.int32]:
            # Full-resolution pixel centres to thumbnail pixels, 4 fractional bits.
            col = (rowcol[:, 1] + 0.5) / per_col - 0.5
            row = (rowcol[:, 0] + 0.5) / per_row - 0.5
            return np.round(np.column_stack([col, row]) * 16).astype(np.int32)

        # The matched shape underneath, wider, so that both lines show where they agree.
        matched = points(library_outline_rowcol(library, rock))
        cv2.polylines(thumb, [matched], True, (230, 0, 230), 2, cv2.LINE_AA, 4)
        cv2.polylines(thumb, [points(rock.outline.contour_rowcol)], True, (0, 230, 230), 1, cv2.LINE_AA, 4)
        ((cx, cy),) = points(rock.outline.centroid_rowcol[None, :]) // 16
        cv2.drawMarker(thumb, (int(cx), int(cy)), (230, 0, 230), cv2.MARKER_CROSS, 7, 1)
    buf = io.BytesIO()
    # Full-resolution colour (4:4:4): thin coloured lines keep their colour.
    Image.fromarray(thumb).save(buf, format="JPEG", quality=85, subsampling=0)
    return "data:image/jpeg;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def _rgb8(pixels: NDArray[np.generic]) -> NDArray[np.uint8]:
    arr = np.asarray(pixels)
    if arr.dtype == np.uint16:
        arr = (arr >> 8).astype(np.uint8)
    elif arr.dtype != np.uint8:
        arr = np.clip(arr, 0, 255).astype(np.uint8)
    if arr.ndim == 2:
        arr = np.repeat(arr[..., None], 3, axis=2)
    return np.ascontiguousarray(arr[..., :3])


def interest_score(match: str | None, mscore: float, shape_interest: float) -> float:
    """The ranking rule: MScore weighted by the matched shape's interest.

    Parameters
    ----------
    match : str or None
        The matched shape; None when the rock failed the cutoffs.
    mscore : float
        ``1 - min(w)/mean(w)``, in [0, 1].
    shape_interest : float
        The matched shape's ``interest`` (default 1).

    Returns
    -------
    float
        ``mscore * shape_interest``, or 0 without a match.

    Examples
    --------
    >>> interest_score("five-armed-star", 0.9, 2.0)
    1.8
    >>> interest_score(None, 0.9, 2.0)
    0.0
    """
    return float(mscore) * float(shape_interest) if match is not None else 0.0


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
        Keys :data:`rockscan.report.ROW_KEYS`; the record's own keys keep its
        values, ``rank`` and the novelty keys are None.
    """
    row: dict[str, Any] = dict.fromkeys(ROW_KEYS)
    row.update(record)
    if record.get("error") is None:
        shape_interest = float(library.interest[library.index(record["nearest"])])
        row["shape_interest"] = shape_interest
        row["interest"] = interest_score(record["match"], record["mscore"], shape_interest)
    return row


# ---------------------------------------------------------------- workers

_WORKER: dict[str, Any] = {}


def _init_worker(library: Library, config: ClassifyConfig, thumbnail_size: int) -> None:
    # Ctrl-C is the parent's to handle: it finishes the report, then stops.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _WORKER.update(library=library, config=config, thumbnail_size=thumbnail_size)


def _pool_work(path: str) -> PhotoOutcome:
    return photo_outcome(path, _WORKER["library"], _WORKER["config"], _WORKER["thumbnail_size"])


class _ProcessBackend:
    """Worker processes on this machine; restartable after a worker dies.

    Workers are forked where that is safe (Linux, and no other thread in this
    process): they start at once, sharing the library already in memory.
    Elsewhere they start from a fork server that has rockscan loaded.
    """

    def __init__(
        self,
        n_workers: int,
        fn: Callable[[str], PhotoOutcome],
        initializer: Callable[..., None] | None,
        initargs: tuple[Any, ...],
        context: str | None = None,
    ) -> None:
        import multiprocessing
        import threading

        if context is None:
            safe_fork = sys.platform.startswith("linux") and threading.active_count() == 1
            context = "fork" if safe_fork else "forkserver"
        self.slots = n_workers
        self._args = (fn, initializer, initargs)
        self._context = multiprocessing.get_context(context)
        if context == "forkserver":
            self._context.set_forkserver_preload(["rockscan.triage"])
        self._executor = self._start()

    def _start(self) -> cf.ProcessPoolExecutor:
        _, initializer, initargs = self._args
        return cf.ProcessPoolExecutor(
            self.slots, mp_context=self._context, initializer=initializer, initargs=initargs
        )

    def submit(self, path: str) -> cf.Future[PhotoOutcome]:
        return self._executor.submit(self._args[0], path)

    def restart(self) -> None:
        self._executor.shutdown(wait=False, cancel_futures=True)
        self._executor = self._start()

    def close(self) -> None:
        self._executor.shutdown(wait=True, cancel_futures=True)


class _DaskBackend:
    """Workers of a Dask distributed cluster."""

    def __init__(
        self, address: str, library: Library, config: ClassifyConfig, thumbnail_size: int, timeout_s: float
    ) -> None:
        try:
            from distributed import Client
        except ImportError:
            raise ParameterError("--scheduler needs dask.distributed: pip install 'rockscan[dask]'") from None
        try:
            self._client = Client(address, timeout=f"{timeout_s}s", set_as_default=False)
        except (OSError, TimeoutError, ValueError) as exc:
            raise ParameterError(f"cannot reach the Dask scheduler at {address} ({exc})") from None
        # The library travels to each worker once, not with every photo.
        library_future = self._client.scatter(library, broadcast=True, hash=False)
        self._executor = self._client.get_executor(pure=False)
        self._args = (library_future, config, thumbnail_size)
        self.slots = max(1, sum(self._client.nthreads().values()))

    def submit(self, path: str) -> cf.Future[PhotoOutcome]:
        return self._executor.submit(photo_outcome, path, *self._args)

    def restart(self) -> None:
        """A Dask cluster replaces lost workers itself."""

    def close(self) -> None:
        self._executor.shutdown(wait=False)
        self._client.close()


def _run_backend(
    paths: list[str], backend: _ProcessBackend | _DaskBackend, window: int, *, ordered: bool
) -> Iterator[tuple[int, PhotoOutcome]]:
    """Outcomes of ``paths`` as (index, outcome): as they finish, or in order.

    At most ``window`` photos are in flight or waiting their turn, so memory
    stays flat however many photos there are. If a worker process dies (the
    pool breaks), the photos it may have been working on are tried again one
    at a time in a new pool: the one that breaks it again gets an error row.
    """
    pending: dict[cf.Future[PhotoOutcome], int] = {}
    ready: dict[int, PhotoOutcome] = {}
    suspects: deque[int] = deque()
    isolating = False
    next_new = next_out = 0

    def fill() -> None:
        nonlocal next_new
        if suspects:
            if not pending:
                i = suspects.popleft()
                pending[backend.submit(paths[i])] = i
            return
        while next_new < len(paths) and len(pending) + len(ready) < window:
            pending[backend.submit(paths[next_new])] = next_new
            next_new += 1

    fill()
    while pending:
        done, _ = cf.wait(pending, return_when=cf.FIRST_COMPLETED)
        broken = []
        finished: list[tuple[int, PhotoOutcome]] = []
        for future in done:
            i = pending.pop(future)
            try:
                finished.append((i, future.result()))
            except (cf.BrokenExecutor, cf.CancelledError):
                broken.append(i)
            except Exception as exc:  # a worker lost by the cluster, an unpicklable result, ...
                finished.append((i, PhotoOutcome({"path": paths[i], "error": f"worker failed: {exc}"})))
        if broken:
            lost = sorted(broken + list(pending.values()))
            pending.clear()
            backend.restart()
            if isolating:
                # Alone in the pool, this photo is what kills the worker.
                (culprit,) = broken
                message = (
                    "the worker process died on this photo (out of memory, or a crash while decoding it)"
                )
                finished.append((culprit, PhotoOutcome({"path": paths[culprit], "error": message})))
                lost = [i for i in lost if i != culprit]
            suspects.extend(i for i in lost if i not in suspects)
        isolating = bool(suspects)
        for i, outcome in sorted(finished):
            if ordered:
                ready[i] = outcome
            else:
                yield i, outcome
        while ordered and next_out in ready:
            yield next_out, ready.pop(next_out)
            next_out += 1
        fill()


# ---------------------------------------------------------------- the run


def triage_folder(
    folder: str | os.PathLike[str],
    report: str | os.PathLike[str],
    library: Library,
    config: TriageConfig | None = None,
    *,
    observed: str | os.PathLike[str] | None = None,
    progress: Progress | None = None,
) -> TriageSummary:
    """Classify every photo under a folder and write a ranked report.

    Parameters
    ----------
    folder : path-like
        Walked recursively (:func:`find_photos`).
    report : path-like
        ``.csv``, ``.jsonl`` or ``.html`` (see :mod:`rockscan.report`). Rows
        are written as photos finish; the report is ranked when the run ends,
        or is interrupted.
    library : Library
        The library of interest.
    config : TriageConfig, optional
    observed : path-like, optional
        The observed library file (:mod:`rockscan.novelty`): read if it
        exists, else started from ``library``'s shapes; written back when the
        run ends (and every few seconds while it grows).
    progress : callable, optional
        ``progress(done, total)``.

    Returns
    -------
    TriageSummary

    Raises
    ------
    ParameterError
        For a missing folder, an unknown report ending, an existing report
        without ``resume`` or ``overwrite``, or an unreachable scheduler.
    LibraryError
        If the observed library cannot be read or does not fit ``library``.
    KeyboardInterrupt
        After the report has been ranked with the rows finished so far.
    """
    from rockscan.io import load_library, save_library

    config = config or TriageConfig()
    started = time.perf_counter()
    report = Path(report)
    fmt = report_format(report)
    listing = find_photos(folder)
    novelty_state: ObservedShapes | None = None
    observed_path = Path(observed) if observed is not None else None
    if observed_path is not None:
        if observed_path.exists():
            novelty_state = ObservedShapes.from_file(load_library(observed_path), library, config.novelty)
        else:
            novelty_state = ObservedShapes.from_library(library, config.novelty)
    journal = ReportJournal(report, resume=config.resume, overwrite=config.overwrite)
    html = fmt == "html"
    todo = [p for p in listing.photos if photo_key(p) not in journal.done]
    problems = [(p, msg) for p, msg in listing.problems if photo_key(p) not in journal.done]
    total = len(todo) + len(problems)
    done = n_interesting = n_novel = 0
    last_refresh = last_save = time.monotonic()
    refresh_every = float(config.refresh_s)
    # A new observed library is written even if no rock turns out novel.
    observed_dirty = observed_path is not None and not observed_path.exists()
    names = set(novelty_state.library.names) if novelty_state is not None else set()

    def save_observed() -> None:
        nonlocal observed_dirty, last_save
        if novelty_state is not None and observed_path is not None and observed_dirty:
            save_library(novelty_state.library, observed_path)
            observed_dirty = False
            last_save = time.monotonic()

    def commit(outcome: PhotoOutcome) -> None:
        nonlocal done, n_interesting, n_novel, novelty_state, observed_dirty, last_refresh, refresh_every
        row = triage_row(outcome.record, library)
        if novelty_state is not None and outcome.radii is not None:
            novelty = novelty_state.assess(outcome.radii)
            row.update(novelty=novelty.score, novel=novelty.novel, nearest_observed=novelty.nearest)
            if novelty.novel:
                name = observed_name(Path(row["path"]).stem, names)
                names.add(name)
                novelty_state = novelty_state.with_shape(name, outcome.radii)
                observed_dirty = True
                n_novel += 1
        if html:
            row[THUMBNAIL_KEY] = outcome.thumbnail
        journal.append(row)
        done += 1
        n_interesting += bool(row.get("interesting"))
        now = time.monotonic()
        if observed_dirty and now - last_save >= 5.0:
            save_observed()
        if html and now - last_refresh >= refresh_every:
            refresh_html(report, title=_title(folder), limit=config.html_limit)
            last_refresh = time.monotonic()
            # A refresh reads the whole journal: keep refreshes under 5% of the run.
            refresh_every = max(float(config.refresh_s), 20.0 * (last_refresh - now))
        if progress is not None:
            progress(done, total)

    interrupted = False
    backend: _ProcessBackend | _DaskBackend | None = None
    try:
        if html:
            refresh_html(report, title=_title(folder), limit=config.html_limit)
        if progress is not None:
            progress(0, total)
        for path, message in problems:
            commit(PhotoOutcome({"path": path, "error": message}))
        thumb = int(config.thumbnail_size) if html else 0
        ordered = novelty_state is not None
        if config.scheduler is None and (config.n_workers == 1 or len(todo) <= 1):
            for path in todo:
                commit(photo_outcome(path, library, config.classify, thumb))
        elif todo:
            if config.scheduler is not None:
                backend = _DaskBackend(
                    config.scheduler, library, config.classify, thumb, config.connect_timeout_s
                )
            else:
                if library.face_config.grid == "polar":
                    # Computed once here, inherited by forked workers.
                    _ = library.scan_templates
                backend = _ProcessBackend(
                    min(config.n_workers, len(todo)),
                    _pool_work,
                    _init_worker,
                    (library, config.classify, thumb),
                )
            window = backend.slots * int(config.window or 4)
            for _, outcome in _run_backend(todo, backend, window, ordered=ordered):
                commit(outcome)
    except KeyboardInterrupt:
        interrupted = True
    except BaseException:
        journal.close()
        if backend is not None:
            backend.close()
        # The rows written so far assume the shapes they added are kept.
        with contextlib.suppress(RockscanError, OSError):
            save_observed()
        raise
    if backend is not None:
        backend.close()
    journal.close()
    save_observed()
    ranked: RankedReport = finalize_report(report, title=_title(folder), limit=config.html_limit)
    if interrupted:
        raise KeyboardInterrupt
    return TriageSummary(
        report=report,
        n_found=len(listing.photos) + len(listing.problems),
        n_resumed=len(listing.photos) + len(listing.problems) - total,
        n_processed=done,
        n_rows=ranked.n_rows,
        n_errors=ranked.n_errors,
        n_interesting=n_interesting,
        n_novel=n_novel,
        n_observed=None if novelty_state is None else len(novelty_state.library),
        top=ranked.top,
        errors=ranked.errors,
        elapsed_s=time.perf_counter() - started,
    )


def _title(folder: str | os.PathLike[str]) -> str:
    return f"rockscan triage: {os.fspath(folder)}"
