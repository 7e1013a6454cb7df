"""Segmentation benchmark: rockscan and what a user would try instead, against exact truth.

Photos come from :mod:`scenes` (a generator independent of
``rockscan.core.render``, see its docstring for the conditions and the split) and
from real photos that packages ship: every coin of scikit-image's ``coins()``,
every single-coin crop at native resolution with a margin of a third of its
diameter, the cell of ``cell()`` inside its dark halo, and every whole nucleus
of mahotas' fluorescence micrograph ``nuclear.png``, with ``--all`` and as
crops (the reference outlines are ``tests/data/coins_reference.png``,
``cell_reference.png`` and ``nuclei_reference.png``, see docs/segmentation.md).

Parts: ``dev`` (seeds 0-9999, textures from the top half of each source
photo) is for tuning; ``heldout`` (seeds 100000+, textures from the bottom
half) is for reporting only; ``real`` is the real photos.

Columns, for photos of one rock and crops (the truth is one rock): share of
photos whose outline has IoU >= 0.9 with the truth, median IoU, median error
of the centroid in equivalent radii ``sqrt(area / pi)`` of the truth, and
"no rock" (the method found nothing). For ``--all`` scenes: share of scenes
whose count is exact, share of true rocks matched one to one (IoU > 0.5;
above that threshold a match is unique), merges (found regions holding most of
two or more true rocks) and splits (true rocks holding most of two or more
found regions). Each share is followed by its 95% interval, in parentheses: how far
it may lie from the method's true rate with this many photos (Wilson's score
interval over the photos or scenes; for rocks one to one, a bootstrap over the
scenes, whose rocks fail together).

After the table, for each part: the AUROC of rockscan's segmentation score
(outlines of IoU >= 0.9 against those below 0.8, with the central 95% of its
values over bootstrap resamples of the photos), and rockscan's share at
IoU >= 0.9 apart for rocks lighter and darker than their ground (judged on
the truth: the rock's median gray against a ring of ground round it), and how
its outlines below IoU 0.9 go wrong: too large (precision, the share of the
outline on the rock, below recall, the share of the rock inside it) or too
small, and how many are near misses (IoU 0.8-0.9). The JSON records carry each
photo's precision and recall.

Rows:

* ``rockscan``: ``rockscan.core.segment.segment``; the main rock (or every rock
  with ``all_rocks``) outlined as the pipeline does (``trace_outline`` of the
  rock's coverage, mapped to photo pixels) and filled at photo resolution;
* ``otsu``: gray, 5x5 Gaussian blur, Otsu's threshold (the ground is the
  class covering most of the frame's border), holes filled, connected
  components; the largest is the rock (the one nearest the centre for crops);
* ``watershed``: the same mask split by scikit-image's distance-transform
  watershed (markers: ``peak_local_max`` of the distance, ``min_distance`` a
  40th of the shorter side, at least 5 px);
* ``grabcut``: OpenCV's GrabCut from a box 8% inside the frame, 5 iterations,
  on a copy of at most 256 px (GrabCut takes seconds at full size), the mask
  scaled back; components as for ``otsu``.

Other segmenters are judged with :func:`evaluate`.

Run ``python scripts/bench_segment.py --help`` for options.
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import os
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage as ndi

sys.path.insert(0, str(Path(__file__).resolve().parent))
import scenes

from rockscan.core.errors import NoRockFoundError, RockscanError

ROOT = Path(__file__).resolve().parents[1]
COINS_REFERENCE = ROOT / "tests" / "data" / "coins_reference.png"
CELL_REFERENCE = ROOT / "tests" / "data" / "cell_reference.png"
NUCLEI_REFERENCE = ROOT / "tests" / "data" / "nuclei_reference.png"
#: Real-photo conditions (part ``real``).
REAL_CONDITIONS = ("coins-all", "coins-crops", "cell", "nuclei-all", "nuclei-crops")
#: Truth label of pixels that are not scored (a real photo's objects cut by the
#: frame or hidden by glare): a found region mostly on them is neither right nor wrong.
UNSCORED = -1
METHODS = ("rockscan", "otsu", "watershed", "grabcut")
PARTS = ("dev", "heldout", "real")
#: IoU a rock must reach to count as outlined; IoU a one-to-one match must exceed.
IOU_GOOD = 0.9
IOU_MATCH = 0.5

#: ``method(pixels, kind) -> labels`` at photo resolution (1 = the main rock).
Method = Callable[[NDArray, str], NDArray[np.int32]]


# --------------------------------------------------------------------------- metrics


def iou(a: NDArray[np.bool_], b: NDArray[np.bool_]) -> float:
    """Intersection over union of two masks (1.0 when both are empty)."""
    union = int(np.count_nonzero(a | b))
    return 1.0 if union == 0 else int(np.count_nonzero(a & b)) / union


@dataclass(frozen=True)
class RockScore:
    """How one outline compares with the true rock."""

    iou: float
    centroid_error: float  # in equivalent radii of the truth; inf when nothing was found
    no_rock: bool
    precision: float = 0.0  # share of the found mask on the rock
    recall: float = 0.0  # share of the rock found


def score_rock(found: NDArray[np.bool_], truth: NDArray[np.bool_]) -> RockScore:
    """IoU, centroid error, precision and recall of a found mask against the true one."""
    n_found = int(np.count_nonzero(found))
    if n_found == 0:
        return RockScore(0.0, float("inf"), True)
    n_truth = int(np.count_nonzero(truth))
    shared = int(np.count_nonzero(found & truth))
    radius = float(np.sqrt(n_truth / np.pi))
    c_found = np.array(ndi.center_of_mass(found))
    c_truth = np.array(ndi.center_of_mass(truth))
    return RockScore(
        shared / (n_found + n_truth - shared),
        float(np.hypot(*(c_found - c_truth)) / radius),
        False,
        shared / n_found,
        shared / max(n_truth, 1),
    )


@dataclass(frozen=True)
class CrowdScore:
    """How the rocks found in a scene compare with the true ones."""

    n_true: int
    n_found: int
    matched: int  # one-to-one matches at IoU > 0.5
    merges: int  # found regions holding most of >= 2 true rocks
    splits: int  # true rocks holding most of >= 2 found regions


def overlap_table(found: NDArray[np.integer], truth: NDArray[np.integer]) -> NDArray[np.int64]:
    """Pixel counts ``[i, j]`` of found label ``i`` and true label ``j`` (0 = ground)."""
    n_found, n_true = int(found.max()) + 1, int(truth.max()) + 1
    pairs = found.astype(np.int64).ravel() * n_true + truth.astype(np.int64).ravel()
    return np.bincount(pairs, minlength=n_found * n_true).reshape(n_found, n_true)


def score_crowd(found: NDArray[np.integer], truth: NDArray[np.integer]) -> CrowdScore:
    """Count, one-to-one matches, merges and splits of a labelled scene.

    Labels need not be dense; a label absent from an image is no region.
    """
    from scipy.optimize import linear_sum_assignment

    found = _dense(found)
    truth = _dense(truth)
    table = overlap_table(found, truth)
    inter = table[1:, 1:].astype(np.float64)
    area_found = table[1:, :].sum(axis=1).astype(np.float64)
    area_true = table[:, 1:].sum(axis=0).astype(np.float64)
    n_found, n_true = inter.shape
    matched = 0
    if n_found and n_true:
        union = area_found[:, None] + area_true[None, :] - inter
        ious = inter / np.maximum(union, 1.0)
        rows, cols = linear_sum_assignment(-ious)
        matched = int(np.count_nonzero(ious[rows, cols] > IOU_MATCH))
    # Most of a true rock inside one found region; most of a found region inside one true rock.
    holds_true = inter >= 0.5 * area_true[None, :]
    holds_found = inter >= 0.5 * area_found[:, None]
    merges = int(np.count_nonzero(holds_true.sum(axis=1) >= 2)) if n_true else 0
    splits = int(np.count_nonzero(holds_found.sum(axis=0) >= 2)) if n_found else 0
    return CrowdScore(n_true, n_found, matched, merges, splits)


def scored_parts(
    found: NDArray[np.integer], truth: NDArray[np.integer]
) -> tuple[NDArray[np.int32], NDArray[np.int32]]:
    """A scene's found regions and truth without what is not scored.

    A found region at least half on ``UNSCORED`` pixels of the truth (an
    object cut by the frame, or hidden by glare) is dropped; those pixels are
    ground in the truth.
    """
    unscored = truth == UNSCORED
    if not unscored.any():
        return np.asarray(found, np.int32), np.asarray(truth, np.int32)
    found = np.asarray(found, np.int32).copy()
    sizes = np.bincount(found.ravel())
    on = np.bincount(found[unscored], minlength=sizes.size)
    dropped = np.flatnonzero(on >= 0.5 * np.maximum(sizes, 1))
    found[np.isin(found, dropped[dropped > 0])] = 0
    return found, np.maximum(truth, 0).astype(np.int32)


def _dense(labels: NDArray[np.integer]) -> NDArray[np.int32]:
    """Labels renumbered 1..n in order, ground 0."""
    values = np.unique(labels)
    values = values[values > 0]
    remap = np.zeros(int(labels.max()) + 1 if labels.size else 1, np.int32)
    remap[values] = np.arange(1, len(values) + 1)
    return remap[labels]


# --------------------------------------------------------------------------- methods


def segmentation_labels(seg, shape: tuple[int, int]) -> NDArray[np.int32]:
    """A ``rockscan.core.segment.Segmentation`` as labels at photo resolution.

    Each rock is outlined as the pipeline outlines it (the 0.5 level of its
    coverage, in photo pixels) and filled; rock 1 is the main rock.
    """
    from skimage.draw import polygon

    from rockscan.core.outline import trace_outline

    labels = np.zeros(shape, np.int32)
    for i, rock in enumerate(seg.rocks, start=1):
        try:
            outline = trace_outline(rock.coverage, scale=seg.scale_rowcol, origin_rowcol=rock.origin_rowcol)
        except NoRockFoundError:
            continue
        rr, cc = polygon(outline.contour_rowcol[:, 0], outline.contour_rowcol[:, 1], shape)
        free = labels[rr, cc] == 0
        labels[rr[free], cc[free]] = i
    return labels


def as_method(segment_fn: Callable) -> Method:
    """A segmenter ``segment_fn(pixels, all_rocks=bool)`` as a benchmark method.

    ``segment_fn`` returns a ``rockscan.core.segment.Segmentation`` (anything with
    ``rocks`` and ``scale_rowcol``) or a label image at photo resolution
    (1 = the main rock); it raises ``NoRockFoundError`` or returns no label
    when it finds nothing. The method returns the labels and the main
    rock's segmentation score (NaN for a label image or nothing found).
    """

    def method(pixels: NDArray, kind: str) -> tuple[NDArray[np.int32], float]:
        try:
            out = segment_fn(pixels, all_rocks=kind == "all")
        except NoRockFoundError:
            return np.zeros(pixels.shape[:2], np.int32), float("nan")
        if hasattr(out, "rocks") and hasattr(out, "scale_rowcol"):
            score = float(out.rocks[0].score) if out.rocks else float("nan")
            return segmentation_labels(out, pixels.shape[:2]), score
        labels = np.asarray(out)
        if labels.shape != pixels.shape[:2]:
            raise ValueError(f"labels of shape {labels.shape} for a photo of shape {pixels.shape[:2]}")
        return labels.astype(np.int32), float("nan")

    return method


def _rockscan(pixels: NDArray, kind: str) -> tuple[NDArray[np.int32], float]:
    from rockscan.core.segment import segment

    return as_method(segment)(pixels, kind)


def _gray(pixels: NDArray) -> NDArray[np.uint8]:
    import cv2

    return pixels if pixels.ndim == 2 else cv2.cvtColor(np.ascontiguousarray(pixels), cv2.COLOR_RGB2GRAY)


def _otsu_mask(pixels: NDArray) -> NDArray[np.bool_]:
    """Otsu's threshold of the blurred gray photo; the class on most of the border is ground."""
    import cv2

    gray = cv2.GaussianBlur(_gray(pixels), (5, 5), 0)
    _, binary = cv2.threshold(gray, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    mask = binary > 0
    border = np.concatenate([mask[0], mask[-1], mask[:, 0], mask[:, -1]])
    if border.mean() > 0.5:
        mask = ~mask
    return mask


def _min_area(shape: tuple[int, int]) -> int:
    # What a user drops as specks: 0.1% of the frame.
    return max(16, int(0.001 * shape[0] * shape[1]))


def _components(mask: NDArray[np.bool_]) -> NDArray[np.int32]:
    """Connected components with holes filled, specks dropped, by decreasing area."""
    labels, n = ndi.label(mask)
    if n == 0:
        return labels.astype(np.int32)
    out = np.zeros(mask.shape, np.int32)
    areas = np.bincount(labels.ravel())[1:]
    objects = ndi.find_objects(labels)
    order = np.argsort(-areas, kind="stable")
    k = 0
    for j in order:
        if areas[j] < _min_area(mask.shape):
            break
        sl = objects[j]
        filled = ndi.binary_fill_holes(labels[sl] == j + 1)
        k += 1
        out[sl][filled & (out[sl] == 0)] = k
    return out


def _choose(labels: NDArray[np.int32], kind: str) -> NDArray[np.int32]:
    """Every region (``all``), the largest (``one``) or the one nearest the centre (``crop``)."""
    if kind == "all" or labels.max() == 0:
        return labels
    if kind == "one":
        areas = np.bincount(labels.ravel())[1:]
        keep = int(np.argmax(areas)) + 1
    else:
        centre = (np.array(labels.shape) - 1) / 2.0
        index = np.arange(1, labels.max() + 1)
        present = np.bincount(labels.ravel(), minlength=labels.max() + 1)[1:] > 0
        # Distance from the centre to each region's nearest pixel: 0 for the region under it.
        dist = ndi.distance_transform_edt(~_point(labels.shape, centre))
        nearest = ndi.minimum(dist, labels, index)
        nearest = np.where(present, nearest, np.inf)
        keep = int(index[int(np.argmin(nearest))])
    return (labels == keep).astype(np.int32)


def _point(shape: tuple[int, int], rowcol: NDArray) -> NDArray[np.bool_]:
    out = np.zeros(shape, bool)
    out[round(rowcol[0]), round(rowcol[1])] = True
    return out


def _otsu(pixels: NDArray, kind: str) -> NDArray[np.int32]:
    return _choose(_components(_otsu_mask(pixels)), kind)


def _watershed(pixels: NDArray, kind: str) -> NDArray[np.int32]:
    from skimage.feature import peak_local_max
    from skimage.segmentation import watershed

    cc = _components(_otsu_mask(pixels))
    mask = cc > 0
    if not mask.any():
        return cc
    distance = ndi.distance_transform_edt(mask)
    min_distance = max(5, min(pixels.shape[:2]) // 40)
    peaks = peak_local_max(distance, min_distance=min_distance, labels=cc, exclude_border=False)
    markers = np.zeros(mask.shape, np.int32)
    markers[tuple(peaks.T)] = np.arange(1, len(peaks) + 1)
    labels = watershed(-distance, markers, mask=mask).astype(np.int32)
    return _choose(_dense(labels), kind)


def _grabcut(pixels: NDArray, kind: str) -> NDArray[np.int32]:
    import cv2

    rgb = pixels if pixels.ndim == 3 else np.repeat(pixels[..., None], 3, axis=2)
    rows, cols = rgb.shape[:2]
    factor = min(1.0, 256.0 / max(rows, cols))
    small = cv2.resize(
        rgb, (max(8, round(cols * factor)), max(8, round(rows * factor))), interpolation=cv2.INTER_AREA
    )
    h, w = small.shape[:2]
    mr, mc = max(1, round(0.08 * h)), max(1, round(0.08 * w))
    mask = np.zeros((h, w), np.uint8)
    bgd, fgd = np.zeros((1, 65), np.float64), np.zeros((1, 65), np.float64)
    try:
        cv2.grabCut(
            np.ascontiguousarray(small[..., ::-1]),
            mask,
            (mc, mr, w - 2 * mc, h - 2 * mr),
            bgd,
            fgd,
            5,
            cv2.GC_INIT_WITH_RECT,
        )
    except cv2.error:
        return np.zeros((rows, cols), np.int32)
    fg = ((mask == cv2.GC_FGD) | (mask == cv2.GC_PR_FGD)).astype(np.float32)
    fg = cv2.resize(fg, (cols, rows), interpolation=cv2.INTER_LINEAR) >= 0.5
    return _choose(_components(fg), kind)


BUILTIN_METHODS: dict[str, Method] = {
    "rockscan": _rockscan,
    "otsu": _otsu,
    "watershed": _watershed,
    "grabcut": _grabcut,
}


# --------------------------------------------------------------------------- photos


def _read_labels(path: Path) -> NDArray[np.int32]:
    from PIL import Image

    return np.asarray(Image.open(path), dtype=np.int32)


def coins_reference() -> NDArray[np.int32]:
    """Reference labels of the 24 coins of ``skimage.data.coins()`` (see docs/segmentation.md)."""
    return _read_labels(COINS_REFERENCE)


def cell_reference() -> NDArray[np.int32]:
    """Reference outline of the cell of ``skimage.data.cell()``, without its halo (label 1)."""
    return _read_labels(CELL_REFERENCE)


def nuclear_photo() -> NDArray[np.uint8]:
    """The fluorescence micrograph of nuclei that mahotas ships (``demos/data/nuclear.png``), gray.

    Read from mahotas' installed files without importing it (its compiled
    parts are not needed).
    """
    import importlib.util

    from PIL import Image

    spec = importlib.util.find_spec("mahotas")
    if spec is None or not spec.submodule_search_locations:
        raise RuntimeError("the nuclei photo comes with mahotas: pip install mahotas (or rockscan[test])")
    path = Path(spec.submodule_search_locations[0]) / "demos" / "data" / "nuclear.png"
    return np.asarray(Image.open(path).convert("L"))


def nuclei_reference() -> NDArray[np.int32]:
    """Reference labels of the 40 whole nuclei of :func:`nuclear_photo`, ``UNSCORED``
    where nuclei lie that cannot be outlined whole (see docs/segmentation.md)."""
    labels = _read_labels(NUCLEI_REFERENCE)
    labels[labels == 255] = UNSCORED
    return labels


def coin_crops() -> list[tuple[NDArray[np.uint8], NDArray[np.int32]]]:
    """Every coin cut out at native resolution with a margin of a third of its diameter."""
    from skimage import data

    return _crops(data.coins(), coins_reference())


def nuclei_crops() -> list[tuple[NDArray[np.uint8], NDArray[np.int32]]]:
    """Every whole nucleus cut out at native resolution with a margin of a third of its diameter."""
    return _crops(nuclear_photo(), np.maximum(nuclei_reference(), 0))


@functools.cache
def _real_crops(condition: str) -> list[tuple[NDArray[np.uint8], NDArray[np.int32]]]:
    """The crops of a real photo, cut once per process: a photo of the benchmark is one crop of them."""
    return nuclei_crops() if condition == "nuclei-crops" else coin_crops()


def _crops(
    image: NDArray[np.uint8], labels: NDArray[np.int32]
) -> list[tuple[NDArray[np.uint8], NDArray[np.int32]]]:
    """Each labelled object cut out with a margin of a third of its diameter, and its truth (label 1)."""
    out = []
    for k, sl in enumerate(ndi.find_objects(labels), start=1):
        r0, r1, c0, c1 = sl[0].start, sl[0].stop, sl[1].start, sl[1].stop
        diameter = max(r1 - r0, c1 - c0)
        rc, cc = 0.5 * (r0 + r1 - 1), 0.5 * (c0 + c1 - 1)
        half = diameter / 2 + diameter / 3
        top, bottom = max(0, round(rc - half)), min(image.shape[0], round(rc + half) + 1)
        left, right = max(0, round(cc - half)), min(image.shape[1], round(cc + half) + 1)
        out.append((image[top:bottom, left:right], (labels[top:bottom, left:right] == k).astype(np.int32)))
    return out


def photo(part: str, condition: str, index: int) -> tuple[NDArray, NDArray[np.int32], str]:
    """Photo ``index`` of a condition: (pixels, truth labels, kind)."""
    if part == "real":
        from skimage import data

        if condition == "coins-all":
            return data.coins(), coins_reference(), "all"
        if condition == "cell":
            return data.cell(), cell_reference(), "one"
        if condition == "nuclei-all":
            return nuclear_photo(), nuclei_reference(), "all"
        image, truth = _real_crops(condition)[index]
        return image.copy(), truth.copy(), "crop"
    seed = scenes.part_seeds(part, 1, index)[0]
    kind = scenes.CONDITION_KINDS[condition]
    if _CACHE_DIR is not None:
        path = _CACHE_DIR / f"v{scenes.GENERATOR_VERSION}-{condition}-{seed}.npz"
        if path.exists():
            with np.load(path) as stored:
                return stored["image"], stored["labels"], kind
    scene = scenes.make_scene(condition, seed)
    if _CACHE_DIR is not None:
        _CACHE_DIR.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp.npz")
        np.savez_compressed(tmp, image=scene.image, labels=scene.labels)
        tmp.replace(path)  # atomic: parallel workers never read half a file
    return scene.image, scene.labels, kind


def photo_count(part: str, condition: str, n: int) -> int:
    if part == "real":
        if condition.endswith("-crops"):
            return len(_real_crops(condition))
        return 1
    return n


# --------------------------------------------------------------------------- evaluation

_METHODS: dict[str, Method] = {}
#: Where generated photos are kept between runs (None: generate every time).
_CACHE_DIR: Path | None = None


def _score_one(task: tuple[str, str, int]) -> list[dict]:
    part, condition, index = task
    pixels, truth, kind = photo(part, condition, index)
    records = []
    for name, method in _METHODS.items():
        start = time.perf_counter()
        try:
            found = method(pixels, kind)
            error = ""
            score = float("nan")
            if isinstance(found, tuple):
                found, score = found
        except RockscanError as exc:  # a photo the method refuses
            found, error, score = np.zeros(truth.shape, np.int32), str(exc), float("nan")
        seconds = time.perf_counter() - start
        record = {"method": name, "part": part, "condition": condition, "index": index, "kind": kind}
        if kind == "all":
            record.update(asdict(score_crowd(*scored_parts(found, truth))))
        else:
            record.update(asdict(score_rock(found == 1, truth == 1)))
            record.update(lighter=rock_is_lighter(pixels, truth == 1))
        record.update(seconds=seconds, error=error, score=score)
        records.append(record)
    return records


def run(
    methods: dict[str, Method],
    part: str,
    conditions: Sequence[str],
    n: int,
    *,
    jobs: int = 1,
    progress: bool = True,
    cache: Path | None = None,
    first: int = 0,
) -> list[dict]:
    """Score every method on the same photos; one record per (method, photo).

    With ``jobs > 1`` photos are spread over forked processes (the methods
    need not be picklable). With ``cache``, generated photos are stored there
    and read back on later runs (keyed by generator version, condition, seed).
    Generated photos start ``first`` seeds into their part (a block of seeds
    no earlier run read); the real photos are always all of them.
    """
    global _CACHE_DIR
    start_at = 0 if part == "real" else first
    tasks = [(part, c, start_at + i) for c in conditions for i in range(photo_count(part, c, n))]
    _METHODS.clear()
    _METHODS.update(methods)
    _CACHE_DIR = None if cache is None else Path(cache)
    records: list[dict] = []
    done = 0
    start = time.perf_counter()

    def tick(batch: list[dict]) -> None:
        nonlocal done
        records.extend(batch)
        done += 1
        if progress and (done % 10 == 0 or done == len(tasks)):
            rate = done / (time.perf_counter() - start)
            print(f"  {part}: {done}/{len(tasks)} photos ({rate:.1f}/s)", file=sys.stderr, flush=True)

    if jobs <= 1:
        for task in tasks:
            tick(_score_one(task))
    else:
        import multiprocessing

        with multiprocessing.get_context("fork").Pool(jobs) as pool:
            for batch in pool.imap_unordered(_score_one, tasks, chunksize=2):
                tick(batch)
    records.sort(key=lambda r: (r["condition"], r["index"], r["method"]))
    return records


def summarize(records: list[dict]) -> list[dict]:
    """One row per (part, condition, method), plus a row over all one-rock photos of a part."""
    groups: dict[tuple[str, str, str], list[dict]] = {}
    for r in records:
        groups.setdefault((r["part"], r["condition"], r["method"]), []).append(r)
        if r["part"] != "real" and r["kind"] == "one":
            groups.setdefault((r["part"], "all one-rock", r["method"]), []).append(r)
    rows = []
    for (part, condition, method), rs in groups.items():
        row = {"part": part, "condition": condition, "method": method, "n": len(rs), "kind": rs[0]["kind"]}
        if rs[0]["kind"] == "all":
            n_true = sum(r["n_true"] for r in rs)
            exact = sum(r["n_found"] == r["n_true"] for r in rs)
            row.update(
                exact_count=exact / len(rs),
                exact_interval=wilson_interval(exact, len(rs)),
                matched=sum(r["matched"] for r in rs) / max(n_true, 1),
                matched_interval=matched_interval(rs),
                n_true=n_true,
                merges=sum(r["merges"] for r in rs),
                splits=sum(r["splits"] for r in rs),
            )
        else:
            ious = np.array([r["iou"] for r in rs])
            good = int(np.count_nonzero(ious >= IOU_GOOD))
            row.update(
                good=good / len(rs),
                good_interval=wilson_interval(good, len(rs)),
                median_iou=float(np.median(ious)),
                centroid_error=float(np.median([r["centroid_error"] for r in rs])),
                no_rock=sum(r["no_rock"] for r in rs),
            )
        row["seconds"] = float(np.mean([r["seconds"] for r in rs]))
        rows.append(row)
    order = {c: i for i, c in enumerate((*scenes.CONDITIONS, "all one-rock", *REAL_CONDITIONS))}
    part_order = {p: i for i, p in enumerate(PARTS)}
    method_order = {m: i for i, m in enumerate(METHODS)}
    rows.sort(
        key=lambda r: (
            part_order.get(r["part"], 9),
            order.get(r["condition"], 99),
            method_order.get(r["method"], 9),
        )
    )
    return rows


def evaluate(
    segment_fn: Callable,
    part: str = "dev",
    conditions: Sequence[str] | None = None,
    n: int = 20,
    *,
    jobs: int = 1,
    progress: bool = False,
    cache: Path | str | None = None,
) -> list[dict]:
    """Judge a segmenter on the benchmark; one summary row per condition.

    Parameters
    ----------
    segment_fn : callable
        ``segment_fn(pixels, all_rocks=bool)`` returning a
        ``rockscan.core.segment.Segmentation`` or a label image at photo
        resolution (1 = the main rock), raising ``NoRockFoundError`` when it
        finds nothing; e.g. ``rockscan.core.segment.segment``.
    part : {"dev", "heldout", "real"}
        Tune on ``dev``; ``heldout`` is for reporting.
    conditions : sequence of str, optional
        Default: every condition of the part.
    n : int
        Photos per generated condition.
    jobs : int
        Processes.
    progress : bool
        Print progress to stderr.
    cache : path, optional
        A folder to keep generated photos in, so that later runs skip
        rendering.

    Returns
    -------
    list of dict
        Rows as printed by :func:`format_table`: ``good`` (share at IoU >=
        0.9) and its ``good_interval``, ``median_iou``, ``centroid_error``,
        ``no_rock`` for one-rock conditions; ``exact_count``, ``matched`` (each
        with its ``_interval``), ``merges``, ``splits`` for crowded ones;
        ``condition == "all one-rock"`` pools the one-rock photos.
    """
    conditions = _check_conditions(part, conditions)
    methods = {"candidate": as_method(segment_fn)}
    return summarize(run(methods, part, conditions, n, jobs=jobs, progress=progress, cache=cache))


def _check_conditions(part: str, conditions: Sequence[str] | None) -> list[str]:
    if part not in PARTS:
        raise ValueError(f"part must be one of {', '.join(PARTS)}, got {part!r}")
    known = REAL_CONDITIONS if part == "real" else scenes.CONDITIONS
    if conditions is None:
        return list(known)
    unknown = [c for c in conditions if c not in known]
    if unknown:
        raise ValueError(
            f"unknown conditions for part {part}: {', '.join(unknown)}; known: {', '.join(known)}"
        )
    return list(conditions)


def _pct(x: float) -> str:
    return f"{100 * x:.1f}%"


def _pct_in(x: float, interval) -> str:
    """A share and its 95% interval, as printed in the table."""
    low, high = interval if interval is not None else (float("nan"), float("nan"))
    if low is None or high is None or not (np.isfinite(low) and np.isfinite(high)):
        return _pct(x)
    return f"{_pct(x)} ({100 * low:.1f}-{100 * high:.1f})"


def rock_is_lighter(pixels: NDArray, rock: NDArray[np.bool_]) -> bool | None:
    """Whether the true rock is brighter than the ground around it (medians of
    the gray photo over the rock and over a ring a fifth to half of its
    equivalent radius outside); None for an empty rock or ring."""
    import cv2

    area = int(rock.sum())
    if area == 0:
        return None
    radius = float(np.sqrt(area / np.pi))
    outside = cv2.distanceTransform((~rock).astype(np.uint8), cv2.DIST_L2, 3)
    ring = (outside > max(1.0, 0.2 * radius)) & (outside <= max(3.0, 0.5 * radius))
    if not ring.any():
        return None
    gray = _gray(pixels)
    return bool(np.median(gray[rock]) > np.median(gray[ring]))


def by_brightness(records: list[dict], part: str, method: str = "rockscan") -> dict[str, tuple[int, int]]:
    """Photos of one rock and crops at IoU >= 0.9, of all, for rocks lighter
    and darker than their ground (``rock_is_lighter``): {"lighter": (right, n), "darker": ...}."""
    out = {}
    for name, value in (("lighter", True), ("darker", False)):
        rs = [r for r in _single(records, part, method) if r.get("lighter") is value]
        out[name] = (sum(r["iou"] >= IOU_GOOD for r in rs), len(rs))
    return out


def _single(records: list[dict], part: str, method: str) -> list[dict]:
    """A method's records of a part's photos of one rock and crops."""
    return [r for r in records if r["part"] == part and r["method"] == method and r["kind"] != "all"]


def score_auroc(records: list[dict], part: str, method: str = "rockscan") -> tuple[float, int, int]:
    """AUROC of the segmentation score: outlines of IoU >= 0.9 against those below 0.8.

    Over a part's photos of one rock and crops (outlines in between are
    neither right nor clearly wrong). Returns (AUROC, n right, n wrong);
    NaN when either side is empty.
    """
    rs = [r for r in _single(records, part, method) if np.isfinite(r.get("score", np.nan))]
    good = np.array([r["score"] for r in rs if r["iou"] >= IOU_GOOD])
    bad = np.array([r["score"] for r in rs if r["iou"] < 0.8])
    if not good.size or not bad.size:
        return float("nan"), good.size, bad.size
    return _auroc(good, bad), good.size, bad.size


def _auroc(good: np.ndarray, bad: np.ndarray) -> float:
    """The chance a right outline scores above a wrong one, ties half (Mann-Whitney)."""
    above = (good[:, None] > bad[None, :]).mean() + 0.5 * (good[:, None] == bad[None, :]).mean()
    return float(above)


#: Bootstrap resamples behind :func:`auroc_interval`.
RESAMPLES = 2000


def auroc_interval(
    records: list[dict], part: str, method: str = "rockscan", *, level: float = 0.95, seed: int = 0
) -> tuple[float, float]:
    """How far :func:`score_auroc` moves with the photos drawn: the central
    ``level`` of its values over ``RESAMPLES`` bootstrap resamples of the part's
    photos (seeded, so the same records give the same interval).

    With a few dozen wrong outlines, one of them ranked otherwise moves the
    AUROC by a hundredth or two: a change smaller than this interval is not
    told apart from the photos drawn. NaN, NaN when either side is empty.
    """
    rs = [r for r in _single(records, part, method) if np.isfinite(r.get("score", np.nan))]
    scores = np.array([r["score"] for r in rs], dtype=np.float64)
    ious = np.array([r["iou"] for r in rs], dtype=np.float64)
    if not np.any(ious >= IOU_GOOD) or not np.any(ious < 0.8):
        return float("nan"), float("nan")
    rng = np.random.default_rng(seed)
    values = []
    for _ in range(RESAMPLES):
        pick = rng.integers(0, len(rs), len(rs))
        good, bad = scores[pick][ious[pick] >= IOU_GOOD], scores[pick][ious[pick] < 0.8]
        if good.size and bad.size:
            values.append(_auroc(good, bad))
    low, high = np.quantile(values, [(1.0 - level) / 2.0, (1.0 + level) / 2.0])
    return float(low), float(high)


#: The normal quantile of a two-sided 95% interval.
_Z95 = 1.959963984540054


def wilson_interval(successes: int, n: int, z: float = _Z95) -> tuple[float, float]:
    """Wilson's score interval of a share of ``successes`` in ``n`` photos (95% by default).

    With 40 photos a condition one photo moves a share by 2.5 points, and 30
    right of 40 (75%) is consistent with any rate from 60% to 86%: a
    difference inside the interval is not told apart from the photos drawn.
    Unlike the normal approximation, the interval stays inside [0, 1] and is
    not empty at 0 or n successes. NaN, NaN for no photos.

    Parameters
    ----------
    successes, n : int
        Photos counted, of photos in all (0 <= successes <= n).
    z : float
        The normal quantile of the interval's level.

    Returns
    -------
    (float, float)
        The interval's ends, as shares.
    """
    if n <= 0:
        return float("nan"), float("nan")
    share = successes / n
    scale = 1.0 + z * z / n
    centre = (share + z * z / (2.0 * n)) / scale
    half = z * math.sqrt(share * (1.0 - share) / n + z * z / (4.0 * n * n)) / scale
    # At 0 or n successes an end is 0 or 1 exactly; rounding would leave it a hair off.
    low = 0.0 if successes == 0 else max(0.0, centre - half)
    high = 1.0 if successes == n else min(1.0, centre + half)
    return low, high


def matched_interval(records: list[dict], *, level: float = 0.95, seed: int = 0) -> tuple[float, float]:
    """How far the share of rocks matched one to one moves with the scenes drawn:
    the central ``level`` of its values over ``RESAMPLES`` bootstrap resamples of
    the scenes (seeded).

    The rocks of one scene fail together (a dark ground, a textured skin), so
    the scenes, not the rocks, are resampled; a binomial interval over the
    rocks would be too narrow. NaN, NaN for no scenes.
    """
    matched = np.array([r["matched"] for r in records], dtype=np.float64)
    true = np.array([r["n_true"] for r in records], dtype=np.float64)
    if not records or true.sum() == 0:
        return float("nan"), float("nan")
    rng = np.random.default_rng(seed)
    picks = rng.integers(0, len(records), (RESAMPLES, len(records)))
    shares = matched[picks].sum(axis=1) / np.maximum(true[picks].sum(axis=1), 1.0)
    low, high = np.quantile(shares, [(1.0 - level) / 2.0, (1.0 + level) / 2.0])
    return float(low), float(high)


def wrong_outlines(records: list[dict], part: str, method: str = "rockscan") -> dict[str, int]:
    """How a method's outlines below IoU 0.9 go wrong, over a part's photos of one rock and crops.

    Returns counts: ``wrong`` (found, IoU < 0.9), of them ``too_large`` (more
    of the outline off the rock than of the rock missed: precision below
    recall) and ``too_small``, and ``near`` (IoU 0.8-0.9); ``no_rock`` apart.
    """
    rs = _single(records, part, method)
    wrong = [r for r in rs if not r["no_rock"] and r["iou"] < IOU_GOOD]
    large = sum(r["precision"] < r["recall"] for r in wrong)
    return {
        "wrong": len(wrong),
        "too_large": large,
        "too_small": len(wrong) - large,
        "near": sum(r["iou"] >= 0.8 for r in wrong),
        "no_rock": sum(bool(r["no_rock"]) for r in rs),
    }


def format_table(rows: list[dict]) -> str:
    """The results as one markdown table."""
    lines = [
        "| part | condition | method | n | IoU>=0.9 | median IoU | centroid err (r_eq) | no rock "
        "| exact count | one-to-one | merges | splits |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        if r["kind"] == "all":
            cells = [
                "",
                "",
                "",
                "",
                _pct_in(r["exact_count"], r.get("exact_interval")),
                _pct_in(r["matched"], r.get("matched_interval")),
                str(r["merges"]),
                str(r["splits"]),
            ]
            n = f"{r['n']} ({r['n_true']} rocks)"
        else:
            err = r["centroid_error"]
            cells = [
                _pct_in(r["good"], r.get("good_interval")),
                f"{r['median_iou']:.3f}",
                "inf" if err is None or not np.isfinite(err) else f"{err:.3f}",  # None: read back from JSON
                str(r["no_rock"]),
                "",
                "",
                "",
                "",
            ]
            n = str(r["n"])
        lines.append("| " + " | ".join([r["part"], r["condition"], r["method"], n, *cells]) + " |")
    return "\n".join(lines)


# --------------------------------------------------------------------------- figures


def write_figures(directory: Path, part: str) -> list[Path]:
    """Overlays of truth and rockscan's outline: a hard photo and a crowded scene."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from skimage.measure import find_contours

    directory.mkdir(parents=True, exist_ok=True)
    written = []
    for name, condition in (("segment-hard.png", "combined"), ("segment-crowded.png", "crowded")):
        seed = scenes.part_seeds(part, 1)[0]
        scene = scenes.make_scene(condition, seed)
        found, _ = _rockscan(scene.image, scene.kind)
        fig, ax = plt.subplots(figsize=(8, 8 * scene.image.shape[0] / scene.image.shape[1]), dpi=100)
        ax.imshow(scene.image, cmap="gray", vmin=0, vmax=255)
        for labels, color, width in ((scene.labels, "lime", 2.5), (found, "red", 1.2)):
            for k in range(1, int(labels.max()) + 1):
                for contour in find_contours((labels == k).astype(float), 0.5):
                    ax.plot(contour[:, 1], contour[:, 0], color=color, lw=width)
        ax.set_title(f"{condition} ({part}, seed {seed}): truth green, rockscan red", fontsize=10)
        ax.set_axis_off()
        fig.tight_layout()
        path = directory / name
        fig.savefig(path)
        plt.close(fig)
        written.append(path)
    return written


def write_real_figure(path: Path) -> Path:
    """Overlay of the nuclei photo: the reference, what is not scored, and rockscan's rocks with ``--all``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from skimage.measure import find_contours

    image, truth = nuclear_photo(), nuclei_reference()
    found, _ = _rockscan(image, "all")
    fig, ax = plt.subplots(figsize=(8, 8 * image.shape[0] / image.shape[1]), dpi=100)
    # The photo is dark (ground 22 of 255, most nuclei 35-60): shown stretched.
    ax.imshow(np.clip((image.astype(float) - 18) / 60, 0, 1) ** 0.7, cmap="gray", vmin=0, vmax=1)
    ax.contourf(truth == UNSCORED, [0.5, 1.5], colors="tab:blue", alpha=0.3)
    for labels, color, width in ((np.maximum(truth, 0), "lime", 2.5), (found, "red", 1.2)):
        for k in range(1, int(labels.max()) + 1):
            for contour in find_contours((labels == k).astype(float), 0.5):
                ax.plot(contour[:, 1], contour[:, 0], color=color, lw=width)
    ax.set_title(
        "mahotas' nuclear.png, --all (shown stretched): reference green, rockscan red, not scored blue",
        fontsize=10,
    )
    ax.set_axis_off()
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path


def write_score_figure(records: list[dict], part: str, path: Path) -> Path | None:
    """How the segmentation score reads on a part's photos of one rock and crops:
    the share of right outlines (IoU >= 0.9) among those scored in each tenth,
    beside what the score promises, and how the scores of right and wrong
    (IoU < 0.8) outlines spread. None when the part has no scored outline."""
    rs = [r for r in _single(records, part, "rockscan") if np.isfinite(r.get("score", np.nan))]
    if not rs:
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    score = np.array([r["score"] for r in rs])
    iou = np.array([r["iou"] for r in rs])
    edges = np.linspace(0.0, 1.0, 11)
    which = np.clip(np.digitize(score, edges) - 1, 0, 9)
    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4), dpi=100)
    left.plot([0, 1], [0, 1], color="0.6", lw=1, ls="--", label="as promised")
    centres, shares, counts = [], [], []
    for k in range(10):
        inside = which == k
        if inside.any():
            centres.append(score[inside].mean())
            shares.append((iou[inside] >= IOU_GOOD).mean())
            counts.append(int(inside.sum()))
    left.plot(centres, shares, "o-", color="tab:red", label="rockscan")
    for x, y, n in zip(centres, shares, counts, strict=True):
        # Below the point, or above it near the axis, where the tick labels are.
        below = y > 0.1
        left.annotate(str(n), (x, y), textcoords="offset points", xytext=(4, -12 if below else 6), fontsize=8)
    left.set(xlim=(0, 1), ylim=(0, 1.02), xlabel="segmentation score (mean of each tenth)")
    left.set_ylabel("share of outlines with IoU >= 0.9")
    left.set_title("right where the score says (photos a tenth beside each point)", fontsize=10)
    left.legend(loc="upper left", fontsize=9)
    auroc, n_good, n_bad = score_auroc(records, part)
    bins = np.linspace(0.0, 1.0, 21)
    right.hist(
        score[iou >= IOU_GOOD], bins=bins, color="tab:green", alpha=0.7, label=f"IoU >= 0.9 ({n_good})"
    )
    right.hist(score[iou < 0.8], bins=bins, color="tab:red", alpha=0.7, label=f"IoU < 0.8 ({n_bad})")
    right.axvline(0.5, color="0.3", lw=1, ls=":", label="0.5, below which a rock is never interesting")
    right.set(xlabel="segmentation score", ylabel="outlines", yscale="log")
    right.set_title(f"right and wrong outlines apart: AUROC {auroc:.3f}", fontsize=10)
    right.legend(loc="upper left", fontsize=8)
    fig.suptitle(
        f"segmentation score on the {part} part ({len(rs)} photos of one rock and crops)", fontsize=11
    )
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path


# --------------------------------------------------------------------------- CLI


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--part", choices=(*PARTS, "both"), default="dev", help="default dev; both = dev, heldout, real"
    )
    parser.add_argument("-n", "--n", type=int, default=10, help="photos per generated condition (default 10)")
    parser.add_argument("--conditions", default="", help="comma-separated conditions (default: all)")
    parser.add_argument("--methods", default=",".join(METHODS), help="comma-separated rows (default: all)")
    parser.add_argument("--jobs", type=int, default=1, help="processes (default 1)")
    parser.add_argument("--json", type=Path, help="write the rows and per-photo records here")
    parser.add_argument(
        "--figures", type=Path, help="write the overlay figures and the score's figure into this folder"
    )
    parser.add_argument("--cache", type=Path, help="keep generated photos in this folder between runs")
    parser.add_argument(
        "--first",
        type=int,
        default=0,
        help="start each generated part this many seeds in (default 0): a block no earlier run read",
    )
    args = parser.parse_args(argv)
    methods = [m for m in args.methods.split(",") if m]
    unknown = [m for m in methods if m not in BUILTIN_METHODS]
    if unknown or args.n < 1 or args.jobs < 1 or args.first < 0:
        print(
            f"error: unknown methods {unknown}, n/jobs below 1 or --first below 0; "
            f"methods: {', '.join(METHODS)}",
            file=sys.stderr,
        )
        return 2
    parts = ["dev", "heldout", "real"] if args.part == "both" else [args.part]
    wanted = [c for c in args.conditions.split(",") if c] or None
    records = []
    known = {c for part in parts for c in _known(part)}
    unknown = [c for c in wanted or () if c not in known]
    if unknown:
        print(
            f"error: unknown conditions {', '.join(unknown)}; known: {', '.join(sorted(known))}",
            file=sys.stderr,
        )
        return 2
    try:
        for part in parts:
            if wanted and not set(wanted) & set(_known(part)):
                continue
            conditions = _check_conditions(part, [c for c in wanted if c in _known(part)] if wanted else None)
            chosen = {m: BUILTIN_METHODS[m] for m in methods}
            records += run(
                chosen, part, conditions, args.n, jobs=args.jobs, cache=args.cache, first=args.first
            )
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    rows = summarize(records)
    print(format_table(rows))
    for part in parts:
        auroc, n_good, n_bad = score_auroc(records, part)
        if bool(n_good) != bool(n_bad):
            print(f"{part}: segmentation_score AUROC undefined (IoU >= 0.9: {n_good}, IoU < 0.8: {n_bad})")
        elif n_good:
            low, high = auroc_interval(records, part)
            print(
                f"{part}: segmentation_score AUROC {auroc:.3f} (IoU >= 0.9: {n_good}, IoU < 0.8: {n_bad}; "
                f"{low:.3f}-{high:.3f} over 95% of {RESAMPLES} bootstrap resamples of the photos)"
            )
        split = by_brightness(records, part)
        if any(n for _, n in split.values()):
            cells = ", ".join(
                f"{name} than the ground {right}/{n}" + (f" ({_pct(right / n)})" if n else "")
                for name, (right, n) in split.items()
            )
            print(f"{part}: rockscan at IoU >= 0.9 on rocks {cells}")
        kinds = wrong_outlines(records, part)
        if kinds["wrong"]:
            print(
                f"{part}: rockscan's outlines at IoU < 0.9: {kinds['wrong']}, of them {kinds['too_large']} "
                f"too large (precision below recall) and {kinds['too_small']} too small; "
                f"{kinds['near']} near misses (IoU 0.8-0.9)"
            )
    if args.json:
        args.json.write_text(json.dumps(_finite({"rows": rows, "records": records}), indent=1))
    if args.figures:
        shown = "heldout" if "heldout" in parts else parts[0] if parts[0] != "real" else "dev"
        written = write_figures(args.figures, shown)
        written.append(write_score_figure(records, shown, args.figures / "segment-score.png"))
        if "real" in parts:
            written.append(write_real_figure(args.figures / "segment-nuclei.png"))
        for path in written:
            if path is not None:
                print(f"wrote {path}", file=sys.stderr)
    return 0


def _finite(value):
    """``value`` with every infinite or NaN float as None (strict JSON has neither)."""
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    if isinstance(value, float | np.floating):
        return float(value) if np.isfinite(value) else None
    if isinstance(value, np.integer | np.bool_):
        return value.item()
    return value


def _known(part: str) -> tuple[str, ...]:
    return REAL_CONDITIONS if part == "real" else scenes.CONDITIONS


if __name__ == "__main__":
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    sys.exit(main())
