"""The ``rockscan`` command line: parse, call the library, format.

No math lives here. Heavy modules are imported inside the commands so that
``rockscan --help`` starts at once. A :class:`rockscan.errors.RockscanError`
becomes a one-line error and exit status 1; usage errors exit 2 (click).
"""

from __future__ import annotations

import functools
import json
import os
import sys
from collections.abc import Callable
from typing import Any

import click

FACE_KINDS = ("information", "information-shape", "radii")
METRICS = ("eigenspace", "face")
METHODS = ("default", "paper")


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
            type=click.Choice(METRICS),
            default=None,
            help="Distance that ranks shapes (default: eigenspace).",
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
            help="Largest eigenspace distance of an interesting match (the paper's theta).",
        ),
        click.option(
            "--mscore-cutoff",
            type=float,
            default=None,
            help="MScore an interesting match must exceed (the paper's gamma).",
        ),
        click.option(
            "--no-scan", is_flag=True, help="Match the outline as it lies, without the rotation scan."
        ),
    ]
    for option in reversed(options):
        func = option(func)
    return func


def _match_config(
    method: str,
    metric: str | None,
    angle_metric: str | None,
    distance_cutoff: float | None,
    mscore_cutoff: float | None,
    no_scan: bool,
) -> Any:
    from rockscan.match import MatchConfig

    paper = method == "paper"
    return MatchConfig(
        metric=metric or "eigenspace",
        angle_metric=angle_metric or ("eigenspace" if paper else "face"),
        distance_cutoff=distance_cutoff,
        mscore_cutoff=mscore_cutoff,
        scan=not no_scan,
    )


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
    return load_library(path)


@click.group(context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(package_name="rockscan", prog_name="rockscan")
def main() -> None:
    """Judge rock samples by their shape.

    rockscan finds the rock in a photo, measures its outline, and matches it
    against a library of Superformula shapes of interest (Fleetwood &
    Thangavelautham): nearest shape, match quality (MScore), rotation, and
    whether the sample is worth keeping.
    """


# ---------------------------------------------------------------- library


@main.group()
def library() -> None:
    """Build, inspect and grow shape libraries."""


@library.command("build")
@click.argument("spec", type=click.Path(dir_okay=False))
@click.option(
    "-o", "--output", required=True, type=click.Path(dir_okay=False), help="Library file to write (.npz)."
)
@click.option(
    "--face",
    "face_kind",
    type=click.Choice(FACE_KINDS),
    default="information",
    show_default=True,
    help="Face kind: the paper's variants 1 and 2, or plain radii.",
)
@click.option(
    "--reference",
    default=None,
    help="For --face information-shape: name of the spec shape to compare against.",
)
@click.option(
    "--sigma", type=float, default=0.1, show_default=True, help="Sensor model standard deviation (map units)."
)
@click.option(
    "--n-angles", type=int, default=360, show_default=True, help="Rays per shape (rotation step 360/n)."
)
@click.option(
    "--resolution",
    type=float,
    default=0.02,
    show_default=True,
    help="Section length along a ray (map units).",
)
@click.option(
    "--grid",
    type=click.Choice(["polar", "cartesian"]),
    default="polar",
    show_default=True,
    help="'cartesian' is the paper's grid map (slower; for reproduction).",
)
@click.option(
    "--components", type=int, default=None, help="Keep at most this many eigenfaces (default: all non-zero)."
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
) -> None:
    """Build a library file from a spec (TOML with [[shape]] tables)."""
    from rockscan.errors import SpecError
    from rockscan.information import FaceConfig
    from rockscan.io import read_spec, save_library
    from rockscan.pipeline import library_from_spec

    shapes = read_spec(spec)
    ref_params = None
    if face_kind == "information-shape":
        if reference is None:
            raise SpecError("--face information-shape needs --reference NAME (a shape of the spec)")
        found = [s for s in shapes if s.name == reference and s.params is not None]
        if not found:
            raise SpecError(f"--reference {reference!r} is not a Superformula shape of {spec}")
        ref_params = found[0].params
    config = FaceConfig(
        kind=face_kind, sigma=sigma, n_angles=n_angles, resolution=resolution, grid=grid, reference=ref_params
    )
    lib = library_from_spec(shapes, face_config=config, n_components=components)
    save_library(lib, output)
    click.echo(
        f"wrote {output}: {len(lib)} shapes, {lib.basis.n_components} eigenfaces, "
        f"face {face_kind} {'x'.join(map(str, config.face_shape))}"
    )


@library.command("show")
@click.argument("lib", type=click.Path(dir_okay=False))
@click.option(
    "--plot", "plot_path", type=click.Path(dir_okay=False), default=None, help="Draw the shapes to a PNG."
)
@click.option("--json", "as_json", is_flag=True, help="One JSON object per shape.")
@_errors
def library_show(lib: str, plot_path: str | None, as_json: bool) -> None:
    """List a library's shapes (a .npz library or a .toml spec)."""
    library_obj = _load_library(lib)
    face = library_obj.face_config
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
                    }
                )
            )
    else:
        click.echo(
            f"{lib}: {len(library_obj)} shapes, {library_obj.basis.n_components} eigenfaces; "
            f"face {face.kind} on a {face.grid} grid {'x'.join(map(str, face.face_shape))}, "
            f"sigma {face.sigma:g}"
        )
        click.echo(f"{'name':<22} {'symmetry':>8} {'interest':>8}  parameters (m1 m2 n1 n2 n3 a b)")
        for i, name in enumerate(library_obj.names):
            params = library_obj.params[i]
            text = " ".join(f"{v:g}" for v in params.as_dict().values()) if params else "(from examples)"
            order = int(library_obj.symmetry[i])
            click.echo(
                f"{name:<22} {'circle' if order == 0 else order:>8} {library_obj.interest[i]:>8g}  {text}"
            )
    if plot_path:
        from rockscan.plot import plot_library

        plot_library(library_obj, plot_path)
        click.echo(f"drew {plot_path}", err=as_json)


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


