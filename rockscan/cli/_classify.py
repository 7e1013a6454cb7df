"""``rockscan match`` and ``rockscan classify``: outlines and photos against a library."""

from __future__ import annotations

import json
import os
import sys
from typing import Any

import click

from rockscan.cli import _errors, _library_option, _load_library, _match_config, _match_options, main

# ---------------------------------------------------------------- match (no photo)


@main.command("match")
@click.option(
    "--params",
    "params_text",
    default=None,
    help="Superformula parameters 'm1,m2,n1,n2,n3[,a,b]' of the outline.",
)
@click.option(
    "--radii",
    "radii_path",
    type=click.Path(dir_okay=False),
    default=None,
    help="Radii file: numbers at equal angles from theta=0 (text or .npy).",
)
@click.option(
    "--rotate", type=float, default=0.0, show_default=True, help="Turn the outline first (degrees, CCW)."
)
@_library_option
@_match_options
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
@_errors
def match_cmd(
    params_text: str | None,
    radii_path: str | None,
    rotate: float,
    library_path: str | None,
    method: str,
    metric: str | None,
    angle_metric: str | None,
    distance_cutoff: float | None,
    mscore_cutoff: float | None,
    no_scan: bool,
    as_json: bool,
) -> None:
    """Match an outline given as Superformula parameters or radii, without a photo."""
    import numpy as np

    from rockscan.errors import ParameterError
    from rockscan.io import read_radii
    from rockscan.match import match_radii
    from rockscan.polar import polar_angles, recenter_radii, rotate_radii
    from rockscan.superformula import SuperformulaParams

    if (params_text is None) == (radii_path is None):
        raise click.UsageError("give exactly one of --params or --radii")
    lib = _load_library(library_path)
    n = lib.face_config.n_angles
    if params_text is not None:
        try:
            values = [float(v) for v in params_text.replace(" ", "").split(",") if v]
        except ValueError:
            raise click.BadParameter(
                "must be 5 or 7 comma-separated numbers", param_hint="--params"
            ) from None
        if len(values) not in (5, 7):
            raise click.BadParameter("must be 5 or 7 comma-separated numbers", param_hint="--params")
        radii = SuperformulaParams(*values).radii(polar_angles(n))
        if not np.all(np.isfinite(radii)) or np.any(radii <= 0):
            raise ParameterError("these parameters give an unbounded or degenerate outline")
        radii, _ = recenter_radii(radii)
    else:
        radii = read_radii(radii_path)
        if radii.size != n:
            radii = _resample(radii, n)
    if rotate:
        radii = rotate_radii(radii, rotate)
    config = _match_config(method, metric, angle_metric, distance_cutoff, mscore_cutoff, no_scan)
    result = match_radii(radii, lib, config)
    record = {"source": params_text or radii_path, **result.to_dict()}
    if as_json:
        click.echo(json.dumps(record))
    else:
        verdict = "interesting" if result.interesting else "not interesting"
        click.echo(
            f"nearest {result.nearest}  MScore {result.mscore:.3f}  distance {result.distance:.4g}  "
            f"angle {result.angle_deg:.1f} deg  -> {verdict}"
        )


def _resample(values: Any, n: int) -> Any:
    import numpy as np

    position = np.arange(n) * values.size / n
    lo = np.floor(position).astype(int)
    frac = position - lo
    return values[lo % values.size] * (1 - frac) + values[(lo + 1) % values.size] * frac


# ---------------------------------------------------------------- classify


@main.command("classify")
@click.argument("photos", nargs=-1, required=True, type=click.Path())
@_library_option
@_match_options
@click.option(
    "--json", "as_json", is_flag=True, help="One JSON object per line per photo (per rock with --all)."
)
@click.option(
    "--all", "all_rocks", is_flag=True, help="Classify every rock in each photo, not only the main one."
)
@click.option(
    "--plot",
    "plot_path",
    type=click.Path(dir_okay=False),
    default=None,
    help="Draw each photo with outline, centroid, matched shape and information face (PNG). "
    "With several photos, the photo's name is added to the file name.",
)
@_errors
def classify(
    photos: tuple[str, ...],
    library_path: str | None,
    method: str,
    metric: str | None,
    angle_metric: str | None,
    distance_cutoff: float | None,
    mscore_cutoff: float | None,
    no_scan: bool,
    as_json: bool,
    all_rocks: bool,
    plot_path: str | None,
) -> None:
    """Find the rock in each photo and say which library shape it is closest to.

    Exit status: 0 when every photo was classified, 1 when any could not be.
    """
    from rockscan.pipeline import ClassifyConfig, classify_path

    lib = _load_library(library_path)
    config = ClassifyConfig(
        match=_match_config(method, metric, angle_metric, distance_cutoff, mscore_cutoff, no_scan)
    )
    failed = 0
    if not as_json:
        click.echo(
            f"{'photo':<32} {'rock':>4}  {'match':<20} {'nearest':<20} {'MScore':>6} "
            f"{'distance':>9} {'angle':>6}  {'centroid (x, y)':<18}"
        )
    for photo in photos:
        result = classify_path(photo, lib, config, all_rocks=all_rocks)
        failed += not result.ok
        if as_json:
            for record in result.records():
                click.echo(json.dumps(record))
        elif not result.ok:
            click.echo(f"{_short(photo, 32):<32} error: {result.error}")
        else:
            for rock in result.rocks:
                m = rock.match
                cx, cy = rock.centroid_xy
                click.echo(
                    f"{_short(photo, 32):<32} {rock.index:>4}  {(m.match or '-'):<20} {m.nearest:<20} "
                    f"{m.mscore:>6.3f} {m.distance:>9.4g} {m.angle_deg:>6.1f}  ({cx:.1f}, {cy:.1f})"
                )
        sys.stdout.flush()
        if plot_path and result.ok:
            from rockscan.io import read_image
            from rockscan.plot import plot_classification

            target = plot_path if len(photos) == 1 else _suffixed(plot_path, photo)
            image = read_image(photo)
            plot_classification(image.pixels, list(result.rocks), lib, target, title=os.path.basename(photo))
    sys.exit(1 if failed else 0)


def _short(text: str, width: int) -> str:
    return text if len(text) <= width else "..." + text[-(width - 3) :]


def _suffixed(path: str, photo: str) -> str:
    root, ext = os.path.splitext(path)
    stem = os.path.splitext(os.path.basename(photo))[0]
    return f"{root}-{stem}{ext or '.png'}"
