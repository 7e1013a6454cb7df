"""Photo decoding for :func:`rockscan.io.read_image` (Pillow, and OpenCV for deep colour).

Pillow reads every format the interface names, reports truncated files as
errors instead of returning half an image, and gives the EXIF orientation.
Pillow keeps only 8 bits of a 16-bit colour photo, so those are decoded again by
OpenCV once Pillow has checked the file whole (OpenCV would print its decoder's
complaints about a broken file to the terminal instead of raising). Pillow
cannot read a colour TIFF of 32-bit integer or floating-point samples at all:
OpenCV decodes those, with its messages kept quiet, and they are scaled to 16
bits over their range as Pillow's gray ones are.

Large photos are reduced while decoding, by an integer factor ``k``: JPEG by
the decoder's DCT scaling, other formats by averaging ``k x k`` blocks. Reduced
pixel ``i`` then covers full-resolution pixels ``[i*k, (i+1)*k)`` exactly in
both axes, so one number, ``scale = k``, maps every position back.
"""

from __future__ import annotations

import contextlib
import logging
import os
import struct
import sys
import warnings
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from rockscan.core.errors import ImageReadError, ParameterError
from rockscan.core.errors import first_line as _first_line

_log = logging.getLogger(__name__)

if TYPE_CHECKING:
    from PIL import Image

    from rockscan.core.render import RenderedPhoto

__all__ = ["IMAGE_SUFFIXES", "MAX_DEEP_BYTES", "MAX_PIXELS", "ImageData", "read_image", "write_photo"]

#: Photo file endings rockscan reads (lower case).
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".jpe", ".jfif", ".tif", ".tiff", ".bmp")

#: Largest photo read, in pixels (a 16000 x 12500 frame); larger files are refused
#: rather than exhausting memory.
MAX_PIXELS = 200_000_000
_FORMATS = {"PNG", "JPEG", "MPO", "TIFF", "BMP", "DIB"}
_SUPPORTED = "PNG, JPEG, TIFF or BMP"
#: A 16-bit colour photo whose 8-bit rendering stays below this level is dark:
#: its 16 bits are kept even when that costs memory (see read_image).
_DARK_8BIT = 64
#: Most bytes a 16-bit colour decode may take (OpenCV decodes the whole frame);
#: a larger photo is read at Pillow's 8 bits (a 16-bit RGB frame of 6,600 x
#: 6,600 pixels fits).
MAX_DEEP_BYTES = 512 * 2**20
#: Reducing while decoding keeps the shorter side at least this many pixels.
_MIN_SIDE = 8
# Errors Pillow's decoders raise on broken files; anything they raise is the
# file's fault, not a bug of the caller (a TIFF tag of the wrong type raises
# TypeError as the pixels load).
_DECODE_ERRORS = (
    OSError,
    SyntaxError,
    ValueError,
    EOFError,
    struct.error,
    zlib.error,
    IndexError,
    KeyError,
    TypeError,
)


@dataclass(frozen=True, eq=False)
class ImageData:
    """A decoded photo.

    Attributes
    ----------
    pixels : (rows, cols) or (rows, cols, 3|4) ndarray of uint8 or uint16
        Upright (EXIF orientation applied), RGB(A) order.
    scale : float
        Full-resolution pixels per returned pixel: 1, or the integer factor the
        photo was reduced by while decoding.
    full_shape : tuple of int
        (rows, cols) of the upright photo at full resolution.
    bit_depth : int
        Bits per sample in the file (8 or 16; 1-bit and palette photos give 8),
        which ``pixels.dtype`` does not always say: a 16-bit colour photo that
        is reduced while decoding comes as uint8 unless it is dark (its 8-bit
        rendering below 64), as decoding 16-bit colour takes 12 bytes a pixel
        and a photo that uses its range loses nothing the reduced pixels keep.
    """

    pixels: NDArray[np.generic]
    scale: float
    full_shape: tuple[int, int]
    bit_depth: int = 8


