"""The other cues' outlines of a photo's main rock, for the choice to judge.

The detection's own threshold outlines (``rockscan.core.segment.trace``) fail in
ways the photo can show otherwise: a shaded side left out, a touching
neighbour or a soft cast shadow taken in, a patch of ground taken for the rock.
Each function here outlines the rock by another cue, on the working image,
and returns its mask over that whole image (or None when the cue finds
nothing). ``rockscan.core.segment`` gathers them, with their sources
(``choose.SOURCES``), into the pool the choice model judges:

* :func:`grabcut`: OpenCV's GrabCut (colour models of rock and ground, a cut
  along edges) started from an outline; :func:`grabcut_box`, from a box
  (:func:`frame_box`: most of the frame);
* :func:`centre_part`: the Otsu class under the frame's centre, cut at necks
  (a crop is centred on its rock);
* watershed basins of the colour gradient (:func:`colour_gradient`,
  :func:`basin`): :func:`centre_basin`, flooded from a disk at the frame's
  centre (:func:`centre_disk`) against its border, and :func:`core_basin`,
  from an outline's core against the ground well outside it.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from rockscan.core.segment.channels import _unit, to_gray
from rockscan.core.segment.split import largest_part, split_necks
from rockscan.core.segment.trace import _disk, _fill_holes
from rockscan.core.segment.types import RockMask

__all__ = [
    "basin",
    "centre_basin",
    "centre_disk",
    "centre_part",
    "colour_gradient",
    "core_basin",
    "edge_strength",
    "frame_box",
    "grabcut",
    "grabcut_box",
]


def grabcut(work: NDArray[np.generic], dtype: np.dtype, rock: RockMask) -> NDArray[np.bool_] | None:
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


def frame_box(shape: tuple[int, int]) -> tuple[int, int, int, int]:
    """Most of the frame: a rock lies in it, wherever its first outline put it."""
    rows, cols = shape
    mr, mc = round(0.08 * rows), round(0.08 * cols)
    return (mr, rows - mr, mc, cols - mc)


def grabcut_box(
    work: NDArray[np.generic], dtype: np.dtype, box: tuple[int, int, int, int]
) -> NDArray[np.bool_] | None:
    """OpenCV's GrabCut from a box (outside it ground, inside undecided).

    It runs on the box and a margin of ground round it, reduced to at most
    ``_BOX_SIZE`` pixels: GrabCut's cost grows with the pixels it cuts, and
    the colour models need no more.
    """
    import cv2

    rows, cols = work.shape[:2]
    r0, r1, c0, c1 = box
    mr, mc = round(_BOX_MARGIN * (r1 - r0)), round(_BOX_MARGIN * (c1 - c0))
    R0, R1, C0, C1 = max(0, r0 - mr), min(rows, r1 + mr), max(0, c0 - mc), min(cols, c1 + mc)
    image = _unit(np.ascontiguousarray(work[R0:R1, C0:C1]), dtype)
    if image.ndim == 2:
        image = np.repeat(image[..., None], 3, axis=2)
    factor = min(1.0, _BOX_SIZE / max(R1 - R0, C1 - C0))
    h, w = max(8, round((R1 - R0) * factor)), max(8, round((C1 - C0) * factor))
    small = cv2.resize((image * 255).astype(np.uint8), (w, h), interpolation=cv2.INTER_AREA)
    fy, fx = h / (R1 - R0), w / (C1 - C0)
    b0, b1 = max(1, round((r0 - R0) * fy)), min(h - 1, round((r1 - R0) * fy))
    d0, d1 = max(1, round((c0 - C0) * fx)), min(w - 1, round((c1 - C0) * fx))
    if b1 - b0 < 4 or d1 - d0 < 4:
        return None
    trimap = np.zeros((h, w), np.uint8)
    bgd, fgd = np.zeros((1, 65), np.float64), np.zeros((1, 65), np.float64)
    cv2.setRNGSeed(0)
    try:
        cv2.grabCut(
            small, trimap, (d0, b0, d1 - d0, b1 - b0), bgd, fgd, _BOX_ITERATIONS, cv2.GC_INIT_WITH_RECT
        )
    except cv2.error:
        return None
    fg = ((trimap == cv2.GC_FGD) | (trimap == cv2.GC_PR_FGD)).astype(np.float32)
    fg = cv2.resize(fg, (C1 - C0, R1 - R0), interpolation=cv2.INTER_LINEAR) >= 0.5
    biggest = largest_part(fg)
    if biggest is None:
        return None
    out = np.zeros((rows, cols), bool)
    out[R0:R1, C0:C1] = _fill_holes(biggest)
    return out


#: Longer side of the copy a box's GrabCut runs on.
_BOX_SIZE = 160.0
#: Ground round a box that the box's GrabCut sees, as a share of the box's sides.
_BOX_MARGIN = 0.25
#: A box's GrabCut rounds of colour models and cut.
_BOX_ITERATIONS = 4


#: GrabCut's rounds of colour models and cut.
_GRABCUT_ITERATIONS = 3


def centre_part(work: NDArray[np.generic], dtype: np.dtype) -> NDArray[np.bool_] | None:
    """The Otsu class under the frame's centre (most of a disk there), holes filled,
    cut at necks from touching neighbours; None when no part of it covers the disk."""
    import cv2

    gray = to_gray(work) if work.ndim == 3 else _unit(work, dtype)
    gray8 = cv2.GaussianBlur((gray * 255).astype(np.uint8), (5, 5), 0)
    _, binary = cv2.threshold(gray8, 0, 1, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    rows, cols = binary.shape
    # The centre is judged by a disk, not its one pixel, which may fall on a
    # speck of the rock's own texture of the other class.
    centre = centre_disk((rows, cols))
    if 2 * np.count_nonzero(binary[centre]) < np.count_nonzero(centre):
        binary = 1 - binary
    _, labels = cv2.connectedComponents(binary, connectivity=4)
    under = labels[centre]
    under = under[under > 0]
    if under.size == 0:
        return None
    region = _fill_holes(labels == np.bincount(under).argmax())
    parts = [part for part in split_necks(region, 0.01 * rows * cols) if part[centre].any()]
    return max(parts, key=lambda part: np.count_nonzero(part[centre])) if parts else region


def colour_gradient(work: NDArray[np.generic], dtype: np.dtype) -> NDArray[np.float32]:
    """The largest over the colour channels of the Sobel gradient's length, after a little smoothing."""
    import cv2

    image = _unit(work, dtype)
    if image.ndim == 2:
        image = image[..., None]
    gradient = np.zeros(image.shape[:2], np.float32)
    for c in range(image.shape[2]):
        smooth = cv2.GaussianBlur(np.ascontiguousarray(image[..., c], np.float32), (0, 0), _WATERSHED_SIGMA)
        gx = cv2.Sobel(smooth, cv2.CV_32F, 1, 0, ksize=3)
        gy = cv2.Sobel(smooth, cv2.CV_32F, 0, 1, ksize=3)
        np.maximum(gradient, np.hypot(gx, gy), out=gradient)
    return gradient


