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

__version__ = "0.1.0"

_API = {
    # errors
    "RockscanError": "rockscan.errors",
    "ParameterError": "rockscan.errors",
    "ImageReadError": "rockscan.errors",
    "NoRockFoundError": "rockscan.errors",
    "LibraryError": "rockscan.errors",
    "SpecError": "rockscan.errors",
    # shapes and radii
    "SuperformulaParams": "rockscan.superformula",
    "polar_angles": "rockscan.polar",
    "contour_radii": "rockscan.polar",
    "symmetry_order": "rockscan.polar",
    "rotate_radii": "rockscan.polar",
    "recenter_radii": "rockscan.polar",
    # faces, eigenfaces, libraries, matching
    "FaceConfig": "rockscan.information",
    "information_face": "rockscan.information",
    "EigenBasis": "rockscan.eigen",
    "ShapeSpec": "rockscan.library",
    "Library": "rockscan.library",
    "shape_radii": "rockscan.library",
    "MatchConfig": "rockscan.match",
    "Match": "rockscan.match",
    "match_radii": "rockscan.match",
    "rotation_scores": "rockscan.match",
    # growing libraries
    "FitConfig": "rockscan.fit",
    "FitResult": "rockscan.fit",
    "fit_superformula": "rockscan.fit",
    "family": "rockscan.fit",
    # photos
    "SegmentConfig": "rockscan.segment",
    "trace_outline": "rockscan.outline",
    "ClassifyConfig": "rockscan.pipeline",
    "classify_image": "rockscan.pipeline",
    "classify_path": "rockscan.pipeline",
    "measure_rocks": "rockscan.pipeline",
    "library_from_spec": "rockscan.pipeline",
    "RenderConfig": "rockscan.render",
    "render_photo": "rockscan.render",
    "render_scene": "rockscan.render",
    "random_superformula": "rockscan.render",
    # folders
    "TriageConfig": "rockscan.triage",
    "TriageSummary": "rockscan.triage",
    "triage_folder": "rockscan.triage",
    "find_photos": "rockscan.triage",
    "NoveltyConfig": "rockscan.novelty",
    "ObservedShapes": "rockscan.novelty",
    "read_rows": "rockscan.report",
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

#: The stages and edges, reachable as ``rockscan.<name>`` (e.g. ``rockscan.segment.segment``).
_MODULES = (
    "errors",
    "superformula",
    "polar",
    "information",
    "eigen",
    "library",
    "match",
    "segment",
    "outline",
    "pipeline",
    "render",
    "io",
    "plot",
    "fit",
    "triage",
    "novelty",
    "report",
    "baselines",
)

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
