"""The ``rockscan`` group, the options its commands share, errors and logging.

No math lives here. Heavy modules are imported inside the commands so that
``rockscan --help`` starts at once. A :class:`rockscan.core.errors.RockscanError`
becomes a one-line error and exit status 1; usage errors exit 2 (click).

One module per command family; this one holds the group, shared options and
the logging setup: library modules log to ``rockscan.*`` loggers and never
print; here the ``rockscan`` logger gets one handler that writes one line per
record to standard error. Every command takes ``-q`` (warnings and errors only)
and ``-v`` (debug lines too); the default shows what a command wrote and the
progress of long runs.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib
import logging
import math
import os
import sys
import time
from collections.abc import Callable, Iterable, Iterator
from typing import Any, TypeVar

import click

from rockscan.core.choices import METHODS, METRICS, PX_PER_MM_RANGE, RANK_METRICS

#: Exit status when the reader of standard output goes away (``| head``).
BROKEN_PIPE_STATUS = 141


class ConfigOption(click.Option):
    """An option whose default is a field of a settings dataclass, read when it is
    needed: the command line restates no default, and ``rockscan --help`` still
    imports nothing heavy (the dataclass loads when a command's help or value
    needs it).

    ``config`` is ``"module.Class"``; ``field`` one field name or several;
    ``convert`` turns the field value(s) into the option's value.
    """

    def __init__(
        self,
        *args: Any,
        config: str,
        field: str | tuple[str, ...],
        convert: Callable[..., Any] | None = None,
        **kwargs: Any,
    ) -> None:
        kwargs.setdefault("show_default", True)
        super().__init__(*args, **kwargs)
        self.config, self.fields = config, (field,) if isinstance(field, str) else field
        self.convert = convert

    def get_default(self, ctx: click.Context, call: bool = True) -> Any:
        module, _, name = self.config.rpartition(".")
        fields = {f.name: f for f in dataclasses.fields(getattr(importlib.import_module(module), name))}
        values = [fields[n].default for n in self.fields]
        return self.convert(*values) if self.convert else values[0]


class PathName(click.Path):
    """A path, where an empty name is a usage error.

    ``click.Path`` takes ``""``, which the operating system reads as the
    current folder: ``triage ""`` would walk it and ``classify --plot ""``
    drew nothing and exited 0.
    """

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        if isinstance(value, str) and not value.strip():
            self.fail("an empty name; give a path.", param, ctx)
        return super().convert(value, param, ctx)


class Number(click.ParamType):
    """A number within optional bounds; nan, and unless ``infinite`` also inf, is a
    usage error (exit status 2), as a word where a number belongs is.

    ``click.FloatRange`` lets nan through (every comparison with it is false),
    and a setting checked later fails as the run's error, after the command
    started. Here the command line itself is refused.
    """

    name = "float"

    def __init__(
        self,
        low: float | None = None,
        high: float | None = None,
        *,
        low_open: bool = False,
        infinite: bool = False,
    ) -> None:
        self.low, self.high, self.low_open, self.infinite = low, high, low_open, infinite

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> float:
        number = click.FLOAT.convert(value, param, ctx)
        if math.isnan(number) or (math.isinf(number) and not self.infinite):
            self.fail(f"{value!r} is not a finite number.", param, ctx)
        below = self.low is not None and (number <= self.low if self.low_open else number < self.low)
        above = self.high is not None and number > self.high
        if below or above:
            self.fail(f"{number:g} is not in the range {self._range()}.", param, ctx)
        return number

    def _range(self) -> str:
        if self.high is None:
            return f"x {'>' if self.low_open else '>='} {self.low:g}"
        if self.low is None:
            return f"x <= {self.high:g}"
        return f"{self.low:g} {'<' if self.low_open else '<='} x <= {self.high:g}"


def config_option(
    *names: str, config: str, field: str | tuple[str, ...], **kwargs: Any
) -> Callable[..., Any]:
    """``click.option`` with its default read from a settings dataclass (see :class:`ConfigOption`)."""
    return click.option(*names, cls=ConfigOption, config=config, field=field, **kwargs)


def _check_output(
    path: str | None,
    hint: str,
    *,
    suffixes: tuple[str, ...] = (),
    inputs: Iterable[str] = (),
    overwrite: bool | None = None,
    plot: bool = False,
) -> None:
    """Refuse, as a usage error and before any work, an output that would lose what
    the user has: a name without the file kind it writes (``suffixes``), a folder
    that is missing, one of the command's own ``inputs`` (a spec written over by
    its library, a photo by its plot), a folder it cannot write in, a figure
    (``plot``) of a format matplotlib cannot draw, or, where the command offers
    ``--overwrite`` (``overwrite`` not None), a file that exists."""
    if path is None:
        return
    if plot:
        _check_plot_format(path)
    if suffixes and not path.lower().endswith(suffixes):
        raise click.BadParameter(f"{path!r} must end in {' or '.join(suffixes)}", param_hint=hint)
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise click.BadParameter(f"folder {folder!r} does not exist", param_hint=hint)
    if not os.access(folder, os.W_OK | os.X_OK):
        # Found at the end, it would lose the run's work (a triage's observed library).
        raise click.BadParameter(f"cannot write in folder {folder!r} (permission denied)", param_hint=hint)
    for given in inputs:
        # By name too: two outputs of one run (a report and its observed library)
        # may name one file that does not exist yet.
        same_name = os.path.abspath(path) == os.path.abspath(given)
        if same_name or (os.path.exists(path) and os.path.exists(given) and os.path.samefile(path, given)):
            message = f"{path} is an input of this command; give another name"
            raise click.BadParameter(message, param_hint=hint)
    if os.path.exists(path):
        if overwrite is False:
            message = f"{path} exists; give --overwrite to replace, or another name"
            raise click.BadParameter(message, param_hint=hint)


def _check_plot_format(path: str) -> None:
    """A plot's file ending must be a format matplotlib draws (none: PNG); found
    only when the figure was saved, it failed the run after its work, exit 1."""
    suffix = os.path.splitext(path)[1].lower().lstrip(".")
    if not suffix:
        return
    from rockscan.draw.plot import figure_formats

    if suffix not in figure_formats():
        message = f"cannot draw a .{suffix} file; name a .png (or .pdf, .svg, .jpg)"
        raise click.BadParameter(message, param_hint="--plot")


def _fail(message: str, status: int = 1) -> None:
    click.echo(f"rockscan: error: {message}", err=True)
    sys.exit(status)


def _errors(func: Callable[..., Any]) -> Callable[..., Any]:
    """Turn the library's errors into one clear line and exit status 1."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        from rockscan.core.errors import RockscanError

        try:
            return func(*args, **kwargs)
        except RockscanError as exc:
            _fail(str(exc))
        except BrokenPipeError:
            # The reader went away (| head): stop quietly with the status of a tool
            # that SIGPIPE ended (128 + 13), as `cat` and `grep` give, not the
            # status 1 of a failed photo (docs/robustness.md).
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
            sys.exit(BROKEN_PIPE_STATUS)
        except KeyboardInterrupt:
            _fail("interrupted", 130)

    return wrapper