def read_image(path: str | os.PathLike[str], *, max_side: int | None = None) -> ImageData:
    """Read a photo: PNG, JPEG, TIFF or BMP; gray, RGB or RGBA; 8 or 16 bits, or a
    TIFF of 32-bit integer or floating-point samples (scaled to 16 bits over the
    range of its gray or colour samples; an alpha in [0, 1] as it stands).

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
        PNG, JPEG, TIFF or BMP, unreadable, larger than 200 million pixels, a
        TIFF of wide colour samples whose file and two copies of its samples
        exceed ``MAX_DEEP_BYTES``, or holds non-finite values;
        the message is one line that starts with the path.
    ParameterError
        If ``max_side`` is not a whole number of at least 1.

    Notes
    -----
    Peak memory beyond the reduced pixels, for a photo reduced while
    decoding: a JPEG about 1/64 of its full size; PNG, TIFF and BMP one full
    decode inside Pillow (4 bytes a pixel for colour, 1 or 2 for gray). Only
    OpenCV decodes 16-bit colour, at 12 bytes a pixel, so a reduced 16-bit
    colour photo is read through Pillow's 8 bits when it reaches 64 in them
    (a photo that uses its range loses nothing the reduced pixels keep), and
    through OpenCV only when it is darker and its 16 bits fit
    ``rockscan.io.photos.MAX_DEEP_BYTES`` (512 MiB; docs/robustness.md).
    Decoders' own messages about a broken file are kept off standard error.
    """

    if isinstance(path, str) and not path.strip():
        # Path("") is the current folder: "an empty path" says what went wrong.
        raise ImageReadError("an empty path; give a photo's path")
    given = os.fspath(path)
    try:
        return _read_image(Path(path), max_side)
    except ImageReadError as exc:
        # Path drops a leading "./" and doubled slashes: the message names the
        # photo as the user wrote it, as the "path" beside it does.
        named = str(Path(path))
        message = str(exc)
        if given != named and message.startswith(named + ":"):
            raise ImageReadError(given + message[len(named) :]) from None
        raise


def _read_image(path: Path, max_side: int | None) -> ImageData:
    _check_file(path)
    if max_side is not None and (
        isinstance(max_side, bool) or not isinstance(max_side, (int, np.integer)) or max_side < 1
    ):
        raise ParameterError(f"max_side must be a whole number of pixels, at least 1; got {max_side!r}")
    pixels, factor, decoded, orientation, (full_rows, full_cols), bit_depth, deep_color = _decode(
        path, max_side
    )
    if deep_color:
        try:
            with _quiet_decoders():
                pixels = _decode_deep(path, factor)
        except MemoryError:
            raise ImageReadError(f"{path}: not enough memory to decode this photo") from None
    assert pixels is not None
    pixels = _apply_orientation(pixels, orientation)
    if orientation in (5, 6, 7, 8):
        full_rows, full_cols = full_cols, full_rows
    if pixels.size == 0 or min(pixels.shape[:2]) < 1:
        raise ImageReadError(f"{path}: image has no pixels")
    return ImageData(
        pixels=pixels,
        scale=float(decoded * factor),
        full_shape=(full_rows, full_cols),
        bit_depth=bit_depth,
    )


