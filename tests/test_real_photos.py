"""Real photos: scikit-image's coins (24 Greek coins under uneven light) and the bundled examples.

The coins' positions come from an independent oracle, scikit-image's own
gallery segmentation of this photo (Sobel elevation map, watershed from dark
and bright markers, holes filled), not from rockscan; their outlines from the
segmentation benchmark's reference (tests/data/coins_reference.png, made per
coin and checked by eye).
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image
from scipy import ndimage
from skimage import data, filters, measure, segmentation

from rockscan.cli import main
from rockscan.core.segment import CONFIDENT_SCORE, segment
from rockscan.io import data_path
from rockscan.run.pipeline import classify_image, classify_path

EXAMPLES = data_path("examples")


@pytest.fixture(scope="module")
def coins() -> np.ndarray:
    return data.coins()


@pytest.fixture(scope="module")
def oracle(coins) -> list:
    """The 24 coins as scikit-image's gallery segments them (regions over 100 px)."""
    elevation = filters.sobel(coins)
    markers = np.zeros_like(coins)
    markers[coins < 30] = 1
    markers[coins > 150] = 2
    filled = ndimage.binary_fill_holes(segmentation.watershed(elevation, markers) - 1)
    regions = [r for r in measure.regionprops(ndimage.label(filled)[0]) if r.area > 100]
    assert len(regions) == 24
    return regions


def test_classify_all_finds_the_24_coins_as_circles(tmp_path, coins, oracle):
    path = tmp_path / "coins.png"
    Image.fromarray(coins).save(path)
    result = CliRunner().invoke(main, ["classify", "--all", "--json", str(path)])
    assert result.exit_code == 0, result.output
    records = [json.loads(line) for line in result.stdout.splitlines()]
    assert len(records) == 24
    assert all(r["nearest"] == "circle" for r in records)
    # The coins are ovals (axis ratios 1.03-1.18 in the hand-checked reference):
    # a clean sample is judged by the circle's clean cutoff, which lies just
    # inside the library's spacing, so all but the two most oval are accepted
    # (docs/decision.md).
    assert all(
        r["match"] in ("circle", None) and r["interesting"] == (r["match"] is not None) for r in records
    )
    assert sum(r["interesting"] for r in records) >= 22
    # One found rock per oracle coin, at its centroid, of its size.
    centroids = np.array([r["centroid"] for r in records])
    unmatched = set(range(24))
    for region in oracle:
        cy, cx = region.centroid
        distance = np.hypot(*(centroids - [cx, cy]).T)
        j = int(np.argmin(distance))
        assert distance[j] < 2.0, (cx, cy)
        assert records[j]["area_px"] == pytest.approx(region.area, rel=0.1)
        unmatched.discard(j)
    assert not unmatched


def test_single_coin_crops_classify_as_circles(coins, oracle, default_lib):
    """Each coin cut out with a margin of 15% of its size on every side."""
    for region in oracle:
        r0, c0, r1, c1 = region.bbox
        margin = int(0.15 * max(r1 - r0, c1 - c0))
        top, left = max(0, r0 - margin), max(0, c0 - margin)
        crop = coins[top : r1 + margin, left : c1 + margin]
        rock = classify_image(crop, default_lib)[0]
        cy, cx = region.centroid
        assert rock.match.nearest == "circle", (cx, cy)
        np.testing.assert_allclose(rock.centroid_xy, [cx - left, cy - top], atol=2.5)


def test_bundled_examples_stay_small_and_documented():
    names = sorted(p.name for p in EXAMPLES.iterdir())
    assert "README.md" in names
    assert sum(p.stat().st_size for p in EXAMPLES.iterdir()) < 1_000_000
    readme = (EXAMPLES / "README.md").read_text()
    photos = [name for name in names if name.endswith((".png", ".jpg"))]
    assert "coin.png" in photos and len(photos) == 4
    for name in photos:
        assert name in readme
    for name in names:
        if name.endswith(".json"):
            assert json.loads((EXAMPLES / name).read_text())["photo"] in photos


def test_bundled_coin_is_a_circle(default_lib):
    result = classify_path(EXAMPLES / "coin.png", default_lib)
    assert result.ok, result.error
    assert result.rocks[0].match.nearest == result.rocks[0].match.match == "circle"


