"""Make the reference outlines of the real photos of the segmentation benchmark.

Writes beside this file:

* ``coins_reference.png``: a label image of ``skimage.data.coins()``'s size,
  0 for the background and 1-24 for the coins, numbered by rows of coins from
  the top, left to right;
* ``cell_reference.png``: the bright cell of ``skimage.data.cell()`` (label 1)
  without its dark phase-contrast halo;
* ``nuclei_reference.png``: the whole nuclei of the fluorescence micrograph
  ``nuclear.png`` that mahotas ships (labels 1-40), and 255 where a nucleus
  lies that cannot be outlined whole: cut by the frame, or under the glare of
  the four overexposed nuclei (:func:`nuclei_reference`).

How the outlines were made and checked is in docs/segmentation.md; run
``python tests/data/coins_reference.py`` to remake the files (the result is
the same, bit for bit).

Steps, per coin, at the photo's native resolution:

1. Seeds: a local threshold (block 151 px, offset 10 gray levels), opened and
   filled; the 24 components over 500 px are the coins.
2. GrabCut at 4x (bicubic) from a mask: the seed eroded by an eighth of its
   diameter is certain coin, everything beyond the seed dilated as much (and
   every other coin) is certain background.
3. Rays: from the coin's centroid, 720 rays; on each, the edge is the
   outermost point where the photo (Gaussian 0.7 px) crosses half-way between
   the coin's median level and the background's along that ray (1.25-1.6
   radii out), before the ray meets another coin. A radius more than 12% of
   the coin's radius off the 30-degree running median is a neighbour or a
   dark engraving at the rim and is interpolated over; a 4.5-degree running
   median smooths the rest. Done twice, the second time with the first
   pass's coins as the neighbours.
4. Hand correction, after looking at every coin at 6x: on coins 2, 5, 13 and
   21 a dark engraving or dirt reaches the rim and the traced outline dents
   inwards where the coin's edge does not; their outline is the convex hull
   of the traced one.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import cv2
import numpy as np
from PIL import Image
from scipy import ndimage as ndi
from skimage import data
from skimage.draw import polygon
from skimage.feature import peak_local_max
from skimage.filters import threshold_local
from skimage.morphology import convex_hull_image
from skimage.segmentation import relabel_sequential, watershed

#: Label of the nuclei that are not scored (cut by the frame, or under glare).
UNSCORED = 255
#: Points (row, col) in territories of one nucleus that the seeds split in two
#: (an elongated nucleus, two peaks of texture): checked by eye at 4x.
NUCLEI_JOINED = (((433, 529), (419, 485)), ((637, 369), (635, 318)), ((712, 93), (702, 44)))
#: Points in the clusters round the four overexposed nuclei, whose glare hides
#: the dim nuclei under and beside them: no outline of them is certain.
NUCLEI_UNCLEAR = ((281, 960), (164, 1018), (947, 187), (946, 108), (958, 266), (837, 184))

#: Coins (in the final numbering) whose outline is replaced by its convex hull.
HULL_COINS = (2, 5, 13, 21)
N_RAYS = 720


def seeds(image: np.ndarray) -> np.ndarray:
    f = image.astype(float)
    mask = f > threshold_local(f, 151, offset=-10)
    mask = ndi.binary_fill_holes(ndi.binary_opening(mask, iterations=2))
    labels, n = ndi.label(mask)
    areas = np.bincount(labels.ravel())
    keep = [k for k in range(1, n + 1) if areas[k] > 500]
    out = np.zeros(labels.shape, np.int32)
    for i, k in enumerate(keep, start=1):
        out[labels == k] = i
    return out


def grabcut(image: np.ndarray, coarse_labels: np.ndarray, up: int = 4) -> np.ndarray:
    out = np.zeros(image.shape, np.int32)
    for k in range(1, coarse_labels.max() + 1):
        coarse = coarse_labels == k
        rs, cs = ndi.find_objects(coarse.astype(int))[0]
        diameter = max(rs.stop - rs.start, cs.stop - cs.start)
        pad = int(0.35 * diameter)
        r0, r1 = max(0, rs.start - pad), min(image.shape[0], rs.stop + pad)
        c0, c1 = max(0, cs.start - pad), min(image.shape[1], cs.stop + pad)
        window = image[r0:r1, c0:c1]
        big = cv2.resize(window, None, fx=up, fy=up, interpolation=cv2.INTER_CUBIC)
        cw = coarse[r0:r1, c0:c1]
        width = max(3, diameter // 8)
        init = np.full(window.shape, cv2.GC_PR_BGD, np.uint8)
        init[cw] = cv2.GC_PR_FGD
        init[ndi.binary_erosion(cw, iterations=width)] = cv2.GC_FGD
        init[~ndi.binary_dilation(cw, iterations=width)] = cv2.GC_BGD
        init[(coarse_labels[r0:r1, c0:c1] > 0) & ~cw] = cv2.GC_BGD
        mask = cv2.resize(init, (big.shape[1], big.shape[0]), interpolation=cv2.INTER_NEAREST)
        bgd, fgd = np.zeros((1, 65)), np.zeros((1, 65))
        cv2.grabCut(cv2.cvtColor(big, cv2.COLOR_GRAY2BGR), mask, None, bgd, fgd, 8, cv2.GC_INIT_WITH_MASK)
        fg = ((mask == cv2.GC_FGD) | (mask == cv2.GC_PR_FGD)).astype(np.float32)
        small = cv2.resize(fg, (window.shape[1], window.shape[0]), interpolation=cv2.INTER_AREA) >= 0.5
        parts, n = ndi.label(small)
        if n > 1:
            small = parts == np.argmax(np.bincount(parts.ravel())[1:]) + 1
        out[r0:r1, c0:c1][ndi.binary_fill_holes(small)] = k
    return out


def rays(image: np.ndarray, labels: np.ndarray) -> np.ndarray:
    smooth = ndi.gaussian_filter(image.astype(float), 0.7)
    out = np.zeros(labels.shape, np.int32)
    theta = np.linspace(0, 2 * np.pi, N_RAYS, endpoint=False)
    for k in range(1, labels.max() + 1):
        coin = labels == k
        cr, cc = ndi.center_of_mass(coin)
        radius = np.sqrt(coin.sum() / np.pi)
        others = ndi.binary_dilation((labels > 0) & ~coin, iterations=2)
        t = np.arange(0.5 * radius, 1.6 * radius, 0.1)
        rr = cr + np.outer(np.sin(theta), t)
        cols = cc + np.outer(np.cos(theta), t)
        profile = ndi.map_coordinates(smooth, [rr, cols], order=1, mode="nearest")
        blocked = (
            ndi.map_coordinates(others.astype(float), [rr, cols], order=0, mode="constant", cval=1) > 0.5
        )
        coin_level = np.median(image[ndi.binary_erosion(coin, iterations=3)])
        background = np.median(image[~coin & ~others])
        radii = np.full(N_RAYS, np.nan)
        for a in range(N_RAYS):
            p, o = profile[a], blocked[a]
            ring = (t > 1.25 * radius) & ~o
            bg = np.median(p[ring]) if ring.sum() > 3 else background
            threshold = bg + 0.5 * (coin_level - bg)
            stop = int(np.argmax(o)) if o.any() else len(t)
            inside = np.nonzero(p[:stop] >= threshold)[0]
            if len(inside) == 0:
                continue
            i = inside[-1]
            if i + 1 < len(t):
                radii[a] = t[i] + (p[i] - threshold) / (p[i] - p[i + 1] + 1e-9) * (t[i + 1] - t[i])
            else:
                radii[a] = t[i]
        radii = without_outliers(radii, radius)
        r_, c_ = polygon(cr + radii * np.sin(theta), cc + radii * np.cos(theta), labels.shape)
        free = out[r_, c_] == 0
        out[r_[free], c_[free]] = k
    return out


def without_outliers(radii: np.ndarray, radius: float) -> np.ndarray:
    """Rays' radii with the missing interpolated over, those more than 12% of the
    radius off the 30-degree running median (a neighbour, an engraving) as well,
    then smoothed by a 4.5-degree running median."""
    index = np.arange(N_RAYS)
    ok = np.isfinite(radii)
    radii = np.interp(index, index[ok], radii[ok], period=N_RAYS)
    broad = ndi.median_filter(radii, size=61, mode="wrap")
    good = np.abs(radii - broad) <= 0.12 * radius
    radii = np.interp(index, index[good], radii[good], period=N_RAYS)
    return ndi.median_filter(radii, size=9, mode="wrap")


def by_rows(labels: np.ndarray) -> np.ndarray:
    """Renumber: rows of coins from the top (a gap of 25 px between rows), left to right."""
    index = np.arange(1, labels.max() + 1)
    centres = np.array(ndi.center_of_mass(labels > 0, labels, index))
    order = np.argsort(centres[:, 0])
    rows, row = [], [order[0]]
    for a, b in itertools.pairwise(order):
        if centres[b, 0] - centres[a, 0] > 25:
            rows.append(row)
            row = []
        row.append(b)
    rows.append(row)
    remap = np.zeros(labels.max() + 1, np.int32)
    n = 0
    for row in rows:
        for j in sorted(row, key=lambda j: centres[j, 1]):
            n += 1
            remap[j + 1] = n
    return remap[labels]


def reference(image: np.ndarray) -> np.ndarray:
    labels = grabcut(image, seeds(image))
    labels = rays(image, rays(image, labels))
    labels = by_rows(labels)
    for k in HULL_COINS:
        hull = convex_hull_image(labels == k, include_borders=False)
        labels[hull & (labels == 0)] = k
    return labels


def cell_reference(image: np.ndarray) -> np.ndarray:
    """The cell: on 720 rays (Gaussian 1 px), half-way between its median level and the halo's minimum."""
    smooth = ndi.gaussian_filter(image.astype(float), 1.0)
    parts, _ = ndi.label(smooth > 150)
    cell = ndi.binary_fill_holes(parts == np.argmax(np.bincount(parts.ravel())[1:]) + 1)
    cr, cc = ndi.center_of_mass(cell)
    radius = np.sqrt(cell.sum() / np.pi)
    theta = np.linspace(0, 2 * np.pi, N_RAYS, endpoint=False)
    t = np.arange(0.5 * radius, 1.5 * radius, 0.1)
    profile = ndi.map_coordinates(
        smooth, [cr + np.outer(np.sin(theta), t), cc + np.outer(np.cos(theta), t)], order=1
    )
    level = np.median(image[ndi.binary_erosion(cell, iterations=5)])
    radii = np.zeros(N_RAYS)
    for a in range(N_RAYS):
        p = profile[a]
        j = int(np.argmin(p))
        threshold = p[j] + 0.5 * (level - p[j])
        i = np.nonzero(p[:j] >= threshold)[0][-1]
        radii[a] = t[i] + (p[i] - threshold) / (p[i] - p[i + 1]) * (t[i + 1] - t[i])
    radii = ndi.median_filter(radii, size=9, mode="wrap")
    out = np.zeros(image.shape, np.int32)
    out[polygon(cr + radii * np.sin(theta), cc + radii * np.cos(theta), image.shape)] = 1
    return out


