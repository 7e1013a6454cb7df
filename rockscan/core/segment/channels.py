"""The photo as segmentation sees it: validated pixels, a pyramid, and the channels
(luminance, colour) in which a rock may stand out.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rockscan.core.errors import ParameterError

_LUMA = np.array([0.299, 0.587, 0.114], np.float32)


def to_gray(pixels: NDArray[np.generic]) -> NDArray[np.float32]:
    """Luminance in [0, 1] of a gray, RGB or RGBA photo of any integer or float type.

    Parameters
    ----------
    pixels : (rows, cols) or (rows, cols, 3|4) ndarray
        Integer photos are scaled by their type's maximum; float photos are
        taken to be in [0, 1] and clipped.

    Returns
    -------
    gray : (rows, cols) ndarray of float32
        ``0.299 R + 0.587 G + 0.114 B`` (ITU-R BT.601).
    """
    arr = np.asarray(pixels)
    if arr.ndim == 3 and arr.shape[2] in (3, 4):
        arr = arr[..., :3].astype(np.float32) @ _LUMA
    elif arr.ndim != 2:
        raise ParameterError(f"a photo must be (rows, cols) or (rows, cols, 3|4), got shape {arr.shape}")
    return _unit(arr, np.asarray(pixels).dtype)


def _check_pixels(pixels: NDArray[np.generic]) -> NDArray[np.generic]:
    arr = np.asarray(pixels)
    if arr.ndim == 3 and arr.shape[2] == 1:
        arr = arr[..., 0]
    if arr.ndim not in (2, 3) or arr.size == 0:
        raise ParameterError(
            f"a photo must be (rows, cols) or (rows, cols, 3|4) pixels, got shape {np.shape(pixels)}"
        )
    if arr.ndim == 3 and arr.shape[2] not in (3, 4):
        raise ParameterError(f"a photo must have 1, 3 or 4 channels, got {arr.shape[2]}")
    if min(arr.shape[:2]) < 8:
        raise ParameterError(f"a photo must be at least 8x8 pixels, got {arr.shape[0]}x{arr.shape[1]}")
    if arr.dtype.kind not in "uif":
        raise ParameterError(f"photo pixels must be numbers, got dtype {arr.dtype}")
    if arr.dtype.kind == "f" and not np.all(np.isfinite(arr)):
        raise ParameterError("photo pixels must be finite (no NaN or infinity)")
    if arr.dtype.kind == "f" and np.count_nonzero(arr > 1.0) > arr.size // 2:
        # Clipped to [0, 1], such a photo is one flat white: say why.
        raise ParameterError(
            f"float photo pixels must lie in [0, 1], got most above 1 (up to {float(arr.max()):g}); "
            "scale them (8-bit values: divide by 255)"
        )
    if arr.dtype.kind in "ui" and arr.dtype.itemsize > 1:
        arr = _full_range(arr)
    return arr


def _full_range(arr: NDArray[np.integer]) -> NDArray[np.integer]:
    """A photo of integers wider than 8 bits whose colour uses only the low bits
    (a 10-, 12- or 14-bit sensor's values, or 8-bit ones, stored in 16 bits or
    in numpy's default int64) shifted up to fill its type; any other photo as
    it is. A signed type's negatives are no light, 0.

    The contrast a rock needs is a fraction of the full scale: 8-bit values
    stored as 16 bits gave "nothing stands out" where the same values as 8 bits
    gave the rock. The bits in use are rounded up to an even count of at least
    8, so that a dark photo of a sensor's full depth stays as dark as it is.
    """
    colour = arr[..., :3] if arr.ndim == 3 else arr
    used = max(8, int(colour.max()).bit_length())
    room = np.iinfo(arr.dtype).bits - (arr.dtype.kind == "i")
    shift = room - (used + used % 2)
    if shift <= 0:
        return arr
    out = np.maximum(arr, 0) if arr.dtype.kind == "i" else arr.copy()
    if out.ndim == 3:
        out[..., :3] <<= shift
    else:
        out <<= shift
    return out


def _pyramid(arr: NDArray[np.generic], smallest: int) -> list[NDArray[np.generic]]:
    """The image and its exact halvings (area averages), down to a longer side of ``smallest``.

    Level k's pixel covers exactly ``2**k`` photo pixels each way: an odd side
    loses its last pixel before halving, which keeps OpenCV on its fast path
    and the geometry exact.
    """
    import cv2

    if arr.dtype not in (np.uint8, np.uint16, np.float32, np.float64):
        arr = arr.astype(np.float32)
    levels = [np.ascontiguousarray(arr)]
    while max(levels[-1].shape[:2]) >= 2 * smallest and min(levels[-1].shape[:2]) >= 16:
        top = levels[-1]
        half = (top.shape[1] // 2, top.shape[0] // 2)
        even = np.ascontiguousarray(top[: 2 * half[1], : 2 * half[0]])
        levels.append(
            cv2.resize(even, half, interpolation=cv2.INTER_AREA).reshape(half[1], half[0], *top.shape[2:])
        )
    return levels


def _at_scale(
    levels: list[NDArray[np.generic]], scale: float
) -> tuple[NDArray[np.generic], tuple[float, float]]:
    """The photo reduced about ``scale`` times, and the photo pixels it covers (rows, cols).

    The deepest pyramid level not coarser than ``scale`` is resized once more:
    by area averaging, or bilinearly when the step is small enough that no
    detail is lost between samples.
    """
    import cv2

    k = min(len(levels) - 1, max(0, math.floor(math.log2(max(scale, 1.0)) + 1e-9)))
    level = levels[k]
    covered = (level.shape[0] * 2.0**k, level.shape[1] * 2.0**k)
    size = (max(1, round(covered[1] / scale)), max(1, round(covered[0] / scale)))
    if (level.shape[1], level.shape[0]) == size:
        return level, covered
    step = max(level.shape[1] / size[0], level.shape[0] / size[1])
    method = cv2.INTER_LINEAR if step < 1.5 else cv2.INTER_AREA
    out = cv2.resize(level, size, interpolation=method)
    return out.reshape(size[1], size[0], *level.shape[2:]), covered


def _unit(arr: NDArray[np.generic], dtype: np.dtype) -> NDArray[np.float32]:
    """Values in [0, 1] as float32: integers by their type's maximum (a signed
    type's negatives as 0, no light), floats clipped (before they are narrowed,
    so that a huge value is 1, not an overflow)."""
    if dtype.kind == "u":
        return arr.astype(np.float32) * np.float32(1.0 / np.iinfo(dtype).max)
    if dtype.kind == "i":
        return np.maximum(arr, 0).astype(np.float32) * np.float32(1.0 / np.iinfo(dtype).max)
    return np.clip(arr, 0.0, 1.0).astype(np.float32)


def cielab(unit: NDArray[np.float32]) -> NDArray[np.float32]:
    """Colour where a distance is about as far to the eye in every hue.

    Parameters
    ----------
    unit : (rows, cols, 3) or (rows, cols) ndarray of float32
        RGB or brightness in [0, 1].

    Returns
    -------
    (rows, cols, 3) or (rows, cols, 1) ndarray of float32
        CIELAB for RGB; 100 times the brightness (CIELAB's scale of lightness)
        for gray.
    """
    import cv2

    unit = np.ascontiguousarray(unit, dtype=np.float32)
    if unit.ndim == 3:
        return cv2.cvtColor(unit, cv2.COLOR_RGB2Lab)
    return (100.0 * unit)[..., None]


@dataclass(frozen=True, eq=False)
class _Channel:
    """A brightness channel: how to compute it from colour or gray pixels in [0, 1].

    ``direction`` and ``center`` define the chromaticity channel (a projection
    of ``rgb / (r + g + b)``); luminance has neither. ``multiplicative`` says
    whether lighting multiplies the channel (luminance) or cancels in it.
    """

    name: str
    multiplicative: bool
    direction: NDArray[np.float32] | None = None
    center: NDArray[np.float32] | None = None
    #: The ground's chromaticity: with it, the channel is each pixel's distance
    #: from it in the chromaticity plane (any hue away from the ground's).
    ground: NDArray[np.float32] | None = None

    def values(self, image: NDArray[np.float32]) -> NDArray[np.float32]:
        if image.ndim == 2:
            return image
        if self.ground is not None:
            return _hue_distance(image, self.ground)
        if self.direction is None:
            return image @ _LUMA
        total = image.sum(axis=2)
        # Chromaticity is noise where there is no light; the darkest pixels get the mean.
        projected = (image @ self.direction - self.center @ self.direction * total) / np.maximum(
            total, _LEAST_LIGHT
        )
        return np.where(total > _LEAST_LIGHT, projected, 0.0).astype(np.float32)


#: Least sum of a pixel's red, green and blue (each in [0, 1]) for it to have a
#: hue: darker, the chromaticity ``rgb / (r + g + b)`` is noise.
_LEAST_LIGHT = 0.06


def border_band(shape: tuple[int, int]) -> NDArray[np.bool_]:
    """A band along the frame's border, 4% of the shorter side wide (at least
    2 pixels): where the ground is first learnt, since a rock that lies inside
    the frame is not there, whatever share of the frame it covers."""
    rows, cols = shape
    width = max(2, round(0.04 * min(rows, cols)))
    band = np.zeros((rows, cols), dtype=bool)
    band[:width], band[-width:], band[:, :width], band[:, -width:] = True, True, True, True
    return band


def _hue_distance(image: NDArray[np.float32], ground: NDArray[np.float32]) -> NDArray[np.float32]:
    """Distance of each pixel's chromaticity ``rgb / (r + g + b)`` from ``ground``'s
    (0 where there is too little light for a hue)."""
    total = image.sum(axis=2)
    chroma = image / np.maximum(total, _LEAST_LIGHT)[..., None]
    distance = np.sqrt(((chroma - ground) ** 2).sum(axis=2))
    return np.where(total > _LEAST_LIGHT, distance, 0.0).astype(np.float32)


def _border_chromaticity(image: NDArray[np.float32]) -> NDArray[np.float32] | None:
    """The median chromaticity of a band along the frame's border (the ground's,
    as detection first learns it), or None where the band is too dark."""
    ground = median_chromaticity(image[border_band(image.shape[:2])], 16)
    return None if ground is None else ground.astype(np.float32)


def median_chromaticity(pixels: NDArray[np.floating], least: int) -> NDArray[np.floating] | None:
    """Median chromaticity ``rgb / (r + g + b)`` of those of ``pixels`` (n, 3)
    bright enough to have a hue (``_LEAST_LIGHT``), in their own type; None
    when fewer than ``least`` are."""
    total = pixels.sum(axis=1)
    lit = total > _LEAST_LIGHT
    if np.count_nonzero(lit) < least:
        return None
    return np.median(pixels[lit] / total[lit, None], axis=0)


def _channels(small: NDArray[np.float32], *, every_hue: bool = False) -> Iterator[_Channel]:
    """Candidate channels, learnt from the detection image (module docstring, step 2).

    A generator: the chromaticity is only worked out when the caller asks past
    luminance. With ``every_hue`` (``--all``), last the distance from the
    ground's hue: the rocks of a scene may each have a hue of their own, on
    either side of the ground's along the principal direction or across it,
    where the projection sees only one side of one direction.
    """
    yield _Channel("luminance", True)
    if small.ndim == 2:
        return
    total = small.sum(axis=2)
    lit = total > _LEAST_LIGHT
    if lit.sum() < 16:
        return
    chroma = small[lit] / total[lit, None]
    center = chroma.mean(axis=0)
    values, vectors = np.linalg.eigh(np.cov(chroma.T))
    # A chromaticity that barely varies (a gray or evenly tinted photo) adds nothing.
    if values[-1] > 1e-5:
        direction = vectors[:, -1].astype(np.float32)
        yield _Channel("chromaticity", False, direction, center.astype(np.float32))
        ground = _border_chromaticity(small) if every_hue else None
        if ground is not None:
            yield _Channel("hue", False, ground=ground)
