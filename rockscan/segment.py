"""Photo -> rock masks.

The photo is reduced to one brightness channel at a capped working size, its
uneven lighting is flattened, it is thresholded with the rock's polarity chosen
automatically, and the rock is picked from the connected regions by a stated
rule. Every step is a function of arrays.

Steps (see :func:`segment`):

1. **Channel.** Luminance; for colour photos also the first principal
   component of the colours, and the one that separates best into two classes
   (Otsu's between-class variance over total variance) is kept. An alpha
   channel that really cuts the rock out is used directly.
2. **Working size.** The longer side is reduced to ``work_size`` pixels (area
   averaging), which bounds time and memory for any photo size.
3. **Smoothing.** A median filter, then a small Gaussian, suppress sensor noise,
   JPEG blocks and fine texture.
4. **Lighting.** The ground's illumination is estimated by normalised
   convolution over pixels currently judged ground (a wide Gaussian that
   ignores the rock) and divided out; this is repeated ``iterations`` times so
   that a rock covering most of the frame does not bias it.
5. **Threshold and polarity.** Otsu's threshold splits the flattened image;
   the ground is the class that holds most of the frame's border, so the rock
   may be lighter or darker than it.
6. **Clean-up.** Opening removes specks and pebbles much smaller than the
   rock; holes inside a region (texture, glints) are filled.
7. **Choice of rock.** Regions touching the frame's border are cut off and are
   used only if nothing else is left. The main rock is the largest remaining
   region; ``all rocks`` are the remaining regions of at least
   ``min_relative_area`` of the largest, in order of decreasing area.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rockscan._choices import POLARITIES
from rockscan.errors import NoRockFoundError, ParameterError

__all__ = ["SegmentConfig", "Segmentation", "segment", "to_gray"]


@dataclass(frozen=True)
class SegmentConfig:
    """Settings of the segmentation.

    Parameters
    ----------
    work_size : int
        Longer side of the working image, in pixels.
    median : int
        Median filter aperture at working size (odd; 1 disables).
    smooth_sigma : float
        Gaussian smoothing at working size, pixels.
    lighting_sigma : float
        Width of the lighting estimate, as a fraction of the working image's
        longer side.
    iterations : int
        Rounds of lighting estimation and thresholding.
    min_area_fraction : float
        Smallest region kept, as a fraction of the frame.
    min_relative_area : float
        With several rocks, smallest region kept as a fraction of the largest.
    polarity : {"auto", "dark", "light"}
        Whether the rock is darker or lighter than the ground.
    """

    work_size: int = 512
    median: int = 5
    smooth_sigma: float = 1.0
    lighting_sigma: float = 0.12
    iterations: int = 3
    min_area_fraction: float = 0.002
    min_relative_area: float = 0.15
    polarity: str = "auto"

    def __post_init__(self) -> None:
        if int(self.work_size) < 32:
            raise ParameterError("work_size must be at least 32 pixels")
        if self.median < 1 or self.median % 2 == 0:
            raise ParameterError("median must be an odd aperture >= 1")
        if self.polarity not in POLARITIES:
            raise ParameterError("polarity must be 'auto', 'dark' or 'light'")
        if not 0 < self.lighting_sigma <= 2:
            raise ParameterError("lighting_sigma must be in (0, 2]")
        if self.iterations < 1:
            raise ParameterError("iterations must be at least 1")


@dataclass(frozen=True, eq=False)
class Segmentation:
    """The rocks found in a photo, at working resolution.

    Attributes
    ----------
    labels : (rows, cols) ndarray of int32
        0 for ground, ``i`` for the i-th rock (1 = the main rock).
    scale : float
        Photo pixels per working pixel (the working image was reduced by it).
    polarity : {"dark", "light"}
        Whether the rocks are darker or lighter than the ground.
    n_rocks : int
    """

    labels: NDArray[np.int32]
    scale: float
    polarity: str
    n_rocks: int

    def mask(self, index: int = 1) -> NDArray[np.bool_]:
        """Mask of rock ``index`` (1-based) at working resolution."""
        return self.labels == index


def to_gray(pixels: NDArray[np.generic]) -> NDArray[np.float32]:
    """Luminance in [0, 1] of a gray, RGB or RGBA photo of any integer or float type."""
    arr = np.asarray(pixels)
    if arr.ndim == 3 and arr.shape[2] in (3, 4):
        arr = arr[..., :3].astype(np.float32) @ np.array([0.299, 0.587, 0.114], np.float32)
    elif arr.ndim != 2:
        raise ParameterError(f"a photo must be (rows, cols) or (rows, cols, 3|4), got shape {arr.shape}")
    return _unit(arr, np.asarray(pixels).dtype)


def segment(
    pixels: NDArray[np.generic], config: SegmentConfig | None = None, *, all_rocks: bool = False
) -> Segmentation:
    """Find the rock (or rocks) in a photo.

    Parameters
    ----------
    pixels : (rows, cols) or (rows, cols, 3|4) ndarray
        The photo, gray or RGB(A), any integer type or float in [0, 1].
    config : SegmentConfig, optional
    all_rocks : bool
        Label every rock, not only the main one.

    Returns
    -------
    Segmentation

    Raises
    ------
    NoRockFoundError
        If the photo is of one colour or no region stands out from the ground.
    """
    config = config or SegmentConfig()
    arr = np.asarray(pixels)
    if arr.ndim not in (2, 3) or arr.size == 0 or min(arr.shape[:2]) < 8:
        raise ParameterError(f"a photo must be at least 8x8 pixels, got shape {arr.shape}")
    if arr.ndim == 3 and arr.shape[2] not in (1, 3, 4):
        raise ParameterError(f"a photo must have 1, 3 or 4 channels, got {arr.shape[2]}")
    if arr.ndim == 3 and arr.shape[2] == 1:
        arr = arr[..., 0]
    if arr.dtype.kind == "f" and not np.all(np.isfinite(arr)):
        raise ParameterError("photo pixels must be finite")
    if arr.dtype.kind not in "uif":
        raise ParameterError(f"photo pixels must be numbers, got {arr.dtype}")
    rows, cols = arr.shape[:2]
    scale = max(1.0, max(rows, cols) / config.work_size)
    size = (max(8, round(cols / scale)), max(8, round(rows / scale)))
    scale = cols / size[0]

    alpha_mask = _alpha_mask(arr, size)
    if alpha_mask is not None:
        return _finish([alpha_mask], scale, "light", config, all_rocks)

    best: tuple[float, list[NDArray[np.bool_]], str] | None = None
    for channel in _channels(arr, size):
        found = _detect(channel, config, all_rocks)
        if found is not None and (best is None or found[0] > best[0]):
            best = found
    if best is None:
        raise NoRockFoundError("no rock found: nothing stands out from the ground")
    _, masks, polarity = best
    return _finish(masks, scale, polarity, config, all_rocks)


def _reduce(arr: NDArray[np.generic], size: tuple[int, int]) -> NDArray[np.generic]:
    """Area-average an image to ``size`` = (cols, rows) in its own dtype."""
    import cv2

    if (arr.shape[1], arr.shape[0]) == size:
        return arr
    if arr.dtype not in (np.uint8, np.uint16, np.float32, np.float64):
        arr = arr.astype(np.float32)
    return cv2.resize(arr, size, interpolation=cv2.INTER_AREA)


def _unit(arr: NDArray[np.generic], dtype: np.dtype) -> NDArray[np.float32]:
    if dtype.kind == "u" or dtype.kind == "i":
        top = float(np.iinfo(dtype).max)
        return (arr.astype(np.float32) / top).astype(np.float32)
    return np.clip(arr.astype(np.float32), 0.0, 1.0)


def _alpha_mask(arr: NDArray[np.generic], size: tuple[int, int]) -> NDArray[np.bool_] | None:
    """The rock cut out by an alpha channel, if the photo has a meaningful one."""

    if arr.ndim != 3 or arr.shape[2] != 4:
        return None
    small = _unit(_reduce(np.ascontiguousarray(arr[..., 3]), size), arr.dtype)
    transparent = float((small < 0.5).mean())
    if not 0.05 < transparent < 0.98:
        return None
    return small >= 0.5


def _channels(arr: NDArray[np.generic], size: tuple[int, int]) -> list[NDArray[np.float32]]:
    """Candidate brightness channels at working size."""

    dtype = arr.dtype
    # Reduce first, in the photo's own type: a float copy of an 8000 x 8000
    # colour photo would cost 768 MB.
    if arr.ndim == 2:
        return [_unit(_reduce(arr, size), dtype)]
    color = _unit(_reduce(np.ascontiguousarray(arr[..., :3]), size), dtype)
    luminance = color @ np.array([0.299, 0.587, 0.114], np.float32)
    flat = color.reshape(-1, 3)
    centered = flat - flat.mean(axis=0)
    _, vectors = np.linalg.eigh(centered.T @ centered)
    principal = (centered @ vectors[:, -1]).reshape(luminance.shape).astype(np.float32)
    return [luminance, principal]


def _detect(
    channel: NDArray[np.float32], config: SegmentConfig, all_rocks: bool
) -> tuple[float, list[NDArray[np.bool_]], str] | None:
    """Detect rocks in one channel; returns (score, masks, polarity) or None."""
    import cv2

    lo, hi = float(channel.min()), float(channel.max())
    if hi - lo < 1e-3:
        return None
    image = ((channel - lo) / (hi - lo)).astype(np.float32)
    if config.median > 1:
        image = cv2.medianBlur((image * 255).astype(np.uint8), config.median).astype(np.float32) / 255.0
    if config.smooth_sigma > 0:
        image = cv2.GaussianBlur(image, (0, 0), config.smooth_sigma)
    rows, cols = image.shape
    min_area = max(12.0, config.min_area_fraction * rows * cols)
    sigma = config.lighting_sigma * max(rows, cols)
    # The ground is learnt from the frame's border, where a rock that lies
    # inside the frame is not, whatever share of the frame the rock covers.
    width = max(2, int(0.04 * min(rows, cols)))
    border = np.zeros((rows, cols), dtype=bool)
    border[:width], border[-width:], border[:, :width], border[:, -width:] = True, True, True, True
    ground = np.ones((rows, cols), dtype=bool)
    result = None
    for _ in range(config.iterations + 1):
        lighting = _normalized_blur(image, ground, sigma)
        # Light multiplies reflectance: divide it out. The offset keeps a
        # nearly black ground from blowing up.
        flat = image / (lighting + 0.05) - 1.0
        reference = border & ground if (border & ground).sum() > 0.25 * border.sum() else border
        z = _robust_z(flat, reference)
        result = _best_regions(z, config, min_area, all_rocks)
        if result is None:
            return None
        _, masks, polarity = result
        # Lighting is learnt from the ground only: not the rocks, nor anything
        # else as far out on the rocks' side (pebbles). The other side stays:
        # dark gaps and shadows are the ground's lighting.
        far = z > _Z_DETECT if polarity == "light" else z < -_Z_DETECT
        outliers = np.logical_or.reduce(masks) | far
        ground = ~cv2.dilate(outliers.astype(np.uint8), np.ones((7, 7), np.uint8)).astype(bool)
        if ground.mean() < 0.05:
            break
    assert result is not None
    score, masks, polarity = result
    refined = [_refine(flat, mask, polarity) for mask in masks]
    return score, refined, polarity


def _robust_z(flat: NDArray[np.float32], ground: NDArray[np.bool_]) -> NDArray[np.float32]:
    """Deviation from the ground in robust standard deviations (median, MAD)."""
    values = flat[ground] if ground.sum() > 50 else flat.ravel()
    median = float(np.median(values))
    mad = float(np.median(np.abs(values - median))) * 1.4826
    spread = max(mad, 0.01 * float(np.abs(values).mean() + 1e-3), 1e-4)
    return ((flat - median) / spread).astype(np.float32)


def _best_regions(
    z: NDArray[np.float32], config: SegmentConfig, min_area: float, all_rocks: bool
) -> tuple[float, list[NDArray[np.bool_]], str] | None:
    """The rock regions of the more convincing polarity.

    A region is a connected set of pixels more than ``_Z_DETECT`` robust
    standard deviations from the ground; its score is its area times its median
    deviation, so a large, clearly contrasting rock beats texture and pebbles.
    """
    import cv2

    rows, cols = z.shape
    best = None
    polarities = ("light", "dark") if config.polarity == "auto" else (config.polarity,)
    for polarity in polarities:
        candidate = z > _Z_DETECT if polarity == "light" else z < -_Z_DETECT
        count, labels, stats, _ = cv2.connectedComponentsWithStats(candidate.astype(np.uint8), connectivity=8)
        if count <= 1:
            continue
        areas = stats[1:, cv2.CC_STAT_AREA].astype(np.float64)
        keep = np.flatnonzero(areas >= min_area)
        if keep.size == 0:
            continue
        flat_labels = labels.ravel()
        abs_z = np.abs(z).ravel()
        order = np.argsort(flat_labels, kind="stable")
        bounds = np.searchsorted(flat_labels[order], np.arange(count + 1))
        medians = np.array(
            [
                float(np.median(abs_z[order[bounds[i + 1] : bounds[i + 2]]])) if i in set(keep) else 0.0
                for i in range(count - 1)
            ]
        )
        scores = areas * medians
        x0, y0 = stats[1:, cv2.CC_STAT_LEFT], stats[1:, cv2.CC_STAT_TOP]
        x1 = x0 + stats[1:, cv2.CC_STAT_WIDTH]
        y1 = y0 + stats[1:, cv2.CC_STAT_HEIGHT]
        touches = (x0 == 0) | (y0 == 0) | (x1 == cols) | (y1 == rows)
        usable = np.zeros(count - 1, bool)
        usable[keep] = True
        inside = usable & ~touches
        pool = inside if inside.any() else usable
        ranked = [int(i) for i in np.argsort(-np.where(pool, scores, -1.0)) if pool[i]]
        if all_rocks:
            largest = areas[ranked].max()
            ranked = [i for i in ranked if areas[i] >= config.min_relative_area * largest]
        else:
            ranked = ranked[:1]
        total = float(scores[ranked[0]]) * (1.0 if inside.any() else 0.5)
        if best is None or total > best[0]:
            best = (total, [labels == i + 1 for i in ranked], polarity)
    return best


def _refine(flat: NDArray[np.float32], detected: NDArray[np.bool_], polarity: str) -> NDArray[np.bool_]:
    """Re-threshold a detected rock in a window around it.

    The detection threshold sits far out in the ground's tail; the outline
    belongs half-way between rock and ground, which Otsu's threshold finds
    once the window holds about as much rock as ground.
    """
    import cv2

    rows, cols = flat.shape
    ys, xs = np.nonzero(detected)
    h, w = ys.max() - ys.min() + 1, xs.max() - xs.min() + 1
    r0, r1 = max(0, ys.min() - h // 2), min(rows, ys.max() + h // 2 + 1)
    c0, c1 = max(0, xs.min() - w // 2), min(cols, xs.max() + w // 2 + 1)
    window = flat[r0:r1, c0:c1]
    threshold, _ = _otsu(window)
    inside = window > threshold if polarity == "light" else window < threshold
    count, labels = cv2.connectedComponents(inside.astype(np.uint8), connectivity=8)
    seed = detected[r0:r1, c0:c1]
    overlap = np.bincount(labels[seed], minlength=count)
    overlap[0] = 0
    if overlap.max() == 0:
        return detected
    region = labels == int(np.argmax(overlap))
    # A region that leaks out of its window has merged with the ground; keep
    # the detection instead.
    edge = np.concatenate([region[0], region[-1], region[:, 0], region[:, -1]])
    touches_frame = np.array([r0 == 0, r1 == rows, c0 == 0, c1 == cols])
    if edge.mean() > 0.25 and not touches_frame.any():
        return detected
    out = np.zeros_like(detected)
    out[r0:r1, c0:c1] = region | seed
    return out


#: Detection threshold, robust standard deviations from the ground.
_Z_DETECT = 3.0


def _normalized_blur(
    image: NDArray[np.float32], weight: NDArray[np.bool_], sigma: float
) -> NDArray[np.float32]:
    """Gaussian blur of ``image`` counting only pixels where ``weight`` is set."""
    import cv2

    # A wide blur is cheap on a reduced copy; lighting has no fine detail.
    factor = max(1, int(sigma // 4))
    small_size = (max(4, image.shape[1] // factor), max(4, image.shape[0] // factor))
    w = cv2.resize(weight.astype(np.float32), small_size, interpolation=cv2.INTER_AREA)
    v = cv2.resize(image * weight, small_size, interpolation=cv2.INTER_AREA)
    s = sigma / factor
    num = cv2.GaussianBlur(v, (0, 0), s, borderType=cv2.BORDER_REFLECT)
    den = cv2.GaussianBlur(w, (0, 0), s, borderType=cv2.BORDER_REFLECT)
    fallback = float((image * weight).sum() / max(weight.sum(), 1))
    est = np.where(den > 1e-3, num / np.maximum(den, 1e-6), fallback).astype(np.float32)
    return cv2.resize(est, (image.shape[1], image.shape[0]), interpolation=cv2.INTER_LINEAR)


def _otsu(values: NDArray[np.float32]) -> tuple[float, float]:
    """Otsu's threshold and the separation (between-class over total variance)."""
    v = values.ravel()
    hist, edges = np.histogram(v, bins=256)
    centers = (edges[:-1] + edges[1:]) / 2
    w0 = np.cumsum(hist).astype(np.float64)
    w1 = w0[-1] - w0
    s0 = np.cumsum(hist * centers)
    m0 = s0 / np.maximum(w0, 1)
    m1 = (s0[-1] - s0) / np.maximum(w1, 1)
    between = w0 * w1 * (m0 - m1) ** 2 / w0[-1] ** 2
    i = int(np.argmax(between[:-1]))
    total = float(v.var())
    return float(edges[i + 1]), float(between[i] / total) if total > 0 else 0.0


