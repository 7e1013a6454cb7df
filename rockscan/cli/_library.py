"""``rockscan library``: build, show (and grow) shape libraries."""

from __future__ import annotations

import json
import os

import click

from rockscan.cli._main import (
    DEFAULT_LIBRARY_NAME,
    Number,
    PathName,
    _check_output,
    _errors,
    _load_library,
    config_option,
    log,
    main,
)
from rockscan.core.choices import DEFAULT_TOLERANCE, FACE_KINDS, GRIDS, MAX_FACE_ANGLES

#: Where the face options take their defaults.
FACE = "rockscan.core.information.FaceConfig"

# ---------------------------------------------------------------- library


@main.group()
def library() -> None:
    """Build, inspect and grow shape libraries."""


@library.command("build")
@click.argument("spec", type=PathName(dir_okay=False))
@click.option(
    "-o", "--output", required=True, type=PathName(dir_okay=False), help="Library file to write (.npz)."
)
@config_option(
    "--face",
    "face_kind",
    type=click.Choice(FACE_KINDS),
    config=FACE,
    field="kind",
    help="Face kind: the paper's variants 1 and 2, or plain radii.",
)
@click.option(
    "--reference",
    default=None,
    help="For --face information-shape: name of the spec shape to compare against.",
)
@config_option(
    "--sigma",
    type=Number(0, low_open=True),
    config=FACE,
    field="sigma",
    help="Sensor model standard deviation (map units).",
)
@config_option(
    "--n-angles",
    type=click.IntRange(8, MAX_FACE_ANGLES),
    config=FACE,
    field="n_angles",
    help="Rays per shape (rotation step 360/n).",
)
@config_option(
    "--resolution",
    type=Number(0, low_open=True),
    config=FACE,
    field="resolution",
    help="Section length along a ray (map units).",
)
@config_option(
    "--grid",
    type=click.Choice(GRIDS),
    config=FACE,
    field="grid",
    help="'cartesian' is the paper's grid map (slower; for reproduction).",
)
@click.option(
    "--components",
    type=click.IntRange(min=1),
    default=None,
    help="Keep at most this many eigenfaces (default: all non-zero).",
)
@click.option(
    "--tolerance",
    type=Number(0, 1),
    default=DEFAULT_TOLERANCE,
    show_default=True,
    help="Outline noise (standard deviation, 0.2 = 20%) a sample may carry and still belong to its shape; "
    "the per-shape cutoffs are calibrated for it.",
)
@_errors
def library_build(
    spec: str,
    output: str,
    face_kind: str,
    reference: str | None,
    sigma: float,
    n_angles: int,
    resolution: float,
    grid: str,
    components: int | None,
    tolerance: float,
) -> None:
    """Build a library file from a spec (TOML with [[shape]] tables), with cutoffs calibrated for it."""
    from rockscan.core.errors import ParameterError
    from rockscan.core.information import FaceConfig
    from rockscan.io import read_spec, save_library
    from rockscan.io.library import check_library_size
    from rockscan.run.pipeline import library_from_spec

    _check_output(output, "--output", suffixes=(".npz",), inputs=(spec,))

    shapes = read_spec(spec)
    ref_params = None
    # The options are at fault here, not the spec: usage errors (exit 2).
    if face_kind == "information-shape":
        if reference is None:
            raise click.UsageError("--face information-shape needs --reference NAME (a shape of the spec)")
        found = [s for s in shapes if s.name == reference and s.params is not None]
        if not found:
            raise click.BadParameter(
                f"{reference!r} is not a Superformula shape of {spec}", param_hint="--reference"
            )
        ref_params = found[0].params
    elif reference is not None:
        raise click.UsageError("--reference is for --face information-shape")
    try:
        config = FaceConfig(
            kind=face_kind,
            sigma=sigma,
            n_angles=n_angles,
            resolution=resolution,
            grid=grid,
            reference=ref_params,
        )
        check_library_size(len(shapes), config.face_shape, components)
    except ParameterError as exc:
        raise click.UsageError(str(exc)) from None
    lib = library_from_spec(shapes, face_config=config, n_components=components, tolerance=tolerance)
    save_library(lib, output)
    cutoffs = lib.cutoffs
    click.echo(
        f"wrote {output}: {len(lib)} shapes, {lib.basis.n_components} eigenfaces, "
        f"face {face_kind} {'x'.join(map(str, config.face_shape))}; cutoffs calibrated for "
        f"{100 * lib.tolerance:g}% outline noise ({cutoffs.min():.3g} to {cutoffs.max():.3g})"
    )


