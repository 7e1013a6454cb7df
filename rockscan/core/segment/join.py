"""Pieces of one rock, joined again (with ``all_rocks``).

A rock with a textured skin, on a ground of about its own level, breaks
into pieces: veins and dark patches fall below the growth threshold and
part it, and the cues that cut touching rocks apart
(``rockscan.core.segment.split``) cut along them as readily as along the
contact between two rocks. On the development crowded scenes, most scenes
counted wrong held such a rock (none of its pieces most of it).

Whether two touching regions are one rock is read from the pair, as it
lies in the scene:

- **size** against the scene's median region: two pieces of a rock make
  about one rock, two rocks about two;
- **contact** along which they touch, against the smaller one's equivalent
  diameter: a cut through a rock runs across it, while rocks touch along a
  short stretch of their outlines;
- **shape**: the solidity of the two together and of each, and what joining
  gains; two pieces of a rock fill each other's notches;
- **appearance**: the difference of their levels and how far the line they
  meet along lies towards the ground's level, both in units of their step
  from the ground; and how sharp that line is against the skin around it
  (the median gradient along it over the median inside the pair, away from
  it and the outline): where two rocks touch, it is an occluding edge,
  sharper than either skin's texture; a vein is no sharper than the rest of
  the skin.

None decides alone (contact, the best, has an AUROC of 0.82 on the
development scenes). Gradient-boosted trees (:mod:`join_model`, written by
``scripts/fit_segment_join.py`` from development crowded scenes the
benchmark does not report) give each touching pair the probability that
it is one rock; the most probable pair is joined while that is at least
``JOIN_PROBABILITY``, and the joined region's pairs are measured again.

The same trees judge a cut the other way (:func:`parted`): rocks that touch
along a contact with neither a neck, a dark seam nor a pocket of ground stay
one region through every cut, and a large region that is not convex is cut
between the two peaks of its distance to the ground when its two halves are
unlikely to be one rock.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from rockscan.core.segment import join_model
from rockscan.core.segment.stats import solidity, touching_pairs
from rockscan.core.segment.trees import tree_sum, trees_of

__all__ = [
    "FEATURES",
    "JOIN_PROBABILITY",
    "PART_PROBABILITY",
    "join_probabilities",
    "joined",
    "pair_features",
    "parted",
]

#: What the trees read of a touching pair, in this order (module docstring).
FEATURES = (
    "union",
    "smaller",
    "ratio",
    "solidity",
    "solidity_gain",
    "least_solidity",
    "contact",
    "level_difference",
    "seam",
    "seam_sharpness",
)
#: Least probability that a pair is one rock for it to be joined. Chosen on
#: development crowded scenes the trees were not fitted on
#: (``scripts/fit_segment_join.py``).
JOIN_PROBABILITY = 0.6
#: A large region that is not convex is cut between the two peaks of its
#: distance to the ground when the two halves are less likely one rock than
#: this (:func:`parted`). Chosen on development crowded scenes the trees were
#: not fitted on: rocks one to one 92.65% -> 93.31% at 0.2 (93.24% at 0.1 and
#: 0.3), counted on the regions the join leaves.
PART_PROBABILITY = 0.2
#: ... when its area is at least this many times the median region's ...
PART_LARGE = 1.5
#: ... and its solidity under this.
PART_SOLIDITY = 0.92
#: The two peaks lie at least this share of the median region's equivalent
#: radius apart (at least 3 pixels).
PART_PEAKS = 0.3


def pair_features(
    labels: NDArray[np.integer], gray: NDArray[np.floating]
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Every pair of touching regions, and what :data:`FEATURES` reads of each.

    Parameters
    ----------
    labels : (rows, cols) ndarray of int
        0 for ground, ``1 .. n`` for the regions.
    gray : (rows, cols) ndarray of float
        Brightness on the same grid.

    Returns
    -------
    pairs : (n_pairs, 2) ndarray of int64
        Labels ``a < b`` of regions that touch (8-connected).
    features : (n_pairs, len(FEATURES)) ndarray of float64
    """
    labels = np.asarray(labels)
    gray = np.asarray(gray, dtype=np.float64)
    scene = _Scene.of(labels, gray)
    pairs = touching_pairs(labels)
    features = np.array([scene.features([a], [b]) for a, b in pairs], dtype=np.float64)
    return pairs, features.reshape(len(pairs), len(FEATURES))


