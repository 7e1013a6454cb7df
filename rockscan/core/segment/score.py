"""How well a photo supports a rock's outline: a score in [0, 1].

A right outline runs where the photo steps from the rock's level to the
ground's all the way round. A wrong one shows it somewhere along its length:

* an outline that leaked into the ground runs through ground texture, with
  no step across it (``support`` low, ``weak`` high);
* an outline that left part of the rock out (a shaded side) has rock, not
  ground, just outside it (``outside`` high);
* an outline that took in a neighbour or the ground between rocks is ragged
  and hollow (``solidity`` low) or runs along the frame (``frame``);
* an outline of a faint rock on a busy ground is hard to trust wherever it
  runs (``noise``: the ground's spread against the step).

Each is measured on the level map of the rock's window (0 the ground's
level, 1 the rock's), the score is a logistic function of them, its weights
fitted on photos of known truth (the development part of the segmentation
benchmark) so that a low score marks a likely wrong outline.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rockscan.core.segment.stats import logistic, robust_spread, solidity

__all__ = ["OutlineEvidence", "outline_evidence", "outline_score"]


@dataclass(frozen=True)
class OutlineEvidence:
    """What the photo says about one outline (module docstring).

    Attributes
    ----------
    support : float
        Mean step across the outline, from just inside to just outside, in
        units of the rock's step (1 for a clean edge all round, clipped to [0, 1]).
    weak : float
        Share of the outline where that step is under a third of the rock's.
    outside : float
        Mean level just outside the outline (0 when ground lies there).
    noise : float
        Robust spread of the ground's level around the rock, in units of the step.
    frame : float
        Share of the outline that runs along the photo's frame.
    solidity : float
        Area over the area of the convex hull.
    darker_outside : float
        Share of a band just outside the outline (three band widths wide)
        darker than the ground by at least ``DARKER_LEVEL`` of the rock's
        step: something against the outline, beyond the ground from the rock
        (for a light rock, its own shaded side or its cast shadow). Not
        scored: the fast path reads it (``rockscan.core.segment``).
    inner_spread : float
        Robust spread of the level inside the outline, beyond the band along
        it, in units of the step (capped at 2). Not scored: the choice among
        candidates reads it (``rockscan.core.segment.choose``): an outline
        found in a channel that noise dominates on the rock (a dark rock's
        chromaticity) is uneven inside, and often ragged.
    """

    support: float
    weak: float
    outside: float
    noise: float
    frame: float
    solidity: float
    darker_outside: float = 0.0
    inner_spread: float = 1.0

    def as_array(self) -> NDArray[np.float64]:
        """The scored measurements, in the order of ``WEIGHTS``."""
        return np.array([self.support, self.weak, self.outside, self.noise, self.frame, self.solidity])


#: Level (0 the ground's, 1 the rock's) below which a pixel beside an
#: outline lies beyond the ground from the rock (``darker_outside``).
DARKER_LEVEL = -0.25


#: Pixels the inside's spread is read from, at most (a strided sample).
_SPREAD_SAMPLE = 2048


#: Logistic weights of the evidence (support, weak, outside, noise, frame,
#: solidity) and the intercept, fitted on the benchmark's development part.
WEIGHTS = np.array([6.0, -10.0, -6.0, -4.0, -6.0, 6.0])
INTERCEPT = -5.5


def outline_score(evidence: OutlineEvidence) -> float:
    """The logistic score in [0, 1] of an outline's evidence (higher: more likely right)."""
    return logistic(float(INTERCEPT + WEIGHTS @ evidence.as_array()))


def _box_sums(
    image: NDArray[np.generic], box: tuple[NDArray[np.intp], ...], depth: int
) -> NDArray[np.float64]:
    """Sums of ``image`` over boxes (rows r0:r1, cols c0:c1, each array one box per entry)."""
    import cv2

    r0, r1, c0, c1 = box
    total = cv2.integral(image, sdepth=depth)
    return (total[r1, c1] - total[r0, c1] - total[r1, c0] + total[r0, c0]).astype(np.float64)


