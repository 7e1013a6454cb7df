"""``rockscan match`` and ``rockscan classify``: outlines and photos against a library."""

from __future__ import annotations

import json
import os
import shutil
import sys
import unicodedata
from typing import Any

import click

from rockscan.cli._main import (
    LIBRARY_HINT,
    Number,
    PathName,
    _check_output,
    _errors,
    _library_option,
    _load_library,
    _match_options,
    _px_per_mm_option,
    log,
    main,
)

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
    type=PathName(dir_okay=False),
    default=None,
    help="Radii file: numbers at equal angles from theta=0, measured from the outline's area "
    "centroid (text or .npy).",
)
@click.option(
    "--rotate", type=Number(), default=0.0, show_default=True, help="Turn the outline first (degrees, CCW)."
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
    from rockscan.core.match import match_radii
    from rockscan.core.polar import resample_radii, rotate_radii
    from rockscan.core.superformula import SuperformulaParams, shape_radii
    from rockscan.io import read_radii

    if (params_text is None) == (radii_path is None):
        raise click.UsageError("give exactly one of --params or --radii")
    lib = _load_library(library_path, option=LIBRARY_HINT)
    n = lib.face_config.n_angles
    if params_text is not None:
        from rockscan.core.errors import ParameterError

        fields = params_text.replace(" ", "").split(",")
        try:
            # An empty field is no number: "3,,3,2,2,2" is not five parameters.
            values = [float(v) for v in fields]
        except ValueError:
            raise click.BadParameter(
                "must be 5 or 7 comma-separated numbers", param_hint="--params"
            ) from None
        if len(values) not in (5, 7):
            raise click.BadParameter("must be 5 or 7 comma-separated numbers", param_hint="--params")
        try:
            radii = shape_radii(SuperformulaParams(*values), n)
        except ParameterError as exc:
            raise click.BadParameter(str(exc), param_hint="--params") from None
    else:
        radii = read_radii(radii_path)
        if radii.size != n:
            radii = resample_radii(radii, n)
    if rotate:
        radii = rotate_radii(radii, rotate)
    result = match_radii(radii, lib, match_config)
    # What decided, beside the paper's distance: the library's cutoffs are on the
    # sensor distance (library show prints them), which the distance is not.
    record = {
        "source": params_text or radii_path,
        **result.to_dict(),
        "sensor_distance": result.sensor_distance,
        "cutoff_distance": result.cutoff_distance,
        "decided_by": result.decided_by,
    }
    if as_json:
        click.echo(json.dumps(record))
    else:
        verdict = "interesting" if result.interesting else "not interesting"
        click.echo(
            f"nearest {result.nearest}  MScore {result.mscore:.3f}  distance {result.distance:.4g}  "
            f"angle {result.angle_deg:.1f} deg  -> {verdict} ({_decision(result)})"
        )


def _decision(result: Any) -> str:
    """The test that decided a match, e.g. ``sensor distance 0.351 > cutoff 0.0901``."""
    if result.decided_by == "calibrated-cutoff":
        test = "<=" if result.sensor_distance <= result.cutoff_distance else ">"
        return f"sensor distance {result.sensor_distance:.3g} {test} cutoff {result.cutoff_distance:.3g}"
    if result.decided_by == "distance-cutoff":
        return (
            f"{'within' if result.interesting else 'beyond'} --distance-cutoff {result.cutoff_distance:.3g}"
        )
    return f"decided by --{result.decided_by}"


# ---------------------------------------------------------------- classify


@main.command("classify")
@click.argument("photos", nargs=-1, required=True, type=PathName(), metavar="PHOTO...")
@_library_option
@_match_options
@_px_per_mm_option
@click.option(
    "--json", "as_json", is_flag=True, help="One JSON object per line per photo (per rock with --all)."
)
@click.option(
    "--all", "all_rocks", is_flag=True, help="Classify every rock in each photo, not only the main one."
)
@click.option(
    "--plot",
    "plot_path",
    type=PathName(dir_okay=False),
    default=None,
    help="Draw each photo with outline, centroid, matched shape, information face and distances "
    "(PNG). With several photos, the photo's name is added to the file name.",
)
@click.option("--overwrite", is_flag=True, help="Replace plots that exist (default: refuse).")
@_errors
def classify(
    photos: tuple[str, ...],
    library_path: str | None,
    match_config: Any,
    px_per_mm: float | None,
    as_json: bool,
    all_rocks: bool,
    plot_path: str | None,
    overwrite: bool,
) -> None:
    """Find the rock in each photo and say which library shape it is closest to.

    PHOTO is a PNG, JPEG, TIFF or BMP file (gray, RGB or RGBA; 8 or 16 bits);
    '-' reads photo paths from standard input, one a line (e.g. from find).
    A photo that cannot be classified gives an error line (with --json,
    {"path": ..., "error": ...}), also on standard error, and the others are
    still processed.

    Exit status: 0 when every photo was classified, 1 when any could not be,
    2 for usage errors.
    """
    from rockscan.core.errors import RockscanError, internal_error
    from rockscan.run.pipeline import ClassifyConfig, PhotoResult, classify_path

    photos = _expand_stdin(photos)
    inputs = (*photos, *([library_path] if library_path else []))
    targets = _plot_targets(plot_path, photos, inputs, overwrite=overwrite) if plot_path is not None else {}
    lib = _load_library(library_path, option=LIBRARY_HINT)
    config = ClassifyConfig(match=match_config, px_per_mm=px_per_mm)
    failed = 0
    table = None if as_json else _Table(photos, lib.names, shutil.get_terminal_size((120, 24)).columns)
    if table is not None:
        click.echo(table.header())
    for i, photo in enumerate(photos):
        try:
            result = classify_path(photo, lib, config, all_rocks=all_rocks)
        except Exception as exc:  # a bug, not the photo's fault: the other photos still go
            log.debug("%s: classification failed", photo, exc_info=True)
            result = PhotoResult(path=photo, error=internal_error(exc))
        failed += not result.ok
        if as_json:
            for record in result.records():
                click.echo(json.dumps(record))
        elif not result.ok:
            click.echo(table.error_row(photo, result.error))
        else:
            for rock in result.rocks:
                click.echo(table.row(photo, rock))
        sys.stdout.flush()
        if not result.ok:
            # Errors also on standard error, so that they show when the table or JSON goes to a file.
            log.error("%s", result.error if result.error.startswith(photo) else f"{photo}: {result.error}")
        if plot_path and result.ok:
            try:
                _plot(photo, result.rocks, lib, targets[i], config)
            except RockscanError as exc:
                log.error("%s", exc)
                failed += 1
            else:
                log.info("drew %s", targets[i])
    sys.exit(1 if failed else 0)


#: How PNG, JPEG and TIFF (both byte orders) begin (a BMP: :func:`_is_bmp`).
_PHOTO_SIGNATURES = (b"\x89PNG\r\n\x1a\n", b"\xff\xd8\xff", b"II*\0", b"MM\0*")


def _is_bmp(raw: bytes) -> bool:
    # "BM" may begin a path: a BMP's header also gives the file's own length.
    return raw.startswith(b"BM") and len(raw) >= 6 and int.from_bytes(raw[2:6], "little") == len(raw)


def _expand_stdin(photos: tuple[str, ...]) -> tuple[str, ...]:
    """Replace a '-' by the paths on standard input (one a line, blank lines skipped)."""
    if photos.count("-") > 1:
        raise click.BadParameter("'-' (paths from standard input) may be given once", param_hint="PHOTO")
    if "-" not in photos:
        return photos
    stream = sys.stdin
    if stream.isatty():
        raise click.BadParameter(
            "'-' reads photo paths from standard input, which is a terminal: pipe them in "
            "(e.g. find DIR -name '*.jpg' | rockscan classify -)",
            param_hint="PHOTO",
        )
    # read(), not line iteration: click 8.2's test runner ends iteration with EOFError.
    # Bytes, decoded as the file system names files: a path that is not valid in
    # the locale's encoding still names its file, and never raises.
    raw = stream.buffer.read() if hasattr(stream, "buffer") else os.fsencode(stream.read())
    raw = raw.removeprefix(b"\xef\xbb\xbf")  # a UTF-8 byte-order mark (Notepad) is no part of a path
    # A photo piped in starts with its format's signature, or holds NUL bytes
    # without ending on one; paths ended by NUL (find -print0) may hold
    # newlines, carriage returns and spaces, as a file's name may.
    if raw.startswith(_PHOTO_SIGNATURES) or _is_bmp(raw) or (b"\0" in raw and not raw.endswith(b"\0")):
        raise click.BadParameter(
            "'-' reads photo paths from standard input, one a line (or each ended by NUL, as "
            "find -print0 writes them), but it holds binary data (a photo itself?): give the "
            "photo's path instead",
            param_hint="PHOTO",
        )
    if b"\0" in raw:
        read = [name for name in os.fsdecode(raw).split("\0") if name]
    else:
        read = [line.rstrip("\r") for line in os.fsdecode(raw).split("\n")]
        read = [line for line in read if line.strip()]
    if not read:
        raise click.BadParameter("'-' given but standard input holds no photo paths", param_hint="PHOTO")
    at = photos.index("-")
    return (*photos[:at], *read, *photos[at + 1 :])


def _plot(photo: str, rocks: Any, lib: Any, target: str, config: Any) -> None:
    from rockscan.draw.plot import plot_classification
    from rockscan.io import read_image

    # The plot needs no more detail than the segmentation saw: read reduced.
    image = read_image(photo, max_side=2 * config.segment.work_size)
    plot_classification(
        image.pixels,
        list(rocks),
        lib,
        target,
        title=os.path.basename(photo),
        scale=image.scale,
        match_config=config.match,
    )


def _plot_targets(
    plot_path: str, photos: tuple[str, ...], inputs: tuple[str, ...], *, overwrite: bool
) -> dict[int, str]:
    """One plot file per photo: the given name for one photo, else the name plus
    the photo's stem (and its position, if two photos share a stem).

    Refuses (a usage error) when a plot would replace a file, unless ``overwrite``:
    a folder never holds plots of two runs without the user asking for it; and
    whatever is given, a plot that would replace one of the command's ``inputs``
    (a photo, the library), which ``--overwrite`` once drew over before reading it.
    """
    _check_output(plot_path, "--plot", plot=True)  # folder and format; each plot's name below
    if len(photos) == 1:
        targets = {0: plot_path}
    else:
        root, ext = os.path.splitext(plot_path)
        stems = [os.path.splitext(os.path.basename(p))[0] for p in photos]
        targets = {
            i: f"{root}-{stem}{'-' + str(i) if stems.count(stem) > 1 else ''}{ext or '.png'}"
            for i, stem in enumerate(stems)
        }
    for target in targets.values():
        _check_output(target, "--plot", inputs=inputs)
    existing = [t for t in targets.values() if os.path.lexists(t)]
    if existing and not overwrite:
        more = f" and {len(existing) - 1} more" if len(existing) > 1 else ""
        raise click.BadParameter(
            f"{existing[0]}{more} exists; give --overwrite to replace, or another name", param_hint="--plot"
        )
    if existing:
        log.info("replacing %d earlier plot%s", len(existing), "s" if len(existing) > 1 else "")
    if len(photos) > 1:
        import glob

        root, ext = os.path.splitext(plot_path)
        pattern = f"{glob.escape(root)}-*{ext or '.png'}"
        others = sorted(set(glob.glob(pattern)) - set(targets.values()))
        if others:
            log.warning(
                "%d other plot%s named %s (of an earlier run?) stay beside these, e.g. %s",
                len(others),
                "s" if len(others) > 1 else "",
                pattern,
                others[0],
            )
    return targets


class _Table:
    """The classify table, its columns fitted to a terminal ``width`` characters wide.

    The numbers keep their widths; the shape columns are as wide as the
    library's longest name and the photo column takes the rest, up to the
    longest path, so that every row lines up. On a narrow terminal the
    centroid column (also in --json) goes first, then names and paths are cut
    in the middle.
    """

    #: Width of the rock index, MScore, distance and angle columns and the gaps.
    _FIXED = 1 + 4 + 2 + 1 + 1 + 6 + 1 + 9 + 1 + 6
    #: The centroid column, up to (9999.9, 9999.9), and its gap.
    _CENTROID = 2 + 16
    _MIN_PHOTO = 12

    def __init__(self, photos: tuple[str, ...], names: tuple[str, ...], width: int) -> None:
        longest = max([len("nearest"), *(len(n) for n in names)])
        longest_photo = max([len("photo"), *(len(_printable(p)) for p in photos)])
        room = width - self._FIXED - self._CENTROID
        self.centroid = room >= self._MIN_PHOTO + 2 * longest
        if not self.centroid:
            room += self._CENTROID
        # The paths get at least a third of the room (less if they are shorter), the names the rest.
        photo_share = max(self._MIN_PHOTO, min(longest_photo, room // 3))
        self.name_w = max(min(longest, (room - photo_share) // 2), 9)
        self.photo_w = min(max(room - 2 * self.name_w, self._MIN_PHOTO), longest_photo)

    def header(self) -> str:
        return (
            f"{'photo':<{self.photo_w}} {'rock':>4}  {'match':<{self.name_w}} {'nearest':<{self.name_w}} "
            f"{'MScore':>6} {'distance':>9} {'angle':>6}" + ("  centroid (x, y)" if self.centroid else "")
        )

    def row(self, photo: str, rock: Any) -> str:
        m = rock.match
        cx, cy = rock.centroid_xy
        return (
            f"{_cut_middle(_printable(photo), self.photo_w):<{self.photo_w}} {rock.index:>4}  "
            f"{_cut_middle(m.match or '-', self.name_w):<{self.name_w}} "
            f"{_cut_middle(m.nearest, self.name_w):<{self.name_w}} "
            f"{m.mscore:>6.3f} {m.distance:>9.4g} {m.angle_deg:>6.1f}"
            + (f"  ({cx:.1f}, {cy:.1f})" if self.centroid else "")
        )

    def error_row(self, photo: str, error: str) -> str:
        return f"{_cut_middle(_printable(photo), self.photo_w):<{self.photo_w}} error: {_printable(error)}"


def _printable(text: str) -> str:
    """``text`` with its control characters escaped (``\\n``, ``\\t``, ``\\x07``): a file
    name may hold a newline or a tab, which broke the table's rows and columns.
    (A byte that is not UTF-8, decoded as a lone surrogate, is left to the
    output's own escape, as standard error prints it.)"""
    return "".join(repr(ch)[1:-1] if unicodedata.category(ch) == "Cc" else ch for ch in text)


def _cut_middle(text: str, width: int) -> str:
    """``text`` in at most ``width`` characters: its middle replaced by '...' if too long,
    so that a path keeps its start (the folder) and its end (the file name)."""
    if len(text) <= width:
        return text
    if width <= 3:
        return text[:width]
    tail = (width - 3) // 2 + (width - 3) % 2
    return text[: width - 3 - tail] + "..." + text[len(text) - tail :]
