"""The package under test is complete: every module and shipped file is installed."""

from __future__ import annotations

import importlib
import pkgutil
from pathlib import Path

import rockscan


def test_every_module_of_the_source_tree_is_importable():
    # Run against an installed copy, a module left out of the package list
    # would fail here (the console script imports rockscan.cli).
    names = {m.name for m in pkgutil.walk_packages(rockscan.__path__, "rockscan.")}
    assert {"rockscan.cli", "rockscan.cli._classify", "rockscan.core.segment", "rockscan.run.triage"} <= names
    for name in names:
        importlib.import_module(name)


def test_shipped_data_is_beside_the_package():
    from rockscan.io import data_path

    spec = data_path("default_library.toml")
    assert spec.is_file() and (data_path("examples") / "coin.png").is_file()
    # Installed, the data lives inside the package; from a checkout, beside it.
    package = Path(rockscan.__file__).resolve().parent
    assert package in spec.resolve().parents or package.parent in spec.resolve().parents
