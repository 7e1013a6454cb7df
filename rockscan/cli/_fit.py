"""``rockscan library fit`` and ``rockscan library family``: grow a library from examples."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path
from typing import Any

import click

from rockscan.cli._library import library
from rockscan.cli._main import PathName, _check_output, _errors, log

#: Rays an outline is measured at (the library's default).
_N_ANGLES = 360


# ---------------------------------------------------------------- fit


@library.command("fit")
@click.argument("inputs", metavar="PHOTO...", nargs=-1, required=True, type=PathName())
@click.option(
    "-o",
    "--output",
    type=PathName(dir_okay=False),
    default=None,
    help="Spec (.toml) to write the fitted shapes to. Default: print the spec on standard output "
    "and the report on standard error.",
)
@click.option("--append", is_flag=True, help="Add the fitted shapes to the existing spec -o.")
@click.option(
    "--plot",
    "plot_path",
    type=PathName(dir_okay=False),
    default=None,
    help="Draw each outline with its fitted curve overlaid (PNG).",
)
@click.option(
    "--json",
    "as_json",
    is_flag=True,
    help="Report one JSON object per input (the spec then goes only to -o).",
)
@click.option("--overwrite", is_flag=True, help="Replace a plot that exists (default: refuse).")
@click.option(
    "--seed",
    type=click.IntRange(min=0),
    default=0,
    show_default=True,
    help="Seed of the fit's random restarts.",
)
@_errors
def library_fit(
    inputs: tuple[str, ...],
    output: str | None,
    append: bool,
    plot_path: str | None,
    overwrite: bool,
    as_json: bool,
    seed: int,
) -> None:
    """Fit Superformula parameters and a rotation to each rock.

    The parameters are m1, m2, n1, n2, n3, a and b (a = 1: the size is free).
    PHOTO is a photo (PNG, JPEG, TIFF, BMP; its main rock is fitted) or a radii file (text
    or .npy: radii about the centroid at equal angles from theta = 0). Each
    fitted shape is named after its file (lower case, other characters to
    '-'). The report gives the fit's RMS radius error in percent of the mean
    radius. An input that cannot be fitted gives an error line and the others
    are still fitted. Without --append, -o replaces the spec.

    Exit status: 0 when every input was fitted, 1 when any could not be, 2 for
    usage errors.
    """
    from rockscan.core.errors import RockscanError
    from rockscan.core.fit import fit_superformula
    from rockscan.core.library import ShapeSpec, sanitize_name, unique_name
    from rockscan.draw.fits import plot_fits
    from rockscan.io import read_spec, write_spec

    if append and output is None:
        raise click.UsageError("--append needs -o SPEC (the spec to add the shapes to)")
    _check_output(output, "--output", suffixes=(".toml",), inputs=inputs)
    _check_output(plot_path, "--plot", inputs=inputs, overwrite=overwrite, plot=True)
    existing = read_spec(output) if append and os.path.exists(output or "") else []
    taken = {shape.name for shape in existing}
    report = sys.stdout if output is not None or as_json else sys.stderr
    shapes, drawn, failed = [], [], 0
    for path in inputs:
        name = unique_name(sanitize_name(Path(path).stem), taken)
        try:
            radii = _outline_radii(path)
            fit = fit_superformula(radii, rng=seed)
        except RockscanError as exc:
            failed += 1
            # Readers name the file themselves; others are told which input failed.
            message = str(exc) if str(exc).startswith(path) else f"{path}: {exc}"
            if as_json:
                click.echo(json.dumps({"path": path, "error": message}))
            else:
                click.echo(f"rockscan: error: {message}", err=True)
            continue
        taken.add(name)
        if twin := next((s.name for s in (*existing, *shapes) if s.params == fit.params), None):
            # Two copies of one photo: library build refuses one outline given twice.
            log.warning("%s fits the same shape as %s; library build refuses the two together", name, twin)
        shapes.append(ShapeSpec(name, fit.params))
        drawn.append((name, radii, fit))
        if as_json:
            record = {
                "path": path,
                "name": name,
                "params": fit.params.as_dict(),
                "angle_deg": round(fit.angle_deg, 3),
                "rms_percent": round(fit.rms_percent, 4),
            }
            click.echo(json.dumps(record))
        else:
            p = fit.params
            click.echo(
                f"{name:<24} rms {fit.rms_percent:6.2f}%  angle {fit.angle_deg:6.1f}  "
                f"m1 {p.m1:g} m2 {p.m2:g} n1 {p.n1:g} n2 {p.n2:g} n3 {p.n3:g} a {p.a:g} b {p.b:g}",
                file=report,
            )
    if shapes:
        if output is not None and existing:
            # Appended as text: the spec's own comments and layout stay as written.
            from rockscan.io.atomic import write_bytes_atomic

            before = Path(output).read_bytes().rstrip(b"\n") + b"\n\n"
            write_bytes_atomic(output, before + write_spec(shapes).encode("utf-8"), what="spec")
            click.echo(f"wrote {output}: {len(shapes)} fitted shapes", err=as_json)
        elif output is not None:
            write_spec(shapes, output)
            click.echo(f"wrote {output}: {len(shapes)} fitted shapes", err=as_json)
        elif not as_json:
            click.echo(write_spec(shapes), nl=False)
        if plot_path:
            plot_fits(drawn, plot_path)
            click.echo(f"drew {plot_path}", err=as_json or output is None)
    sys.exit(1 if failed else 0)


def _outline_radii(path: str) -> Any:
    """Radii about the centroid of a photo's main rock, or of a radii file."""
    from rockscan.core.segment import SegmentConfig
    from rockscan.io import IMAGE_SUFFIXES, read_image, read_radii
    from rockscan.run.pipeline import measure_rocks

    if Path(path).suffix.lower() not in IMAGE_SUFFIXES:
        return read_radii(path)
    config = SegmentConfig()
    image = read_image(path, max_side=2 * config.work_size)
    _, rocks = measure_rocks(image.pixels, _N_ANGLES, config, scale=image.scale)
    return rocks[0].radii


