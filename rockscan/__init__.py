"""rockscan: judge rock samples by their shape.

photo -> segment -> outline and centroid -> polar radii -> information face ->
eigenfaces against a library of Superformula shapes -> distance, MScore,
cutoffs -> best rotation.

The public API is listed in ``__all__``; submodules load on first use so that
the command line starts fast.
"""

from __future__ import annotations

import importlib
from typing import Any

from rockscan._version import __version__

_API = {
    # errors
    "RockscanError": "rockscan.core.errors",
    "ParameterError": "rockscan.core.errors",
    "ImageReadError": "rockscan.core.errors",
    "NoRockFoundError": "rockscan.core.errors",
    "LibraryError": "rockscan.core.errors",
    "SpecError": "rockscan.core.errors",
    # shapes and radii
    "SuperformulaParams": "rockscan.core.superformula",
    "polar_angles": "rockscan.core.polar",
    "contour_radii": "rockscan.core.polar",
    "symmetry_order": "rockscan.core.polar",
    "rotate_radii": "rockscan.core.polar",
    "recenter_radii": "rockscan.core.polar",
    # faces, eigenfaces, libraries, matching
    "FaceConfig": "rockscan.core.information",
    "information_face": "rockscan.core.information",
    "EigenBasis": "rockscan.core.eigen",
    "ShapeSpec": "rockscan.core.library",
    "Library": "rockscan.core.library",
    "shape_radii": "rockscan.core.superformula",
    "MatchConfig": "rockscan.core.match",
    "Match": "rockscan.core.match",
    "match_radii": "rockscan.core.match",
    "rotation_scores": "rockscan.core.match",
    # growing libraries
    "FitConfig": "rockscan.core.fit",
    "FitResult": "rockscan.core.fit",
    "fit_superformula": "rockscan.core.fit",
    "family": "rockscan.core.family",
    # photos
    "SegmentConfig": "rockscan.core.segment",
    "trace_outline": "rockscan.core.outline",
    "ClassifyConfig": "rockscan.run.pipeline",
    "classify_image": "rockscan.run.pipeline",
    "classify_path": "rockscan.run.pipeline",
    "measure_rocks": "rockscan.run.pipeline",
    "library_from_spec": "rockscan.run.pipeline",
    "RenderConfig": "rockscan.core.render",
    "render_photo": "rockscan.core.render",
    "render_scene": "rockscan.core.render",
    "random_superformula": "rockscan.core.render",
    # folders
    "TriageConfig": "rockscan.run.triage",
    "TriageSummary": "rockscan.run.triage",
    "triage_folder": "rockscan.run.triage",
    "find_photos": "rockscan.io.folders",
    "NoveltyConfig": "rockscan.core.novelty",
    "ObservedShapes": "rockscan.core.novelty",
    "read_rows": "rockscan.io.report",
    # files
    "read_image": "rockscan.io",
    "read_spec": "rockscan.io",
    "write_spec": "rockscan.io",
    "read_radii": "rockscan.io",
    "load_library": "rockscan.io",
    "save_library": "rockscan.io",
    "default_library": "rockscan.io",
    "default_spec_path": "rockscan.io",
}

#: The layers, reachable as ``rockscan.<name>``; see the README's Development section.
_MODULES = ("core", "io", "draw", "run", "cli")

__all__ = [*sorted(_API), "__version__"]


def __getattr__(name: str) -> Any:
    if name in _MODULES:
        return importlib.import_module(f"rockscan.{name}")
    module = _API.get(name)
    if module is None:
        raise AttributeError(f"module 'rockscan' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return __all__
