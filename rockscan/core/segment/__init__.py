"""Photo -> rock masks.

The rock is found on a small copy of the photo, then outlined on a larger one
by a threshold half-way between the rock's level and the ground's. Every step
is a function of arrays.

Steps (see :func:`segment`):

1. **Sizes.** The photo is halved by area averaging as often as needed, then
   resized once more, to a detection image whose longer side is at most
   ``detect_size`` pixels (rocks are found there) and, after detection, to a
   working image (rocks are outlined there) on which the smallest rock found
   spans about ``outline_radius`` pixels, with a longer side of at most
   ``work_size`` and never coarser than the detection image. Time and memory
   are bounded for any photo size.
2. **Channel.** Luminance. Only if it shows no rock, the first principal
   component of the chromaticity ``rgb / (r + g + b)`` (a rock of another hue
   than its ground but of the same brightness). An alpha channel that really
   cuts the rock out (5% to 98% of the frame transparent) is used directly.
3. **Lighting.** After a median filter and a Gaussian of ``detect_sigma``
   (sensor noise, JPEG blocks, fine texture), a polynomial surface of degree
   ``lighting_degree`` is fitted to the ground by least squares, leaving out
   pixels beyond 2.5 robust standard deviations of the fit: first to a band
   along the frame's border, where the rock is not, then ``iterations`` times
   to every pixel that is not part of a rock nor beyond ``z_grow`` from the
   ground. From the second round on, what the polynomial misses (a dark
   corner, a bright patch) is added as the ground's residual spread by a
   normalised Gaussian ``lighting_sigma`` of the longer side wide. Luminance
   is divided by the lighting (light multiplies reflectance); chromaticity,
   which light does not change, has it subtracted.
4. **Regions.** Each pixel's deviation from the ground is measured in robust
   standard deviations ``z`` (median and MAD of the ground pixels, the MAD
   taken as at least ``min_contrast / z_detect``, so that on a smooth ground
   noise and JPEG blocks are no rock). A region
   grows from pixels beyond ``z_detect`` through connected pixels beyond
   ``z_grow`` (hysteresis), lighter or darker than the ground; regions smaller
   than ``min_area_fraction`` of the frame (pebbles, specks) are dropped.
5. **Choice of rock.** A region scores its area, times its edge step (mean
   ``z`` just inside its edge less just outside; a rock's edge is a step as
   high as its contrast, a blob of texture fades out), times its compactness
   ``4 pi area / perimeter**2`` (the ground between several rocks has a long
   ragged edge), times ``(1 - s)**2`` where ``s`` is the share of its edge
   that runs along the frame's (a rock lies inside the frame). The **main
   rock** is the region of highest score over both polarities; the photo's
   polarity is that of its main rock, whether the ground is lighter or darker.
   A region whose contrast has two clear levels (Otsu's separation above 0.8:
   a rock and a faint halo, or rocks joined through the ground between them)
   is cut at Otsu's threshold, and its largest part kept. With ``all_rocks``,
   every region of the main rock's polarity that scores at least a tenth of
   the main rock and covers at least ``min_relative_area`` of its area is cut
   so, and every part whose area is at least ``min_relative_area`` of the
   largest is a rock, by decreasing area.
6. **Outline.** In a window around each rock, at working size, after a
   ``smooth_sigma`` Gaussian, the rock's level is the median inside the
   detected region (less a margin) and the ground's the median of a ring
   around it, away from other outliers. In gray photos the level is read from
   the flattened brightness; in colour along Fisher's discriminant of the
   flattened brightness and the smoothed hue (red and blue less luminance),
   so that a rock's hue counts as well as its brightness and ground texture,
   which mostly varies the ground's brightness, counts less; brightness keeps
   at least half of the step, so that the outline stays at its sharp edge
   rather than the smoothed hue's. Half-way between
   rock and ground is where a blurred step edge lies, whatever the blur.
   Pixels clipped by the sensor on a light rock count as rock. The connected
   part beyond half-way that overlaps the detection is the rock; its holes
   (texture, glints, engravings) are filled. If it reaches the window's edge,
   the window is widened around it and the step repeated (at most three
   times). If it still reaches it, or its area is under a quarter or over
   four times the detection's, the threshold has failed and the detection
   is kept. Besides the mask, a coverage map rising from 0 to 1
   across the edge lets :func:`rockscan.core.outline.trace_outline` place the
   outline between pixels.

Known limits: a shadow darker than half-way between ground and rock joins a
dark rock; a pebble or a patch of ground as light (or dark) as the rock and
touching it joins it; a rock whose contrast is within about three standard
deviations of the ground's texture may be found only in part; where the
sensor clips a light rock its outline lies up to a blur's width outside; a
rock cut by the frame's border is outlined along the border.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rockscan.core._threads import one_blas_thread
from rockscan.core.choices import POLARITIES
from rockscan.core.errors import NoRockFoundError, ParameterError
from rockscan.core.segment.score import outline_evidence, outline_score
from rockscan.core.segment.split import split_necks, split_rocks, territories

__all__ = ["CONFIDENT_SCORE", "RockMask", "SegmentConfig", "Segmentation", "segment", "to_gray"]

#: Segmentation score below which an outline is not trusted: such a rock is
#: never reported as interesting (calibrated on the segmentation benchmark's
#: development part, see docs/segmentation.md).
CONFIDENT_SCORE = 0.5


@dataclass(frozen=True)
class SegmentConfig:
    """Settings of the segmentation.

    Parameters
    ----------
    work_size : int
        Longer side of the working image, in pixels (outline resolution).
    outline_radius : float
        Radius, in working pixels, that is enough to outline a rock: a larger
        rock is outlined on a proportionally smaller working image (never
        smaller than the detection image).
    detect_size : int
        Longer side of the detection image, in pixels (at most ``work_size``).
    median : int
        Median filter aperture of the detection image (1, 3 or 5; 1
        disables); the working image gets 3 unless it is 1.
    detect_sigma : float
        Gaussian smoothing of the detection image, in pixels of an image
        ``detect_size`` long (less for a smaller photo): texture averages
        out, a rock stays.
    smooth_sigma : float
        Gaussian smoothing of the working image before the outline's
        threshold, in its pixels.
    lighting_degree : int
        Degree of the polynomial lighting surface (0 to 4; 0 is flat).
    lighting_sigma : float
        Width of the local lighting correction, as a fraction of the longer
        side (0 disables it).
    iterations : int
        Rounds of lighting fit and detection.
    z_detect : float
        Detection threshold, in robust standard deviations of the ground.
    z_grow : float
        Regions grow from pixels beyond ``z_detect`` through pixels beyond
        this (hysteresis), in robust standard deviations.
    min_contrast : float
        Smallest difference a rock's seeds must have from the ground:
        relative brightness (0.05 is 5% lighter or darker), or chromaticity.
    min_area_fraction : float
        Smallest region kept, as a fraction of the frame.
    min_relative_area : float
        With several rocks, smallest region kept as a fraction of the largest.
    polarity : {"auto", "dark", "light"}
        Whether the rock is darker or lighter than the ground.
    """

    work_size: int = 512
    outline_radius: float = 80.0
    detect_size: int = 256
    median: int = 3
    detect_sigma: float = 2.0
    smooth_sigma: float = 0.7
    lighting_degree: int = 2
    lighting_sigma: float = 0.2
    iterations: int = 1
    z_detect: float = 3.0
    z_grow: float = 2.0
    min_contrast: float = 0.05
    min_area_fraction: float = 0.002
    min_relative_area: float = 0.15
    polarity: str = "auto"

    def __post_init__(self) -> None:
        for name in ("work_size", "detect_size", "median", "lighting_degree", "iterations"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                raise ParameterError(f"{name} must be an integer, got {value!r}")
        if self.work_size < 32 or self.detect_size < 32:
            raise ParameterError("work_size and detect_size must be at least 32 pixels")
        if self.detect_size > self.work_size:
            raise ParameterError("detect_size must not exceed work_size")
        if self.median not in (1, 3, 5):
            raise ParameterError("median must be 1 (off), 3 or 5")
        if not 0 <= self.lighting_degree <= 4:
            raise ParameterError("lighting_degree must be between 0 and 4")
        if self.iterations < 1:
            raise ParameterError("iterations must be at least 1")
        for name in (
            "detect_sigma",
            "smooth_sigma",
            "z_detect",
            "z_grow",
            "min_area_fraction",
            "min_relative_area",
        ):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ParameterError(f"{name} must be a non-negative number, got {value!r}")
        if not 0 < self.z_grow <= self.z_detect:
            raise ParameterError("z_grow must be positive and at most z_detect")
        if self.min_area_fraction >= 0.5 or self.min_relative_area > 1:
            raise ParameterError("min_area_fraction must be below 0.5 and min_relative_area at most 1")
        if self.polarity not in POLARITIES:
            raise ParameterError(f"polarity must be one of {', '.join(POLARITIES)}; got {self.polarity!r}")


@dataclass(frozen=True, eq=False)
class RockMask:
    """One rock, in a window of the working image.

    Attributes
    ----------
    mask : (h, w) ndarray of bool
        The rock, holes filled.
    coverage : (h, w) ndarray of float32
        0 on the ground, 1 on the rock, in between across the edge; its 0.5
        level is the outline, between pixels.
    origin_rowcol : (int, int)
        The window's top-left pixel in the working image.
    score : float
        Segmentation score in [0, 1]: how well the photo supports this
        outline (a step from the rock's level to the ground's all round it,
        rock inside, ground outside, off the frame, solid; see
        ``rockscan.core.segment.score``). Low means a likely wrong outline; below
        :data:`CONFIDENT_SCORE` the outline is not to be trusted.
    evidence : tuple of float
        The measurements the score is computed from (support, weak, outside,
        noise, frame, solidity).
    """

    mask: NDArray[np.bool_]
    coverage: NDArray[np.float32]
    origin_rowcol: tuple[int, int]
    score: float = 1.0
    evidence: tuple[float, ...] = ()

    @property
    def area(self) -> int:
        """Area in working pixels."""
        return int(self.mask.sum())


@dataclass(frozen=True, eq=False)
class Segmentation:
    """The rocks found in a photo, at working resolution.

    Attributes
    ----------
    labels : (rows, cols) ndarray of int32
        0 for ground, ``i`` for the i-th rock (1 = the main rock).
    rocks : tuple of RockMask
        The rocks in label order.
    scale_rowcol : (float, float)
        Photo pixels per working pixel along rows and columns.
    polarity : {"dark", "light"}
        Whether the rocks are darker or lighter than the ground.
    channel : {"luminance", "chromaticity", "alpha"}
        The channel the rocks were found in.
    """

    labels: NDArray[np.int32]
    rocks: tuple[RockMask, ...]
    scale_rowcol: tuple[float, float]
    polarity: str
    channel: str

    @property
    def n_rocks(self) -> int:
        """Number of rocks."""
        return len(self.rocks)

    @property
    def scale(self) -> float:
        """Photo pixels per working pixel (the mean of rows and columns)."""
        return 0.5 * (self.scale_rowcol[0] + self.scale_rowcol[1])

    def mask(self, index: int = 1) -> NDArray[np.bool_]:
        """Mask of rock ``index`` (1-based) over the whole working image."""
        if not 1 <= index <= self.n_rocks:
            raise ParameterError(f"rock index must be between 1 and {self.n_rocks}, got {index}")
        return self.labels == index


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


@one_blas_thread
def segment(
    pixels: NDArray[np.generic], config: SegmentConfig | None = None, *, all_rocks: bool = False
) -> Segmentation:
    """Find the rock (or rocks) in a photo.

    Parameters
    ----------
    pixels : (rows, cols) or (rows, cols, 1|3|4) ndarray
        The photo, gray or RGB(A), any integer type or float in [0, 1].
    config : SegmentConfig, optional
    all_rocks : bool
        Find every rock, not only the main one.

    Returns
    -------
    Segmentation

    Raises
    ------
    ParameterError
        If ``pixels`` is not a photo (wrong shape, too small, not numbers).
    NoRockFoundError
        If the photo is of one colour or no region stands out from the ground.

    Notes
    -----
    The steps and the rule that picks the main rock are in the module's
    docstring.
    """
    config = config or SegmentConfig()
    arr = _check_pixels(pixels)
    rows, cols = arr.shape[:2]
    color = arr[..., :3] if arr.ndim == 3 else arr
    detect_scale = max(1.0, max(rows, cols) / config.detect_size)
    largest_scale = max(1.0, max(rows, cols) / config.work_size)

    if arr.ndim == 3 and arr.shape[2] == 4:
        alpha, covered = _at_scale(_pyramid(arr[..., 3], config.work_size), largest_scale)
        alpha = _unit(alpha, arr.dtype)
        if 0.05 < float((alpha < 0.5).mean()) < 0.98:
            scale_rowcol = (covered[0] / alpha.shape[0], covered[1] / alpha.shape[1])
            return _from_alpha(alpha, scale_rowcol, config, all_rocks)

    levels = _pyramid(color, config.detect_size)
    small, detect_covered = _at_scale(levels, detect_scale)
    small = _unit(small, arr.dtype)
    outline = _Outliner(
        levels, arr.dtype, small.shape[:2], detect_covered, detect_scale, largest_scale, config
    )
    best: tuple[float, Segmentation, float] | None = None
    for channel in _channels(small):
        detection = _detect(channel.values(small), channel, config, all_rocks)
        if detection is None:
            continue
        if all_rocks:
            found = outline(detection)
            if found is not None:
                return found
            continue
        for candidate in _candidates(detection):
            found = outline(candidate)
            if found is None:
                continue
            key = _choice_key(found, candidate.score)
            if best is None or key > best[0]:
                best = (key, found, candidate.score)
            # Fast path: an outline the photo clearly supports, of a rock that
            # stood out clearly from every other region, needs no rival.
            if best[1].rocks[0].score >= FAST_SCORE and _unrivalled(detection):
                return best[1]
    if best is None:
        raise NoRockFoundError("no rock found: nothing stands out from the ground")
    _, incumbent, detection_score = best
    for found in outline.refined(incumbent):
        key = _choice_key(found, detection_score)
        if key > best[0]:
            best = (key, found, detection_score)
    return best[1]


#: A main rock's segmentation score from which no other candidate is tried (the fast path).
FAST_SCORE = 0.95


def _unrivalled(detection: _Detection) -> bool:
    """Whether the main region's detection score is far above every other region's."""
    rivals = [
        score for score, region, _ in detection.alternatives if _overlap(region, detection.regions[0]) < 0.5
    ]
    return not rivals or max(rivals) <= _RIVAL_SHARE * detection.score


#: Share of the main region's detection score that a rival must stay under for the fast path.
_RIVAL_SHARE = 0.25


def _candidates(detection: _Detection) -> Iterator[_Detection]:
    """The detection's main rock, then its alternatives (whole regions, runners-up, the other polarity)."""
    yield detection
    seen = [detection.regions[0]]
    for score, region, polarity in detection.alternatives:
        if any(_overlap(region, other) > 0.9 for other in seen):
            continue
        seen.append(region)
        yield dataclasses.replace(detection, score=score, regions=[region], polarity=polarity, others=[])