#: How usage errors name the ``--library`` option (as click names it).
LIBRARY_HINT = "'--library' / '-l'"


def _library_option(func: Callable[..., Any]) -> Callable[..., Any]:
    return click.option(
        "--library",
        "-l",
        "library_path",
        type=PathName(dir_okay=False),
        default=None,
        help=f"Library file (.npz from 'rockscan library build') or spec (.toml); "
        f"'{DEFAULT_LIBRARY_NAME}' (the default) is the built-in library.",
    )(func)


def _px_per_mm_option(func: Callable[..., Any]) -> Callable[..., Any]:
    """Add ``--px-per-mm F``; the command receives it as ``px_per_mm`` (float or None)."""
    return click.option(
        "--px-per-mm",
        "px_per_mm",
        type=Number(*PX_PER_MM_RANGE),
        default=None,
        metavar="F",
        help="Photo pixels per millimetre (1e-6 to 1e6): adds area_mm2, equivalent_diameter_mm, "
        "major_axis_mm and minor_axis_mm.",
    )(func)


def _match_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """Add the matcher's options; the command receives them as ``match_config``."""
    options = [
        click.option(
            "--method",
            type=click.Choice(METHODS),
            default="default",
            show_default=True,
            help="'paper': the paper's exact matcher (eigenspace distance for shape and angle).",
        ),
        click.option(
            "--metric",
            type=click.Choice(RANK_METRICS),
            default=None,
            help="Distance that ranks shapes (default: auto, the paper's eigenspace distance for a "
            "clean outline, the sensor model's for a noisy one; docs/decision.md).",
        ),
        click.option(
            "--angle-metric",
            type=click.Choice(METRICS),
            default=None,
            help="Distance the angle minimises (default: face).",
        ),
        click.option(
            "--distance-cutoff",
            type=Number(infinite=True),
            default=None,
            help="Largest distance of an interesting match (the paper's theta).",
        ),
        click.option(
            "--mscore-cutoff",
            type=Number(infinite=True),
            default=None,
            help="MScore an interesting match must exceed (the paper's gamma).",
        ),
        click.option(
            "--residual-cutoff",
            type=Number(infinite=True),
            default=None,
            help="Largest distance from face space of an interesting match (Turk & Pentland).",
        ),
        click.option(
            "--no-scan", is_flag=True, help="Match the outline as it lies, without the rotation scan."
        ),
    ]

    @functools.wraps(func)
    def wrapper(
        *args: Any,
        method: str,
        metric: str | None,
        angle_metric: str | None,
        distance_cutoff: float | None,
        mscore_cutoff: float | None,
        residual_cutoff: float | None,
        no_scan: bool,
        **kwargs: Any,
    ) -> Any:
        from rockscan.core.errors import ParameterError
        from rockscan.core.match import MatchConfig

        preset = MatchConfig.paper() if method == "paper" else MatchConfig()
        try:
            kwargs["match_config"] = MatchConfig(
                metric=metric or preset.metric,
                angle_metric=angle_metric or preset.angle_metric,
                distance_cutoff=distance_cutoff,
                mscore_cutoff=mscore_cutoff,
                residual_cutoff=residual_cutoff,
                scan=not no_scan,
            )
        except ParameterError as exc:
            # Built before the command runs, outside its error handling: the
            # options themselves are at fault.
            raise click.UsageError(str(exc)) from None
        return func(*args, **kwargs)

    for option in reversed(options):
        wrapper = option(wrapper)
    return wrapper


