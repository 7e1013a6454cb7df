"""The files shipped with rockscan: the default library spec and example photos."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rockscan.core.information import FaceConfig
    from rockscan.core.library import Library

from rockscan.io.spec import read_spec


def data_path(name: str) -> Path:
    """Path of a file shipped in rockscan's ``data/`` folder.

    Parameters
    ----------
    name : str
        Path within ``data/``, e.g. ``"default_library.toml"`` or ``"examples"``.

    Returns
    -------
    Path
        Inside the installed package, or in the source tree's ``data/`` folder
        when rockscan runs from a checkout that was not installed.
    """
    from importlib.resources import files

    try:
        return Path(str(files("rockscan._data") / name))
    except ModuleNotFoundError:
        return Path(__file__).resolve().parents[2] / "data" / name


def default_spec_path() -> Path:
    """Path of the built-in default library spec shipped with the package."""
    return data_path("default_library.toml")


_DEFAULT_CACHE: dict[object, Library] = {}


def default_library(face_config: FaceConfig | None = None) -> Library:
    """The built-in default library, built from its spec once per process.

    Parameters
    ----------
    face_config : FaceConfig, optional
        Face settings (default: the paper's variant 1 on the polar grid).

    Returns
    -------
    Library
    """
    from rockscan.core.information import FaceConfig
    from rockscan.core.library import Library

    config = face_config or FaceConfig()
    key = (config.kind, config.grid, json.dumps(config.to_dict(), sort_keys=True))
    if key not in _DEFAULT_CACHE:
        _DEFAULT_CACHE[key] = Library.from_shapes(read_spec(default_spec_path()), face_config=config)
    return _DEFAULT_CACHE[key]
