"""Photo decoding for :func:`rockscan.io.read_image` (Pillow underneath).

Pillow reads every format the interface names, reports truncated files as
errors instead of returning half an image, and gives the EXIF orientation.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from rockscan.errors import ImageReadError

__all__ = ["MAX_PIXELS", "ImageData", "read_image"]

#: Largest photo read, in pixels (a 16000 x 12500 frame); larger files are refused
#: rather than exhausting memory.
MAX_PIXELS = 200_000_000
_FORMATS = {"PNG", "JPEG", "MPO", "TIFF", "BMP", "DIB"}


@dataclass(frozen=True, eq=False)
class ImageData:
    """A decoded photo.

    Attributes
    ----------
    pixels : (rows, cols) or (rows, cols, 3|4) ndarray of uint8 or uint16
        Upright (EXIF orientation applied), RGB(A) order.
    scale : float
        Full-resolution pixels per returned pixel (1 unless decoded reduced).
    full_shape : tuple of int
        (rows, cols) of the upright photo at full resolution.
    """

    pixels: NDArray[np.generic]
    scale: float
    full_shape: tuple[int, int]


def read_image(path: Path, *, max_side: int | None = None) -> ImageData:
    """See :func:`rockscan.io.read_image`."""
    from PIL import Image, UnidentifiedImageError

    if not path.exists():
        raise ImageReadError(f"{path}: file not found")
    if path.is_dir():
        raise ImageReadError(f"{path}: is a folder, not a photo")
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise ImageReadError(f"{path}: cannot read ({exc.strerror or exc})") from None
    if size == 0:
        raise ImageReadError(f"{path}: file is empty")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", Image.DecompressionBombWarning)
            Image.MAX_IMAGE_PIXELS = MAX_PIXELS
            with Image.open(path) as im:
                if im.format not in _FORMATS:
                    raise ImageReadError(
                        f"{path}: {im.format} images are not supported (use PNG, JPEG, TIFF or BMP)"
                    )
                orientation = _orientation(im)
                full_cols, full_rows = im.size
                scale = 1.0
                if max_side and im.format in {"JPEG", "MPO"} and max(im.size) > 2 * max_side:
                    im.draft(
                        im.mode,
                        (
                            max(1, full_cols * max_side // max(im.size)),
                            max(1, full_rows * max_side // max(im.size)),
                        ),
                    )
                    scale = full_cols / im.size[0]
                im.load()
                pixels = _to_array(im, path)
    except ImageReadError:
        raise
    except (Image.DecompressionBombError, Image.DecompressionBombWarning):
        raise ImageReadError(f"{path}: photo is larger than {MAX_PIXELS:,} pixels") from None
    except UnidentifiedImageError:
        raise ImageReadError(f"{path}: not a supported image (PNG, JPEG, TIFF or BMP)") from None
    except (OSError, SyntaxError, ValueError, EOFError) as exc:
        text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise ImageReadError(f"{path}: image is truncated or corrupt ({text})") from None
    except MemoryError:
        raise ImageReadError(f"{path}: not enough memory to decode this photo") from None
    pixels = _apply_orientation(pixels, orientation)
    if orientation in (5, 6, 7, 8):
        full_rows, full_cols = full_cols, full_rows
    if pixels.size == 0 or min(pixels.shape[:2]) < 1:
        raise ImageReadError(f"{path}: image has no pixels")
    return ImageData(pixels=pixels, scale=scale, full_shape=(full_rows, full_cols))


def _orientation(im: object) -> int:
    try:
        value = im.getexif().get(0x0112, 1)  # type: ignore[attr-defined]
        return int(value) if int(value) in range(1, 9) else 1
    except Exception:  # a broken EXIF block must not cost the photo
        return 1


def _to_array(im: object, path: Path) -> NDArray[np.generic]:
    from PIL import Image

    assert isinstance(im, Image.Image)
    mode = im.mode
    if mode in {"L", "RGB", "RGBA"}:
        return np.asarray(im)
    if mode in {"I;16", "I;16B", "I;16L", "I;16N"}:
        return np.asarray(im).astype(np.uint16, copy=False)
    if mode in {"I", "F"}:
        arr = np.asarray(im).astype(np.float64)
        if not np.all(np.isfinite(arr)):
            raise ImageReadError(f"{path}: image holds non-finite values")
        lo, hi = float(arr.min()), float(arr.max())
        if lo >= 0 and hi <= 65535 and mode == "I":
            return arr.astype(np.uint16)
        return np.round((arr - lo) / (hi - lo if hi > lo else 1.0) * 65535).astype(np.uint16)
    if mode == "1":
        return np.asarray(im.convert("L"))
    if mode in {"LA", "PA", "P", "RGBa", "La"} or "transparency" in im.info:
        return np.asarray(im.convert("RGBA"))
    return np.asarray(im.convert("RGB"))


def _apply_orientation(pixels: NDArray[np.generic], orientation: int) -> NDArray[np.generic]:
    """Turn pixels upright per the EXIF orientation tag (values 1-8)."""
    ops = {
        1: lambda a: a,
        2: lambda a: a[:, ::-1],
        3: lambda a: a[::-1, ::-1],
        4: lambda a: a[::-1, :],
        5: lambda a: np.swapaxes(a, 0, 1),
        6: lambda a: np.swapaxes(a, 0, 1)[:, ::-1],
        7: lambda a: np.swapaxes(a, 0, 1)[::-1, ::-1],
        8: lambda a: np.swapaxes(a, 0, 1)[::-1, :],
    }
    return np.ascontiguousarray(ops[orientation](pixels))
