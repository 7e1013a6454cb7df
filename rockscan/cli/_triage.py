"""``rockscan triage``: rank a folder of photos by interest."""

from __future__ import annotations

import logging
import os
import shutil
import signal
import sys
import tempfile
import time
from typing import Any

import click

from rockscan.cli._main import (
    LIBRARY_HINT,
    Number,
    PathName,
    _check_output,
    _errors,
    _fail,
    _library_option,
    _load_library,
    _match_options,
    _px_per_mm_option,
    log,
    main,
)
from rockscan.core.choices import NOVELTY_METRICS


@main.command("triage")
@click.argument("folder", type=PathName(exists=True, file_okay=False))
@click.option(
    "-o",
    "--output",
    "report_path",
    type=PathName(dir_okay=False),
    default=None,
    help="Report: .csv, .jsonl (JSON lines), .html (contact sheet) or .geojson (rock outlines), "
    "by its ending. Default: the ranked JSON lines on standard output.",
)
@_library_option
@_match_options
@click.option(
    "-j",
    "--workers",
    type=click.IntRange(min=1),
    default=None,
    help="Worker processes on this machine (default: every core).",
)
@click.option(
    "--scheduler",
    default=None,
    metavar="ADDRESS",
    help="Classify on a Dask distributed cluster (tcp://host:8786); its workers must see FOLDER.",
)
@click.option(
    "--resume",
    is_flag=True,
    help="Continue the report: skip photos already in it, try those that failed again.",
)
@click.option("--overwrite", is_flag=True, help="Replace an existing report.")
@click.option(
    "--observed",
    "observed_path",
    type=PathName(dir_okay=False),
    default=None,
    help="Observed library (.npz) for novelty: created from the library if missing, "
    "grown by every novel rock, kept between runs.",
)
@click.option(
    "--novelty-threshold",
    type=Number(0),
    default=None,
    help="Novelty above which a rock is novel (default: half the median spacing of the library's shapes).",
)
@click.option(
    "--novelty-metric",
    type=click.Choice(NOVELTY_METRICS),
    default="face",
    show_default=True,
    help="'face': whole-face distance; 'eigenspace': the paper's distance within face space only.",
)
@click.option(
    "--novelty-weight",
    type=Number(0),
    default=None,
    help="With --observed, what a novel rock's interest is (default: the library's largest shape "
    "interest; 0: novelty does not change the ranking).",
)
@_px_per_mm_option
@click.option(
    "--all",
    "all_rocks",
    is_flag=True,
    help="Rank every rock of every photo, not only the main one (each row with its index).",
)
@click.option(
    "--html-limit",
    type=click.IntRange(min=1),
    default=2000,
    show_default=True,
    help="Photos an HTML report shows (its .jsonl beside it keeps all).",
)
@click.option(
    "-q", "--quiet", is_flag=True, help="No progress (bar or lines), no summary; errors still on stderr."
)
@_errors
def triage(
    folder: str,
    report_path: str | None,
    library_path: str | None,
    match_config: Any,
    workers: int | None,
    scheduler: str | None,
    resume: bool,
    overwrite: bool,
    observed_path: str | None,
    novelty_threshold: float | None,
    novelty_metric: str,
    novelty_weight: float | None,
    px_per_mm: float | None,
    all_rocks: bool,
    html_limit: int,
    quiet: bool,
) -> None:
    """Rank every photo under FOLDER by interest and write a report.

    Interest is MScore times the matched shape's interest (a spec shape's
    'interest = <number>', default 1); a rock with no match scores 0. With
    --observed, a rock unlike every shape seen so far scores as much as a
    perfect match of the most wanted shape (--novelty-weight). Rows are
    written as photos finish, so an interrupted run keeps them: run again with
    --resume to finish it. A report records how it was made; --resume with
    other settings is refused. Off a terminal, progress lines go to stderr
    every few seconds; error rows go to stderr as they come.

    Exit status: 0 when every photo was classified, 1 when any could not be
    (or the run could not go on), 2 for a usage error (a missing FOLDER, a
    report that exists without --resume or --overwrite, resuming with other
    settings), 130 when interrupted.
    """
    from rockscan.core.novelty import NoveltyConfig
    from rockscan.io.report import ReportSettingsError
    from rockscan.run.pipeline import ClassifyConfig
    from rockscan.run.triage import TriageConfig, triage_folder

    _check_options(workers, scheduler, resume, overwrite, report_path, observed_path, library_path)
    if report_path is not None:
        from rockscan.io.report import report_target

        # A link's target: checked for writing, written and locked as the report.
        report_path = str(report_target(report_path))
    # `rockscan -q triage` is `triage -q`: the group's -q leaves warnings and errors only.
    quiet = quiet or not log.isEnabledFor(logging.INFO)
    lib = _load_library(library_path, option=LIBRARY_HINT)
    config = TriageConfig(
        classify=ClassifyConfig(match=match_config, px_per_mm=px_per_mm),
        workers=workers,
        scheduler=scheduler,
        resume=resume,
        overwrite=overwrite,
        novelty=NoveltyConfig(threshold=novelty_threshold, metric=novelty_metric),
        novelty_weight=novelty_weight,
        all_rocks=all_rocks,
        html_limit=html_limit,
    )
    bar = _Progress(bar=not quiet and sys.stderr.isatty(), lines=not quiet and not sys.stderr.isatty())
    scratch = None if report_path is not None else tempfile.mkdtemp(prefix="rockscan-triage-")
    target = report_path if scratch is None else os.path.join(scratch, "triage.jsonl")
    # SIGTERM (a batch system's stop) ends the run as Ctrl-C does: the report is ranked first.
    previous = signal.signal(signal.SIGTERM, _interrupt)
    try:
        try:
            summary = triage_folder(
                folder, target, lib, config, observed=observed_path, progress=bar, on_error=bar.error
            )
        except ReportSettingsError as exc:
            _fail(str(exc), 2)
        except KeyboardInterrupt:
            bar.close()
            _print_ranked(scratch, target)
            hint = "stopped"
            if report_path:
                hint = f"{report_path} keeps them; run again with --resume to finish"
            click.echo(f"rockscan: interrupted after {bar.done} photos: {hint}", err=True)
            sys.exit(130)
        finally:
            bar.close()
        _print_ranked(scratch, target)
    finally:
        signal.signal(signal.SIGTERM, previous)
        if scratch is not None:
            shutil.rmtree(scratch, ignore_errors=True)
    if not quiet:
        _print_summary(summary, folder, to_stderr=report_path is None)
    sys.exit(1 if summary.failed else 0)


