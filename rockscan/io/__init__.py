"""Files: photos, library specs (TOML), library files (.npz), radii files, and the
one atomic write they all use.

The stages in :mod:`rockscan.core` take and return arrays; this layer is where
paths become arrays and back. Each kind of file has its module; the names used
most are gathered here.
"""

from __future__ import annotations

from rockscan.io.data import data_path, default_library, default_spec_path
from rockscan.io.library import (
    LIBRARY_FORMAT,
    LIBRARY_VERSION,
    RecalibratedWarning,
    load_library,
    save_library,
)
from rockscan.io.photos import IMAGE_SUFFIXES, ImageData, read_image
from rockscan.io.radii import read_radii
from rockscan.io.spec import parse_spec, read_spec, write_spec

__all__ = [
    "IMAGE_SUFFIXES",
    "LIBRARY_FORMAT",
    "LIBRARY_VERSION",
    "ImageData",
    "RecalibratedWarning",
    "data_path",
    "default_library",
    "default_spec_path",
    "load_library",
    "parse_spec",
    "read_image",
    "read_radii",
    "read_spec",
    "save_library",
    "write_spec",
]
