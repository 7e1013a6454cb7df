"""Outlining a detection's rocks on the working image, and the other cues' outlines of the main rock.

An :class:`Outliner` holds the photo's pyramid and turns a detection
(``rockscan.core.segment.detect``) into a :class:`~rockscan.core.segment.types.Segmentation`
at the working scale the smallest rock asks for (``rockscan.core.segment``'s
module docstring, step 6), remembering for each segmentation the working
image it was outlined on. :meth:`Outliner.refined` outlines a found main
rock by the other cues (``rockscan.core.segment.cues``, and the outlines with
touching pebbles opened off), each scored as a threshold outline is, for the
choice among candidates (``rockscan.core.segment.choose``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rockscan.core.segment.channels import _at_scale
from rockscan.core.segment.cues import (
    centre_basin,
    centre_part,
    colour_gradient,
    core_basin,
    frame_box,
    grabcut,
    grabcut_box,
)
from rockscan.core.segment.detect import _Detection, _luminance_polarity
from rockscan.core.segment.split import opened, territories
from rockscan.core.segment.stats import bounding_box
from rockscan.core.segment.trace import _outline_rock, _scored
from rockscan.core.segment.types import RockMask, Segmentation, SegmentConfig

__all__ = ["Outliner", "assemble", "cropped"]


@dataclass(frozen=True, eq=False)
class Outliner:
    """Outlines a detection's rocks at working size and scores them
    (``rockscan.core.segment``'s module docstring, step 6)."""

    levels: list[NDArray[np.generic]]
    dtype: np.dtype
    small_shape: tuple[int, int]
    detect_covered: tuple[float, float]
    detect_scale: float
    largest_scale: float
    config: SegmentConfig
    #: The working image, its scale and the detection of each segmentation made.
    works: dict = dataclasses.field(default_factory=dict)

    def work_scale(self, detection: _Detection) -> float:
        """Photo pixels per working pixel for a detection's rocks.

        Outlines are traced on an image where the smallest rock found spans
        about ``outline_radius`` pixels: finer costs time and adds nothing to its shape.
        """
        smallest = min(int(np.count_nonzero(r)) for r in detection.regions)
        radius_photo = math.sqrt(smallest / math.pi) * self.detect_scale
        return min(max(self.largest_scale, radius_photo / self.config.outline_radius), self.detect_scale)

    def __call__(
        self, detection: _Detection, work_scale: float | None = None, edge: float = 0.5
    ) -> Segmentation | None:
        config = self.config
        if work_scale is None:
            work_scale = self.work_scale(detection)
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
            rock = _outline_rock(work, self.dtype, region, owners == index, up, detection, config, edge)
            if rock is not None:
                rocks.append(rock)
        if not rocks:
            return None
        polarity = detection.polarity
        if detection.channel.name != "luminance":
            polarity = _luminance_polarity(work, self.dtype, rocks[0])
        found = assemble(rocks, work.shape[:2], scale_rowcol, polarity, detection.channel.name)
        self.works[id(found)] = (work, up, detection)
        return found

    def to_detect(
        self, shape: tuple[int, int], up: tuple[float, float]
    ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """The detection image's row of each working row, and column of each working column."""
        return tuple(
            np.minimum(((np.arange(n) + 0.5) / u).astype(np.int64), m - 1)
            for n, u, m in zip(shape, up, self.small_shape, strict=True)
        )

    def refined(self, found: Segmentation) -> Iterator[tuple[str, Segmentation]]:
        """Other outlines of a found main rock, each with its source (``choose.SOURCES``):
        GrabCut from it and from most of the frame, the Otsu part and the watershed
        basin under the frame's centre, the basin of its core, and those
        outlines with touching pebbles opened off."""
        work, up, detection = self.works[id(found)]
        rock = found.rocks[0]
        to_row, to_col = self.to_detect(work.shape[:2], up)
        gradient = colour_gradient(work, self.dtype)
        core = core_basin(gradient, rock)
        masks = [
            ("grabcut", grabcut(work, self.dtype, rock)),
            ("centre-otsu", centre_part(work, self.dtype)),
            ("centre-basin", centre_basin(gradient)),
            ("core-basin", core),
            ("opened", opened(rock.whole(work.shape[:2]))),
            ("opened-core", opened(core) if core is not None else None),
        ]
        if self.config.polarity == "auto":
            # A box's GrabCut knows no polarity: it stays out when the user set one.
            masks.append(("box-frame", grabcut_box(work, self.dtype, frame_box(work.shape[:2]))))
        # A rock is no smaller than the detection's smallest region may be.
        least = self.config.min_area_fraction * work.shape[0] * work.shape[1]
        for source, mask in masks:
            if mask is None or np.count_nonzero(mask) < least:
                continue
            candidate = RockMask(mask=mask, coverage=mask.astype(np.float32), origin_rowcol=(0, 0))
            candidate = cropped(
                _scored(work, self.dtype, candidate, (to_row, to_col), up, detection, self.config)
            )
            refined = assemble([candidate], work.shape[:2], found.scale_rowcol, found.polarity, found.channel)
            self.works[id(refined)] = (work, up, detection)
            yield source, refined


def assemble(
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
        view = labels[rock.window]
        view[rock.mask & (view == 0)] = index
    return Segmentation(
        labels=labels, rocks=tuple(rocks), scale_rowcol=scale_rowcol, polarity=polarity, channel=channel
    )


def cropped(rock: RockMask) -> RockMask:
    """The rock in the smallest window that holds it, with a pixel to spare."""
    top, bottom, left, right = bounding_box(rock.mask)
    r0, r1 = max(0, top - 1), min(rock.mask.shape[0], bottom + 1)
    c0, c1 = max(0, left - 1), min(rock.mask.shape[1], right + 1)
    o0, o1 = rock.origin_rowcol
    return dataclasses.replace(
        rock,
        mask=rock.mask[r0:r1, c0:c1],
        coverage=rock.coverage[r0:r1, c0:c1],
        origin_rowcol=(o0 + int(r0), o1 + int(c0)),
    )