def _check_options(
    workers: int | None,
    scheduler: str | None,
    resume: bool,
    overwrite: bool,
    report_path: str | None,
    observed_path: str | None,
    library_path: str | None,
) -> None:
    """Usage errors of a triage run, found before any photo is classified (an
    observed library that cannot be written at the end would lose what the run
    learnt; a scheduler's address that cannot work would leave a report behind;
    an observed library named as the report or the library in use would be
    written over it)."""
    from rockscan.core.errors import ParameterError

    if workers is not None and scheduler is not None:
        raise click.UsageError("give -j/--workers or --scheduler, not both")
    if resume and overwrite:
        raise click.UsageError("give --resume or --overwrite, not both")
    if resume and report_path is None:
        raise click.UsageError("--resume needs the report to continue: -o REPORT")
    if report_path is not None:
        from rockscan.io.report import journal_path, report_target

        try:
            target = report_target(report_path)
        except ParameterError as exc:
            raise click.BadParameter(str(exc), param_hint="-o/--output") from None
        # The journal of an HTML or GeoJSON report counts: a run cut short leaves only it
        # (beside a link's target, where the run wrote it).
        there = [str(p) for p in (target, journal_path(target)) if os.path.exists(p)]
        if there and not (resume or overwrite):
            message = f"{there[0]} exists: add --resume to continue it, or --overwrite to start again"
            raise click.BadParameter(message, param_hint="-o/--output")
    _check_output(report_path, "-o/--output")
    inputs = [p for p in (report_path, library_path) if p]
    _check_output(observed_path, "--observed", suffixes=(".npz",), inputs=inputs)
    if scheduler is not None:
        from rockscan.run.backends import check_scheduler_address

        try:
            check_scheduler_address(scheduler)
        except ParameterError as exc:
            raise click.BadParameter(str(exc), param_hint="--scheduler") from None