#: The name that stands for the built-in library wherever a library is asked for
#: (``./default`` names a file called default).
DEFAULT_LIBRARY_NAME = "default"


def _load_library(path: str | None, *, option: str | None = None) -> Any:
    """The library at ``path`` (a .npz file, a .toml spec, or the built-in one).

    Given as an ``option`` (``--library``), a library that cannot be loaded is
    a bad option value, a usage error (exit 2): no photo was at fault.
    """
    if option is None:
        return _library_at(path)
    from rockscan.core.errors import RockscanError

    try:
        return _library_at(path)
    except RockscanError as exc:
        raise click.BadParameter(str(exc), param_hint=option) from None


def _library_at(path: str | None) -> Any:
    from rockscan.core.library import Library
    from rockscan.io import default_library, load_library, read_spec

    if path is None or path == DEFAULT_LIBRARY_NAME:
        return default_library()
    if path.lower().endswith(".toml"):
        shapes = read_spec(path)
        if any(s.params is None for s in shapes):
            from rockscan.run.pipeline import library_from_spec

            return library_from_spec(shapes)
        return Library.from_shapes(shapes)
    import warnings

    from rockscan.io import RecalibratedWarning

    with warnings.catch_warnings(record=True) as notes:
        warnings.simplefilter("always", RecalibratedWarning)
        library = load_library(path)
    for note in notes:
        click.echo(f"rockscan: note: {note.message}", err=True)
    return library


# ---------------------------------------------------------------- logging and progress

#: The logger every rockscan module logs under.
LOGGER_NAME = "rockscan"
log = logging.getLogger(f"{LOGGER_NAME}.cli")


class _StderrHandler(logging.Handler):
    """One line per record on the standard error in force (click's, so tests capture it)."""

    def emit(self, record: logging.LogRecord) -> None:
        try:
            click.echo(self.format(record), err=True)
        except Exception:
            self.handleError(record)