def basin(
    gradient: NDArray[np.float32],
    inner: NDArray[np.bool_],
    outer: NDArray[np.bool_],
    compactness: float = 0.0,
) -> NDArray[np.bool_] | None:
    """What a watershed of the gradient floods from ``inner`` against ``outer``.

    The two floods meet on the strongest closed edge between the markers:
    rocks that touch are told apart by the edge between them even where they
    share a colour, and a soft shadow's edge gives way to the rock's sharp one.
    With ``compactness`` > 0 (scikit-image's compact watershed) each pixel's
    level is raised by that much per pixel of its distance from the marker
    that reaches it, so that a flood crosses a weak contact only to what lies
    near it. None when either marker is empty, or when the basin's edge is no
    edge (:func:`edge_strength` under ``_EDGE_FLOOR``: a flood over flat ground).
    """
    from skimage.segmentation import watershed

    markers = np.zeros(gradient.shape, np.int32)
    markers[outer] = 2
    markers[inner] = 1
    if not (markers == 1).any() or not (markers == 2).any():
        return None
    basin = watershed(gradient, markers, compactness=compactness) == 1
    if not basin.any() or not edge_strength(gradient, basin) >= _EDGE_FLOOR:
        return None
    return _fill_holes(basin)


def edge_strength(gradient: NDArray[np.float32], mask: NDArray[np.bool_]) -> float:
    """The mean gradient along a mask's edge, over the mean of the photo's strongest 1%
    (0 where the photo has no gradient)."""
    import cv2

    edge = mask ^ (cv2.erode(mask.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0)
    flat = gradient.ravel()
    top = max(1, flat.size // 100)
    strongest = float(np.partition(flat, flat.size - top)[flat.size - top :].mean())
    return float(gradient[edge].mean()) / strongest if strongest > 0 else 0.0


def centre_basin(gradient: NDArray[np.float32]) -> NDArray[np.bool_] | None:
    """The basin of a disk at the frame's centre against the frame's border (a crop
    is centred on its rock), flooded compactly where that stops on a clear edge.

    A crop's neighbours touch its rock along contacts that step little where
    they share its colour, while their own texture ridges their insides: the
    plain flood crosses a contact and fills the neighbour up to its far edge.
    A compact flood (:func:`basin`, ``_COMPACTNESS``) leaves a neighbour that
    lies nearer the frame than the centre to the frame's flood. On flat ground
    it stops anywhere, about half way to the frame: it is taken only when its
    edge holds at least ``_COMPACT_EDGE`` of the photo's strongest gradient
    (:func:`edge_strength`), and otherwise the plain flood is.
    """
    border = np.zeros(gradient.shape, bool)
    border[0, :] = border[-1, :] = border[:, 0] = border[:, -1] = True
    disk = centre_disk(gradient.shape)
    plain = basin(gradient, disk, border)
    if plain is None:
        return None
    compact = basin(gradient, disk, border, _COMPACTNESS / min(gradient.shape))
    if compact is not None and edge_strength(gradient, compact) >= _COMPACT_EDGE:
        return compact
    return plain


def centre_disk(shape: tuple[int, int]) -> NDArray[np.bool_]:
    """A disk at the frame's centre, of radius ``_WATERSHED_MARKER`` of its shorter side."""
    rows, cols = shape
    yy, xx = np.ogrid[:rows, :cols]
    radius = max(1.0, _WATERSHED_MARKER * min(rows, cols))
    return (yy - (rows - 1) / 2) ** 2 + (xx - (cols - 1) / 2) ** 2 <= radius**2


def core_basin(gradient: NDArray[np.float32], rock: RockMask) -> NDArray[np.bool_] | None:
    """The basin of an outline's core (round its deepest point) against the ground well outside it
    (the frame's border is no marker: a rock the frame cuts keeps its edge along it).

    When the outline joined the rock to pebbles that touch it, or left out a
    shaded side, the core still lies in the rock (the largest blob), and
    the flood from it stops at the rock's own edge.
    """
    import cv2

    mask = rock.whole(gradient.shape).astype(np.uint8)
    depth = cv2.distanceTransform(np.pad(mask, 1), cv2.DIST_L2, 5)[1:-1, 1:-1]
    deepest = float(depth.max())
    if deepest < 2.0:
        return None
    # A disk round the deepest point: the region's other deep parts may lie
    # across the rock's edge (the middle of a rock and its shadow together).
    row, col = np.unravel_index(int(np.argmax(depth)), depth.shape)
    yy, xx = np.ogrid[: depth.shape[0], : depth.shape[1]]
    inner = (yy - row) ** 2 + (xx - col) ** 2 <= (_CORE_SHARE * deepest) ** 2
    radius = math.sqrt(max(rock.area, 1) / math.pi)
    reach = _disk(max(2, round(_CORE_REACH * radius)))
    outer = cv2.dilate(mask, reach) == 0
    return basin(gradient, inner, outer)


#: Gaussian smoothing before the watersheds' gradient, working pixels.
_WATERSHED_SIGMA = 1.0
#: Least mean gradient along a basin's edge, as a share of the mean of the
#: photo's strongest 1%: every basin of the development photos had at least 0.48.
_EDGE_FLOOR = 0.2
#: The compact centre basin's compactness, times the frame's shorter side in
#: working pixels: over that side a pixel's level rises by this much (the
#: gradient's units). Development crops 4000-4159: the compact flood's outline
#: at IoU >= 0.9 on 111 of 160 against 87 for the plain flood (110 and 111 at
#: 0.25 and 0.1).
_COMPACTNESS = 0.15
#: Least edge strength (``edge_strength``) of a compact centre basin that is taken.
#: Development photos of one rock where it misses the rock (73 of photos 4000-4039
#: of four conditions): 0.29 at the median, 19% at 0.45 or more; development crops
#: 4000-4159 where it outlines the rock and the plain flood does not (30): 0.40-0.84,
#: 0.67 at the median.
_COMPACT_EDGE = 0.45
#: Radius of the centre basin's marker, as a share of the frame's shorter side.
_WATERSHED_MARKER = 0.05
#: Radius of an outline's core round its deepest point, as a share of that depth.
_CORE_SHARE = 0.3
#: The ground marker of the core basin lies this far outside the outline, in equivalent radii.
_CORE_REACH = 0.6