def _decode(
    path: Path, max_side: int | None
) -> tuple[NDArray[np.generic] | None, int, int, int, tuple[int, int], int, bool]:
    """Decode through Pillow: (pixels or None when OpenCV must decode deep colour,
    reduction factor, decoder's own reduction, EXIF orientation, full (rows, cols),
    the file's bits per sample, deep colour)."""
    from PIL import Image, UnidentifiedImageError

    header = _tiff_header(path)
    if header is not None and header.misread:
        return _decode_wide_tiff(path, header, max_side)
    deep_color = False
    try:
        with _quiet_decoders(), _pillow_limits(), open(path, "rb") as fh, Image.open(fh) as im:
            if im.format not in _FORMATS:
                raise ImageReadError(f"{path}: {im.format} images are not supported (use {_SUPPORTED})")
            pages = int(getattr(im, "n_frames", 1)) if im.format == "TIFF" else 1
            page = _full_resolution_page(im, pages)
            # OpenCV decodes a TIFF's first page only: another page keeps Pillow's 8 bits.
            deep_color = page == 0 and _is_deep_color(im)
            bit_depth = 16 if deep_color or im.mode.startswith("I") else 8
            full_cols, full_rows = im.size
            decoded = 1
            wanted = _reduction(im.size, max_side)
            if im.format in {"JPEG", "MPO"} and wanted > 1:
                # The decoder itself scales by 1/2, 1/4 or 1/8 (never below the wanted size).
                drafted = im.draft(im.mode, (full_cols // wanted, full_rows // wanted))
                if drafted is not None:
                    decoded = round(full_cols / drafted[1][2])
            factor = _reduction(im.size, max_side)
            im.load()
            if decoded == 1 and im.size != (full_cols, full_rows):
                # Pillow 10 has libtiff turn a TIFF upright as it loads (and drops the
                # tag): the photo is upright already, at the loaded size.
                full_cols, full_rows = im.size
            # A PNG may carry its EXIF block after the pixels: read it after load().
            orientation = _orientation(im)
            if deep_color and _deep_bytes(im) > MAX_DEEP_BYTES:
                # OpenCV decodes a whole frame at once; beyond the budget the 8 bits
                # Pillow decoded (4 bytes a pixel) are what the photo gives.
                deep_color = False
            if deep_color and factor > 1 and max(_band_maxima(im)) >= _DARK_8BIT:
                # OpenCV needs 12 bytes a pixel to decode 16-bit colour; a photo this
                # large is reduced anyway, and at full range 8 bits lose nothing
                # the reduced photo keeps. Only dark photos need their low bits.
                deep_color = False
            pixels = None if deep_color else _pixels(im, path, factor)
    except ImageReadError:
        raise
    except PermissionError:
        raise ImageReadError(f"{path}: cannot read (permission denied)") from None
    except (Image.DecompressionBombError, Image.DecompressionBombWarning):
        raise ImageReadError(f"{path}: photo is larger than {MAX_PIXELS:,} pixels") from None
    except UnidentifiedImageError:
        if header is None:
            kind = _signature(path)
            if kind is not None:
                # The file says what it is: "not a supported image" would tell the user
                # to convert it to the format it has.
                raise ImageReadError(f"{path}: a {kind} file that cannot be decoded (corrupt)") from None
            raise ImageReadError(f"{path}: not a supported image ({_SUPPORTED})") from None
        # Pillow reads gray floating-point TIFFs but not colour ones, nor 32-bit
        # integer colour: OpenCV decodes those (and tells a broken one apart).
        return _decode_wide_tiff(path, header, max_side)
    except MemoryError:
        raise ImageReadError(f"{path}: not enough memory to decode this photo") from None
    except _DECODE_ERRORS as exc:
        raise ImageReadError(f"{path}: image is truncated or corrupt ({_first_line(exc)})") from None
    if pages > 1:
        # A stack (a microscope's focus series): its first page, said aloud (and not
        # while the decoders' own messages are kept off standard error).
        which = "its first" if page == 0 else f"page {page + 1}, its first at full resolution"
        _log.warning("%s: a TIFF of %d pages; reading %s", path, pages, which)
    return pixels, factor, decoded, orientation, (full_rows, full_cols), bit_depth, deep_color


def _full_resolution_page(im: Image.Image, pages: int) -> int:
    """The first page of a TIFF that is not a reduced-resolution copy (a preview
    a scanner or camera puts first: bit 0 of its NewSubfileType), turned to;
    0 when every page is one, or for one page (of any format)."""
    if pages <= 1:
        return 0
    for page in range(pages):
        if page:
            im.seek(page)
        if not int(im.tag_v2.get(_NEW_SUBFILE_TYPE, 0)) & 1:
            return page
    im.seek(0)
    return 0


def _signature(path: Path) -> str | None:
    """The format a file's first bytes name (PNG, JPEG or BMP), or None."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(8)
    except OSError:
        return None
    for magic, kind in _SIGNATURES:
        if head.startswith(magic):
            return kind
    return None


_SIGNATURES = ((b"\x89PNG\r\n\x1a\n", "PNG"), (b"\xff\xd8\xff", "JPEG"), (b"BM", "BMP"))


#: The TIFF tag whose bit 0 marks a page as a reduced-resolution copy of another.
_NEW_SUBFILE_TYPE = 254


@dataclass(frozen=True)
class _TiffHeader:
    """What the first image directory of a TIFF says of its pixels."""

    rows: int
    cols: int
    samples: int
    bits: int
    orientation: int
    #: Where the orientation's value lies in the file, and its byte order.
    orientation_at: int | None = None
    order: str = "<"
    #: 1: samples interleaved pixel by pixel; 2: stored plane by plane.
    planar: int = 1
    #: 1: unsigned integers; 2: signed integers; 3: floating point.
    sample_format: int = 1

    @property
    def misread(self) -> bool:
        """Whether Pillow and OpenCV misread these samples, and tifffile decodes them:
        more than 8 bits a sample stored plane by plane (Pillow keeps 8 bits,
        OpenCV returns memory it never filled), signed bytes and unsigned 32-bit
        integers (read with the wrong sign), half floats (read by neither)."""
        return (
            (self.planar == 2 and self.bits > 8)
            or (self.sample_format == 2 and self.bits == 8)
            or (self.sample_format == 1 and self.bits == 32)
            or (self.sample_format == 3 and self.bits == 16)
        )


#: TIFF tags read from the first directory: size, bits and samples, orientation,
#: how the samples are laid out and what numbers they are.
_TIFF_TAGS = {
    256: "cols",
    257: "rows",
    258: "bits",
    277: "samples",
    274: "orientation",
    284: "planar",
    339: "sample_format",
}
#: Sizes of TIFF field types: SHORT, LONG, LONG8.
_TIFF_INTS = {3: ("H", 2), 4: ("I", 4), 16: ("Q", 8)}
#: Classic (42) and big (43) TIFF: how entries are counted, how offsets are
#: stored, and where the header keeps the first directory's offset.
_TIFF_LAYOUTS = {42: ("H", "I", 4), 43: ("Q", "Q", 8)}


def _tiff_header(path: Path) -> _TiffHeader | None:
    """The first directory of a classic or big TIFF, or None if the file is no TIFF."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(16)
            order = {b"II": "<", b"MM": ">"}.get(head[:2])
            if order is None or len(head) < 16:
                return None
            version = struct.unpack(order + "H", head[2:4])[0]
            if version not in _TIFF_LAYOUTS:
                return None
            # Classic TIFF counts entries in 2 bytes and points in 4, big TIFF in 8 and 8.
            count_code, wide, first = _TIFF_LAYOUTS[version]
            width, count_size = struct.calcsize(wide), struct.calcsize(count_code)
            offset = struct.unpack(order + wide, head[first : first + width])[0]
            fh.seek(offset)
            (count,) = struct.unpack(order + count_code, fh.read(count_size))
            entry_size = 4 + 2 * width
            start = offset + count_size
            entries = fh.read(min(count, 4096) * entry_size)
            found: dict = {"samples": 1, "bits": 8, "orientation": 1, "order": order}
            for k in range(len(entries) // entry_size):
                entry = entries[k * entry_size : (k + 1) * entry_size]
                tag, kind = struct.unpack(order + "HH", entry[:4])
                if tag not in _TIFF_TAGS or kind not in _TIFF_INTS:
                    continue
                code, size = _TIFF_INTS[kind]
                n, field = struct.unpack(order + wide, entry[4 : 4 + width])[0], entry[4 + width :]
                if n * size > width:
                    # The values lie elsewhere (bits of several samples): the first is enough.
                    fh.seek(struct.unpack(order + wide, field)[0])
                    field = fh.read(size)
                elif tag == 274 and size == 2:
                    found["orientation_at"] = start + k * entry_size + 4 + width
                found[_TIFF_TAGS[tag]] = struct.unpack(order + code, field[:size])[0]
    except (OSError, struct.error):
        return None
    if "rows" not in found or "cols" not in found:
        return None
    return _TiffHeader(**found)


def _decode_wide_tiff(
    path: Path, header: _TiffHeader, max_side: int | None
) -> tuple[NDArray[np.uint16], int, int, int, tuple[int, int], int, bool]:
    """A TIFF of floating-point or 32-bit samples, decoded by OpenCV (by tifffile
    where both Pillow and OpenCV misread them: ``_TiffHeader.misread``) and scaled
    to 16 bits over the range of its colour samples (as Pillow's gray ones are;
    alpha in [0, 1] as it stands); the tuple of :func:`_decode`."""
    rows, cols = header.rows, header.cols
    if rows * cols > MAX_PIXELS:
        raise ImageReadError(f"{path}: photo is larger than {MAX_PIXELS:,} pixels")
    decoded_bytes = rows * cols * max(1, header.samples) * max(1, header.bits // 8)
    # OpenCV holds the file's bytes and decodes through a second buffer of the
    # samples' size (a 412 MiB float RGB TIFF peaked at 1.28 GB).
    if path.stat().st_size + 2 * decoded_bytes > MAX_DEEP_BYTES:
        raise ImageReadError(
            f"{path}: a TIFF of {header.bits}-bit samples, {cols}x{rows} pixels, is too large to decode "
            f"(its file and two copies of its samples must fit in {MAX_DEEP_BYTES // 2**20} MiB; "
            "save it with 8 or 16 bits a sample)"
        )
    arr = _tifffile_samples(path) if header.misread else _opencv_samples(path, header)
    if arr is None or arr.size == 0:
        raise ImageReadError(f"{path}: not a supported image ({_SUPPORTED})")
    if arr.ndim == 3 and arr.shape[2] > 4:
        raise ImageReadError(f"{path}: photos have at most 4 channels, this one has {arr.shape[2]}")
    factor = _reduction((cols, rows), max_side)
    orientation = header.orientation if header.orientation in range(1, 9) else 1
    if arr.dtype in (np.uint8, np.uint16):
        # Unsigned samples of 16 bits stored plane by plane (tifffile's): as they stand.
        kept = _reduce(arr, factor)
        if kept.ndim == 3 and kept.shape[2] == 2:
            kept = np.dstack([kept[..., 0]] * 3 + [kept[..., 1]])
        return kept, factor, 1, orientation, (rows, cols), 8 * arr.itemsize, False
    if arr.dtype not in (np.float32, np.float64):
        arr = arr.astype(np.float32)
    arr = _reduce(arr, factor)
    if not np.all(np.isfinite(arr)):
        raise ImageReadError(f"{path}: image holds non-finite values")
    return _wide_to_16(arr, rgb=header.misread), factor, 1, orientation, (rows, cols), 16, False


def _opencv_samples(path: Path, header: _TiffHeader) -> NDArray[np.generic] | None:
    """A TIFF's first page as OpenCV decodes it: gray, gray + alpha, BGR or BGRA,
    the stored pixels (not turned upright); None if it cannot."""
    import cv2

    data = np.fromfile(path, dtype=np.uint8)
    if header.orientation_at is not None and header.orientation_at + 2 <= data.size:
        # Some OpenCV releases turn a TIFF upright as they decode it, some do not:
        # it decodes the stored pixels, and the tag is applied here, as for any photo.
        data[header.orientation_at : header.orientation_at + 2] = np.frombuffer(
            struct.pack(header.order + "H", 1), np.uint8
        )
    with _quiet_decoders():
        return cv2.imdecode(data, cv2.IMREAD_UNCHANGED)


def _tifffile_samples(path: Path) -> NDArray[np.generic]:
    """A TIFF's first page as tifffile decodes it: gray, gray + alpha, RGB or RGBA,
    the stored pixels (not turned upright), samples last."""
    import tifffile

    try:
        with _quiet_decoders(), tifffile.TiffFile(path) as tif:
            page = tif.pages[0]
            arr, axes, photometric = page.asarray(), page.axes, int(page.photometric)
    except MemoryError:
        raise
    except (*_DECODE_ERRORS, RuntimeError) as exc:
        if "imagecodecs" in str(exc):
            # LZW, JPEG and most compressions other than deflate: the file is whole.
            raise ImageReadError(
                f"{path}: this TIFF's compression needs the imagecodecs package (pip install imagecodecs)"
            ) from None
        raise ImageReadError(f"{path}: image is truncated or corrupt ({_first_line(exc)})") from None
    if arr.ndim == 3 and axes.startswith("S"):
        # Stored plane by plane: the samples come first.
        arr = np.moveaxis(arr, 0, -1)
    return np.ascontiguousarray(_as_light(arr, photometric))


def _as_light(arr: NDArray[np.generic], photometric: int) -> NDArray[np.generic]:
    """Samples that say how much light (gray or RGB), from TIFF's inks (CMYK) or
    gray stored with 0 as white; others as they are. tifffile gives what the
    file stores, where Pillow and OpenCV convert."""
    if arr.dtype.kind not in "uf" or photometric not in (_MIN_IS_WHITE, _SEPARATED):
        return arr
    top = float(np.iinfo(arr.dtype).max) if arr.dtype.kind == "u" else float(max(arr.max(), 1.0))
    if photometric == _MIN_IS_WHITE:
        return (top - arr.astype(np.float64)).astype(arr.dtype)
    if arr.ndim != 3 or arr.shape[2] < 4:
        return arr
    ink = arr[..., :4].astype(np.float64) / top
    light = (1.0 - ink[..., :3]) * (1.0 - ink[..., 3:4]) * top
    return np.rint(light).astype(arr.dtype) if arr.dtype.kind == "u" else light.astype(arr.dtype)


#: TIFF's photometric interpretations that store ink or darkness, not light.
_MIN_IS_WHITE, _SEPARATED = 0, 5


def _wide_to_16(arr: NDArray[np.floating], *, rgb: bool = False) -> NDArray[np.uint16]:
    """OpenCV's gray, gray + alpha, BGR or BGRA samples (``rgb``: gray, gray +
    alpha, RGB or RGBA, as tifffile gives them) as 16-bit gray or RGB(A)."""
    if arr.ndim == 3 and arr.shape[2] == 1:
        arr = arr[..., 0]
    alpha = arr.ndim == 3 and arr.shape[2] in (2, 4)
    # In place, through views: the decoded samples are this function's own, and
    # a full-size photo's temporaries would double its memory.
    colour = arr[..., :-1] if alpha else arr
    lo, hi = float(colour.min()), float(colour.max())
    # Scaled before the offset is taken off: samples near float32's limits of
    # both signs would overflow their difference.
    scale = 65535 / (hi - lo) if hi > lo else 0.0
    colour *= scale
    colour -= lo * scale
    if alpha:
        opacity = arr[..., -1]
        a_lo, a_hi = float(opacity.min()), float(opacity.max())
        if a_lo >= 0.0 and a_hi <= 1.0:
            opacity *= 65535
        elif a_hi > a_lo:
            opacity -= a_lo
            opacity *= 65535 / (a_hi - a_lo)
        else:
            opacity[...] = 65535
    samples = np.rint(np.clip(arr, 0.0, 65535.0, out=arr), out=arr).astype(np.uint16)
    if rgb and samples.ndim == 3 and samples.shape[2] in (3, 4):
        return np.ascontiguousarray(samples)
    return _opencv_to_rgb(samples)


def _opencv_to_rgb(arr: NDArray[np.generic]) -> NDArray[np.generic]:
    """OpenCV's gray, gray + alpha, BGR or BGRA pixels as gray, RGBA, RGB or RGBA."""
    if arr.ndim == 3 and arr.shape[2] == 2:
        gray, alpha = arr[..., 0], arr[..., 1]
        return np.dstack([gray, gray, gray, alpha])
    if arr.ndim == 3:
        return np.ascontiguousarray(arr[..., 2::-1] if arr.shape[2] == 3 else arr[..., [2, 1, 0, 3]])
    return np.ascontiguousarray(arr)


def _check_file(path: Path) -> None:
    try:
        exists, folder, regular = path.exists(), path.is_dir(), path.is_file()
        size = path.stat().st_size if regular else 0
    except OSError as exc:
        raise ImageReadError(f"{path}: cannot read ({exc.strerror or exc})") from None
    if not exists:
        raise ImageReadError(f"{path}: file not found")
    if folder:
        raise ImageReadError(f"{path}: is a folder, not a photo")
    if not regular:
        raise ImageReadError(f"{path}: not a regular file")
    if size == 0:
        raise ImageReadError(f"{path}: file is empty")


@contextlib.contextmanager
def _pillow_limits() -> Iterator[None]:
    """Pillow's decompression-bomb limit at rockscan's size, restored afterwards.

    Decoders warn about oddities of a file (a broken EXIF block, say) that cost
    nothing here: those stay quiet, and a photo over the limit is an error.
    """
    from PIL import Image

    saved = Image.MAX_IMAGE_PIXELS
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            warnings.simplefilter("error", Image.DecompressionBombWarning)
            Image.MAX_IMAGE_PIXELS = MAX_PIXELS
            yield
    finally:
        Image.MAX_IMAGE_PIXELS = saved


@contextlib.contextmanager
def _quiet_decoders() -> Iterator[None]:
    """Keep what libpng, libtiff and OpenCV print about a broken file off the terminal.

    They write to the process's standard error themselves, in lines the user did
    not ask for ("libpng warning: IEND: invalid"); the photo's own error line says
    what matters. Standard error points at the null device meanwhile, for the
    whole process: another thread's message written during a decode is lost.
    """
    sys.stderr.flush()
    saved = os.dup(2)
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, 2)
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(null)


def _reduction(size: tuple[int, int], max_side: int | None) -> int:
    """Integer reduction keeping the longer side at least ``max_side``; 1 unless
    the photo is more than twice that."""
    longest = max(size)
    if not max_side or longest <= 2 * int(max_side):
        return 1
    # A thin photo keeps its short side at 8 pixels or more (the least segmentation
    # takes), so a photo too thin to hold a rock is refused at its own size.
    return max(1, min(longest // int(max_side), min(size) // _MIN_SIDE))


def _is_deep_color(im: Image.Image) -> bool:
    """A colour (or gray + alpha) photo stored with 16 bits per sample."""
    if im.mode not in {"RGB", "RGBA", "LA"} or im.format not in {"PNG", "TIFF"} or not im.tile:
        return False
    # A tile is (codec, extents, offset, args); Pillow 11 names the fields, 10 does not.
    args = im.tile[0][3]
    rawmode = args[0] if isinstance(args, tuple) and args else args
    return isinstance(rawmode, str) and ";16" in rawmode


def _deep_bytes(im: Image.Image) -> int:
    """Bytes a 16-bit colour photo takes decoded whole and put in RGB order: two
    copies of 2 bytes a sample (OpenCV gives gray + alpha as 2 samples)."""
    return im.size[0] * im.size[1] * 4 * len(im.getbands())


def _band_maxima(im: Image.Image) -> list[float]:
    extrema = im.getextrema()
    bands = extrema if isinstance(extrema[0], tuple) else (extrema,)
    return [float(hi) for _, hi in bands]


def _decode_deep(path: Path, factor: int) -> NDArray[np.uint16]:
    """16-bit colour pixels, RGB(A) order, by OpenCV (which ignores EXIF here)."""
    import cv2

    data = np.fromfile(path, dtype=np.uint8)
    arr = cv2.imdecode(data, cv2.IMREAD_UNCHANGED)
    del data
    if arr is None or arr.dtype != np.uint16:
        raise ImageReadError(f"{path}: cannot decode this 16-bit colour photo")
    # Reduce first: reordering the channels copies the pixels.
    return _opencv_to_rgb(_reduce(arr, factor))


def _orientation(im: Image.Image) -> int:
    try:
        value = int(im.getexif().get(0x0112, 1))
    except Exception:  # a broken EXIF block must not cost the photo
        return 1
    return value if value in range(1, 9) else 1


def _pixels(im: Image.Image, path: Path, factor: int) -> NDArray[np.generic]:
    """The decoded image as an array, reduced by ``factor`` without a full-size copy."""
    if factor <= 1:
        return _to_array(im, path, _extrema(im, path))
    cols, rows = im.size[0] // factor, im.size[1] // factor
    if im.mode in {"L", "RGB"} and "transparency" not in im.info:
        return np.asarray(im.reduce(factor, box=(0, 0, cols * factor, rows * factor)))
    # Other modes Pillow cannot reduce, and turning the whole image into an array
    # would copy it (twice, for 16-bit gray): reduce it a band of rows at a time.
    extrema = _extrema(im, path)
    band = max(1, (1 << 22) // max(1, cols * factor * factor))
    parts = []
    for top in range(0, rows, band):
        bottom = min(rows, top + band)
        strip = im.crop((0, top * factor, cols * factor, bottom * factor))
        parts.append(_reduce(_to_array(strip, path, extrema), factor))
    return np.concatenate(parts, axis=0)


def _extrema(im: Image.Image, path: Path) -> tuple[float, float] | None:
    """Range of a 32-bit integer or float image, for one scaling to 16 bits."""
    if im.mode not in {"I", "F"}:
        return None
    lo, hi = im.getextrema()
    if not (np.isfinite(lo) and np.isfinite(hi)):
        raise ImageReadError(f"{path}: image holds non-finite values")
    return float(lo), float(hi)


def _to_array(im: Image.Image, path: Path, extrema: tuple[float, float] | None) -> NDArray[np.generic]:
    """Pixels as uint8 gray/RGB/RGBA or uint16 gray (``extrema``: see :func:`_extrema`)."""
    mode = im.mode
    if mode in {"L", "RGB", "RGBA"} and "transparency" not in im.info:
        return np.asarray(im)
    if mode.startswith("I;16"):
        return np.asarray(im).astype(np.uint16, copy=False)
    if mode in {"I", "F"}:
        arr = np.asarray(im).astype(np.float64)
        if not np.all(np.isfinite(arr)):
            raise ImageReadError(f"{path}: image holds non-finite values")
        lo, hi = extrema if extrema is not None else (float(arr.min()), float(arr.max()))
        if lo >= 0 and hi <= 65535 and mode == "I":
            return arr.astype(np.uint16)
        return np.round((arr - lo) / (hi - lo if hi > lo else 1.0) * 65535).astype(np.uint16)
    if mode == "1":
        return np.asarray(im.convert("L"))
    if mode in {"LA", "PA", "P", "RGBa", "La"} or "transparency" in im.info:
        return np.asarray(im.convert("RGBA"))
    return np.asarray(im.convert("RGB"))


def _reduce(pixels: NDArray[np.generic], factor: int) -> NDArray[np.generic]:
    """Average ``factor x factor`` blocks; the last partial row and column of
    blocks are dropped so that the mapping to full pixels stays exact."""
    if factor <= 1:
        return pixels
    import cv2

    rows, cols = pixels.shape[0] // factor, pixels.shape[1] // factor
    block = pixels[: rows * factor, : cols * factor]
    if pixels.ndim == 3 and pixels.shape[2] > 4:
        raise ImageReadError("photos have at most 4 channels")
    # INTER_AREA at an integer ratio is the exact block mean, in the photo's own type;
    # OpenCV reads the cropped view through its row stride, without a copy.
    return cv2.resize(block, (cols, rows), interpolation=cv2.INTER_AREA)


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


def write_photo(photo: RenderedPhoto, path: str | os.PathLike[str]) -> None:
    """Write a rendered photo in the format its suffix names (see ``RenderedPhoto.encode``).

    Parameters
    ----------
    photo : RenderedPhoto
    path : path-like
        ``.png``, ``.jpg``, ``.tif`` or ``.bmp``; written atomically.

    Raises
    ------
    ParameterError
        For another suffix, or a 16-bit photo as JPEG or BMP.
    WriteError
        If the file cannot be written.
    """
    from rockscan.io.atomic import write_bytes_atomic

    path = Path(path)
    write_bytes_atomic(path, photo.encode(path.suffix), what="the photo")