def join_probabilities(features: NDArray[np.floating]) -> NDArray[np.float64]:
    """The probability that each pair of :func:`pair_features` is one rock."""
    features = np.asarray(features, dtype=np.float64).reshape(-1, len(FEATURES))
    t = np.clip(tree_sum(features, trees_of(join_model)), -50.0, 50.0)
    return 1.0 / (1.0 + np.exp(-t))


def joined(
    labels: NDArray[np.integer], gray: NDArray[np.floating], probability: float = JOIN_PROBABILITY
) -> NDArray[np.int64]:
    """Which region each region joins: the most probable pair first, while its
    probability is at least ``probability``.

    Parameters
    ----------
    labels : (rows, cols) ndarray of int
        0 for ground, ``1 .. n`` for the regions.
    gray : (rows, cols) ndarray of float
        Brightness on the same grid.
    probability : float
        Least probability of one rock for a pair to be joined.

    Returns
    -------
    (n + 1,) ndarray of int64
        For each label, the smallest label of the regions it is joined with
        (itself when it joins none); entry 0 is the ground's, 0.
    """
    labels = np.asarray(labels)
    gray = np.asarray(gray, dtype=np.float64)
    count = int(labels.max()) if labels.size else 0
    owner = np.arange(count + 1, dtype=np.int64)
    if count < 2:
        return owner
    scene = _Scene.of(labels, gray)
    members: dict[int, list[int]] = {k: [k] for k in range(1, count + 1)}
    pairs = [(a, b) for a, b in touching_pairs(labels).tolist()]
    first = join_probabilities(np.array([scene.features([a], [b]) for a, b in pairs]))
    measured = dict(zip(pairs, first.tolist(), strict=True))
    while measured:
        (a, b), best = max(measured.items(), key=lambda item: item[1])
        if best < probability:
            break
        # b's members join a; every pair that held either is measured again.
        members[a] = sorted(members[a] + members.pop(b))
        neighbours = {x for pair in measured if a in pair or b in pair for x in pair} - {a, b}
        measured = {pair: p for pair, p in measured.items() if a not in pair and b not in pair}
        for other in neighbours:
            pair = (min(a, other), max(a, other))
            measured[pair] = _probability(scene.features(members[pair[0]], members[pair[1]]))
    for group in members.values():
        owner[group] = min(group)
    return owner


def parted(
    labels: NDArray[np.integer], gray: NDArray[np.floating], probability: float = PART_PROBABILITY
) -> dict[int, NDArray[np.bool_]]:
    """Large regions that are two rocks, and where to cut them.

    Rocks that touch along a contact with neither a neck, a dark seam nor a
    pocket of ground stay one region through every cut of
    ``rockscan.core.segment.split``. A region of at least ``PART_LARGE``
    times the median region's area and solidity under ``PART_SOLIDITY`` is
    cut by a watershed of its distance to the ground from its two highest
    peaks; the cut stands when the join's trees give the two halves, as they
    lie in the scene, a probability of one rock under ``probability``.

    Parameters
    ----------
    labels : (rows, cols) ndarray of int
        0 for ground, ``1 .. n`` for the regions.
    gray : (rows, cols) ndarray of float
        Brightness on the same grid.
    probability : float
        The halves are two rocks when less likely one rock than this.

    Returns
    -------
    dict of int to (rows, cols) ndarray of bool
        For each region cut, the half of it that becomes a rock of its own
        (the rest stays with the region).
    """
    labels = np.asarray(labels)
    gray = np.asarray(gray, dtype=np.float64)
    count = int(labels.max()) if labels.size else 0
    if count < 1:
        return {}
    scene = _Scene.of(labels, gray)
    cuts = {}
    for k in range(1, count + 1):
        if scene.boxes[k] is None or scene.areas[k] < PART_LARGE * scene.median_area:
            continue
        box = scene.boxes[k]
        region = labels[box] == k
        half = _halves(region, PART_PEAKS * math.sqrt(scene.median_area / math.pi))
        if half is None:
            continue
        cut = np.zeros(labels.shape, bool)
        cut[box] = half
        if _probability(scene.split(k, cut).features([k], [count + 1])) < probability:
            cuts[k] = cut
    return cuts


