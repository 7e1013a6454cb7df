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
A rock that fails the cutoffs (no match) has interest 0. With an observed
library, novelty is rewarded too::

    interest = max(MScore * interest_k, w * min(novelty / threshold, 1))

so a rock unlike everything seen (novel: ``novelty > threshold``) scores ``w``
(default: the library's largest ``interest_k``, as much as a perfect match of
its most wanted shape) instead of sinking to the bottom. Ties go to the higher
MScore, then to the path; photos that could not be classified come last.
"""

from __future__ import annotations

import base64
import concurrent.futures as cf
import contextlib
import dataclasses
import hashlib
import io
import json
import logging
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
    lock_report,
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
    "library_hash",
    "photo_outcome",
    "report_provenance",
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
        A data URI of a small picture of the photo with outline and matched shape drawn, when asked for.
    more : tuple of PhotoOutcome
        The photo's other rocks, with ``all_rocks`` (index 1, 2, ...).
    """

    record: dict[str, Any]
    radii: NDArray[np.float64] | None = None
    thumbnail: str | None = None
    more: tuple[PhotoOutcome, ...] = ()

    def rocks(self) -> tuple[PhotoOutcome, ...]:
        """This outcome and those of the photo's other rocks, by index."""
        return (self, *self.more)


def photo_outcome(
    path: str,
    library: Library,
    config: ClassifyConfig | None = None,
    thumbnail_size: int = 0,
    all_rocks: bool = False,
) -> PhotoOutcome:
    """Classify one photo for triage; never raises for a bad photo.

    Parameters
    ----------
    path : str
    library : Library
    config : ClassifyConfig, optional
    thumbnail_size : int
        Make a thumbnail with this longer side (0: none).
    all_rocks : bool
        Every rock of the photo, not only the main one.

    Returns
    -------
    PhotoOutcome
        A photo rockscan cannot use gives the error record ``classify`` gives.
        An unexpected failure (a bug) gives an error record that says so,
        so that one photo never stops a batch.
    """
    try:
        result = classify_path(path, library, config, all_rocks=all_rocks)
        if not result.ok:
            return PhotoOutcome(record=result.records()[0])
        thumbs = _thumbnails_or_none(path, result.rocks, library, thumbnail_size)
        outcomes = [
            PhotoOutcome(record=record, radii=rock.radii, thumbnail=thumb)
            for record, rock, thumb in zip(result.records(), result.rocks, thumbs, strict=True)
        ]
        return dataclasses.replace(outcomes[0], more=tuple(outcomes[1:]))
    except Exception as exc:  # one photo must never stop a batch of millions
        first = str(exc).splitlines()[0] if str(exc) else ""
        return PhotoOutcome(
            record={
                "path": path,
                "error": f"internal error, please report it: {type(exc).__name__}: {first}".rstrip(": "),
            }
        )


def _thumbnails_or_none(
    path: str, rocks: tuple[RockResult, ...], library: Library, size: int
) -> list[str | None]:
    if not size:
        return [None] * len(rocks)
    try:
        return thumbnail_data_uris(path, rocks, library, size)
    except RockscanError:
        return [None] * len(rocks)


def thumbnail_data_uri(path: str, rock: RockResult | None, library: Library, size: int = 144) -> str:
    """A small WebP (or JPEG) of a photo with the rock's outline and the matched
    library shape (turned by the found angle) drawn on it.

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
        ``data:image/webp;base64,...`` (JPEG where Pillow has no WebP).

    Raises
    ------
    ImageReadError
        If the photo cannot be read.
    """
    return thumbnail_data_uris(path, (rock,), library, size)[0]


#: WebP quality of thumbnails: about 3 kB each at 144 pixels on textured ground,
#: half a JPEG's (a 2,000-rock sheet stays under 10 MB; scripts/bench_report_size.py
#: measures it).
THUMBNAIL_QUALITY = 50