# ---------------------------------------------------------------- family


@library.command("family")
@click.argument("spec", type=PathName(dir_okay=False))
@click.argument("name")
@click.option(
    "--vary",
    "vary_texts",
    multiple=True,
    required=True,
    metavar="NAME=START:STOP:COUNT",
    help="Vary a parameter (m1 m2 n1 n2 n3 a b, or together: m = m1,m2; n23 = n2,n3; n = n1,n2,n3) "
    "by COUNT factors from START to STOP, or by a list NAME=V1,V2,... Repeat for more parameters.",
)
@click.option(
    "--absolute", is_flag=True, help="The --vary values are parameter values, not factors of the base's."
)
@click.option(
    "--one-at-a-time",
    is_flag=True,
    help="Vary each parameter alone (the paper's sweeps), not every combination.",
)
@click.option(
    "-o",
    "--output",
    type=PathName(dir_okay=False),
    default=None,
    help="Spec (.toml) to write. Default: standard output.",
)
@click.option("--variants-only", is_flag=True, help="Write only the variants, not the spec's own shapes.")
@_errors
def library_family(
    spec: str,
    name: str,
    vary_texts: tuple[str, ...],
    absolute: bool,
    one_at_a_time: bool,
    output: str | None,
    variants_only: bool,
) -> None:
    """Write variants of a spec's shape: the paper's Section IV-C sweeps.

    NAME is a Superformula shape of SPEC. Each variant is named
    NAME-PARAMETER-VALUE (e.g. egg-n1-0-9 for n1 at 0.9 times the egg's) and
    keeps the base's interest. The spec's shapes and the
    variants are written together unless --variants-only.

    \b
    Example: rockscan library family lib.toml egg --vary n1=0.8:1.2:5 --vary n23=0.9,1.1 -o fam.toml
    """
    from rockscan.core.errors import ParameterError, SpecError
    from rockscan.core.family import family, parse_vary
    from rockscan.io import read_spec, write_spec

    vary = []
    for text in vary_texts:
        try:
            vary.append(parse_vary(text))
        except ParameterError as exc:
            raise click.BadParameter(str(exc), param_hint="--vary") from None
    _check_output(output, "--output", suffixes=(".toml",), inputs=(spec,))
    shapes = read_spec(spec)
    by_name = {shape.name: shape for shape in shapes}
    if name not in by_name:
        raise SpecError(f"{spec} has no shape {name!r}; it has {', '.join(by_name)}")
    variants = family(by_name[name], vary, absolute=absolute, one_at_a_time=one_at_a_time)
    clash = sorted({v.name for v in variants} & set(by_name))
    if clash and not variants_only:
        raise SpecError(f"{spec} already has shapes named {', '.join(clash)}; use --variants-only or -o")
    if not variants:
        raise SpecError("every variant equals the base shape; vary the parameters by other factors")
    out = variants if variants_only else [*shapes, *variants]
    if output is None:
        click.echo(write_spec(out), nl=False)
    else:
        write_spec(out, output)
        click.echo(f"wrote {output}: {len(variants)} variants of {name} ({len(out)} shapes)")
