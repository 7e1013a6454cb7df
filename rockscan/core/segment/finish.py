"""The last steps on the chosen outline of the main rock (steps 8-17 of
``rockscan.core.segment``'s module docstring).

Touching pebbles and slivers are cut off (``pebbles``, ``slivers``); then,
on a window of the photo round the rock (:func:`rock_window`), on which the
rock outlined on the working grid is placed (:func:`placed`), a cast shadow
taken in is cut off (``shadow``; in colour, only a part of the ground's
hue), the outline moves to the photo's steepest edge where the half-way
level missed it (``snap``; off the fast path) and out to a shaded rim's
valley (``rim``), and, for a rock chosen among the whole pool, by the
learnt offsets where they agree (``offset``); last, off the fast path, a
light rock's shaded side left out is taken in (``shade``) and, in colour,
the outline is told from its ground by hue (``hued``): a part of the
ground's hue its two colours part off, a side of the rock's own hue taken
in, a part of the ground's hue it still holds cut off; and a face the
sensor clipped white is taken in (``clipped``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from rockscan.core.segment.channels import _LUMA, _at_scale, _pyramid, _unit
from rockscan.core.segment.clipped import MIN_CLIPPED as CLIPPED_LEAST
from rockscan.core.segment.clipped import REACH as CLIPPED_REACH
from rockscan.core.segment.clipped import clipped_on
from rockscan.core.segment.confidence import offset_evidence
from rockscan.core.segment.hued import OFF_RING as HUE_OFF_RING
from rockscan.core.segment.hued import RING as HUE_RING
from rockscan.core.segment.hued import ROCK_HUE, hue_off, hue_on, hue_parted
from rockscan.core.segment.offset import OffsetsRead, moved_by, offsets_read
from rockscan.core.segment.outliner import cropped
from rockscan.core.segment.pebbles import pebbles_off
from rockscan.core.segment.rim import rim_on
from rockscan.core.segment.shade import REACH as SHADE_REACH
from rockscan.core.segment.shade import shade_on
from rockscan.core.segment.shadow import MIN_AREA as SHADOW_MIN_AREA
from rockscan.core.segment.shadow import Region, hue_from_ground, measured_region, shadow_off
from rockscan.core.segment.slivers import slivers_off
from rockscan.core.segment.snap import MARGIN as SNAP_MARGIN
from rockscan.core.segment.snap import REACH as SNAP_REACH
from rockscan.core.segment.snap import snapped
from rockscan.core.segment.split import largest_part
from rockscan.core.segment.trace import RING, RING_PIXELS, _fill_holes
from rockscan.core.segment.types import RockMask, Segmentation

__all__ = ["completed", "finished", "offset_inputs", "placed", "rock_hued", "rock_window"]


def completed(
    found: Segmentation,
    choice: NDArray[np.float64] | None,
    pixels: NDArray[np.generic],
    *,
    easy: bool,
) -> tuple[Segmentation, NDArray[np.float64] | None]:
    """The chosen segmentation after steps 8-17 (``easy``: the fast path
    took it), and for a rock chosen among the whole pool (``choice``, its
    score's features from the choice) all of the score's features
    (``confidence``), None otherwise."""
    found = finished(found, pixels, full=not easy)
    if choice is None:
        return (found if easy else _sides(found, pixels)), None
    before = _offsets_of(found, pixels)
    moved = None if before is None else _offset_moved(found, before[0][0], before[1])
    after = before if moved is None else _offsets_of(moved, pixels)
    evidence = offset_evidence(*(None if r is None else r[1].on_usable for r in (before, after)))
    # A move is clipped to ``offset.REACH``: an outline further off the
    # rock's edge than that (a wide blur over a darkening limb) is read
    # again where the first move left it, and moves once more by what the
    # trees read there. The score reads the first move, as it was fitted.
    if moved is not None and after is not None:
        moved = _offset_moved(moved, after[0][0], after[1]) or moved
    return _sides(found if moved is None else moved, pixels), np.concatenate([choice, evidence])


def _sides(found: Segmentation, pixels: NDArray[np.generic]) -> Segmentation:
    """The main rock with a side its outline left out taken in, told by
    brightness (``shade.shade_on``), a part of the ground's hue its two
    colours tell from the rock cut off (``hued.hue_parted``), a side of its
    own hue taken in (``hued.hue_on``), a part of the ground's hue it still
    holds cut off (``hued.hue_off``), and a face the sensor clipped taken in
    (``clipped.clipped_on``)."""
    # Taking the ground's part off first lets the rock's own hue be read on
    # an outline that is mostly rock, before the side of that hue is taken in.
    hued = _hue_off(_hue_on(_hue_parted(_shade_on(found, pixels), pixels), pixels), pixels)
    # Last: the hue steps read white, a clipped face's colour, as the ground's.
    return _clipped_on(hued, pixels)


def _clipped_on(found: Segmentation, pixels: NDArray[np.generic]) -> Segmentation:
    """The main rock with a face the sensor clipped, left out of its outline,
    taken in (``clipped.clipped_on``), read on a window of the photo
    ``clipped.REACH`` of its radius round it; the rock keeps its score."""
    if found.channel == "alpha":
        return found
    window = _rock_box(found, CLIPPED_REACH)
    # Most photos clip nothing round the rock: a look at one photo pixel in
    # each grid pixel's block spares reading the window.
    if not _nearly_clipped(pixels, window, found.scale_rowcol):
        return found
    mask = placed(found.rocks[0], window, found.scale_rowcol)
    if mask is None:
        return found
    # A gray photo is read once, as brightness, not first tried for colour.
    in_colour = np.ndim(pixels) == 3 and np.shape(pixels)[2] >= 3
    read = _working_colour if in_colour else _working_gray
    colour = read(pixels, window, found.scale_rowcol)
    if colour is None:
        return found
    grown = clipped_on(colour, mask)
    return found if grown is mask else _main_grown(found, window, mask, grown)


def _nearly_clipped(
    pixels: NDArray[np.generic], window: tuple[int, int, int, int], scale_rowcol: tuple[float, float]
) -> bool:
    """Whether the photo under a window of the working grid has pixels near
    the sensor's ceiling (``NEARLY_CLIPPED``), one photo pixel read in each grid
    pixel's block: a grid pixel at the ceiling is a block of such pixels."""
    r0, r1, c0, c1 = window
    sr, sc = scale_rowcol
    photo = np.asarray(pixels)
    step = max(1, math.floor(min(sr, sc)))
    sample = photo[math.floor(r0 * sr) : round(r1 * sr) : step, math.floor(c0 * sc) : round(c1 * sc) : step]
    if sample.ndim == 3 and sample.shape[2] >= 3:
        # Pairwise, not ``max(axis=2)``: a reduction over three values a pixel is slow.
        sample = np.maximum(np.maximum(sample[..., 0], sample[..., 1]), sample[..., 2])
    elif sample.ndim == 3:
        sample = sample[..., 0]
    return np.count_nonzero(_unit(sample, photo.dtype) >= NEARLY_CLIPPED) >= CLIPPED_LEAST


#: A photo pixel this near the ceiling may lie in a grid pixel at it (the
#: grid's pixel averages a block of the photo's; ``clipped.CEILING``).
NEARLY_CLIPPED = 0.95


def _shade_on(found: Segmentation, pixels: NDArray[np.generic]) -> Segmentation:
    """The main rock with a shaded side its outline left out taken in
    (``shade.shade_on``), read on a window of the photo ``shade.REACH`` of
    its radius round it; the rock keeps its score."""
    if found.channel == "alpha":
        return found
    window, gray = rock_window(found, pixels, SHADE_REACH)
    mask = placed(found.rocks[0], window, found.scale_rowcol)
    if mask is None:
        return found
    grown = shade_on(gray, mask)
    return found if grown is mask else _main_grown(found, window, mask, grown)


def _hue_on(found: Segmentation, pixels: NDArray[np.generic]) -> Segmentation:
    """The main rock with a part of its own hue its outline left out taken
    in (``hued.hue_on``), read on a window of the photo's colour
    ``hued.RING[1]`` of its radius round it; a gray photo's rock, and one an
    alpha channel gave, stand as they are. The rock keeps its score."""
    read = _in_colour(found, pixels, HUE_RING[1])
    if read is None:
        return found
    window, colour, mask = read
    grown = hue_on(colour, mask)
    return found if grown is mask else _main_grown(found, window, mask, grown)


def _hue_off(found: Segmentation, pixels: NDArray[np.generic]) -> Segmentation:
    """The main rock with a part of the ground's hue its outline took cut off
    (``hued.hue_off``)."""
    return _cut_in_colour(found, pixels, hue_off)


def _hue_parted(found: Segmentation, pixels: NDArray[np.generic]) -> Segmentation:
    """The main rock with the parts of the ground's hue its two colours tell
    from it cut off (``hued.hue_parted``), and the cut outline finished again
    (steps 8-11, :func:`finished`)."""
    parted = _cut_in_colour(found, pixels, hue_parted)
    # The colours cut along a line the outline never ran on: touching pebbles,
    # the shadow's rise, the steepest edge and a rim are read there afresh.
    return parted if parted is found else finished(parted, pixels)


def _cut_in_colour(
    found: Segmentation,
    pixels: NDArray[np.generic],
    step: Callable[[NDArray[np.float32], NDArray[np.bool_]], NDArray[np.bool_]],
) -> Segmentation:
    """The main rock cut by ``step(colour, mask)``, read on a window of the
    photo's colour ``hued.OFF_RING[1]`` of its radius round it; a gray
    photo's rock, and one an alpha channel gave, stand as they are. The rock
    keeps its score."""
    read = _in_colour(found, pixels, HUE_OFF_RING[1])
    if read is None:
        return found
    window, colour, mask = read
    kept = step(colour, mask)
    if kept is mask:
        return found
    rock = found.rocks[0]
    (r0, _, c0, _), (o0, o1), (h, w) = window, rock.origin_rowcol, rock.mask.shape
    return _main_cut(found, kept[o0 - r0 : o0 - r0 + h, o1 - c0 : o1 - c0 + w] & rock.mask)


def _in_colour(
    found: Segmentation, pixels: NDArray[np.generic], reach: float
) -> tuple[tuple[int, int, int, int], NDArray[np.float32], NDArray[np.bool_]] | None:
    """The window of the working grid round the main rock with ``reach`` of
    its radius (``_rock_box``), the photo's colour on it and the rock's mask
    placed on it; None for a gray photo, a rock an alpha channel gave, or one
    that does not fit."""
    if found.channel == "alpha" or np.ndim(pixels) != 3:
        return None
    window = _rock_box(found, reach)
    colour = _working_colour(pixels, window, found.scale_rowcol)
    mask = None if colour is None else placed(found.rocks[0], window, found.scale_rowcol)
    return None if mask is None else (window, colour, mask)


def rock_hued(
    pixels: NDArray[np.generic],
    window: tuple[int, int, int, int],
    scale_rowcol: tuple[float, float],
    region: NDArray[np.bool_],
    part: NDArray[np.bool_],
) -> bool:
    """Whether a part of a rock's region, taken for its cast shadow, has the
    rock's hue, not the ground's: at least ``ROCK_HUE`` of the way from the
    ground's hue to the rest of the rock's (``shadow.hue_from_ground``), a
    darker band of the rock itself, which stays.

    Parameters
    ----------
    pixels : ndarray
        The photo.
    window : (r0, r1, c0, c1)
        The window of the working grid (``scale_rowcol`` photo pixels per
        grid pixel) that ``region`` and ``part`` cover.
    scale_rowcol : (float, float)
    region, part : (rows, cols) ndarray of bool
        The rock's region with the part, and the part.

    Returns
    -------
    bool
        False for a gray photo, or a part without a hue to read: it goes as
        the brightness says.
    """
    colour = _working_colour(pixels, window, scale_rowcol)
    if colour is None:
        return False
    place = hue_from_ground(colour, region, part)
    return place is not None and place >= ROCK_HUE


def _offsets_of(found: Segmentation, pixels: NDArray[np.generic]) -> tuple[_OnWindow, OffsetsRead] | None:
    """What the offset step reads of the main rock (:func:`offset_inputs`) and
    the trees' offsets across its outline; None where they cannot be read."""
    inputs = None if found.channel == "alpha" else offset_inputs(found, pixels)
    read = None if inputs is None else offsets_read(*inputs[1:], _scale(found))
    return None if read is None else (inputs, read)


def finished(found: Segmentation, pixels: NDArray[np.generic], *, full: bool = True) -> Segmentation:
    """The main rock with touching pebbles and slivers cut off and its edges seen to
    (steps 8-11), step 11 only with ``full`` (off the fast path); an
    outline an alpha channel gave stands as it is."""
    if found.channel == "alpha":
        return found
    return _edges(_slivers_off(_pebbles_off(found)), pixels, snap=full)


#: A window (rows r0:r1, cols c0:c1), the log brightness and a rock's coverage
#: on it, and the rock's level, the ground's and the ground's spread.
_OnWindow = tuple[
    tuple[int, int, int, int], NDArray[np.float32], NDArray[np.float32], tuple[float, float, float]
]


def _scale(found: Segmentation) -> float:
    """Photo pixels per pixel of the working grid."""
    return 0.5 * (found.scale_rowcol[0] + found.scale_rowcol[1])


def offset_inputs(found: Segmentation, pixels: NDArray[np.generic]) -> _OnWindow | None:
    """What the offset step reads of the main rock: its window on the working
    grid, the photo's log brightness there, the rock's coverage placed on it,
    and the rock's and the ground's levels with the ground's spread; None when
    the rock does not fit its window or is too small to measure."""
    rock = found.rocks[0]
    # Read again, not taken over from the edge steps: the rim may have grown
    # the rock, and its levels are read round the outline as it now is. It
    # costs a millisecond or two, off the fast path only.
    window, gray = rock_window(found, pixels)
    mask = placed(rock, window, found.scale_rowcol)
    if mask is None:
        return None
    region = measured_region(gray, mask, SHADOW_MIN_AREA)
    if region is None:
        return None
    return window, gray, _main_coverage(rock, window, mask.shape), region[3]


def _offset_moved(
    found: Segmentation, window: tuple[int, int, int, int], read: OffsetsRead
) -> Segmentation | None:
    """The main rock with its outline moved by the offsets read across it on
    ``window`` (``offset.moved_by``); None when nothing moved."""
    moved = moved_by(read)
    agreed = None if moved is None else _agreed(moved)
    return None if agreed is None else _main_replaced(found, (window[0], window[2]), *agreed)


def _agreed(moved: NDArray[np.float32]) -> tuple[NDArray[np.bool_], NDArray[np.float32]] | None:
    """A moved coverage's rock (its largest piece past half-way, holes
    filled) and the coverage made to agree with it: filled holes are rock,
    anything else past half-way that is not the rock's one piece is ground;
    None when nothing is past half-way."""
    kept = largest_part(moved >= 0.5)
    if kept is None:
        return None
    kept = _fill_holes(kept)
    moved[kept & (moved < 0.5)] = 1.0
    moved[~kept & (moved >= 0.5)] = 0.49
    return kept, moved


def _pebbles_off(found: Segmentation) -> Segmentation:
    """The main rock with the pebbles that touch it cut off (``pebbles.pebbles_off``).

    The choice prefers outlines without pebbles, but the fast path and the
    best candidate may still carry one: a pebble as dark as the rock joins
    every cue's region. Cut off along its contact, it leaves the rock's own
    edge as it was outlined. Other rocks of the segmentation are left as
    they are.
    """
    rock = found.rocks[0]
    return _main_cut(found, pebbles_off(rock.mask))


def _slivers_off(found: Segmentation) -> Segmentation:
    """The main rock with the thin slivers that run off it along a crevice
    taken off (``slivers.slivers_off``); other rocks are left as they are."""
    return _main_cut(found, slivers_off(found.rocks[0].mask))


def _edges(found: Segmentation, pixels: NDArray[np.generic], *, snap: bool = True) -> Segmentation:
    """The main rock with a cast shadow that joined it taken off
    (``shadow.shadow_off``), with ``snap`` its outline moved to the steepest
    edge beside it (``snap.snapped``), then a dark rim its outline left out
    taken in (``rim.rim_on``).

    All are judged on the photo's log brightness around the rock, brought
    to the working grid the rock was outlined on, and on the rock's and the
    ground's levels, read once for all. A rock cut, moved or grown keeps its score.
    """
    window, gray, mask, region = _on_photo(found, pixels)
    if region is None:
        return found
    kept = shadow_off(gray, mask, region)
    # Read only when a cut is proposed: the fast path costs nothing more.
    if kept is not mask and rock_hued(pixels, window, found.scale_rowcol, mask, mask & ~kept):
        kept = mask
    if kept is not mask:
        rock = found.rocks[0]
        (r0, _, c0, _), (o0, o1), (h, w) = window, rock.origin_rowcol, rock.mask.shape
        found = _main_cut(found, kept[o0 - r0 : o0 - r0 + h, o1 - c0 : o1 - c0 + w])
        window, gray, mask, region = _on_photo(found, pixels)
        if region is None:
            return found
    if snap and found.channel == "luminance":
        found, mask, region = _snapped(found, window, gray, mask, region)
    grown = rim_on(gray, mask, region)
    return found if grown is mask else _main_grown(found, window, mask, grown)


def _on_photo(
    found: Segmentation, pixels: NDArray[np.generic]
) -> tuple[tuple[int, int, int, int], NDArray[np.float32], NDArray[np.bool_] | None, Region | None]:
    """The main rock placed on a window of the photo round it (:func:`rock_window`,
    :func:`placed`): the window, its log brightness, the rock's mask there and
    the rock's and ground's levels read on it (``shadow.measured_region``;
    None where they cannot be read)."""
    window, gray = rock_window(found, pixels)
    mask = placed(found.rocks[0], window, found.scale_rowcol)
    return window, gray, mask, measured_region(gray, mask, SHADOW_MIN_AREA)


def _snapped(
    found: Segmentation,
    window: tuple[int, int, int, int],
    gray: NDArray[np.float32],
    mask: NDArray[np.bool_],
    region: Region,
) -> tuple[Segmentation, NDArray[np.bool_], Region]:
    """The main rock with its outline moved to the steepest edge beside it
    (``snap.snapped``), its mask on ``window`` and its region; as they were
    when nothing moved. The rock keeps its score."""
    import cv2

    rock = found.rocks[0]
    (r0, r1, c0, c1), (o0, o1), (h, w) = window, rock.origin_rowcol, rock.mask.shape
    reach = SNAP_REACH / (0.5 * (found.scale_rowcol[0] + found.scale_rowcol[1]))
    # The rock's own window, wide enough for its outline to move and be read across.
    pad = math.ceil(reach + SNAP_MARGIN) + 1
    R0, R1, C0, C1 = max(r0, o0 - pad), min(r1, o0 + h + pad), max(c0, o1 - pad), min(c1, o1 + w + pad)
    coverage = _main_coverage(rock, (R0, R1, C0, C1), (R1 - R0, C1 - C0))
    _, _, _, (rock_level, ground_level, _) = region
    # A blur spreads light, not its logarithm: the steepest change of the
    # log brightness lies towards the dark side of an edge.
    light = np.exp(gray[R0 - r0 : R1 - r0, C0 - c0 : C1 - c0])
    moved = snapped(light, coverage, rock_level > ground_level, reach)
    agreed = None if moved is None else _agreed(moved)
    if agreed is None:
        return found, mask, region
    kept, moved = agreed
    found = _main_replaced(found, (R0, C0), kept, moved)
    mask = np.zeros(mask.shape, bool)
    mask[R0 - r0 : R1 - r0, C0 - c0 : C1 - c0] = kept
    mask8 = mask.view(np.uint8)
    moments = cv2.moments(mask8, binaryImage=True)
    area = moments["m00"]
    return found, mask, (mask8, (moments["m01"] / area, moments["m10"] / area), area, region[3])


def _main_grown(
    found: Segmentation,
    window: tuple[int, int, int, int],
    mask: NDArray[np.bool_],
    grown: NDArray[np.bool_],
) -> Segmentation:
    """The segmentation with its main rock (``mask`` on ``window``) grown to
    ``grown``: what is added is rock in the coverage and the labels; other
    rocks are left as they are."""
    coverage = _main_coverage(found.rocks[0], window, mask.shape)
    coverage[grown & ~mask] = 1.0
    return _main_replaced(found, (window[0], window[2]), grown, coverage)


def _main_coverage(
    rock: RockMask, window: tuple[int, int, int, int], shape: tuple[int, int]
) -> NDArray[np.float32]:
    """A rock's coverage placed on a window (rows r0:r1, cols c0:c1) of its working grid."""
    (r0, _, c0, _), (o0, o1), (h, w) = window, rock.origin_rowcol, rock.mask.shape
    coverage = np.zeros(shape, np.float32)
    coverage[o0 - r0 : o0 - r0 + h, o1 - c0 : o1 - c0 + w] = rock.coverage
    return coverage


def _main_replaced(
    found: Segmentation, origin: tuple[int, int], mask: NDArray[np.bool_], coverage: NDArray[np.float32]
) -> Segmentation:
    """The segmentation with its main rock's mask and coverage replaced by
    ``mask`` and ``coverage`` on a window from ``origin``, in the labels too;
    other rocks are left as they are."""
    r0, c0 = origin
    main = cropped(dataclasses.replace(found.rocks[0], mask=mask, coverage=coverage, origin_rowcol=origin))
    labels = found.labels.copy()
    view = labels[r0 : r0 + mask.shape[0], c0 : c0 + mask.shape[1]]
    view[~mask & (view == 1)] = 0
    view[mask & (view == 0)] = 1
    return dataclasses.replace(found, labels=labels, rocks=(main, *found.rocks[1:]))


def rock_window(
    found: Segmentation, pixels: NDArray[np.generic], reach: float = RING[1]
) -> tuple[tuple[int, int, int, int], NDArray[np.float32]]:
    """The window of the working grid around the main rock (rows r0:r1, cols
    c0:c1) with the ring its ground's level is read from (or ``reach`` of its
    equivalent radius), and the photo's log brightness on it."""
    window = _rock_box(found, reach)
    gray = _working_gray(pixels, window, found.scale_rowcol)
    return window, np.log(gray + np.float32(_LOG_FLOOR))


def _rock_box(found: Segmentation, reach: float) -> tuple[int, int, int, int]:
    """The window of the working grid (rows r0:r1, cols c0:c1) round the
    main rock with ``reach`` of its equivalent radius, or the ring its
    ground's level is read from, past its box; cut by the frame."""
    rock = found.rocks[0]
    h, w = rock.mask.shape
    radius = math.sqrt(max(rock.area, 1) / math.pi)
    pad = math.ceil(max(RING_PIXELS[1], reach * radius)) + 2
    rows, cols = found.labels.shape
    o0, o1 = rock.origin_rowcol
    return (max(0, o0 - pad), min(rows, o0 + h + pad), max(0, o1 - pad), min(cols, o1 + w + pad))


def placed(
    rock: RockMask,
    window: tuple[int, int, int, int],
    scale_rowcol: tuple[float, float],
    grid_scale_rowcol: tuple[float, float] | None = None,
) -> NDArray[np.bool_] | None:
    """A rock's mask on a window of a working grid (photo pixels per grid pixel
    ``scale_rowcol``); None if it does not fit inside.

    The rock may have been outlined on another grid (``grid_scale_rowcol``,
    the same by default): each window pixel takes the value under its centre.
    """
    r0, r1, c0, c1 = window
    (o0, o1), (h, w) = rock.origin_rowcol, rock.mask.shape
    own = grid_scale_rowcol or scale_rowcol
    # The rock's extent in window pixels (fractional when the grids differ).
    top, left = o0 * own[0] / scale_rowcol[0], o1 * own[1] / scale_rowcol[1]
    bottom, right = (o0 + h) * own[0] / scale_rowcol[0], (o1 + w) * own[1] / scale_rowcol[1]
    if top < r0 - _FIT or left < c0 - _FIT or bottom > r1 + _FIT or right > c1 + _FIT:
        return None
    rows = np.floor((np.arange(r0, r1) + 0.5) * scale_rowcol[0] / own[0]).astype(np.int64) - o0
    cols = np.floor((np.arange(c0, c1) + 0.5) * scale_rowcol[1] / own[1]).astype(np.int64) - o1
    # The indices rise with the window's: the pixels over the rock are one
    # block, filled by a gather of rows, then of columns (a 2-D fancy index
    # would cost a hundred times more on the rock's own grid).
    on_rows = np.flatnonzero((rows >= 0) & (rows < h))
    on_cols = np.flatnonzero((cols >= 0) & (cols < w))
    mask = np.zeros((r1 - r0, c1 - c0), bool)
    if on_rows.size and on_cols.size:
        block = rock.mask.take(rows[on_rows], axis=0).take(cols[on_cols], axis=1)
        mask[on_rows[0] : on_rows[-1] + 1, on_cols[0] : on_cols[-1] + 1] = block
    return mask


#: How far, in pixels of the window's grid, a rock outlined on another grid
#: may reach past the window's edge and still be placed on it (rounding).
_FIT = 1.0


def _working_gray(
    pixels: NDArray[np.generic], window: tuple[int, int, int, int], scale_rowcol: tuple[float, float]
) -> NDArray[np.float32]:
    """Luminance in [0, 1] of a window (rows r0:r1, cols c0:c1) of the working
    image, from the photo's pixels under it, reduced as the working image was
    (exact halvings, then one resize) before the conversion to gray."""
    import cv2

    reduced, dtype, size = _reduced(pixels, window, scale_rowcol)
    gray = _unit(reduced[..., :3].astype(np.float32) @ _LUMA if reduced.ndim == 3 else reduced, dtype)
    if gray.shape != size[::-1]:
        gray = cv2.resize(gray, size, interpolation=cv2.INTER_LINEAR)
    return gray


def _working_colour(
    pixels: NDArray[np.generic], window: tuple[int, int, int, int], scale_rowcol: tuple[float, float]
) -> NDArray[np.float32] | None:
    """Red, green and blue in [0, 1] of a window of the working image, reduced
    as :func:`_working_gray` reduces it; None for a gray photo."""
    import cv2

    reduced, dtype, size = _reduced(pixels, window, scale_rowcol)
    if reduced.ndim != 3:
        return None
    colour = _unit(np.ascontiguousarray(reduced[..., :3]), dtype)
    if colour.shape[:2] != size[::-1]:
        colour = cv2.resize(colour, size, interpolation=cv2.INTER_LINEAR)
    return colour


def _reduced(
    pixels: NDArray[np.generic], window: tuple[int, int, int, int], scale_rowcol: tuple[float, float]
) -> tuple[NDArray[np.generic], np.dtype, tuple[int, int]]:
    """The photo's pixels under a window of the working image, reduced by exact
    halvings towards its scale; their type, and the window's (cols, rows)."""
    r0, r1, c0, c1 = window
    sr, sc = scale_rowcol
    photo = np.asarray(pixels)
    if photo.ndim == 3 and photo.shape[2] == 1:
        photo = photo[..., 0]
    p0, p1 = math.floor(r0 * sr), min(photo.shape[0], max(math.floor(r0 * sr) + 1, round(r1 * sr)))
    q0, q1 = math.floor(c0 * sc), min(photo.shape[1], max(math.floor(c0 * sc) + 1, round(c1 * sc)))
    size = (c1 - c0, r1 - r0)
    reduced, _ = _at_scale(_pyramid(photo[p0:p1, q0:q1], max(1, min(size))), max(sr, sc))
    return reduced, photo.dtype, size


#: Added to brightness in [0, 1] before its logarithm (ten levels of eight
#: bits): near black, sensor noise and compression make ratios meaningless,
#: and the logarithm would stretch a dark rock's texture into steps. On the
#: development part any value from 0.008 to 0.08 gives the same outlines.
_LOG_FLOOR = 0.04


def _main_cut(found: Segmentation, kept: NDArray[np.bool_]) -> Segmentation:
    """The segmentation with its main rock's mask cut to ``kept`` (a part of it, on its window).

    What is cut goes from the coverage and the labels; other rocks are left as they are.
    """
    rock = found.rocks[0]
    if kept is rock.mask:
        return found
    cut = rock.mask & ~kept
    main = dataclasses.replace(rock, mask=kept, coverage=np.where(cut, 0.0, rock.coverage).astype(np.float32))
    labels = found.labels.copy()
    view = labels[rock.window]
    view[cut & (view == 1)] = 0
    return dataclasses.replace(found, labels=labels, rocks=(main, *found.rocks[1:]))