def thumbnail_data_uris(
    path: str, rocks: tuple[RockResult | None, ...], library: Library, size: int = 144
) -> list[str]:
    """Thumbnails of one photo, one per rock (the photo is read once).

    The outline is drawn in :data:`rockscan.report_html.OUTLINE_RGB` (yellow)
    over the matched shape in :data:`rockscan.report_html.SHAPE_RGB` (blue),
    wider, so that both show where they agree. WebP halves colour resolution;
    its sharp colour conversion and the lines' wide gap in lightness keep them
    apart (tests/test_report_html.py measures it).

    Parameters
    ----------
    path : str
    rocks : tuple of RockResult or None
    library : Library
    size : int

    Returns
    -------
    list of str
        Data URIs, one per rock.

    Raises
    ------
    ImageReadError
        If the photo cannot be read.
    """
    import cv2
    from PIL import Image, features

    from rockscan.io import read_image
    from rockscan.plot import library_outline_rowcol
    from rockscan.report_html import OUTLINE_RGB, SHAPE_RGB

    image = read_image(path, max_side=2 * size)
    pixels = _rgb8(image.pixels)
    rows, cols = pixels.shape[:2]
    factor = min(1.0, size / max(rows, cols))
    out_size = (max(1, round(cols * factor)), max(1, round(rows * factor)))
    base = cv2.resize(pixels, out_size, interpolation=cv2.INTER_AREA) if factor < 1 else pixels
    full_rows, full_cols = image.full_shape
    per_row, per_col = full_rows / base.shape[0], full_cols / base.shape[1]

    def points(rowcol: NDArray[np.float64]) -> NDArray[np.int32]:
        # Full-resolution pixel centres to thumbnail pixels, 4 fractional bits.
        col = (rowcol[:, 1] + 0.5) / per_col - 0.5
        row = (rowcol[:, 0] + 0.5) / per_row - 0.5
        return np.round(np.column_stack([col, row]) * 16).astype(np.int32)

    webp = features.check("webp")
    out = []
    for rock in rocks:
        thumb = base.copy()
        if rock is not None:
            matched = points(library_outline_rowcol(library, rock))
            # Two pixels at least: WebP keeps colour at half resolution.
            cv2.polylines(thumb, [matched], True, SHAPE_RGB, 3, cv2.LINE_AA, 4)
            cv2.polylines(thumb, [points(rock.outline.contour_rowcol)], True, OUTLINE_RGB, 2, cv2.LINE_AA, 4)
            ((cx, cy),) = points(rock.outline.centroid_rowcol[None, :]) // 16
            cv2.drawMarker(thumb, (int(cx), int(cy)), SHAPE_RGB, cv2.MARKER_CROSS, 8, 2)
        buf = io.BytesIO()
        if webp:
            Image.fromarray(thumb).save(buf, format="WEBP", quality=THUMBNAIL_QUALITY, use_sharp_yuv=True)
        else:
            Image.fromarray(thumb).save(buf, format="JPEG", quality=THUMBNAIL_QUALITY, subsampling=0)
        kind = "webp" if webp else "jpeg"
        out.append(f"data:image/{kind};base64," + base64.b64encode(buf.getvalue()).decode("ascii"))
    return out


def _rgb8(pixels: NDArray[np.generic]) -> NDArray[np.uint8]:
    arr = np.asarray(pixels)
    if arr.dtype == np.uint16:
        arr = (arr >> 8).astype(np.uint8)
    elif arr.dtype != np.uint8:
        arr = np.clip(arr, 0, 255).astype(np.uint8)
    if arr.ndim == 2:
        arr = np.repeat(arr[..., None], 3, axis=2)
    return np.ascontiguousarray(arr[..., :3])


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
        The rock's distance from every shape seen so far (:mod:`rockscan.novelty`).
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
        Keys :data:`rockscan.report.ROW_KEYS` then any other key of the
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


# ---------------------------------------------------------------- provenance