def _halves(region: NDArray[np.bool_], apart: float) -> NDArray[np.bool_] | None:
    """The part of a region (not convex) flooded from the second of the two
    highest peaks of its distance to the ground, or None."""
    from scipy import ndimage
    from skimage.feature import peak_local_max
    from skimage.segmentation import watershed

    if solidity(region) >= PART_SOLIDITY:
        return None
    distance = ndimage.distance_transform_edt(np.pad(region, 1))[1:-1, 1:-1]
    peaks = peak_local_max(
        distance, min_distance=max(3, int(apart)), num_peaks=2, labels=region.astype(np.int32)
    )
    if len(peaks) < 2:
        return None
    markers = np.zeros(region.shape, np.int32)
    markers[tuple(peaks.T)] = [1, 2]
    return watershed(-distance, markers, mask=region) == 2


def _probability(features: list[float]) -> float:
    return float(join_probabilities(np.array([features]))[0])


#: How far the skin a seam's sharpness is compared with lies from the seam and
#: the outline, in pixels.
_SKIN_MARGIN = 3
#: Smoothing of the brightness before its gradient, in pixels (noise and JPEG).
_GRADIENT_SIGMA = 1.0
#: A seam's sharpness is capped here: on a skin without texture (a drawing, a
#: flat render) the ratio grows without bound and says no more.
_SHARPNESS_CAP = 100.0


