"""Detection: the lighting of the ground fitted and taken out, and the regions that
stand out from it, scored, at working size.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rockscan.core.segment.channels import _Channel, _unit, border_band
from rockscan.core.segment.split import label_image, rejoined, split_rocks
from rockscan.core.segment.stats import robust_spread
from rockscan.core.segment.types import RockMask, SegmentConfig


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
    #: The channel smoothed and flattened by the lighting, at detection size.
    flat: NDArray[np.float32]


def _poly_terms(rows_norm: NDArray[np.float64], cols_norm: NDArray[np.float64], degree: int) -> list:
    return [cols_norm**i * rows_norm**j for i in range(degree + 1) for j in range(degree + 1 - i)]


def _norm_coords(n: int) -> NDArray[np.float64]:
    """Pixel centres of an axis of n pixels mapped to [-1, 1] (frame edges at -1 and 1)."""
    return (np.arange(n) + 0.5) / n * 2.0 - 1.0


#: Shortest side from which the lighting is fitted to every fourth ground pixel each way
#: (``border_band`` is then at least 4 pixels wide).
_SAMPLED = 100


def _fit_lighting(image: NDArray[np.float32], ground: NDArray[np.bool_], degree: int) -> NDArray[np.float64]:
    """Polynomial surface through the ground pixels; its coefficients.

    Least squares, twice more without the pixels beyond 2.5 robust standard
    deviations of the fit: a rock that reaches into the ground pixels, a
    pebble or a shadow then do not bend the surface.
    """
    rows, cols = image.shape
    # Every fourth pixel each way is plenty for a smooth surface and sixteen times
    # cheaper, where the border band is at least 4 pixels wide: a narrower one
    # (a frame under _SAMPLED pixels across) would be sampled along two sides
    # only, and the surface would be free to tilt across the other two.
    rr, cc = np.nonzero(ground[::4, ::4])
    rr, cc = rr * 4, cc * 4
    if rr.size < 3 * (degree + 1) ** 2 or min(rows, cols) < _SAMPLED:
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
        if np.count_nonzero(inliers) < terms.shape[1] * 3:
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
    ground = border_band((rows, cols))
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
        if found is None:
            # Nothing stands out against the whole border's (or ground's) spread:
            # neighbours reaching into a crop, or a ground whose texture varies
            # across the frame, may have widened it. Try most stretches' spread.
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
    return _Detection(score, regions, polarity, lighting, channel, outliers, others, alternatives, flat)


def _luminance_polarity(work: NDArray[np.generic], dtype: np.dtype, rock: RockMask) -> str:
    """Whether a rock found by its hue is lighter or darker than the ground around it."""
    lum = _Channel("luminance", True).values(_unit(work[rock.window], dtype))
    outside = lum[~rock.mask]
    if outside.size == 0:
        return "light"
    return "light" if float(np.median(lum[rock.mask])) > float(np.median(outside)) else "dark"


def _robust_z(
    flat: NDArray[np.float32], ground: NDArray[np.bool_], floor: float, *, local: bool = False
) -> NDArray[np.float32]:
    """Deviation from the ground in robust standard deviations (median, MAD, at least ``floor``;
    with ``local``, at most the typical spread of the ground's stretches)."""
    values = flat[ground] if np.count_nonzero(ground) > 50 else flat.ravel()
    # Every fourth value gives the same statistics at a quarter of the cost.
    values = values[::4] if values.size > 4000 else values
    median = float(np.median(values))
    mad = robust_spread(values, median)
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
                spreads.append(robust_spread(values))
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
    best_strength = 0.0
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
                if np.count_nonzero(part) >= min_area and (signed[part] > config.z_detect).any()
            ]
        else:
            regions = [labels == i for i in usable]
        if not regions:
            continue
        measures = _region_measures(signed, regions)
        scores = _region_scores(measures)
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
                # Its component is the label under its first pixel.
                whole = labels == labels.flat[int(np.argmax(regions[main]))]
                if np.count_nonzero(whole) > 1.2 * np.count_nonzero(regions[main]):
                    alternatives.append((total, whole, polarity))
        strength = total
        if all_rocks and split and total > 0:
            kept = _rock_like(signed, regions, measures, scores, config)
            # With --all, the polarity whose rocks together stand out most: one
            # dark region (an eye in a cat's fur, a hole) must not outweigh a
            # scene of light rocks, nor one glint a scene of dark ones.
            strength = float(scores[kept].sum())
        if total <= 0 or (best is not None and strength <= best_strength):
            continue
        best_strength = strength
        if all_rocks and split:
            regions = _every_rock(signed, regions, kept, min_area)
        elif all_rocks:
            # Before the last round, the rocks to leave out of the ground: those
            # that stand out about as clearly as the main one; ground texture
            # that passes the thresholds scores far less. These regions are
            # whole components, apart: their measured areas are their own.
            areas_r = measures[0]
            keep = (scores >= _RELATIVE_SCORE * total) & (areas_r >= _RELATIVE_AREA * areas_r[main])
            largest = float(areas_r[keep].max())
            regions = [regions[i] for i in np.flatnonzero(keep & (areas_r >= _RELATIVE_AREA * largest))]
        else:
            parts = _split(regions[main], signed, min_area) if split else []
            regions = [max(parts, key=lambda r: int(np.count_nonzero(r)))] if parts else [regions[main]]
        # In a crop, the neighbours that would be rocks with --all.
        others = [
            candidates[i]
            for i in range(len(candidates))
            if i != main
            and not all_rocks
            and scores[i] >= _RELATIVE_SCORE * total
            and np.count_nonzero(candidates[i]) >= _RELATIVE_AREA * np.count_nonzero(candidates[main])
        ]
        best = (total, regions, polarity, others)
    if best is None:
        return None
    alternatives.sort(key=lambda a: -a[0])
    # The chosen region first among the alternatives: whole, before any cut.
    return (*best, alternatives)