def _overlap(a: NDArray[np.bool_], b: NDArray[np.bool_]) -> float:
    """Intersection over union of two masks."""
    union = int((a | b).sum())
    return float((a & b).sum()) / union if union else 0.0


def _choice_key(found: Segmentation, detection_score: float) -> float:
    """Rank of a candidate main rock: its segmentation score, a little for how it was detected.

    A pebble or a highlight can be outlined as crisply as the rock it lies
    on or by: of outlines about as well supported, the one whose region
    stood out more (larger, clearer, off the frame, nearer the centre) wins.
    """
    return found.rocks[0].score * max(detection_score, 0.0) ** _DETECTION_WEIGHT


#: Exponent of a candidate's detection score in its rank (a tenth of it costs a quarter of the rank).
_DETECTION_WEIGHT = 0.125


@dataclass(frozen=True, eq=False)
class _Outliner:
    """Outlines a detection's rocks at working size (module docstring, step 6) and scores them."""

    levels: list[NDArray[np.generic]]
    dtype: np.dtype
    small_shape: tuple[int, int]
    detect_covered: tuple[float, float]
    detect_scale: float
    largest_scale: float
    config: SegmentConfig
    #: The working image, its scale and the detection of each segmentation made.
    works: dict = dataclasses.field(default_factory=dict)

    def __call__(self, detection: _Detection) -> Segmentation | None:
        config = self.config
        # Outline on an image where the smallest rock found spans about
        # outline_radius pixels: finer costs time and adds nothing to its shape.
        smallest = min(int(r.sum()) for r in detection.regions)
        radius_photo = math.sqrt(smallest / math.pi) * self.detect_scale
        work_scale = min(max(self.largest_scale, radius_photo / config.outline_radius), self.detect_scale)
        work, covered = _at_scale(self.levels, work_scale)
        scale_rowcol = (covered[0] / work.shape[0], covered[1] / work.shape[1])
        # Working pixels per detection pixel, each image over the photo pixels it covers.
        up = (
            self.detect_covered[0] / self.small_shape[0] / scale_rowcol[0],
            self.detect_covered[1] / self.small_shape[1] / scale_rowcol[1],
        )
        rocks = []
        # Neighbours that are no rock of their own still bound a rock's territory.
        owners = territories(detection.regions + detection.others)
        for index, region in enumerate(detection.regions, start=1):
            rock = _outline_rock(work, self.dtype, region, owners == index, up, detection, config)
            if rock is not None:
                rocks.append(rock)
        if not rocks:
            return None
        polarity = detection.polarity
        if detection.channel.name != "luminance":
            polarity = _luminance_polarity(work, self.dtype, rocks[0])
        found = _assemble(rocks, work.shape[:2], scale_rowcol, polarity, detection.channel.name)
        self.works[id(found)] = (work, up, detection)
        return found

    def refined(self, found: Segmentation) -> Iterator[Segmentation]:
        """Other outlines of a found main rock: GrabCut from it, and the Otsu part under the centre."""
        work, up, detection = self.works[id(found)]
        rock = found.rocks[0]
        to_row = np.minimum(
            ((np.arange(work.shape[0]) + 0.5) / up[0]).astype(np.int64), self.small_shape[0] - 1
        )
        to_col = np.minimum(
            ((np.arange(work.shape[1]) + 0.5) / up[1]).astype(np.int64), self.small_shape[1] - 1
        )
        for mask in (_grabcut(work, self.dtype, rock), _centre_part(work, self.dtype)):
            if mask is None or not mask.any():
                continue
            candidate = RockMask(mask=mask, coverage=mask.astype(np.float32), origin_rowcol=(0, 0))
            candidate = _cropped(
                _scored(work, self.dtype, candidate, (to_row, to_col), up, detection, self.config)
            )
            yield _assemble([candidate], work.shape[:2], found.scale_rowcol, found.polarity, found.channel)