class _Formatter(logging.Formatter):
    """``rockscan: message``, with the level named for warnings, errors and debug lines."""

    def format(self, record: logging.LogRecord) -> str:
        message = record.getMessage()
        if record.levelno >= logging.ERROR:
            return f"rockscan: error: {message}"
        if record.levelno >= logging.WARNING:
            return f"rockscan: warning: {message}"
        if record.levelno >= logging.INFO:
            return f"rockscan: {message}"
        return f"rockscan: debug: {record.name}: {message}"


def _configure_logging(verbosity: int) -> None:
    """Set the ``rockscan`` logger's level: -1 quiet (warnings), 0 info, 1 (or more) debug.

    The handler is added once, however many commands run in one process.
    """
    logger = logging.getLogger(LOGGER_NAME)
    if not any(isinstance(h, _StderrHandler) for h in logger.handlers):
        handler = _StderrHandler()
        handler.setFormatter(_Formatter())
        logger.addHandler(handler)
        # The lines are the command's own; a host application's root handlers would print them twice.
        logger.propagate = False
    logger.setLevel(logging.WARNING if verbosity < 0 else logging.INFO if verbosity == 0 else logging.DEBUG)


def _verbosity_callback(ctx: click.Context, param: click.Parameter, value: int | bool) -> None:
    # Only when given, so that a command's default does not undo a -q/-v before it.
    if value:
        _configure_logging(-1 if param.name == "quiet" else int(value))


#: The verbosity options every command gets: flags, keyword arguments of click.Option.
_VERBOSITY = (
    (("-v", "--verbose"), {"count": True, "help": "Say more: debug lines too."}),
    (("-q", "--quiet"), {"is_flag": True, "help": "Only warnings and errors on standard error."}),
)


def _verbosity_options(command: click.Command) -> None:
    """Give a command (and its subcommands) -q/--quiet and -v/--verbose, unless it has its own."""
    taken = {opt for p in command.params for opt in getattr(p, "opts", [])}
    for flags, kwargs in _VERBOSITY:
        if not set(flags) & taken:
            command.params.append(
                click.Option(list(flags), expose_value=False, callback=_verbosity_callback, **kwargs)
            )
    for sub in getattr(command, "commands", {}).values():
        _verbosity_options(sub)


_T = TypeVar("_T")


def _progress(items: Iterable[_T], total: int, *, unit: str, verb: str, minimum: int = 20) -> Iterator[_T]:
    """Yield ``items``, showing progress of a long run (``minimum`` items or more).

    On a terminal a tqdm bar; elsewhere (a pipe, a log file) a log line every
    tenth of the run or every 10 seconds, whichever comes first, so that a
    batch job's log shows it is alive. Quiet (-q) shows neither.
    """
    if total < minimum or not log.isEnabledFor(logging.INFO):
        yield from items
        return
    if sys.stderr.isatty():
        from tqdm import tqdm

        yield from tqdm(items, total=total, unit=unit, file=sys.stderr)
        return
    step = max(1, -(-total // 10))
    last = time.monotonic()
    for done, item in enumerate(items, start=1):
        yield item
        now = time.monotonic()
        if done % step == 0 or done == total or now - last >= 10.0:
            log.info("%s %d/%d %ss", verb, done, total, unit)
            last = now


@click.group(context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(package_name="rockscan", prog_name="rockscan")
@click.option("-v", "--verbose", count=True, help="Say more: debug lines too (also after the command).")
@click.option("-q", "--quiet", is_flag=True, help="Only warnings and errors (also after the command).")
def main(verbose: int, quiet: bool) -> None:
    """Judge rock samples by their shape.

    rockscan finds the rock in a photo, measures its outline, and matches it
    against a library of Superformula shapes of interest (Fleetwood &
    Thangavelautham): nearest shape, match quality (MScore), rotation, and
    whether the sample is worth keeping.
    """
    # rockscan's matrices are small and it parallelises across photos: BLAS
    # threads would only contend (and make results depend on the thread count
    # in the last digit). Set before numpy loads; the user's own setting wins.
    for name in _BLAS_THREAD_VARIABLES:
        os.environ.setdefault(name, "1")
    # A file name that is not valid in the locale's encoding (bytes from another
    # system) is printed escaped, as standard error does, instead of ending the run.
    if hasattr(sys.stdout, "reconfigure"):
        sys.stdout.reconfigure(errors="backslashreplace")
    _configure_logging(-1 if quiet else verbose)


#: Environment variables that set the BLAS libraries' thread counts.
_BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
