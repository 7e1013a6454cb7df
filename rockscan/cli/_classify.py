"""``rockscan match`` and ``rockscan classify``: outlines and photos against a library."""

from __future__ import annotations

import json
import os
import sys
from typing import Any

import click

from rockscan.cli import _errors, _library_option, _load_library, _match_options, main

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
    match_config: Any,
    as_json: bool,
) -> None:
    """Match an outline given as Superformula parameters or radii, without a photo."""
    from rockscan.io import read_radii
    from rockscan.library import shape_radii
    from rockscan.match import match_radii
    from rockscan.polar import resample_radii, rotate_radii
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
        radii = shape_radii(SuperformulaParams(*values), n)
    else:
        radii = read_radii(radii_path)
        if radii.size != n:
            radii = resample_radii(radii, n)
    if rotate:
        radii = rotate_radii(radii, rotate)
    result = match_radii(radii, lib, match_config)
    record = {"source": params_text or radii_path, **result.to_dict()}
    if as_json:
        click.echo(json.dumps(record))
    else:
        verdict = "interesting" if result.interesting else "not interesting"
        click.echo(
            f"nearest {result.nearest}  MScore {result.mscore:.3f}  distance {result.distance:.4g}  "
            f"angle {result.angle_deg:.1f} deg  -> {verdict}"
        )


# ---------------------------------------------------------------- classify

_COLUMNS = (
    f"{'photo':<32} {'rock':>4}  {'match':<20} {'nearest':<20} {'MScore':>6} "
    f"{'distance':>9} {'angle':>6}  {'centroid (x, y)':<18}"
)


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
    help="Draw each photo with outline, centroid, matched shape, information face and distances "
    "(PNG). With several photos, the photo's name is added to the file name.",
)
@_errors
def classify(
    photos: tuple[str, ...],
    library_path: str | None,
    match_config: Any,
    as_json: bool,
    all_rocks: bool,
    plot_path: str | None,
) -> None:
    """Find the rock in each photo and say which library shape it is closest to.

    PHOTO is a PNG, JPEG, TIFF or BMP file (gray, RGB or RGBA; 8 or 16 bits).
    A photo that cannot be classified gives an error line (with --json,
    {"path": ..., "error": ...}) and the others are still processed.

    Exit status: 0 when every photo was classified, 1 when any could not be,
    2 for usage errors.
    """
    from rockscan.errors import RockscanError
    from rockscan.pipeline import ClassifyConfig, classify_path

    if plot_path is not None:
        folder = os.path.dirname(os.path.abspath(plot_path))
        if not os.path.isdir(folder):
            raise click.BadParameter(f"folder {folder!r} does not exist", param_hint="--plot")
    lib = _load_library(library_path)
    config = ClassifyConfig(match=match_config)
    failed = 0
    targets = _plot_targets(plot_path, photos) if plot_path else {}
    if not as_json:
        click.echo(_COLUMNS)
    for i, photo in enumerate(photos):
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
            try:
                _plot(photo, result.rocks, lib, targets[i], config.segment.work_size)
            except RockscanError as exc:
                click.echo(f"rockscan: error: {exc}", err=True)
                failed += 1
    sys.exit(1 if failed else 0)


def _plot(photo: str, rocks: Any, lib: Any, target: str, work_size: int) -> None:
    from rockscan.io import read_image
    from rockscan.plot import plot_classification

    # The plot needs no more detail than the segmentation saw: read reduced.
    image = read_image(photo, max_side=2 * work_size)
    plot_classification(
        image.pixels, list(rocks), lib, target, title=os.path.basename(photo), scale=image.scale
    )


def _plot_targets(plot_path: str, photos: tuple[str, ...]) -> dict[int, str]:
    """One plot file per photo: the given name for one photo, else the name plus
    the photo's stem (and its position, if two photos share a stem)."""
    if len(photos) == 1:
        return {0: plot_path}
    root, ext = os.path.splitext(plot_path)
    stems = [os.path.splitext(os.path.basename(p))[0] for p in photos]
    return {
        i: f"{root}-{stem}{'-' + str(i) if stems.count(stem) > 1 else ''}{ext or '.png'}"
        for i, stem in enumerate(stems)
    }


def _short(text: str, width: int) -> str:
    return text if len(text) <= width else "..." + text[-(width - 3) :]