class _Scene:
    """What the features of every pair of one scene share: its labels, its
    brightness and the gradient's magnitude, each region's window, area and
    level, the median region's area and the ground's level."""

    def __init__(self, labels, gray, gradient, boxes, areas, levels, median_area, ground) -> None:
        self.labels = labels
        self.gray = gray
        self.gradient = gradient
        self.boxes = boxes
        self.areas = areas
        self.levels = levels
        self.median_area = median_area
        self.ground = ground

    @classmethod
    def of(cls, labels: NDArray[np.integer], gray: NDArray[np.float64]) -> _Scene:
        import cv2
        from scipy import ndimage

        gray = np.ascontiguousarray(gray)
        rows, cols = np.gradient(cv2.GaussianBlur(gray, (0, 0), _GRADIENT_SIGMA))
        gradient = np.hypot(rows, cols)

        count = int(labels.max()) if labels.size else 0
        areas = np.bincount(labels.ravel(), minlength=count + 1).astype(np.float64)
        boxes = [None, *ndimage.find_objects(labels.astype(np.int32), max_label=count)]
        # Each region's median read in its own window: a fraction of sorting the frame by label.
        levels = np.zeros(count + 1)
        for k in range(1, count + 1):
            if boxes[k] is not None:
                levels[k] = np.median(gray[boxes[k]][labels[boxes[k]] == k])
        ground = float(np.median(gray[labels == 0])) if (labels == 0).any() else 0.0
        present = areas[1:][areas[1:] > 0]
        median_area = float(np.median(present)) if present.size else 1.0
        return cls(labels, gray, gradient, boxes, areas, levels, median_area, ground)

    def split(self, label: int, cut: NDArray[np.bool_]) -> _Scene:
        """The scene with the ``cut`` part of region ``label`` a region of its own,
        the next label after the last; the median region's area is the scene's."""
        from scipy import ndimage

        new = int(self.areas.size)
        labels = self.labels.copy()
        labels[cut] = new
        rest = self.boxes[label]
        boxes = [
            *self.boxes[:label],
            *ndimage.find_objects((labels[rest] == label).astype(np.int32)),
            *self.boxes[label + 1 :],
        ]
        inner = boxes[label]
        boxes[label] = tuple(
            slice(o.start + i.start, o.start + i.stop) for o, i in zip(rest, inner, strict=True)
        )
        boxes.append(ndimage.find_objects(cut.astype(np.int32))[0])
        areas = np.append(self.areas, float(np.count_nonzero(cut)))
        areas[label] -= areas[new]
        levels = np.append(self.levels, float(np.median(self.gray[cut])))
        levels[label] = float(np.median(self.gray[rest][labels[rest] == label]))
        return _Scene(labels, self.gray, self.gradient, boxes, areas, levels, self.median_area, self.ground)

    def features(self, first: list[int], second: list[int]) -> list[float]:
        """:data:`FEATURES` of two groups of regions, each taken as one."""
        import cv2

        rows, cols = self.labels.shape
        boxes = [self.boxes[k] for k in first + second if self.boxes[k] is not None]
        r0 = max(min(b[0].start for b in boxes) - 1, 0)
        r1 = min(max(b[0].stop for b in boxes) + 1, rows)
        c0 = max(min(b[1].start for b in boxes) - 1, 0)
        c1 = min(max(b[1].stop for b in boxes) + 1, cols)
        window = self.labels[r0:r1, c0:c1]
        a, b = np.isin(window, first), np.isin(window, second)
        area_a, area_b = float(self.areas[first].sum()), float(self.areas[second].sum())
        kernel = np.ones((3, 3), np.uint8)
        seam = (a & (cv2.dilate(b.astype(np.uint8), kernel) > 0)) | (
            b & (cv2.dilate(a.astype(np.uint8), kernel) > 0)
        )
        level_a, level_b = self._level(first), self._level(second)
        level = 0.5 * (level_a + level_b)
        step = abs(level - self.ground) + 1e-3
        towards_rock = 1.0 if level >= self.ground else -1.0
        gray = self.gray[r0:r1, c0:c1]
        seam_level = float(np.median(gray[seam])) if seam.any() else level
        solid_a, solid_b, solid = solidity(a), solidity(b), solidity(a | b)
        smaller = min(area_a, area_b)
        return [
            (area_a + area_b) / self.median_area,
            smaller / self.median_area,
            smaller / max(area_a, area_b, 1.0),
            solid,
            solid - max(solid_a, solid_b),
            min(solid_a, solid_b),
            # Each side of the contact counts its own pixels: half the seam is its length.
            0.5 * np.count_nonzero(seam) / (2.0 * math.sqrt(max(smaller, 1.0) / math.pi)),
            abs(level_a - level_b) / step,
            (level - seam_level) / step * towards_rock,
            self._sharpness(a | b, seam, (r0, r1, c0, c1)),
        ]

    def _sharpness(self, union: NDArray[np.bool_], seam: NDArray[np.bool_], window: tuple) -> float:
        """The median gradient along the seam over the median inside the pair,
        ``_SKIN_MARGIN`` pixels away from the seam and the outline (1 when no
        such skin is left; at most ``_SHARPNESS_CAP``)."""
        import cv2

        r0, r1, c0, c1 = window
        gradient = self.gradient[r0:r1, c0:c1]
        kernel = np.ones((2 * _SKIN_MARGIN + 1, 2 * _SKIN_MARGIN + 1), np.uint8)
        skin = (cv2.erode(union.astype(np.uint8), kernel) > 0) & ~(
            cv2.dilate(seam.astype(np.uint8), kernel) > 0
        )
        if not seam.any() or not skin.any():
            return 1.0
        ratio = float(np.median(gradient[seam])) / max(float(np.median(gradient[skin])), 1e-12)
        return min(ratio, _SHARPNESS_CAP)

    def _level(self, group: list[int]) -> float:
        """The median brightness of a group: its regions' medians weighed by area."""
        if len(group) == 1:
            return float(self.levels[group[0]])
        weights = self.areas[group]
        order = np.argsort(self.levels[group])
        cumulative = np.cumsum(weights[order])
        return float(self.levels[group][order][np.searchsorted(cumulative, 0.5 * cumulative[-1])])