def _rock_like(
    signed: NDArray[np.float32],
    regions: list[NDArray[np.bool_]],
    measures: tuple[NDArray[np.float64], ...],
    scores: NDArray[np.float64],
    config: SegmentConfig,
) -> NDArray[np.bool_]:
    """Which of one polarity's regions are rocks, with ``all_rocks`` (module docstring, step 5).

    A region is a rock if it looks as much like one as the best regions do,
    whatever its size (a small rock scores less than a large one, but not per
    pixel), or if it scores at least ``_RELATIVE_SCORE`` of the main rock; and
    if less than ``_FRAME_SHARE`` of its edge runs along the frame's. The best
    regions are several, so that one region of ground (a shadowed band, a
    stripe) cannot set the standard alone.
    """
    main = int(np.argmax(scores))
    likeness = _likeness(measures)
    reference = float(np.median(likeness[np.argsort(-scores, kind="stable")[:_TYPICAL]]))
    # Most of a rock's pixels stand out as far as a seed must: a lighter
    # patch of ground that only just passes the growth threshold does not.
    contrast = np.array([float(np.median(signed[r])) for r in regions])
    alike = (likeness >= _LIKENESS * reference) & (contrast >= config.z_detect)
    keep = (alike | (scores >= _RELATIVE_SCORE * scores[main])) & (measures[3] < _FRAME_SHARE)
    keep[main] = True
    return keep


def _every_rock(
    signed: NDArray[np.float32],
    regions: list[NDArray[np.bool_]],
    keep: NDArray[np.bool_],
    min_area: float,
) -> list[NDArray[np.bool_]]:
    """The regions ``keep`` marks as rocks (:func:`_rock_like`), each cut where its
    contrast has two levels, touching pieces that together are convex joined
    again; largest first.

    Rocks much smaller than the largest are dropped only once every outline
    has been cut into its rocks (``min_relative_area``; module docstring of
    :mod:`rockscan.core.segment`): here the largest region may still be a
    cluster of touching rocks.
    """
    rocks = [part for i in np.flatnonzero(keep) for part in _split(regions[i], signed, min_area)]
    rocks = rejoined(rocks)
    return sorted(rocks, key=lambda r: -int(np.count_nonzero(r)))


