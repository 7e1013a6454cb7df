"""``rockscan examples``: the example photos shipped with the package, copied out."""

from __future__ import annotations

import os
import shutil

import click

from rockscan.cli._main import PathName, _errors, log, main

#: Photo file endings among the examples (the rest are their truth and notes).
_PHOTO_ENDINGS = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp")


@main.command("examples")
@click.argument("folder", type=PathName(file_okay=False))
@click.option("--overwrite", is_flag=True, help="Replace files of the same names in FOLDER.")
@_errors
def examples_cmd(folder: str, overwrite: bool) -> None:
    """Copy the example photos (and their ground truth) into FOLDER.

    The photos are installed with the package; this puts them where you can
    try them, e.g. 'rockscan examples examples && rockscan classify examples/coin.png'.
    FOLDER is created if needed; files already there are left alone unless
    --overwrite is given.
    """
    from rockscan.core.errors import ParameterError
    from rockscan.io import data_path

    source = data_path("examples")
    names = sorted(p.name for p in source.iterdir() if p.is_file() and not p.name.startswith((".", "_")))
    clashes = [n for n in names if os.path.lexists(os.path.join(folder, n))]
    if clashes and not overwrite:
        raise click.UsageError(
            f"{folder} already has {len(clashes)} of the example files ({', '.join(clashes[:3])}"
            f"{', ...' if len(clashes) > 3 else ''}); give --overwrite to replace them, or another folder"
        )
    try:
        os.makedirs(folder, exist_ok=True)
        for name in names:
            shutil.copyfile(source / name, os.path.join(folder, name))
    except OSError as exc:
        raise ParameterError(f"{folder}: cannot copy the examples ({exc.strerror or exc})") from None
    photos = sum(n.lower().endswith(_PHOTO_ENDINGS) for n in names)
    log.info("copied %d example photos (%d files) to %s", photos, len(names), folder)
