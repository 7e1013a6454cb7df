"""``rockscan render``: synthetic rock photos with ground truth."""

from __future__ import annotations

import json
import os
import re
from typing import TYPE_CHECKING

import click

from rockscan.cli._main import PathName, _errors, _progress, config_option, log, main
from rockscan.core.choices import RENDER_POLARITIES

if TYPE_CHECKING:
    from rockscan.core.render import RenderConfig

#: Where the render options take their defaults.
RENDER = "rockscan.core.render.RenderConfig"


@main.command("render")
@click.argument("spec", type=PathName(dir_okay=False), required=False)
@click.option(
    "-o",
    "--output",
    "out_dir",
    required=True,
    type=PathName(file_okay=False),
    help="Folder to write photos and their truth (.json) into.",
)
@click.option(
    "-n",
    "--count",
    type=click.IntRange(min=1),
    default=None,
    help="Photos to draw (default: one per spec shape).",
)
@click.option(
    "--rocks",
    type=click.IntRange(1, 10_000),
    default=1,
    show_default=True,
    help="Rocks per photo; with more than one, each photo shows shapes drawn at random from the "
    "spec, apart from each other, sharing --area.",
)
@click.option("--shape", "shape_names", multiple=True, help="Only these spec shapes (repeatable).")
@click.option(
    "--seed",
    type=click.IntRange(min=0),
    default=0,
    show_default=True,
    help="Random seed; the same seed draws the same photos.",
)
@config_option(
    "--size", config=RENDER, field=("rows", "cols"), convert="{}x{}".format, help="Photo size ROWSxCOLS."
)
@config_option(
    "--area", type=float, config=RENDER, field="area_fraction", help="Rock area as a fraction of the frame."
)
@click.option("--angle", type=float, default=None, help="Rotation in degrees (default: random).")
@click.option(
    "--polarity",
    type=click.Choice(RENDER_POLARITIES),
    default="random",
    show_default=True,
    help="Rock lighter or darker than the ground.",
)
@config_option(
    "--contrast",
    type=float,
    config=RENDER,
    field="contrast",
    help="Brightness difference of rock and ground (0 to 1).",
)
@config_option(
    "--rock-texture", type=float, config=RENDER, field="rock_texture", help="Amplitude of the rock's texture."
)
@config_option(
    "--ground-texture",
    type=float,
    config=RENDER,
    field="ground_texture",
    help="Amplitude of the ground's texture.",
)
@config_option(
    "--pebbles",
    type=click.IntRange(min=0),
    config=RENDER,
    field="pebbles",
    help="Pebbles scattered on the ground.",
)
@config_option("--gradient", type=float, config=RENDER, field="gradient", help="Lighting gradient strength.")
@config_option("--shadow", type=float, config=RENDER, field="shadow", help="Shadow darkness, 0 to 1.")
@config_option("--noise", type=float, config=RENDER, field="noise", help="Pixel noise standard deviation.")
@config_option("--blur", type=float, config=RENDER, field="blur", help="Gaussian blur sigma, pixels.")
@click.option(
    "--jpeg",
    "jpeg_quality",
    type=int,
    default=None,
    help="Compress at this JPEG quality: written as .jpg, or its artefacts kept losslessly with "
    "--format png/tif/bmp (default: no compression, PNG).",
)
@config_option(
    "--outline-noise",
    type=float,
    config=RENDER,
    field="outline_noise",
    help="Radial noise: each radius times 1+e, e ~ N(0, this) (paper Fig. 11).",
)
@click.option("--gray", is_flag=True, help="Gray photos instead of colour.")
@config_option("--bits", type=click.Choice(["8", "16"]), config=RENDER, field="bit_depth", convert=str)
@click.option(
    "--format",
    "fmt",
    type=click.Choice(["png", "jpg", "tif", "bmp"]),
    default=None,
    help="File format (default: png, or jpg with --jpeg).",
)
@click.option(
    "--overwrite",
    is_flag=True,
    help="Replace the photos of an earlier render in the folder (all of them, so that none is left "
    "from that run); default: refuse.",
)
@_errors
def render_cmd(
    spec: str | None,
    out_dir: str,
    count: int | None,
    rocks: int,
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
    overwrite: bool,
) -> None:
    """Draw synthetic rock photos of a spec's shapes, each with a ground-truth JSON.

    SPEC is a library spec (TOML); without it, the built-in library's spec.
    Photo i is named NNNN-SHAPE.EXT and its truth NNNN-SHAPE.json: rotation,
    scale, position, centroid, polarity, symmetry and every render setting.
    The same --seed draws the same photos; photo i alone is
    rockscan.core.render.render_numbered(shapes, config, seed=seed, index=i).
    A folder that holds an earlier render is refused, unless --overwrite,
    which first removes that render's photos and truth (other files stay).
    """
    from rockscan.core.render import numbered_stem, render_numbered
    from rockscan.io import default_spec_path, read_spec
    from rockscan.io.atomic import write_bytes_atomic
    from rockscan.io.photos import write_photo

    shapes = [s for s in read_spec(spec or default_spec_path()) if s.params is not None]
    if shape_names:
        unknown = set(shape_names) - {s.name for s in shapes}
        if unknown:
            raise click.BadParameter(f"not in the spec: {', '.join(sorted(unknown))}", param_hint="--shape")
        shapes = [s for s in shapes if s.name in shape_names]
    if not shapes:
        raise click.UsageError("the spec has no Superformula shapes to draw")
    config = _render_config(
        size,
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
    if suffix in (".jpg", ".bmp") and config.bit_depth == 16:
        raise click.UsageError(f"{suffix[1:].upper()} photos are 8 bits; use --bits 8 or --format png/tif")
    named = [(s.name, s.params) for s in shapes]
    total = count if count is not None else len(shapes)
    stems = [numbered_stem([name for name, _ in named], i, rocks) for i in range(total)]
    _prepare_folder(out_dir, overwrite, [name for stem in stems for name in (stem + suffix, stem + ".json")])
    shrunk: dict[str, float] = {}
    for i in _progress(range(total), total, unit="photo", verb="rendered"):
        stem, photo = render_numbered(named, config, seed=seed, index=i, rocks=rocks)
        drawn = float(photo.truth.get("area_fraction", config.area_fraction))
        if rocks == 1 and drawn < 0.95 * config.area_fraction:
            # A long rock at a large share does not fit the frame: the renderer shrinks it.
            shrunk[stem] = drawn
        write_photo(photo, os.path.join(out_dir, stem + suffix))
        truth = {"photo": stem + suffix, "seed": seed, "index": i, **photo.truth}
        text = json.dumps(truth, indent=1)
        write_bytes_atomic(os.path.join(out_dir, stem + ".json"), text.encode("utf-8"), what="the truth")
    if shrunk:
        stem, drawn = min(shrunk.items(), key=lambda item: item[1])
        log.warning(
            "%d of the rocks did not fit the frame at %g%% of it and were drawn smaller (%s at %.3g%%); "
            "each truth file gives its area_fraction",
            len(shrunk),
            100 * config.area_fraction,
            stem,
            100 * drawn,
        )
    log.info("wrote %d photos with truth (seed %d) to %s", total, seed, out_dir)


def _render_config(size: str, **settings: object) -> RenderConfig:
    """The render settings of the options, or a usage error naming the bad one."""
    from rockscan.core.errors import ParameterError
    from rockscan.core.render import RenderConfig

    try:
        rows, cols = (int(v) for v in size.lower().split("x"))
    except ValueError:
        raise click.BadParameter("must be ROWSxCOLS, e.g. 480x640", param_hint="--size") from None
    try:
        return RenderConfig(rows=rows, cols=cols, **settings)
    except ParameterError as exc:
        raise click.UsageError(str(exc)) from None


def _prepare_folder(out_dir: str, overwrite: bool, names: list[str]) -> None:
    """Make the output folder; remove an earlier render's photos if ``overwrite``, else refuse them.

    Refused too, before anything is drawn: a folder that cannot be written in,
    and one holding a file of its own under a name the render writes (``names``):
    ``--overwrite`` removes an earlier render's files, never the user's.
    """
    from rockscan.core.errors import WriteError

    earlier = _earlier_render(out_dir)
    if earlier and not overwrite:
        raise click.UsageError(
            f"{out_dir} holds {len(earlier) // 2} photos of an earlier render; give --overwrite to "
            "replace them (they are all removed first), or another folder"
        )
    if os.path.isdir(out_dir):
        if not os.access(out_dir, os.W_OK | os.X_OK):
            raise click.BadParameter(f"cannot write in folder {out_dir!r}", param_hint="-o")
        taken = sorted(set(names) & set(os.listdir(out_dir)) - set(earlier))
        if taken:
            more, them = (f" and {len(taken) - 1} more", "them") if len(taken) > 1 else ("", "it")
            raise click.UsageError(
                f"{out_dir} holds {taken[0]}{more}, not of an earlier render, under a name this "
                f"render writes; move {them}, or render to another folder"
            )
    try:
        os.makedirs(out_dir, exist_ok=True)
        for name in earlier:
            os.remove(os.path.join(out_dir, name))
    except OSError as exc:
        raise WriteError(f"{out_dir}: cannot prepare the folder ({exc.strerror or exc})") from None
    if earlier:
        log.info("removed the %d photos of an earlier render from %s", len(earlier) // 2, out_dir)


#: A rendered photo's truth file: NNNN-NAME.json.
_TRUTH_NAME = re.compile(r"\d{4}-[a-z0-9-]+\.json")


def _earlier_render(folder: str) -> list[str]:
    """The photos and truth files an earlier ``rockscan render`` left in ``folder``.

    A photo counts only beside its truth file naming it, so that no other file
    is ever taken for one.
    """
    if not os.path.isdir(folder):
        return []
    found = []
    for name in sorted(os.listdir(folder)):
        if not _TRUTH_NAME.fullmatch(name):
            continue
        try:
            with open(os.path.join(folder, name), encoding="utf-8") as fh:
                photo = json.load(fh).get("photo")
        except (OSError, ValueError, AttributeError):
            continue
        if (
            isinstance(photo, str)
            and os.path.splitext(photo)[0] == name[:-5]
            and os.path.isfile(os.path.join(folder, photo))
        ):
            found += [photo, name]
    return found
