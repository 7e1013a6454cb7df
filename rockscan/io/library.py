"""Library files: numpy ``.npz`` archives read with ``allow_pickle=False``.

Plain arrays plus a UTF-8 JSON ``metadata`` record that names the format and
its version. Anything else is rejected with a one-line :class:`LibraryError`.
Archives are read through :mod:`rockscan.io._npzsafe`, which checks every
member's size before anything is inflated.
"""

from __future__ import annotations

import dataclasses
import json
import os
import warnings
import zipfile
import zlib
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from rockscan._version import __version__
from rockscan.core.errors import LibraryError, ParameterError, WriteError
from rockscan.core.superformula import SuperformulaParams
from rockscan.io._npzsafe import SafeNpz

if TYPE_CHECKING:
    from rockscan.core.library import Library

from rockscan.core.errors import first_line as _first_line
from rockscan.io.atomic import atomic_file

LIBRARY_FORMAT = "rockscan-library"
LIBRARY_VERSION = 2
#: The first format version whose files say whether they carry cutoffs: every
#: version-2 file has a "calibration" record, null for a library saved without
#: them by design (an observed library: novelty has its own threshold).
_CALIBRATED_VERSION = 2

_ARRAYS = ("radii", "interest", "symmetry", "mean", "components", "eigenvalues", "weights")
#: Per-shape calibration arrays (absent from files written before cutoffs were stored).
_CUTOFF_ARRAYS = ("cutoffs", "cutoff_spacing", "cutoff_crowded", "cutoff_calibrated")
#: Stored since calibration version 2 (the cutoff of a sample without noise of its own).
_CLEAN_CUTOFFS = "cutoff_clean"
#: A large library's sensor metric (optional: made on first use when absent).
_SENSOR_ARRAYS = ("sensor_weights", "sensor_spectra", "sensor_norm_sq")
_PARAM_NAMES = SuperformulaParams.names()


def save_library(library: Library, path: str | os.PathLike[str]) -> None:
    """Write a library file (``.npz`` with JSON metadata; no pickle).

    Parameters
    ----------
    library : Library
    path : path-like
        File to write. It is written to a temporary name and renamed, so an
        interrupted save never leaves a half-written library behind.

    Raises
    ------
    WriteError
        If the file cannot be written.
    TypeError
        If ``library`` is not a :class:`Library`.
    """
    from rockscan.core.match import require_library

    require_library(library)
    metadata = {
        "format": LIBRARY_FORMAT,
        "version": LIBRARY_VERSION,
        "rockscan": __version__,
        "names": list(library.names),
        "params": [_params_dict(p) for p in library.params],
        "face": library.face_config.to_dict(),
    }
    cutoff_arrays = {}
    metadata["calibration"] = None
    if library.calibration is not None:
        cal = library.calibration
        metadata["calibration"] = cal.to_dict()
        cutoff_arrays = dict(
            zip(_CUTOFF_ARRAYS, (cal.cutoffs, cal.spacing, cal.crowded, cal.calibrated), strict=True)
        )
        cutoff_arrays[_CLEAN_CUTOFFS] = cal.clean_cutoffs
    sensor_arrays = _sensor_arrays(library, metadata)  # adds its record to the metadata
    arrays = {
        "metadata": np.frombuffer(json.dumps(metadata).encode("utf-8"), dtype=np.uint8),
        "radii": library.radii,
        "interest": library.interest,
        "symmetry": library.symmetry,
        "mean": library.basis.mean,
        "components": library.basis.components,
        "eigenvalues": library.basis.eigenvalues,
        "weights": library.basis.weights,
        **cutoff_arrays,
        **sensor_arrays,
    }
    # Refused here rather than written and then refused by load_library.
    size = sum(np.asarray(a).nbytes + _NPY_HEADER for a in arrays.values())
    if size > (budget := _budget(metadata)):
        raise WriteError(
            f"{path}: the library would take {size:,} bytes, past the {budget:,} a library file may hold "
            "(fewer rays, coarser sections or fewer shapes)"
        )
    with atomic_file(path, what="library") as fh:
        np.savez(fh, **arrays)


#: Bytes of an ``.npy`` member's header, at most (numpy writes 128).
_NPY_HEADER = 128


def _params_dict(params: SuperformulaParams | None) -> dict[str, float] | None:
    """``params.as_dict()``: the same dictionary, without dataclasses.asdict's deep copy
    (a third of a second for 10,000 shapes)."""
    return None if params is None else {name: getattr(params, name) for name in _PARAM_NAMES}