def _finish(
    masks: list[NDArray[np.bool_]], scale: float, polarity: str, config: SegmentConfig, all_rocks: bool
) -> Segmentation:
    """Fill holes, drop specks, and label the rocks by decreasing area."""
    import cv2
    from scipy import ndimage

    rows, cols = masks[0].shape
    min_area = max(12.0, config.min_area_fraction * rows * cols)
    cleaned = []
    for mask in masks:
        radius = max(1, int(math.sqrt(mask.sum() / math.pi) * 0.05))
        kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))
        opened = cv2.morphologyEx(mask.astype(np.uint8), cv2.MORPH_OPEN, kernel)
        count, labels, stats, _ = cv2.connectedComponentsWithStats(opened, connectivity=8)
        if count <= 1:
            continue
        largest = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
        region = ndimage.binary_fill_holes(labels == largest)
        if region.sum() >= min_area:
            cleaned.append(region)
    if not cleaned:
        raise NoRockFoundError("no rock found: nothing stands out from the ground")
    cleaned.sort(key=lambda m: -int(m.sum()))
    if not all_rocks:
        cleaned = cleaned[:1]
    out = np.zeros((rows, cols), np.int32)
    for index, region in enumerate(cleaned, start=1):
        out[region & (out == 0)] = index
    return Segmentation(labels=out, scale=float(scale), polarity=polarity, n_rocks=len(cleaned))