def _interrupt(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt


def _print_ranked(scratch: str | None, target: str) -> None:
    """Without -o, the ranked rows go to standard output."""
    if scratch is not None and os.path.exists(target):
        with open(target, encoding="utf-8") as fh:
            shutil.copyfileobj(fh, sys.stdout)
        sys.stdout.flush()


class _Progress:
    """Progress of a run: tqdm on a terminal (created at the first call, when the
    total is known); off a terminal, a line on stderr every few seconds or
    tenth of the run; each error row on stderr as it comes."""

    #: Least time between two progress lines, seconds.
    EVERY_S = 5.0

    def __init__(self, *, bar: bool, lines: bool = False) -> None:
        self.enabled = bar
        self.lines = lines
        self.done = 0
        self.errors = 0
        self._bar: Any = None
        self._last = 0.0
        self._last_done = 0
        self._started = time.monotonic()

    def __call__(self, done: int, total: int) -> None:
        self.done = done
        if not total:
            # Every photo already in the report: the summary says so, a "0/0" line nothing.
            return
        if self.lines:
            now = time.monotonic()
            step = max(1, total // 10)
            if done == total or now - self._last >= self.EVERY_S or done - self._last_done >= step:
                if done:
                    rate = done / max(now - self._started, 1e-9)
                    click.echo(
                        f"rockscan: triage: {done}/{total} photos ({100 * done // max(total, 1)}%), "
                        f"{self.errors} errors, {rate:.1f} photos/s",
                        err=True,
                    )
                self._last, self._last_done = now, done
            return
        if not self.enabled:
            return
        if self._bar is None:
            import tqdm

            # No monitor thread: worker processes are started while the bar runs.
            tqdm.tqdm.monitor_interval = 0
            self._bar = tqdm.tqdm(total=total, unit="photo", file=sys.stderr, dynamic_ncols=True)
        self._bar.update(done - self._bar.n)

    def error(self, row: dict[str, Any]) -> None:
        from rockscan.io.report import shown_text

        self.errors += 1
        message = row["error"]
        line = message if message.startswith(row["path"]) else f"{row['path']}: {message}"
        text = f"rockscan: error: {shown_text(line)}"
        if self._bar is not None:
            self._bar.write(text, file=sys.stderr)
        else:
            click.echo(text, err=True)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None


def _skipped(summary: Any) -> str:
    """The summary's note of the files skipped, e.g. ``; 3 other files skipped (.heic,
    .txt)``, or "" when there were none: no file goes unmentioned."""
    if not summary.n_skipped:
        return ""
    kinds = ", ".join(ending or "no ending" for ending in summary.skipped_endings)
    many = "s" if summary.n_skipped > 1 else ""
    return f"; {summary.n_skipped} other file{many} skipped ({kinds})"


def _retried(summary: Any) -> str:
    """The summary's note of the photos with an error row that a resume tried again, e.g.
    `` (3 of them failed before)``, or "" when there were none."""
    if not summary.n_retried:
        return ""
    return f" ({summary.n_retried} of them failed before)"


def _print_summary(summary: Any, folder: str, *, to_stderr: bool) -> None:
    from rockscan.io.report import shown_text

    def echo(text: str = "") -> None:
        # Names that are not UTF-8 or hold control characters print escaped.
        click.echo(shown_text(text) if text else text, err=to_stderr)

    echo(
        f"triage of {folder}: {summary.n_found} photos found, {summary.n_resumed} already in the report, "
        f"{summary.n_processed} classified{_retried(summary)} in {summary.elapsed_s:.1f} s{_skipped(summary)}"
    )
    if summary.n_gone:
        one = summary.n_gone == 1
        log.warning(
            "%d photo%s in the report %s no longer under %s; %s kept (--overwrite starts afresh)",
            summary.n_gone,
            "" if one else "s",
            "is" if one else "are",
            folder,
            "its row is" if one else "their rows are",
        )
    if summary.n_changed:
        one = summary.n_changed == 1
        log.warning(
            "%d photo%s in the report %s changed after it was last written; %s of the photo%s as %s "
            "(--overwrite classifies %s afresh)",
            summary.n_changed,
            "" if one else "s",
            "was" if one else "were",
            "its row is" if one else "their rows are",
            "" if one else "s",
            "it was" if one else "they were",
            "it" if one else "them",
        )
    if not summary.n_found:
        from rockscan.io.photos import IMAGE_SUFFIXES

        log.warning("no photos under %s: photos end in %s", folder, ", ".join(IMAGE_SUFFIXES))
    where = "" if to_stderr else f"{summary.report}: "
    line = (
        f"{where}{summary.n_rows - summary.n_errors} ranked, {summary.n_errors} "
        f"error{'' if summary.n_errors == 1 else 's'}; "
        f"{summary.n_interesting} interesting in this run"
    )
    if summary.n_observed is not None:
        line += f"; {summary.n_novel} novel (observed library: {summary.n_observed} shapes)"
    echo(line)
    if summary.top:
        echo(f"top {len(summary.top)}:")
        echo(f"  {'rank':>4} {'interest':>8} {'MScore':>6} {'angle':>6}  {'match':<20} photo")
        for row in summary.top:
            echo(
                f"  {row['rank']:>4} {row['interest']:>8.3f} {row['mscore']:>6.3f} {row['angle_deg']:>6.1f}  "
                f"{(row['match'] or '-'):<20} {row['path']}"
            )
    if summary.n_errors:
        more = f", first {len(summary.errors)}" if summary.n_errors > len(summary.errors) else ""
        echo(f"errors ({summary.n_errors}{more}):")
        for row in summary.errors:
            message = row["error"]
            echo(f"  {message}" if message.startswith(row["path"]) else f"  {row['path']}: {message}")
