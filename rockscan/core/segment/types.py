"""Settings and results of segmentation: SegmentConfig, RockMask, Segmentation."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rockscan.core.choices import POLARITIES
from rockscan.core.errors import ParameterError

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
        With several rocks, smallest rock kept as a fraction of the largest
        (once touching rocks are parted).
    min_median_area : float
        With three rocks or more, smallest rock kept as a fraction of the
        median rock's area: what is smaller is a piece of a textured rock or
        a patch of ground between rocks (0 keeps every rock).
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
    min_relative_area: float = 0.05
    min_median_area: float = 0.2
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
            "min_median_area",
        ):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ParameterError(f"{name} must be a non-negative number, got {value!r}")
        for name, value, top in (
            ("outline_radius", self.outline_radius, self.work_size),
            ("lighting_sigma", self.lighting_sigma, 1.0),
            ("min_contrast", self.min_contrast, 1.0),
            # Wider than the image they smooth, they blur it flat and take minutes.
            ("detect_sigma", self.detect_sigma, self.detect_size / 4),
            ("smooth_sigma", self.smooth_sigma, self.work_size / 4),
        ):
            low_ok = value > 0 if name == "outline_radius" else value >= 0
            if not (isinstance(value, (int, float)) and math.isfinite(value) and low_ok and value <= top):
                low = "above 0" if name == "outline_radius" else "from 0"
                raise ParameterError(f"{name} must be a number {low} to {top:g}, got {value!r}")
        if not 0 < self.z_grow <= self.z_detect:
            raise ParameterError("z_grow must be positive and at most z_detect")
        if self.min_area_fraction >= 0.5 or self.min_relative_area > 1 or self.min_median_area > 1:
            raise ParameterError(
                "min_area_fraction must be below 0.5, min_relative_area and min_median_area at most 1"
            )
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
        Segmentation score in [0, 1]. For the main rock of a photo of one
        rock chosen among candidate outlines, an estimate of the probability
        that its outline is right (IoU >= 0.9 with the rock): read from the
        whole choice (``rockscan.core.segment.confidence``), or the choice
        model's own when the detected candidates alone decided.
        For a main rock the fast path took, for every rock found with
        ``all_rocks`` and for every candidate before the choice, how well
        the photo supports the outline (a step
        from the rock's level to the ground's all round it, rock inside,
        ground outside, off the frame, solid; see
        ``rockscan.core.segment.score``). Low means a likely wrong outline;
        below :data:`CONFIDENT_SCORE` the outline is not to be trusted.
    evidence : tuple of float
        The measurements the score is computed from (support, weak, outside,
        noise, frame, solidity).
    darker_outside : float
        Share of a band just outside the outline darker than the ground, away
        from the rock's level (``rockscan.core.segment.score.OutlineEvidence``).
    inner_spread : float
        Robust spread of the level inside the outline, in units of the step
        (``rockscan.core.segment.score.OutlineEvidence``).
    """

    mask: NDArray[np.bool_]
    coverage: NDArray[np.float32]
    origin_rowcol: tuple[int, int]
    score: float = 1.0
    evidence: tuple[float, ...] = ()
    darker_outside: float = 0.0
    inner_spread: float = 1.0

    @property
    def area(self) -> int:
        """Area in working pixels."""
        return int(np.count_nonzero(self.mask))

    @property
    def window(self) -> tuple[slice, slice]:
        """Where the mask lies on the working grid: ``grid[rock.window]`` is under it."""
        (r0, c0), (h, w) = self.origin_rowcol, self.mask.shape
        return slice(r0, r0 + h), slice(c0, c0 + w)

    def whole(self, shape: tuple[int, int]) -> NDArray[np.bool_]:
        """The mask over a whole grid of ``shape`` (the working image it was outlined on)."""
        whole = np.zeros(shape, bool)
        whole[self.window] = self.mask
        return whole


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
    channel : {"luminance", "chromaticity", "hue", "alpha"}
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