def load_library(path: str | os.PathLike[str]) -> Library:
    """Read a library file written by :func:`save_library`.

    Parameters
    ----------
    path : path-like

    Returns
    -------
    Library

    Raises
    ------
    LibraryError
        With a one-line reason if the file is missing, truncated, corrupt,
        not a rockscan library, of a newer format version, or inconsistent.
    """
    path = Path(path)
    if not path.exists():
        raise LibraryError(f"{path}: library file not found")
    if path.is_dir():
        raise LibraryError(f"{path}: is a folder, not a library file")
    meta, arrays = _read_archive(path)
    version = meta.get("version")
    if not isinstance(version, int) or version < 1:
        raise LibraryError(f"{path}: library metadata has no valid format version")
    if version > LIBRARY_VERSION:
        raise LibraryError(
            f"{path}: library format version {version} is newer than this rockscan reads "
            f"({LIBRARY_VERSION}); upgrade rockscan"
        )
    library = _library_from(meta, arrays, path)
    return _recalibrated(library, version, path)


def _read_archive(path: Path) -> tuple[dict[str, object], dict[str, NDArray]]:
    """The metadata and the arrays of a library file, each checked before it is inflated."""
    try:
        with open(path, "rb") as fh:
            magic = fh.read(6)
            if not magic:
                raise LibraryError(f"{path}: file is empty, not a rockscan library")
            if magic.startswith(b"\x93NUMPY"):
                raise LibraryError(
                    f"{path}: not a rockscan library (a bare numpy array, not an .npz archive)"
                )
            if not magic.startswith(b"PK"):
                raise LibraryError(f"{path}: not a rockscan library (not an .npz archive)")
            fh.seek(0)
            with SafeNpz(fh, str(path)) as archive:
                missing = [k for k in ("metadata", *_ARRAYS) if k not in archive.files]
                if missing:
                    raise LibraryError(f"{path}: not a rockscan library (missing {', '.join(missing)})")
                meta = _library_metadata(archive["metadata"], path)
                archive.max_bytes = _budget(meta)
                arrays = {k: archive[k] for k in _ARRAYS}
                stored = (*_CUTOFF_ARRAYS, _CLEAN_CUTOFFS, *_SENSOR_ARRAYS)
                arrays.update({k: archive[k] for k in stored if k in archive.files})
    except LibraryError:
        raise
    except (zipfile.BadZipFile, zlib.error, EOFError) as exc:
        raise LibraryError(f"{path}: library file is truncated or corrupt ({_first_line(exc)})") from None
    except (ValueError, OSError, AttributeError, KeyError) as exc:
        raise LibraryError(f"{path}: not a rockscan library file ({_first_line(exc)})") from None
    return meta, arrays


def _library_from(meta: dict[str, object], arrays: dict[str, NDArray], path: Path) -> Library:
    """The library a file's metadata and arrays describe, or a one-line LibraryError."""
    from rockscan.core.eigen import EigenBasis
    from rockscan.core.information import FaceConfig
    from rockscan.core.library import Library

    try:
        params = [SuperformulaParams(**p) if p is not None else None for p in meta["params"]]
        face = FaceConfig.from_dict(meta["face"])
        basis = EigenBasis(
            mean=arrays["mean"],
            components=arrays["components"],
            eigenvalues=arrays["eigenvalues"],
            weights=arrays["weights"],
        )
        for name in ("mean", "components", "weights"):
            if not np.all(np.isfinite(getattr(basis, name))):
                raise LibraryError(f"library {name} holds non-finite values")
        library = Library(
            names=_library_names(meta, path),
            radii=arrays["radii"],
            params=tuple(params),
            interest=arrays["interest"],
            symmetry=arrays["symmetry"],
            face_config=face,
            basis=basis,
            calibration=_read_calibration(meta, arrays, path),
        )
        _attach_sensor_metric(library, meta, arrays)
    except ParameterError as exc:
        raise LibraryError(f"{path}: library cutoffs are inconsistent ({_first_line(exc)})") from None
    except (KeyError, TypeError, ValueError, OverflowError) as exc:
        raise LibraryError(f"{path}: library file is inconsistent ({_first_line(exc)})") from None
    return library


def check_library_size(n_shapes: int, face_shape: tuple[int, ...], n_components: int | None = None) -> None:
    """Refuse, before a library is built, one whose file would be past its budget.

    The file holds at least the eigenfaces and their mean, ``face_shape``
    floats each: known from the options alone, where building
    the library first would take many times as much memory (a resolution of
    1e-5 took 20 GB) only to be refused by :func:`save_library`.

    Raises
    ------
    ParameterError
        If those arrays alone are past the budget.
    """
    from rockscan.core.errors import ParameterError

    face = int(np.prod(face_shape))
    # A basis of n centred faces has at most n - 1 eigenfaces.
    kept = max(0, n_shapes - 1) if n_components is None else min(n_components, max(0, n_shapes - 1))
    size = 8 * face * (kept + 1)
    budget = _budget({"names": [""] * n_shapes, "face": {"n_angles": int(face_shape[0])}})
    if size > budget:
        raise ParameterError(
            f"the library would take at least {size:,} bytes, past the {budget:,} a library file may hold "
            f"(a face of {' x '.join(map(str, face_shape))}: fewer rays, coarser sections or fewer shapes)"
        )


