"""The ``rockscan`` command line: parse, call the library, format.

No math lives here. Heavy modules are imported inside the commands so that
``rockscan --help`` starts at once. A :class:`rockscan.errors.RockscanError`
becomes a one-line error and exit status 1; usage errors exit 2 (click).

One module per command family; this one holds the group and shared options.
"""

from __future__ import annotations

import functools
import os
import sys
from collections.abc import Callable
from typing import Any

import click

from rockscan._choices import METHODS, METRICS, RANK_METRICS


def _fail(message: str, status: int = 1) -> None:
    click.echo(f"rockscan: error: {message}", err=True)
    sys.exit(status)


def _errors(func: Callable[..., Any]) -> Callable[..., Any]:
    """Turn the library's errors into one clear line and exit status 1."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        from rockscan.errors import RockscanError

        try:
            return func(*args, **kwargs)
        except RockscanError as exc:
            _fail(str(exc))
        except BrokenPipeError:
            # The reader went away (| head): stop quietly, as Unix tools do.
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
            sys.exit(1)
        except KeyboardInterrupt:
            _fail("interrupted", 130)

    return wrapper


def _library_option(func: Callable[..., Any]) -> Callable[..., Any]:
    return click.option(
        "--library",
        "-l",
        "library_path",
        type=click.Path(dir_okay=False),
        default=None,
        help="Library file (.npz from 'rockscan library build') or spec (.toml). "
        "Default: the built-in library.",
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
            help="Distance that ranks shapes (default: auto, the eigenspace distance for "
            "libraries of 4 or more shapes).",
        ),
        click.option(
            "--angle-metric",
            type=click.Choice(METRICS),
            default=None,
            help="Distance the angle minimises (default: face).",
        ),
        click.option(
            "--distance-cutoff",
            type=float,
            default=None,
            help="Largest distance of an interesting match (the paper's theta).",
        ),
        click.option(
            "--mscore-cutoff",
            type=float,
            default=None,
            help="MScore an interesting match must exceed (the paper's gamma).",
        ),
        click.option(
            "--residual-cutoff",
            type=float,
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
        from rockscan.match import MatchConfig

        paper = method == "paper"
        kwargs["match_config"] = MatchConfig(
            metric=metric or ("eigenspace" if paper else "auto"),
            angle_metric=angle_metric or ("eigenspace" if paper else "face"),
            distance_cutoff=distance_cutoff,
            mscore_cutoff=mscore_cutoff,
            residual_cutoff=residual_cutoff,
            scan=not no_scan,
        )
        return func(*args, **kwargs)

    for option in reversed(options):
        wrapper = option(wrapper)
    return wrapper


def _load_library(path: str | None) -> Any:
    from rockscan.io import default_library, load_library, read_spec
    from rockscan.library import Library

    if path is None:
        return default_library()
    if path.lower().endswith(".toml"):
        shapes = read_spec(path)
        if any(s.params is None for s in shapes):
            from rockscan.pipeline import library_from_spec

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


@click.group(context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(package_name="rockscan", prog_name="rockscan")
def main() -> None:
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


#: Environment variables that set the BLAS libraries' thread counts.
_BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def _register() -> None:
    from rockscan.cli import _classify, _fit, _library, _render, _triage  # noqa: F401


_register()