@pytest.mark.parametrize(
    "truth_path",
    sorted(EXAMPLES.glob("*.json")),
    ids=lambda p: p.stem,
)
def test_bundled_rendered_rocks_classify_as_their_truth(truth_path, default_lib):
    truth = json.loads(truth_path.read_text())
    result = classify_path(EXAMPLES / truth["photo"], default_lib)
    assert result.ok, result.error
    rock = result.rocks[0]
    # Nearest and flagged: the examples are the library's own shapes.
    assert rock.match.nearest == rock.match.match == truth["shape"]
    np.testing.assert_allclose(rock.centroid_xy, truth["centroid_xy"], atol=1.0)
    period = 360.0 / truth["symmetry"]
    assert abs((rock.match.angle_deg - truth["angle_deg"] + period / 2) % period - period / 2) < 1.5


# ---------------------------------------------------------------- against the reference outlines


def _bench():
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
    import bench_segment

    return bench_segment


def test_all_finds_the_24_reference_coins_one_to_one():
    """--all on coins(): every coin of the hand-checked reference, one region each."""
    bench = _bench()
    truth = bench.coins_reference()
    found, _ = bench.as_method(segment)(data.coins(), "all")
    crowd = bench.score_crowd(found, truth)
    assert (crowd.n_true, crowd.n_found, crowd.matched, crowd.merges, crowd.splits) == (24, 24, 24, 0, 0)


def test_all_finds_most_whole_nuclei_of_a_fluorescence_photo_one_to_one():
    """--all on mahotas' nuclear.png, which nothing was tuned on: 35 of the 40 whole
    nuclei one to one when it was first measured, none merged or split. The five
    missed are faint: two small ones, two beside the glare of overexposed nuclei,
    one whose glow reaches the frame."""
    bench = _bench()
    found, _ = bench.as_method(segment)(bench.nuclear_photo(), "all")
    crowd = bench.score_crowd(*bench.scored_parts(found, bench.nuclei_reference()))
    assert crowd.n_true == 40
    assert crowd.matched >= 34 and crowd.n_found <= 41
    assert crowd.merges == 0 and crowd.splits == 0


def test_single_nucleus_crops_are_mostly_outlined():
    """Every whole nucleus cut out with a margin of a third of its diameter: 28 of 40 at
    IoU >= 0.9 when first measured (median 0.94); the misses lie inside the reference's
    half-way edge, which on these soft edges is a convention, and score low."""
    bench = _bench()
    ious, scores = [], []
    for crop, truth in bench.nuclei_crops():
        seg = segment(crop)
        ious.append(bench.iou(bench.segmentation_labels(seg, crop.shape) == 1, truth == 1))
        scores.append(seg.rocks[0].score)
    ious, scores = np.array(ious), np.array(scores)
    assert np.count_nonzero(ious >= 0.9) >= 26 and np.median(ious) >= 0.92
    assert np.all(ious >= 0.5)  # every crop's rock is the nucleus it is centred on
    # Wrong outlines score lower than right ones, as the score promises.
    assert np.median(scores[ious < 0.8]) < np.median(scores[ious >= 0.9])


def test_single_coin_crops_with_neighbours_at_the_edges_are_outlined_and_circles(default_lib):
    """Every coin at native resolution, a margin of a third of its diameter (neighbours intrude)."""
    bench = _bench()
    unsure = []
    for k, (crop, truth) in enumerate(bench.coin_crops()):
        seg = segment(crop)
        found = bench.segmentation_labels(seg, crop.shape)
        assert bench.iou(found == 1, truth == 1) >= 0.9, k
        rock = classify_image(crop, default_lib)[0]
        assert rock.match.nearest == "circle", k
        if rock.segmentation_score < CONFIDENT_SCORE:
            unsure.append(k)
    # Crop 23's detected regions are both neighbours at the frame; the right
    # outline is chosen from the refinements, and the choice model alone,
    # having seen such photos go wrong, was not sure of it (probability 0.05).
    # Read over the whole pool (no rival object, the candidates agreeing), it
    # scores 0.53.
    assert unsure == []