def outline_evidence(
    level: NDArray[np.float32], mask: NDArray[np.bool_], frame_sides: tuple[bool, bool, bool, bool]
) -> OutlineEvidence:
    """Measure an outline's evidence on a window's level map.

    Parameters
    ----------
    level : (h, w) ndarray of float32
        0 at the ground's level, 1 at the rock's.
    mask : (h, w) ndarray of bool
        The rock.
    frame_sides : (bool, bool, bool, bool)
        Whether the window's top, bottom, left and right edges are the photo's frame.

    Returns
    -------
    OutlineEvidence
    """
    import cv2

    m8 = mask.astype(np.uint8)
    area = int(np.count_nonzero(m8))
    if area == 0:
        return OutlineEvidence(0.0, 1.0, 1.0, 1.0, 0.0, 0.0)
    radius = math.sqrt(area / math.pi)
    width = max(2, round(0.08 * radius))
    # The bands stand a band's width off the outline: a blurred edge is a
    # ramp across the outline, and a right outline has rock beyond the ramp
    # on one side and ground on the other.
    gap = width
    reach = gap + width
    pad = reach + 1
    # Pad with replicated values so that bands near the window's edge are whole.
    lv = cv2.copyMakeBorder(level.astype(np.float32), pad, pad, pad, pad, cv2.BORDER_REPLICATE)
    mk = cv2.copyMakeBorder(m8, pad, pad, pad, pad, cv2.BORDER_CONSTANT, value=0)
    # Distances to the outline, inside and outside, give the bands without large structuring elements.
    inside_dist = cv2.distanceTransform(mk, cv2.DIST_L2, 3)
    outside_dist = cv2.distanceTransform(1 - mk, cv2.DIST_L2, 3)
    inner = ((inside_dist > gap) & (inside_dist <= reach)).astype(np.uint8)
    outer = ((outside_dist > gap) & (outside_dist <= reach)).astype(np.uint8)
    boundary = (mk & (1 - cv2.erode(mk, np.ones((3, 3), np.uint8)))).astype(bool)
    # The frame: boundary pixels on a window edge that is the photo's edge.
    on_frame = np.zeros(mk.shape, bool)
    top, bottom, left, right = frame_sides
    if top:
        on_frame[: pad + 1] = True
    if bottom:
        on_frame[-pad - 1 :] = True
    if left:
        on_frame[:, : pad + 1] = True
    if right:
        on_frame[:, -pad - 1 :] = True
    frame_px = boundary & on_frame
    inside_px = boundary & ~on_frame
    n_boundary = int(np.count_nonzero(boundary))
    frame = float(np.count_nonzero(frame_px)) / max(n_boundary, 1)
    # The bands' sums in a box round each boundary pixel, from integral
    # images: only the boundary's boxes are needed, not every pixel's. The
    # padding keeps every such box inside the window.
    rows_at, cols_at = np.nonzero(inside_px)
    box = (rows_at - reach, rows_at + reach + 1, cols_at - reach, cols_at + reach + 1)
    in_n = _box_sums(inner, box, cv2.CV_32S)
    in_s = _box_sums(lv * inner, box, cv2.CV_64F)
    out_n = _box_sums(outer, box, cv2.CV_32S)
    out_s = _box_sums(lv * outer, box, cv2.CV_64F)
    at = (in_n > 0) & (out_n > 0)
    if np.count_nonzero(at) < 4:
        support, weak, outside = 0.0, 1.0, 1.0
    else:
        inside_mean = in_s[at] / in_n[at]
        outside_mean = out_s[at] / out_n[at]
        step = inside_mean - outside_mean
        support = float(np.clip(step, 0.0, 1.0).mean())
        weak = float((step < 1.0 / 3.0).mean())
        outside = float(np.clip(outside_mean, 0.0, 1.0).mean())
    beside = (outside_dist > 0) & (outside_dist <= 3 * width)
    darker_outside = float(np.count_nonzero(beside & (lv < DARKER_LEVEL))) / max(np.count_nonzero(beside), 1)
    # A strided grid of pixels: the spread of a few thousand is as good as all of them.
    step = max(1, math.isqrt(area // _SPREAD_SAMPLE))
    core = lv[::step, ::step][inside_dist[::step, ::step] > reach]
    inner_spread = min(robust_spread(core), 2.0) if core.size >= 8 else 1.0
    ring = (outside_dist > reach) & (outside_dist <= 3 * reach)
    ring = ring[pad:-pad, pad:-pad]
    values = level[ring] if np.count_nonzero(ring) >= 8 else level[~mask]
    if values.size >= 8:
        noise = robust_spread(values)
    else:
        noise = 1.0
    return OutlineEvidence(
        support, weak, outside, min(noise, 2.0), frame, min(1.0, solidity(m8)), darker_outside, inner_spread
    )