def _assemble(
    rocks: list[RockMask],
    shape: tuple[int, int],
    scale_rowcol: tuple[float, float],
    polarity: str,
    channel: str,
) -> Segmentation:
    """A segmentation of outlined rocks, by decreasing area."""
    rocks = sorted(rocks, key=lambda r: -r.area)
    labels = np.zeros(shape, np.int32)
    for index, rock in enumerate(rocks, start=1):
        r0, c0 = rock.origin_rowcol
        h, w = rock.mask.shape
        view = labels[r0 : r0 + h, c0 : c0 + w]
        view[rock.mask & (view == 0)] = index
    return Segmentation(
        labels=labels, rocks=tuple(rocks), scale_rowcol=scale_rowcol, polarity=polarity, channel=channel
    )


def _cropped(rock: RockMask) -> RockMask:
    """The rock in the smallest window that holds it, with a pixel to spare."""
    ys, xs = np.nonzero(rock.mask)
    r0, r1 = max(0, ys.min() - 1), min(rock.mask.shape[0], ys.max() + 2)
    c0, c1 = max(0, xs.min() - 1), min(rock.mask.shape[1], xs.max() + 2)
    o0, o1 = rock.origin_rowcol
    return dataclasses.replace(
        rock,
        mask=rock.mask[r0:r1, c0:c1],
        coverage=rock.coverage[r0:r1, c0:c1],
        origin_rowcol=(o0 + int(r0), o1 + int(c0)),
    )


def _grabcut(work: NDArray[np.generic], dtype: np.dtype, rock: RockMask) -> NDArray[np.bool_] | None:
    """OpenCV's GrabCut (colour models of rock and ground, cut along edges) started from an outline.

    Pixels well inside the outline are rock, well outside ground, the band
    between undecided. Returns the rock over the whole working image.
    """
    import cv2

    rows, cols = work.shape[:2]
    r0, c0 = rock.origin_rowcol
    h, w = rock.mask.shape
    radius = math.sqrt(max(rock.area, 1) / math.pi)
    pad = round(max(8.0, 0.6 * radius))
    R0, R1, C0, C1 = max(0, r0 - pad), min(rows, r0 + h + pad), max(0, c0 - pad), min(cols, c0 + w + pad)
    m = np.zeros((R1 - R0, C1 - C0), np.uint8)
    m[r0 - R0 : r0 - R0 + h, c0 - C0 : c0 - C0 + w] = rock.mask
    disk = _disk(max(2, round(0.25 * radius)))
    trimap = np.full(m.shape, cv2.GC_BGD, np.uint8)
    trimap[cv2.dilate(m, disk) > 0] = cv2.GC_PR_BGD
    trimap[m > 0] = cv2.GC_PR_FGD
    sure = cv2.erode(m, disk) > 0
    if not sure.any():
        return None
    trimap[sure] = cv2.GC_FGD
    window = _unit(np.ascontiguousarray(work[R0:R1, C0:C1]), dtype)
    if window.ndim == 2:
        window = np.repeat(window[..., None], 3, axis=2)
    image = np.ascontiguousarray((window * 255).astype(np.uint8))
    bgd, fgd = np.zeros((1, 65), np.float64), np.zeros((1, 65), np.float64)
    # GrabCut starts its colour models by k-means from OpenCV's random state:
    # seeded, the same photo gives the same outline every time.
    cv2.setRNGSeed(0)
    try:
        cv2.grabCut(image, trimap, None, bgd, fgd, _GRABCUT_ITERATIONS, cv2.GC_INIT_WITH_MASK)
    except cv2.error:
        return None
    fg = ((trimap == cv2.GC_FGD) | (trimap == cv2.GC_PR_FGD)).astype(np.uint8)
    count, labels = cv2.connectedComponents(fg, connectivity=4)
    overlap = np.bincount(labels[sure], minlength=count)
    overlap[0] = 0
    out = np.zeros((rows, cols), bool)
    out[R0:R1, C0:C1] = _fill_holes(labels == int(np.argmax(overlap)))
    return out


#: GrabCut's rounds of colour models and cut.
_GRABCUT_ITERATIONS = 3


