"""Provenance of a triage report: everything that changes a row, recorded with the rows.

A report never mixes rows made with different settings: a run that would
continue a report compares its provenance first (:mod:`rockscan.io.report`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
from typing import TYPE_CHECKING, Any

import numpy as np

from rockscan.core.novelty import ObservedShapes

if TYPE_CHECKING:
    from rockscan.core.library import Library
    from rockscan.run.triage import TriageConfig


__all__ = ["library_hash", "novelty_weight", "report_provenance"]


def _jsonable(value: Any) -> Any:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _jsonable(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return _jsonable(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    return repr(value)


def library_hash(library: Library) -> str:
    """A content hash of a library: its shapes, not the file they came in.

    SHA-256 of the names, interests, symmetries, face settings, basis size and
    calibration tolerance (canonical JSON), and the radii and both calibrated cutoffs
    (at the tolerance and clean) as little-endian float64 rounded to 10 decimals. The basis itself (a BLAS
    result) is left out, so the hash is the same in every process and at every
    thread count; the same spec built twice, or saved and loaded, hashes the same.

    Parameters
    ----------
    library : Library

    Returns
    -------
    str
        64 hex digits.
    """
    meta = {
        "names": list(library.names),
        "interest": [float(v) for v in library.interest],
        "symmetry": [int(v) for v in library.symmetry],
        "face_config": _jsonable(library.face_config),
        "n_components": int(library.basis.n_components),
        "tolerance": float(library.tolerance),
    }
    digest = hashlib.sha256(json.dumps(meta, sort_keys=True, separators=(",", ":")).encode("utf-8"))
    digest.update(np.round(np.asarray(library.radii, dtype="<f8"), 10).tobytes())
    digest.update(np.round(np.asarray(library.cutoffs, dtype="<f8"), 10).tobytes())
    digest.update(np.round(np.asarray(library.calibration_in_force.clean_cutoffs, dtype="<f8"), 10).tobytes())
    return digest.hexdigest()


def report_provenance(
    library: Library,
    config: TriageConfig,
    novelty: ObservedShapes | None = None,
    *,
    folder: str | os.PathLike[str] | None = None,
    observed: str | os.PathLike[str] | None = None,
) -> dict[str, Any]:
    """How a triage report's rows are made: everything that changes a row.

    Parameters
    ----------
    library : Library
    config : TriageConfig
    novelty : ObservedShapes, optional
        The observed library at the start of the run (its threshold and metric
        are recorded; the shapes it gains during a run are not settings).
    folder : path-like, optional
        The folder of photos. Recorded as ``photos``: its absolute path, and
        for a folder given as a relative path the working folder the rows'
        paths are relative to, so that a resumed run neither adds another
        folder's photos nor gives the same photos again under other names.
    observed : path-like, optional
        The observed library's file, recorded (its real path) with the novelty
        settings: a run resumed with another file (a typing slip starts a new,
        empty one) called shapes novel that the first file had already seen.

    Returns
    -------
    dict
        ``rockscan`` (version), ``library`` (content hash, shapes, face kind),
        ``method`` (the matcher's metrics and scan), ``cutoffs`` (in force,
        defaults resolved), ``options`` (every rock, novelty, the interest
        rule's weight, other classify settings), ``segmentation`` (every
        segmentation setting), and ``photos`` when ``folder`` is given. JSON-able.
    """
    from rockscan._version import __version__

    match = config.classify.match
    classify = _jsonable(config.classify)
    classify.pop("match", None)
    segmentation = classify.pop("segment", None)
    options: dict[str, Any] = {"all_rocks": bool(config.all_rocks), **classify}
    if novelty is not None:
        options["novelty"] = {
            "metric": novelty.metric,
            "threshold": novelty.threshold,
            "file": None if observed is None else os.path.realpath(observed),
        }
        options["novelty_weight"] = novelty_weight(library, config)
    provenance: dict[str, Any] = {
        "rockscan": __version__,
        "library": {
            "sha256": library_hash(library),
            "shapes": len(library),
            "face": library.face_config.kind,
        },
        "method": {
            # As given: "auto" ranks a clean sample as "eigenspace" does and a noisy
            # one as "sensor" does, so it is neither, and rows of the two never mix.
            "metric": match.metric,
            "angle_metric": match.angle_metric,
            "scan": match.scan,
            "refine": match.refine,
        },
        "cutoffs": {
            # The per-shape cutoffs belong to the library (and to its hash); these
            # are the ones the user set on top of them (None: not in force).
            "tolerance": float(library.tolerance),
            "distance": match.distance_cutoff,
            "mscore": match.mscore_cutoff,
            "residual": match.residual_cutoff,
        },
        "options": options,
        "segmentation": segmentation,
    }
    if folder is not None:
        relative = not os.path.isabs(folder)
        provenance["photos"] = {
            "folder": os.path.abspath(folder),
            "relative_to": os.path.abspath(os.curdir) if relative else None,
        }
    return provenance


def novelty_weight(library: Library, config: TriageConfig) -> float:
    if config.novelty_weight is not None:
        return float(config.novelty_weight)
    return float(np.max(library.interest))