def nuclear_photo() -> np.ndarray:
    """The gray levels of mahotas' ``nuclear.png``, read without importing mahotas."""
    import importlib.util

    spec = importlib.util.find_spec("mahotas")
    if spec is None or not spec.submodule_search_locations:
        raise SystemExit("the nuclei photo comes with mahotas: pip install mahotas")
    path = Path(spec.submodule_search_locations[0]) / "demos" / "data" / "nuclear.png"
    return np.asarray(Image.open(path).convert("L"))


def nuclei_territories(image: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each nucleus's territory, the foreground, and the unclear clusters.

    The foreground is the photo (Gaussian 2 px) 4 gray levels above the
    median, opened; one seed per peak of the log contrast smoothed by 10 px
    (at least 22 px apart), the seeds of one nucleus joined (``NUCLEI_JOINED``);
    the line between touching nuclei is the valley of the photo (Gaussian 2 px)
    between their eroded seeds' regions.
    """
    f = image.astype(float)
    background = np.median(f)
    fore = ndi.binary_opening(ndi.gaussian_filter(f, 2) > background + 4, iterations=4)
    coarse = ndi.gaussian_filter(np.log1p(np.maximum(f - background, 0) / 3), 10)
    peaks = peak_local_max(coarse, min_distance=22, threshold_abs=0.5, labels=ndi.label(fore)[0])
    markers = np.zeros(f.shape, np.int32)
    markers[tuple(peaks.T)] = np.arange(1, len(peaks) + 1)
    labels = watershed(-coarse, markers, mask=fore)
    for group in NUCLEI_JOINED:
        first, *rest = (labels[p] for p in group)
        for k in rest:
            labels[labels == k] = first
    markers = np.zeros(f.shape, np.int32)
    for k in np.unique(labels[labels > 0]):
        own = labels == k
        markers[ndi.binary_erosion(own, iterations=max(2, int(0.4 * np.sqrt(own.sum() / np.pi))))] = k
    labels = watershed(-ndi.gaussian_filter(f, 2), markers, mask=fore)
    unclear = np.zeros(f.shape, bool)
    for p in NUCLEI_UNCLEAR:
        unclear |= labels == labels[p]
    labels[unclear] = 0
    return labels, fore, unclear


def nucleus_rays(image: np.ndarray, labels: np.ndarray, fore: np.ndarray) -> np.ndarray:
    """Each nucleus on 720 rays (Gaussian 1.5 px): where the photo first falls below
    half-way from the nucleus's median level to the ground's, going out from its
    centroid and stopping at any other nucleus; outliers as for the coins; then its
    convex hull, within its territory."""
    f = image.astype(float)
    smooth = ndi.gaussian_filter(f, 1.5)
    ground = ~ndi.binary_dilation(fore, iterations=3)
    out = np.zeros(labels.shape, np.int32)
    theta = np.linspace(0, 2 * np.pi, N_RAYS, endpoint=False)
    rows_at, cols_at = np.ogrid[: f.shape[0], : f.shape[1]]
    for k in [k for k in np.unique(labels) if k]:
        own = labels == k
        cr, cc = ndi.center_of_mass(own)
        radius = np.sqrt(own.sum() / np.pi)
        others = ((labels > 0) & ~own) | (fore & (labels == 0))
        t = np.arange(0.2 * radius, 2.0 * radius, 0.1)
        rr, cols = cr + np.outer(np.sin(theta), t), cc + np.outer(np.cos(theta), t)
        profile = ndi.map_coordinates(smooth, [rr, cols], order=1, mode="nearest")
        blocked = (
            ndi.map_coordinates(others.astype(float), [rr, cols], order=0, mode="constant", cval=1) > 0.5
        )
        near = (rows_at - cr) ** 2 + (cols_at - cc) ** 2 <= (2.5 * radius) ** 2
        background = np.median(f[near & ground])
        level = np.median(f[ndi.binary_erosion(own, iterations=max(2, int(0.3 * radius)))])
        threshold = background + 0.5 * (level - background)
        radii = np.full(N_RAYS, np.nan)
        for a in range(N_RAYS):
            p, o = profile[a], blocked[a]
            stop = int(np.argmax(o)) if o.any() else len(t)
            # The first fall from the centre out: a neighbour's glow beyond does not pull the edge out.
            below = np.nonzero(p[:stop] < threshold)[0]
            if len(below) == 0:
                radii[a] = t[stop - 1] if stop > 0 else np.nan
                continue
            if below[0] == 0:
                continue
            i = below[0] - 1
            radii[a] = t[i] + (p[i] - threshold) / (p[i] - p[i + 1]) * (t[i + 1] - t[i])
        radii = without_outliers(radii, radius)
        shape = np.zeros(labels.shape, bool)
        shape[polygon(cr + radii * np.sin(theta), cc + radii * np.cos(theta), labels.shape)] = True
        shape = convex_hull_image(shape) & ~others
        out[shape & (out == 0)] = k
    return out


def nuclei_reference(image: np.ndarray) -> np.ndarray:
    """The whole nuclei (1..n, by rows) and ``UNSCORED`` where nuclei lie that are not scored.

    A nucleus whose outline comes within 3 px of the frame is cut by it. Not
    scored: those, the unclear clusters, and every other part of the
    foreground that no whole nucleus holds (a found region there is neither
    right nor wrong).
    """
    labels, fore, unclear = nuclei_territories(image)
    nuclei = nucleus_rays(image, labels, fore)
    frame = np.zeros(nuclei.shape, bool)
    frame[:3] = frame[-3:] = True
    frame[:, :3] = frame[:, -3:] = True
    for k in np.unique(nuclei[frame]):
        nuclei[nuclei == k] = 0
    unscored = (fore | ndi.binary_dilation(unclear, iterations=3)) & ~ndi.binary_dilation(
        nuclei > 0, iterations=6
    )
    nuclei = by_rows(relabel_sequential(nuclei)[0])
    nuclei[unscored] = UNSCORED
    return nuclei


if __name__ == "__main__":
    here = Path(__file__).parent
    labels = reference(data.coins())
    assert labels.max() == 24
    Image.fromarray(labels.astype(np.uint8)).save(here / "coins_reference.png")
    print("coin areas:", np.bincount(labels.ravel())[1:].tolist())
    cell = cell_reference(data.cell())
    Image.fromarray(cell.astype(np.uint8)).save(here / "cell_reference.png")
    print("cell area:", int(cell.sum()))
    nuclei = nuclei_reference(nuclear_photo())
    assert nuclei[nuclei != UNSCORED].max() == 40
    Image.fromarray(nuclei.astype(np.uint8)).save(here / "nuclei_reference.png")
    print("nuclei areas:", np.bincount(nuclei[nuclei != UNSCORED].ravel())[1:].tolist())