# ---------------------------------------------------------------- render


@main.command("render")
@click.argument("spec", type=click.Path(dir_okay=False), required=False)
@click.option(
    "-o",
    "--output",
    "out_dir",
    required=True,
    type=click.Path(file_okay=False),
    help="Folder to write photos and their truth (.json) into.",
)
@click.option("-n", "--count", type=int, default=None, help="Photos to draw (default: one per spec shape).")
@click.option("--shape", "shape_names", multiple=True, help="Only these spec shapes (repeatable).")
@click.option(
    "--seed", type=int, default=0, show_default=True, help="Random seed; the same seed draws the same photos."
)
@click.option("--size", default="480x640", show_default=True, help="Photo size ROWSxCOLS.")
@click.option(
    "--area", type=float, default=0.12, show_default=True, help="Rock area as a fraction of the frame."
)
@click.option("--angle", type=float, default=None, help="Rotation in degrees (default: random).")
@click.option(
    "--polarity",
    type=click.Choice(["random", "light", "dark"]),
    default="random",
    show_default=True,
    help="Rock lighter or darker than the ground.",
)
@click.option("--contrast", type=float, default=0.35, show_default=True)
@click.option("--rock-texture", type=float, default=0.04, show_default=True)
@click.option("--ground-texture", type=float, default=0.04, show_default=True)
@click.option("--pebbles", type=int, default=0, show_default=True, help="Pebbles scattered on the ground.")
@click.option("--gradient", type=float, default=0.2, show_default=True, help="Lighting gradient strength.")
@click.option("--shadow", type=float, default=0.0, show_default=True, help="Shadow darkness, 0 to 1.")
@click.option("--noise", type=float, default=0.02, show_default=True, help="Pixel noise standard deviation.")
@click.option("--blur", type=float, default=0.8, show_default=True, help="Gaussian blur sigma, pixels.")
@click.option(
    "--jpeg", "jpeg_quality", type=int, default=None, help="Write JPEG at this quality (default: PNG)."
)
@click.option(
    "--outline-noise",
    type=float,
    default=0.0,
    show_default=True,
    help="Radial noise: each radius times 1+e, e ~ N(0, this) (paper Fig. 11).",
)
@click.option("--gray", is_flag=True, help="Gray photos instead of colour.")
@click.option("--bits", type=click.Choice(["8", "16"]), default="8", show_default=True)
@click.option(
    "--format",
    "fmt",
    type=click.Choice(["png", "jpg", "tif", "bmp"]),
    default=None,
    help="File format (default: png, or jpg with --jpeg).",
)
@_errors
def render_cmd(
    spec: str | None,
    out_dir: str,
    count: int | None,
    shape_names: tuple[str, ...],
    seed: int,
    size: str,
    area: float,
    angle: float | None,
    polarity: str,
    contrast: float,
    rock_texture: float,
    ground_texture: float,
    pebbles: int,
    gradient: float,
    shadow: float,
    noise: float,
    blur: float,
    jpeg_quality: int | None,
    outline_noise: float,
    gray: bool,
    bits: str,
    fmt: str | None,
) -> None:
    """Draw synthetic rock photos of a spec's shapes, each with a ground-truth JSON."""
    import numpy as np

    from rockscan.io import default_spec_path, read_spec
    from rockscan.render import RenderConfig, render_photo

    try:
        rows, cols = (int(v) for v in size.lower().split("x"))
    except ValueError:
        raise click.BadParameter("must be ROWSxCOLS, e.g. 480x640", param_hint="--size") from None
    shapes = [s for s in read_spec(spec or default_spec_path()) if s.params is not None]
    if shape_names:
        unknown = set(shape_names) - {s.name for s in shapes}
        if unknown:
            raise click.BadParameter(f"not in the spec: {', '.join(sorted(unknown))}", param_hint="--shape")
        shapes = [s for s in shapes if s.name in shape_names]
    if not shapes:
        raise click.UsageError("the spec has no Superformula shapes to draw")
    config = RenderConfig(
        rows=rows,
        cols=cols,
        area_fraction=area,
        angle_deg=angle,
        rock_lighter=None if polarity == "random" else polarity == "light",
        contrast=contrast,
        rock_texture=rock_texture,
        ground_texture=ground_texture,
        pebbles=pebbles,
        gradient=gradient,
        shadow=shadow,
        noise=noise,
        blur=blur,
        jpeg_quality=jpeg_quality,
        outline_noise=outline_noise,
        color=not gray,
        bit_depth=int(bits),
    )
    suffix = "." + (fmt or ("jpg" if jpeg_quality else "png"))
    os.makedirs(out_dir, exist_ok=True)
    rng = np.random.default_rng(seed)
    total = count if count is not None else len(shapes)
    for i in range(total):
        shape = shapes[i % len(shapes)]
        photo = render_photo(shape.params, config, rng=rng, name=shape.name)
        stem = f"{i:04d}-{shape.name}"
        with open(os.path.join(out_dir, stem + suffix), "wb") as fh:
            fh.write(photo.encode(suffix))
        with open(os.path.join(out_dir, stem + ".json"), "w", encoding="utf-8") as fh:
            json.dump({"photo": stem + suffix, "seed": seed, **photo.truth}, fh, indent=1)
    click.echo(f"wrote {total} photos with truth to {out_dir}")


if __name__ == "__main__":  # pragma: no cover
    main()