@library.command("show")
@click.argument("lib", type=PathName(dir_okay=False), default=DEFAULT_LIBRARY_NAME)
@click.option(
    "--plot",
    "plot_path",
    # click.Path: the flag alone passes "" through the type, meaning LIBNAME.png.
    type=click.Path(dir_okay=False),
    is_flag=False,
    flag_value="",
    default=None,
    help="Draw the shapes to a PNG: --plot OUT.png, or --plot alone for LIBNAME.png here.",
)
@click.option("--overwrite", is_flag=True, help="Replace a plot that exists (default: refuse).")
@click.option("--json", "as_json", is_flag=True, help="One JSON object per shape.")
@_errors
def library_show(lib: str, plot_path: str | None, overwrite: bool, as_json: bool) -> None:
    """List a library's shapes: LIB is a .npz library, a .toml spec, or 'default'
    (the built-in library, also when LIB is left out)."""
    import numpy as np

    if plot_path == "":
        plot_path = os.path.splitext(os.path.basename(lib))[0] + ".png"
    _check_output(plot_path, "--plot", inputs=(lib,), overwrite=overwrite, plot=True)
    library_obj = _load_library(lib)
    face = library_obj.face_config
    cutoffs = library_obj.cutoffs
    clean = library_obj.calibration_in_force.clean_cutoffs
    assert clean is not None
    calibration = library_obj.calibration
    spacing = calibration.spacing if calibration is not None else np.full(len(library_obj), np.inf)
    crowded = calibration.crowded if calibration is not None else np.zeros(len(library_obj), bool)
    if as_json:
        for i, name in enumerate(library_obj.names):
            params = library_obj.params[i]
            click.echo(
                json.dumps(
                    {
                        "name": name,
                        "symmetry": int(library_obj.symmetry[i]),
                        "interest": float(library_obj.interest[i]),
                        "params": params.as_dict() if params is not None else None,
                        "cutoff": float(cutoffs[i]),
                        "clean_cutoff": float(clean[i]),
                        "spacing": float(spacing[i]) if np.isfinite(spacing[i]) else None,
                        "crowded": bool(crowded[i]),
                        "tolerance": library_obj.tolerance,
                    }
                )
            )
    else:
        label = f"{lib} (built-in)" if lib == DEFAULT_LIBRARY_NAME else lib
        click.echo(
            f"{label}: {len(library_obj)} shapes, {library_obj.basis.n_components} eigenfaces; "
            f"face {face.kind} on a {face.grid} grid {'x'.join(map(str, face.face_shape))}, "
            f"sigma {face.sigma:g}; cutoffs on the sensor distance, for a clean outline and one of "
            f"{100 * library_obj.tolerance:g}% outline noise (in between, in proportion to the noise; "
            "'rockscan match' shows the one applied)"
        )
        # As wide as the longest name: a longer one pushed its row's columns out of line.
        width = max(22, *(len(name) for name in library_obj.names))
        click.echo(
            f"{'name':<{width}} {'symmetry':>8} {'interest':>8} {'clean':>7} {'cutoff':>7} {'spacing':>7}  "
            "parameters (m1 m2 n1 n2 n3 a b)"
        )
        for i, name in enumerate(library_obj.names):
            params = library_obj.params[i]
            text = " ".join(f"{v:g}" for v in params.as_dict().values()) if params else "(from examples)"
            order = int(library_obj.symmetry[i])
            gap = f"{spacing[i]:7.3g}" if np.isfinite(spacing[i]) else f"{'-':>7}"
            mark = " (crowded)" if crowded[i] else ""
            click.echo(
                f"{name:<{width}} {'circle' if order == 0 else order:>8} {library_obj.interest[i]:>8g} "
                f"{clean[i]:7.3g} {cutoffs[i]:7.3g} {gap}  {text}{mark}"
            )
    if plot_path:
        from rockscan.draw.plot import plot_library

        plot_library(library_obj, plot_path)
        log.info("drew %s", plot_path)