def _region_measures(
    signed: NDArray[np.float32], regions: list[NDArray[np.bool_]]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Each region's area, edge step, compactness and share of its edge on the frame's.

    The edge step is the mean contrast just inside the region less just
    outside it: a rock's edge is a step as high as its contrast; a blob of
    texture fades out and barely steps at its edge. Two touching rocks each
    have an edge along the cut between them. Compactness is ``4 pi area /
    perimeter**2`` at most 1: rocks are solid; the ground between several
    rocks, or a blob of texture, has a long ragged edge for its area.
    """
    import cv2

    rows, cols = signed.shape
    labels = label_image(regions)
    count = len(regions) + 1
    band = np.ones((5, 5), np.uint8)
    # OpenCV's morphology takes 16-bit labels, and far fewer regions than 65536 compete.
    small = labels.astype(np.uint16) if count < 65536 else labels.astype(np.float32)
    grown = cv2.dilate(small, band)
    inner = (labels > 0) & ((cv2.erode(small, band) != small) | (grown != small))
    outer_labels = grown.astype(np.int64)
    outer = (labels == 0) & (outer_labels > 0)
    clipped = np.minimum(signed, _Z_CAP)
    inner_n = np.bincount(labels[inner], minlength=count)[1:]
    inner_sum = np.bincount(labels[inner], weights=clipped[inner], minlength=count)[1:]
    outer_n = np.bincount(outer_labels[outer], minlength=count)[1:]
    outer_sum = np.bincount(outer_labels[outer], weights=clipped[outer], minlength=count)[1:]
    step = inner_sum / np.maximum(inner_n, 1) - outer_sum / np.maximum(outer_n, 1)
    # A rock lies inside the frame; the ground (or a lighting residue) runs along it.
    # The inner band is two pixels wide: half its count is the perimeter.
    edge = np.zeros((rows, cols), bool)
    edge[0], edge[-1], edge[:, 0], edge[:, -1] = True, True, True, True
    perimeter = np.maximum(inner_n / 2.0, 1.0)
    on_edge = np.bincount(labels[edge], minlength=count)[1:]
    share = np.clip(on_edge / perimeter, 0.0, 1.0)
    areas = np.bincount(labels.ravel(), minlength=count)[1:].astype(np.float64)
    compactness = np.minimum(4.0 * np.pi * areas / perimeter**2, 1.0)
    return areas, step, compactness, share


def _likeness(measures: tuple[NDArray[np.float64], ...]) -> NDArray[np.float64]:
    """How much each region looks like a rock, whatever its size: its score per pixel."""
    _, step, compactness, share = measures
    return np.maximum(step, 0.0) * compactness * (1.0 - share) ** 2


def _region_scores(measures: tuple[NDArray[np.float64], ...]) -> NDArray[np.float64]:
    """How clearly each region stands out as a rock (module docstring, step 5).

    Its area, times its edge step, times its compactness, times the square of
    the share of its edge that does not run along the frame's
    (:func:`_region_measures`).
    """
    return measures[0] * _likeness(measures)


def _centre_weight(regions: list[NDArray[np.bool_]], shape: tuple[int, int]) -> NDArray[np.float64]:
    """1 at the frame's centre, falling to ``1 - _CENTRE_PRIOR`` at its corners (squared distance)."""
    import cv2

    weights = []
    rows_at, cols_at = np.arange(shape[0]), np.arange(shape[1])
    for region in regions:
        # The centroid from the region's row and column profiles: two sums, no
        # pixel list (OpenCV's sums of the bytes cost a fifth of numpy's).
        pixels = np.ascontiguousarray(region).view(np.uint8)
        by_row = cv2.reduce(pixels, 1, cv2.REDUCE_SUM, dtype=cv2.CV_32S).ravel()
        by_col = cv2.reduce(pixels, 0, cv2.REDUCE_SUM, dtype=cv2.CV_32S).ravel()
        area = max(int(by_row.sum()), 1)
        dy = (int(by_row @ rows_at) / area + 0.5) / shape[0] * 2.0 - 1.0
        dx = (int(by_col @ cols_at) / area + 0.5) / shape[1] * 2.0 - 1.0
        weights.append(1.0 - _CENTRE_PRIOR * 0.5 * (dy * dy + dx * dx))
    return np.array(weights)


#: Regions of each polarity that compete for the main rock.
_ALTERNATIVES = 3

#: How much a rock at a corner of the frame loses against one at its centre.
_CENTRE_PRIOR = 0.3


#: Before the last round, and for the neighbours in a crop: the smallest score
#: and area of another rock as fractions of the main rock's.
_RELATIVE_SCORE = 0.1
_RELATIVE_AREA = 0.15

#: With ``all_rocks``, a region is a rock if its likeness (score per pixel) is at
#: least ``_LIKENESS`` of the median of the ``_TYPICAL`` best-scoring regions',
#: and less than ``_FRAME_SHARE`` of its edge runs along the frame's.
_TYPICAL = 5
_LIKENESS = 0.5
_FRAME_SHARE = 0.5


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
    try:
        hist, edges = np.histogram(values, bins=64)
    except ValueError:
        # Values all but equal (float32 holds no 64 bins between them): one level.
        return float(values.min()), 0.0
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