def _budget(meta: dict[str, object]) -> int:
    """Bytes the arrays of a library file may take: ``MAX_ARCHIVE_BYTES``, and for a
    library of more than ``EXACT_LIMIT`` shapes what its per-shape arrays can take
    besides (about 8 KiB a shape at 360 rays)."""
    from rockscan.core.library import EXACT_LIMIT
    from rockscan.io import _npzsafe

    names, face = meta.get("names"), meta.get("face")
    n = len(names) if isinstance(names, list) else 0
    rays = face.get("n_angles") if isinstance(face, dict) else None
    rays = rays if isinstance(rays, int) and 0 < rays <= 1 << 16 else 360
    # Radii, sensor spectra (pairs of floats) and up to 256 coordinates, plus the per-shape scalars.
    per_shape = 8 * (rays + 2 * (rays // 2 + 1) + 256 + 8)
    return _npzsafe.MAX_ARCHIVE_BYTES + (n * per_shape if n > EXACT_LIMIT else 0)


def _sensor_arrays(library: Library, metadata: dict[str, object]) -> dict[str, NDArray]:
    """A large library's sensor metric, so that loading it need not remake it (optional fields)."""
    from rockscan.core.library import EXACT_LIMIT

    if len(library) <= EXACT_LIMIT:
        return {}
    metric = library.sensor_metric
    metadata["sensor"] = {
        "tolerance": metric.tolerance,
        "noise_band": list(metric.noise_band),
        "noise_gain": metric.noise_gain,
        "noise_floor": metric.noise_floor,
    }
    # Complex numbers as pairs of floats: library files hold real arrays only.
    spectra = np.ascontiguousarray(metric.spectra, dtype=np.complex128).view(np.float64)
    return dict(zip(_SENSOR_ARRAYS, (metric.weights, spectra, metric.norm_sq), strict=True))


def _attach_sensor_metric(library: Library, meta: dict[str, object], arrays: dict[str, NDArray]) -> None:
    """The stored sensor metric, when the file has one (files without it make it on first use)."""
    from rockscan.core.calibrate import SensorMetric

    sensor = meta.get("sensor")
    if not isinstance(sensor, dict) or any(k not in arrays for k in _SENSOR_ARRAYS):
        return
    weights, pairs, norm_sq = (np.asarray(arrays[k]) for k in _SENSOR_ARRAYS)
    n_freq = library.face_config.n_angles // 2 + 1
    if pairs.shape != (len(library), 2 * n_freq) or pairs.dtype != np.float64:
        raise ValueError("its sensor metric does not fit its shapes")
    spectra = np.ascontiguousarray(pairs).view(np.complex128)
    if (
        weights.shape != (n_freq,)
        or spectra.shape != (len(library), n_freq)
        or norm_sq.shape != (len(library),)
        or not all(np.all(np.isfinite(a)) for a in (weights, spectra, norm_sq))
    ):
        raise ValueError("its sensor metric does not fit its shapes")
    lo, hi = (int(v) for v in sensor["noise_band"])
    metric = SensorMetric(
        weights=weights.astype(np.float64),
        spectra=spectra.astype(np.complex128),
        norm_sq=norm_sq.astype(np.float64),
        tolerance=float(sensor["tolerance"]),
        noise_band=(lo, hi),
        noise_gain=float(sensor["noise_gain"]),
        noise_floor=float(sensor["noise_floor"]),
    )
    if metric.tolerance == library.tolerance:  # else made anew for the library's tolerance
        object.__setattr__(library, "sensor_metric", metric)


def _recalibrated(library: Library, version: int, path: Path) -> Library:
    """The library with cutoffs of the current calibration: those it stores, or
    calibrated now (with a RecalibratedWarning) for a file that has none or whose
    cutoffs come from an earlier calibration."""
    from rockscan.core.calibrate import CALIBRATION_VERSION, calibrate
    from rockscan.core.library import noise_origins

    stored = library.calibration
    if stored is None and version < _CALIBRATED_VERSION:
        # A file from before cutoffs were stored: its shapes are all that is
        # needed to calibrate them as `library build` now does.
        message = (
            f"{path}: written before libraries stored their cutoffs; calibrated them now at the default "
            "tolerance (rebuild it with `rockscan library build` to store them)"
        )
        settings: dict[str, object] = {}
    elif stored is not None and stored.version < CALIBRATION_VERSION:
        # Cutoffs of an earlier calibration mean another test: recalibrated at the stored tolerance.
        message = (
            f"{path}: its cutoffs come from an earlier calibration (version {stored.version}); calibrated "
            f"them now at its tolerance {stored.tolerance:g} (rebuild it with `rockscan library build` "
            "to store them)"
        )
        settings = {"tolerance": stored.tolerance, "seed": stored.seed}
    else:
        return library
    warnings.warn(message, RecalibratedWarning, stacklevel=3)
    calibration = calibrate(library.radii, origins=noise_origins(library.params, library.radii), **settings)
    return dataclasses.replace(
        library, calibration=dataclasses.replace(calibration, note="calibrated when loaded")
    )


class RecalibratedWarning(UserWarning):
    """A library file without stored cutoffs was calibrated when it was loaded."""


def _read_calibration(meta: dict[str, object], arrays: dict[str, NDArray], path: Path) -> object:
    """The stored calibration, or None for a file written before cutoffs were stored."""
    from rockscan.core.calibrate import Calibration

    info = meta.get("calibration")
    if info is None:
        return None
    missing = [k for k in _CUTOFF_ARRAYS if k not in arrays]
    if not isinstance(info, dict) or missing:
        what = ", ".join(missing) or "settings"
        raise LibraryError(f"{path}: library cutoffs are incomplete (missing {what})")
    return Calibration(
        cutoffs=arrays["cutoffs"],
        spacing=arrays["cutoff_spacing"],
        crowded=arrays["cutoff_crowded"],
        calibrated=arrays["cutoff_calibrated"],
        clean_cutoffs=arrays[_CLEAN_CUTOFFS] if _CLEAN_CUTOFFS in arrays else None,
        tolerance=float(info["tolerance"]),
        seed=int(info.get("seed", 0)),
        version=int(info.get("version", 1)),
        note=str(info.get("note", "")),
    )


def _library_metadata(raw: object, path: Path) -> dict[str, object]:
    """The metadata record of a library file, checked to be a JSON object of the format."""
    if not isinstance(raw, np.ndarray) or raw.dtype != np.uint8 or raw.ndim != 1:
        raise LibraryError(f"{path}: not a rockscan library (bad metadata record)")
    try:
        meta = json.loads(raw.tobytes().decode("utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError):
        raise LibraryError(f"{path}: library metadata is corrupt") from None
    if not isinstance(meta, dict):
        raise LibraryError(f"{path}: not a rockscan library (metadata is not a JSON object)")
    if meta.get("format") != LIBRARY_FORMAT:
        raise LibraryError(f"{path}: not a rockscan library (format is {meta.get('format')!r})")
    return meta


def _library_names(meta: dict[str, object], path: Path) -> tuple[str, ...]:
    """Shape names of a library file, held to the rule spec names follow."""
    from rockscan.core.library import NAME_PATTERN

    names = meta.get("names")
    if not isinstance(names, list):
        raise LibraryError(f"{path}: library metadata has no list of shape names")
    for name in names:
        if not isinstance(name, str) or not NAME_PATTERN.match(name):
            raise LibraryError(f"{path}: shape name {name!r} must match [a-z0-9-]+")
    return tuple(names)


def append_pending(path: str | os.PathLike[str] | None, name: str, radii: NDArray[np.float64]) -> None:
    """Append one shape an observed library has gained to its pending file.

    One JSON line (``{"name": ..., "radii": [...]}``, the radii exact) in one
    unbuffered write: a run killed before it writes the library whole keeps the
    shapes it found, and a torn last line is dropped when read.

    Parameters
    ----------
    path : path-like or None
        The pending file (None: nothing to keep).
    name : str
    radii : (n_angles,) ndarray of float

    Raises
    ------
    WriteError
        If the file cannot be written.
    """
    if path is None:
        return
    line = json.dumps({"name": name, "radii": [float(r) for r in radii]}) + "\n"
    try:
        with open(path, "ab", buffering=0) as fh:
            fh.write(line.encode("utf-8"))
    except OSError as exc:
        raise WriteError(f"{path}: cannot write the observed shapes ({exc.strerror or exc})") from None


def read_pending(path: str | os.PathLike[str] | None) -> list[tuple[str, NDArray[np.float64]]]:
    """The shapes of a pending file, in the order they were found (see :func:`append_pending`).

    A missing file is no shapes; a line that is not a whole record (a write cut
    short) is skipped.
    """
    if path is None or not os.path.exists(path):
        return []
    shapes = []
    with open(path, "rb") as fh:
        for line in fh:
            try:
                record = json.loads(line)
                shapes.append((str(record["name"]), np.asarray(record["radii"], dtype=np.float64)))
            except (ValueError, KeyError, TypeError):
                continue
    return shapes
