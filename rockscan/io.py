"""File readers and writers: library specs (TOML), library files (.npz), photos.

This is the only module that touches the file system for the core pipeline;
every stage takes and returns arrays.

Library files are numpy ``.npz`` archives read with ``allow_pickle=False``:
plain arrays plus a UTF-8 JSON ``metadata`` record that names the format and
its version. Anything else is rejected with a one-line :class:`LibraryError`.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import tomllib
import warnings
import zipfile
import zlib
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from rockscan import __version__
from rockscan._npzsafe import SafeNpz
from rockscan.errors import LibraryError, ParameterError, SpecError
from rockscan.superformula import SuperformulaParams

if TYPE_CHECKING:
    from rockscan._imageio import ImageData
    from rockscan.information import FaceConfig
    from rockscan.library import Library, ShapeSpec

__all__ = [
    "IMAGE_SUFFIXES",
    "LIBRARY_FORMAT",
    "LIBRARY_VERSION",
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

LIBRARY_FORMAT = "rockscan-library"
LIBRARY_VERSION = 2
#: The first format version whose files say whether they carry cutoffs: every
#: version-2 file has a "calibration" record, null for a library saved without
#: them by design (an observed library: novelty has its own threshold).
_CALIBRATED_VERSION = 2
#: Photo file endings rockscan reads (lower case).
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp")

_ARRAYS = ("radii", "interest", "symmetry", "mean", "components", "eigenvalues", "weights")
#: Per-shape calibration arrays (absent from files written before cutoffs were stored).
_CUTOFF_ARRAYS = ("cutoffs", "cutoff_spacing", "cutoff_crowded", "cutoff_calibrated")
#: A large library's sensor metric (optional: made on first use when absent).
_SENSOR_ARRAYS = ("sensor_weights", "sensor_spectra", "sensor_norm_sq")
_SHAPE_KEYS = {"name", "interest", "images", *SuperformulaParams.names()}


# ---------------------------------------------------------------- specs


def read_spec(path: str | os.PathLike[str]) -> list[ShapeSpec]:
    """Read a library spec (TOML, ``[[shape]]`` tables; see the interface).

    Parameters
    ----------
    path : path-like

    Returns
    -------
    shapes : list of ShapeSpec
        Example image paths are made absolute, relative to the spec's folder.

    Raises
    ------
    SpecError
        On unreadable files, TOML errors, unknown keys or impossible shapes.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise SpecError(f"{path}: spec file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise SpecError(f"{path}: cannot read spec ({exc})") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SpecError(f"{path}: not valid TOML ({exc})") from None
    return parse_spec(data, base=path.parent, source=str(path))


def parse_spec(data: dict[str, object], *, base: Path | None = None, source: str = "spec") -> list[ShapeSpec]:
    """Turn parsed TOML (``{"shape": [{...}, ...]}``) into shapes; see :func:`read_spec`."""
    from rockscan.library import ShapeSpec

    shapes = data.get("shape")
    if not isinstance(shapes, list) or not shapes:
        raise SpecError(f"{source}: a spec needs [[shape]] tables (see the README)")
    out: list[ShapeSpec] = []
    seen: set[str] = set()
    for i, entry in enumerate(shapes, start=1):
        if not isinstance(entry, dict):
            raise SpecError(f"{source}: shape {i} is not a table")
        name = entry.get("name")
        where = f"{source}: shape {name!r}" if isinstance(name, str) else f"{source}: shape {i}"
        unknown = set(entry) - _SHAPE_KEYS
        if unknown:
            raise SpecError(f"{where}: unknown keys {', '.join(sorted(unknown))}")
        if isinstance(name, str) and name in seen:
            raise SpecError(f"{where}: the name is used twice")
        images = entry.get("images", ())
        if not isinstance(images, (list, tuple)) or not all(isinstance(x, str) for x in images):
            raise SpecError(f"{where}: images must be a list of file paths")
        param_keys = set(SuperformulaParams.names()) & set(entry)
        try:
            params = None
            if param_keys or not images:
                missing = {"m1", "m2", "n1", "n2", "n3"} - set(entry)
                if missing:
                    raise SpecError(f"missing {', '.join(sorted(missing))}")
                params = SuperformulaParams(**{k: entry[k] for k in SuperformulaParams.names() if k in entry})
            paths = tuple(
                str((base / p) if base is not None and not Path(p).is_absolute() else p) for p in images
            )
            shape = ShapeSpec(name=name, params=params, interest=entry.get("interest", 1.0), images=paths)
        except (ParameterError, SpecError) as exc:
            raise SpecError(f"{where}: {exc}") from None
        seen.add(shape.name)
        out.append(shape)
    return out


def write_spec(shapes: Sequence[ShapeSpec], path: str | os.PathLike[str] | None = None) -> str:
    """Write shapes as a spec (TOML).

    Parameters
    ----------
    shapes : sequence of ShapeSpec
    path : path-like, optional
        File to write (atomically). None only returns the text.

    Returns
    -------
    text : str
        The spec, readable by :func:`read_spec`.
    """
    lines: list[str] = []
    for shape in shapes:
        lines.append("[[shape]]")
        lines.append(f'name = "{shape.name}"')
        if shape.params is not None:
            for key, value in shape.params.as_dict().items():
                lines.append(f"{key} = {_toml_float(value)}")
        if shape.images:
            listed = ", ".join(_toml_string(p) for p in shape.images)
            lines.append(f"images = [{listed}]")
        if shape.interest != 1.0:
            lines.append(f"interest = {_toml_float(shape.interest)}")
        lines.append("")
    text = "\n".join(lines)
    if path is not None:
        _atomic_write_bytes(Path(path), text.encode("utf-8"))
    return text


def _toml_string(text: str) -> str:
    """A TOML basic string. JSON's escapes are not TOML's: JSON writes a character
    beyond U+FFFF as a surrogate pair, which TOML refuses, and leaves U+007F bare."""
    out = []
    for ch in text:
        code = ord(ch)
        if ch in '"\\':
            out.append("\\" + ch)
        elif (code < 0x20 and ch != "\t") or code == 0x7F:
            out.append(f"\\u{code:04x}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def _toml_float(value: float) -> str:
    text = repr(float(value))
    return text if math.isfinite(value) else ("inf" if value > 0 else "-inf")


# ---------------------------------------------------------------- library files


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
    LibraryError
        If the file cannot be written.
    """
    metadata = {
        "format": LIBRARY_FORMAT,
        "version": LIBRARY_VERSION,
        "rockscan": __version__,
        "names": list(library.names),
        "params": [p.as_dict() if p is not None else None for p in library.params],
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
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise LibraryError(f"{path}: cannot write library ({exc.strerror or exc})") from None


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
    from rockscan.eigen import EigenBasis
    from rockscan.information import FaceConfig
    from rockscan.library import Library

    path = Path(path)
    if not path.exists():
        raise LibraryError(f"{path}: library file not found")
    if path.is_dir():
        raise LibraryError(f"{path}: is a folder, not a library file")
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
                raw = archive["metadata"]
                meta = _library_metadata(raw, path)
                archive.max_bytes = _budget(meta)
                arrays = {k: archive[k] for k in _ARRAYS}
                arrays.update({k: archive[k] for k in _CUTOFF_ARRAYS if k in archive.files})
                arrays.update({k: archive[k] for k in _SENSOR_ARRAYS if k in archive.files})
    except LibraryError:
        raise
    except (zipfile.BadZipFile, zlib.error, EOFError) as exc:
        raise LibraryError(f"{path}: library file is truncated or corrupt ({_first_line(exc)})") from None
    except (ValueError, OSError, AttributeError, KeyError) as exc:
        raise LibraryError(f"{path}: not a rockscan library file ({_first_line(exc)})") from None
    version = meta.get("version")
    if not isinstance(version, int) or version < 1:
        raise LibraryError(f"{path}: library metadata has no valid format version")
    if version > LIBRARY_VERSION:
        raise LibraryError(
            f"{path}: library format version {version} is newer than this rockscan reads "
            f"({LIBRARY_VERSION}); upgrade rockscan"
        )
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
    if library.calibration is None and version < _CALIBRATED_VERSION:
        from rockscan.calibrate import calibrate

        # A file from before cutoffs were stored: its shapes are all that is
        # needed to calibrate them as `library build` now does.
        warnings.warn(
            f"{path}: written before libraries stored their cutoffs; calibrated them now at the default "
            "tolerance (rebuild it with `rockscan library build` to store them)",
            RecalibratedWarning,
            stacklevel=2,
        )
        calibration = calibrate(library.radii)
        library = dataclasses.replace(
            library, calibration=dataclasses.replace(calibration, note="calibrated when loaded")
        )
    return library


def _budget(meta: dict[str, object]) -> int:
    """Bytes the arrays of a library file may take: ``MAX_ARCHIVE_BYTES``, and for a
    library of more than ``EXACT_LIMIT`` shapes what its per-shape arrays can take
    besides (about 8 KiB a shape at 360 rays)."""
    from rockscan import _npzsafe
    from rockscan.library import EXACT_LIMIT

    names, face = meta.get("names"), meta.get("face")
    n = len(names) if isinstance(names, list) else 0
    rays = face.get("n_angles") if isinstance(face, dict) else None
    rays = rays if isinstance(rays, int) and 0 < rays <= 1 << 16 else 360
    # Radii, sensor spectra (pairs of floats) and up to 256 coordinates, plus the per-shape scalars.
    per_shape = 8 * (rays + 2 * (rays // 2 + 1) + 256 + 8)
    return _npzsafe.MAX_ARCHIVE_BYTES + (n * per_shape if n > EXACT_LIMIT else 0)


def _sensor_arrays(library: Library, metadata: dict[str, object]) -> dict[str, NDArray]:
    """A large library's sensor metric, so that loading it need not remake it (optional fields)."""
    from rockscan.library import EXACT_LIMIT

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
    from rockscan.calibrate import SensorMetric

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


class RecalibratedWarning(UserWarning):
    """A library file without stored cutoffs was calibrated when it was loaded."""


def _read_calibration(meta: dict[str, object], arrays: dict[str, NDArray], path: Path) -> object:
    """The stored calibration, or None for a file written before cutoffs were stored."""
    from rockscan.calibrate import Calibration

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
    from rockscan.library import NAME_PATTERN

    names = meta.get("names")
    if not isinstance(names, list):
        raise LibraryError(f"{path}: library metadata has no list of shape names")
    for name in names:
        if not isinstance(name, str) or not NAME_PATTERN.match(name):
            raise LibraryError(f"{path}: shape name {name!r} must match [a-z0-9-]+")
    return tuple(names)


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
        return Path(__file__).resolve().parent.parent / "data" / name


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
    from rockscan.information import FaceConfig
    from rockscan.library import Library

    config = face_config or FaceConfig()
    key = (config.kind, config.grid, json.dumps(config.to_dict(), sort_keys=True))
    if key not in _DEFAULT_CACHE:
        _DEFAULT_CACHE[key] = Library.from_shapes(read_spec(default_spec_path()), face_config=config)
    return _DEFAULT_CACHE[key]


# ---------------------------------------------------------------- radii files


def read_radii(path: str | os.PathLike[str]) -> NDArray[np.float64]:
    """Read an outline given as radii: a text file of numbers (any whitespace or
    commas), or a ``.npy`` array, sampled at equal angles from theta = 0.

    Parameters
    ----------
    path : path-like

    Returns
    -------
    radii : (n,) ndarray of float

    Raises
    ------
    ParameterError
        If the file cannot be read or holds no usable radii.
    """
    path = Path(path)
    try:
        if path.suffix.lower() == ".npy":
            values = np.load(path, allow_pickle=False)
        else:
            text = path.read_text(encoding="utf-8").replace(",", " ")
            values = np.array([float(tok) for tok in text.split()])
    except FileNotFoundError:
        raise ParameterError(f"{path}: radii file not found") from None
    except (OSError, ValueError, UnicodeDecodeError) as exc:
        raise ParameterError(f"{path}: cannot read radii ({_first_line(exc)})") from None
    values = np.asarray(values, dtype=np.float64).ravel()
    if values.size < 8 or not np.all(np.isfinite(values)) or np.any(values < 0) or values.max() <= 0:
        raise ParameterError(f"{path}: radii must be at least 8 finite, non-negative numbers, not all zero")
    return values


# ---------------------------------------------------------------- photos


def read_image(path: str | os.PathLike[str], *, max_side: int | None = None) -> ImageData:
    """Read a photo: PNG, JPEG, TIFF or BMP; gray, RGB or RGBA; 8 or 16 bits.

    Parameters
    ----------
    path : path-like
    max_side : int, optional
        A photo whose longer side exceeds twice this is reduced while decoding
        by an integer factor ``k`` that keeps the longer side at least
        ``max_side``: a JPEG by the decoder itself (k = 2, 4 or 8, so an
        8000 x 8000 JPEG never exists in memory at full size), other formats
        by averaging k x k blocks as they leave the decoder. Reduced pixel
        ``i`` covers full pixels ``[i*k, (i+1)*k)``; ``scale = k`` maps back.

    Returns
    -------
    ImageData
        ``pixels`` as (rows, cols) or (rows, cols, 3|4) RGB(A), uint8 or uint16,
        turned upright by the EXIF orientation tag; ``scale``, ``full_shape``
        (upright) and ``bit_depth``. 16-bit photos keep their 16 bits, except a
        16-bit colour photo reduced while decoding that uses its range (see
        Notes).

    Raises
    ------
    ImageReadError
        If the file is missing, a folder, empty, truncated or corrupt, not a
        PNG, JPEG, TIFF or BMP, unreadable, or larger than 200 million pixels;
        the message is one line that starts with the path.
    ParameterError
        If ``max_side`` is not a positive number.

    Notes
    -----
    Peak memory beyond the reduced pixels, for a photo reduced while
    decoding: a JPEG about 1/64 of its full size; PNG, TIFF and BMP one full
    decode inside Pillow (4 bytes a pixel for colour, 1 or 2 for gray). Only
    OpenCV decodes 16-bit colour, at 12 bytes a pixel, so a reduced 16-bit
    colour photo is read through Pillow's 8 bits when it reaches 64 in them
    (a photo that uses its range loses nothing the reduced pixels keep), and
    through OpenCV only when it is darker and its 16 bits fit
    ``rockscan._imageio.MAX_DEEP_BYTES`` (512 MiB; docs/robustness.md).
    Decoders' own messages about a broken file are kept off standard error.
    """
    from rockscan._imageio import read_image as _read

    return _read(Path(path), max_side=max_side)


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__


def _atomic_write_bytes(path: Path, data: bytes) -> None:
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        tmp.write_bytes(data)
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise ParameterError(f"{path}: cannot write ({exc.strerror or exc})") from None
