"""Thumbnails for the triage contact sheet: a small picture of a photo with its
rock's outline and the matched library shape drawn on it, as a data URI.
"""

from __future__ import annotations

import base64
import io
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from rockscan.core.library import Library
    from rockscan.run.pipeline import RockResult

__all__ = ["THUMBNAIL_QUALITY", "thumbnail_data_uri", "thumbnail_data_uris"]


def thumbnail_data_uri(path: str, rock: RockResult | None, library: Library, size: int = 144) -> str:
    """A small WebP (or JPEG) of a photo with the rock's outline and the matched
    library shape (turned by the found angle) drawn on it.

    Parameters
    ----------
    path : str
        The photo.
    rock : RockResult or None
        Its main rock; None draws the photo alone.
    library : Library
    size : int
        Longer side of the thumbnail, pixels (a smaller photo is not enlarged).

    Returns
    -------
    str
        ``data:image/webp;base64,...`` (JPEG where Pillow has no WebP).

    Raises
    ------
    ImageReadError
        If the photo cannot be read.
    """
    return thumbnail_data_uris(path, (rock,), library, size)[0]


#: WebP quality of thumbnails: about 3 kB each at 144 pixels on textured ground,
#: half a JPEG's (a 2,000-rock sheet stays under 10 MB; scripts/bench_report_size.py
#: measures it).
THUMBNAIL_QUALITY = 50


def thumbnail_data_uris(
    path: str, rocks: tuple[RockResult | None, ...], library: Library, size: int = 144
) -> list[str]:
    """Thumbnails of one photo, one per rock (the photo is read once).

    The outline is drawn in :data:`rockscan.draw.sheet.OUTLINE_RGB` (yellow)
    over the matched shape in :data:`rockscan.draw.sheet.SHAPE_RGB` (blue),
    wider, so that both show where they agree. WebP halves colour resolution;
    its sharp colour conversion and the lines' wide gap in lightness keep them
    apart (tests/test_report_html.py measures it).

    Parameters
    ----------
    path : str
    rocks : tuple of RockResult or None
    library : Library
    size : int

    Returns
    -------
    list of str
        Data URIs, one per rock.

    Raises
    ------
    ImageReadError
        If the photo cannot be read.
    """
    import cv2
    from PIL import Image, features

    from rockscan.draw.plot import library_outline_rowcol
    from rockscan.draw.sheet import OUTLINE_RGB, SHAPE_RGB
    from rockscan.io import read_image

    image = read_image(path, max_side=2 * size)
    pixels = _rgb8(image.pixels)
    rows, cols = pixels.shape[:2]
    factor = min(1.0, size / max(rows, cols))
    out_size = (max(1, round(cols * factor)), max(1, round(rows * factor)))
    base = cv2.resize(pixels, out_size, interpolation=cv2.INTER_AREA) if factor < 1 else pixels
    full_rows, full_cols = image.full_shape
    per_row, per_col = full_rows / base.shape[0], full_cols / base.shape[1]

    def points(rowcol: NDArray[np.float64]) -> NDArray[np.int32]:
        # Full-resolution pixel centres to thumbnail pixels, 4 fractional bits.
        col = (rowcol[:, 1] + 0.5) / per_col - 0.5
        row = (rowcol[:, 0] + 0.5) / per_row - 0.5
        return np.round(np.column_stack([col, row]) * 16).astype(np.int32)

    webp = features.check("webp")
    out = []
    for rock in rocks:
        thumb = base.copy()
        if rock is not None:
            matched = points(library_outline_rowcol(library, rock))
            # Two pixels at least: WebP keeps colour at half resolution.
            cv2.polylines(thumb, [matched], True, SHAPE_RGB, 3, cv2.LINE_AA, 4)
            cv2.polylines(thumb, [points(rock.outline.contour_rowcol)], True, OUTLINE_RGB, 2, cv2.LINE_AA, 4)
            ((cx, cy),) = points(rock.outline.centroid_rowcol[None, :]) // 16
            cv2.drawMarker(thumb, (int(cx), int(cy)), SHAPE_RGB, cv2.MARKER_CROSS, 8, 2)
        buf = io.BytesIO()
        if webp:
            Image.fromarray(thumb).save(buf, format="WEBP", quality=THUMBNAIL_QUALITY, use_sharp_yuv=True)
        else:
            Image.fromarray(thumb).save(buf, format="JPEG", quality=THUMBNAIL_QUALITY, subsampling=0)
        kind = "webp" if webp else "jpeg"
        out.append(f"data:image/{kind};base64," + base64.b64encode(buf.getvalue()).decode("ascii"))
    return out


def _rgb8(pixels: NDArray[np.generic]) -> NDArray[np.uint8]:
    arr = np.asarray(pixels)
    if arr.dtype == np.uint16:
        arr = (arr >> 8).astype(np.uint8)
    elif arr.dtype != np.uint8:
        arr = np.clip(arr, 0, 255).astype(np.uint8)
    if arr.ndim == 2:
        arr = np.repeat(arr[..., None], 3, axis=2)
    return np.ascontiguousarray(arr[..., :3])