def _jsonable(value: Any) -> Any:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _jsonable(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return _jsonable(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    return repr(value)


def library_hash(library: Library) -> str:
    """A content hash of a library: its shapes, not the file they came in.

    SHA-256 of the names, interests, symmetries, face settings, basis size and
    calibration tolerance (canonical JSON), and the radii and calibrated cutoffs
    as little-endian float64 rounded to 10 decimals. The basis itself (a BLAS
    result) is left out, so the hash is the same in every process and at every
    thread count; the same spec built twice, or saved and loaded, hashes the same.

    Parameters
    ----------
    library : Library

    Returns
    -------
    str
        64 hex digits.
    """
    meta = {
        "names": list(library.names),
        "interest": [float(v) for v in library.interest],
        "symmetry": [int(v) for v in library.symmetry],
        "face_config": _jsonable(library.face_config),
        "n_components": int(library.basis.n_components),
        "tolerance": float(library.tolerance),
    }
    digest = hashlib.sha256(json.dumps(meta, sort_keys=True, separators=(",", ":")).encode("utf-8"))
    digest.update(np.round(np.asarray(library.radii, dtype="<f8"), 10).tobytes())
    digest.update(np.round(np.asarray(library.cutoffs, dtype="<f8"), 10).tobytes())
    return digest.hexdigest()


def report_provenance(
    library: Library, config: TriageConfig, novelty: ObservedShapes | None = None
) -> dict[str, Any]:
    """How a triage report's rows are made: everything that changes a row.

    Parameters
    ----------
    library : Library
    config : TriageConfig
    novelty : ObservedShapes, optional
        The observed library at the start of the run (its threshold and metric
        are recorded; the shapes it gains during a run are not settings).

    Returns
    -------
    dict
        ``rockscan`` (version), ``library`` (content hash, shapes, face kind),
        ``method`` (the matcher's metrics and scan), ``cutoffs`` (in force,
        defaults resolved), ``options`` (every rock, novelty, the interest
        rule's weight, other classify settings), ``segmentation`` (every
        segmentation setting). JSON-able.
    """
    from rockscan import __version__

    match = config.classify.match
    classify = _jsonable(config.classify)
    classify.pop("match", None)
    segmentation = classify.pop("segment", None)
    options: dict[str, Any] = {"all_rocks": bool(config.all_rocks), **classify}
    if novelty is not None:
        options["novelty"] = {"metric": novelty.metric, "threshold": novelty.threshold}
        options["novelty_weight"] = _novelty_weight(library, config)
    return {
        "rockscan": __version__,
        "library": {
            "sha256": library_hash(library),
            "shapes": len(library),
            "face": library.face_config.kind,
        },
        "method": {
            "metric": match.resolved_metric(library),
            "angle_metric": match.angle_metric,
            "scan": match.scan,
            "refine": match.refine,
        },
        "cutoffs": {
            # The per-shape cutoffs belong to the library (and to its hash); these
            # are the ones the user set on top of them (None: not in force).
            "tolerance": float(library.tolerance),
            "distance": match.distance_cutoff,
            "mscore": match.mscore_cutoff,
            "residual": match.residual_cutoff,
        },
        "options": options,
        "segmentation": segmentation,
    }


def _novelty_weight(library: Library, config: TriageConfig) -> float:
    if config.novelty_weight is not None:
        return float(config.novelty_weight)
    return float(np.max(library.interest))


# ---------------------------------------------------------------- workers

_WORKER: dict[str, Any] = {}


def _die_with_parent(parent: int | None) -> None:
    """End this worker when the process that started the pool ends (kill -9 included)."""
    if sys.platform.startswith("linux"):
        import ctypes

        # Sent when the process that forked this one ends: the triage itself, or
        # the fork server, which ends with the triage.
        with contextlib.suppress(OSError, AttributeError):
            pr_set_pdeathsig = 1
            ctypes.CDLL(None, use_errno=True).prctl(pr_set_pdeathsig, int(signal.SIGKILL), 0, 0, 0)
    if parent is None:
        return
    # The parent may have died before the signal was asked for.
    if not _alive(parent):
        os._exit(1)
    if not sys.platform.startswith("linux"):
        import threading

        def watch() -> None:
            while _alive(parent):
                time.sleep(1.0)
            os._exit(1)

        threading.Thread(target=watch, daemon=True, name="rockscan-parent-watch").start()


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # another user's process of that number: it exists
        return True
    return True


def _init_worker(
    library: Library, config: ClassifyConfig, thumbnail_size: int, all_rocks: bool, parent: int | None
) -> None:
    _die_with_parent(parent)
    # Ctrl-C is the parent's to handle: it finishes the report, then stops.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _WORKER.update(library=library, config=config, thumbnail_size=thumbnail_size, all_rocks=all_rocks)


def _pool_work(path: str) -> PhotoOutcome:
    return photo_outcome(
        path, _WORKER["library"], _WORKER["config"], _WORKER["thumbnail_size"], _WORKER["all_rocks"]
    )


class _ProcessBackend:
    """Worker processes on this machine; restartable after a worker dies.

    Workers are forked where that is safe (Linux, and no other thread in this
    process): they start at once, sharing the library already in memory.
    Elsewhere they start from a fork server that has rockscan loaded. Each
    worker ends with the process that started it (a parent-death signal on
    Linux, a watch of the parent elsewhere), so a killed triage leaves no
    orphans.
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

    def check(self) -> None:
        """Local workers cannot go away unnoticed (the pool breaks)."""

    def close(self) -> None:
        self._executor.shutdown(wait=True, cancel_futures=True)


#: Address schemes a Dask scheduler on another process can be reached by.
_DASK_SCHEMES = ("tcp", "tls", "ws", "wss", "ucx")


def _check_scheduler_address(address: str) -> None:
    """Refuse an address that cannot work before any connection is tried
    (distributed would fail late, and leave a half-made client behind)."""
    scheme, sep, rest = address.partition("://")
    if not sep:
        scheme, rest = "tcp", address
    scheme = scheme.lower()
    hint = "give the scheduler's address, such as tcp://host:8786"
    if scheme == "inproc":
        # inproc://host/pid/n: a scheduler of this very process (a LocalCluster without processes).
        parts = rest.split("/")
        if len(parts) == 3 and parts[1] == str(os.getpid()):
            return
        raise ParameterError(
            f"--scheduler {address}: inproc:// reaches only a scheduler inside this process; {hint}"
        )
    if scheme not in _DASK_SCHEMES:
        raise ParameterError(
            f"--scheduler {address}: unknown address scheme {scheme!r} "
            f"(known: {', '.join(s + '://' for s in _DASK_SCHEMES)}); {hint}"
        )
    if not rest or rest.startswith(":"):
        raise ParameterError(f"--scheduler {address}: no host in the address; {hint}")
    if scheme in ("tls", "wss"):
        from distributed.security import Security

        if Security().get_connection_args("client").get("ssl_context") is None:
            raise ParameterError(
                f"--scheduler {address}: {scheme}:// needs TLS certificates; set them in the Dask "
                "configuration (distributed.comm.tls.ca-file, .client.cert, .client.key)"
            )


class _DaskBackend:
    """Workers of a Dask distributed cluster.

    A worker lost mid-run costs nothing: the scheduler runs its photos again
    on another. A lost scheduler ends the run at once with a clear error (the
    rows so far are kept), never a hang.
    """

    def __init__(
        self,
        address: str,
        library: Library,
        config: ClassifyConfig,
        thumbnail_size: int,
        timeout_s: float,
        all_rocks: bool = False,
    ) -> None:
        try:
            from distributed import Client
        except ImportError:
            raise ParameterError("--scheduler needs dask.distributed: pip install 'rockscan[dask]'") from None
        _check_scheduler_address(address)
        self.address = address
        # distributed logs a traceback for every failed reconnection: the run says it once.
        self._quiet = _QuietLogger("distributed")
        try:
            self._client = Client(address, timeout=f"{timeout_s}s", set_as_default=False)
        except (OSError, TimeoutError, ValueError, TypeError) as exc:
            self._quiet.restore()
            raise ParameterError(f"cannot reach the Dask scheduler at {address} ({exc})") from None
        # The library travels to each worker once, not with every photo.
        library_future = self._client.scatter(library, broadcast=True, hash=False)
        self._executor = self._client.get_executor(pure=False)
        self._args = (library_future, config, thumbnail_size, all_rocks)
        self.slots = max(1, sum(self._client.nthreads().values()))

    def submit(self, path: str) -> cf.Future[PhotoOutcome]:
        self.check()
        return self._executor.submit(photo_outcome, path, *self._args)

    def check(self) -> None:
        """Raise if the scheduler is gone."""
        status = getattr(self._client.status, "value", self._client.status)
        if status != "running":
            raise ParameterError(
                f"lost the Dask scheduler at {self.address} (client {status}); the rows so far are kept: "
                "run again with --resume"
            )

    def restart(self) -> None:
        """A Dask cluster replaces lost workers itself; futures are cancelled
        only when the scheduler is lost."""
        self.check()

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self._executor.shutdown(wait=False)
        with contextlib.suppress(Exception):
            self._client.close(timeout=2)
        self._quiet.restore()


class _QuietLogger:
    """Silence a library's loggers (the named one and its children) for a while,
    then put their levels back."""

    def __init__(self, name: str) -> None:
        names = [name, *(n for n in logging.root.manager.loggerDict if n.startswith(name + "."))]
        self._levels = {n: logging.getLogger(n).level for n in names}
        for n in names:
            logging.getLogger(n).setLevel(logging.CRITICAL + 1)

    def restore(self) -> None:
        for n, level in self._levels.items():
            logging.getLogger(n).setLevel(level)


#: How long to wait for a photo before asking the backend whether it is alive, seconds.
_POLL_S = 2.0


def _run_backend(
    paths: list[str], backend: Any, window: int, *, ordered: bool
) -> Iterator[tuple[int, PhotoOutcome]]:
    """Outcomes of ``paths`` as (index, outcome): as they finish, or in order.

    At most ``window`` photos are in flight or waiting their turn, so memory
    stays flat however many photos there are. If a worker process dies (the
    pool breaks), the photos it may have been working on are tried again one
    at a time in a new pool: the one that breaks it again gets an error row.
    A backend that cannot go on (a lost scheduler) raises from ``check`` or
    ``restart``.
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
        done, _ = cf.wait(pending, timeout=_POLL_S, return_when=cf.FIRST_COMPLETED)
        if not done:
            backend.check()
            continue
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
        for i, outcome in sorted(finished, key=lambda item: item[0]):
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
    on_error: Callable[[dict[str, Any]], None] | None = None,
) -> TriageSummary:
    """Classify every photo under a folder and write a ranked report.

    Parameters
    ----------
    folder : path-like
        Walked recursively (:func:`find_photos`).
    report : path-like
        ``.csv``, ``.jsonl``, ``.html`` or ``.geojson`` (see
        :mod:`rockscan.report`). Rows are written as photos finish; the report
        is ranked when the run ends, or is interrupted. The report is locked
        for the run: a second run on it is refused at once.
    library : Library
        The library of interest.
    config : TriageConfig, optional
    observed : path-like, optional
        The observed library file (:mod:`rockscan.novelty`): read if it
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
    """
    config = config or TriageConfig()
    report = Path(report)
    report_format(report)
    listing = find_photos(folder)
    with lock_report(report):
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
    from rockscan.io import load_library, save_library

    started = time.perf_counter()
    fmt = report_format(report)
    novelty_state: ObservedShapes | None = None
    observed_path = Path(observed) if observed is not None else None
    if observed_path is not None:
        if observed_path.exists():
            novelty_state = ObservedShapes.from_file(load_library(observed_path), library, config.novelty)
        else:
            novelty_state = ObservedShapes.from_library(library, config.novelty)
    provenance = report_provenance(library, config, novelty_state)
    novelty_weight = _novelty_weight(library, config)
    journal = ReportJournal(report, resume=config.resume, overwrite=config.overwrite, provenance=provenance)
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

    def row_of(outcome: PhotoOutcome) -> dict[str, Any]:
        nonlocal novelty_state, observed_dirty, n_novel
        row = triage_row(outcome.record, library)
        if novelty_state is not None and outcome.radii is not None:
            novelty = novelty_state.assess(outcome.radii)
            row.update(novelty=novelty.score, novel=novelty.novel, nearest_observed=novelty.nearest)
            row["interest"] = interest_score(
                row["match"],
                row["mscore"],
                row["shape_interest"],
                novelty=novelty.score,
                threshold=novelty_state.threshold,
                novelty_weight=novelty_weight,
            )
            if novelty.novel:
                stem = Path(row["path"]).stem + (f"-{row['index']}" if row.get("index") else "")
                name = observed_name(stem, names)
                names.add(name)
                novelty_state = novelty_state.with_shape(name, outcome.radii)
                observed_dirty = True
                n_novel += 1
        if html:
            row[THUMBNAIL_KEY] = outcome.thumbnail
        return row

    def commit(outcome: PhotoOutcome) -> None:
        nonlocal done, n_interesting, last_refresh, refresh_every
        rows = [row_of(rock) for rock in outcome.rocks()]
        # All rows of a photo in one write: a crash leaves all of them or none.
        journal.append(rows)
        done += 1
        n_interesting += sum(bool(row.get("interesting")) for row in rows)
        if on_error is not None and rows[0].get("error") is not None:
            on_error(rows[0])
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
    failure: RockscanError | None = None
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
                commit(photo_outcome(path, library, config.classify, thumb, config.all_rocks))
        elif todo:
            if config.scheduler is not None:
                backend = _DaskBackend(
                    config.scheduler,
                    library,
                    config.classify,
                    thumb,
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
                    (library, config.classify, thumb, config.all_rocks, os.getpid()),
                )
            window = backend.slots * int(config.window or 4)
            for _, outcome in _run_backend(todo, backend, window, ordered=ordered):
                commit(outcome)
    except KeyboardInterrupt:
        interrupted = True
    except RockscanError as exc:
        # A lost scheduler, a full disk: rank what is done, then say why the run stopped.
        failure = exc
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
    try:
        save_observed()
        ranked: RankedReport = finalize_report(report, title=_title(folder), limit=config.html_limit)
    except RockscanError:
        if failure is None:
            raise
        raise failure from None
    if failure is not None:
        raise failure
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