def _centre_part(work: NDArray[np.generic], dtype: np.dtype) -> NDArray[np.bool_] | None:
    """The Otsu class under the frame's centre, holes filled, cut at necks from touching neighbours."""
    import cv2

    gray = to_gray(work) if work.ndim == 3 else _unit(work, dtype)
    gray8 = cv2.GaussianBlur((gray * 255).astype(np.uint8), (5, 5), 0)
    _, binary = cv2.threshold(gray8, 0, 1, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    rows, cols = binary.shape
    if not binary[rows // 2, cols // 2]:
        binary = 1 - binary
    _, labels = cv2.connectedComponents(binary, connectivity=4)
    region = _fill_holes(labels == labels[rows // 2, cols // 2])
    for part in split_necks(region, 0.01 * rows * cols):
        if part[rows // 2, cols // 2]:
            return part
    return region


# ---------------------------------------------------------------- input and channels


_LUMA = np.array([0.299, 0.587, 0.114], np.float32)


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
    return arr


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
    """Values in [0, 1] as float32: integers by their type's maximum, floats clipped."""
    if dtype.kind in "ui":
        return arr.astype(np.float32) * np.float32(1.0 / np.iinfo(dtype).max)
    return np.clip(arr.astype(np.float32), 0.0, 1.0)


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

    def values(self, image: NDArray[np.float32]) -> NDArray[np.float32]:
        if image.ndim == 2:
            return image
        if self.direction is None:
            return image @ _LUMA
        total = image.sum(axis=2)
        # Chromaticity is noise where there is no light; the darkest pixels get the mean.
        projected = (image @ self.direction - self.center @ self.direction * total) / np.maximum(total, 0.06)
        return np.where(total > 0.06, projected, 0.0).astype(np.float32)


def _channels(small: NDArray[np.float32]) -> Iterator[_Channel]:
    """Candidate channels, learnt from the detection image (module docstring, step 2).

    A generator: the chromaticity is only worked out if luminance finds no rock.
    """
    yield _Channel("luminance", True)
    if small.ndim == 2:
        return
    total = small.sum(axis=2)
    lit = total > 0.06
    if lit.sum() < 16:
        return
    chroma = small[lit] / total[lit, None]
    center = chroma.mean(axis=0)
    values, vectors = np.linalg.eigh(np.cov(chroma.T))
    # A chromaticity that barely varies (a gray or evenly tinted photo) adds nothing.
    if values[-1] > 1e-5:
        direction = vectors[:, -1].astype(np.float32)
        yield _Channel("chromaticity", False, direction, center.astype(np.float32))


# ---------------------------------------------------------------- detection


@dataclass(frozen=True, eq=False)
class _Detection:
    """What detection found in one channel, and what the outline step needs from it."""

    score: float
    regions: list[NDArray[np.bool_]]
    polarity: str
    lighting: NDArray[np.float32]
    channel: _Channel
    outliers: NDArray[np.bool_]
    #: Every other rock-like region of the rocks' polarity (neighbours in a crop).
    others: list[NDArray[np.bool_]]
    #: Regions that might be the main rock instead: (score, region, polarity), best first.
    alternatives: list[tuple[float, NDArray[np.bool_], str]]


def _poly_terms(rows_norm: NDArray[np.float64], cols_norm: NDArray[np.float64], degree: int) -> list:
    return [cols_norm**i * rows_norm**j for i in range(degree + 1) for j in range(degree + 1 - i)]


def _norm_coords(n: int) -> NDArray[np.float64]:
    """Pixel centres of an axis of n pixels mapped to [-1, 1] (frame edges at -1 and 1)."""
    return (np.arange(n) + 0.5) / n * 2.0 - 1.0


def _fit_lighting(image: NDArray[np.float32], ground: NDArray[np.bool_], degree: int) -> NDArray[np.float64]:
    """Polynomial surface through the ground pixels; its coefficients.

    Least squares, twice more without the pixels beyond 2.5 robust standard
    deviations of the fit: a rock that reaches into the ground pixels, a
    pebble or a shadow then do not bend the surface.
    """
    rows, cols = image.shape
    # Every fourth pixel each way is plenty for a smooth surface and sixteen times cheaper.
    rr, cc = np.nonzero(ground[::4, ::4])
    rr, cc = rr * 4, cc * 4
    if rr.size < 3 * (degree + 1) ** 2:
        rr, cc = np.nonzero(ground)
    if rr.size == 0:
        return np.array([float(image.mean())])
    terms = np.stack(_poly_terms(_norm_coords(rows)[rr], _norm_coords(cols)[cc], degree), axis=1)
    values = image[rr, cc].astype(np.float64)
    keep = np.ones(values.size, bool)
    for _ in range(3):
        t, v = terms[keep], values[keep]
        gram = t.T @ t
        gram[np.diag_indices_from(gram)] += 1e-9 * max(float(np.trace(gram)), 1.0)
        coef = np.linalg.solve(gram, t.T @ v)
        residual = values - terms @ coef
        # The mean absolute deviation (times 1.25, a normal's ratio) is robust
        # enough here, and needs no sort.
        kept = residual[keep]
        spread = 1.2533 * float(np.abs(kept - kept.mean()).mean())
        inliers = np.abs(residual) <= 2.5 * max(spread, 1e-6)
        if inliers.sum() < terms.shape[1] * 3:
            break
        keep = inliers
    return coef


def _eval_lighting(
    coef: NDArray[np.float64], rows_norm: NDArray[np.float64], cols_norm: NDArray[np.float64]
) -> NDArray[np.float32]:
    degree = round((math.sqrt(8 * coef.size + 1) - 3) / 2)
    # sum_ij c_ij x^i y^j = Y C X^T with Vandermonde matrices: one matrix product.
    grid = np.zeros((degree + 1, degree + 1))
    pairs = [(i, j) for i in range(degree + 1) for j in range(degree + 1 - i)]
    for c, (i, j) in zip(coef, pairs, strict=True):
        grid[j, i] = c
    rows_v = rows_norm[:, None] ** np.arange(degree + 1)
    cols_v = cols_norm[:, None] ** np.arange(degree + 1)
    return (rows_v @ grid @ cols_v.T).astype(np.float32)


def _local_residual(
    residual: NDArray[np.float32], ground: NDArray[np.bool_], sigma: float
) -> NDArray[np.float32]:
    """What the polynomial misses of the ground's lighting (a dark corner, a
    bright patch): the ground's residual spread by a normalised Gaussian."""
    import cv2

    rows, cols = residual.shape
    # So wide a blur loses nothing on a copy a few pixels per sigma.
    factor = max(1, int(sigma // 3))
    size = (max(4, cols // factor), max(4, rows // factor))
    weight = cv2.resize(ground.astype(np.float32), size, interpolation=cv2.INTER_AREA)
    spread = cv2.resize(
        np.where(ground, residual, 0.0).astype(np.float32), size, interpolation=cv2.INTER_AREA
    )
    small_sigma = sigma * size[0] / cols
    weight = cv2.GaussianBlur(weight, (0, 0), small_sigma, borderType=cv2.BORDER_REFLECT)
    spread = cv2.GaussianBlur(spread, (0, 0), small_sigma, borderType=cv2.BORDER_REFLECT)
    local = np.where(weight > 1e-3, spread / np.maximum(weight, 1e-6), 0.0).astype(np.float32)
    return cv2.resize(local, (cols, rows), interpolation=cv2.INTER_LINEAR)


def _window_of(
    small: NDArray[np.float32], up: tuple[float, float], box: tuple[int, int, int, int]
) -> NDArray[np.float32]:
    """A smooth detection-size map, bilinearly enlarged to working size, inside a window.

    ``up`` is working pixels per detection pixel (rows, cols); ``box`` the
    window (r0, r1, c0, c1) in working pixels.
    """
    import cv2

    r0, r1, c0, c1 = box
    # Working pixel centre (r, c) sits at detection pixel ((r + 0.5) / up - 0.5).
    inverse = np.array(
        [[1.0 / up[1], 0.0, (c0 + 0.5) / up[1] - 0.5], [0.0, 1.0 / up[0], (r0 + 0.5) / up[0] - 0.5]]
    )
    flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    return cv2.warpAffine(small, inverse, (c1 - c0, r1 - r0), flags=flags, borderMode=cv2.BORDER_REPLICATE)


def _flatten(
    image: NDArray[np.float32], lighting: NDArray[np.float32], multiplicative: bool
) -> NDArray[np.float32]:
    if multiplicative:
        # The offset keeps a nearly black ground from amplifying its noise without bound.
        return (image - lighting) / (np.maximum(lighting, 0.0) + np.float32(0.05))
    return image - lighting


def _smooth(image: NDArray[np.float32], median: int, sigma: float) -> NDArray[np.float32]:
    import cv2

    if median > 1:
        image = cv2.medianBlur(np.ascontiguousarray(image, dtype=np.float32), median)
    if sigma > 0:
        image = cv2.GaussianBlur(image, (0, 0), sigma)
    return image


def _detect(
    channel_values: NDArray[np.float32], channel: _Channel, config: SegmentConfig, all_rocks: bool
) -> _Detection | None:
    """Find rocks in one channel at detection size (module docstring, steps 3-5)."""
    import cv2

    if float(channel_values.max()) - float(channel_values.min()) < 1e-3:
        return None
    # detect_sigma is in pixels of a detect_size image: a smaller photo is smoothed less.
    sigma = config.detect_sigma * min(1.0, max(channel_values.shape) / config.detect_size)
    image = _smooth(channel_values, config.median, sigma)
    rows, cols = image.shape
    rows_norm, cols_norm = _norm_coords(rows), _norm_coords(cols)
    min_area = max(12.0, config.min_area_fraction * rows * cols)
    # The ground is first learnt from the frame's border, where a rock that
    # lies inside the frame is not, whatever share of the frame it covers.
    width = max(2, round(0.04 * min(rows, cols)))
    ground = np.zeros((rows, cols), dtype=bool)
    ground[:width], ground[-width:], ground[:, :width], ground[:, -width:] = True, True, True, True
    kernel = np.ones((5, 5), np.uint8)
    fit_ground = stat_ground = ground
    for round_ in range(config.iterations + 1):
        coef = _fit_lighting(image, fit_ground, config.lighting_degree)
        lighting = _eval_lighting(coef, rows_norm, cols_norm)
        if round_ > 0 and config.lighting_sigma > 0:
            lighting = lighting + _local_residual(
                image - lighting, fit_ground, config.lighting_sigma * max(rows, cols)
            )
        flat = _flatten(image, lighting, channel.multiplicative)
        # A smooth ground has a tiny spread; the floor keeps a rock at least
        # min_contrast from it, so that noise and JPEG blocks are no rock.
        z = _robust_z(flat, stat_ground, config.min_contrast / config.z_detect)
        last = round_ == config.iterations
        # Before the last round every rock counts, not only the main one: a
        # neighbour intruding into a crop is no ground for the next round.
        found = _best_regions(z, config, min_area, all_rocks or not last, split=last)
        if found is None and round_ == 0:
            # Nothing stands out against the whole border's spread: neighbours
            # reaching into a crop may have widened it. Try most stretches' spread.
            z = _robust_z(flat, stat_ground, config.min_contrast / config.z_detect, local=True)
            found = _best_regions(z, config, min_area, all_rocks or not last, split=last)
        if found is None:
            return None
        outliers = np.abs(z) > config.z_grow
        if last:
            break
        # Next round the ground is everything but the rocks. The lighting fit
        # also leaves out anything else far from the ground on either side
        # (pebbles, shadows, glints); the ground's spread does not, or it
        # would shrink round after round.
        rocks = cv2.dilate(np.logical_or.reduce(found[1]).astype(np.uint8), kernel) > 0
        far = cv2.dilate((np.abs(z) > config.z_grow).astype(np.uint8), kernel) > 0
        if (~rocks).mean() < 0.1:
            break
        stat_ground = ~rocks
        fit_ground = ~(rocks | far) if (~(rocks | far)).mean() >= 0.1 else stat_ground
    score, regions, polarity, others, alternatives = found
    return _Detection(score, regions, polarity, lighting, channel, outliers, others, alternatives)


def _luminance_polarity(work: NDArray[np.generic], dtype: np.dtype, rock: RockMask) -> str:
    """Whether a rock found by its hue is lighter or darker than the ground around it."""
    r0, c0 = rock.origin_rowcol
    h, w = rock.mask.shape
    lum = _Channel("luminance", True).values(_unit(work[r0 : r0 + h, c0 : c0 + w], dtype))
    outside = lum[~rock.mask]
    if outside.size == 0:
        return "light"
    return "light" if float(np.median(lum[rock.mask])) > float(np.median(outside)) else "dark"


def _robust_z(
    flat: NDArray[np.float32], ground: NDArray[np.bool_], floor: float, *, local: bool = False
) -> NDArray[np.float32]:
    """Deviation from the ground in robust standard deviations (median, MAD, at least ``floor``;
    with ``local``, at most the typical spread of the ground's stretches)."""
    values = flat[ground] if ground.sum() > 50 else flat.ravel()
    # Every fourth value gives the same statistics at a quarter of the cost.
    values = values[::4] if values.size > 4000 else values
    median = float(np.median(values))
    mad = float(np.median(np.abs(values - median))) * 1.4826
    if local:
        # Neighbours reaching into the frame's border (a crop) widen the MAD
        # of the whole band; the ground's own spread is that of most of its
        # stretches, each about even.
        mad = min(mad, _stretch_spread(flat, ground))
    spread = max(mad, floor, 1e-6)
    return ((flat - median) / spread).astype(np.float32)


def _stretch_spread(flat: NDArray[np.float32], ground: NDArray[np.bool_]) -> float:
    """Median over an 8 x 8 grid of the frame of the ground's robust spread in each cell."""
    rows, cols = flat.shape
    spreads = []
    for r in range(8):
        for c in range(8):
            cell = (slice(r * rows // 8, (r + 1) * rows // 8), slice(c * cols // 8, (c + 1) * cols // 8))
            values = flat[cell][ground[cell]]
            if values.size >= 12:
                spreads.append(1.4826 * float(np.median(np.abs(values - np.median(values)))))
    return float(np.median(spreads)) if len(spreads) >= 4 else math.inf


#: Contrast beyond which a pixel counts no more toward its region's edge step,
#: in robust standard deviations: a few glints must not outweigh a rock.
_Z_CAP = 30.0


def _best_regions(
    z: NDArray[np.float32], config: SegmentConfig, min_area: float, all_rocks: bool, *, split: bool = True
) -> tuple[float, list[NDArray[np.bool_]], str, list[NDArray[np.bool_]], list] | None:
    """Score of the main rock, the rock regions, their polarity and the other candidate regions
    (module docstring, steps 4-5), and the alternatives for the main rock, best first."""
    import cv2

    rows, cols = z.shape
    best = None
    alternatives: list[tuple[float, NDArray[np.bool_], str]] = []
    polarities = ("light", "dark") if config.polarity == "auto" else (config.polarity,)
    for polarity in polarities:
        signed = z if polarity == "light" else -z
        # Hysteresis: regions grow from seeds beyond z_detect through pixels beyond z_grow.
        candidate = (signed > config.z_grow).astype(np.uint8)
        count, labels, stats, _ = cv2.connectedComponentsWithStats(candidate, connectivity=8)
        if count <= 1:
            continue
        seeded = np.bincount(labels[signed > config.z_detect], minlength=count)[1:] > 0
        areas = stats[1:, cv2.CC_STAT_AREA]
        usable = np.flatnonzero(seeded & (areas >= min_area)) + 1
        if usable.size == 0:
            continue
        if split:
            # Touching rocks grow into one region: one region per rock (rockscan.core.segment.split).
            regions = [
                part
                for i in usable
                for part in split_rocks(signed, labels == i, min_area, config.z_grow)
                if part.sum() >= min_area and (signed[part] > config.z_detect).any()
            ]
        else:
            regions = [labels == i for i in usable]
        if not regions:
            continue
        scores = _region_scores(signed, regions)
        candidates = regions
        if not all_rocks:
            # A crop is centred on its rock: of two rocks alike, the nearer the centre.
            scores = scores * _centre_weight(regions, (rows, cols))
        main = int(np.argmax(scores))
        total = float(scores[main])
        if not all_rocks:
            # Runners-up for the main rock, which the outline's own evidence may prefer.
            ranked = [int(i) for i in np.argsort(-scores, kind="stable")[:_ALTERNATIVES] if scores[i] > 0]
            # A crop is centred on its rock: the region under the centre competes too.
            ranked += [i for i, r in enumerate(regions) if r[rows // 2, cols // 2] and i not in ranked]
            alternatives.extend((float(scores[i]), regions[i], polarity) for i in ranked)
            if total > 0:
                # The main rock's whole region, before it was split: texture on a
                # rock can look like a dip between two.
                ys, xs = np.nonzero(regions[main])
                whole = labels == labels[ys[0], xs[0]]
                if whole.sum() > 1.2 * ys.size:
                    alternatives.append((total, whole, polarity))
        if total <= 0 or (best is not None and total <= best[0]):
            continue
        areas_r = np.array([float(r.sum()) for r in regions])
        if all_rocks:
            # Another rock stands out about as clearly as the main one; ground
            # texture that passes the thresholds scores far less.
            keep = (scores >= _RELATIVE_SCORE * total) & (areas_r >= config.min_relative_area * areas_r[main])
            regions = [
                part
                for i in np.flatnonzero(keep)
                for part in (_split(regions[i], signed, min_area) if split else [regions[i]])
            ]
            if not regions:
                continue
            largest = max(int(r.sum()) for r in regions)
            regions = [r for r in regions if r.sum() >= config.min_relative_area * largest]
            regions.sort(key=lambda r: -int(r.sum()))
        else:
            parts = _split(regions[main], signed, min_area) if split else []
            regions = [max(parts, key=lambda r: int(r.sum()))] if parts else [regions[main]]
        # In a crop, the neighbours that would be rocks with --all.
        others = [
            candidates[i]
            for i in range(len(candidates))
            if i != main
            and not all_rocks
            and scores[i] >= _RELATIVE_SCORE * total
            and candidates[i].sum() >= config.min_relative_area * candidates[main].sum()
        ]
        best = (total, regions, polarity, others)
    if best is None:
        return None
    alternatives.sort(key=lambda a: -a[0])
    # The chosen region first among the alternatives: whole, before any cut.
    return (*best, alternatives)


def _region_scores(signed: NDArray[np.float32], regions: list[NDArray[np.bool_]]) -> NDArray[np.float64]:
    """How clearly each region stands out as a rock (module docstring, step 5).

    Its area, times its edge step, times its compactness, times the square of
    the share of its edge that does not run along the frame's.
    """
    import cv2

    rows, cols = signed.shape
    labels = np.zeros((rows, cols), np.int32)
    for i, region in enumerate(regions, start=1):
        labels[region & (labels == 0)] = i
    count = len(regions) + 1
    band = np.ones((5, 5), np.uint8)
    as_float = labels.astype(np.float32)
    # Edge step: mean contrast just inside a region less just outside it.
    # A rock's edge is a step as high as its contrast; a blob of texture
    # fades out and barely steps at its edge. Two touching rocks each have an
    # edge along the cut between them.
    inner = (labels > 0) & (
        (cv2.erode(as_float, band) != as_float) | (cv2.dilate(as_float, band) != as_float)
    )
    outer_labels = cv2.dilate(as_float, band).astype(np.int64)
    outer = (labels == 0) & (outer_labels > 0)
    clipped = np.minimum(signed, _Z_CAP)
    inner_n = np.bincount(labels[inner], minlength=count)[1:]
    inner_sum = np.bincount(labels[inner], weights=clipped[inner], minlength=count)[1:]
    outer_n = np.bincount(outer_labels[outer], minlength=count)[1:]
    outer_sum = np.bincount(outer_labels[outer], weights=clipped[outer], minlength=count)[1:]
    step = inner_sum / np.maximum(inner_n, 1) - outer_sum / np.maximum(outer_n, 1)
    # The share of a region's edge that is the frame's edge: a rock lies
    # inside the frame, the ground (or a lighting residue) runs along it.
    # The inner band is two pixels wide: half its count is the perimeter.
    edge = np.zeros((rows, cols), bool)
    edge[0], edge[-1], edge[:, 0], edge[:, -1] = True, True, True, True
    perimeter = np.maximum(inner_n / 2.0, 1.0)
    on_edge = np.bincount(labels[edge], minlength=count)[1:]
    share = np.clip(on_edge / perimeter, 0.0, 1.0)
    # Rocks are solid; the ground between several rocks, or a blob of
    # texture, has a long ragged edge for its area (1 for a disc).
    areas = np.bincount(labels.ravel(), minlength=count)[1:].astype(np.float64)
    compactness = np.minimum(4.0 * np.pi * areas / perimeter**2, 1.0)
    return areas * np.maximum(step, 0.0) * compactness * (1.0 - share) ** 2


def _centre_weight(regions: list[NDArray[np.bool_]], shape: tuple[int, int]) -> NDArray[np.float64]:
    """1 at the frame's centre, falling to ``1 - _CENTRE_PRIOR`` at its corners (squared distance)."""
    weights = []
    for region in regions:
        ys, xs = np.nonzero(region)
        dy = (ys.mean() + 0.5) / shape[0] * 2.0 - 1.0
        dx = (xs.mean() + 0.5) / shape[1] * 2.0 - 1.0
        weights.append(1.0 - _CENTRE_PRIOR * 0.5 * (dy * dy + dx * dx))
    return np.array(weights)


#: Regions of each polarity that compete for the main rock.
_ALTERNATIVES = 3

#: How much a rock at a corner of the frame loses against one at its centre.
_CENTRE_PRIOR = 0.3


#: With several rocks, the smallest score of a rock as a fraction of the main rock's.
_RELATIVE_SCORE = 0.1


def _split(
    region: NDArray[np.bool_], signed: NDArray[np.float32], min_area: float
) -> list[NDArray[np.bool_]]:
    """A region cut into the rocks it holds, if its contrast has two clear levels.

    Growth at a low threshold joins a rock to a faint surround (a halo, a
    lighter patch of ground) or several rocks to each other through the ground
    between them. Then the region's contrast is bimodal, and Otsu's threshold
    parts rock from surround. A single rock's contrast, however textured, is
    one hump (Otsu's separation below ``_BIMODAL``) and is left whole. Parts
    smaller than ``min_area`` are dropped.
    """
    import cv2

    values = np.minimum(signed[region], _Z_CAP)
    threshold, separation = _otsu(values)
    if separation < _BIMODAL:
        return [region]
    count, labels, stats, _ = cv2.connectedComponentsWithStats(
        (region & (signed > threshold)).astype(np.uint8), connectivity=8
    )
    parts = [labels == i for i in range(1, count) if stats[i, cv2.CC_STAT_AREA] >= min_area]
    return parts or [region]


def _otsu(values: NDArray[np.float32]) -> tuple[float, float]:
    """Otsu's threshold of some values, and its separation (between-class over total variance)."""
    hist, edges = np.histogram(values, bins=64)
    centers = 0.5 * (edges[:-1] + edges[1:])
    w0 = np.cumsum(hist).astype(np.float64)
    w1 = w0[-1] - w0
    s0 = np.cumsum(hist * centers)
    m0 = s0 / np.maximum(w0, 1)
    m1 = (s0[-1] - s0) / np.maximum(w1, 1)
    between = w0 * w1 * (m0 - m1) ** 2 / w0[-1] ** 2
    i = int(np.argmax(between[:-1]))
    total = float(values.var())
    return float(edges[i + 1]), float(between[i] / total) if total > 0 else 0.0


#: Otsu's separation above which a region's contrast counts as two levels: a
#: single normal hump gives 2/pi = 0.64, two clearly apart levels near 1.
_BIMODAL = 0.8


# ---------------------------------------------------------------- outline at working size


#: Smoothing of the hue before it joins the brightness, in working pixels.
_HUE_SIGMA = 3.0
#: Red and blue less luminance (BT.601), the two hue coordinates.
_HUE_MATRIX = np.array([[0.701, -0.587, -0.114], [-0.299, -0.587, 0.886]], np.float32)

#: Pixel value (photo in [0, 1]) from which a pixel counts as clipped by the sensor.
_CEILING = 0.98


def _outline_rock(
    work: NDArray[np.generic],
    dtype: np.dtype,
    region: NDArray[np.bool_],
    territory: NDArray[np.bool_],
    up: tuple[float, float],
    detection: _Detection,
    config: SegmentConfig,
) -> RockMask | None:
    """Outline one detected rock at working size (module docstring, step 6)."""
    rows, cols = work.shape[:2]
    # Working pixel -> nearest detection pixel, along each axis.
    to_row = np.minimum(((np.arange(rows) + 0.5) / up[0]).astype(np.int64), region.shape[0] - 1)
    to_col = np.minimum(((np.arange(cols) + 0.5) / up[1]).astype(np.int64), region.shape[1] - 1)
    ys, xs = np.nonzero(region)
    r0, r1 = math.floor(ys.min() * up[0]), min(rows, math.ceil((ys.max() + 1) * up[0]))
    c0, c1 = math.floor(xs.min() * up[1]), min(cols, math.ceil((xs.max() + 1) * up[1]))
    detected = region[to_row[r0:r1, None], to_col[None, c0:c1]]
    estimate, origin = detected, (r0, c0)
    rock, reaches_edge = None, False
    # A rock only partly detected reaches its window's edge: look again in a
    # window around what was found. What still reaches it after three looks,
    # or has grown past four times the detection, has flooded the ground.
    for _ in range(3):
        rock, reaches_edge = _threshold_rock(
            work, dtype, estimate, origin, territory, (to_row, to_col), up, detection, config
        )
        if rock is None or not reaches_edge:
            break
        estimate, origin = rock.mask, rock.origin_rowcol
    if rock is None or reaches_edge or rock.area > 4.0 * float(detected.sum()):
        rock = _fallback(detected, (r0, c0))
    if rock is None:
        return None
    return _scored(work, dtype, rock, (to_row, to_col), up, detection, config)


def _scored(
    work: NDArray[np.generic],
    dtype: np.dtype,
    rock: RockMask,
    to_detect: tuple[NDArray[np.int64], NDArray[np.int64]],
    up: tuple[float, float],
    detection: _Detection,
    config: SegmentConfig,
) -> RockMask:
    """The rock with its segmentation score (rockscan.core.segment.score).

    The evidence is read on the flattened channel the rock was found in,
    as a level from the ground's (0, the median of a ring around the
    outline) to the rock's (1, the median inside).
    """
    import cv2

    rows, cols = work.shape[:2]
    o0, o1 = rock.origin_rowcol
    h, w = rock.mask.shape
    radius = math.sqrt(max(rock.area, 1) / math.pi)
    pad = round(max(6.0, 0.4 * radius))
    r0, r1 = max(0, o0 - pad), min(rows, o0 + h + pad)
    c0, c1 = max(0, o1 - pad), min(cols, o1 + w + pad)
    mask = np.zeros((r1 - r0, c1 - c0), bool)
    mask[o0 - r0 : o0 - r0 + h, o1 - c0 : o1 - c0 + w] = rock.mask
    window = _unit(np.ascontiguousarray(work[r0:r1, c0:c1]), dtype)
    values = _smooth(detection.channel.values(window), 1, config.smooth_sigma)
    lighting = _window_of(detection.lighting, up, (r0, r1, c0, c1))
    flat = _flatten(values, lighting, detection.channel.multiplicative)
    mask8 = mask.astype(np.uint8)
    inside = cv2.distanceTransform(mask8, cv2.DIST_L2, 3) > max(1.0, 0.15 * radius)
    core = flat[inside] if inside.sum() >= 4 else flat[mask]
    outside = cv2.distanceTransform(1 - mask8, cv2.DIST_L2, 3)
    ring = (outside > max(3.0, 0.12 * radius)) & (outside <= max(6.0, 0.35 * radius))
    ground = float(np.median(flat[ring])) if ring.sum() >= 8 else 0.0
    step = float(np.median(core)) - ground
    if not math.isfinite(step) or abs(step) < 1e-6:
        return dataclasses.replace(rock, score=0.0, evidence=())
    sides = (r0 == 0, r1 == rows, c0 == 0, c1 == cols)
    level = ((flat - np.float32(ground)) / np.float32(step)).astype(np.float32)
    evidence = outline_evidence(level, mask, sides)
    return dataclasses.replace(
        rock, score=outline_score(evidence), evidence=tuple(float(v) for v in evidence.as_array())
    )


def _threshold_rock(
    work: NDArray[np.generic],
    dtype: np.dtype,
    estimate: NDArray[np.bool_],
    origin: tuple[int, int],
    territory: NDArray[np.bool_],
    to_detect: tuple[NDArray[np.int64], NDArray[np.int64]],
    up: tuple[float, float],
    detection: _Detection,
    config: SegmentConfig,
) -> tuple[RockMask | None, bool]:
    """Threshold half-way between rock and ground in a window around an estimate of the rock.

    Returns the rock and whether it reaches an edge of the window that is not
    the frame's.
    """
    import cv2

    rows, cols = work.shape[:2]
    ys, xs = np.nonzero(estimate)
    if ys.size == 0:
        return None, False
    radius = math.sqrt(ys.size / math.pi)
    pad = round(max(6.0, 0.5 * radius))
    r0 = max(0, origin[0] + int(ys.min()) - pad)
    r1 = min(rows, origin[0] + int(ys.max()) + 1 + pad)
    c0 = max(0, origin[1] + int(xs.min()) - pad)
    c1 = min(cols, origin[1] + int(xs.max()) + 1 + pad)
    detected = np.zeros((r1 - r0, c1 - c0), bool)
    detected[ys + origin[0] - r0, xs + origin[1] - c0] = True
    to_row, to_col = to_detect
    others = detection.outliers[to_row[r0:r1, None], to_col[None, c0:c1]] & ~detected

    window = _unit(np.ascontiguousarray(work[r0:r1, c0:c1]), dtype)
    values = _smooth(detection.channel.values(window), 1, config.smooth_sigma)
    lighting = _window_of(detection.lighting, up, (r0, r1, c0, c1))
    flat = _flatten(values, lighting, detection.channel.multiplicative)

    # Distances to the detection's edge, inside and outside, give the core and
    # the ring without large structuring elements.
    det8 = detected.astype(np.uint8)
    inside_dist = cv2.distanceTransform(det8, cv2.DIST_L2, 3)
    outside_dist = cv2.distanceTransform(1 - det8, cv2.DIST_L2, 3)
    margin = max(2.0, 0.15 * radius)
    core = inside_dist > margin
    if core.sum() < 4:
        core = detected
    ring = (outside_dist > margin) & (outside_dist <= margin + max(3.0, 0.3 * radius))
    ring &= cv2.dilate(others.astype(np.uint8), np.ones((5, 5), np.uint8)) == 0
    if ring.sum() < 8:
        ring = outside_dist > margin
    if ring.sum() < 8:
        return _fallback(detected, (r0, c0)), False
    level = _level(window, flat, lighting, core, ring, detection.channel)
    if level is None:
        return _fallback(detected, (r0, c0)), False
    if detection.channel.multiplicative and detection.polarity == "light":
        # A sensor's ceiling hides how much brighter than its ground a light
        # rock is; where it clips, the rock is at least at its own level.
        ceiling = (window.max(axis=2) if window.ndim == 3 else window) >= _CEILING
        # Clipped ground (a glaring corner) stays ground: only what already rises is lifted.
        ceiling &= level > 0.25
        level[ceiling] = np.maximum(level[ceiling], 1.0)
    # A touching neighbour beyond half-way is not this rock: keep to its territory.
    own = territory[to_row[r0:r1, None], to_col[None, c0:c1]]
    count, labels = cv2.connectedComponents(((level > 0.5) & own).astype(np.uint8), connectivity=4)
    overlap = np.bincount(labels[core], minlength=count)
    overlap[0] = 0
    if overlap.max() == 0:
        return _fallback(detected, (r0, c0)), False
    mask = _fill_holes(labels == int(np.argmax(overlap)))
    if mask.sum() < 0.25 * detected.sum():
        return _fallback(detected, (r0, c0)), False
    coverage = np.clip(level, 0.0, 1.0).astype(np.float32)
    # Only this rock's own edge: filled holes count as rock, anything beyond
    # a pixel of its mask as ground.
    coverage[mask & (coverage < 0.5)] = 1.0
    coverage[~(cv2.dilate(mask.astype(np.uint8), _disk(1)) > 0)] = 0.0
    coverage[~mask & (coverage >= 0.5)] = 0.49
    touching = (
        (r0 > 0 and mask[0].any())
        or (r1 < rows and mask[-1].any())
        or (c0 > 0 and mask[:, 0].any())
        or (c1 < cols and mask[:, -1].any())
    )
    return RockMask(mask=mask, coverage=coverage, origin_rowcol=(r0, c0)), bool(touching)


def _level(
    window: NDArray[np.float32],
    flat: NDArray[np.float32],
    lighting: NDArray[np.float32],
    core: NDArray[np.bool_],
    ring: NDArray[np.bool_],
    channel: _Channel,
) -> NDArray[np.float32] | None:
    """Where each pixel lies from the ground's level (0) to the rock's (1).

    A gray photo is measured by its flattened brightness. In colour, rock and
    ground are told apart along Fisher's discriminant of the flattened
    brightness and the smoothed hue (two colour differences), from the core's
    and the ring's means and pooled covariance: a rock's hue then counts as
    well as its brightness, and ground texture, which mostly varies the
    ground's brightness, counts less; brightness keeps at least half of the
    step between the two. Either way the levels are medians over the core and
    the ring.
    """
    import cv2

    core_at, ring_at = _sample_at(core), _sample_at(ring)
    projected = flat
    flat_values = flat.ravel()
    rock_lum, ground_lum = flat_values[core_at], flat_values[ring_at]
    if window.ndim == 3 and channel.name == "luminance":
        inverse = 1.0 / (np.maximum(lighting, 0.0) + np.float32(0.05))
        # Red and blue less luminance, flattened like the brightness. Hue varies
        # slowly on a rock and JPEG stores it in coarse blocks: the outline's
        # position is left to the brightness, whose edge is sharp.
        hue = cv2.transform(window, _HUE_MATRIX) * inverse[..., None]
        hue = cv2.GaussianBlur(hue, (0, 0), _HUE_SIGMA).reshape(-1, 2)
        features_r = np.column_stack([rock_lum, hue[core_at]]).astype(np.float64)
        features_g = np.column_stack([ground_lum, hue[ring_at]]).astype(np.float64)
        if features_r.shape[0] > 8 and features_g.shape[0] > 8:
            pooled = 0.5 * (np.cov(features_r.T) + np.cov(features_g.T))
            pooled[np.diag_indices(3)] += 1e-6 * max(float(np.trace(pooled)), 1e-9)
            difference = features_r.mean(axis=0) - features_g.mean(axis=0)
            weights = np.linalg.solve(pooled, difference)
            # Brightness carries at least half of the step, so that the
            # outline stays at its sharp edge (hue is smoothed, and on a black
            # ground it would otherwise take over).
            from_brightness, from_hue = weights[0] * difference[0], weights[1:] @ difference[1:]
            if from_hue > from_brightness > 0:
                weights[1:] *= from_brightness / from_hue
            elif from_brightness <= 0:
                weights = np.array([1.0, 0.0, 0.0])
            weights = weights.astype(np.float32)
            projected = flat * weights[0] + (hue @ weights[1:]).reshape(flat.shape)
    values = projected.ravel()
    rock_level = float(np.median(values[core_at]))
    ground_level = float(np.median(values[ring_at]))
    step = rock_level - ground_level
    if not math.isfinite(step) or abs(step) < 1e-9:
        return None
    return ((projected - np.float32(ground_level)) / np.float32(step)).astype(np.float32)


def _sample_at(mask: NDArray[np.bool_], limit: int = 4096) -> NDArray[np.int64]:
    """Flat indices of at most about ``limit`` evenly spaced pixels of a mask:
    the statistics of a window need no more."""
    at = np.flatnonzero(mask)
    return at[:: max(1, at.size // limit)]


def _disk(radius: int) -> NDArray[np.uint8]:
    import cv2

    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))


def _fallback(detected: NDArray[np.bool_], origin: tuple[int, int]) -> RockMask | None:
    mask = _fill_holes(detected)
    if not mask.any():
        return None
    return RockMask(mask=mask, coverage=mask.astype(np.float32), origin_rowcol=origin)


def _fill_holes(mask: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """The mask with every enclosed hole filled (flood fill of the ground from outside)."""
    import cv2

    padded = np.zeros((mask.shape[0] + 2, mask.shape[1] + 2), np.uint8)
    padded[1:-1, 1:-1] = mask
    flood = np.zeros((padded.shape[0] + 2, padded.shape[1] + 2), np.uint8)
    cv2.floodFill(padded, flood, (0, 0), 2)
    return padded[1:-1, 1:-1] != 2


def _from_alpha(
    alpha: NDArray[np.float32], scale_rowcol: tuple[float, float], config: SegmentConfig, all_rocks: bool
) -> Segmentation:
    """Rocks cut out by an alpha channel: its opaque regions, alpha as coverage."""
    import cv2

    rows, cols = alpha.shape
    min_area = max(12.0, config.min_area_fraction * rows * cols)
    _, labels, stats, _ = cv2.connectedComponentsWithStats((alpha >= 0.5).astype(np.uint8), connectivity=8)
    areas = stats[1:, cv2.CC_STAT_AREA]
    order = [int(i) for i in np.argsort(-areas, kind="stable") if areas[i] >= min_area]
    if not order:
        raise NoRockFoundError("no rock found: the alpha channel cuts out nothing large enough")
    if all_rocks:
        order = [i for i in order if areas[i] >= config.min_relative_area * areas[order[0]]]
    else:
        order = order[:1]
    rocks, out = [], np.zeros((rows, cols), np.int32)
    for index, i in enumerate(order, start=1):
        mask = _fill_holes(labels == i + 1)
        coverage = np.where(mask, np.maximum(alpha, 0.5), np.minimum(alpha, 0.49)).astype(np.float32)
        coverage[~(cv2.dilate(mask.astype(np.uint8), _disk(1)) > 0)] = 0.0
        rocks.append(RockMask(mask=mask, coverage=coverage, origin_rowcol=(0, 0)))
        out[mask & (out == 0)] = index
    return Segmentation(
        labels=out, rocks=tuple(rocks), scale_rowcol=scale_rowcol, polarity="light", channel="alpha"
    )
